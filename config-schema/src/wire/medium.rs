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
    /// Node -> medium -> plant / monitor: node `addr` runs table generation `generation`
    /// from now on (sent at boot and at every activation, before any pin the new table
    /// drives), so a plant's trace says under which generation each step ran.
    Running { addr: u16, generation: u32 },
    /// Client -> medium: answer `Now` with the medium's clock.
    Clock,
    /// Medium -> client: the answer to `Clock`: `at_us` microseconds after the medium
    /// started, the clock of `Seen` (a monitor stamps the frames it hears with it).
    Now { at_us: u64 },
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

    /// A node's output level as the medium saw it: `(at_us, addr, pin, level)`.
    pub fn output_seen(&self) -> Option<(u64, u16, u8, bool)> {
        match *self {
            Link::Seen {
                at_us,
                addr,
                pin,
                level,
                output: true,
            } => Some((at_us, addr, pin, level)),
            _ => None,
        }
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

/// The stream announced a message longer than [`MAX_LINK`] (`len`: its body's length). The
/// deframer skips it, bytes as they come, and goes on after it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TooLong {
    pub len: usize,
}

/// Splits a byte stream into messages: the one reader of every medium connection (the
/// medium's, its clients', a node's, the gateway's serial line). A fixed buffer of `N`
/// bytes (at least [`MAX_LINK`]), no allocation; bytes go in through [`Deframer::space`]
/// and [`Deframer::filled`] (or [`Deframer::push`]), whole message bodies come out of
/// [`Deframer::take`].
#[derive(Debug, Clone)]
pub struct Deframer<const N: usize> {
    buf: [u8; N],
    /// Unread bytes are `buf[start..end]`.
    start: usize,
    end: usize,
    /// Bytes of a too-long message still to skip.
    skip: usize,
    /// A too-long length is taken for a framing slip (a serial line's stray byte), not a
    /// message: one byte is dropped and the length read again one byte on
    /// ([`Deframer::resynchronising`]).
    resync: bool,
}

impl<const N: usize> Default for Deframer<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Deframer<N> {
    const HOLDS_A_MESSAGE: () = assert!(N >= MAX_LINK, "a deframer holds a whole message");

    pub const fn new() -> Self {
        let () = Self::HOLDS_A_MESSAGE;
        Deframer {
            buf: [0; N],
            start: 0,
            end: 0,
            skip: 0,
            resync: false,
        }
    }

    /// A deframer for a line that can lose or gain bytes (a serial line: noise, a UART
    /// glitch at power-up), where a stream over TCP cannot: a length longer than any
    /// message drops one byte, not the length, so the next whole message is found again
    /// at once. (Skipping the length, a stray byte before `0E 00` read as a length of
    /// 3,584 skipped that much real traffic, and again at the slip it landed on.)
    pub const fn resynchronising() -> Self {
        let mut d = Self::new();
        d.resync = true;
        d
    }

