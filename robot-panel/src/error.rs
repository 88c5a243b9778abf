//! What can stop the panel, typed. No `error:` prefix: the binary adds it.

use std::io;
use std::net::SocketAddr;

#[derive(Debug, thiserror::Error)]
pub enum PanelError {
    /// The robot does not give a page (its wiring does not load).
    #[error("{0}")]
    Robot(String),
    #[error(
        "cannot listen on {addr}: the address is in use (another panel, or another \
         program, listens there): give another --listen"
    )]
    InUse { addr: SocketAddr },
    #[error("cannot listen on {addr}: {source}")]
    Listen {
        addr: SocketAddr,
        #[source]
        source: io::Error,
    },
    #[error("cannot reach the medium at {addr}: {source}")]
    Medium {
        addr: SocketAddr,
        #[source]
        source: io::Error,
    },
    #[error("the panel's token: {0}")]
    Token(String),
    #[error("panel thread: {0}")]
    Thread(#[source] io::Error),
}
