//! The secured frame of a running machine's link messages (`Event`, `EventAck`), read and
//! written on a short path of its own: exactly the frame [`secure_default_mpdu_with`]
//! writes for such a message (data frame, short addresses, PAN id compression, 2006, no
//! acknowledgement request; ENC-MIC-64 with a key index), its headers compared as bytes,
//! its payload put together and opened in a buffer its size. Any other frame is not one:
//! [`SealedLink::new`] says `None` and the general path ([`open_default_mpdu_with`]) takes
//! it, which answers these frames exactly as this does (tests below hold the two equal).
//!
//! ```text
//! | frame control (2) | seq | PAN id (2) | dst (2) | src (2) |      MAC header (9)
//! | security control | frame counter (4, LE) | key index |     aux header (6)
//! | payload (1..=8, encrypted)  | MIC (8) |
//!  \__ a data: bytes 0..15 ___/  (the MIC covers the headers and the plaintext)
//! ```
//!
//! [`secure_default_mpdu_with`]: super::secure_default_mpdu_with
//! [`open_default_mpdu_with`]: super::open_default_mpdu_with

use super::star::{self, Direction, MIC_LEN};
use super::{
    ext_addr, nonce, AuxRepr, BlockCipher, SecError, SecurityLevel, AUX_LEN_KEY_INDEX,
    CONTROL_KEY_ID_MODE_SHIFT, KEY_LEN,
};
use crate::wire::mac::{data_header, Header, DATA_HEADER_LEN, FCS_LEN, MAX_PSDU, SECURED_DATA_FC};
use crate::wire::msg::LinkMessage;

/// The security control byte of these frames: ENC-MIC-64, key identifier mode 1 (a key
/// index).
pub const CONTROL: u8 = SecurityLevel::EncMic64.bits() | 1 << CONTROL_KEY_ID_MODE_SHIFT;
/// The a data: MAC header and aux header.
pub const A_LEN: usize = DATA_HEADER_LEN + AUX_LEN_KEY_INDEX;

mod field {
    pub type Field = core::ops::Range<usize>;
    pub const FC: Field = 0..2;
    pub const SEQ: usize = 2;
    pub const PAN: Field = 3..5;
    pub const DST: Field = 5..7;
    pub const SRC: Field = 7..9;
    pub const CONTROL: usize = 9;
    pub const COUNTER: Field = 10..14;
    pub const KEY_INDEX: usize = 14;
}

/// A secured link frame, its headers checked: [`SealedLink::new`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SealedLink<'a> {
    a: &'a [u8; A_LEN],
    /// The encrypted payload, 1 to `LinkMessage::MAX_LEN` bytes.
    m: &'a [u8],
    mic: &'a [u8; MIC_LEN],
}

/// Two little-endian bytes of `a` at `f` (in range: `a` is the whole a data).
fn u16_at(a: &[u8; A_LEN], f: field::Field) -> u16 {
    match a.get(f) {
        Some(&[b0, b1]) => u16::from_le_bytes([b0, b1]),
        _ => 0,
    }
}

