//! The host board's radio, pins and inputs: one TCP connection to the simulated medium
//! (`config_schema::wire::medium` framing). A reader thread parses what the medium sends and
//! hands it to the runtime through `embassy-sync` channels; writes go straight to the socket
//! (loopback: a write of one message does not block for long). Nothing is lost between the
//! medium and the node: when a channel is full the reader waits (TCP then holds the medium
//! back), so loss is the medium's to model, with its seed.
//!
//! - `Frame` from the medium: a received PSDU (longer than 127 bytes: dropped, counted);
//! - `Pin { addr, pin, level }` for this node's address: input `pin` is now at `level`
//!   (from the plant, which the medium attaches; the node never knows its role);
//! - anything else (other nodes' pins, a `Hello`, bytes that are not a message): ignored,
//!   counted.
//!
//! The node sends `Hello(Node { addr })` first and waits for the medium's `Welcome` (from
//! then on the medium routes to it), then sends a `Frame` per transmitted PSDU and a `Pin`
//! per output change.

use std::io::{self, Read, Write};
use std::net::{Shutdown, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use config_schema::wire::mac::MAX_PSDU;
use config_schema::wire::medium::{Deframer, Link, Peer, MAX_LINK};
use embassy_futures::select::{select, Either};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::{Channel, TrySendError};
use embassy_sync::signal::Signal;

use crate::runtime::{mpdu_of, psdu_of, Inputs, Pins, Psdu, Radio, Received};

/// Received frames buffered between the reader thread and the runtime.
pub const RX_QUEUE: usize = 64;
/// Input changes buffered between the reader thread and the runtime.
pub const PIN_QUEUE: usize = 64;

/// What the reader thread counted.
#[derive(Debug, Default)]
pub struct LinkCounters {
    /// Times the reader waited for the runtime (a channel was full).
    pub backpressure: AtomicU32,
    /// Frames longer than a PSDU.
    pub oversized: AtomicU32,
    /// Messages that did not parse, or made no sense from the medium.
    pub garbage: AtomicU32,
}

/// Where the reader thread and the runtime meet.
struct Shared {
    frames: Channel<CriticalSectionRawMutex, Psdu, RX_QUEUE>,
    pins: Channel<CriticalSectionRawMutex, (u8, bool), PIN_QUEUE>,
    closed: Signal<CriticalSectionRawMutex, ()>,
    /// The runtime is gone: the reader stops waiting for room.
    stopping: AtomicBool,
    counters: LinkCounters,
}

impl Shared {
    /// Puts `item` into `channel`, waiting for room; `false` if the runtime is gone.
    fn put<T, const N: usize>(
        &self,
        channel: &Channel<CriticalSectionRawMutex, T, N>,
        mut item: T,
    ) -> bool {
        let mut waited = false;
        loop {
            match channel.try_send(item) {
                Ok(()) => return true,
                Err(TrySendError::Full(back)) => item = back,
            }
            if self.stopping.load(Ordering::Relaxed) {
                return false;
            }
            if !waited {
                waited = true;
                self.counters.backpressure.fetch_add(1, Ordering::Relaxed);
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

/// The connection was lost.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Closed;

/// One node's connection to the medium.
pub struct Connection {
    addr: u16,
    stream: TcpStream,
    writer: Arc<Mutex<TcpStream>>,
    shared: Arc<Shared>,
    reader: Option<JoinHandle<()>>,
}

fn write_link(stream: &mut TcpStream, msg: &Link<'_>) -> io::Result<()> {
    let mut buf = [0u8; MAX_LINK];
    let n = msg
        .emit(&mut buf)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "message too long"))?;
    stream.write_all(buf.get(..n).unwrap_or(&buf))
}

/// How long a node waits for the medium's `Welcome`.
pub const WELCOME_TIMEOUT: Duration = Duration::from_secs(5);

/// What a node reads from its connection: messages of at most `MAX_LINK` bytes.
type Incoming = Box<Deframer<{ 16 * MAX_LINK }>>;

/// The next message body from `stream` (bytes past it stay in `incoming`); `None` when the
/// connection ends. A message longer than any is skipped and counted (`too_long`).
fn next_body<'a>(
    stream: &mut impl Read,
    incoming: &'a mut Incoming,
    mut too_long: impl FnMut(),
) -> Option<&'a [u8]> {
    // Asks whether a message is whole before taking it: the borrow it returns is then not
    // held across the read.
    loop {
        match incoming.complete() {
            Ok(true) => break,
            Ok(false) => {}
            Err(_) => {
                too_long();
                continue;
            }
        }
        let n = stream.read(incoming.space()).ok()?;
        if n == 0 {
            return None;
        }
        incoming.filled(n);
    }
    incoming.take().ok().flatten()
}

/// Reads messages until the medium's `Welcome`, for [`WELCOME_TIMEOUT`] in all (what
/// else it says does not extend the wait); returns what was read past it.
fn await_welcome(stream: &TcpStream) -> io::Result<Incoming> {
    let mut reader = Until {
        stream,
        end: Instant::now() + WELCOME_TIMEOUT,
    };
    let mut incoming = Incoming::default();
    loop {
        let body = next_body(&mut reader, &mut incoming, || {}).ok_or_else(|| {
            io::Error::new(
                io::ErrorKind::InvalidData,
                "the medium did not welcome this node",
            )
        })?;
        if Link::parse(body) == Ok(Link::Welcome) {
            break;
        }
    }
    stream.set_read_timeout(None)?;
    Ok(incoming)
}

/// Reads from `stream` until `end` (then `TimedOut`), however the bytes come.
struct Until<'s> {
    stream: &'s TcpStream,
    end: Instant,
}

