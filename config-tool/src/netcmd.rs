//! The commands that talk to nodes over the (simulated) radio: `medium`, `scan`, `push`,
//! `status`, `start`, `monitor`, `demo`, and the hidden `node` (one generic node in this
//! process: what `demo` starts, so a single build runs the whole machine).

use std::io::{self, Read, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use clap::{Args, Subcommand};
use config_schema::wire::mac::Frame;
use config_schema::wire::medium::{Deframer, Link, Peer, MAX_LINK};
use config_schema::wire::msg::{Command, Message, Status};
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use node_fw::ota::Progress;

use medium::Conn;
use robot_compiler::{compile, Compiled, Source};
use robot_net::demo::{self, Bed, BedFault};
use robot_net::live_plant;
use robot_net::push::{self, Ids};
use robot_net::radio::{ToolRadio, TOOL_ADDR};

/// The exit statuses of the radio commands (docs/config-tool.md).
pub mod exit {
    /// Anything else that went wrong (bad robot, no medium, nodes that never started).
    pub const ERROR: u8 = 1;
    /// A node did not activate its table (refused, or stopped answering).
    pub const PUSH_FAILED: u8 = 3;
    /// A cycle did not produce the declared sequence.
    pub const MISMATCH: u8 = 4;
    /// A node faulted (a watchdog, a peer's fault).
    pub const FAULTED: u8 = 5;
}

/// A radio command that failed: what to print, and the exit status.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct Failure {
    pub code: u8,
    pub message: String,
}

impl From<String> for Failure {
    fn from(message: String) -> Failure {
        Failure {
            code: exit::ERROR,
            message,
        }
    }
}

/// How a demo ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Every cycle matched its declared sequence.
    Matched,
    PushFailed,
    Mismatch,
    Faulted,
}

impl Verdict {
    /// The command's result.
    pub fn result(self) -> Result<(), Failure> {
        let (code, message) = match self {
            Verdict::Matched => return Ok(()),
            Verdict::PushFailed => (exit::PUSH_FAILED, "demo: the push failed"),
            Verdict::Mismatch => (
                exit::MISMATCH,
                "demo: a cycle did not match its declared sequence",
            ),
            Verdict::Faulted => (exit::FAULTED, "demo: the machine faulted"),
        };
        Err(Failure {
            code,
            message: message.into(),
        })
    }
}

/// Where the medium is.
#[derive(Args, Debug, Clone)]
pub struct MediumAddr {
    /// The medium's address (`config-tool medium --listen ...`).
    #[arg(long, default_value = "127.0.0.1:15400")]
    pub medium: SocketAddr,
    /// Reach real nodes instead: through an nRF52840 gateway on this serial port (a medium
    /// bridged to the air runs in this process, as `config-tool gateway` does).
    #[arg(long, conflicts_with = "medium")]
    pub serial: Option<PathBuf>,
    /// The gateway's baud rate (with --serial).
    #[arg(long, default_value_t = 1_000_000, requires = "serial")]
    pub baud: u32,
}

