//! One client's connection: waits for its hello (within `HELLO_TIMEOUT`), then reads its
//! messages, within its rate, and hands them to the air in order.

use std::io::{self, Read};
use std::net::TcpStream;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
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
    /// Connections open, and those not past their hello (the accept thread's caps).
    pub open: Arc<AtomicUsize>,
    pub greeting: Arc<AtomicUsize>,
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
        if let Err(e) = self.read(&stream, &mut greeted) {
            if !greeted || e.kind() == io::ErrorKind::InvalidData {
                self.counters.count(|s| s.silent += 1);
            }
        }
        if !greeted {
            self.greeting.fetch_sub(1, Ordering::SeqCst);
        }
        let _ = stream.shutdown(std::net::Shutdown::Both);
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
                        self.greeting.fetch_sub(1, Ordering::SeqCst);
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
