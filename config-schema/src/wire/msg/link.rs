//! `Event` and `EventAck`, the messages of every step of a running machine, written and
//! read on a short path of their own: the same bytes as the codec's (variant index, then
//! each `u16` as a varint, the topic one raw byte). Only canonical encodings are read
//! here and only into a buffer they fit; anything else goes to the codec, so
//! [`Message::parse`], [`Message::parse_node`] and [`Message::emit`] answer exactly as
//! without it. With it the node core takes 1,363 instructions per event received
//! instead of 1,736, 631 per ack instead of 950 (`bench/instructions.sh`, x86-64).

use super::Message;

const EVENT: u8 = 0;
const EVENT_ACK: u8 = 1;

/// An `Event` or an `EventAck` alone: the messages of a running machine, read and written
/// on the short path without the whole [`Message`] (a node core's per-event path).
/// [`LinkMessage::parse`] takes exactly the payloads [`Message::parse_node`] reads on this
/// path, as the same message; [`LinkMessage::write`] writes [`Message::emit`]'s bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LinkMessage {
    /// [`Message::Event`].
    Event { epoch: u16, seq: u16, topic: u8 },
    /// [`Message::EventAck`].
    EventAck { epoch: u16, next: u16 },
}

impl LinkMessage {
    /// The longest encoding.
    pub const MAX_LEN: usize = 8;

    /// `payload` as an `Event` or `EventAck` in its canonical encoding; `None`: anything
    /// else (another message, a longer encoding, trailing bytes: [`Message::parse_node`]'s
    /// codec path).
    #[inline]
    pub fn parse(payload: &[u8]) -> Option<LinkMessage> {
        Self::short_event(payload).or_else(|| Self::parse_fields(payload))
    }

    /// An event with a one-byte epoch and a one- or two-byte seq (a link's first 16,384
    /// events), matched as a whole; `None`: anything else (read field by field).
    #[inline(always)]
    fn short_event(payload: &[u8]) -> Option<LinkMessage> {
        match *payload {
            [EVENT, epoch, seq, topic] if epoch < 0x80 && seq < 0x80 => Some(LinkMessage::Event {
                epoch: u16::from(epoch),
                seq: u16::from(seq),
                topic,
            }),
            [EVENT, epoch, s0, s1, topic] if epoch < 0x80 && s0 >= 0x80 && s1 != 0 && s1 < 0x80 => {
                Some(LinkMessage::Event {
                    epoch: u16::from(epoch),
                    seq: u16::from(s0 & 0x7F) | u16::from(s1) << 7,
                    topic,
                })
            }
            _ => None,
        }
    }

    /// The short event [`LinkMessage::parse`] reads as a whole (a link's first 16,384
    /// events: a one-byte epoch, a one- or two-byte seq) as its `(epoch, seq, topic)`,
    /// read in the caller's code (a call cost more than the read: the node core's short
    /// path of a frame in clear), the fields straight to the caller (no [`LinkMessage`]
    /// merged with the other reads); `None`: anything else, which
    /// [`LinkMessage::parse_fields`] reads as `parse` does.
    #[inline(always)]
    pub fn event_fields(payload: &[u8]) -> Option<(u16, u16, u8)> {
        let (epoch, seq, topic) = match *payload {
            [EVENT, epoch, seq, topic] if seq < 0x80 => (epoch, u16::from(seq), topic),
            [EVENT, epoch, s0, s1, topic] if s0 >= 0x80 && s1 != 0 && s1 < 0x80 => {
                (epoch, u16::from(s0 & 0x7F) | u16::from(s1) << 7, topic)
            }
            _ => return None,
        };
        (epoch < 0x80).then_some((u16::from(epoch), seq, topic))
    }

    /// [`LinkMessage::parse`] of anything but a short event ([`LinkMessage::event_fields`]
    /// read `None`): field by field.
    #[inline(never)]
    pub fn parse_fields(payload: &[u8]) -> Option<LinkMessage> {
        let (&tag, rest) = payload.split_first()?;
        match tag {
            EVENT => {
                let (epoch, rest) = take(rest)?;
                let (seq, rest) = take(rest)?;
                match rest {
                    [topic] => Some(LinkMessage::Event {
                        epoch,
                        seq,
                        topic: *topic,
                    }),
                    _ => None,
                }
            }
            EVENT_ACK => {
                let (epoch, rest) = take(rest)?;
                let (next, rest) = take(rest)?;
                rest.is_empty()
                    .then_some(LinkMessage::EventAck { epoch, next })
            }
            _ => None,
        }
    }