/// The radio commands.
#[derive(Subcommand, Debug)]
pub enum NetCommand {
    /// Run the simulated IEEE 802.15.4 medium (loopback) until interrupted.
    Medium {
        #[arg(long, default_value = "127.0.0.1:15400")]
        listen: SocketAddr,
        /// Probability a frame is lost (per receiver).
        #[arg(long, default_value_t = 0.0, value_parser = probability)]
        loss: f64,
        /// Probability a frame arrives twice.
        #[arg(long, default_value_t = 0.0, value_parser = probability)]
        dup: f64,
        /// Probability a frame arrives with a flipped bit.
        #[arg(long, default_value_t = 0.0, value_parser = probability)]
        corrupt: f64,
        /// Extra delay per frame, uniform in A..B ms (reorders frames).
        #[arg(long, value_parser = delay_range, default_value = "0..0")]
        delay_ms: (u64, u64),
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Write every frame on the air to this pcap (link type 195).
        #[arg(long)]
        pcap: Option<PathBuf>,
    },
    /// List the nodes in range: address, firmware, generation, role.
    Scan {
        #[command(flatten)]
        at: MediumAddr,
    },
    /// Compile a robot and push every role to its node (or one role to a given node).
    Push {
        robot: PathBuf,
        #[command(flatten)]
        at: MediumAddr,
        /// Push only this role.
        #[arg(long)]
        role: Option<String>,
        /// To this node instead of the one the robot assigns (with --role).
        #[arg(long, value_parser = node_fw::host::parse_addr, requires = "role")]
        node: Option<u16>,
        /// Generation of the tables (default: the robot's, at least 1).
        #[arg(long)]
        generation: Option<u32>,
        /// Push even if the node runs the same or a newer generation.
        #[arg(long)]
        force: bool,
    },
    /// A node's status: role, generation, chart states, outputs, fault, links, counters.
    Status {
        #[command(flatten)]
        at: MediumAddr,
        #[arg(long, value_parser = node_fw::host::parse_addr)]
        node: u16,
    },
    /// START (as the START button of the robot), to the node with the start input.
    Start {
        #[command(flatten)]
        at: MediumAddr,
        #[arg(long, value_parser = node_fw::host::parse_addr)]
        node: u16,
    },
    /// Leave a fault: back to the initial state.
    Reset {
        #[command(flatten)]
        at: MediumAddr,
        #[arg(long, value_parser = node_fw::host::parse_addr)]
        node: u16,
    },
    /// The robot's machine (cylinders, gripper) on the medium, in real time: it moves the
    /// actuators the nodes command and closes their switches; prints every step.
    Plant {
        robot: PathBuf,
        #[command(flatten)]
        at: MediumAddr,
    },
    /// A live trace of frames, events and pin changes on the medium.
    Monitor {
        #[command(flatten)]
        at: MediumAddr,
        /// Stop after this many seconds (default: run until interrupted).
        #[arg(long)]
        seconds: Option<u64>,
    },
    /// The whole machine on this host: medium, unconfigured nodes, plant; push, run the
    /// cycles, check them, then push a reconfiguration to the running nodes.
    Demo {
        robot: PathBuf,
        #[arg(long, default_value_t = 3)]
        cycles: usize,
        /// Frame loss on the medium (with half as much duplication, and reordering).
        #[arg(long, default_value_t = 0.0, value_parser = probability)]
        loss: f64,
        /// The robot pushed afterwards to the same running nodes (default:
        /// paint-robot-double-dip.ron beside ROBOT, if there is one).
        #[arg(long)]
        then: Option<PathBuf>,
        /// Skip the reconfiguration.
        #[arg(long)]
        no_reconfigure: bool,
        /// Write every frame on the air to this pcap.
        #[arg(long)]
        pcap: Option<PathBuf>,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Run the nodes as QEMU instances (mps2-an385) booting the firmware image.
        #[arg(long)]
        qemu: bool,
        /// The firmware image the QEMU nodes boot (with --qemu).
        #[arg(long, default_value = demo::QEMU_ELF, requires = "qemu")]
        elf: PathBuf,
        /// Count the instructions the QEMU nodes execute (`-icount shift=0`) during the
        /// first robot's cycles: instructions per cycle and per stimulus (frame or input).
        #[arg(long, requires = "qemu")]
        icount: bool,
        /// Inject a fault into the running machine, as `sim --fault` does: stuck:ACT or
        /// switch:ACT.end|ACT.home (the plant), stop:ROLE (the node's process is killed),
        /// then @STEP or @CYCLE.STEP. The demo reports the detection and exits "faulted".
        #[arg(long)]
        fault: Option<String>,
    },
    /// Run one emulated node: QEMU booting the firmware image, its UART on the medium.
    QemuNode(QemuNodeArgs),
    /// Run a medium whose frames also go to the air, through an nRF52840 gateway on a
    /// serial port (`nrf52840` image built with `--features gateway`): `push`, `scan`,
    /// `status`, `monitor` with `--medium` then reach the real nodes in range.
    Gateway {
        /// The gateway's serial port (the DK's J-Link virtual COM port: /dev/ttyACM0).
        #[arg(long)]
        serial: PathBuf,
        /// The baud rate (set with `stty`; the gateway's UART runs at 1 Mbaud).
        #[arg(long, default_value_t = 1_000_000)]
        baud: u32,
        #[arg(long, default_value = "127.0.0.1:15400")]
        listen: SocketAddr,
    },
    /// Run one generic node in this process (what `demo` starts).
    #[command(hide = true)]
    Node(node_fw::host::Args),
}

/// One QEMU node.
#[derive(Args, Debug, Clone)]
pub struct QemuNodeArgs {
    /// The firmware image (`node-fw/boards/qemu-mps2`, built with `cargo build --release`).
    #[arg(long, default_value = demo::QEMU_ELF)]
    pub elf: PathBuf,
    /// The QEMU program.
    #[arg(long, default_value = "qemu-system-arm")]
    pub qemu: PathBuf,
    /// The node's address, written to its provisioning word.
    #[arg(long, value_parser = node_fw::host::parse_addr)]
    pub addr: u16,
    /// The medium its UART connects to (host:port).
    #[arg(long)]
    pub medium: SocketAddr,
    /// A host file for its flash slots (created erased if missing; no comma or space).
    #[arg(long)]
    pub flash: Option<PathBuf>,
    /// Count instructions (`-icount shift=0`): the node logs its busy time, frames and
    /// input changes every second to DIR/node-AAAA.log.
    #[arg(long, value_name = "DIR")]
    pub count: Option<PathBuf>,
}

/// Checks the image is there (a clear message instead of QEMU's).
fn check_elf(elf: &Path) -> Result<(), String> {
    if elf.is_file() {
        Ok(())
    } else {
        Err(format!(
            "error: no firmware image at {}: build it with `cargo build --release` in \
             node-fw/boards/qemu-mps2 (or give --elf)",
            elf.display()
        ))
    }
}

/// Bridges a medium to the air: every frame on the medium goes to the gateway on `serial`
/// (the medium's framing), and every frame the gateway hears goes on the medium. The
/// bridge joins the medium as a monitor (it sees every frame, without the medium's loss).
fn gateway(serial: &Path, baud: u32, listen: SocketAddr) -> Result<(), String> {
    let (m, up) = bridge(serial, baud, listen)?;
    println!(
        "medium listening on {}, bridged to the air through {}",
        m.addr(),
        serial.display()
    );
    match up.join() {
        Ok(r) => r.map_err(|e| format!("error: {}: {e}", serial.display())),
        Err(_) => Err("error: the gateway bridge stopped".into()),
    }
}