impl<'a> SealedLink<'a> {
    /// `mpdu` (no FCS) if it is such a frame on `pan` to `dst`: the frame control field,
    /// PAN id, destination and security control these frames have, a payload of 1 to
    /// `LinkMessage::MAX_LEN` bytes and a frame counter below `u32::MAX` (the last is never
    /// sent). `None`: any other frame.
    #[inline]
    pub fn new(mpdu: &'a [u8], pan: u16, dst: u16) -> Option<SealedLink<'a>> {
        let (a, rest) = mpdu.split_first_chunk::<A_LEN>()?;
        let (m, mic) = rest.split_last_chunk::<MIC_LEN>()?;
        let frame = SealedLink { a, m, mic };
        let fits = !m.is_empty() && m.len() <= LinkMessage::MAX_LEN;
        (fits
            && u16_at(a, field::FC) == SECURED_DATA_FC
            && u16_at(a, field::PAN) == pan
            && u16_at(a, field::DST) == dst
            && a.get(field::CONTROL) == Some(&CONTROL)
            && frame.counter() != u32::MAX)
            .then_some(frame)
    }

    /// The sender's short address.
    pub fn src(&self) -> u16 {
        u16_at(self.a, field::SRC)
    }

    /// The frame counter.
    pub fn counter(&self) -> u32 {
        match self.a.get(field::COUNTER) {
            Some(&[c0, c1, c2, c3]) => u32::from_le_bytes([c0, c1, c2, c3]),
            _ => u32::MAX,
        }
    }

    /// The key index.
    pub fn key_index(&self) -> u8 {
        self.a.get(field::KEY_INDEX).copied().unwrap_or(0)
    }

    /// The MAC header's fields, as the general parse gives them.
    pub fn header(&self) -> Header {
        Header {
            seq: self.a.get(field::SEQ).copied().unwrap_or(0),
            pan_id: u16_at(self.a, field::PAN),
            dst: u16_at(self.a, field::DST),
            src: self.src(),
            ack_request: false,
            secured: true,
        }
    }

    /// The aux header's fields.
    pub fn aux(&self) -> AuxRepr {
        AuxRepr::new(self.key_index(), self.counter())
    }

    /// Checks the MIC under `key` (the sender's link key; the nonce takes the sender's
    /// extended address, [`ext_addr`] of the PAN and `src`) and decrypts the payload into
    /// `out`: its bytes. On any error `out` is zeroed (no unauthenticated plaintext is
    /// left behind): [`SecError::BadMic`], or [`SecError::Cipher`] if a block failed.
    pub fn open<'o, C: BlockCipher>(
        &self,
        key: &[u8; KEY_LEN],
        out: &'o mut [u8; LinkMessage::MAX_LEN],
    ) -> Result<&'o [u8], SecError> {
        let header = self.header();
        let nonce = nonce(
            &ext_addr(header.pan_id, header.src),
            self.counter(),
            SecurityLevel::EncMic64,
        );
        let (m, _) = out.split_at_mut(self.m.len().min(LinkMessage::MAX_LEN));
        m.iter_mut().zip(self.m).for_each(|(o, c)| *o = *c);
        let opened = match star::ccm_star_64(&C::new(key), &nonce, self.a, m, Direction::Open) {
            Ok(tag) if star::same_mic(&tag, self.mic) => Ok(m.len()),
            Ok(_) => Err(SecError::BadMic),
            Err(e) => Err(e),
        };
        match opened {
            Ok(n) => Ok(out.get(..n).unwrap_or_default()),
            Err(e) => {
                out.fill(0);
                Err(e)
            }
        }
    }
}

