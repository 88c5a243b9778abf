//! The command line: one clap command tree. Only this crate knows the flags.

use std::net::SocketAddr;
use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

#[derive(Parser)]
#[command(
    name = "config-tool",
    version,
    about = "Check, compile, simulate, verify and push RON robot descriptions to generic ECC nodes"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Parse and validate a robot: every problem, with file:line:col.
    Check { robot: PathBuf },
    /// Compile a robot to one table blob per role (`DIR/ROLE.bin`).
    Compile {
        robot: PathBuf,
        #[arg(long)]
        out: PathBuf,
        /// Deployment generation written into every blob (default: the robot's
        /// `generation`, or 0).
        #[arg(long)]
        generation: Option<u32>,
    },
    /// Write each chart type as an IEC 61499-2 basic FB type (`DIR/TYPE.fbt`) and the
    /// robot as a system (`DIR/ROBOT.sys`) for Eclipse 4diac IDE (docs/iec61499-xml.md).
    #[command(name = "export-4diac")]
    Export4diac {
        robot: PathBuf,
        #[arg(long)]
        out: PathBuf,
    },
    /// Print a table blob in readable form.
    Dump { blob: PathBuf },
    /// Print each control function's matrices: M, F, m(0), x and u (docs/petri-nets.md).
    Matrix {
        robot: PathBuf,
        /// Only this function.
        #[arg(long)]
        function: Option<String>,
        /// The same as CSV.
        #[arg(long)]
        csv: bool,
    },
    /// Print a role's charts as Graphviz DOT (or SVG through `dot`).
    Diagram {
        robot: PathBuf,
        #[arg(long)]
        role: String,
        #[arg(long, value_enum, default_value = "dot")]
        format: Format,
    },
    /// Run the compiled blobs on the host interpreter with plant models, on virtual time.
    Sim(SimArgs),
    /// Explore every reachable state of the machine (charts, plant, radio) and check
    /// deadlock freedom, sequence conformance, interlocks and no double actuation.
    Verify(VerifyArgs),
    /// Run the simulated IEEE 802.15.4 medium (loopback) until interrupted.
    Medium(MediumArgs),
    /// List the nodes in range: address, firmware, generation, role (and with the robot,
    /// whether each of its nodes is homed).
    Scan {
        /// The robot whose nodes to show homed or not.
        robot: Option<PathBuf>,
        #[command(flatten)]
        at: MediumAddr,
        #[command(flatten)]
        keys: KeysArg,
    },
    /// Compile and verify a robot, then push every role to its node (or one role to a given
    /// node); nothing is sent if `verify` fails, unless --no-verify.
    Push(PushArgs),
    /// Confirm the generation on trial (`push --trial`) on every node of the robot: it
    /// stays the boot table.
    Confirm(MachineArgs),
    /// Return every node of the robot to its previous generation together, at the
    /// machine's next idle point (or --now).
    Rollback(SwitchArgs),
    /// A node's status: role, generation, chart states, outputs, fault, links, counters
    /// (and with the robot, whether the node is homed).
    Status {
        /// The robot the node plays a role of.
        robot: Option<PathBuf>,
        #[command(flatten)]
        at: MediumAddr,
        #[arg(long, value_parser = node_fw::host::parse_addr)]
        node: u16,
        #[command(flatten)]
        keys: KeysArg,
    },
    /// START (as the START button of the robot), to the node with the start input; with
    /// the robot, refused unless every node of it is homed and at rest.
    Start {
        /// The robot: START goes to its start role's node (unless --node), once every node
        /// of it is homed, at rest and not faulted.
        #[arg(required_unless_present = "node")]
        robot: Option<PathBuf>,
        #[command(flatten)]
        at: MediumAddr,
        #[arg(long, value_parser = node_fw::host::parse_addr)]
        node: Option<u16>,
        #[command(flatten)]
        keys: KeysArg,
    },
    /// Home the robot: HOME to its home role's node, which runs the homing sequence; waits
    /// until every chart of every node rests in its idle state. Refused while a node is
    /// faulted (reset first) or a cycle runs.
    Home(HomeArgs),
    /// Every node's latched alarms: level, wall time, node and role, source, whether it
    /// is acknowledged and whether its cause persists.
    Alarms {
        robot: PathBuf,
        #[command(flatten)]
        at: MediumAddr,
        /// Print them again whenever they change, until interrupted.
        #[arg(long)]
        watch: bool,
        #[command(flatten)]
        keys: KeysArg,
    },
    /// Acknowledge the alarms on every node of the robot; prints what stayed and why (a
    /// fault alarm whose cause persists stays: exit 6).
    Ack {
        robot: PathBuf,
        #[command(flatten)]
        at: MediumAddr,
        #[command(flatten)]
        keys: KeysArg,
    },
    /// Leave a fault: back to the initial state.
    Reset {
        #[command(flatten)]
        at: MediumAddr,
        #[arg(long, value_parser = node_fw::host::parse_addr)]
        node: u16,
        #[command(flatten)]
        keys: KeysArg,
    },
    /// The robot's machine (cylinders, gripper, a station's ball feed, motors) on the
    /// medium, in real time: it moves the actuators the nodes command and closes their
    /// switches; prints every step, ball and motion.
    Plant {
        robot: PathBuf,
        #[command(flatten)]
        at: MediumAddr,
    },
    /// The operator's panel: one web page of the running machine (actuator lanes, the
    /// cycle, charts, nodes, alarms) fed live from the medium, with the operator's buttons
    /// (START, STOP, RESET, ACK, HOME, CONFIRM), each offered only when the machine allows
    /// it. Loopback by default; another address needs the token printed at start-up.
    Panel {
        robot: PathBuf,
        #[command(flatten)]
        at: MediumAddr,
        /// Where the page is served.
        #[arg(long, default_value = "127.0.0.1:15480")]
        listen: SocketAddr,
        #[command(flatten)]
        keys: KeysArg,
    },
    /// A live trace of frames, events and pin changes on the medium.
    Monitor {
        #[command(flatten)]
        at: MediumAddr,
        /// Stop after this many seconds (default: run until interrupted).
        #[arg(long)]
        seconds: Option<u64>,
        /// The machine secret's key file: secured frames are shown decrypted.
        #[arg(long)]
        keys: Option<PathBuf>,
        /// A generation whose link keys to try before one is seen on the air.
        #[arg(long, requires = "keys")]
        generation: Option<u32>,
    },
    /// The whole machine on this host: medium, unconfigured nodes, plant; push, run the
    /// cycles, check them, then push a reconfiguration to the running nodes.
    Demo(DemoArgs),
    /// Run one emulated node: QEMU booting the firmware image, its UART on the medium;
    /// started by hand (Linux) it ends when the medium closes the connection, as a host
    /// node does.
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
    /// The machine's keys: its secret (`keys new`) and what to provision on each node
    /// (`keys provision`); see docs/security.md.
    Keys {
        #[command(subcommand)]
        command: KeysCommand,
    },
    /// Run one generic node in this process (what `demo` starts).
    #[command(hide = true)]
    Node(node_fw::host::Args),
}