/// A medium on `listen` whose frames also go to the air through the gateway on `serial`
/// (and the air's to it); returns the medium and the thread carrying the air's frames.
fn bridge(
    serial: &Path,
    baud: u32,
    listen: SocketAddr,
) -> Result<(medium::Medium, std::thread::JoinHandle<io::Result<()>>), String> {
    if serial.to_str().is_some_and(|p| p.starts_with("/dev/tty")) {
        let status = std::process::Command::new("stty")
            .arg("-F")
            .arg(serial)
            .args([baud.to_string().as_str(), "raw", "-echo"])
            .status()
            .map_err(|e| format!("error: stty: {e}"))?;
        if !status.success() {
            return Err(format!(
                "error: stty -F {} {baud} raw: {status}",
                serial.display()
            ));
        }
    }
    let port = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(serial)
        .map_err(|e| format!("error: {}: {e}", serial.display()))?;
    let m = medium::Medium::start(medium::Config {
        listen,
        ..medium::Config::default()
    })
    .map_err(|e| format!("error: medium on {listen}: {e}"))?;
    let conn = Conn::join(m.addr(), Peer::Monitor).map_err(|e| e.to_string())?;
    let stream = conn.try_clone_stream().map_err(|e| e.to_string())?;
    let to_air = port.try_clone().map_err(|e| e.to_string())?;
    let from_medium = stream.try_clone().map_err(|e| e.to_string())?;
    // Medium -> air and air -> medium, each in its own thread; frames only.
    std::thread::spawn(move || forward_frames(from_medium, to_air));
    let up = std::thread::spawn(move || forward_frames(port, stream));
    Ok((m, up))
}

/// Copies the `Link::Frame` messages of `from` to `to` until `from` ends.
fn forward_frames(mut from: impl Read, mut to: impl Write) -> io::Result<()> {
    let mut incoming = Box::new(Deframer::<{ 8 * MAX_LINK }>::new());
    let mut out = [0u8; MAX_LINK];
    loop {
        let n = from.read(incoming.space())?;
        if n == 0 {
            return Ok(());
        }
        incoming.filled(n);
        loop {
            let body = match incoming.take() {
                Ok(Some(body)) => body,
                Ok(None) => break,
                // Longer than any message (noise on a serial line): skipped.
                Err(_) => continue,
            };
            if let Ok(Link::Frame(psdu)) = Link::parse(body) {
                if let Ok(m) = Link::Frame(psdu).emit(&mut out) {
                    to.write_all(&out[..m])?;
                }
            }
        }
    }
}

/// Checks QEMU runs (a clear message now instead of nodes that never answer).
fn check_qemu() -> Result<(), String> {
    match std::process::Command::new("qemu-system-arm")
        .arg("--version")
        .stdout(std::process::Stdio::null())
        .status()
    {
        Ok(s) if s.success() => Ok(()),
        Ok(s) => Err(format!("error: qemu-system-arm --version: {s}")),
        Err(e) => Err(format!(
            "error: cannot run qemu-system-arm: {e} (Debian: apt-get install qemu-system-arm)"
        )),
    }
}

/// Becomes QEMU (exec), so whoever started this process stops the node by stopping it.
fn qemu_node(a: QemuNodeArgs) -> Result<(), String> {
    check_elf(&a.elf)?;
    let args = demo::qemu_args(
        &a.elf,
        a.addr,
        a.medium,
        a.flash.as_deref(),
        a.count.as_deref(),
    )?;
    let mut cmd = std::process::Command::new(&a.qemu);
    cmd.args(&args);
    let failed = |e: io::Error| {
        format!(
            "error: cannot run {}: {e} (Debian: apt-get install qemu-system-arm)",
            a.qemu.display()
        )
    };
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        Err(failed(cmd.exec()))
    }
    #[cfg(not(unix))]
    {
        let status = cmd.status().map_err(failed)?;
        if status.success() {
            Ok(())
        } else {
            Err(format!("qemu: {status}"))
        }
    }
}

fn probability(s: &str) -> Result<f64, String> {
    let p: f64 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
    if (0.0..=1.0).contains(&p) {
        Ok(p)
    } else {
        Err(format!("`{s}` is not a probability in 0..1"))
    }
}

fn delay_range(s: &str) -> Result<(u64, u64), String> {
    let (a, b) = s
        .split_once("..")
        .ok_or_else(|| format!("`{s}` is not a range A..B (ms)"))?;
    let a: u64 = a
        .trim()
        .parse()
        .map_err(|_| format!("`{a}` is not a number of ms"))?;
    let b: u64 = b
        .trim()
        .parse()
        .map_err(|_| format!("`{b}` is not a number of ms"))?;
    if a > b {
        return Err(format!("the range {a}..{b} is empty"));
    }
    Ok((a, b))
}

fn load(path: &Path) -> Result<Compiled, String> {
    let src = Source::read(path)?;
    compile::compile(&src).map_err(|diags| {
        let errors: Vec<crate::Diagnostic> = diags.into_iter().filter(|d| d.is_error()).collect();
        format!(
            "{}{}: does not compile",
            robot_compiler::diag::render_all(&src, &errors, false),
            src.name
        )
    })
}

/// The generation to push: the robot's, at least 1 (an unconfigured node runs 0).
fn generation_of(c: Compiled, generation: Option<u32>) -> Result<Compiled, String> {
    let g = generation.unwrap_or(c.ir.generation).max(1);
    c.with_generation(g)
}

