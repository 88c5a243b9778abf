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

use crate::live_plant::{self, Actuator, Injection, Step};
use crate::push::{self, Ids, Target};
use crate::radio::{ToolRadio, TOOL_ADDR};
use crate::watch::{self, Seen, Watch};
use medium::{self, Medium};
use robot_compiler::compile::Compiled;

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
    /// The machine faulted during the cycle: who detected it, when, and what followed.
    pub fault: Option<FaultReport>,
}

impl Cycle {
    pub fn ok(&self) -> bool {
        self.steps == self.expect && self.faults.is_empty() && self.fault.is_none()
    }
}

/// A fault, as the demo saw it happen. Times are since the cycle's START.
#[derive(Debug, Clone, PartialEq)]
pub struct FaultReport {
    /// When the first node published its fault (or, without a publication, when a
    /// status showed it).
    pub at: Duration,
    /// Found by a status after no step for this long (no node published a fault).
    pub stalled: Option<Duration>,
    pub role: String,
    pub addr: u16,
    /// Its fault code (`synth::FAULT_MOTION_TIMEOUT`, ...), if its status said.
    pub code: Option<u8>,
    /// Its links in trouble, by peer role: (peer, broken); not broken is an alarm (the
    /// peer stopped acknowledging; the node still retries).
    pub links: Vec<(String, bool)>,
    /// The step under way on the detecting role when it faulted: (step, when it was
    /// commanded); `jammed` when the plant saw the command and did not move.
    pub step: Option<(String, Duration, bool)>,
    /// Every role's node after the fault: (role, address, fault code, outputs).
    pub nodes: Vec<(String, u16, Option<u8>, u16)>,
    /// Output levels the nodes drove from the detection on: (time, address, pin, level).
    pub outputs: Vec<(Duration, u16, u8, bool)>,
}

/// Who detected a fault, and when (since the cycle's START).
struct Detected {
    at: Duration,
    addr: u16,
    role: String,
    /// Found by a status after no step for this long.
    stalled: Option<Duration>,
}

/// The running machine.
pub struct Bed {
    options: Options,
    medium: Medium,
    nodes: BTreeMap<u16, Child>,
    plant: Option<(Arc<AtomicBool>, JoinHandle<io::Result<()>>)>,
    steps: Receiver<Step>,
    steps_tx: mpsc::Sender<Step>,
    watch: Option<Watch>,
    seen: Receiver<Seen>,
    seen_tx: mpsc::Sender<Seen>,
    radio: ToolRadio,
    ids: Ids,
    /// Steps the plant has seen since it was wired (what an injection counts).
    steps_seen: usize,
    /// A fault to inject once the plant has seen so many steps.
    pending: Option<(usize, BedFault)>,
}