    /// `msg` if it is an `Event` or `EventAck`.
    #[inline]
    pub fn of(msg: &Message<'_>) -> Option<LinkMessage> {
        match *msg {
            Message::Event { epoch, seq, topic } => Some(LinkMessage::Event { epoch, seq, topic }),
            Message::EventAck { epoch, next } => Some(LinkMessage::EventAck { epoch, next }),
            _ => None,
        }
    }

    /// Writes the message into `out` (the bytes [`Message::emit`] writes); returns its
    /// length.
    #[inline(always)]
    pub fn write(&self, out: &mut [u8; Self::MAX_LEN]) -> usize {
        match *self {
            LinkMessage::Event { epoch, seq, topic } => {
                out[0] = EVENT;
                let n = put(epoch, out, 1);
                let n = put(seq, out, n);
                out[n & 7] = topic;
                n + 1
            }
            LinkMessage::EventAck { epoch, next } => {
                out[0] = EVENT_ACK;
                let n = put(epoch, out, 1);
                put(next, out, n)
            }
        }
    }
}

impl From<LinkMessage> for Message<'_> {
    #[inline]
    fn from(m: LinkMessage) -> Self {
        match m {
            LinkMessage::Event { epoch, seq, topic } => Message::Event { epoch, seq, topic },
            LinkMessage::EventAck { epoch, next } => Message::EventAck { epoch, next },
        }
    }
}

pub(super) fn emit(msg: &Message<'_>, buf: &mut [u8]) -> Option<usize> {
    let m = LinkMessage::of(msg)?;
    // Room for the longest (8 bytes): written in place, only its own bytes touched.
    if let Some(out) = buf.first_chunk_mut::<8>() {
        return Some(m.write(out));
    }
    let mut out = [0u8; 8];
    let n = m.write(&mut out);
    // Too small a buffer: postcard says so in its own words.
    buf.get_mut(..n)?.copy_from_slice(out.get(..n)?);
    Some(n)
}

/// Writes `v` as a varint into `out` from `at` (at most 3 bytes); returns the end.
#[inline]
fn put(v: u16, out: &mut [u8; 8], at: usize) -> usize {
    if v < 0x80 {
        out[at & 7] = v as u8;
        at + 1
    } else if v < 0x4000 {
        out[at & 7] = (v as u8) | 0x80;
        out[(at + 1) & 7] = (v >> 7) as u8;
        at + 2
    } else {
        out[at & 7] = (v as u8) | 0x80;
        out[(at + 1) & 7] = ((v >> 7) as u8) | 0x80;
        out[(at + 2) & 7] = (v >> 14) as u8;
        at + 3
    }
}

pub(super) fn parse(payload: &[u8]) -> Option<Message<'static>> {
    LinkMessage::parse(payload).map(Message::from)
}