/// The medium to talk to: the one at `--medium`, or with `--serial` one bridged to the air
/// started here (it lives as long as the command).
fn resolve(at: &MediumAddr) -> Result<SocketAddr, String> {
    match &at.serial {
        None => Ok(at.medium),
        Some(serial) => {
            let (m, _) = bridge(serial, at.baud, SocketAddr::from(([127, 0, 0, 1], 0)))?;
            let addr = m.addr();
            std::mem::forget(m);
            Ok(addr)
        }
    }
}

fn connect(at: &MediumAddr) -> Result<ToolRadio, String> {
    let medium = resolve(at)?;
    ToolRadio::connect(medium, TOOL_ADDR)
        .map_err(|e| format!("error: cannot reach the medium at {medium}: {e}"))
}

/// Runs a radio command.
pub fn run(cmd: NetCommand) -> Result<(), Failure> {
    match cmd {
        NetCommand::Medium {
            listen,
            loss,
            dup,
            corrupt,
            delay_ms,
            seed,
            pcap,
        } => {
            let m = medium::Medium::start(medium::Config {
                listen,
                loss,
                dup,
                corrupt,
                delay_ms,
                seed,
                pcap,
            })
            .map_err(|e| format!("error: medium on {listen}: {e}"))?;
            println!("medium listening on {}", m.addr());
            loop {
                std::thread::sleep(Duration::from_secs(3600));
            }
        }
        NetCommand::Scan { at } => {
            let mut radio = connect(&at)?;
            let found = push::scan(&mut radio, &mut Ids::default(), Duration::from_secs(2))
                .map_err(|e| e.to_string())?;
            for (addr, a) in &found {
                let role = if a.role.is_empty() {
                    "(unconfigured)"
                } else {
                    a.role.as_str()
                };
                println!(
                    "{addr:#06x}  firmware {}  generation {}  {role}",
                    a.firmware, a.generation
                );
            }
            println!("{} node(s)", found.len());
            Ok(())
        }
        NetCommand::Push {
            robot,
            at,
            role,
            node,
            generation,
            force,
        } => {
            let c = generation_of(load(&robot)?, generation)?;
            let mut targets = demo::targets(&c);
            if let Some(role) = &role {
                targets.retain(|t| &t.role == role);
                if targets.is_empty() {
                    return Err(format!("error: {} has no role {role}", robot.display()).into());
                }
                if let Some(addr) = node {
                    targets[0].addr = addr;
                }
            }
            let mut radio = connect(&at)?;
            let outcomes = push_with_bars(&mut radio, &targets, force)?;
            report_push(&outcomes).map_err(|message| Failure {
                code: exit::PUSH_FAILED,
                message,
            })
        }
        NetCommand::Status { at, node } => {
            let mut radio = connect(&at)?;
            let s = command(&mut radio, node, Command::Status)?;
            println!("{}", status_text(node, &s));
            Ok(())
        }
        NetCommand::Start { at, node } => Ok(order(&at, node, Command::Start, "started")?),
        NetCommand::Reset { at, node } => {
            let mut radio = connect(&at)?;
            let s = command(&mut radio, node, Command::Reset)?;
            println!("{}", reset_text(node, &s));
            Ok(())
        }
        NetCommand::Plant { robot, at } => {
            let c = load(&robot)?;
            let actuators = live_plant::actuators(&c)?;
            for a in &actuators {
                println!(
                    "{:<4} on node {:#06x}: valves {:?}, home {:?}, end {:?}",
                    a.name, a.addr, a.valves, a.home, a.end
                );
            }
            let (tx, rx) = std::sync::mpsc::channel();
            let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
            if at.serial.is_some() {
                return Err(String::from(
                    "error: the plant is the simulated machine: it needs a medium, not --serial",
                )
                .into());
            }
            let medium = at.medium;
            let handle = std::thread::spawn(move || live_plant::run(medium, actuators, tx, stop));
            for step in rx {
                println!("{:>9.3}  {step}", step.at.as_secs_f64());
            }
            match handle.join() {
                Ok(Ok(())) => Ok(()),
                Ok(Err(e)) => Err(format!("error: plant on {medium}: {e}").into()),
                Err(_) => Err(String::from("error: the plant stopped").into()),
            }
        }
        NetCommand::Monitor { at, seconds } => Ok(monitor(&at, seconds.map(Duration::from_secs))?),
        NetCommand::Demo {
            robot,
            cycles,
            loss,
            then,
            no_reconfigure,
            pcap,
            seed,
            qemu,
            elf,
            icount,
            fault,
        } => {
            let fault = fault
                .as_deref()
                .map(robot_analysis::inject::parse)
                .transpose()
                .map_err(|e| e.to_string())?;
            let count_dir = if icount {
                let dir =
                    std::env::temp_dir().join(format!("config-tool-icount-{}", std::process::id()));
                std::fs::create_dir_all(&dir)
                    .map_err(|e| format!("error: {}: {e}", dir.display()))?;
                Some(dir)
            } else {
                None
            };
            let then = match (no_reconfigure, then) {
                (true, _) => None,
                (false, Some(p)) => Some(p),
                (false, None) => {
                    let p = robot.with_file_name("paint-robot-double-dip.ron");
                    (p.exists() && p != robot).then_some(p)
                }
            };
            let exe = std::env::current_exe().map_err(|e| e.to_string())?;
            let options = demo::Options {
                medium: medium::Config {
                    loss,
                    dup: loss / 2.0,
                    delay_ms: if loss > 0.0 { (0, 8) } else { (0, 0) },
                    seed,
                    pcap,
                    ..medium::Config::default()
                },
                node_command: if qemu {
                    check_elf(&elf)?;
                    check_qemu()?;
                    let elf = std::path::absolute(&elf).map_err(|e| e.to_string())?;
                    let mut cmd = vec![
                        exe.into_os_string(),
                        "qemu-node".into(),
                        "--elf".into(),
                        elf.into_os_string(),
                    ];
                    if let Some(dir) = &count_dir {
                        cmd.extend(["--count".into(), dir.clone().into_os_string()]);
                    }
                    cmd
                } else {
                    vec![exe.into_os_string(), "node".into()]
                },
                flash_dir: None,
                timeout: Duration::from_secs(60),
            };
            let verdict = run_demo(
                &Demo {
                    robot: &robot,
                    then: then.as_deref(),
                    cycles,
                    fault,
                    count_dir: count_dir.as_deref(),
                },
                options,
                &mut io::stdout(),
            );
            if let Some(dir) = &count_dir {
                let _ = std::fs::remove_dir_all(dir);
            }
            verdict?.result()
        }
        NetCommand::QemuNode(args) => Ok(qemu_node(args)?),
        NetCommand::Gateway {
            serial,
            baud,
            listen,
        } => Ok(gateway(&serial, baud, listen)?),
        NetCommand::Node(args) => {
            node_fw::host::run(args).map_err(|e| Failure::from(format!("node: {e}")))
        }
    }
}

