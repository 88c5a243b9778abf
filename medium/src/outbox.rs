//! One client's outbox: a bounded queue of encoded messages and the thread that writes
//! them, so a client that reads slowly (or not at all) never holds up the air thread.

use std::io::{self, Write};
use std::net::{Shutdown, TcpStream};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::thread;

use config_schema::wire::medium::{Link, Peer, MAX_LINK};

use super::{limits, ClientId};

/// Why a message was not queued.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Refused {
    /// The outbox is full: the client is not reading fast enough.
    Full,
    /// The writer stopped (the connection is gone).
    Gone,
}

/// The sending end of a client's outbox.
pub(super) struct Outbox {
    tx: SyncSender<Vec<u8>>,
    stream: TcpStream,
}

impl Outbox {
    /// Starts the writer thread of `stream`.
    pub fn start(id: ClientId, stream: TcpStream, peer: Peer) -> io::Result<Outbox> {
        stream.set_write_timeout(Some(limits::WRITE_TIMEOUT))?;
        socket2::SockRef::from(&stream).set_send_buffer_size(limits::SOCKET_BUFFER)?;
        let (tx, rx) = mpsc::sync_channel(limits::OUTBOX);
        let writer = stream.try_clone()?;
        thread::Builder::new()
            .name(format!("medium-out-{id}-{peer:?}"))
            .spawn(move || write_all(writer, rx))?;
        Ok(Outbox { tx, stream })
    }

    /// Queues `msg`, never waiting.
    pub fn put(&self, msg: &Link) -> Result<(), Refused> {
        let mut buf = [0u8; MAX_LINK];
        let Ok(n) = msg.emit(&mut buf) else {
            return Ok(());
        };
        let bytes = buf.get(..n).unwrap_or_default().to_vec();
        match self.tx.try_send(bytes) {
            Ok(()) => Ok(()),
            Err(TrySendError::Full(_)) => Err(Refused::Full),
            Err(TrySendError::Disconnected(_)) => Err(Refused::Gone),
        }
    }

    /// Closes the connection (its reader then reports the client gone).
    pub fn close(&self) {
        let _ = self.stream.shutdown(Shutdown::Both);
    }
}

/// Writes queued messages (what is queued together, in one write) until the queue closes
/// or a write fails (or takes too long).
fn write_all(mut stream: TcpStream, rx: Receiver<Vec<u8>>) {
    let mut batch = Vec::with_capacity(16 * MAX_LINK);
    while let Ok(first) = rx.recv() {
        batch.clear();
        batch.extend_from_slice(&first);
        while batch.len() < 15 * MAX_LINK {
            let Ok(more) = rx.try_recv() else { break };
            batch.extend_from_slice(&more);
        }
        if stream.write_all(&batch).is_err() {
            let _ = stream.shutdown(Shutdown::Both);
            return;
        }
    }
}
