//! The simulated IEEE 802.15.4 medium: a loopback TCP relay between nodes, the tool, plant
//! processes and monitors (framing: `config_schema::wire::medium`).
//!
//! - Frames go to the client whose address is the destination (every other radio for the
//!   broadcast address); monitors see every frame put on the air.
//! - The air is one shared channel at 250 kbit/s: a frame occupies it for
//!   `mac::airtime_us(len)` and waits for the frames before it.
//! - Faults, per frame and per receiver, from a seeded generator: loss, duplication,
//!   corruption (one bit flipped, so the FCS fails), and a random extra delay (which reorders).
//! - Pins: a node's output levels go to plants and monitors; a plant's input levels go to the
//!   node with that address.
//! - Every frame on the air is written to a pcap (link type 195, IEEE 802.15.4 with FCS).

mod pcap;

use std::collections::{BinaryHeap, HashMap};
use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::PathBuf;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use config_schema::wire::mac::{self, BROADCAST};
use config_schema::wire::medium::{next_message, Link, Peer, MAX_LINK};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

pub use pcap::PcapLog;

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
}

/// A running medium. Dropping it does not stop it; call [`Medium::stop`].
pub struct Medium {
    addr: SocketAddr,
    stats: Arc<Mutex<Stats>>,
    events: Sender<Event>,
}

type ClientId = u64;

enum Event {
    Joined(ClientId, Peer, TcpStream),
    Frame(ClientId, Vec<u8>),
    Pin(ClientId, u16, u8, bool),
    Left(ClientId),
    Stop,
}

struct Client {
    peer: Peer,
    stream: TcpStream,
}

/// A frame due at a client.
#[derive(PartialEq, Eq, PartialOrd, Ord)]
struct Due {
    at: Instant,
    seq: u64,
    to: ClientId,
    psdu: Vec<u8>,
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
        let pcap = match &config.pcap {
            Some(path) => Some(PcapLog::create(path)?),
            None => None,
        };
        let stats = Arc::new(Mutex::new(Stats::default()));
        let (events, rx) = mpsc::channel();
        let accept_events = events.clone();
        thread::spawn(move || accept(listener, accept_events));
        let air = Air {
            config,
            rng: StdRng::seed_from_u64(0),
            clients: HashMap::new(),
            due: BinaryHeap::new(),
            seq: 0,
            air_free: Instant::now(),
            start: Instant::now(),
            pcap,
            stats: stats.clone(),
        };
        thread::spawn(move || air.run(rx));
        Ok(Medium {
            addr,
            stats,
            events,
        })
    }

    /// The address clients connect to.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    pub fn stats(&self) -> Stats {
        self.stats.lock().map(|s| *s).unwrap_or_default()
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

    /// Stops relaying (connections are closed).
    pub fn stop(&self) {
        let _ = self.events.send(Event::Stop);
    }
}

fn accept(listener: TcpListener, events: Sender<Event>) {
    let mut next_id: ClientId = 0;
    for stream in listener.incoming() {
        let Ok(stream) = stream else { continue };
        next_id += 1;
        let id = next_id;
        let events = events.clone();
        thread::spawn(move || serve(id, stream, events));
    }
}

/// Reads one client's messages and hands them to the air.
fn serve(id: ClientId, mut stream: TcpStream, events: Sender<Event>) {
    let _ = stream.set_nodelay(true);
    let mut buf = Vec::with_capacity(4 * MAX_LINK);
    let mut chunk = [0u8; 1024];
    let mut joined = false;
    loop {
        let n = match stream.read(&mut chunk) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        buf.extend_from_slice(&chunk[..n]);
        while let Some(body) = next_message(&buf) {
            let event = match Link::parse(&buf[body.clone()]) {
                Ok(Link::Hello(peer)) if !joined => match stream.try_clone() {
                    Ok(w) => {
                        joined = true;
                        Some(Event::Joined(id, peer, w))
                    }
                    Err(_) => None,
                },
                Ok(Link::Frame(psdu)) if joined && psdu.len() <= mac::MAX_PSDU => {
                    Some(Event::Frame(id, psdu.to_vec()))
                }
                Ok(Link::Pin { addr, pin, level }) if joined => {
                    Some(Event::Pin(id, addr, pin, level))
                }
                // A client that speaks nonsense is disconnected.
                _ => {
                    let _ = events.send(Event::Left(id));
                    return;
                }
            };
            buf.drain(..body.end);
            if let Some(e) = event {
                if events.send(e).is_err() {
                    return;
                }
            }
        }
        if buf.len() > 4 * MAX_LINK {
            break;
        }
    }
    let _ = events.send(Event::Left(id));
}