/// `keys`' subcommands.
#[derive(Subcommand, Debug)]
pub enum KeysCommand {
    /// Create the machine secret (32 random bytes from the OS) in a key file, mode 0600.
    New {
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
        /// Replace an existing file (every node must then be provisioned again).
        #[arg(long)]
        force: bool,
    },
    /// Print what to write on a node (its address and management key) for each board, or
    /// for one.
    Provision {
        /// The machine secret's key file (`keys new`).
        #[arg(long, value_name = "FILE")]
        keys: PathBuf,
        #[arg(long, value_parser = node_fw::host::parse_addr)]
        node: u16,
        #[arg(long, value_enum)]
        board: Option<Board>,
        /// Write the host board's key file here (mode 0600) instead of printing it.
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
        /// Replace an existing --out file.
        #[arg(long, requires = "out")]
        force: bool,
    },
}

/// The boards `keys provision` knows.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Board {
    /// `node-host` / `config-tool node`: a key file.
    Host,
    /// `qemu-mps2`: QEMU loader arguments.
    Qemu,
    /// nRF52840: `nrfjprog` writes to UICR.
    Nrf52840,
}

/// `sim`'s arguments.
#[derive(Args, Debug)]
pub struct SimArgs {
    pub robot: PathBuf,
    /// Cycles to run (1 to 10,000; default 3); a sorting station runs its feed instead.
    #[arg(long, value_parser = cycles)]
    pub cycles: Option<usize>,
    /// Print every trace entry.
    #[arg(long)]
    pub trace: bool,
    /// Inject a fault: stuck:ACT, switch:ACT.end|ACT.home, stop:ROLE or
    /// link:FROM->TO, then @STEP or @CYCLE.STEP (injected just before that step).
    #[arg(long)]
    pub fault: Option<String>,
    /// Write a time diagram of the run (SVG): actuator positions, chart states, events.
    #[arg(long)]
    pub timeline: Option<PathBuf>,
    /// A sorting station's balls, front first, as colours or their first letters
    /// (`"B G O"`); default: the robot's `sorting.feed`.
    #[arg(long, conflicts_with = "random")]
    pub feed: Option<String>,
    /// A sorting station's feed of this many balls of random colours (those the sensors
    /// tell apart), from `--seed`: the same seed, the same feed.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=10_000))]
    pub random: Option<u16>,
    /// The seed of `--random`.
    #[arg(long, default_value_t = 1, requires = "random")]
    pub seed: u64,
}

