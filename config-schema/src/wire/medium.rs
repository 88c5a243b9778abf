//! The connection to the simulated 802.15.4 medium (TCP on loopback; the QEMU UART bridge
//! uses the same framing): each message is a `u16` little-endian length and then the
//! postcard encoding of a [`Link`] message.
//!
//! Who connects: a **node** (its radio and its pins), the **tool** (a radio with an address),
//! a **plant** (the machine: it sees the nodes' output pins and drives their input pins, by
//! node address and pin number, so a plant attaches without the node knowing its role),
//! and a **monitor** (sees every frame and pin change).
//!
//! A connection starts with the client's `Hello`; the medium answers `Welcome` once it
//! routes to the client (nothing sent to the client before it is lost to a race). `Sync(n)`
//! is a barrier: the medium answers `Synced(n)` once it has handled every message the client
//! sent before it (a plant's switch levels are at the nodes before anything sent after).
//! Output levels reach plants and monitors as `Seen`, stamped with the medium's clock when
//! the medium saw the change (the time a step happened, whatever the reader's delays).

use serde::{Deserialize, Serialize};

/// Largest encoded [`Link`] message.
pub const MAX_LINK: usize = 160;

/// Who is on the other end of a connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Peer {
    Node { addr: u16 },
    Tool { addr: u16 },
    Plant,
    Monitor,
}

/// One message on a medium connection.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum Link<'a> {
    /// The first message of a connection.
    Hello(Peer),
    /// A PSDU, FCS included. Client -> medium: transmit. Medium -> client: received.
    Frame(#[serde(borrow)] &'a [u8]),
    /// A pin level. Node -> medium -> plant/monitor: output `pin` of node `addr`.
    /// Plant -> medium -> node: input `pin` of node `addr`.
    Pin { addr: u16, pin: u8, level: bool },
    /// Medium -> client: the answer to `Hello`; the medium routes to this client now.
    Welcome,
    /// Client -> medium: answer `Synced` with the same number once every message sent
    /// before this one is handled.
    Sync(u32),
    /// Medium -> client: the answer to `Sync`.
    Synced(u32),
    /// Medium -> plant / monitor: a pin level as the medium saw it, `at_us` microseconds
    /// after the medium started: a node's output (`output`), or an input level a plant
    /// drove (monitors only).
    Seen {
        at_us: u64,
        addr: u16,
        pin: u8,
        level: bool,
        output: bool,
    },
}

/// Why bytes are not a link message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkError {
    /// The buffer is too small.
    NoRoom,
    /// Not a message.
    Malformed,
}

impl<'a> Link<'a> {
    /// Writes length and message into `buf`; returns the bytes written.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, LinkError> {
        let body = buf.get_mut(2..).ok_or(LinkError::NoRoom)?;
        let n = postcard::to_slice(self, body)
            .map_err(|_| LinkError::NoRoom)?
            .len();
        buf[..2].copy_from_slice(&(n as u16).to_le_bytes());
        Ok(n + 2)
    }

    /// Parses one message body (without its length). Never panics.
    pub fn parse(body: &'a [u8]) -> Result<Link<'a>, LinkError> {
        match postcard::take_from_bytes::<Link<'a>>(body) {
            Ok((msg, [])) => Ok(msg),
            _ => Err(LinkError::Malformed),
        }
    }
}

/// The length prefix of a message, if `buf` holds at least one whole message: returns the
/// body's range.
pub fn next_message(buf: &[u8]) -> Option<core::ops::Range<usize>> {
    let len = usize::from(u16::from_le_bytes([*buf.first()?, *buf.get(1)?]));
    (buf.len() >= 2 + len).then_some(2..2 + len)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_with_length_prefix() {
        let psdu = [1u8, 2, 3, 4, 5];
        let mut buf = [0u8; MAX_LINK];
        for msg in [
            Link::Hello(Peer::Node { addr: 0x0012 }),
            Link::Frame(&psdu),
            Link::Pin {
                addr: 0x0012,
                pin: 3,
                level: true,
            },
            Link::Welcome,
            Link::Sync(7),
            Link::Synced(u32::MAX),
            Link::Seen {
                at_us: u64::MAX,
                addr: 0xFFFF,
                pin: 255,
                level: true,
                output: false,
            },
        ] {
            let n = msg.emit(&mut buf).unwrap();
            let body = next_message(&buf[..n]).unwrap();
            assert_eq!(body, 2..n);
            assert_eq!(Link::parse(&buf[body]), Ok(msg));
            assert_eq!(next_message(&buf[..n - 1]), None, "incomplete");
        }
    }

    #[test]
    fn a_full_psdu_fits() {
        let psdu = [0xAAu8; crate::wire::mac::MAX_PSDU];
        let mut buf = [0u8; MAX_LINK];
        assert!(Link::Frame(&psdu).emit(&mut buf).is_ok());
    }

    #[test]
    fn the_first_variants_keep_their_bytes() {
        // Hello(Node 0x12), Pin: what a node and a plant of an earlier build send.
        let mut buf = [0u8; MAX_LINK];
        let n = Link::Hello(Peer::Node { addr: 0x0012 })
            .emit(&mut buf)
            .unwrap();
        assert_eq!(&buf[..n], &[3, 0, 0, 0, 0x12]);
        let n = Link::Welcome.emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], &[1, 0, 3]);
        let n = Link::Sync(300).emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], &[3, 0, 4, 0xAC, 0x02]);
    }

    #[test]
    fn garbage_is_malformed() {
        assert_eq!(Link::parse(&[9, 9, 9]), Err(LinkError::Malformed));
        assert_eq!(Link::parse(&[]), Err(LinkError::Malformed));
    }
}
