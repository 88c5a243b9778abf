//! The host board: one generic node on Embassy's std executor, whose radio and pins are a
//! connection to the simulated medium ([`medium`]) and whose flash is a file ([`flash`]).
//!
//! `node-host` is [`Args`] + [`run`]; `config-tool` can run nodes in-process the same way
//! (one thread per node: [`run`] blocks until the medium closes the connection).

pub mod flash;
pub mod key;
pub mod medium;

use std::cell::RefCell;
use std::future::Future;
use std::net::{SocketAddr, TcpStream};
use std::path::PathBuf;
use std::rc::Rc;
use std::sync::atomic::Ordering;
use std::time::{SystemTime, UNIX_EPOCH};

use embassy_executor::raw::TaskStorage;
use embassy_executor::Executor;
use log::{info, warn, LevelFilter, Log, Metadata, Record};

use crate::provision::ManagementKey;
use crate::runtime::{self, Board, Stats, Stop};
use flash::{HostFlash, OpenError};
use medium::{Closed, Connection};

/// `node-host`'s command line.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    name = "node-host",
    version,
    about = "One generic node on the host: its radio and pins are a connection to the \
             simulated 802.15.4 medium, its table slots a file"
)]
pub struct Args {
    /// The node's 16-bit short address (hex with 0x, or decimal; not 0xFFFE or 0xFFFF, nor
    /// config-tool's own 0x0100).
    #[arg(long, value_parser = parse_addr)]
    pub addr: u16,
    /// The medium to connect to (host:port).
    #[arg(long)]
    pub medium: SocketAddr,
    /// The flash file with the two table slots and the boot counter (created erased if
    /// missing; one node process at a time). With a key, the frame counter is in
    /// FILE.counter beside it: move or restore the two together (a counter file started
    /// afresh numbers frames from 0 again under the same key). Without it the slots are in
    /// RAM and the node boots unconfigured.
    #[arg(long)]
    pub flash: Option<PathBuf>,
    /// The node's management key file (`config-tool keys provision --board host --out
    /// FILE`; mode 0600, for this address). With it, every frame on the config PAN is
    /// secured (ENC-MIC-64) and the tool's frames are taken only secured with it.
    #[arg(long, value_name = "FILE")]
    pub key: Option<PathBuf>,
}

/// What the node runs with: its arguments, the provisioned key read and checked.
#[derive(Debug)]
pub struct Config {
    pub addr: u16,
    pub medium: SocketAddr,
    pub flash: Option<PathBuf>,
    /// The management key (`--key`), if provisioned.
    pub key: Option<ManagementKey>,
}

impl Config {
    /// Reads what the arguments name (the key file); the flash is opened by [`run`].
    pub fn load(args: &Args) -> Result<Config, HostError> {
        let key = match &args.key {
            Some(path) => Some(key::load(path, args.addr).map_err(HostError::Key)?),
            None => None,
        };
        Ok(Config {
            addr: args.addr,
            medium: args.medium,
            flash: args.flash.clone(),
            key,
        })
    }
}

/// Parses a short address: `0x0003`, `0X3` or `3`.
pub fn parse_addr(s: &str) -> Result<u16, String> {
    let t = s.trim();
    let parsed = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(hex) => u16::from_str_radix(hex, 16),
        None => t.parse(),
    };
    match parsed {
        Ok(a) if a >= 0xFFFE => Err(format!(
            "{a:#06x} is not a node address (0xFFFE and 0xFFFF are reserved by IEEE 802.15.4)"
        )),
        Ok(config_schema::wire::TOOL_ADDR) => Err(format!(
            "{:#06x} is not a node address (it is config-tool's own)",
            config_schema::wire::TOOL_ADDR
        )),
        Ok(a) => Ok(a),
        Err(_) => Err(format!("`{s}` is not a 16-bit address (write 0x0003 or 3)")),
    }
}

