//! The whole machine on the host: the simulated medium, one unconfigured node process per
//! physical node, the plant, and the tool. `demo` pushes the tables over the medium, runs
//! cycles and checks each against the declared sequence, then pushes a reconfiguration to
//! the running nodes. The end-to-end tests drive the same [`Bed`].

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::io::{self, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command as Process, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use config_schema::wire::msg::{Announce, Command, Status};

use crate::compile::Compiled;
use crate::medium::{self, Medium};
use crate::plant::{self, Actuator, Step};
use crate::push::{self, Ids, Target};
use crate::radio::{ToolRadio, TOOL_ADDR};

/// How to run the test bed.
#[derive(Debug, Clone)]
pub struct Options {
    /// The medium's faults.
    pub medium: medium::Config,
    /// The program (and leading arguments) that runs one node; `--addr A --medium M
    /// [--flash F]` are appended.
    pub node_command: Vec<OsString>,
    /// A directory for the nodes' flash files (`None`: RAM, a restart forgets).
    pub flash_dir: Option<PathBuf>,
    /// Bound of one cycle (and of waiting for nodes).
    pub timeout: Duration,
}

/// What one cycle did.
#[derive(Debug, Clone, PartialEq)]
pub struct Cycle {
    pub steps: Vec<String>,
    pub expect: Vec<String>,
    pub duration: Duration,
    /// Frames put on the air during the cycle.
    pub frames: u64,
    pub airtime_us: u64,
    /// Faults reported by the nodes at the end of the cycle: (role, code).
    pub faults: Vec<(String, u8)>,
}

impl Cycle {
    pub fn ok(&self) -> bool {
        self.steps == self.expect && self.faults.is_empty()
    }
}

/// The running machine.
pub struct Bed {
    options: Options,
    medium: Medium,
    nodes: BTreeMap<u16, Child>,
    plant: Option<(Arc<AtomicBool>, JoinHandle<io::Result<()>>)>,
    steps: Receiver<Step>,
    steps_tx: mpsc::Sender<Step>,
    radio: ToolRadio,
    ids: Ids,
}

fn err(e: impl std::fmt::Display) -> String {
    e.to_string()
}

impl Bed {
    /// Starts the medium and the tool's radio; no nodes yet.
    pub fn start(options: Options) -> Result<Bed, String> {
        let medium = Medium::start(options.medium.clone()).map_err(|e| format!("medium: {e}"))?;
        let radio = ToolRadio::connect(medium.addr(), TOOL_ADDR).map_err(err)?;
        let (steps_tx, steps) = mpsc::channel();
        Ok(Bed {
            options,
            medium,
            nodes: BTreeMap::new(),
            plant: None,
            steps,
            steps_tx,
            radio,
            ids: Ids::default(),
        })
    }

    pub fn medium(&self) -> &Medium {
        &self.medium
    }

    pub fn radio(&mut self) -> &mut ToolRadio {
        &mut self.radio
    }

    /// Starts (or restarts) the node process at `addr`.
    pub fn start_node(&mut self, addr: u16) -> Result<(), String> {
        self.kill_node(addr);
        let (program, lead) = self
            .options
            .node_command
            .split_first()
            .ok_or("no node command")?;
        let mut cmd = Process::new(program);
        cmd.args(lead)
            .arg("--addr")
            .arg(format!("{addr:#06x}"))
            .arg("--medium")
            .arg(self.medium.addr().to_string())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null());
        if let Some(dir) = &self.options.flash_dir {
            cmd.arg("--flash")
                .arg(dir.join(format!("node-{addr:04x}.flash")));
        }
        let child = cmd
            .spawn()
            .map_err(|e| format!("cannot start node {addr:#06x}: {e}"))?;
        self.nodes.insert(addr, child);
        Ok(())
    }

    /// Kills the node process at `addr` (a power cut).
    pub fn kill_node(&mut self, addr: u16) {
        if let Some(mut child) = self.nodes.remove(&addr) {
            let _ = child.kill();
            let _ = child.wait();
        }
    }

    /// Wires the plant for these actuators (restarting it: call between cycles). The plant
    /// is on the medium, its switches set, when this returns.
    pub fn set_plant(&mut self, actuators: Vec<Actuator>) -> Result<(), String> {
        self.stop_plant();
        let stop = Arc::new(AtomicBool::new(false));
        let stream =
            plant::attach(self.medium.addr(), &actuators).map_err(|e| format!("plant: {e}"))?;
        let (tx, flag) = (self.steps_tx.clone(), stop.clone());
        let handle = std::thread::spawn(move || plant::run_attached(stream, actuators, tx, flag));
        self.plant = Some((stop, handle));
        while self.steps.try_recv().is_ok() {}
        Ok(())
    }

    fn stop_plant(&mut self) {
        if let Some((stop, handle)) = self.plant.take() {
            stop.store(true, Ordering::Relaxed);
            let _ = handle.join();
        }
    }

    /// Waits until every address in `addrs` has announced itself.
    pub fn wait_for_nodes(&mut self, addrs: &[u16]) -> Result<BTreeMap<u16, Announce>, String> {
        let end = Instant::now() + self.options.timeout;
        let mut found = BTreeMap::new();
        while Instant::now() < end {
            let seen = push::scan(&mut self.radio, &mut self.ids, Duration::from_millis(600))
                .map_err(err)?;
            found.extend(seen);
            if addrs.iter().all(|a| found.contains_key(a)) {
                return Ok(found);
            }
        }
        let missing: Vec<String> = addrs
            .iter()
            .filter(|a| !found.contains_key(a))
            .map(|a| format!("{a:#06x}"))
            .collect();
        Err(format!("nodes did not answer: {}", missing.join(", ")))
    }

    /// Pushes every role of `c` to its node.
    pub fn push(
        &mut self,
        c: &Compiled,
        force: bool,
        progress: &mut dyn FnMut(usize, usize, usize),
    ) -> Result<Vec<push::Outcome>, String> {
        let targets = targets(c);
        push::push(&mut self.radio, &targets, force, progress).map_err(err)
    }

    /// A command to a node, resent until acknowledged.
    pub fn command(&mut self, addr: u16, command: Command) -> Result<Status, String> {
        push::command(
            &mut self.radio,
            &mut self.ids,
            addr,
            command,
            self.options.timeout,
        )
        .map_err(err)?
        .ok_or_else(|| format!("node {addr:#06x} did not answer {command:?}"))
    }

    /// Presses START (the command, to the role with the start input) and follows one cycle:
    /// every step as the plant sees it (`on_step`), until the declared number of steps
    /// happened and every node is back in its initial state.
    pub fn run_cycle(
        &mut self,
        c: &Compiled,
        on_step: &mut dyn FnMut(&Step),
    ) -> Result<Cycle, String> {
        let expect: Vec<String> = c.ir.expect.iter().map(|s| s.to_string()).collect();
        let (start_role, _) = c.ir.start.clone().ok_or("the robot has no start input")?;
        let start_addr = c.ir.roles[start_role].address;
        while self.steps.try_recv().is_ok() {}
        let before = self.medium.stats();
        let t0 = Instant::now();
        let end = t0 + self.options.timeout;
        self.command(start_addr, Command::Start)?;
        let mut steps = Vec::new();
        let mut faults = Vec::new();
        loop {
            while let Ok(step) = self.steps.try_recv() {
                on_step(&step);
                steps.push(step.to_string());
            }
            if steps.len() >= expect.len() {
                // Done when every node is back where it started (and nothing else moved).
                let statuses = self.statuses(c)?;
                faults = faults_of(c, &statuses);
                if !faults.is_empty() || at_rest(c, &statuses) {
                    break;
                }
            }
            if Instant::now() > end {
                break;
            }
            if let Ok(step) = self.steps.recv_timeout(Duration::from_millis(100)) {
                on_step(&step);
                steps.push(step.to_string());
            }
        }
        while let Ok(step) = self.steps.try_recv() {
            on_step(&step);
            steps.push(step.to_string());
        }
        let after = self.medium.stats();
        Ok(Cycle {
            steps,
            expect,
            duration: t0.elapsed(),
            frames: after.frames - before.frames,
            airtime_us: after.airtime_us - before.airtime_us,
            faults,
        })
    }

    /// The status of every role's node.
    pub fn statuses(&mut self, c: &Compiled) -> Result<Vec<Status>, String> {
        c.ir.roles
            .iter()
            .map(|r| self.command(r.address, Command::Status))
            .collect()
    }

    /// Stops the plant, the nodes and the medium.
    pub fn stop(mut self) {
        self.stop_plant();
        let addrs: Vec<u16> = self.nodes.keys().copied().collect();
        for a in addrs {
            self.kill_node(a);
        }
        self.medium.stop();
    }
}

