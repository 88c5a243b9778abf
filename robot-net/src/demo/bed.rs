//! The test bed: medium, node processes, plant, monitor and the tool's radio; one cycle
//! at a time, with faults injected and reported as they happen.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::io;
use std::path::PathBuf;
use std::process::{Child, Command as Process, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use config_schema::alarm::AlarmReport;
use config_schema::wire::msg::{Announce, Command, Status};

use crate::error::NetError;
use crate::home::{self, HomeEnd};
use crate::live_plant::{self, Actuator, Injection, Stroke};
use crate::push::{self, Ids, Target};
use crate::radio::{ToolRadio, TOOL_ADDR};
use crate::sniff::Sniffer;
use crate::watch::{self, Seen, Watch};
use medium::{self, Medium};
use robot_compiler::compile::Compiled;
use robot_compiler::ir::Step;

/// The operator's side of a plant with motors: requests to it, motions from it.
pub type MotorPlant = (
    mpsc::Sender<crate::live_motor::Operate>,
    Receiver<crate::live_motor::Motion>,
);

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
    /// Secure the management traffic: the bed makes a machine secret of its own, gives
    /// every node its key file (`--key`: `node` reads it, `qemu-node` writes it to the
    /// provisioning area) and the tool's radio the secret.
    pub secured: bool,
}

/// What one cycle did.
#[derive(Debug, Clone, PartialEq)]
pub struct Cycle {
    pub steps: Vec<Step>,
    /// The generation each step's node ran when it commanded it (parallel to `steps`).
    pub generations: Vec<u32>,
    pub expect: Vec<Step>,
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
    /// Whether the cycle's steps ran under more than one table generation.
    pub fn mixed(&self) -> bool {
        self.generations.windows(2).any(|w| w[0] != w[1])
    }

    pub fn ok(&self) -> bool {
        self.steps == self.expect && self.faults.is_empty() && self.fault.is_none() && !self.mixed()
    }
}

/// How homing on the bed ended ([`Bed::home`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Homing {
    pub end: HomeEnd,
    /// The steps the plant saw (homing's, and anything since the last cycle).
    pub steps: Vec<Step>,
    /// From the HOME command to its end.
    pub took: Duration,
}

/// A node's fault and outputs, as its status said after a fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeAfter {
    pub fault: Option<u8>,
    pub outputs: u16,
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
    /// Every role's node after the fault: (role, address, what its status said; `None`:
    /// it did not answer).
    pub nodes: Vec<(String, u16, Option<NodeAfter>)>,
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
    steps: Receiver<Stroke>,
    steps_tx: mpsc::Sender<Stroke>,
    watch: Option<Watch>,
    seen: Receiver<Seen>,
    seen_tx: mpsc::Sender<Seen>,
    radio: ToolRadio,
    ids: Ids,
    /// Steps the plant has seen since it was wired (what an injection counts).
    steps_seen: usize,
    /// A fault to inject once the plant has seen so many steps.
    pending: Option<(usize, BedFault)>,
    /// Secured: the directory with the machine secret and every node's key file.
    keys: Option<KeyDir>,
}

/// The key directories of the beds alive in this process ([`remove_key_dirs`]).
static KEY_DIRS: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Removes the key directories of every bed alive in this process, for a process about to
/// end without dropping its bed (an interrupted `demo`: its handler then exits), so that
/// no machine secret or node key is left behind in the temporary directory.
pub fn remove_key_dirs() {
    let mut dirs = KEY_DIRS.lock().unwrap_or_else(|e| e.into_inner());
    for dir in dirs.drain(..) {
        let _ = std::fs::remove_dir_all(dir);
    }
}

/// The bed's keys: a directory of its own (removed with the bed, or by
/// [`remove_key_dirs`]) holding the machine secret (`machine.key`) and each node's key
/// file (`node-AAAA.key`), all mode 0600.
struct KeyDir {
    dir: PathBuf,
    secret: robot_keys::MachineSecret,
}