/// Why the node could not run.
#[derive(Debug)]
pub enum HostError {
    Flash(OpenError),
    /// The boot counter could not be read or written.
    BootCounter(std::io::Error),
    Connect(SocketAddr, std::io::Error),
    /// The flash does not fit two slots (a bug of the board).
    FlashGeometry,
    /// The key file was refused.
    Key(key::KeyError),
    /// The frame counter file could not be read (its path).
    FrameCounter(PathBuf),
}

impl std::fmt::Display for HostError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HostError::Flash(e) => write!(f, "{e}"),
            HostError::BootCounter(e) => write!(f, "flash file: boot counter: {e}"),
            HostError::Connect(addr, e) => write!(f, "cannot connect to the medium at {addr}: {e}"),
            HostError::FlashGeometry => write!(f, "the flash does not fit two table slots"),
            HostError::Key(e) => write!(f, "key file: {e}"),
            HostError::FrameCounter(p) => {
                write!(f, "frame counter file {}: unreadable", p.display())
            }
        }
    }
}

impl std::error::Error for HostError {}

/// The link epoch of a node without a flash file: the wall clock in seconds (u16), newer
/// on every restart that comes at least a second (and fewer than 9 hours) later.
pub fn epoch_of_clock() -> u16 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as u16)
}

struct Stderr;

impl Log for Stderr {
    fn enabled(&self, metadata: &Metadata<'_>) -> bool {
        metadata.level() <= log::max_level()
    }
    fn log(&self, record: &Record<'_>) {
        if self.enabled(record.metadata()) {
            // A log nobody reads any more (a supervisor dropped the pipe) is lost; the node
            // goes on (`eprintln!` would panic).
            let line = format_args!("{:<5} {}\n", record.level(), record.args());
            let _ = std::io::Write::write_fmt(&mut std::io::stderr().lock(), line);
        }
    }
    fn flush(&self) {}
}

static STDERR: Stderr = Stderr;

/// Logs to stderr at info level, unless the process already has a logger.
pub fn init_logging() {
    if log::set_logger(&STDERR).is_ok() {
        log::set_max_level(LevelFilter::Info);
    }
}

/// Table pins of the host board: all 64 a table may name (its pins are `Pin` messages on
/// the medium; which exist is the plant's business).
pub const PINS: usize = 64;

/// Runs the node until the medium closes the connection (`Ok`), or fails to start.
pub fn run(args: Args) -> Result<(), HostError> {
    init_logging();
    let args = Config::load(&args)?;
    let addr = args.addr;
    let (flash, what) = match &args.flash {
        Some(path) => (
            HostFlash::open(path).map_err(HostError::Flash)?,
            format!("flash {}", path.display()),
        ),
        None => (HostFlash::ram(), "flash in RAM".to_string()),
    };
    // With a flash file its boot counter reserves the link epochs (`crate::epoch`): it is
    // counted again, on a handle of its own, when this boot has taken most of them.
    // The runtime's `'static` closure is leaked, not the handle it counts on: that handle
    // shares the flash file's lock, and is closed when the node stops (a node run on a
    // thread left its flash file locked until the process ended).
    let boot_counter = Closing(Rc::new(RefCell::new(None)));
    let (boot, epoch, counted) = match flash.boot_counter().map_err(HostError::BootCounter)? {
        Some(mut counter) => {
            let boots = counter.count().map_err(HostError::BootCounter)?;
            *boot_counter.0.borrow_mut() = Some(counter);
            let held = Rc::clone(&boot_counter.0);
            let count: &'static mut dyn FnMut() -> Option<u32> = Box::leak(Box::new(move || {
                held.borrow_mut().as_mut().and_then(|c| c.count().ok())
            }));
            let boot = runtime::Boot::Counted {
                boots,
                persisted: true,
                count,
            };
            (boot, crate::epoch::of_boot(boots), format!("boot {boots}"))
        }
        None => {
            let epoch = epoch_of_clock();
            (runtime::Boot::Epoch(epoch), epoch, "clock".to_string())
        }
    };
    let security = match args.key.clone() {
        Some(key) => Some(runtime::Security {
            key,
            counter: Box::leak(frame_counter(args.flash.as_deref())?),
        }),
        None => None,
    };
    let stream = TcpStream::connect(args.medium).map_err(|e| HostError::Connect(args.medium, e))?;
    let conn = Connection::start(addr, stream).map_err(|e| HostError::Connect(args.medium, e))?;
    let key = if args.key.is_some() {
        "management key provisioned"
    } else {
        "no management key"
    };
    info!(
        "node {addr:#06x}: medium {}, {what}, epoch {epoch} ({counted}), {key}",
        args.medium
    );
    let board = Board {
        radio: conn.radio(),
        outputs: conn.pins(),
        inputs: conn.inputs(),
        flash,
        pin_mask: runtime::pin_range(PINS),
    };
    let (stop, stats) = run_on_executor(addr, boot, board, security);
    drop(boot_counter);
    let c = conn.counters();
    let (backpressure, oversized, garbage) = (
        c.backpressure.load(Ordering::Relaxed),
        c.oversized.load(Ordering::Relaxed),
        c.garbage.load(Ordering::Relaxed),
    );
    conn.close();
    info!(
        "node {addr:#06x}: stopped: {stop:?}; {} activations, {} flash failures, \
         tx dropped {} (queue) + {} (radio); from the medium: {oversized} oversized \
         frames, {garbage} garbage messages, {backpressure} waits for room",
        stats.activations, stats.flash_failures, stats.tx_queue_full, stats.tx_failed
    );
    match stop {
        Stop::Radio(Closed) => Ok(()),
        Stop::FlashGeometry => Err(HostError::FlashGeometry),
    }
}