/// A canonical varint `u16` (the shortest encoding) at the start of `b`.
#[inline]
fn take(b: &[u8]) -> Option<(u16, &[u8])> {
    match *b {
        [a, ref rest @ ..] if a < 0x80 => Some((u16::from(a), rest)),
        [a, b1, ref rest @ ..] if b1 != 0 && b1 < 0x80 => {
            Some((u16::from(a & 0x7F) | u16::from(b1) << 7, rest))
        }
        [a, b1, c, ref rest @ ..] if b1 >= 0x80 && c != 0 && c <= 0x03 => Some((
            u16::from(a & 0x7F) | u16::from(b1 & 0x7F) << 7 | u16::from(c) << 14,
            rest,
        )),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::super::{codec, MessageError};
    use super::*;

    fn by_codec(payload: &[u8]) -> Result<Message<'_>, MessageError> {
        let mut r = codec::In::new(payload);
        let msg = codec::message(&mut r);
        r.end().map(|()| msg)
    }

    /// Every event and ack of four, five and six bytes whose epoch and first seq byte are
    /// any byte (the second seq byte at the short read's bounds): the short read and the
    /// read of what it leaves together read what `parse` reads, and the short read only
    /// canonical events, as the general parse reads them. (The property test below draws
    /// 256 of these; a 2-byte seq is seldom one it draws.)
    #[test]
    fn the_short_read_and_the_rest_read_every_small_payload_as_parse_does() {
        for tag in 0u8..3 {
            for e in 0..=255u8 {
                for s0 in 0..=255u8 {
                    for s1 in [0u8, 1, 0x7E, 0x7F, 0x80, 0x81, 0xFE, 0xFF] {
                        for payload in [
                            &[tag, e, s0, 9][..],
                            &[tag, e, s0, s1, 9][..],
                            &[tag, e, s0, s1, 9, 0][..],
                        ] {
                            let short =
                                LinkMessage::event_fields(payload).map(|(epoch, seq, topic)| {
                                    LinkMessage::Event { epoch, seq, topic }
                                });
                            let read = short.or_else(|| LinkMessage::parse_fields(payload));
                            assert_eq!(read, LinkMessage::parse(payload), "{payload:02x?}");
                            if let Some(m) = short {
                                assert_eq!(Message::parse(payload), Ok(Message::from(m)));
                                let mut out = [0u8; LinkMessage::MAX_LEN];
                                let n = m.write(&mut out);
                                assert_eq!(&out[..n], payload, "canonical");
                            }
                        }
                    }
                }
            }
        }
    }

    proptest! {
        /// An event of four or five bytes (read as a whole when its epoch is one byte and
        /// its seq one or two) reads as the codec reads it, and is read exactly when it is
        /// an event in its canonical encoding (the bytes `write` gives back).
        #[test]
        fn a_short_event_reads_as_the_codec_reads_it(
            tag in 0u8..3, e in any::<u8>(), s0 in any::<u8>(), s1 in any::<u8>(), t in any::<u8>(),
        ) {
            for payload in [&[tag, e, s0, t][..], &[tag, e, s0, s1, t][..]] {
                let canonical = match by_codec(payload) {
                    Ok(Message::Event { epoch, seq, topic }) => {
                        let m = LinkMessage::Event { epoch, seq, topic };
                        let mut out = [0u8; LinkMessage::MAX_LEN];
                        let n = m.write(&mut out);
                        (out[..n] == *payload).then_some(m)
                    }
                    _ => None,
                };
                if tag == EVENT {
                    prop_assert_eq!(LinkMessage::parse(payload), canonical);
                }
                // The short read reads only what `parse` reads, as the same event; what it
                // leaves, `parse_fields` reads as `parse` does.
                match LinkMessage::event_fields(payload) {
                    Some((epoch, seq, topic)) => prop_assert_eq!(
                        LinkMessage::parse(payload),
                        Some(LinkMessage::Event { epoch, seq, topic })
                    ),
                    None => prop_assert_eq!(
                        LinkMessage::parse_fields(payload),
                        LinkMessage::parse(payload)
                    ),
                }
                prop_assert_eq!(Message::parse(payload), by_codec(payload));
            }
        }

        /// Any short payload of the first variants reads as the codec alone reads it.
        #[test]
        fn short_payloads_read_as_the_codec_reads_them(
            tag in 0u8..3, body in proptest::collection::vec(any::<u8>(), 0..8),
        ) {
            let mut payload = [tag; 9];
            payload[1..=body.len()].copy_from_slice(&body);
            let payload = &payload[..=body.len()];
            prop_assert_eq!(Message::parse(payload), by_codec(payload));
            let mut r = codec::In::new(payload);
            let heard = codec::heard(&mut r);
            prop_assert_eq!(Message::parse_node(payload), r.end().map(|()| heard));
        }

        /// Events and acks are written as the codec writes them, into any buffer.
        #[test]
        fn events_and_acks_are_written_as_the_codec_writes_them(
            epoch: u16, seq: u16, topic: u8, len in 0usize..10,
        ) {
            for msg in [Message::Event { epoch, seq, topic }, Message::EventAck { epoch, next: seq }] {
                let (mut ours, mut theirs) = ([0u8; 10], [0u8; 10]);
                let a = msg.emit(&mut ours[..len]);
                let mut w = codec::Out::new(&mut theirs[..len]);
                codec::emit(&msg, &mut w);
                prop_assert_eq!(a, w.len());
                if let Ok(n) = a {
                    prop_assert_eq!(&ours[..n], &theirs[..n]);
                    prop_assert_eq!(Message::parse(&ours[..n]), Ok(msg.clone()));
                }
            }
        }
    }
}