/// `verify`'s arguments.
#[derive(Args, Debug)]
pub struct VerifyArgs {
    pub robot: PathBuf,
    #[command(flatten)]
    pub how: VerifyHow,
}

/// `verify`'s default bound on the states explored (also `push`'s).
pub const MAX_STATES: usize = 2_000_000;

/// How `verify` explores (`push` verifies with the defaults).
#[derive(Args, Debug, Clone, Copy)]
pub struct VerifyHow {
    /// A delivery may also fail after the link's retries (link alarm).
    #[arg(long)]
    pub lossy: bool,
    /// Assume the radio is faster than any motion or timer: nothing arrives or
    /// expires while a publication is in flight (also when the robot declares
    /// `assume_prompt_radio`).
    #[arg(long)]
    pub prompt: bool,
    /// Explore any radio delay, even if the robot declares `assume_prompt_radio`.
    #[arg(long, conflicts_with = "prompt")]
    pub any_delay: bool,
    /// The operator may press START at any time, not only when the machine is idle.
    #[arg(long)]
    pub start_anytime: bool,
    /// Stop (inconclusive) beyond this many states (at least 1).
    #[arg(long, default_value_t = MAX_STATES, value_parser = at_least_one)]
    pub max_states: usize,
    /// A sorting station: explore every colour sequence of up to this many balls (1 to
    /// 200; default 4).
    #[arg(long, value_parser = balls)]
    pub balls: Option<usize>,
    /// Declared fault contacts: explore up to this many fault pulses in a run (1 to 8;
    /// default 2), each set and released at any moment against the radio's delays.
    #[arg(long, value_parser = faults)]
    pub faults: Option<u8>,
    /// Explore only the cycle (from the machine homed) or only homing (from every start
    /// position); both without it.
    #[arg(long, value_enum)]
    pub only: Option<VerifyPart>,
}

/// One of `verify`'s two explorations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum VerifyPart {
    Cycle,
    Homing,
}

