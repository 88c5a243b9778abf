//! A client's connection to a medium (the tool's radio, the plant, the monitor, the
//! gateway bridge): joins and waits to be welcomed, sends messages, and reads them one at
//! a time with a deadline, so every client reads the stream the same way.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use std::collections::VecDeque;

use config_schema::wire::medium::{Deframer, Link, Peer, MAX_LINK};

/// How long a client waits for the medium's `Welcome` (and a `Synced`).
pub const JOIN_TIMEOUT: Duration = Duration::from_secs(5);

/// Messages a [`Conn::sync`] keeps for [`Conn::recv`] at most (more are dropped: a client
/// that syncs reads what it needs right after).
const HELD: usize = 1024;

/// A joined connection.
pub struct Conn {
    stream: TcpStream,
    /// The medium's address, for what a failure says.
    medium: SocketAddr,
    incoming: Box<Deframer<{ 16 * MAX_LINK }>>,
    /// Messages read during a sync, not yet returned.
    held: VecDeque<Vec<u8>>,
    syncs: u32,
}

impl Conn {
    /// Connects as `peer` and returns once the medium routes to this client.
    pub fn join(medium: SocketAddr, peer: Peer) -> io::Result<Conn> {
        let stream = TcpStream::connect_timeout(&medium, JOIN_TIMEOUT)?;
        stream.set_nodelay(true)?;
        let mut conn = Conn {
            stream,
            medium,
            incoming: Box::default(),
            held: VecDeque::new(),
            syncs: 0,
        };
        conn.send(&Link::Hello(peer))?;
        let until = Instant::now() + JOIN_TIMEOUT;
        match conn.recv(until, |l| matches!(l, Link::Welcome).then_some(()))? {
            Some(()) => Ok(conn),
            None => Err(io::Error::new(
                io::ErrorKind::TimedOut,
                format!("the medium at {medium} did not welcome this client"),
            )),
        }
    }

    pub fn send(&mut self, link: &Link) -> io::Result<()> {
        let mut buf = [0u8; MAX_LINK];
        let n = link
            .emit(&mut buf)
            .map_err(|_| io::Error::other("message too long for the medium"))?;
        self.stream
            .write_all(buf.get(..n).unwrap_or_default())
            .map_err(|e| gone(e, self.medium))
    }

    /// Writes raw bytes on the connection (a test's hand-built message).
    pub fn send_raw(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.stream
            .write_all(bytes)
            .map_err(|e| gone(e, self.medium))
    }

    /// A barrier: returns once the medium has handled everything sent before. Messages
    /// received meanwhile stay queued for [`Conn::recv`].
    pub fn sync(&mut self) -> io::Result<()> {
        self.syncs = self.syncs.wrapping_add(1);
        let n = self.syncs;
        self.send(&Link::Sync(n))?;
        let until = Instant::now() + JOIN_TIMEOUT;
        let mut kept = VecDeque::new();
        let held = self.held.len();
        let done = loop {
            let synced = self.next_in(until, |body| {
                if Link::parse(body).is_ok_and(|l| l == Link::Synced(n)) {
                    return Some(());
                }
                if held + kept.len() < HELD {
                    kept.push_back(body.to_vec());
                }
                None
            })?;
            match synced {
                Next::Taken(()) => break true,
                Next::Declined => {}
                Next::TimedOut => break false,
            }
        };
        // After what earlier syncs held: the stream's order.
        self.held.append(&mut kept);
        if done {
            Ok(())
        } else {
            Err(io::Error::new(
                io::ErrorKind::TimedOut,
                "the medium did not answer a sync",
            ))
        }
    }

