//! A client's connection to a medium (the tool's radio, the plant, the monitor, the
//! gateway bridge): joins and waits to be welcomed, sends messages, and reads them one at
//! a time with a deadline, so every client reads the stream the same way.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use config_schema::wire::medium::{next_message, Link, Peer, MAX_LINK};

/// How long a client waits for the medium's `Welcome` (and a `Synced`).
pub const JOIN_TIMEOUT: Duration = Duration::from_secs(5);

/// Bytes of a partial message a client keeps at most (a message is at most `MAX_LINK`).
const PENDING: usize = 2 + u16::MAX as usize;

/// A joined connection.
pub struct Conn {
    stream: TcpStream,
    pending: Vec<u8>,
    syncs: u32,
}

impl Conn {
    /// Connects as `peer` and returns once the medium routes to this client.
    pub fn join(medium: SocketAddr, peer: Peer) -> io::Result<Conn> {
        let stream = TcpStream::connect_timeout(&medium, JOIN_TIMEOUT)?;
        stream.set_nodelay(true)?;
        let mut conn = Conn {
            stream,
            pending: Vec::new(),
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
        self.stream.write_all(buf.get(..n).unwrap_or_default())
    }

    /// A barrier: returns once the medium has handled everything sent before. Messages
    /// received meanwhile stay queued for [`Conn::recv`].
    pub fn sync(&mut self) -> io::Result<()> {
        self.syncs = self.syncs.wrapping_add(1);
        let n = self.syncs;
        self.send(&Link::Sync(n))?;
        let until = Instant::now() + JOIN_TIMEOUT;
        let mut kept = Vec::new();
        let done = loop {
            match self.next_raw(until)? {
                None => break false,
                Some(raw) => {
                    if Link::parse(&raw).is_ok_and(|l| l == Link::Synced(n)) {
                        break true;
                    }
                    kept.extend_from_slice(&(raw.len() as u16).to_le_bytes());
                    kept.extend_from_slice(&raw);
                }
            }
        };
        kept.append(&mut self.pending);
        self.pending = kept;
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
        while let Some(raw) = self.next_raw(until)? {
            if let Some(t) = Link::parse(&raw).ok().and_then(&mut pick) {
                return Ok(Some(t));
            }
        }
        Ok(None)
    }

    /// The next message body, or `None` once `until` passes.
    fn next_raw(&mut self, until: Instant) -> io::Result<Option<Vec<u8>>> {
        loop {
            if let Some(body) = next_message(&self.pending) {
                let raw = self.pending.get(body.clone()).unwrap_or_default().to_vec();
                self.pending.drain(..body.end);
                return Ok(Some(raw));
            }
            let now = Instant::now();
            if now >= until {
                return Ok(None);
            }
            self.stream
                .set_read_timeout(Some((until - now).max(Duration::from_millis(1))))?;
            let mut chunk = [0u8; 4096];
            match self.stream.read(&mut chunk) {
                Ok(0) => {
                    return Err(io::Error::new(
                        io::ErrorKind::UnexpectedEof,
                        "the medium closed the connection",
                    ))
                }
                Ok(n) => {
                    self.pending
                        .extend_from_slice(chunk.get(..n).unwrap_or_default());
                    if self.pending.len() > PENDING {
                        return Err(io::Error::new(
                            io::ErrorKind::InvalidData,
                            "the medium sent something that is not a message",
                        ));
                    }
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) => {}
                Err(e) => return Err(e),
            }
        }
    }

    /// A second handle on the same connection (for a writer in another thread).
    pub fn try_clone_stream(&self) -> io::Result<TcpStream> {
        self.stream.try_clone()
    }
}
