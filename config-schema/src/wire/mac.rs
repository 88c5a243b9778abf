//! IEEE 802.15.4-2006 MAC frames: the subset the nodes speak.
//!
//! Data and acknowledgement frames; 16-bit short addresses with PAN ID compression (one PAN
//! id, the destination's); sequence number; FCS = CRC-16/KERMIT appended little-endian.
//! Anything else (beacons, MAC commands, extended addresses, inter-PAN frames) is parsed far
//! enough to be rejected with [`FrameError::Unsupported`].
//!
//! The FCS seam: the node core deals in MPDUs, the frame without its FCS
//! ([`Frame::parse_mpdu`], [`emit_data_mpdu`]); the radio edge adds and checks the FCS
//! ([`append_fcs`], [`strip_fcs`]): the nRF52840's radio in hardware, the host medium
//! transport and the QEMU UART in software. What travels on the medium, in pcap files and
//! through the tool's radio are PSDUs with a correct FCS ([`Frame::parse`], [`emit_data`],
//! [`emit_ack`]: the same codec with the FCS step at either end).
//!
//! Security: the frame-control "security enabled" bit is carried in [`Header::secured`].
//! A secured frame has an auxiliary security header after the addressing fields and a MIC
//! before the FCS; this module hands its payload out untouched, and [`super::security`]
//! secures and opens it (AES-CCM*) between this codec and the application messages.
//!
//! ```text
//! data frame, PSDU:
//! | FC (2) | seq (1) | dst PAN (2) | dst addr (2) | src addr (2) | payload (n) | FCS (2) |
//! ack frame:  | FC (2) | seq (1) | FCS (2) |
//! ```

use core::fmt;

/// Largest PSDU of the 2.4 GHz PHY.
pub const MAX_PSDU: usize = 127;
/// Frame check sequence length.
pub const FCS_LEN: usize = 2;
/// Largest MPDU (a PSDU without its FCS): what the node core sends and receives.
pub const MAX_MPDU: usize = MAX_PSDU - FCS_LEN;
/// MAC header length of a data frame with short addresses and PAN ID compression.
pub const DATA_HEADER_LEN: usize = 9;
/// Largest payload of such a data frame.
pub const MAX_PAYLOAD: usize = MAX_PSDU - DATA_HEADER_LEN - FCS_LEN;
/// Length of an acknowledgement frame.
pub const ACK_LEN: usize = 5;
/// The broadcast short address.
pub const BROADCAST: u16 = 0xFFFF;

/// The FCS CRC.
pub const FCS: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_KERMIT);

const TYPE_DATA: u16 = 0b001;
const TYPE_ACK: u16 = 0b010;
const FC_SECURITY: u16 = 1 << 3;
const FC_PENDING: u16 = 1 << 4;
const FC_ACK_REQUEST: u16 = 1 << 5;
const FC_PAN_COMPRESSION: u16 = 1 << 6;
const ADDR_SHORT: u16 = 0b10;
const VERSION_2006: u16 = 0b01;

/// The frame control field of a data frame as [`finish_data_mpdu`] writes it without
/// security or an acknowledgement request (short addresses, PAN id compression, 2006): a
/// receiver's short path can compare the first two bytes against it.
pub const PLAIN_DATA_FC: u16 =
    TYPE_DATA | FC_PAN_COMPRESSION | (ADDR_SHORT << 10) | (VERSION_2006 << 12) | (ADDR_SHORT << 14);

/// [`PLAIN_DATA_FC`] with the security bit: the frame control field of a data frame as
/// frame security writes it (`security::secure_default_mpdu_with`).
pub const SECURED_DATA_FC: u16 = PLAIN_DATA_FC | FC_SECURITY;

/// Why bytes are not a frame we accept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameError {
    /// Shorter than its header and FCS.
    Truncated,
    /// Longer than a PSDU.
    Oversized,
    /// The FCS does not match.
    BadFcs,
    /// A frame type, addressing mode or version this node does not speak.
    Unsupported,
    /// The payload does not fit the buffer or the PSDU (emit).
    NoRoom,
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FrameError::Truncated => "truncated frame",
            FrameError::Oversized => "frame longer than 127 bytes",
            FrameError::BadFcs => "FCS mismatch",
            FrameError::Unsupported => "unsupported frame type or addressing",
            FrameError::NoRoom => "payload does not fit the frame",
        })
    }
}