    /// Reads messages until `pick` takes one (returns it) or `until` passes (`None`).
    /// Messages `pick` declines, and ones that do not parse, are consumed.
    pub fn recv<T>(
        &mut self,
        until: Instant,
        mut pick: impl FnMut(Link<'_>) -> Option<T>,
    ) -> io::Result<Option<T>> {
        while let Some(raw) = self.held.pop_front() {
            if let Some(t) = Link::parse(&raw).ok().and_then(&mut pick) {
                return Ok(Some(t));
            }
        }
        loop {
            match self.next_in(until, |body| Link::parse(body).ok().and_then(&mut pick))? {
                Next::Taken(t) => return Ok(Some(t)),
                Next::Declined => {}
                Next::TimedOut => return Ok(None),
            }
        }
    }

    /// Hands the next message body to `take`, reading until one is whole or `until`
    /// passes.
    fn next_in<T>(
        &mut self,
        until: Instant,
        take: impl FnOnce(&[u8]) -> Option<T>,
    ) -> io::Result<Next<T>> {
        loop {
            let not_framing = || {
                io::Error::new(
                    io::ErrorKind::InvalidData,
                    "the medium sent something that is not a message",
                )
            };
            if let Some(body) = self.incoming.take().map_err(|_| not_framing())? {
                return Ok(match take(body) {
                    Some(t) => Next::Taken(t),
                    None => Next::Declined,
                });
            }
            // Past `until`, what the medium already sent is still taken (without waiting):
            // a caller that comes late must not take an answer waiting here for a timeout.
            let late = !readable(&self.stream, until)?;
            if late {
                self.stream.set_nonblocking(true)?;
            }
            let read = self.stream.read(self.incoming.space());
            if late {
                self.stream.set_nonblocking(false)?;
            }
            match read {
                Ok(0) => return Err(closed(io::ErrorKind::UnexpectedEof, self.medium)),
                Ok(n) => self.incoming.filled(n),
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    if late {
                        return Ok(Next::TimedOut);
                    }
                }
                Err(e) => return Err(e),
            }
        }
    }

    /// A second handle on the same connection (for a writer in another thread).
    pub fn try_clone_stream(&self) -> io::Result<TcpStream> {
        self.stream.try_clone()
    }
}

/// Waits until `stream` has something to read (bytes, the end, an error) or `until`
/// passes; `false` if it passed.
///
/// With poll(2) (ppoll on Linux: a nanosecond timeout on a high-resolution timer), not a
/// socket receive timeout: Linux counts `SO_RCVTIMEO` in scheduler ticks (4 ms at
/// `CONFIG_HZ=250`) on the coarse timer wheel, and a read timing out with it was measured
/// 2 to 11 ms late (median 6 ms). The plant waits so for its next arrival, so every hop
/// (switch reached -> next actuator moves) carried that lateness.
fn readable(stream: &TcpStream, until: Instant) -> io::Result<bool> {
    use rustix::event::{poll, PollFd, PollFlags, Timespec};
    loop {
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Ok(false);
        }
        // At most a day per wait (`until` may be far off): the loop waits again.
        let left = left.min(Duration::from_secs(24 * 3600));
        let timeout = Timespec::try_from(left).map_err(io::Error::other)?;
        let mut fds = [PollFd::new(stream, PollFlags::IN)];
        match poll(&mut fds, Some(&timeout)) {
            Ok(0) => {}
            Ok(_) => return Ok(true),
            Err(rustix::io::Errno::INTR) => {}
            Err(e) => return Err(e.into()),
        }
    }
}

/// What [`Conn::next_in`] did with the next message.
enum Next<T> {
    Taken(T),
    Declined,
    TimedOut,
}

/// Whether `e`, met on a connection to the medium, says the medium went away: the
/// connection ended (a read), or was reset or broken under a write, whichever came first.
pub fn went_away(e: &io::Error) -> bool {
    use io::ErrorKind::{BrokenPipe, ConnectionAborted, ConnectionReset, UnexpectedEof};
    matches!(
        e.kind(),
        UnexpectedEof | BrokenPipe | ConnectionReset | ConnectionAborted
    )
}

/// A write's error, said as a read's end is when it means that the medium went away: not
/// as this process's own output breaking.
fn gone(e: io::Error, medium: SocketAddr) -> io::Error {
    if went_away(&e) {
        return closed(e.kind(), medium);
    }
    e
}

/// The medium at `medium` ended the connection (a read's end, or a write's reset).
fn closed(kind: io::ErrorKind, medium: SocketAddr) -> io::Error {
    io::Error::new(
        kind,
        format!("the medium at {medium} closed the connection"),
    )
}