/// Sends a command that changes the node and says it was done.
fn order(at: &MediumAddr, node: u16, cmd: Command, done: &str) -> Result<(), String> {
    let mut radio = connect(at)?;
    command(&mut radio, node, cmd)?;
    println!("{node:#06x}: {done}");
    Ok(())
}

fn command(radio: &mut ToolRadio, node: u16, cmd: Command) -> Result<Status, String> {
    push::command(
        radio,
        &mut Ids::default(),
        node,
        cmd,
        Duration::from_secs(5),
    )
    .map_err(|e| e.to_string())?
    .ok_or_else(|| format!("error: node {node:#06x} did not answer"))
}

/// A status in readable form.
pub fn status_text(addr: u16, s: &Status) -> String {
    let role = if s.role.is_empty() {
        "(unconfigured)"
    } else {
        s.role.as_str()
    };
    let states: Vec<String> = s.states.iter().map(|x| format!("S{x}")).collect();
    let (c, r) = (s.counters, s.runtime);
    format!(
        "{addr:#06x}  role {role}  generation {}\n  states {}  outputs {:#06x}  inputs {:#06x}  fault {}\n  link alarms {:#010b}  broken {:#010b}  epoch {}\n  frames sent {} received {} retried {} dropped {}  events delivered {}\n  tx queue full {}  high-water {}  radio failures {}  flash failures {}",
        s.generation,
        if states.is_empty() { "-".to_string() } else { states.join(" ") },
        s.outputs,
        s.inputs,
        s.fault.map_or("none".to_string(), |f| format!("{f:#04x}")),
        s.link_alarms,
        s.links_broken,
        s.epoch,
        c.sent,
        c.received,
        c.retried,
        c.dropped,
        c.delivered,
        r.tx_queue_full,
        r.tx_queue_high,
        r.tx_failed,
        r.flash_failures,
    )
}

/// The answer to `reset`: which links the node re-established (in which epoch).
pub fn reset_text(addr: u16, s: &Status) -> String {
    let peers: Vec<String> = (0..8)
        .filter(|i| s.links_restarted & (1 << i) != 0)
        .map(|i| format!("#{i}"))
        .collect();
    let links = if peers.is_empty() {
        "no link needed re-establishing".to_string()
    } else {
        format!(
            "links to peer {} re-established in epoch {}",
            peers.join(" "),
            s.epoch
        )
    };
    format!("{addr:#06x}: reset; {links}")
}

fn bars(targets: &[push::Target]) -> (MultiProgress, Vec<ProgressBar>) {
    let multi = MultiProgress::new();
    let style = ProgressStyle::with_template("{prefix:>8} [{bar:30}] {pos:>5}/{len} bytes {msg}")
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
    let bars = targets
        .iter()
        .map(|t| {
            let b = multi.add(ProgressBar::new(t.blob.len() as u64));
            b.set_style(style.clone());
            b.set_prefix(format!("{} {:#06x}", t.role, t.addr));
            b
        })
        .collect();
    (multi, bars)
}

fn push_with_bars(
    radio: &mut ToolRadio,
    targets: &[push::Target],
    force: bool,
) -> Result<Vec<push::Outcome>, String> {
    let (_multi, bars) = bars(targets);
    let outcomes = push::push(radio, targets, force, &mut |i, acked, _| {
        if let Some(b) = bars.get(i) {
            b.set_position(acked as u64);
        }
    })
    .map_err(|e| e.to_string())?;
    for (b, o) in bars.iter().zip(&outcomes) {
        b.finish_with_message(o.verdict());
    }
    Ok(outcomes)
}