/// A handle shared with a leaked closure, closed when this is dropped (however
/// [`run`] returns).
struct Closing<T>(Rc<RefCell<Option<T>>>);

impl<T> Drop for Closing<T> {
    fn drop(&mut self) {
        drop(self.0.borrow_mut().take());
    }
}

type Stopped = (Stop<Closed>, Stats);
type HostBoard = Board<medium::HostRadio, medium::HostPins, medium::HostInputs, HostFlash>;

/// Runs the runtime as a task of a fresh std executor on this thread until it stops.
fn run_on_executor(
    addr: u16,
    boot: runtime::Boot<'static>,
    board: HostBoard,
    security: Option<runtime::Security<'static>>,
) -> Stopped {
    block_on(async move { runtime::run_secured(addr, boot, board, &mut (), security).await })
        .unwrap_or((Stop::Radio(Closed), Stats::default()))
}

/// A frame counter source.
type CounterSource = Box<dyn FnMut() -> Option<u32>>;

/// The node's frame counter: with a flash file, a `FrameCounter` in the counter file beside
/// it (`FLASH.counter`, reserved ahead, strictly increasing across restarts and power
/// cuts); without one, in RAM from [`clock_counter_seed`].
pub fn frame_counter(flash: Option<&std::path::Path>) -> Result<CounterSource, HostError> {
    let Some(flash) = flash else {
        let mut next = Some(clock_counter_seed());
        return Ok(Box::new(move || {
            let n = next?;
            next = n.checked_add(1).filter(|n| *n != u32::MAX);
            Some(n)
        }));
    };
    let path = flash::counter_path(flash);
    let file = HostFlash::open_counter(&path).map_err(HostError::Flash)?;
    // The host flash does its I/O synchronously: these futures complete when first polled.
    let mut counter = crate::frame_counter::FrameCounter::open(file)
        .map_err(|_| HostError::FrameCounter(path))?;
    Ok(Box::new(move || counter.next().ok()))
}

/// Where the frame counter of a node without a flash file starts: 16 per second since
/// 2026-01-01 (as [`epoch_of_clock`] does for epochs), so a restart starts above what it
/// sent before unless it sent more than 16 secured frames a second on average (the
/// config PAN carries a few per command). Lasts until 2034; a flash file has none of these
/// limits.
pub fn clock_counter_seed() -> u32 {
    const Y2026: u64 = 1_767_225_600;
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    u32::try_from(secs.saturating_sub(Y2026).saturating_mul(16)).unwrap_or(u32::MAX - 1)
}

