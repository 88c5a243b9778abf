//! One client's connection: waits for its hello (within `HELLO_TIMEOUT`), then reads its
//! messages, within its rate, and hands them to the air in order.

use std::collections::VecDeque;
use std::io::{self, Read};
use std::net::{Shutdown, TcpStream};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use config_schema::wire::mac;
use config_schema::wire::medium::{Deframer, Link, MAX_LINK};

use super::air::Hub;
use super::outbox::Outbox;
use super::{limits, ClientId, Counters, Event};

/// What a connection thread needs.
pub(super) struct Connection {
    pub id: ClientId,
    pub hub: Arc<Hub>,
    pub counters: Counters,
    /// Connections open (the accept thread's cap), and those not past their hello.
    pub open: Arc<AtomicUsize>,
    pub waiting: Arc<Waiting>,
}

/// The connections that have not said hello yet, oldest first: at most `MAX_GREETING`. A
/// newcomer past that takes the oldest one's place, which is closed: connections that
/// never say hello, made again and again, cannot keep a client out.
#[derive(Default)]
pub(super) struct Waiting(Mutex<VecDeque<(ClientId, TcpStream)>>);

impl Waiting {
    /// Adds connection `id`, closing the oldest one waiting if there is no room: whether
    /// it did. An error: the socket could not be kept (the connection is refused).
    pub fn admit(&self, id: ClientId, stream: &TcpStream) -> io::Result<bool> {
        let kept = stream.try_clone()?;
        let mut waiting = self.0.lock().unwrap_or_else(|e| e.into_inner());
        waiting.push_back((id, kept));
        if waiting.len() <= limits::MAX_GREETING {
            return Ok(false);
        }
        // Its thread's read ends; it finds itself no longer waiting and is not counted again.
        if let Some((_, oldest)) = waiting.pop_front() {
            let _ = oldest.shutdown(Shutdown::Both);
        }
        Ok(true)
    }

    /// Connection `id` said hello, or ended: whether it was still waiting (not closed for a
    /// newcomer).
    pub fn done(&self, id: ClientId) -> bool {
        let mut waiting = self.0.lock().unwrap_or_else(|e| e.into_inner());
        let before = waiting.len();
        waiting.retain(|(w, _)| *w != id);
        waiting.len() < before
    }
}

/// A token bucket: `RATE_PER_S` messages a second, `BURST` at once.
struct Rate {
    tokens: f64,
    last: Instant,
}

impl Rate {
    fn new() -> Rate {
        Rate {
            tokens: f64::from(limits::BURST),
            last: Instant::now(),
        }
    }

    fn take(&mut self) -> bool {
        let now = Instant::now();
        let refill = now.duration_since(self.last).as_secs_f64() * f64::from(limits::RATE_PER_S);
        self.tokens = (self.tokens + refill).min(f64::from(limits::BURST));
        self.last = now;
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

impl Connection {
    /// Serves the connection until it closes, says nonsense, or the medium stops.
    pub fn serve(self, stream: TcpStream) {
        let _ = stream.set_nodelay(true);
        let mut greeted = false;
        let read = self.read(&stream, &mut greeted);
        // Closed for a newcomer while it waited for its hello: counted when it was closed.
        let evicted = !greeted && !self.waiting.done(self.id);
        if let Err(e) = read {
            if !evicted && (!greeted || e.kind() == io::ErrorKind::InvalidData) {
                self.counters.count(|s| s.silent += 1);
            }
        }
        let _ = stream.shutdown(Shutdown::Both);
        self.hub.handle(Event::Left(self.id));
        self.open.fetch_sub(1, Ordering::SeqCst);
    }

    fn read(&self, stream: &TcpStream, greeted: &mut bool) -> io::Result<()> {
        let nonsense = || io::Error::new(io::ErrorKind::InvalidData, "not a medium message");
        let gone = || io::Error::new(io::ErrorKind::BrokenPipe, "the medium stopped");
        stream.set_read_timeout(Some(limits::HELLO_TIMEOUT))?;
        let deadline = Instant::now() + limits::HELLO_TIMEOUT;
        let mut reader = stream;
        let mut incoming = Box::new(Deframer::<{ 8 * MAX_LINK }>::new());
        let mut rate = Rate::new();
        loop {
            if !*greeted && Instant::now() >= deadline {
                return Err(io::Error::new(io::ErrorKind::TimedOut, "no hello"));
            }
            let n = match reader.read(incoming.space()) {
                Ok(0) => return Ok(()),
                Ok(n) => n,
                Err(e) => return Err(e),
            };
            incoming.filled(n);
            while let Some(body) = incoming.take().map_err(|_| nonsense())? {
                let link = Link::parse(body).map_err(|_| nonsense())?;
                let event = match link {
                    Link::Hello(peer) if !*greeted => {
                        *greeted = true;
                        self.waiting.done(self.id);
                        stream.set_read_timeout(None)?;
                        let outbox = Outbox::start(self.id, stream.try_clone()?, peer)?;
                        Event::Joined(self.id, peer, outbox)
                    }
                    _ if !*greeted => return Err(nonsense()),
                    _ if !rate.take() => {
                        self.counters.count(|s| s.rate_limited += 1);
                        continue;
                    }
                    Link::Frame(psdu) if psdu.len() <= mac::MAX_PSDU => {
                        Event::Frame(self.id, psdu.to_vec())
                    }
                    Link::Pin { addr, pin, level } => Event::Pin(self.id, addr, pin, level),
                    Link::Running { addr, generation } => Event::Running(self.id, addr, generation),
                    Link::Sync(n) => Event::Sync(self.id, n),
                    Link::Clock => Event::Clock(self.id),
                    // A client that speaks nonsense (or the medium's words) is disconnected.
                    _ => return Err(nonsense()),
                };
                // Handled here, in order (the hub's lock orders it with every other
                // client's): a level is relayed before the next byte is read.
                if !self.hub.handle(event) {
                    return Err(gone());
                }
            }
        }
    }
}