fn report_push(outcomes: &[push::Outcome]) -> Result<(), String> {
    for o in outcomes {
        println!("{}", demo::push_line(o));
    }
    let (bytes, frames, retries) = outcomes.iter().fold((0, 0, 0), |a, o| {
        (a.0 + o.bytes, a.1 + o.stats.frames, a.2 + o.stats.retries)
    });
    let time = outcomes.iter().map(|o| o.elapsed).max().unwrap_or_default();
    println!(
        "pushed {} table(s): {bytes} bytes, {frames} frames, {retries} retries, {:.1} ms",
        outcomes.len(),
        time.as_secs_f64() * 1e3
    );
    if outcomes.iter().all(|o| o.progress == Progress::Done) {
        Ok(())
    } else {
        Err("error: not every node activated its table".into())
    }
}

/// What `demo` runs.
pub struct Demo<'a> {
    pub robot: &'a Path,
    /// The robot pushed afterwards to the running nodes (one cycle).
    pub then: Option<&'a Path>,
    pub cycles: usize,
    /// A fault injected into the first robot's run.
    pub fault: Option<robot_analysis::inject::FaultSpec>,
    /// Where counting QEMU nodes log (`--icount`).
    pub count_dir: Option<&'a Path>,
}

/// Where a `--fault` goes on the test bed: the plant's injection, or the bed's fault to
/// inject after so many steps.
type Placed = (Option<live_plant::Injection>, Option<(usize, BedFault)>);

fn place_fault(
    c: &Compiled,
    actuators: &[live_plant::Actuator],
    spec: &robot_analysis::inject::FaultSpec,
) -> Result<Placed, String> {
    use robot_analysis::inject::FaultKind;
    let after = (spec.cycle - 1) * c.ir.expect.len() + (spec.step - 1);
    let actuator = |name: &str| {
        actuators
            .iter()
            .position(|a| a.name == name)
            .ok_or_else(|| format!("error: --fault: the robot has no actuator {name}"))
    };
    let address = |role: &str| {
        c.ir.roles
            .iter()
            .find(|r| r.name == role)
            .map(|r| r.address)
            .ok_or_else(|| format!("error: --fault: the robot has no role {role}"))
    };
    match &spec.kind {
        FaultKind::Stuck(name) => Ok((
            Some(live_plant::Injection {
                after,
                actuator: actuator(name)?,
                kind: live_plant::Jam::Stuck,
            }),
            None,
        )),
        FaultKind::Switch(target) => {
            let (name, end) = match target.rsplit_once('.') {
                Some((n, "end")) => (n, true),
                Some((n, "home")) => (n, false),
                _ => {
                    return Err(format!(
                        "error: --fault: `{target}`: a switch is ACT.end or ACT.home"
                    ))
                }
            };
            Ok((
                Some(live_plant::Injection {
                    after,
                    actuator: actuator(name)?,
                    kind: live_plant::Jam::SwitchOpen { end },
                }),
                None,
            ))
        }
        FaultKind::Stop(role) => Ok((None, Some((after, BedFault::Stop(address(role)?))))),
        FaultKind::Link(from, to) => {
            let fault = BedFault::Cut {
                from: address(from)?,
                to: address(to)?,
            };
            Ok((None, Some((after, fault))))
        }
    }
}