impl Read for Until<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let left = self.end.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(io::ErrorKind::TimedOut.into());
        }
        self.stream.set_read_timeout(Some(left))?;
        let mut stream = self.stream;
        stream.read(buf)
    }
}

impl Connection {
    /// Says hello on `stream` as node `addr`, waits until the medium routes to it (its
    /// `Welcome`), and starts reading.
    pub fn start(addr: u16, stream: TcpStream) -> io::Result<Self> {
        stream.set_nodelay(true)?;
        let mut writer = stream.try_clone()?;
        write_link(&mut writer, &Link::Hello(Peer::Node { addr }))?;
        let incoming = await_welcome(&stream)?;
        let shared = Arc::new(Shared {
            frames: Channel::new(),
            pins: Channel::new(),
            closed: Signal::new(),
            stopping: AtomicBool::new(false),
            counters: LinkCounters::default(),
        });
        let reading = stream.try_clone()?;
        let for_reader = shared.clone();
        let reader = std::thread::Builder::new()
            .name(format!("medium-{addr:04x}"))
            .spawn(move || read_loop(addr, reading, incoming, &for_reader))?;
        Ok(Connection {
            addr,
            stream,
            writer: Arc::new(Mutex::new(writer)),
            shared,
            reader: Some(reader),
        })
    }

    pub fn radio(&self) -> HostRadio {
        HostRadio {
            writer: self.writer.clone(),
            shared: self.shared.clone(),
        }
    }

    pub fn pins(&self) -> HostPins {
        HostPins {
            addr: self.addr,
            writer: self.writer.clone(),
        }
    }

    pub fn inputs(&self) -> HostInputs {
        HostInputs {
            shared: self.shared.clone(),
            levels: [false; 256],
        }
    }

    pub fn counters(&self) -> &LinkCounters {
        &self.shared.counters
    }

    /// Closes the connection and waits for the reader thread.
    pub fn close(mut self) {
        self.shared.stopping.store(true, Ordering::Relaxed);
        let _ = self.stream.shutdown(Shutdown::Both);
        if let Some(reader) = self.reader.take() {
            let _ = reader.join();
        }
    }
}

