//! The simulated IEEE 802.15.4 medium: a loopback TCP relay between nodes, the tool, plant
//! processes and monitors (framing: `config_schema::wire::medium`).
//!
//! - Frames go to the client whose address is the destination (every other radio for the
//!   broadcast address); monitors see every frame put on the air.
//! - The air is one shared channel at 250 kbit/s: a frame occupies it for
//!   `mac::airtime_us(len)` and waits for the frames before it.
//! - Faults, per frame and per receiver, from a seeded generator: loss, duplication,
//!   corruption (one bit flipped, so the FCS fails), and a random extra delay (which reorders).
//! - Pins: a node's output levels go to plants and monitors (as `Seen`, stamped with the
//!   medium's clock); a plant's input levels go to the node with that address.
//! - A link can be cut ([`Medium::cut`]): from then on, no frame of one radio reaches
//!   another (a fault injected by `demo --fault link:FROM->TO`).
//! - A client is routed to once the medium answered its `Hello` with `Welcome`.
//! - Every frame on the air is written to a pcap (link type 195, IEEE 802.15.4 with FCS).
//!
//! Nothing grows without bound, whatever clients do ([`limits`]): a client's frames wait
//! for the air in a bounded transmit queue (past it they are dropped, as a radio reports a
//! channel access failure); each client has a bounded rate of messages; each receiver has
//! its own bounded outbox (straight into the socket when nothing waits, else by its own
//! thread) (a radio that cannot keep up loses
//! frames, as a radio's receive buffer overruns; a plant or monitor that does not read is
//! disconnected); connections that do not say hello in time are closed, and so is the
//! oldest of them when one more comes past their cap; connections are capped. Every drop
//! is counted in [`Stats`].

mod air;
mod bridge;
mod client;
mod outbox;
mod pcap;
mod serve;

use std::io;
use std::net::{SocketAddr, TcpListener};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use config_schema::wire::medium::Peer;

pub use bridge::{bridge, BridgeError};
pub use client::{went_away, Conn, JOIN_TIMEOUT};
pub use pcap::PcapLog;

/// Every bound of the medium, in one place.
pub mod limits {
    use std::time::Duration;

    /// Connections open at once (more are closed at once, counted in `refused`).
    pub const MAX_CONNECTIONS: usize = 128;
    /// Connections that have not said hello yet, at once: one more closes the oldest of
    /// them (counted in `silent`).
    pub const MAX_GREETING: usize = 16;
    /// A connection must say hello within this time.
    pub const HELLO_TIMEOUT: Duration = Duration::from_secs(2);
    /// Frames of one client waiting for (or on) the air; more are dropped (`busy`).
    pub const TX_QUEUE: usize = 64;
    /// Messages a client may send per second, sustained, and in a burst.
    pub const RATE_PER_S: u32 = 2_000;
    pub const BURST: u32 = 400;
    /// Messages waiting to be written to one client. A radio past it loses frames
    /// (`overruns`); a plant or monitor past it is disconnected (`slow`).
    pub const OUTBOX: usize = 512;
    /// The kernel's send buffer of each client's socket (bytes), so the kernel holds
    /// little more than the outbox for a client that does not read.
    pub const SOCKET_BUFFER: usize = 32 * 1024;
    /// A write to a client that takes longer than this disconnects it.
    pub const WRITE_TIMEOUT: Duration = Duration::from_secs(2);
}

/// What the medium does to frames.
#[derive(Debug, Clone)]
pub struct Config {
    pub listen: SocketAddr,
    /// Probability a frame is lost, per receiver.
    pub loss: f64,
    /// Probability a frame arrives twice, per receiver.
    pub dup: f64,
    /// Probability a frame arrives with one bit flipped, per receiver.
    pub corrupt: f64,
    /// Extra delay per delivery, uniform in this range (ms).
    pub delay_ms: (u64, u64),
    pub seed: u64,
    pub pcap: Option<PathBuf>,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            listen: SocketAddr::from(([127, 0, 0, 1], 0)),
            loss: 0.0,
            dup: 0.0,
            corrupt: 0.0,
            delay_ms: (0, 0),
            seed: 1,
            pcap: None,
        }
    }
}

/// Counters of the medium.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Frames put on the air.
    pub frames: u64,
    /// Bytes put on the air (PSDUs).
    pub bytes: u64,
    /// Airtime used, PHY overhead included (us).
    pub airtime_us: u64,
    pub delivered: u64,
    pub lost: u64,
    pub duplicated: u64,
    pub corrupted: u64,
    /// Clients connected (after their hello).
    pub clients: u64,
    /// Frames dropped because their sender's transmit queue was full.
    pub busy: u64,
    /// Messages dropped because their sender exceeded its rate.
    pub rate_limited: u64,
    /// Messages dropped because a radio's outbox was full.
    pub overruns: u64,
    /// Plants and monitors disconnected because they did not read.
    pub slow: u64,
    /// Connections closed because they did not say hello in time, or said nonsense.
    pub silent: u64,
    /// Connections refused (too many at once).
    pub refused: u64,
    /// Frames the pcap (`Config::pcap`) lacks: its file could not be written (from the
    /// first failure on, the file ends there).
    pub pcap_unwritten: u64,
    /// Why the first of them was not written.
    pub pcap_error: Option<io::ErrorKind>,
    /// Deliveries scheduled and not made yet (a gauge).
    pub queued: u64,
    /// Deliveries not made because their link was cut ([`Medium::cut`]).
    pub cut: u64,
}

