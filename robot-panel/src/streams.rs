//! The pages' event streams open at once: at most [`MAX_STREAMS`]. A newcomer past them
//! closes the oldest, so streams that never read (a stuck tab, a local process holding
//! connections) cannot keep a page out; a page whose stream was closed opens another by
//! itself (`EventSource`) and gets the state at once.

use std::collections::VecDeque;
use std::net::{Shutdown, TcpStream};
use std::sync::{Mutex, MutexGuard};

/// At most this many pages stream at once (each holds a thread).
pub const MAX_STREAMS: usize = 32;

/// The streams open, oldest first.
#[derive(Default)]
pub struct Streams {
    open: Mutex<Open>,
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
    /// A place for the stream on `socket`, closing the oldest stream if [`MAX_STREAMS`]
    /// are open (its thread finds its socket closed at its next write). Fails only if the
    /// socket cannot be shared.
    pub fn open(&self, socket: &TcpStream) -> std::io::Result<Slot<'_>> {
        let handle = socket.try_clone()?;
        let mut open = self.lock();
        while open.streams.len() >= MAX_STREAMS {
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