impl KeyDir {
    fn create() -> Result<KeyDir, NetError> {
        use std::sync::atomic::AtomicU32;
        static RUN: AtomicU32 = AtomicU32::new(0);
        let run = RUN.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("robot-bed-{}-{run}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        KEY_DIRS
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(dir.clone());
        std::fs::create_dir_all(&dir).map_err(NetError::Radio)?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700))
                .map_err(NetError::Radio)?;
        }
        let path = dir.join("machine.key");
        robot_keys::write_machine_secret(&path, false)?;
        let secret = robot_keys::load_machine_secret(&path)?;
        Ok(KeyDir { dir, secret })
    }

    /// Writes node `addr`'s key file (again, for a restart); returns its path.
    fn node_key(&self, addr: u16) -> Result<PathBuf, NetError> {
        let path = self.dir.join(format!("node-{addr:04x}.key"));
        let key = robot_keys::management_key(&self.secret, addr);
        let key = node_fw::provision::ManagementKey::from_bytes(*key.expose());
        let line = node_fw::provision::NodeKeyLine { addr, key: &key }.to_string();
        robot_keys::write_secret_file(&path, line.as_bytes(), true)?;
        Ok(path)
    }
}

impl Drop for KeyDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
        KEY_DIRS
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .retain(|d| *d != self.dir);
    }
}

/// A fault the bed injects into the running machine (`demo --fault`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BedFault {
    /// Stops the node at this address (a power cut): `stop:ROLE`.
    Stop(u16),
    /// Cuts the radio link from one node to another: `link:FROM->TO`.
    Cut { from: u16, to: u16 },
}

