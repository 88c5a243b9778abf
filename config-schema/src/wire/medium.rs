//! The connection to the simulated 802.15.4 medium (TCP on loopback; the QEMU UART bridge
//! uses the same framing): each message is a `u16` little-endian length and then the
//! postcard encoding of a [`Link`] message.
//!
//! Who connects: a **node** (its radio and its pins), the **tool** (a radio with an address),
//! a **plant** (the machine: it sees the nodes' output pins and drives their input pins, by
//! node address and pin number, so a plant attaches without the node knowing its role),
//! and a **monitor** (sees every frame and pin change).

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
    fn garbage_is_malformed() {
        assert_eq!(Link::parse(&[9, 9, 9]), Err(LinkError::Malformed));
        assert_eq!(Link::parse(&[]), Err(LinkError::Malformed));
    }
}