fn read_loop(addr: u16, mut stream: TcpStream, mut incoming: Incoming, shared: &Shared) {
    let too_long = || {
        shared.counters.oversized.fetch_add(1, Ordering::Relaxed);
    };
    while let Some(msg) = next_body(&mut stream, &mut incoming, too_long) {
        let c = &shared.counters;
        match Link::parse(msg) {
            Ok(Link::Frame(psdu)) => match Psdu::from_slice(psdu) {
                Ok(frame) => {
                    if !shared.put(&shared.frames, frame) {
                        break;
                    }
                }
                Err(_) => {
                    c.oversized.fetch_add(1, Ordering::Relaxed);
                }
            },
            Ok(Link::Pin {
                addr: a,
                pin,
                level,
            }) if a == addr => {
                if !shared.put(&shared.pins, (pin, level)) {
                    break;
                }
            }
            _ => {
                c.garbage.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
    shared.closed.signal(());
}

/// The radio: frames over the connection.
pub struct HostRadio {
    writer: Arc<Mutex<TcpStream>>,
    shared: Arc<Shared>,
}

impl Radio for HostRadio {
    type Error = Closed;

    /// The radio edge: the MPDU goes on the medium with its FCS appended.
    async fn send(&mut self, mpdu: &[u8]) -> Result<(), Closed> {
        // Longer than an MPDU: the runtime's queue never holds one.
        let Some(psdu) = psdu_of(mpdu) else {
            return Ok(());
        };
        let mut stream = self.writer.lock().map_err(|_| Closed)?;
        write_link(&mut stream, &Link::Frame(&psdu)).map_err(|_| Closed)
    }

    /// The radio edge: a PSDU off the medium, its FCS checked and cut off.
    async fn receive(&mut self, buf: &mut [u8; MAX_PSDU]) -> Result<Received, Closed> {
        // Frames first: those that arrived before the connection closed are delivered.
        match select(self.shared.frames.receive(), self.shared.closed.wait()).await {
            Either::First(frame) => Ok(mpdu_of(&frame, buf)),
            Either::Second(()) => {
                self.shared.closed.signal(());
                Err(Closed)
            }
        }
    }
}

/// The outputs: `Pin` messages to the medium.
pub struct HostPins {
    addr: u16,
    writer: Arc<Mutex<TcpStream>>,
}

impl Pins for HostPins {
    fn set(&mut self, pin: u8, level: bool) {
        if let Ok(mut stream) = self.writer.lock() {
            // A lost connection shows up at the radio, which stops the runtime.
            let _ = write_link(
                &mut stream,
                &Link::Pin {
                    addr: self.addr,
                    pin,
                    level,
                },
            );
        }
    }
    /// The host board has no outputs of its own: until a table names them, nothing is
    /// driven (the table's safe values follow at boot and at every activation).
    fn all_off(&mut self) {}
    fn running(&mut self, generation: u32) {
        if let Ok(mut stream) = self.writer.lock() {
            let addr = self.addr;
            let _ = write_link(&mut stream, &Link::Running { addr, generation });
        }
    }
}

/// The inputs: `Pin` messages from the medium, every change reported once, in order.
pub struct HostInputs {
    shared: Arc<Shared>,
    /// The last level of every pin.
    levels: [bool; 256],
}

impl Inputs for HostInputs {
    /// What the plant said before the node booted (usually nothing: all low).
    fn levels(&mut self) -> u64 {
        while let Ok((pin, level)) = self.shared.pins.try_receive() {
            self.levels[usize::from(pin)] = level;
        }
        self.levels
            .iter()
            .take(64)
            .enumerate()
            .filter(|(_, &high)| high)
            .fold(0, |m, (i, _)| m | (1 << i))
    }

    async fn change(&mut self) -> (u8, bool) {
        let (pin, level) = self.shared.pins.receive().await;
        self.levels[usize::from(pin)] = level;
        (pin, level)
    }
}