/// The shared channel: who is connected, what is in flight.
struct Air {
    config: Config,
    rng: StdRng,
    clients: HashMap<ClientId, Client>,
    due: BinaryHeap<std::cmp::Reverse<Due>>,
    seq: u64,
    air_free: Instant,
    start: Instant,
    pcap: Option<PcapLog>,
    stats: Arc<Mutex<Stats>>,
}

fn send(stream: &mut TcpStream, msg: &Link) -> bool {
    let mut buf = [0u8; MAX_LINK];
    match msg.emit(&mut buf) {
        Ok(n) => stream.write_all(&buf[..n]).is_ok(),
        Err(_) => true,
    }
}

impl Air {
    fn run(mut self, rx: Receiver<Event>) {
        self.rng = StdRng::seed_from_u64(self.config.seed);
        loop {
            let clients = self.clients.len() as u64;
            self.count(|s| s.clients = clients);
            let timeout = self
                .due
                .peek()
                .map(|d| d.0.at.saturating_duration_since(Instant::now()))
                .unwrap_or(Duration::from_millis(100));
            match rx.recv_timeout(timeout) {
                Ok(Event::Stop) | Err(RecvTimeoutError::Disconnected) => break,
                Ok(event) => self.handle(event),
                Err(RecvTimeoutError::Timeout) => {}
            }
            self.deliver_due();
        }
        for client in self.clients.values() {
            let _ = client.stream.shutdown(std::net::Shutdown::Both);
        }
    }

    fn handle(&mut self, event: Event) {
        match event {
            Event::Joined(id, peer, stream) => {
                self.clients.insert(id, Client { peer, stream });
            }
            Event::Left(id) => {
                if let Some(c) = self.clients.remove(&id) {
                    let _ = c.stream.shutdown(std::net::Shutdown::Both);
                }
            }
            Event::Frame(id, psdu) => self.transmit(id, psdu),
            Event::Pin(id, addr, pin, level) => self.pin(id, addr, pin, level),
            Event::Stop => {}
        }
    }

    fn radio_addr(peer: Peer) -> Option<u16> {
        match peer {
            Peer::Node { addr } | Peer::Tool { addr } => Some(addr),
            Peer::Plant | Peer::Monitor => None,
        }
    }