impl core::error::Error for FrameError {}

/// The MAC header fields of a data frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    pub seq: u8,
    pub pan_id: u16,
    pub dst: u16,
    pub src: u16,
    /// Ask the receiver's MAC for an acknowledgement frame.
    pub ack_request: bool,
    /// Security enabled: the payload starts with an auxiliary security header.
    pub secured: bool,
}

/// A parsed frame, borrowing its payload from the PSDU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Frame<'a> {
    Data { header: Header, payload: &'a [u8] },
    Ack { seq: u8, pending: bool },
}

/// The radio edge on receipt: checks a PSDU's FCS and returns the MPDU before it.
/// [`FrameError::Oversized`] past [`MAX_PSDU`], [`FrameError::Truncated`] shorter than the
/// FCS, [`FrameError::BadFcs`] if it does not match. Never panics.
pub fn strip_fcs(psdu: &[u8]) -> Result<&[u8], FrameError> {
    if psdu.len() > MAX_PSDU {
        return Err(FrameError::Oversized);
    }
    let split = psdu
        .len()
        .checked_sub(FCS_LEN)
        .ok_or(FrameError::Truncated)?;
    let (body, fcs) = psdu.split_at(split);
    let stored = u16::from_le_bytes([fcs[0], fcs[1]]);
    if FCS.checksum(body) != stored {
        return Err(FrameError::BadFcs);
    }
    Ok(body)
}

fn le16(bytes: &[u8], at: usize) -> Result<u16, FrameError> {
    match bytes.get(at..at + 2) {
        Some(b) => Ok(u16::from_le_bytes([b[0], b[1]])),
        None => Err(FrameError::Truncated),
    }
}