/// `--balls N`: 1 to [`robot_analysis::verify::MAX_BALLS`].
fn balls(text: &str) -> Result<usize, String> {
    let max = robot_analysis::verify::MAX_BALLS;
    match text.parse::<usize>() {
        Ok(n) if (1..=max).contains(&n) => Ok(n),
        _ => Err(format!("a number of balls from 1 to {max}")),
    }
}

/// `sim --cycles N`, `demo --cycles N`: 1 to [`robot_analysis::sim::MAX_CYCLES`].
fn cycles(text: &str) -> Result<usize, String> {
    let max = robot_analysis::sim::MAX_CYCLES;
    match text.parse::<usize>() {
        Ok(n) if (1..=max).contains(&n) => Ok(n),
        _ => Err(format!("a number of cycles from 1 to {max}")),
    }
}

/// `home --wait S`: a whole number of seconds from 1 (homing takes time).
fn homing_wait(text: &str) -> Result<u64, String> {
    match text.parse::<u64>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err("a whole number of seconds from 1 (homing takes time)".to_string()),
    }
}

/// `push --wait S`, `rollback --wait S`: a whole number of seconds from 1 (the nodes are
/// asked whether they are idle first; `--now` switches at once).
fn idle_wait(text: &str) -> Result<u64, String> {
    match text.parse::<u64>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(
            "a whole number of seconds from 1 (the nodes are asked first; --now switches at once)"
                .to_string(),
        ),
    }
}

/// `--faults N`: 1 to 8.
fn faults(text: &str) -> Result<u8, String> {
    match text.parse::<u8>() {
        Ok(n @ 1..=8) => Ok(n),
        _ => Err("a number of fault pulses from 1 to 8".to_string()),
    }
}

impl Default for VerifyHow {
    /// `verify` without options.
    fn default() -> Self {
        VerifyHow {
            lossy: false,
            prompt: false,
            any_delay: false,
            start_anytime: false,
            max_states: MAX_STATES,
            balls: None,
            faults: None,
            only: None,
        }
    }
}

/// `medium`'s arguments.
#[derive(Args, Debug)]
pub struct MediumArgs {
    #[arg(long, default_value = "127.0.0.1:15400")]
    pub listen: SocketAddr,
    /// Probability a frame is lost (per receiver).
    #[arg(long, default_value_t = 0.0, value_parser = probability, allow_negative_numbers = true)]
    pub loss: f64,
    /// Probability a frame arrives twice (1: every frame).
    #[arg(long, default_value_t = 0.0, value_parser = probability_to_one, allow_negative_numbers = true)]
    pub dup: f64,
    /// Probability a frame arrives with a flipped bit.
    #[arg(long, default_value_t = 0.0, value_parser = probability, allow_negative_numbers = true)]
    pub corrupt: f64,
    /// Extra delay per frame, uniform in A..B ms (reorders frames).
    #[arg(long, value_parser = delay_range, default_value = "0..0")]
    pub delay_ms: (u64, u64),
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write every frame on the air to this pcap (link type 195).
    #[arg(long)]
    pub pcap: Option<PathBuf>,
}