/// Runs `future` as the one task of a fresh Embassy std executor on this thread, until it
/// completes (`None` only if the task could not be spawned). The executor and the task's
/// storage are leaked: they must be `'static`, and this runs once per node.
pub fn block_on<F>(future: F) -> Option<F::Output>
where
    F: Future + 'static,
    F::Output: 'static,
{
    let result = Rc::new(RefCell::new(None));
    let out = result.clone();
    let done = result.clone();
    let executor: &'static mut Executor = Box::leak(Box::new(Executor::new()));
    let spawned = std::cell::Cell::new(true);
    executor.run_until(
        |spawner| {
            let task = Box::leak(Box::new(TaskStorage::new()));
            match task.spawn(move || async move {
                let value = future.await;
                *out.borrow_mut() = Some(value);
            }) {
                Ok(token) => spawner.spawn(token),
                Err(e) => {
                    warn!("cannot spawn the task: {e:?}");
                    spawned.set(false);
                }
            }
        },
        || !spawned.get() || done.borrow().is_some(),
    );
    let value = result.borrow_mut().take();
    value
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::provision::NodeKeyLine;

    fn key_file(name: &str, addr: u16, mode: u32) -> PathBuf {
        let p = std::env::temp_dir().join(format!("node-host-{}-{name}", std::process::id()));
        let key = ManagementKey::from_bytes([0x33; 16]);
        std::fs::write(&p, NodeKeyLine { addr, key: &key }.to_string()).unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&p, std::fs::Permissions::from_mode(mode)).unwrap();
        }
        #[cfg(not(unix))]
        let _ = mode;
        p
    }

    fn args(extra: &[&str]) -> Args {
        let mut argv = vec![
            "node-host",
            "--addr",
            "0x0011",
            "--medium",
            "127.0.0.1:15400",
        ];
        argv.extend(extra);
        Args::try_parse_from(argv).unwrap()
    }

    #[test]
    fn the_key_file_is_read_into_the_config() {
        let p = key_file("good", 0x0011, 0o600);
        let c = Config::load(&args(&["--key", p.to_str().unwrap()])).unwrap();
        assert_eq!(c.key.as_ref().map(|k| *k.expose()), Some([0x33; 16]));
        assert_eq!(
            format!("{:?}", c.key),
            "Some(ManagementKey(<secret>))",
            "the config's Debug hides the key"
        );
        assert!(Config::load(&args(&[])).unwrap().key.is_none());
    }

    #[test]
    fn the_frame_counter_resumes_above_everything_sent_before_a_restart() {
        let flash = std::env::temp_dir().join(format!("node-host-{}-fc.flash", std::process::id()));
        let _ = std::fs::remove_file(flash::counter_path(&flash));
        let mut first = frame_counter(Some(&flash)).unwrap();
        let sent: Vec<u32> = (0..5).map(|_| first().unwrap()).collect();
        assert_eq!(sent, [0, 1, 2, 3, 4]);
        drop(first);
        let mut again = frame_counter(Some(&flash)).unwrap();
        assert_eq!(again(), Some(crate::frame_counter::STEP));
        let _ = std::fs::remove_file(flash::counter_path(&flash));
        // Without a flash file: from the clock.
        let mut ram = frame_counter(None).unwrap();
        assert!(ram().is_some_and(|n| n >= clock_counter_seed().saturating_sub(16)));
    }

    #[test]
    fn a_refused_key_file_stops_the_node_before_it_connects() {
        let other = key_file("other", 0x0012, 0o600);
        let e = Config::load(&args(&["--key", other.to_str().unwrap()])).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!(
                "key file: {}: the key of node 0x0012, not of this node (0x0011)",
                other.display()
            )
        );
        // `run` loads the config first: nothing listens on port 1, yet the error is the key's.
        let mut a = args(&["--key", other.to_str().unwrap()]);
        a.medium = "127.0.0.1:1".parse().unwrap();
        assert!(matches!(
            run(a),
            Err(HostError::Key(key::KeyError::OtherNode(..)))
        ));
    }
}