/// Secures the frame in `out` whose payload, `n` bytes, is in place already (from
/// [`A_LEN`], where such a frame's payload starts): writes its MAC and aux headers in
/// front of it (the frame this firmware writes, for any payload: data, short addresses,
/// PAN id compression, no acknowledgement request whatever `header.ack_request` says,
/// ENC-MIC-64 with key index `key_index`, frame counter `counter`), encrypts the payload
/// under `key` and writes the
/// MIC after it. Returns the MPDU's length: the bytes [`secure_default_mpdu_with`] writes
/// for the same payload, without a copy of it. [`SecError::NoRoom`] if the MPDU would not
/// fit `out` or a frame; nothing to send on that, [`SecError::CounterExhausted`]
/// (`u32::MAX` is never sent) or [`SecError::Cipher`].
///
/// [`secure_default_mpdu_with`]: super::secure_default_mpdu_with
pub fn seal_in_place<C: BlockCipher>(
    header: &Header,
    key_index: u8,
    counter: u32,
    key: &[u8; KEY_LEN],
    out: &mut [u8],
    n: usize,
) -> Result<usize, SecError> {
    if counter == u32::MAX {
        return Err(SecError::CounterExhausted);
    }
    let len = n.saturating_add(A_LEN + MIC_LEN);
    if len.saturating_add(FCS_LEN) > MAX_PSDU {
        return Err(SecError::NoRoom);
    }
    let [h0, h1, h2, h3, h4, h5, h6, h7, h8] = data_header(&Header {
        ack_request: false,
        secured: true,
        ..*header
    });
    let [c0, c1, c2, c3] = counter.to_le_bytes();
    let (a, rest) = out
        .split_first_chunk_mut::<A_LEN>()
        .ok_or(SecError::NoRoom)?;
    *a = [
        h0, h1, h2, h3, h4, h5, h6, h7, h8, CONTROL, c0, c1, c2, c3, key_index,
    ];
    // The payload, then the MIC right after it.
    let (body, after) = rest.split_at_mut_checked(n).ok_or(SecError::NoRoom)?;
    let mic = after.first_chunk_mut::<MIC_LEN>().ok_or(SecError::NoRoom)?;
    let nonce = nonce(
        &ext_addr(header.pan_id, header.src),
        counter,
        SecurityLevel::EncMic64,
    );
    *mic = star::ccm_star_64(&C::new(key), &nonce, a, body, Direction::Seal)?;
    Ok(len)
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use crate::wire::mac::MAX_MPDU;
    use crate::wire::msg::Message;
    use crate::wire::security::{open_default_mpdu_with, secure_default_mpdu_with, SoftAes};
    use proptest::prelude::*;
    use std::vec::Vec;

    const KEY: [u8; KEY_LEN] = [0x42; KEY_LEN];
    const PAN: u16 = 0x4242;

    fn header(seq: u8, dst: u16, src: u16) -> Header {
        Header {
            seq,
            pan_id: PAN,
            dst,
            src,
            ack_request: false,
            secured: false,
        }
    }

    /// The general codec's frame of `m`.
    fn general(h: &Header, index: u8, counter: u32, m: LinkMessage) -> Option<Vec<u8>> {
        let mut payload = [0u8; 16];
        let n = Message::from(m).emit(&mut payload).ok()?;
        let mut out = [0u8; MAX_MPDU];
        let aux = AuxRepr::new(index, counter);
        let len = secure_default_mpdu_with::<SoftAes>(
            h,
            &aux,
            &KEY,
            ext_addr(h.pan_id, h.src),
            &payload[..n],
            &mut out,
        )
        .ok()?;
        Some(out[..len].to_vec())
    }

    /// `m` written after the headers and sealed in place, as a node sends it.
    fn sealed(h: &Header, index: u8, counter: u32, m: LinkMessage) -> Option<Vec<u8>> {
        let mut out = [0u8; MAX_MPDU];
        let payload = out[A_LEN..].first_chunk_mut::<{ LinkMessage::MAX_LEN }>()?;
        let n = m.write(payload);
        let len = seal_in_place::<SoftAes>(h, index, counter, &KEY, &mut out, n).ok()?;
        Some(out[..len].to_vec())
    }

    fn message() -> impl Strategy<Value = LinkMessage> {
        prop_oneof![
            (any::<u16>(), any::<u16>(), any::<u8>())
                .prop_map(|(epoch, seq, topic)| LinkMessage::Event { epoch, seq, topic }),
            (any::<u16>(), any::<u16>())
                .prop_map(|(epoch, next)| LinkMessage::EventAck { epoch, next }),
        ]
    }

    /// An event as a node writes it, byte for byte: the headers as literals, then the
    /// encrypted payload and the MIC (those of the general codec, which the Annex C and
    /// OpenSSL tests check).
    #[test]
    fn an_event_is_these_bytes() {
        let m = LinkMessage::Event {
            epoch: 1,
            seq: 2,
            topic: 3,
        };
        let frame = sealed(&header(7, 2, 1), 5, 0x0102_0304, m).unwrap();
        assert_eq!(
            frame[..A_LEN],
            [
                0x49, 0x98, // data, security, PAN id compression, 2006, short addresses
                7, 0x42, 0x42, // seq, PAN
                2, 0, 1, 0,    // dst, src
                0x0E, // ENC-MIC-64, key index mode
                4, 3, 2, 1, // frame counter, little-endian
                5, // key index
            ]
        );
        assert_eq!(frame.len(), A_LEN + 4 + MIC_LEN);
        assert_eq!(Some(frame), general(&header(7, 2, 1), 5, 0x0102_0304, m));
    }

    proptest! {
        /// A message sealed in place is the general codec's frame for every message, address, counter and
        /// key index (nothing where the codec sends nothing: the last counter), and
        /// `SealedLink` opens it to the message, where the general path opens it to the
        /// same payload.
        #[test]
        fn the_short_path_writes_and_opens_the_general_codecs_frames(
            m in message(),
            seq in any::<u8>(),
            src in any::<u16>(),
            index in any::<u8>(),
            counter in prop_oneof![any::<u32>(), Just(u32::MAX), Just(u32::MAX - 1)],
        ) {
            let h = header(seq, 2, src);
            let frame = sealed(&h, index, counter, m);
            prop_assert_eq!(&frame, &general(&h, index, counter, m));
            let Some(frame) = frame.as_deref() else { return Ok(()) };
            let link = SealedLink::new(frame, PAN, 2).unwrap();
            prop_assert_eq!(link.src(), src);
            prop_assert_eq!(link.counter(), counter);
            prop_assert_eq!(link.key_index(), index);
            prop_assert_eq!(link.header(), Header { secured: true, ..h });
            prop_assert_eq!(link.aux(), AuxRepr::new(index, counter));
            let mut out = [0u8; LinkMessage::MAX_LEN];
            let opened = link.open::<SoftAes>(&KEY, &mut out).unwrap();
            prop_assert_eq!(LinkMessage::parse(opened), Some(m));
            let mut scratch = [0u8; 127];
            let general = open_default_mpdu_with::<SoftAes, _>(
                frame,
                |h, _| Some((KEY, ext_addr(h.pan_id, h.src))),
                &mut scratch,
            )
            .unwrap();
            prop_assert_eq!(general.payload, opened);
        }

        /// Any change to a frame's bytes: either not such a frame (the general path's), or
        /// its MIC fails and nothing of the payload is left; the general path refuses it
        /// with the same error.
        #[test]
        fn a_damaged_frame_does_not_open(
            m in message(),
            at in 0usize..A_LEN + LinkMessage::MAX_LEN + MIC_LEN,
            flip in 1u8..=255,
        ) {
            let mut frame = sealed(&header(0, 2, 1), 1, 10, m).unwrap();
            let at = at % frame.len();
            frame[at] ^= flip;
            let Some(link) = SealedLink::new(&frame, PAN, 2) else { return Ok(()) };
            let mut out = [0u8; LinkMessage::MAX_LEN];
            let e = link.open::<SoftAes>(&KEY, &mut out).unwrap_err();
            prop_assert_eq!(e, SecError::BadMic);
            prop_assert_eq!(out, [0u8; LinkMessage::MAX_LEN]);
            let mut scratch = [0u8; 127];
            let general = open_default_mpdu_with::<SoftAes, _>(
                &frame,
                |h, _| Some((KEY, ext_addr(h.pan_id, h.src))),
                &mut scratch,
            );
            prop_assert_eq!(general, Err(SecError::BadMic));
        }
    }

    proptest! {
        /// `seal_in_place` writes the general codec's frame for any payload that fits a
        /// frame, and refuses one that does not.
        #[test]
        fn sealing_in_place_writes_the_general_codecs_frame(
            payload in proptest::collection::vec(any::<u8>(), 0..110),
            seq in any::<u8>(),
            dst in any::<u16>(),
            index in any::<u8>(),
            counter in prop_oneof![any::<u32>(), Just(u32::MAX)],
        ) {
            let h = header(seq, dst, 1);
            let mut out = [0u8; MAX_MPDU];
            out[A_LEN..A_LEN + payload.len()].copy_from_slice(&payload);
            let short = seal_in_place::<SoftAes>(&h, index, counter, &KEY, &mut out, payload.len())
                .map(|n| out[..n].to_vec());
            let mut general = [0u8; MAX_MPDU];
            let aux = AuxRepr::new(index, counter);
            let general = secure_default_mpdu_with::<SoftAes>(
                &h,
                &aux,
                &KEY,
                ext_addr(h.pan_id, h.src),
                &payload,
                &mut general,
            )
            .map(|n| general[..n].to_vec());
            prop_assert_eq!(short, general);
        }
    }

    /// Frames of another kind, or to another node or PAN, are not such frames.
    #[test]
    fn only_these_frames_are_taken() {
        let m = LinkMessage::EventAck { epoch: 0, next: 1 };
        let frame = sealed(&header(0, 2, 1), 1, 10, m).unwrap();
        assert!(SealedLink::new(&frame, PAN, 2).is_some());
        assert!(SealedLink::new(&frame, PAN + 1, 2).is_none());
        assert!(SealedLink::new(&frame, PAN, 3).is_none());
        let changed = |at: usize, v: u8| {
            let mut f = frame.clone();
            f[at] = v;
            f
        };
        // Acknowledgement requested; another level; a key source.
        assert!(SealedLink::new(&changed(0, 0x69), PAN, 2).is_none());
        assert!(SealedLink::new(&changed(9, 0x0D), PAN, 2).is_none());
        assert!(SealedLink::new(&changed(9, 0x16), PAN, 2).is_none());
        // The last counter is never sent.
        let mut last = frame.clone();
        last[10..14].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(SealedLink::new(&last, PAN, 2).is_none());
        // No payload, or one longer than a link message.
        let mut empty = frame[..A_LEN].to_vec();
        empty.extend_from_slice(&[0; MIC_LEN]);
        assert!(SealedLink::new(&empty, PAN, 2).is_none());
        let mut long = frame[..A_LEN].to_vec();
        long.extend_from_slice(&[0; LinkMessage::MAX_LEN + 1 + MIC_LEN]);
        assert!(SealedLink::new(&long, PAN, 2).is_none());
        assert!(SealedLink::new(&frame[..A_LEN + MIC_LEN], PAN, 2).is_none());
    }
}