/// `push`'s arguments.
#[derive(Args, Debug)]
pub struct PushArgs {
    pub robot: PathBuf,
    #[command(flatten)]
    pub at: MediumAddr,
    /// Push only this role.
    #[arg(long)]
    pub role: Option<String>,
    /// To this node instead of the one the robot assigns (with --role; a role without
    /// peers only: to move a role, assign it in the robot and push every role).
    #[arg(long, value_parser = node_fw::host::parse_addr, requires = "role")]
    pub node: Option<u16>,
    /// Generation of the tables (default: the robot's, at least 1).
    #[arg(long)]
    pub generation: Option<u32>,
    /// Push even if the node runs the same or a newer generation.
    #[arg(long)]
    pub force: bool,
    /// Push without verifying the robot first (by default `push` runs `verify` on the
    /// whole robot and sends nothing if a property fails).
    #[arg(long)]
    pub no_verify: bool,
    /// Switch every node over at once, whatever the machine does (a stopped or faulted
    /// machine); by default the nodes switch together at the machine's next idle point.
    #[arg(long)]
    pub now: bool,
    /// Only stage the tables (checked and persisted, not running): a later `push` of the
    /// same generation switches them.
    #[arg(long, conflicts_with = "now")]
    pub stage_only: bool,
    /// How long to wait for the machine to be idle (the cycle in progress to end), seconds.
    #[arg(long, default_value_t = 60, value_parser = idle_wait)]
    pub wait: u64,
    /// Switch on trial: until `config-tool confirm`, a power cut or `config-tool rollback`
    /// returns every node to the previous generation.
    #[arg(long)]
    pub trial: bool,
    /// With --trial: stay and watch the trial for this many seconds; a node that faults
    /// rolls every node back at once, a trial not confirmed (`config-tool confirm`) by
    /// then rolls them back at the idle point.
    #[arg(long, value_name = "SECONDS", requires = "trial")]
    pub watch: Option<u64>,
    /// With --trial: watch the trial for this many cycles of the machine (with --watch:
    /// whichever ends first); not confirmed by then, every node goes back at the idle
    /// point after the last of them.
    #[arg(long, value_name = "CYCLES", requires = "trial", value_parser = clap::value_parser!(u32).range(1..))]
    pub watch_cycles: Option<u32>,
    #[command(flatten)]
    pub keys: KeysArg,
}

/// `rollback`: which machine, and how.
#[derive(Args, Debug, Clone)]
pub struct SwitchArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// At once, whatever the machine does.
    #[arg(long)]
    pub now: bool,
    /// How long to wait for the machine to be idle, seconds.
    #[arg(long, default_value_t = 60, value_parser = idle_wait)]
    pub wait: u64,
}

/// `confirm` (and `rollback`'s machine): the robot whose nodes a command addresses, where,
/// and with which keys.
#[derive(Args, Debug, Clone)]
pub struct MachineArgs {
    /// The robot whose nodes to address.
    pub robot: PathBuf,
    #[command(flatten)]
    pub at: MediumAddr,
    #[command(flatten)]
    pub keys: KeysArg,
}

/// `home`'s arguments.
#[derive(Args, Debug, Clone)]
pub struct HomeArgs {
    /// The robot to home.
    pub robot: PathBuf,
    #[command(flatten)]
    pub at: MediumAddr,
    /// How long to wait for homing to end, seconds (at least 1: homing takes time).
    #[arg(long, default_value_t = 60, value_parser = homing_wait)]
    pub wait: u64,
    #[command(flatten)]
    pub keys: KeysArg,
}

/// The machine secret that secures what a radio command sends and receives.
#[derive(Args, Debug, Clone)]
pub struct KeysArg {
    /// The machine secret's key file (`config-tool keys new`): every frame to and from the
    /// nodes is secured with their keys; the tool's frame counter is kept beside it
    /// (FILE.counter). Default: the file named by the environment variable
    /// CONFIG_TOOL_KEYS. `push` of a secured robot (the default) needs it.
    #[arg(long, value_name = "FILE")]
    pub keys: Option<PathBuf>,
}

impl MediumArgs {
    /// The medium these flags describe.
    pub fn config(self) -> medium::Config {
        medium::Config {
            listen: self.listen,
            loss: self.loss,
            dup: self.dup,
            corrupt: self.corrupt,
            delay_ms: self.delay_ms,
            seed: self.seed,
            pcap: self.pcap,
        }
    }
}