/// The demo: pushes, runs the cycles, reports each; says how it ended.
pub fn run_demo(
    demo: &Demo,
    options: demo::Options,
    out: &mut dyn Write,
) -> Result<Verdict, String> {
    let c = generation_of(load(demo.robot)?, None)?;
    let next = match demo.then {
        Some(p) => Some(generation_of(load(p)?, Some(c.ir.generation + 1))?),
        None => None,
    };
    let first_actuators = live_plant::actuators(&c)?;
    let placed = demo
        .fault
        .as_ref()
        .map(|f| place_fault(&c, &first_actuators, f))
        .transpose()?;
    let mut bed = Bed::start(options)?;
    let addrs = demo::node_addrs(&c);
    demo::say(
        out,
        &format!(
            "medium on {}; starting {} unconfigured node(s)",
            bed.medium().addr(),
            addrs.len()
        ),
    );
    for a in &addrs {
        bed.start_node(*a)?;
    }
    bed.set_plant(first_actuators)?;
    let found = bed.wait_for_nodes(&addrs)?;
    for (addr, a) in &found {
        let role = if a.role.is_empty() {
            "unconfigured"
        } else {
            a.role.as_str()
        };
        demo::say(
            out,
            &format!("  node {addr:#06x}: firmware {}, {role}", a.firmware),
        );
    }
    let mut verdict = Verdict::Matched;
    let mut first_robot = true;
    let runs = [(demo.robot, &c, demo.cycles)].into_iter().chain(
        next.as_ref()
            .map(|n| (demo.then.unwrap_or(demo.robot), n, 1)),
    );
    'robots: for (label, robot, n) in runs {
        demo::say(
            out,
            &format!(
                "pushing {} (generation {})",
                label.display(),
                robot.ir.generation
            ),
        );
        let outcomes = bed.push(robot, false, &mut |_, _, _| {})?;
        for o in &outcomes {
            demo::say(out, &demo::push_line(o));
        }
        let failed: Vec<&push::Outcome> = outcomes
            .iter()
            .filter(|o| o.progress != Progress::Done)
            .collect();
        if !failed.is_empty() {
            for o in failed {
                demo::say(
                    out,
                    &format!(
                        "push FAILED: role {} at node {:#06x}: {}",
                        o.role,
                        o.addr,
                        o.verdict()
                    ),
                );
            }
            verdict = Verdict::PushFailed;
            break;
        }
        let activated = Instant::now();
        let (injection, kill) = match (&placed, first_robot) {
            (Some(p), true) => *p,
            _ => (None, None),
        };
        bed.set_plant_injected(live_plant::actuators(robot)?, injection)?;
        bed.watch(robot)?;
        if let Some((after, fault)) = kill {
            bed.inject_after(after, fault);
        }
        if let Some(spec) = demo.fault.as_ref().filter(|_| first_robot) {
            demo::say(out, &format!("fault to inject: {spec}"));
        }
        let expect: Vec<String> = robot.ir.expect.iter().map(|s| s.to_string()).collect();
        demo::say(out, &format!("sequence: {}", expect.join(" ")));
        let mut first_motion = None;
        let counted = match demo.count_dir {
            Some(dir) if first_robot => Some((dir, settled_counts(dir, &addrs))),
            _ => None,
        };
        first_robot = false;
        for i in 1..=n {
            let cycle = bed.run_cycle(robot, &mut |s, at| {
                if s.moved {
                    first_motion.get_or_insert_with(|| activated.elapsed());
                }
                let jammed = if s.moved { "" } else { "  (jammed: no motion)" };
                let _ = writeln!(io::stderr(), "  {:>7.3} s  {s}{jammed}", at.as_secs_f64());
            })?;
            demo::say(out, &demo::cycle_line(i, &cycle));
            if let (1, Some(t), None) = (i, first_motion, &counted) {
                demo::say(
                    out,
                    &format!(
                        "first motion {:.1} ms after the last table was activated (START \
                         included)",
                        t.as_secs_f64() * 1e3
                    ),
                );
            }
            if !cycle.ok() {
                verdict = if cycle.fault.is_some() {
                    Verdict::Faulted
                } else {
                    Verdict::Mismatch
                };
                break 'robots;
            }
        }
        if let Some((dir, before)) = counted {
            let after = settled_counts(dir, &addrs);
            for line in count_lines(&addrs, &before, &after, n) {
                demo::say(out, &line);
            }
        }
    }
    let s = bed.medium().stats();
    demo::say(
        out,
        &format!(
            "medium: {} frames, {:.1} ms airtime, {} lost, {} duplicated",
            s.frames,
            s.airtime_us as f64 / 1e3,
            s.lost,
            s.duplicated
        ),
    );
    bed.stop();
    demo::say(
        out,
        match verdict {
            Verdict::Matched => "demo: every cycle matched",
            Verdict::PushFailed => "demo: FAILED (push)",
            Verdict::Mismatch => "demo: FAILED (sequence mismatch)",
            Verdict::Faulted => "demo: FAULTED",
        },
    );
    Ok(verdict)
}

/// Every node's counts once they stop changing (the nodes log every second).
fn settled_counts(dir: &Path, addrs: &[u16]) -> Vec<Option<demo::Counts>> {
    let read = || -> Vec<Option<demo::Counts>> {
        addrs.iter().map(|a| demo::read_counts(dir, *a)).collect()
    };
    let mut last = read();
    for _ in 0..10 {
        std::thread::sleep(Duration::from_millis(1200));
        let now = read();
        if now == last {
            break;
        }
        last = now;
    }
    last
}

/// Instructions per node over `cycles` cycles, per cycle and per stimulus.
fn count_lines(
    addrs: &[u16],
    before: &[Option<demo::Counts>],
    after: &[Option<demo::Counts>],
    cycles: usize,
) -> Vec<String> {
    let mut lines = vec![format!(
        "instructions executed during the {cycles} cycle(s) (QEMU -icount shift=0):"
    )];
    let mut total = demo::Counts::default();
    for ((a, b), e) in addrs.iter().zip(before).zip(after) {
        let (Some(b), Some(e)) = (b, e) else {
            lines.push(format!("  node {a:#06x}: no counts"));
            continue;
        };
        let d = demo::Counts {
            instructions: e.instructions.saturating_sub(b.instructions),
            frames: e.frames.saturating_sub(b.frames),
            pins: e.pins.saturating_sub(b.pins),
            changes: e.changes.saturating_sub(b.changes),
            core_frame: e.core_frame.saturating_sub(b.core_frame),
            core_frames: e.core_frames.saturating_sub(b.core_frames),
            core_input: e.core_input.saturating_sub(b.core_input),
            core_inputs: e.core_inputs.saturating_sub(b.core_inputs),
        };
        total.instructions += d.instructions;
        total.frames += d.frames;
        total.pins += d.pins;
        total.changes += d.changes;
        total.core_frame += d.core_frame;
        total.core_frames += d.core_frames;
        total.core_input += d.core_input;
        total.core_inputs += d.core_inputs;
        lines.push(count_line(&format!("node {a:#06x}"), &d, cycles));
    }
    lines.push(count_line("all nodes  ", &total, cycles));
    lines
}

fn count_line(who: &str, d: &demo::Counts, cycles: usize) -> String {
    // A stimulus is what the node must react to: a frame, or an input that changed (the
    // plant's repeated levels cost instructions too, but are not events).
    let stimuli = d.frames + d.changes;
    format!(
        "  {who}: {:>9} instructions, {:>8.0} per cycle; {:>4} frames + {:>3} input changes \
         ({:>3} level messages): {:>6.0} per stimulus",
        d.instructions,
        d.instructions as f64 / cycles.max(1) as f64,
        d.frames,
        d.changes,
        d.pins,
        d.instructions as f64 / stimuli.max(1) as f64
    ) + &format!(
        "\n  {:w$}  of which in the node core: {:>6.0} per frame, {:>5.0} per level message",
        "",
        d.core_frame as f64 / d.core_frames.max(1) as f64,
        d.core_input as f64 / d.core_inputs.max(1) as f64,
        w = who.len()
    )
}