/// A running medium. Dropping it does not stop it; call [`Medium::stop`].
pub struct Medium {
    addr: SocketAddr,
    stats: Arc<Mutex<Stats>>,
    hub: Arc<air::Hub>,
    start: Instant,
}

type ClientId = u64;

/// What the connection threads (and the tool) tell the air.
enum Event {
    Joined(ClientId, Peer, outbox::Outbox),
    Frame(ClientId, Vec<u8>),
    Pin(ClientId, u16, u8, bool),
    Running(ClientId, u16, u32),
    Sync(ClientId, u32),
    Clock(ClientId),
    Cut { from: u16, to: u16 },
    Left(ClientId),
    Stop,
}

/// Shared counters, updated by every thread.
#[derive(Clone)]
struct Counters(Arc<Mutex<Stats>>);

impl Counters {
    fn count(&self, f: impl FnOnce(&mut Stats)) {
        if let Ok(mut s) = self.0.lock() {
            f(&mut s);
        }
    }
}

impl Medium {
    /// Binds and starts the medium's threads.
    pub fn start(config: Config) -> io::Result<Medium> {
        let listener = TcpListener::bind(config.listen)?;
        if !listener.local_addr()?.ip().is_loopback() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "the medium listens on loopback only",
            ));
        }
        let addr = listener.local_addr()?;
        let pcap = config.pcap.as_deref().map(|path| {
            PcapLog::create(path)
                .map_err(|e| io::Error::new(e.kind(), format!("pcap {}: {e}", path.display())))
        });
        let pcap = pcap.transpose()?;
        let stats = Arc::new(Mutex::new(Stats::default()));
        let counters = Counters(stats.clone());
        let start = Instant::now();
        let hub = Arc::new(air::Hub::new(air::Air::new(
            config,
            start,
            pcap,
            counters.clone(),
        )));
        let accept_hub = hub.clone();
        thread::Builder::new()
            .name("medium-accept".into())
            .spawn(move || accept(listener, accept_hub, counters))?;
        let air_hub = hub.clone();
        thread::Builder::new()
            .name("medium-air".into())
            .spawn(move || air_hub.run())?;
        Ok(Medium {
            addr,
            stats,
            hub,
            start,
        })
    }

    /// The address clients connect to.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    pub fn stats(&self) -> Stats {
        self.stats.lock().map(|s| *s).unwrap_or_default()
    }

    /// The medium's clock: the time since it started (what `Seen` stamps carry).
    pub fn now(&self) -> Duration {
        self.start.elapsed()
    }

    /// When the medium started (the zero of its clock).
    pub fn started(&self) -> Instant {
        self.start
    }

    /// Waits (up to `timeout`) until `n` clients have joined; returns whether they did.
    pub fn wait_for_clients(&self, n: u64, timeout: Duration) -> bool {
        let end = Instant::now() + timeout;
        while Instant::now() < end {
            if self.stats().clients >= n {
                return true;
            }
            thread::sleep(Duration::from_millis(5));
        }
        false
    }

    /// Cuts the link from the radio at address `from` to the radio at `to`: no frame `from`
    /// puts on the air after this reaches `to` (the other direction, and every other
    /// receiver, are untouched). Frames already in flight still arrive.
    pub fn cut(&self, from: u16, to: u16) {
        self.hub.handle(Event::Cut { from, to });
    }

    /// Stops relaying (connections are closed).
    pub fn stop(&self) {
        self.hub.handle(Event::Stop);
    }
}

/// Makes the calling thread's timed waits (and those of the threads it starts from now on)
/// end within a microsecond of their deadline, not up to Linux's default timer slack of
/// 50 us later: the medium's airtimes and a plant's motions end on timed waits. Nothing
/// elsewhere, or when the kernel refuses.
pub fn precise_timers() {
    #[cfg(target_os = "linux")]
    let _ = rustix::thread::set_current_timer_slack(std::num::NonZeroU64::new(1));
}

/// How long the accept loop waits after an accept that failed.
const ACCEPT_RETRY: std::time::Duration = std::time::Duration::from_millis(50);

/// Accepts connections, each served by its own thread, within the connection caps (a
/// newcomer past `MAX_GREETING` waiting for their hello closes the oldest of them).
fn accept(listener: TcpListener, hub: Arc<air::Hub>, counters: Counters) {
    let open = Arc::new(AtomicUsize::new(0));
    let waiting = Arc::new(serve::Waiting::default());
    let mut next_id: ClientId = 0;
    for stream in listener.incoming() {
        let Ok(stream) = stream else {
            // No descriptor left (or the like): try again once some have closed, without
            // spinning.
            thread::sleep(ACCEPT_RETRY);
            continue;
        };
        next_id += 1;
        let admitted = match open.load(Ordering::SeqCst) < limits::MAX_CONNECTIONS {
            true => waiting.admit(next_id, &stream).ok(),
            false => None,
        };
        match admitted {
            None => {
                let _ = stream.shutdown(std::net::Shutdown::Both);
                counters.count(|s| s.refused += 1);
                continue;
            }
            Some(true) => counters.count(|s| s.silent += 1),
            Some(false) => {}
        }
        open.fetch_add(1, Ordering::SeqCst);
        let conn = serve::Connection {
            id: next_id,
            hub: hub.clone(),
            counters: counters.clone(),
            open: open.clone(),
            waiting: waiting.clone(),
        };
        let spawned = thread::Builder::new()
            .name(format!("medium-conn-{next_id}"))
            .spawn(move || conn.serve(stream));
        if spawned.is_err() {
            open.fetch_sub(1, Ordering::SeqCst);
            waiting.done(next_id);
            counters.count(|s| s.refused += 1);
        }
    }
}