impl Bed {
    /// Starts the medium and the tool's radio; no nodes yet.
    pub fn start(options: Options) -> Result<Bed, NetError> {
        let medium = Medium::start(options.medium.clone()).map_err(NetError::Medium)?;
        let mut radio = ToolRadio::connect(medium.addr(), TOOL_ADDR)?;
        let keys = if options.secured {
            let keys = KeyDir::create()?;
            // A fresh secret per bed run: the tool's counter may start at 0 (in memory).
            let mut next = 0u32;
            radio.secure(
                keys.secret.clone(),
                Box::new(move || {
                    let n = next;
                    next = (next.checked_add(1).filter(|n| *n != u32::MAX))
                        .ok_or_else(|| std::io::Error::other("the bed's counter is used up"))?;
                    Ok(n)
                }),
            );
            Some(keys)
        } else {
            None
        };
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
            keys,
        })
    }

    pub fn medium(&self) -> &Medium {
        &self.medium
    }

    pub fn radio(&mut self) -> &mut ToolRadio {
        &mut self.radio
    }

    /// The machine secret of a secured bed (tests check the nodes' answers with it).
    pub fn secret(&self) -> Option<&robot_keys::MachineSecret> {
        self.keys.as_ref().map(|k| &k.secret)
    }

    /// Starts (or restarts) the node process at `addr`. Its log goes nowhere unless
    /// `BED_NODE_LOG` is set in the environment (then to this process's stderr): for
    /// reading what a node did in a failing end-to-end test.
    pub fn start_node(&mut self, addr: u16) -> Result<(), NetError> {
        self.kill_node(addr);
        let (program, lead) = self
            .options
            .node_command
            .split_first()
            .ok_or(NetError::NoNodeCommand)?;
        let mut cmd = Process::new(program);
        cmd.args(lead)
            .arg("--addr")
            .arg(format!("{addr:#06x}"))
            .arg("--medium")
            .arg(self.medium.addr().to_string())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(if std::env::var_os("BED_NODE_LOG").is_some() {
                Stdio::inherit()
            } else {
                Stdio::null()
            });
        if let Some(dir) = &self.options.flash_dir {
            cmd.arg("--flash")
                .arg(dir.join(format!("node-{addr:04x}.flash")));
        }
        if let Some(keys) = &self.keys {
            cmd.arg("--key").arg(keys.node_key(addr)?);
        }
        let child = cmd
            .spawn()
            .map_err(|source| NetError::NodeStart { addr, source })?;
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
    pub fn set_plant(&mut self, actuators: Vec<Actuator>) -> Result<(), NetError> {
        self.set_plant_injected(actuators, None)
    }

    /// [`Bed::set_plant`], with a fault the plant injects.
    pub fn set_plant_injected(
        &mut self,
        actuators: Vec<Actuator>,
        injection: Option<Injection>,
    ) -> Result<(), NetError> {
        self.stop_plant();
        let stop = Arc::new(AtomicBool::new(false));
        let conn = live_plant::attach(self.medium.addr(), &actuators).map_err(NetError::Plant)?;
        let (tx, flag) = (self.steps_tx.clone(), stop.clone());
        let handle = std::thread::spawn(move || {
            live_plant::run_attached(conn, actuators, injection, tx, flag)
        });
        self.plant = Some((stop, handle));
        self.steps_seen = 0;
        while self.steps.try_recv().is_ok() {}
        Ok(())
    }

    /// [`Bed::set_plant`] with a sorting station's ball feed: every ball that lands is
    /// sent to the receiver returned.
    pub fn set_plant_fed(
        &mut self,
        actuators: Vec<Actuator>,
        feed: crate::live_feed::BallFeed,
    ) -> Result<Receiver<crate::live_feed::Landing>, NetError> {
        self.stop_plant();
        let stop = Arc::new(AtomicBool::new(false));
        let conn = live_plant::attach_fed(self.medium.addr(), &actuators, &feed)
            .map_err(NetError::Plant)?;
        let (tx, flag) = (self.steps_tx.clone(), stop.clone());
        let (landed_tx, landed) = mpsc::channel();
        let handle = std::thread::spawn(move || {
            let feed = (feed, std::time::Instant::now());
            live_plant::run_fed(conn, actuators, feed, landed_tx, tx, flag)
        });
        self.plant = Some((stop, handle));
        self.steps_seen = 0;
        while self.steps.try_recv().is_ok() {}
        Ok(landed)
    }

    /// [`Bed::set_plant`] with the robot's declared motors and operator inputs
    /// ([`crate::live_motor`]): the operator's requests go to the sender returned, every
    /// motion and input change comes from the receiver, on the medium's clock.
    pub fn set_plant_motors(
        &mut self,
        actuators: Vec<Actuator>,
        motors: crate::live_motor::Motors,
    ) -> Result<MotorPlant, NetError> {
        self.stop_plant();
        let stop = Arc::new(AtomicBool::new(false));
        let conn = live_plant::attach_motors(self.medium.addr(), &actuators, &motors)
            .map_err(NetError::Plant)?;
        let (tx, flag) = (self.steps_tx.clone(), stop.clone());
        let (operate, operated) = mpsc::channel();
        let (seen_tx, seen) = mpsc::channel();
        let plant = (motors, operated, seen_tx, self.medium.started());
        let handle =
            std::thread::spawn(move || live_plant::run_motors(conn, actuators, plant, tx, flag));
        self.plant = Some((stop, handle));
        self.steps_seen = 0;
        while self.steps.try_recv().is_ok() {}
        Ok((operate, seen))
    }

    /// The bed's bound on waiting (one cycle, one ball).
    pub fn timeout(&self) -> Duration {
        self.options.timeout
    }

    /// Watches the air for the faults of robot `c` (and every output level) from now on.
    pub fn watch(&mut self, c: &Compiled) -> Result<(), NetError> {
        self.watch = None;
        let w = Watch::start(
            self.medium.addr(),
            self.medium.started(),
            watch::fault_topics(c),
            self.keys
                .as_ref()
                .map(|k| Sniffer::new(Some(k.secret.clone()), Some(c.ir.generation))),
            self.seen_tx.clone(),
        )
        .map_err(NetError::Monitor)?;
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
    pub fn wait_for_nodes(&mut self, addrs: &[u16]) -> Result<BTreeMap<u16, Announce>, NetError> {
        let end = crate::deadline(Instant::now(), self.options.timeout);
        let mut found = BTreeMap::new();
        while Instant::now() < end {
            let seen = push::scan(&mut self.radio, &mut self.ids, Duration::from_millis(600))?;
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
        Err(NetError::Silent(missing))
    }

    /// Pushes every role of `c` to its node.
    pub fn push(
        &mut self,
        c: &Compiled,
        force: bool,
        progress: &mut dyn FnMut(usize, usize, usize),
    ) -> Result<Vec<push::Pushed>, NetError> {
        let mut pushed = self.stage(c, force, progress)?;
        push::switch_over(
            &mut self.radio,
            &mut pushed,
            c.ir.generation,
            false,
            push::SWITCH_WAIT,
        )?;
        Ok(pushed)
    }

    /// Stages `c`'s tables on their nodes (the first phase of a push): nothing switches.
    pub fn stage(
        &mut self,
        c: &Compiled,
        force: bool,
        progress: &mut dyn FnMut(usize, usize, usize),
    ) -> Result<Vec<push::Pushed>, NetError> {
        let targets = targets(c);
        Ok(push::push(&mut self.radio, &targets, force, progress)?)
    }

    /// Switches the nodes of `pushed` (staged with [`Bed::stage`]) over to generation
    /// `generation`, at the next idle point within `wait` or (`now`) at once.
    pub fn switch_over(
        &mut self,
        pushed: &mut [push::Pushed],
        generation: u32,
        now: bool,
        wait: std::time::Duration,
    ) -> Result<node_fw::switch::Verdict, NetError> {
        Ok(push::switch_over(
            &mut self.radio,
            pushed,
            generation,
            now,
            wait,
        )?)
    }

    /// A command to a node, resent until acknowledged.
    pub fn command(&mut self, addr: u16, command: Command) -> Result<Status, NetError> {
        push::command(
            &mut self.radio,
            &mut self.ids,
            addr,
            command,
            self.options.timeout,
        )?
        .ok_or_else(|| NetError::NoAnswer {
            addr,
            role: None,
            command: format!("{command:?}"),
        })
    }

    /// `Command::Alarms` (or, with `acknowledge`, `Command::Ack`) to every role's node of
    /// `c`: each node's alarm report, in role order.
    pub fn alarms(
        &mut self,
        c: &Compiled,
        acknowledge: bool,
    ) -> Result<Vec<AlarmReport>, NetError> {
        let command = if acknowledge {
            Command::Ack
        } else {
            Command::Alarms
        };
        home::alarms(
            &mut self.radio,
            &mut self.ids,
            c,
            command,
            self.options.timeout,
        )
    }

    /// Homes the machine of `c` (`robot_net::home::home`) and returns how it ended with
    /// the steps the plant saw since the last cycle, homing or [`Bed::strokes`] (what a
    /// START or a boot before it moved shows there too).
    pub fn home(&mut self, c: &Compiled) -> Result<Homing, NetError> {
        self.home_saying(c, &mut || {})
    }

    /// [`Bed::home`], calling `sending` once HOME is about to be sent (not for a machine
    /// refused).
    pub fn home_saying(
        &mut self,
        c: &Compiled,
        sending: &mut dyn FnMut(),
    ) -> Result<Homing, NetError> {
        let before = self.statuses(c)?;
        self.home_from(c, &before, sending)
    }

    /// [`Bed::home_saying`] from the nodes' statuses `before` (in role order), asked
    /// already ([`Bed::statuses`]).
    pub fn home_from(
        &mut self,
        c: &Compiled,
        before: &[Status],
        sending: &mut dyn FnMut(),
    ) -> Result<Homing, NetError> {
        let within = (self.options.timeout, self.options.timeout);
        let (end, took) =
            home::home_from(&mut self.radio, &mut self.ids, c, before, within, sending)?;
        let steps = self.strokes().into_iter().map(|s| s.step).collect();
        Ok(Homing { end, steps, took })
    }

    /// The strokes the plant saw since the last cycle, homing or call, without waiting.
    pub fn strokes(&mut self) -> Vec<Stroke> {
        std::iter::from_fn(|| self.steps.try_recv().ok()).collect()
    }

    /// Presses START (the command, to the role with the start input) without following
    /// the cycle: its status, as it answered the command.
    pub fn press_start(&mut self, c: &Compiled) -> Result<Status, NetError> {
        let (start_role, _) = c.ir.start.clone().ok_or(NetError::NoStart)?;
        let addr = c.ir.roles.get(start_role).ok_or(NetError::NoStart)?.address;
        self.command(addr, Command::Start)
    }

    /// Waits (at most the bed's timeout) until the plant has seen `n` more strokes; them.
    pub fn await_strokes(&mut self, n: usize) -> Result<Vec<Stroke>, NetError> {
        let end = crate::deadline(Instant::now(), self.options.timeout);
        let mut got = Vec::new();
        while got.len() < n {
            let left = end.saturating_duration_since(Instant::now());
            match self.steps.recv_timeout(left) {
                Ok(s) => got.push(s),
                Err(_) => return Err(NetError::Stalled(got.len(), n)),
            }
        }
        Ok(got)
    }

    /// Injects `fault` once the plant has seen `steps` steps.
    pub fn inject_after(&mut self, steps: usize, fault: BedFault) {
        self.pending = Some((steps, fault));
    }

    /// Presses START (the command, to the role with the start input) and follows one cycle:
    /// every step as the plant sees it (`on_step`), until the declared number of steps
    /// happened and every node is back in its idle state, or a node faults (reported
    /// as it happens, with what every node then did). The machine must be homed
    /// ([`Bed::home`]): a START on one that is not does nothing.
    pub fn run_cycle(
        &mut self,
        c: &Compiled,
        on_step: &mut dyn FnMut(&Stroke, Duration),
    ) -> Result<Cycle, NetError> {
        let expect = c.ir.expect.clone();
        let (start_role, _) = c.ir.start.clone().ok_or(NetError::NoStart)?;
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
        let mut commanded: Vec<(Stroke, bool)> = Vec::new();
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
                // A node that does not answer (`stop:ROLE` killed it) is not at rest, and
                // its peers' links to it fall into alarm: asked within 2 s, not the bed's
                // timeout.
                let answers = self.statuses_answered(c, Duration::from_secs(2))?;
                let answered: Vec<(&Status, &str)> = (answers.iter().zip(&c.ir.roles))
                    .filter_map(|(s, r)| Some((s.as_ref()?, r.name.as_str())))
                    .collect();
                faults = (answered.iter())
                    .filter_map(|(s, role)| s.fault.map(|f| (role.to_string(), f)))
                    .collect();
                // A stalled machine whose node reports a link in trouble: a radio fault
                // (not a fault state of the node: it keeps retrying).
                let link_trouble = stalled
                    .then(|| {
                        (answered.iter())
                            .find(|(s, _)| s.link_alarms | s.links_broken != 0)
                            .map(|(_, role)| (role.to_string(), 0))
                    })
                    .flatten();
                let statuses: Option<Vec<Status>> = answers.into_iter().collect();
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
                if steps.len() >= expect.len() && statuses.is_some_and(|s| at_rest(c, &s)) {
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
                .filter_map(|(role, _, node)| Some((role.clone(), node.as_ref()?.fault?)))
                .collect();
        }
        while let Ok(step) = self.steps.try_recv() {
            self.on_plant_step(&step, m0, &mut steps, &mut commanded, on_step);
        }
        let after = self.medium.stats();
        let generations = commanded
            .iter()
            .filter(|(_, moved)| *moved)
            .map(|(s, _)| s.generation)
            .collect();
        Ok(Cycle {
            steps,
            generations,
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
        step: &Stroke,
        m0: Duration,
        steps: &mut Vec<Step>,
        commanded: &mut Vec<(Stroke, bool)>,
        on_step: &mut dyn FnMut(&Stroke, Duration),
    ) {
        on_step(step, step.at.saturating_sub(m0));
        commanded.push((step.clone(), step.moved));
        if !step.moved {
            return;
        }
        steps.push(step.step.clone());
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
        commanded: &[(Stroke, bool)],
        mut outputs: Vec<(Duration, u16, u8, bool)>,
    ) -> Result<FaultReport, NetError> {
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
        let statuses = self.statuses_answered(c, Duration::from_secs(2))?;
        for ((r, table), status) in c.ir.roles.iter().zip(&c.tables).zip(statuses) {
            if let Some(s) = status.as_ref().filter(|_| r.address == addr) {
                links = links_in_trouble(c, table, s);
            }
            let node = status.map(|s| NodeAfter {
                fault: s.fault,
                outputs: s.outputs,
            });
            nodes.push((r.name.clone(), r.address, node));
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
            .find(|(s, _)| actuators.contains(&s.step.actuator.as_str()))
            .map(|(s, moved)| (s.to_string(), s.at.saturating_sub(m0), !moved));
        let code = (nodes.iter().find(|n| n.1 == addr)).and_then(|n| n.2?.fault);
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
    pub fn statuses(&mut self, c: &Compiled) -> Result<Vec<Status>, NetError> {
        home::statuses(&mut self.radio, &mut self.ids, c, self.options.timeout)
    }

    /// The status of every role's node that answers within `within` (`None`: it did not).
    fn statuses_answered(
        &mut self,
        c: &Compiled,
        within: Duration,
    ) -> Result<Vec<Option<Status>>, NetError> {
        let (radio, ids) = (&mut self.radio, &mut self.ids);
        let answers = home::ask_roles(radio, ids, c, Command::Status, within, push::status_answer)?;
        Ok(answers.into_iter().map(Result::ok).collect())
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

/// Every node back at its idle point (homed, at rest): the cycle is over.
fn at_rest(c: &Compiled, statuses: &[Status]) -> bool {
    statuses.iter().zip(&c.tables).all(|(s, t)| {
        // A node on a newer generation switched over at this idle point (a push waited
        // for it): its new engine starts in its idle states.
        s.generation > t.generation
            || s.generation == t.generation
                && s.states.len() == t.charts.len()
                && s.states
                    .iter()
                    .zip(&t.charts)
                    .all(|(st, ch)| ch.rests_in(*st))
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

/// The addresses of every physical node of the robot (spares too).
pub fn node_addrs(c: &Compiled) -> Vec<u16> {
    c.robot.nodes.iter().map(|n| n.address).collect()
}