/// Prints every frame (decoded) and pin change on the medium. Pin changes carry the
/// medium's time; frames the time they reached the monitor (on the same clock once the
/// first pin change is seen, else since the monitor joined).
fn monitor(at: &MediumAddr, for_: Option<Duration>) -> Result<(), String> {
    let medium = resolve(at)?;
    let mut conn = Conn::join(medium, Peer::Monitor)
        .map_err(|e| format!("error: cannot reach the medium at {medium}: {e}"))?;
    let start = Instant::now();
    let end = for_.map(|d| start + d);
    loop {
        let until = end.unwrap_or_else(|| Instant::now() + Duration::from_secs(3600));
        let got = conn.recv(until, |link| {
            let t = start.elapsed().as_secs_f64();
            match link {
                Link::Frame(psdu) => Some(format!("{t:>9.3}  {}", describe(psdu))),
                Link::Seen {
                    at_us,
                    addr,
                    pin,
                    level,
                    output,
                } => Some(format!(
                    "{:>9.3}  pin {addr:#06x}.{pin} = {} ({})",
                    at_us as f64 / 1e6,
                    u8::from(level),
                    if output { "output" } else { "input" }
                )),
                _ => None,
            }
        });
        match got {
            Ok(Some(line)) => println!("{line}"),
            Ok(None) if end.is_some_and(|e| Instant::now() >= e) => return Ok(()),
            Ok(None) => {}
            Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => return Ok(()),
            Err(e) => return Err(format!("error: monitor: {e}")),
        }
    }
}

/// One frame in readable form.
pub fn describe(psdu: &[u8]) -> String {
    match Frame::parse(psdu) {
        Ok(Frame::Data { header, payload }) => {
            let msg = match Message::parse(payload) {
                Ok(Message::ConfigChunk {
                    generation,
                    offset,
                    data,
                }) => format!(
                    "ConfigChunk {{ generation: {generation}, offset: {offset}, {} bytes }}",
                    data.len()
                ),
                Ok(m) => format!("{m:?}"),
                Err(e) => format!("({e})"),
            };
            format!("{:#06x} -> {:#06x}  {msg}", header.src, header.dst)
        }
        Ok(Frame::Ack { seq, .. }) => format!("ack {seq}"),
        Err(e) => format!("bad frame ({e}), {} bytes", psdu.len()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use config_schema::wire::msg::{Counters, Refusal, RuntimeCounters};
    use node_fw::ota::TransferStats;

    fn status() -> Status {
        Status {
            ack: 9,
            role: heapless::String::try_from("GR").unwrap(),
            generation: 3,
            states: heapless::Vec::from_slice(&[2, 0]).unwrap(),
            outputs: 0x0002,
            inputs: 0x0001,
            fault: None,
            link_alarms: 0b100,
            links_broken: 0b001,
            links_restarted: 0,
            epoch: 257,
            counters: Counters {
                sent: 19,
                received: 36,
                retried: 4,
                dropped: 1,
                delivered: 2,
            },
            runtime: RuntimeCounters {
                tx_queue_full: 5,
                tx_queue_high: 32,
                tx_failed: 1,
                flash_failures: 2,
            },
        }
    }

    #[test]
    fn status_tells_an_alarm_from_a_broken_link_and_shows_the_runtime_counters() {
        assert_eq!(
            status_text(0x0013, &status()),
            "0x0013  role GR  generation 3\n  \
             states S2 S0  outputs 0x0002  inputs 0x0001  fault none\n  \
             link alarms 0b00000100  broken 0b00000001  epoch 257\n  \
             frames sent 19 received 36 retried 4 dropped 1  events delivered 2\n  \
             tx queue full 5  high-water 32  radio failures 1  flash failures 2"
        );
    }

    #[test]
    fn reset_says_which_links_it_re_established() {
        let mut s = status();
        s.links_broken = 0;
        s.link_alarms = 0;
        assert_eq!(
            reset_text(0x0013, &s),
            "0x0013: reset; no link needed re-establishing"
        );
        s.links_restarted = 0b101;
        s.epoch = 258;
        assert_eq!(
            reset_text(0x0013, &s),
            "0x0013: reset; links to peer #0 #2 re-established in epoch 258"
        );
    }

    #[test]
    fn push_prints_the_nodes_refusal_reason() {
        let o = push::Outcome {
            role: "VC".into(),
            addr: 0x0011,
            progress: Progress::Refused(Refusal::Pin {
                pin: 20,
                board: 0xFFFF,
            }),
            stats: TransferStats {
                frames: 5,
                retries: 0,
                bytes: 274,
            },
            bytes: 274,
            elapsed: Duration::from_micros(46_100),
        };
        assert_eq!(
            demo::push_line(&o),
            "  VC     0x0011    274 bytes    5 frames    0 retries    46.1 ms  \
             refused: the table uses pin 20, which the board lacks (its pins: 0-15)"
        );
        let done = push::Outcome {
            progress: Progress::Done,
            ..o
        };
        assert_eq!(done.verdict(), "activated");
    }
}