impl Drop for Bed {
    fn drop(&mut self) {
        for child in self.nodes.values_mut() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// One push target per role.
pub fn targets(c: &Compiled) -> Vec<Target> {
    c.ir.roles
        .iter()
        .zip(&c.blobs)
        .map(|(r, b)| Target {
            role: r.name.clone(),
            addr: r.address,
            blob: b.clone(),
            generation: c.ir.generation,
        })
        .collect()
}

fn at_rest(c: &Compiled, statuses: &[Status]) -> bool {
    statuses.iter().zip(&c.tables).all(|(s, t)| {
        s.generation == t.generation
            && s.states.len() == t.charts.len()
            && s.states
                .iter()
                .zip(&t.charts)
                .all(|(st, ch)| *st == ch.initial)
    })
}

fn faults_of(c: &Compiled, statuses: &[Status]) -> Vec<(String, u8)> {
    statuses
        .iter()
        .zip(&c.ir.roles)
        .filter_map(|(s, r)| s.fault.map(|f| (r.name.clone(), f)))
        .collect()
}

/// The addresses of every physical node of the robot (spares too).
pub fn node_addrs(c: &Compiled) -> Vec<u16> {
    c.robot.nodes.iter().map(|n| n.address).collect()
}

/// A one-line summary of a push.
pub fn push_line(o: &push::Outcome) -> String {
    let verdict = o.verdict();
    format!(
        "  {:<6} {:#06x}  {:>5} bytes  {:>3} frames  {:>3} retries  {:>6.1} ms  {verdict}",
        o.role,
        o.addr,
        o.bytes,
        o.stats.frames,
        o.stats.retries,
        o.elapsed.as_secs_f64() * 1e3
    )
}

/// Prints a cycle's verdict.
pub fn cycle_line(n: usize, cy: &Cycle) -> String {
    let verdict = if cy.ok() { "ok" } else { "MISMATCH" };
    let mut s = format!(
        "cycle {n}: {verdict}  {:.2} s  {} frames  {:.1} ms airtime  {}",
        cy.duration.as_secs_f64(),
        cy.frames,
        cy.airtime_us as f64 / 1e3,
        cy.steps.join(" ")
    );
    if !cy.ok() {
        s.push('\n');
        s.push_str(&crate::sim::diff(&cy.expect, &cy.steps));
        for (role, code) in &cy.faults {
            s.push_str(&format!("  role {role} faulted (code {code:#04x})\n"));
        }
    }
    s
}

/// Writes a line and flushes (the demo prints as things happen).
pub fn say(out: &mut dyn Write, line: &str) {
    let _ = writeln!(out, "{line}");
    let _ = out.flush();
}

/// The emulated board: QEMU's Cortex-M3 machine the `qemu-mps2` image runs on.
pub const QEMU_MACHINE: &str = "mps2-an385";
/// Where the provisioning word goes (`node-fw/boards/qemu-mps2/src/provision.rs`).
pub const PROVISION_AT: u32 = 0x003F_F000;
/// The provisioning word's magic (bits 31..24) and its flag "semihosting on" (bit 16).
const PROVISION_MAGIC: u32 = 0xA5 << 24;
const PROVISION_SEMIHOSTING: u32 = 1 << 16;
/// The release image, relative to the repository.
pub const QEMU_ELF: &str = "node-fw/boards/target/thumbv7m-none-eabi/release/qemu-mps2";

/// The provisioning word of node `addr` (address, magic, semihosting on).
pub fn provision_word(addr: u16) -> u32 {
    PROVISION_MAGIC | PROVISION_SEMIHOSTING | u32::from(addr)
}

/// QEMU's arguments for one node booting `elf`: its address in the provisioning word, its
/// UART connected to the medium, its flash slots in `flash` (through semihosting; without
/// it they are erased at every boot).
pub fn qemu_args(
    elf: &Path,
    addr: u16,
    medium: SocketAddr,
    flash: Option<&Path>,
    count: Option<&Path>,
) -> Result<Vec<OsString>, String> {
    let mut semihosting = OsString::from("enable=on,target=native");
    let mut word = provision_word(addr);
    let mut extra: Vec<OsString> = Vec::new();
    if let Some(dir) = count {
        // A nanosecond of emulated time is one instruction; the firmware logs its busy
        // time and stimuli to the node's log file.
        word |= PROVISION_COUNT;
        let log = count_log(dir, addr);
        let mut chardev = OsString::from("file,id=log,path=");
        chardev.push(log.as_os_str());
        extra.extend(["-icount".into(), "shift=0,sleep=on".into()]);
        extra.extend(["-chardev".into(), chardev]);
        semihosting.push(",chardev=log");
    }
    if let Some(f) = flash {
        let text = f.to_str().unwrap_or(",");
        // QEMU splits options at commas and the firmware its command line at spaces.
        if text.contains([',', ' ']) {
            return Err(format!(
                "flash file {}: a QEMU node's flash path cannot contain a comma or a space",
                f.display()
            ));
        }
        semihosting.push(",arg=flash=");
        semihosting.push(text);
    }
    let mut args: Vec<OsString> = vec![
        "-M".into(),
        QEMU_MACHINE.into(),
        "-display".into(),
        "none".into(),
        "-monitor".into(),
        "none".into(),
        "-kernel".into(),
        elf.as_os_str().to_owned(),
        "-device".into(),
        format!("loader,addr={PROVISION_AT:#010x},data={word:#010x},data-len=4").into(),
        "-chardev".into(),
        format!(
            "socket,id=radio,host={},port={},nodelay=on",
            medium.ip(),
            medium.port()
        )
        .into(),
        "-serial".into(),
        "chardev:radio".into(),
        "-semihosting-config".into(),
    ];
    args.push(semihosting);
    args.extend(extra);
    Ok(args)
}

/// The provisioning flag "count busy time and stimuli".
const PROVISION_COUNT: u32 = 2 << 16;

/// Where a counting QEMU node logs.
pub fn count_log(dir: &Path, addr: u16) -> PathBuf {
    dir.join(format!("node-{addr:04x}.log"))
}

/// What a counting node said last.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// Instructions executed while awake (interrupts included).
    pub instructions: u64,
    /// Frames received.
    pub frames: u64,
    /// `Pin` messages received (the plant repeats levels every 200 ms).
    pub pins: u64,
    /// Input level changes among them.
    pub changes: u64,
    /// Instructions inside the node core (MAC, links, OTA, interpreter) for frames, and
    /// the frames.
    pub core_frame: u64,
    pub core_frames: u64,
    /// The same for `Pin` messages (every one goes to the core; repeats raise no event).
    pub core_input: u64,
    pub core_inputs: u64,
}

/// The last `count:` line of a counting node's log.
pub fn read_counts(dir: &Path, addr: u16) -> Option<Counts> {
    let text = std::fs::read_to_string(count_log(dir, addr)).ok()?;
    let line = text.lines().rev().find(|l| l.contains(" count: "))?;
    let mut words = line.split_whitespace();
    let mut next = |key: &str| -> Option<u64> {
        words.by_ref().find(|w| *w == key)?;
        words.next()?.parse().ok()
    };
    Some(Counts {
        instructions: next("busy_ns")?,
        frames: next("frames")?,
        pins: next("pins")?,
        changes: next("changes")?,
        core_frame: next("core_frame_ns")?,
        core_frames: next("core_frames")?,
        core_input: next("core_input_ns")?,
        core_inputs: next("core_inputs")?,
    })
}