    /// Room for more bytes (never empty: a partial message is shorter than `MAX_LINK`).
    /// Unread bytes move to the front first.
    pub fn space(&mut self) -> &mut [u8] {
        if self.start > 0 {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
        self.buf.get_mut(self.end..).unwrap_or_default()
    }

    /// `n` bytes were written at the start of [`Deframer::space`].
    pub fn filled(&mut self, n: usize) {
        self.end = (self.end + n).min(N);
    }

    /// Copies as much of `bytes` as fits; returns how much it took. Take the messages out
    /// with [`Deframer::take`], then push the rest.
    pub fn push(&mut self, bytes: &[u8]) -> usize {
        let space = self.space();
        let n = bytes.len().min(space.len());
        space[..n].copy_from_slice(&bytes[..n]);
        self.filled(n);
        n
    }

    /// Whether a whole message is buffered (so [`Deframer::take`] returns it). For a reader
    /// that returns the body it finds from a loop that also reads. A too-long message is
    /// reported once, then skipped.
    pub fn complete(&mut self) -> Result<bool, TooLong> {
        if self.skip > 0 {
            let n = self.skip.min(self.end - self.start);
            self.start += n;
            self.skip -= n;
            if self.skip > 0 {
                return Ok(false);
            }
        }
        let unread = self.buf.get(self.start..self.end).unwrap_or_default();
        let len = match unread {
            [lo, hi, ..] => usize::from(u16::from_le_bytes([*lo, *hi])),
            _ => return Ok(false),
        };
        if 2 + len > MAX_LINK && self.resync {
            self.start += 1;
            return Err(TooLong { len });
        }
        if 2 + len > MAX_LINK {
            // Skip what is buffered of it now, the rest as it comes; the next call reports
            // the message after it (which may be too long as well).
            let now = (2 + len).min(unread.len());
            self.start += now;
            self.skip = 2 + len - now;
            return Err(TooLong { len });
        }
        Ok(unread.len() >= 2 + len)
    }

    /// The next whole message's body (consumed), `None` until one is complete.
    pub fn take(&mut self) -> Result<Option<&[u8]>, TooLong> {
        if !self.complete()? {
            return Ok(None);
        }
        let unread = self.buf.get(self.start..self.end).unwrap_or_default();
        let Some(body) = next_message(unread) else {
            return Ok(None);
        };
        let (from, to) = (self.start + body.start, self.start + body.end);
        self.start = to;
        Ok(self.buf.get(from..to))
    }

    /// Bytes buffered and not yet returned.
    pub fn pending(&self) -> usize {
        self.end - self.start
    }

    /// Drops everything buffered.
    pub fn clear(&mut self) {
        self.start = 0;
        self.end = 0;
        self.skip = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_deframer_splits_a_stream_fed_in_any_pieces() {
        // Welcome, Sync(300), Pin { 0x12, 3, true }.
        let stream = [1, 0, 3, 3, 0, 4, 0xAC, 0x02, 4, 0, 2, 0x12, 3, 1];
        let want = [
            Link::Welcome,
            Link::Sync(300),
            Link::Pin {
                addr: 0x12,
                pin: 3,
                level: true,
            },
        ];
        for piece in 1..=stream.len() {
            let mut d = Deframer::<MAX_LINK>::new();
            let mut got = 0;
            for chunk in stream.chunks(piece) {
                assert_eq!(d.push(chunk), chunk.len());
                while let Some(body) = d.take().unwrap() {
                    assert_eq!(Link::parse(body).as_ref(), Ok(&want[got]), "{piece}");
                    got += 1;
                }
            }
            assert_eq!((got, d.pending()), (3, 0), "{piece}");
        }
    }

    #[test]
    fn a_message_past_max_link_is_reported_once_and_skipped() {
        let mut d = Deframer::<MAX_LINK>::new();
        // A 600-byte body, fed in pieces, then Welcome.
        let mut stream = [0xAA; 605];
        stream[..2].copy_from_slice(&[0x58, 0x02]);
        stream[602..].copy_from_slice(&[1, 0, 3]);
        let mut reported = 0;
        let mut got = 0;
        for chunk in stream.chunks(50) {
            assert_eq!(d.push(chunk), chunk.len());
            loop {
                match d.take() {
                    Err(TooLong { len }) => {
                        assert_eq!(len, 600);
                        reported += 1;
                    }
                    Ok(Some(body)) => {
                        assert_eq!(Link::parse(body), Ok(Link::Welcome));
                        got += 1;
                    }
                    Ok(None) => break,
                }
            }
        }
        assert_eq!((reported, got, d.pending()), (1, 1, 0));
        // Two too-long messages in a row, in one piece: each is reported.
        let mut two = [0xAA; 2 * 202 + 3];
        two[..2].copy_from_slice(&[200, 0]);
        two[202..204].copy_from_slice(&[200, 0]);
        two[404..].copy_from_slice(&[1, 0, 3]);
        let mut d = Deframer::<{ 4 * MAX_LINK }>::new();
        assert_eq!(d.push(&two), two.len());
        assert_eq!(d.take(), Err(TooLong { len: 200 }));
        assert_eq!(d.take(), Err(TooLong { len: 200 }));
        assert_eq!(d.take().map(|b| b.map(<[u8]>::len)), Ok(Some(1)));
        let mut d = Deframer::<MAX_LINK>::new();
        // The largest message fits, exactly.
        let mut whole = [0u8; MAX_LINK];
        whole[0] = (MAX_LINK - 2) as u8;
        assert_eq!(d.push(&whole), MAX_LINK);
        assert_eq!(d.take().unwrap().map(<[u8]>::len), Some(MAX_LINK - 2));
        assert_eq!(d.take(), Ok(None));
    }

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
    fn the_clock_and_its_answer_are_variants_8_and_9() {
        let mut buf = [0u8; MAX_LINK];
        let n = Link::Clock.emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], &[1, 0, 8]);
        let n = Link::Now { at_us: 300 }.emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], &[3, 0, 9, 0xAC, 0x02]);
        assert_eq!(Link::parse(&[9, 0xAC, 0x02]), Ok(Link::Now { at_us: 300 }));
    }

    #[test]
    fn garbage_is_malformed() {
        assert_eq!(Link::parse(&[9, 9, 9]), Err(LinkError::Malformed));
        assert_eq!(Link::parse(&[]), Err(LinkError::Malformed));
    }

    /// A stray `00` before `Welcome` (`01 00 03`) reads as the length 0x0100: too long.
    /// The resynchronising deframer drops one byte and finds `Welcome` and `Sync(300)`;
    /// the plain one skips 258 bytes, both messages with them.
    #[test]
    fn a_resynchronising_deframer_finds_the_messages_after_a_stray_byte() {
        let stream = [0x00, 1, 0, 3, 3, 0, 4, 0xAC, 0x02];
        let mut d = Deframer::<MAX_LINK>::resynchronising();
        assert_eq!(d.push(&stream), stream.len());
        assert_eq!(d.take(), Err(TooLong { len: 0x0100 }));
        assert_eq!(d.take().unwrap().map(Link::parse), Some(Ok(Link::Welcome)));
        assert_eq!(
            d.take().unwrap().map(Link::parse),
            Some(Ok(Link::Sync(300)))
        );
        assert_eq!(d.take(), Ok(None));
        let mut plain = Deframer::<MAX_LINK>::new();
        assert_eq!(plain.push(&stream), stream.len());
        assert_eq!(plain.take(), Err(TooLong { len: 0x0100 }));
        assert_eq!(plain.take(), Ok(None));
    }
}
