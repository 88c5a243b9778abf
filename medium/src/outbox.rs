//! One client's outbox: a bounded queue of encoded messages and the thread that writes
//! them, so a client that reads slowly (or not at all) never holds up the medium.
//!
//! A message goes straight into the socket when nothing is queued before it and the
//! socket takes it at once (`send` with `MSG_DONTWAIT`: the usual case, one thread wake-up
//! fewer per message); otherwise it waits in the queue for the writer thread, in order.

use std::collections::VecDeque;
use std::io::{self, Write};
use std::net::{Shutdown, TcpStream};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread;

use config_schema::wire::medium::{Link, Peer, MAX_LINK};
use rustix::io::Errno;
use rustix::net::{send, SendFlags};

use super::{limits, ClientId};

/// Why a message was not queued.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Refused {
    /// The outbox is full: the client is not reading fast enough.
    Full,
    /// The writer stopped (the connection is gone).
    Gone,
}

/// What the sending side and the writer thread share.
#[derive(Default)]
struct Queue {
    /// Encoded messages (or the rest of one the socket took in part), oldest first: at
    /// most `limits::OUTBOX`.
    waiting: VecDeque<Vec<u8>>,
    /// The writer thread is writing a batch it took off `waiting`.
    writing: bool,
    /// No more messages: the writer thread stops (the outbox was dropped or a write failed).
    closed: bool,
}

struct Shared {
    queue: Mutex<Queue>,
    /// Signalled when a message is queued or the outbox closes.
    ready: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Queue> {
        self.queue.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// The sending end of a client's outbox.
pub(super) struct Outbox {
    shared: Arc<Shared>,
    stream: TcpStream,
}

impl Outbox {
    /// Starts the writer thread of `stream`.
    pub fn start(id: ClientId, stream: TcpStream, peer: Peer) -> io::Result<Outbox> {
        stream.set_write_timeout(Some(limits::WRITE_TIMEOUT))?;
        socket2::SockRef::from(&stream).set_send_buffer_size(limits::SOCKET_BUFFER)?;
        let shared = Arc::new(Shared {
            queue: Mutex::new(Queue::default()),
            ready: Condvar::new(),
        });
        let writer = stream.try_clone()?;
        let theirs = shared.clone();
        thread::Builder::new()
            .name(format!("medium-out-{id}-{peer:?}"))
            .spawn(move || write_all(writer, &theirs))?;
        Ok(Outbox { shared, stream })
    }

    /// Sends or queues `msg`, never waiting.
    pub fn put(&self, msg: &Link) -> Result<(), Refused> {
        let mut buf = [0u8; MAX_LINK];
        let Ok(n) = msg.emit(&mut buf) else {
            return Ok(());
        };
        let bytes = buf.get(..n).unwrap_or_default();
        let mut queue = self.shared.lock();
        if queue.closed {
            return Err(Refused::Gone);
        }
        let mut rest = bytes;
        if queue.waiting.is_empty() && !queue.writing {
            // Nothing before it: the socket may take it now. The lock is held, so the
            // writer thread cannot start a batch in between (and `send` never blocks).
            match send(
                &self.stream,
                bytes,
                SendFlags::DONTWAIT | SendFlags::NOSIGNAL,
            ) {
                Ok(sent) => rest = bytes.get(sent..).unwrap_or_default(),
                Err(Errno::AGAIN | Errno::INTR) => {}
                Err(_) => {
                    queue.closed = true;
                    drop(queue);
                    self.close();
                    return Err(Refused::Gone);
                }
            }
            if rest.is_empty() {
                return Ok(());
            }
        } else if queue.waiting.len() >= limits::OUTBOX {
            return Err(Refused::Full);
        }
        queue.waiting.push_back(rest.to_vec());
        self.shared.ready.notify_one();
        Ok(())
    }

    /// Closes the connection (its reader then reports the client gone).
    pub fn close(&self) {
        let _ = self.stream.shutdown(Shutdown::Both);
    }
}

impl Drop for Outbox {
    fn drop(&mut self) {
        self.shared.lock().closed = true;
        self.shared.ready.notify_one();
    }
}

/// Writes queued messages (what is queued together, in one write) until the outbox closes
/// or a write fails (or takes too long).
fn write_all(mut stream: TcpStream, shared: &Shared) {
    let mut batch = Vec::with_capacity(16 * MAX_LINK);
    loop {
        {
            let mut queue = shared.lock();
            queue.writing = false;
            while queue.waiting.is_empty() && !queue.closed {
                queue = shared.ready.wait(queue).unwrap_or_else(|p| p.into_inner());
            }
            if queue.waiting.is_empty() {
                return;
            }
            batch.clear();
            while batch.len() < 15 * MAX_LINK {
                let Some(next) = queue.waiting.pop_front() else {
                    break;
                };
                batch.extend_from_slice(&next);
            }
            queue.writing = true;
        }
        if stream.write_all(&batch).is_err() {
            shared.lock().closed = true;
            let _ = stream.shutdown(Shutdown::Both);
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use std::io::Read;
    use std::net::TcpListener;

    use config_schema::wire::medium::Deframer;

    use super::*;

    /// A connected pair: the outbox's end and the client's.
    fn pair() -> (Outbox, TcpStream) {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let client = TcpStream::connect(listener.local_addr().unwrap()).unwrap();
        let (theirs, _) = listener.accept().unwrap();
        (Outbox::start(1, theirs, Peer::Plant).unwrap(), client)
    }

    fn synced(n: u32) -> Link<'static> {
        Link::Synced(n)
    }

    /// Every `Synced(n)` the client reads, until it has `count` of them.
    fn read(client: &mut TcpStream, count: usize) -> Vec<u32> {
        let mut incoming = Box::new(Deframer::<{ 8 * MAX_LINK }>::new());
        let mut got = Vec::new();
        while got.len() < count {
            while let Some(body) = incoming.take().unwrap() {
                match Link::parse(body).unwrap() {
                    Link::Synced(n) => got.push(n),
                    other => panic!("the outbox was given no {other:?}"),
                }
            }
            if got.len() < count {
                let n = client.read(incoming.space()).unwrap();
                assert!(n > 0, "the outbox closed after {} messages", got.len());
                incoming.filled(n);
            }
        }
        got
    }

    #[test]
    fn messages_sent_at_once_and_queued_behind_a_full_socket_arrive_in_order() {
        let (outbox, mut client) = pair();
        // The client does not read: the socket fills, then the queue, then it is full.
        let mut taken = 0u32;
        let refused = loop {
            match outbox.put(&synced(taken)) {
                Ok(()) => taken += 1,
                Err(refused) => break refused,
            }
            assert!(taken < 1_000_000, "the outbox never filled");
        };
        assert_eq!(refused, Refused::Full);
        assert!(
            outbox.shared.lock().waiting.len() == limits::OUTBOX,
            "the queue holds its bound when full"
        );
        let got = read(&mut client, taken as usize);
        assert_eq!(got, (0..taken).collect::<Vec<_>>());
        // Drained: the next one goes out again, after everything before it.
        outbox.put(&synced(taken)).unwrap();
        assert_eq!(read(&mut client, 1), vec![taken]);
    }

    #[test]
    fn a_client_gone_is_refused_as_gone() {
        let (outbox, client) = pair();
        drop(client);
        // The first write may still be taken by the kernel; a later one learns the reset.
        let refused = (0..1000).find_map(|n| outbox.put(&synced(n)).err());
        assert_eq!(refused, Some(Refused::Gone));
    }
}