/// `demo`'s arguments.
#[derive(Args, Debug)]
pub struct DemoArgs {
    pub robot: PathBuf,
    /// Cycles to run (1 to 10,000; default 3), each checked against the simulation.
    #[arg(long, value_parser = cycles)]
    pub cycles: Option<usize>,
    /// Frame loss on the medium (with half as much duplication, and reordering).
    #[arg(long, default_value_t = 0.0, value_parser = probability, allow_negative_numbers = true)]
    pub loss: f64,
    /// The robot pushed afterwards to the same running nodes (default:
    /// paint-robot-double-dip.ron beside ROBOT, if there is one).
    #[arg(long, conflicts_with = "no_reconfigure")]
    pub then: Option<PathBuf>,
    /// Skip the reconfiguration.
    #[arg(long)]
    pub no_reconfigure: bool,
    /// Write every frame on the air to this pcap.
    #[arg(long)]
    pub pcap: Option<PathBuf>,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Run the nodes as QEMU instances (mps2-an385) booting the firmware image.
    #[arg(long)]
    pub qemu: bool,
    /// The firmware image the QEMU nodes boot (with --qemu).
    #[arg(long, default_value = robot_net::demo::QEMU_ELF, requires = "qemu")]
    pub elf: PathBuf,
    /// Count the instructions the QEMU nodes execute (`-icount shift=0`) during the
    /// first robot's cycles: instructions per cycle and per stimulus (frame or input).
    #[arg(long, requires = "qemu")]
    pub icount: bool,
    /// Inject a fault into the running machine, as `sim --fault` does: stuck:ACT or
    /// switch:ACT.end|ACT.home (the plant), stop:ROLE (the node's process is killed),
    /// link:FROM->TO (the medium cuts that link), then @STEP or @CYCLE.STEP. The demo
    /// reports the detection and exits "faulted".
    #[arg(long)]
    pub fault: Option<String>,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Format {
    Dot,
    Svg,
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

/// One QEMU node.
#[derive(Args, Debug, Clone)]
pub struct QemuNodeArgs {
    /// The firmware image (`node-fw/boards/qemu-mps2`, built with `cargo build --release`).
    #[arg(long, default_value = robot_net::demo::QEMU_ELF)]
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
    /// Its management key: the host board's key file (`keys provision --board host --out
    /// FILE`), written to the provisioning area after the word.
    #[arg(long, value_name = "FILE")]
    pub key: Option<PathBuf>,
    /// Count instructions (`-icount shift=0`): the node logs its busy time, frames and
    /// input changes every second to DIR/node-AAAA.log.
    #[arg(long, value_name = "DIR")]
    pub count: Option<PathBuf>,
    /// End (killed) when the process that started it ends, however that ends (Linux): how
    /// `demo` runs its nodes, so that none outlives an interrupted demo. The process is
    /// then QEMU itself (exec), and its parent ends it: it does not watch the medium.
    #[arg(long)]
    pub end_with_parent: bool,
}

/// A count of at least 1.
pub fn at_least_one(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!("`{s}` is not a number from 1 up")),
    }
}

/// A probability from 0 to 1, 1 included (every frame duplicated runs).
pub fn probability_to_one(s: &str) -> Result<f64, String> {
    let p: f64 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
    if (0.0..=1.0).contains(&p) {
        Ok(p)
    } else {
        Err(format!("`{s}` is not a probability from 0 to 1"))
    }
}

pub fn probability(s: &str) -> Result<f64, String> {
    let p: f64 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
    if (0.0..1.0).contains(&p) {
        Ok(p)
    } else {
        // 1 would lose (or corrupt) every frame: nothing could be run or told apart.
        Err(format!("`{s}` is not a probability from 0 to under 1"))
    }
}

/// The longest delay the medium puts on a frame: a minute (every timeout of the tool and
/// the nodes is shorter; a longer one is a typo).
const MAX_DELAY_MS: u64 = 60_000;

pub fn delay_range(s: &str) -> Result<(u64, u64), String> {
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
    if b > MAX_DELAY_MS {
        return Err(format!(
            "{b} ms is longer than a frame may be held ({MAX_DELAY_MS} ms at most)"
        ));
    }
    Ok((a, b))
}