    /// A frame goes on the air: after the frames before it, for its airtime.
    fn transmit(&mut self, from: ClientId, psdu: Vec<u8>) {
        let now = Instant::now();
        let airtime = Duration::from_micros(u64::from(mac::airtime_us(psdu.len())));
        let on_air = self.air_free.max(now);
        self.air_free = on_air + airtime;
        let arrives = self.air_free;
        if let Some(pcap) = &mut self.pcap {
            pcap.write(on_air.duration_since(self.start), &psdu);
        }
        if let Ok(mut s) = self.stats.lock() {
            s.frames += 1;
            s.bytes += psdu.len() as u64;
            s.airtime_us += airtime.as_micros() as u64;
        }
        let dst = psdu_dst(&psdu);
        let targets: Vec<ClientId> = self
            .clients
            .iter()
            .filter(|(id, _)| **id != from)
            .filter(|(_, c)| match (Self::radio_addr(c.peer), dst) {
                (_, None) => c.peer == Peer::Monitor,
                (Some(a), Some(d)) => a == d || d == BROADCAST,
                (None, _) => c.peer == Peer::Monitor,
            })
            .map(|(id, _)| *id)
            .collect();
        for to in targets {
            let monitor = self
                .clients
                .get(&to)
                .is_some_and(|c| c.peer == Peer::Monitor);
            if monitor {
                self.schedule(to, arrives, psdu.clone());
                continue;
            }
            if self.rng.random_bool(self.config.loss.clamp(0.0, 1.0)) {
                self.count(|s| s.lost += 1);
                continue;
            }
            let copies = if self.rng.random_bool(self.config.dup.clamp(0.0, 1.0)) {
                self.count(|s| s.duplicated += 1);
                2
            } else {
                1
            };
            for _ in 0..copies {
                let mut bytes = psdu.clone();
                if self.rng.random_bool(self.config.corrupt.clamp(0.0, 1.0)) && !bytes.is_empty() {
                    let i = self.rng.random_range(0..bytes.len());
                    bytes[i] ^= 1 << self.rng.random_range(0..8);
                    self.count(|s| s.corrupted += 1);
                }
                let (lo, hi) = self.config.delay_ms;
                let extra = if hi > lo {
                    self.rng.random_range(lo..=hi)
                } else {
                    lo
                };
                self.schedule(to, arrives + Duration::from_millis(extra), bytes);
            }
        }
    }

    fn count(&self, f: impl FnOnce(&mut Stats)) {
        if let Ok(mut s) = self.stats.lock() {
            f(&mut s);
        }
    }

    fn schedule(&mut self, to: ClientId, at: Instant, psdu: Vec<u8>) {
        self.seq += 1;
        self.due.push(std::cmp::Reverse(Due {
            at,
            seq: self.seq,
            to,
            psdu,
        }));
    }

    fn deliver_due(&mut self) {
        let now = Instant::now();
        while self.due.peek().is_some_and(|d| d.0.at <= now) {
            let Some(std::cmp::Reverse(d)) = self.due.pop() else {
                break;
            };
            let Some(client) = self.clients.get_mut(&d.to) else {
                continue;
            };
            let monitor = client.peer == Peer::Monitor;
            if send(&mut client.stream, &Link::Frame(&d.psdu)) {
                if !monitor {
                    self.count(|s| s.delivered += 1);
                }
            } else {
                self.clients.remove(&d.to);
            }
        }
    }

    /// Output levels go from a node to plants and monitors; input levels from a plant to the
    /// node with that address (and monitors).
    fn pin(&mut self, from: ClientId, addr: u16, pin: u8, level: bool) {
        let Some(sender) = self.clients.get(&from).map(|c| c.peer) else {
            return;
        };
        let msg = Link::Pin { addr, pin, level };
        let mut gone = Vec::new();
        for (id, c) in self.clients.iter_mut() {
            let wanted = match (sender, c.peer) {
                (Peer::Node { addr: a }, Peer::Plant | Peer::Monitor) => a == addr,
                (Peer::Plant, Peer::Node { addr: a }) => a == addr,
                (Peer::Plant, Peer::Monitor) => true,
                _ => false,
            };
            if wanted && *id != from && !send(&mut c.stream, &msg) {
                gone.push(*id);
            }
        }
        for id in gone {
            self.clients.remove(&id);
        }
    }
}

/// The destination short address of a data frame (without checking the FCS: a corrupted
/// frame still reaches its receiver, which drops it). `None` for anything else.
fn psdu_dst(psdu: &[u8]) -> Option<u16> {
    let fc = u16::from_le_bytes([*psdu.first()?, *psdu.get(1)?]);
    match fc & 0b111 {
        0b001 if (fc >> 10) & 0b11 == 0b10 => {
            Some(u16::from_le_bytes([*psdu.get(5)?, *psdu.get(6)?]))
        }
        _ => None,
    }
}
