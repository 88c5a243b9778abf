//! Connections held open, oldest first, at most a bound: the pages' event streams (at
//! most [`MAX_STREAMS`]) and the requests whose head is still being read (at most
//! [`MAX_HEADS`]). A newcomer past the bound closes the oldest, so streams that never read
//! (a stuck tab, a local process holding connections) and heads never finished (a client
//! that sends a byte now and then to hold connections: slowloris) cannot keep a page out;
//! a page whose stream was closed opens another by itself (`EventSource`) and gets the
//! state at once, and a page's request is read as it comes, in far less than the time it
//! takes that many newer heads to arrive.

use std::collections::VecDeque;
use std::net::{Shutdown, TcpStream};
use std::sync::{Mutex, MutexGuard};

/// At most this many pages stream at once (each holds a thread).
pub const MAX_STREAMS: usize = 32;

/// At most this many requests are read at once (each holds a thread).
pub const MAX_HEADS: usize = 48;

/// The connections open, oldest first, at most `max`.
pub struct Streams {
    open: Mutex<Open>,
    max: usize,
}

impl Default for Streams {
    /// The pages' event streams: at most [`MAX_STREAMS`].
    fn default() -> Self {
        Streams::bounded(MAX_STREAMS)
    }
}

#[derive(Default)]
struct Open {
    next: u64,
    /// Each stream's number and a handle of its socket (to close it).
    streams: VecDeque<(u64, TcpStream)>,
}

/// A stream's place among the open ones, given back when dropped.
#[must_use]
pub struct Slot<'s> {
    streams: &'s Streams,
    id: u64,
}

impl Streams {
    /// At most `max` connections (at least one).
    pub fn bounded(max: usize) -> Self {
        Streams {
            open: Mutex::default(),
            max: max.max(1),
        }
    }

    /// A place for the connection on `socket`, closing the oldest if the bound's many are
    /// open (its thread finds its socket closed at its next read or write). Fails only if
    /// the socket cannot be shared.
    pub fn open(&self, socket: &TcpStream) -> std::io::Result<Slot<'_>> {
        let handle = socket.try_clone()?;
        let mut open = self.lock();
        while open.streams.len() >= self.max {
            if let Some((_, oldest)) = open.streams.pop_front() {
                let _ = oldest.shutdown(Shutdown::Both);
            }
        }
        let id = open.next;
        open.next += 1;
        open.streams.push_back((id, handle));
        Ok(Slot { streams: self, id })
    }

    /// How many streams are open.
    pub fn len(&self) -> usize {
        self.lock().streams.len()
    }

    /// Whether no stream is open.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn lock(&self) -> MutexGuard<'_, Open> {
        self.open.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl Drop for Slot<'_> {
    fn drop(&mut self) {
        // Gone already if a newcomer closed it.
        self.streams.lock().streams.retain(|(id, _)| *id != self.id);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;
    use std::net::TcpListener;

    /// A connected pair: the server's end, the client's.
    fn pair(listener: &TcpListener) -> (TcpStream, TcpStream) {
        let client = TcpStream::connect(listener.local_addr().expect("addr")).expect("connects");
        let (server, _) = listener.accept().expect("accepts");
        (server, client)
    }

    #[test]
    fn a_newcomer_past_the_bound_closes_the_oldest_stream_only() {
        let listener = TcpListener::bind("127.0.0.1:0").expect("binds");
        let streams = Streams::default();
        let pairs: Vec<_> = (0..=MAX_STREAMS).map(|_| pair(&listener)).collect();
        let mut slots = Vec::new();
        for (server, _) in &pairs[..MAX_STREAMS] {
            slots.push(streams.open(server).expect("a slot"));
        }
        assert_eq!(streams.len(), MAX_STREAMS);
        slots.push(streams.open(&pairs[MAX_STREAMS].0).expect("a slot"));
        assert_eq!(streams.len(), MAX_STREAMS);
        // The oldest's client reads the end; the next oldest's is still open.
        let mut oldest = &pairs[0].1;
        assert_eq!(oldest.read(&mut [0u8; 8]).expect("reads"), 0);
        let mut next = &pairs[1].1;
        next.set_nonblocking(true).expect("nonblocking");
        let err = next
            .read(&mut [0u8; 8])
            .expect_err("nothing to read, not the end");
        assert_eq!(err.kind(), std::io::ErrorKind::WouldBlock);
        // The closed stream's slot, dropped after, frees no other.
        drop(slots.remove(0));
        assert_eq!(streams.len(), MAX_STREAMS);
        drop(slots.remove(0));
        assert_eq!(streams.len(), MAX_STREAMS - 1);
        drop(slots);
        assert!(streams.is_empty());
    }
}