/// A fault the bed injects into the running machine (`demo --fault`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BedFault {
    /// Stops the node at this address (a power cut): `stop:ROLE`.
    Stop(u16),
    /// Cuts the radio link from one node to another: `link:FROM->TO`.
    Cut { from: u16, to: u16 },
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
        let (seen_tx, seen) = mpsc::channel();
        Ok(Bed {
            options,
            medium,
            nodes: BTreeMap::new(),
            plant: None,
            steps,
            steps_tx,
            watch: None,
            seen,
            seen_tx,
            radio,
            ids: Ids::default(),
            steps_seen: 0,
            pending: None,
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
    /// is on the medium, its switches set at the nodes, when this returns.
    pub fn set_plant(&mut self, actuators: Vec<Actuator>) -> Result<(), String> {
        self.set_plant_injected(actuators, None)
    }

    /// [`Bed::set_plant`], with a fault the plant injects.
    pub fn set_plant_injected(
        &mut self,
        actuators: Vec<Actuator>,
        injection: Option<Injection>,
    ) -> Result<(), String> {
        self.stop_plant();
        let stop = Arc::new(AtomicBool::new(false));
        let conn = live_plant::attach(self.medium.addr(), &actuators)
            .map_err(|e| format!("plant: {e}"))?;
        let (tx, flag) = (self.steps_tx.clone(), stop.clone());
        let handle = std::thread::spawn(move || {
            live_plant::run_attached(conn, actuators, injection, tx, flag)
        });
        self.plant = Some((stop, handle));
        self.steps_seen = 0;
        while self.steps.try_recv().is_ok() {}
        Ok(())
    }

    /// Watches the air for the faults of robot `c` (and every output level) from now on.
    pub fn watch(&mut self, c: &Compiled) -> Result<(), String> {
        self.watch = None;
        let w = Watch::start(
            self.medium.addr(),
            self.medium.started(),
            watch::fault_topics(c),
            self.seen_tx.clone(),
        )
        .map_err(|e| format!("monitor: {e}"))?;
        self.watch = Some(w);
        while self.seen.try_recv().is_ok() {}
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

    /// Injects `fault` once the plant has seen `steps` steps.
    pub fn inject_after(&mut self, steps: usize, fault: BedFault) {
        self.pending = Some((steps, fault));
    }

    /// Presses START (the command, to the role with the start input) and follows one cycle:
    /// every step as the plant sees it (`on_step`), until the declared number of steps
    /// happened and every node is back in its initial state, or a node faults (reported
    /// as it happens, with what every node then did).
    pub fn run_cycle(
        &mut self,
        c: &Compiled,
        on_step: &mut dyn FnMut(&Step, Duration),
    ) -> Result<Cycle, String> {
        let expect: Vec<String> = c.ir.expect.iter().map(|s| s.to_string()).collect();
        let (start_role, _) = c.ir.start.clone().ok_or("the robot has no start input")?;
        let start_addr = c.ir.roles[start_role].address;
        while self.steps.try_recv().is_ok() {}
        while self.seen.try_recv().is_ok() {}
        let before = self.medium.stats();
        let t0 = Instant::now();
        let m0 = self.medium.now();
        let end = t0 + self.options.timeout;
        // Without a fault publication (one role), a stall shows a fault: no step for
        // longer than the watchdog.
        let stall = Duration::from_millis(u64::from(c.robot.motion_timeout_ms) + 500);
        self.inject_due();
        self.command(start_addr, Command::Start)?;
        let mut steps = Vec::new();
        let mut commanded: Vec<(Step, bool)> = Vec::new();
        let mut faults = Vec::new();
        let mut outputs = Vec::new();
        let mut detected: Option<Detected> = None;
        let mut last_progress = Instant::now();
        loop {
            while let Ok(step) = self.steps.try_recv() {
                last_progress = Instant::now();
                self.on_plant_step(&step, m0, &mut steps, &mut commanded, on_step);
            }
            while let Ok(seen) = self.seen.try_recv() {
                match seen {
                    Seen::Fault { at, addr, role } => {
                        detected.get_or_insert(Detected {
                            at: at.saturating_sub(m0),
                            addr,
                            role,
                            stalled: None,
                        });
                    }
                    Seen::Output {
                        at,
                        addr,
                        pin,
                        level,
                    } => outputs.push((at.saturating_sub(m0), addr, pin, level)),
                }
            }
            if detected.is_some() {
                break;
            }
            let stalled = last_progress.elapsed() > stall;
            if steps.len() >= expect.len() || stalled {
                // Done when every node is back where it started (and nothing else moved).
                let statuses = self.statuses(c)?;
                faults = faults_of(c, &statuses);
                // A stalled machine whose node reports a link in trouble: a radio fault
                // (not a fault state of the node: it keeps retrying).
                let link_trouble = stalled
                    .then(|| {
                        statuses
                            .iter()
                            .zip(&c.ir.roles)
                            .find(|(s, _)| s.link_alarms | s.links_broken != 0)
                            .map(|(_, r)| (r.name.clone(), 0))
                    })
                    .flatten();
                if let Some((role, _)) = faults.first().or(link_trouble.as_ref()) {
                    let at = self.medium.now().saturating_sub(m0);
                    let addr =
                        c.ir.roles
                            .iter()
                            .find(|r| &r.name == role)
                            .map(|r| r.address);
                    detected = Some(Detected {
                        at,
                        addr: addr.unwrap_or(0),
                        role: role.clone(),
                        stalled: Some(last_progress.elapsed()),
                    });
                    break;
                }
                if steps.len() >= expect.len() && at_rest(c, &statuses) {
                    break;
                }
                last_progress = Instant::now();
            }
            if Instant::now() > end {
                break;
            }
            if let Ok(step) = self.steps.recv_timeout(Duration::from_millis(20)) {
                last_progress = Instant::now();
                self.on_plant_step(&step, m0, &mut steps, &mut commanded, on_step);
            }
        }
        let fault = match detected {
            Some(d) => Some(self.fault_report(c, d, m0, &commanded, outputs)?),
            None => None,
        };
        if let Some(f) = &fault {
            faults = f
                .nodes
                .iter()
                .filter_map(|(role, _, code, _)| code.map(|k| (role.clone(), k)))
                .collect();
        }
        while let Ok(step) = self.steps.try_recv() {
            self.on_plant_step(&step, m0, &mut steps, &mut commanded, on_step);
        }
        let after = self.medium.stats();
        Ok(Cycle {
            steps,
            expect,
            duration: t0.elapsed(),
            frames: after.frames - before.frames,
            airtime_us: after.airtime_us - before.airtime_us,
            faults,
            fault,
        })
    }

    /// A step the plant saw: counted (a jammed command is not a step), printed, and the
    /// node to stop at this point stopped.
    fn on_plant_step(
        &mut self,
        step: &Step,
        m0: Duration,
        steps: &mut Vec<String>,
        commanded: &mut Vec<(Step, bool)>,
        on_step: &mut dyn FnMut(&Step, Duration),
    ) {
        on_step(step, step.at.saturating_sub(m0));
        commanded.push((step.clone(), step.moved));
        if !step.moved {
            return;
        }
        steps.push(step.to_string());
        self.steps_seen += 1;
        self.inject_due();
    }

    /// Injects the pending fault if the plant has seen its steps.
    fn inject_due(&mut self) {
        if let Some((after, fault)) = self.pending {
            if self.steps_seen >= after {
                self.pending = None;
                match fault {
                    BedFault::Stop(addr) => self.kill_node(addr),
                    BedFault::Cut { from, to } => self.medium.cut(from, to),
                }
            }
        }
    }

    /// What every node did after `role` at `addr` faulted at `at`.
    #[allow(clippy::too_many_arguments)]
    fn fault_report(
        &mut self,
        c: &Compiled,
        detected: Detected,
        m0: Duration,
        commanded: &[(Step, bool)],
        mut outputs: Vec<(Duration, u16, u8, bool)>,
    ) -> Result<FaultReport, String> {
        let Detected {
            at,
            addr,
            role,
            stalled,
        } = detected;
        // Give every node the time to hear the fault and drive its outputs safe.
        std::thread::sleep(Duration::from_millis(100));
        let mut nodes = Vec::new();
        let mut links = Vec::new();
        for (r, table) in c.ir.roles.iter().zip(&c.tables) {
            let status = push::command(
                &mut self.radio,
                &mut self.ids,
                r.address,
                Command::Status,
                Duration::from_secs(2),
            )
            .map_err(err)?;
            if let Some(s) = status.as_ref().filter(|_| r.address == addr) {
                links = links_in_trouble(c, table, s);
            }
            nodes.push((
                r.name.clone(),
                r.address,
                status.as_ref().and_then(|s| s.fault),
                status.map_or(0, |s| s.outputs),
            ));
        }
        while let Ok(seen) = self.seen.try_recv() {
            if let Seen::Output {
                at,
                addr,
                pin,
                level,
            } = seen
            {
                outputs.push((at.saturating_sub(m0), addr, pin, level));
            }
        }
        outputs.retain(|o| o.0 >= at.saturating_sub(Duration::from_millis(50)));
        let actuators: Vec<&str> =
            c.ir.roles
                .iter()
                .find(|r| r.name == role)
                .map(|r| {
                    c.robot
                        .roles
                        .iter()
                        .find(|m| m.name == r.name)
                        .map(|m| m.actuators.iter().map(|a| a.name.as_str()).collect())
                        .unwrap_or_default()
                })
                .unwrap_or_default();
        let step = commanded
            .iter()
            .rev()
            .find(|(s, _)| actuators.contains(&s.actuator.as_str()))
            .map(|(s, moved)| (s.to_string(), s.at.saturating_sub(m0), !moved));
        let code = nodes.iter().find(|n| n.1 == addr).and_then(|n| n.2);
        Ok(FaultReport {
            at,
            stalled,
            role,
            addr,
            code,
            links,
            step,
            nodes,
            outputs,
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

/// A node's links in alarm or broken, by peer role (the table's peer list gives the
/// addresses): (peer, broken).
fn links_in_trouble(c: &Compiled, table: &config_schema::Table, s: &Status) -> Vec<(String, bool)> {
    table
        .peers
        .iter()
        .enumerate()
        .filter(|(i, _)| *i < 8 && (s.link_alarms | s.links_broken) & (1 << i) != 0)
        .map(|(i, peer)| {
            let name =
                c.ir.roles
                    .iter()
                    .find(|r| r.address == *peer)
                    .map_or_else(|| format!("{peer:#06x}"), |r| r.name.clone());
            (name, s.links_broken & (1 << i) != 0)
        })
        .collect()
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
    format!(
        "  {:<6} {:#06x}  {:>5} bytes  {:>3} frames  {:>3} retries  {:>6.1} ms  {}",
        o.role,
        o.addr,
        o.bytes,
        o.stats.frames,
        o.stats.retries,
        o.elapsed.as_secs_f64() * 1e3,
        o.verdict()
    )
}

/// Prints a cycle's verdict.
pub fn cycle_line(n: usize, cy: &Cycle) -> String {
    let verdict = match (&cy.fault, cy.ok()) {
        (Some(_), _) => "FAULTED",
        (None, true) => "ok",
        (None, false) => "MISMATCH",
    };
    let mut s = format!(
        "cycle {n}: {verdict}  {:.2} s  {} frames  {:.1} ms airtime  {}",
        cy.duration.as_secs_f64(),
        cy.frames,
        cy.airtime_us as f64 / 1e3,
        cy.steps.join(" ")
    );
    if let Some(f) = &cy.fault {
        s.push('\n');
        s.push_str(&fault_text(f));
    } else if !cy.ok() {
        s.push('\n');
        s.push_str(&robot_analysis::sim::diff(&cy.expect, &cy.steps));
        for (role, code) in &cy.faults {
            s.push_str(&format!("  role {role} faulted (code {code:#04x})\n"));
        }
    }
    s
}

/// A status fault code in words (`node_fw::node::fault_code`).
pub fn fault_meaning(code: u8) -> String {
    const ACTION: u8 = 0x80;
    match code {
        1 => "the interpreter's chain limit (event-less transitions)".into(),
        2 => "the interpreter's event queue overflowed".into(),
        3 => "the interpreter's cascade limit".into(),
        4 => "a guard or assignment failed to evaluate".into(),
        c if c == ACTION | robot_compiler::synth::FAULT_MOTION_TIMEOUT => {
            "its motion watchdog expired".into()
        }
        c if c == ACTION | robot_compiler::synth::FAULT_PEER => "stopped by a peer's fault".into(),
        c if c & ACTION != 0 => format!("fault action {}", c & !ACTION),
        c => format!("fault {c:#04x}"),
    }
}

/// A fault in words: who detected it, how, when, and what every node then did.
pub fn fault_text(f: &FaultReport) -> String {
    let links: Vec<String> = f
        .links
        .iter()
        .map(|(peer, broken)| match broken {
            true => format!("link to {peer} broken (nothing more is sent on it until a reset)"),
            false => format!("link alarm: {peer} does not acknowledge"),
        })
        .collect();
    let how = match f.code {
        Some(code) => fault_meaning(code),
        None if !links.is_empty() => links.join("; "),
        None => "a fault (its status did not answer)".to_string(),
    };
    let mut s = format!(
        "FAULT at {:.3} s: node {:#06x} ({}) detected it: {how}",
        f.at.as_secs_f64(),
        f.addr,
        f.role
    );
    if let Some(quiet) = f.stalled {
        s.push_str(&format!(
            "\n  no node published a fault: its status showed it after {:.3} s without a step",
            quiet.as_secs_f64()
        ));
    }
    let watchdog = f.code.is_some() || f.links.is_empty();
    if let Some((step, at, _)) = f.step.as_ref().filter(|_| !watchdog) {
        s.push_str(&format!(
            "\n  last step: {step}, commanded at {:.3} s",
            at.as_secs_f64()
        ));
    }
    if let Some((step, at, jammed)) = f.step.as_ref().filter(|_| watchdog) {
        let what = if *jammed {
            "the plant saw the command and the rod did not move"
        } else {
            "it did not complete"
        };
        s.push_str(&format!(
            "\n  watchdog of step {step}, commanded at {:.3} s ({:.3} s before the detection): \
             {what}",
            at.as_secs_f64(),
            f.at.saturating_sub(*at).as_secs_f64()
        ));
    }
    for (role, addr, code, outputs) in &f.nodes {
        let state = match code {
            Some(c) => format!("faulted ({}, code {c:#04x})", fault_meaning(*c)),
            None => "NOT faulted".to_string(),
        };
        s.push_str(&format!(
            "\n  node {addr:#06x} ({role}): {state}, outputs {outputs:#06x}"
        ));
        let changes: Vec<String> = f
            .outputs
            .iter()
            .filter(|o| o.1 == *addr)
            .map(|(at, _, pin, level)| {
                format!(
                    "pin {pin} -> {} at {:.3} s",
                    u8::from(*level),
                    at.as_secs_f64()
                )
            })
            .collect();
        if !changes.is_empty() {
            s.push_str(&format!("; {}", changes.join(", ")));
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