impl<'a> Frame<'a> {
    /// Parses a PSDU (FCS included): [`strip_fcs`], then [`Frame::parse_mpdu`]. Never
    /// panics.
    pub fn parse(psdu: &'a [u8]) -> Result<Frame<'a>, FrameError> {
        Frame::parse_mpdu(strip_fcs(psdu)?)
    }

    /// Parses an MPDU (the frame without its FCS, checked at the radio edge). Never panics.
    pub fn parse_mpdu(body: &'a [u8]) -> Result<Frame<'a>, FrameError> {
        if body.len() > MAX_MPDU {
            return Err(FrameError::Oversized);
        }
        let fc = le16(body, 0)?;
        let seq = *body.get(2).ok_or(FrameError::Truncated)?;
        let frame_type = fc & 0b111;
        let dst_mode = (fc >> 10) & 0b11;
        let version = (fc >> 12) & 0b11;
        let src_mode = (fc >> 14) & 0b11;
        if version > VERSION_2006 {
            return Err(FrameError::Unsupported);
        }
        match frame_type {
            TYPE_ACK => {
                if body.len() != ACK_LEN - FCS_LEN {
                    return Err(FrameError::Unsupported);
                }
                Ok(Frame::Ack {
                    seq,
                    pending: fc & FC_PENDING != 0,
                })
            }
            TYPE_DATA => {
                if dst_mode != ADDR_SHORT || src_mode != ADDR_SHORT || fc & FC_PAN_COMPRESSION == 0
                {
                    return Err(FrameError::Unsupported);
                }
                let header = Header {
                    seq,
                    pan_id: le16(body, 3)?,
                    dst: le16(body, 5)?,
                    src: le16(body, 7)?,
                    ack_request: fc & FC_ACK_REQUEST != 0,
                    secured: fc & FC_SECURITY != 0,
                };
                let payload = body.get(DATA_HEADER_LEN..).ok_or(FrameError::Truncated)?;
                Ok(Frame::Data { header, payload })
            }
            _ => Err(FrameError::Unsupported),
        }
    }
}

/// The radio edge on transmit: appends the FCS over the MPDU `buf[..body_len]`; returns the
/// PSDU length.
pub fn append_fcs(buf: &mut [u8], body_len: usize) -> Result<usize, FrameError> {
    let total = body_len + FCS_LEN;
    if total > MAX_PSDU {
        return Err(FrameError::NoRoom);
    }
    let fcs = FCS.checksum(buf.get(..body_len).ok_or(FrameError::NoRoom)?);
    buf.get_mut(body_len..total)
        .ok_or(FrameError::NoRoom)?
        .copy_from_slice(&fcs.to_le_bytes());
    Ok(total)
}

/// Writes a data frame (FCS included) into `buf`; returns the PSDU length.
pub fn emit_data(header: &Header, payload: &[u8], buf: &mut [u8]) -> Result<usize, FrameError> {
    let body_len = DATA_HEADER_LEN + payload.len();
    if buf.len() < body_len + FCS_LEN {
        return Err(FrameError::NoRoom);
    }
    let body_len = emit_data_mpdu(header, payload, buf)?;
    append_fcs(buf, body_len)
}

/// Writes a data frame's MPDU (no FCS: the radio edge appends it) into `buf`; returns its
/// length, at most [`MAX_MPDU`].
pub fn emit_data_mpdu(
    header: &Header,
    payload: &[u8],
    buf: &mut [u8],
) -> Result<usize, FrameError> {
    if DATA_HEADER_LEN + payload.len() > MAX_MPDU {
        return Err(FrameError::NoRoom); // nothing written
    }
    let body = buf
        .get_mut(DATA_HEADER_LEN..)
        .and_then(|b| b.get_mut(..payload.len()));
    super::copy(body.ok_or(FrameError::NoRoom)?, payload).ok_or(FrameError::NoRoom)?;
    finish_data_mpdu(header, buf, payload.len())
}

/// Finishes a data frame's MPDU whose payload (`payload_len` bytes) was written in place at
/// `buf[DATA_HEADER_LEN..]`: writes the MAC header before it; returns the MPDU length. What
/// a node's unsecured send does (no payload buffer, no copy).
#[inline]
pub fn finish_data_mpdu(
    header: &Header,
    buf: &mut [u8],
    payload_len: usize,
) -> Result<usize, FrameError> {
    let body_len = DATA_HEADER_LEN + payload_len;
    if body_len > MAX_MPDU || buf.len() < body_len {
        return Err(FrameError::NoRoom);
    }
    emit_data_header(header, buf)?;
    Ok(body_len)
}

/// Writes the [`DATA_HEADER_LEN`] bytes of a data frame's MAC header into `buf`.
#[inline]
pub(crate) fn emit_data_header(header: &Header, buf: &mut [u8]) -> Result<(), FrameError> {
    let buf = buf
        .first_chunk_mut::<DATA_HEADER_LEN>()
        .ok_or(FrameError::NoRoom)?;
    *buf = data_header(header);
    Ok(())
}

/// The [`DATA_HEADER_LEN`] bytes of a data frame's MAC header (short addresses, PAN id
/// compression, 2006; the acknowledgement request and security bits from `header`).
#[inline]
pub const fn data_header(header: &Header) -> [u8; DATA_HEADER_LEN] {
    let mut fc = PLAIN_DATA_FC;
    if header.ack_request {
        fc |= FC_ACK_REQUEST;
    }
    if header.secured {
        fc |= FC_SECURITY;
    }
    // Put together from its fields, no slice copies (no panic locations).
    let [f0, f1] = fc.to_le_bytes();
    let [p0, p1] = header.pan_id.to_le_bytes();
    let [d0, d1] = header.dst.to_le_bytes();
    let [s0, s1] = header.src.to_le_bytes();
    [f0, f1, header.seq, p0, p1, d0, d1, s0, s1]
}

/// Writes an acknowledgement frame for `seq` into `buf`; returns the PSDU length (5).
pub fn emit_ack(seq: u8, pending: bool, buf: &mut [u8]) -> Result<usize, FrameError> {
    if buf.len() < ACK_LEN {
        return Err(FrameError::NoRoom);
    }
    let mut fc = TYPE_ACK | (VERSION_2006 << 12);
    if pending {
        fc |= FC_PENDING;
    }
    buf[0..2].copy_from_slice(&fc.to_le_bytes());
    buf[2] = seq;
    append_fcs(buf, 3)
}

/// Airtime of a PSDU at 250 kbit/s in microseconds, PHY overhead included (4 bytes preamble,
/// 1 byte SFD, 1 byte PHR: 32 us per byte).
pub const fn airtime_us(psdu_len: usize) -> u32 {
    ((psdu_len + 6) * 32) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> Header {
        Header {
            seq: 0x2A,
            pan_id: 0xBEEF,
            dst: 0x0003,
            src: 0x0001,
            ack_request: true,
            secured: false,
        }
    }

    #[test]
    fn data_frame_bytes_match_the_standard_layout() {
        let mut buf = [0u8; MAX_PSDU];
        let n = emit_data(&header(), &[0xAA, 0xBB], &mut buf).unwrap();
        // FC 0x9861: data, ack request, PAN compression, short/short, 2006.
        assert_eq!(
            &buf[..n - 2],
            &[0x61, 0x98, 0x2A, 0xEF, 0xBE, 0x03, 0x00, 0x01, 0x00, 0xAA, 0xBB]
        );
        let fcs = FCS.checksum(&buf[..n - 2]).to_le_bytes();
        assert_eq!(&buf[n - 2..n], &fcs);
        assert_eq!(
            Frame::parse(&buf[..n]),
            Ok(Frame::Data {
                header: header(),
                payload: &[0xAA, 0xBB]
            })
        );
    }

    #[test]
    fn kermit_check_value() {
        // CRC-16/KERMIT of "123456789" is 0x2189.
        assert_eq!(FCS.checksum(b"123456789"), 0x2189);
    }

    #[test]
    fn ack_frame_round_trip() {
        let mut buf = [0u8; 8];
        let n = emit_ack(7, false, &mut buf).unwrap();
        assert_eq!(n, ACK_LEN);
        assert_eq!(&buf[..3], &[0x02, 0x10, 0x07]);
        assert_eq!(
            Frame::parse(&buf[..n]),
            Ok(Frame::Ack {
                seq: 7,
                pending: false
            })
        );
    }

    #[test]
    fn damaged_frames_are_rejected_by_kind() {
        let mut buf = [0u8; MAX_PSDU];
        let n = emit_data(&header(), &[1, 2, 3], &mut buf).unwrap();
        assert_eq!(Frame::parse(&buf[..1]), Err(FrameError::Truncated));
        assert_eq!(Frame::parse(&[]), Err(FrameError::Truncated));
        let mut bad = buf;
        bad[4] ^= 0x01;
        assert_eq!(Frame::parse(&bad[..n]), Err(FrameError::BadFcs));
        assert_eq!(Frame::parse(&[0u8; 128]), Err(FrameError::Oversized));
        // A valid FCS over a header too short for its addressing fields.
        let mut short = [0x61, 0x98, 0x01, 0xEF, 0, 0];
        let fcs = FCS.checksum(&short[..4]).to_le_bytes();
        short[4..6].copy_from_slice(&fcs);
        assert_eq!(Frame::parse(&short), Err(FrameError::Truncated));
        // A beacon (frame type 0) with a valid FCS.
        let mut beacon = [0x00, 0x10, 0x01, 0, 0];
        let fcs = FCS.checksum(&beacon[..3]).to_le_bytes();
        beacon[3..5].copy_from_slice(&fcs);
        assert_eq!(Frame::parse(&beacon), Err(FrameError::Unsupported));
    }

    #[test]
    fn the_mpdu_is_the_psdu_without_its_fcs() {
        let mut psdu = [0u8; MAX_PSDU];
        let n = emit_data(&header(), &[0xAA, 0xBB], &mut psdu).unwrap();
        let mut mpdu = [0u8; MAX_MPDU];
        let m = emit_data_mpdu(&header(), &[0xAA, 0xBB], &mut mpdu).unwrap();
        assert_eq!((m, &mpdu[..m]), (n - FCS_LEN, &psdu[..n - FCS_LEN]));
        assert_eq!(strip_fcs(&psdu[..n]), Ok(&mpdu[..m]));
        assert_eq!(Frame::parse_mpdu(&mpdu[..m]), Frame::parse(&psdu[..n]));
        // The edge appends the FCS: the same PSDU.
        let mut again = [0u8; MAX_PSDU];
        again[..m].copy_from_slice(&mpdu[..m]);
        assert_eq!(append_fcs(&mut again, m), Ok(n));
        assert_eq!(again, psdu);
        // The edge refuses by kind.
        let mut bad = psdu;
        bad[n - 1] ^= 0x55;
        assert_eq!(strip_fcs(&bad[..n]), Err(FrameError::BadFcs));
        assert_eq!(strip_fcs(&psdu[..1]), Err(FrameError::Truncated));
        assert_eq!(strip_fcs(&[0u8; MAX_PSDU + 1]), Err(FrameError::Oversized));
        // An MPDU longer than a PSDU leaves room for is not one.
        assert_eq!(
            Frame::parse_mpdu(&[0u8; MAX_MPDU + 1]),
            Err(FrameError::Oversized)
        );
        let max = [0x55u8; MAX_PAYLOAD];
        assert_eq!(emit_data_mpdu(&header(), &max, &mut mpdu), Ok(MAX_MPDU));
        let over = [0x55u8; MAX_PAYLOAD + 1];
        let mut big = [0u8; MAX_PSDU];
        assert_eq!(
            emit_data_mpdu(&header(), &over, &mut big),
            Err(FrameError::NoRoom)
        );
        assert_eq!(append_fcs(&mut big, MAX_MPDU + 1), Err(FrameError::NoRoom));
        // The payload written in place, the header before it: the same MPDU.
        let mut inplace = [0u8; MAX_MPDU];
        inplace[DATA_HEADER_LEN..DATA_HEADER_LEN + 2].copy_from_slice(&[0xAA, 0xBB]);
        assert_eq!(finish_data_mpdu(&header(), &mut inplace, 2), Ok(m));
        assert_eq!(&inplace[..m], &psdu[..m]);
        assert_eq!(
            finish_data_mpdu(&header(), &mut inplace, MAX_PAYLOAD + 1),
            Err(FrameError::NoRoom)
        );
        assert_eq!(
            finish_data_mpdu(&header(), &mut inplace[..10], 2),
            Err(FrameError::NoRoom)
        );
    }

    #[test]
    fn payload_limits() {
        let mut buf = [0u8; MAX_PSDU];
        let max = [0x55u8; MAX_PAYLOAD];
        assert_eq!(emit_data(&header(), &max, &mut buf), Ok(MAX_PSDU));
        let over = [0x55u8; MAX_PAYLOAD + 1];
        assert_eq!(
            emit_data(&header(), &over, &mut buf),
            Err(FrameError::NoRoom)
        );
        let mut small = [0u8; 12];
        assert_eq!(
            emit_data(&header(), &[1, 2], &mut small),
            Err(FrameError::NoRoom)
        );
    }

    #[test]
    fn airtime_of_a_full_frame() {
        // 133 bytes on air at 32 us each.
        assert_eq!(airtime_us(MAX_PSDU), 4256);
    }

    mod props {
        use super::super::*;
        use proptest::prelude::*;

        proptest! {
            #[test]
            fn parse_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
                let _ = Frame::parse(&bytes);
            }

            #[test]
            fn parse_never_panics_on_valid_fcs(body in proptest::collection::vec(any::<u8>(), 0..130)) {
                let mut psdu = body.clone();
                psdu.extend_from_slice(&FCS.checksum(&body).to_le_bytes());
                let _ = Frame::parse(&psdu);
            }

            #[test]
            fn data_round_trip(
                seq in any::<u8>(), pan_id in any::<u16>(), dst in any::<u16>(), src in any::<u16>(),
                ack_request in any::<bool>(), secured in any::<bool>(),
                payload in proptest::collection::vec(any::<u8>(), 0..=MAX_PAYLOAD),
            ) {
                let header = Header { seq, pan_id, dst, src, ack_request, secured };
                let mut buf = [0u8; MAX_PSDU];
                let n = emit_data(&header, &payload, &mut buf).unwrap();
                prop_assert_eq!(n, DATA_HEADER_LEN + payload.len() + FCS_LEN);
                prop_assert_eq!(Frame::parse(&buf[..n]), Ok(Frame::Data { header, payload: &payload[..] }));
            }
        }
    }
}
