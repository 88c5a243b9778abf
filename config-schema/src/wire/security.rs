//! IEEE 802.15.4 frame security (802.15.4-2006 section 7.6, the same in 2015 for these
//! frames): the auxiliary security header and AES-128-CCM* over a data frame.
//!
//! ```text
//! secured data frame, PSDU:
//! | MAC header (9) | aux security header (5/6/10/14) | payload (n, encrypted) | MIC (4/8/16) | FCS (2) |
//!  \_____________ a data (authenticated) ____________/ \___ m data ___/
//! (the FCS is outside the MIC: the node core secures and opens MPDUs, the frame without
//! its FCS, with `secure_default_mpdu_with` / `open_default_mpdu_with`; the radio edge adds
//! and checks the FCS, `mac::append_fcs` / `mac::strip_fcs`)
//! aux security header:
//! | security control (1) | frame counter (4, LE) | key source (0/4/8) | key index (0/1) |
//! security control: bits 0-2 security level, bits 3-4 key identifier mode, bits 5-7 zero
//! nonce (13): | source extended address (8, big-endian) | frame counter (4, BE) | level (1) |
//! ```
//!
//! Levels with a MIC only: 1/2/3 (MIC-32/64/128: the payload stays clear and is
//! authenticated with the headers) and 5/6/7 (ENC-MIC-32/64/128: encrypted too); the
//! default is [`SecurityLevel::EncMic64`]. Levels 0 and 4 carry no MIC, so a receiver could
//! not tell a forgery: [`secure`] and [`open`] refuse them ([`SecError::NoMic`]); the header
//! codec still parses them.
//!
//! Our nodes have short addresses; the nonce needs the sender's 64-bit extended address:
//! [`ext_addr`] is the one mapping from (PAN id, short address) to it.
//!
//! This codec knows bytes, not state: keeping frame counters (sender) is the caller's job,
//! and so is rejecting replays (receiver), for which [`replay::ReplayGuard`] is the table.

mod block;
pub mod link;
pub mod replay;
mod star;
#[cfg(test)]
mod tests;

use core::cell::Cell;
use core::fmt;

use ccm::aead::array::{Array, ArraySize};
use ccm::consts::{U13, U16, U4, U8};
use ccm::{AeadInOut, Ccm, TagSize};

use block::OneBlock;
pub use block::{fips197, BlockCipher, CipherFault, SoftAes, BLOCK_LEN};
use star::Direction;

use super::copy;
use super::mac::{self, Frame, FrameError, Header, DATA_HEADER_LEN, FCS_LEN, MAX_PSDU};

/// AES-128 key length.
pub const KEY_LEN: usize = 16;
/// CCM* nonce length (15 - L with L = 2).
pub const NONCE_LEN: usize = 13;
/// Auxiliary security header length with key identifier mode 1 (our default).
pub const AUX_LEN_KEY_INDEX: usize = 6;
/// Bytes a default-secured frame (ENC-MIC-64, key index) adds: aux header + MIC.
pub const DEFAULT_OVERHEAD: usize = AUX_LEN_KEY_INDEX + 8;
/// Largest payload of a default-secured data frame.
pub const MAX_SECURED_PAYLOAD: usize = mac::MAX_PAYLOAD - DEFAULT_OVERHEAD;

/// The key index of the link keys of tables of `generation`: 1 to 255 (0 is the
/// management key), so two consecutive generations never share an index.
pub const fn link_key_index(generation: u32) -> u8 {
    (generation % 255) as u8 + 1
}

/// The security level (security control bits 0-2): what a frame's MIC and encryption are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub enum SecurityLevel {
    None = 0,
    Mic32 = 1,
    Mic64 = 2,
    Mic128 = 3,
    Enc = 4,
    EncMic32 = 5,
    #[default]
    EncMic64 = 6,
    EncMic128 = 7,
}

impl SecurityLevel {
    /// Every level, by value.
    pub const ALL: [SecurityLevel; 8] = [
        SecurityLevel::None,
        SecurityLevel::Mic32,
        SecurityLevel::Mic64,
        SecurityLevel::Mic128,
        SecurityLevel::Enc,
        SecurityLevel::EncMic32,
        SecurityLevel::EncMic64,
        SecurityLevel::EncMic128,
    ];

    /// The level of the low three bits of `bits`.
    pub const fn from_bits(bits: u8) -> SecurityLevel {
        SecurityLevel::ALL[(bits & 0b111) as usize]
    }

    /// Its 3-bit value (also the last byte of the nonce).
    pub const fn bits(self) -> u8 {
        self as u8
    }

    /// MIC length in bytes (0, 4, 8 or 16).
    pub const fn mic_len(self) -> usize {
        match self.bits() & 0b11 {
            0 => 0,
            1 => 4,
            2 => 8,
            _ => 16,
        }
    }

    /// Whether the payload is encrypted.
    pub const fn encrypts(self) -> bool {
        self.bits() & 0b100 != 0
    }
}

/// The key identifier: key identifier mode (security control bits 3-4) and its fields.
/// A key source is kept in the byte order it has on the air.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum KeyId {
    /// Mode 0: the key follows from the two ends (no field).
    Implicit,
    /// Mode 1: a key index (1 byte) into the receiver's key table.
    Index(u8),
    /// Mode 2: a 4-byte key source and a key index.
    Source4 { source: [u8; 4], index: u8 },
    /// Mode 3: an 8-byte key source and a key index.
    Source8 { source: [u8; 8], index: u8 },
}

impl KeyId {
    /// The key identifier mode, 0..=3.
    pub const fn mode(&self) -> u8 {
        match self {
            KeyId::Implicit => 0,
            KeyId::Index(_) => 1,
            KeyId::Source4 { .. } => 2,
            KeyId::Source8 { .. } => 3,
        }
    }

    /// The key index, if the mode has one.
    pub const fn index(&self) -> Option<u8> {
        match *self {
            KeyId::Implicit => None,
            KeyId::Index(index) | KeyId::Source4 { index, .. } | KeyId::Source8 { index, .. } => {
                Some(index)
            }
        }
    }
}

/// Length of the key identifier field of key identifier mode `mode` (0..=3).
const fn key_id_len(mode: u8) -> usize {
    match mode & 0b11 {
        0 => 0,
        1 => 1,
        2 => 5,
        _ => 9,
    }
}

/// Why a frame cannot be secured or is not accepted: each one a reason a node counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SecError {
    /// Not a well-formed MAC data frame (truncated, bad FCS, unsupported addressing...).
    Frame(FrameError),
    /// A data frame without the security-enabled bit.
    NotSecured,
    /// Secured, but its auxiliary security header is truncated or has reserved bits set, or
    /// the frame is shorter than its MIC.
    Malformed,
    /// Security level 0 or 4: no MIC, so nothing would tell a forgery.
    NoMic,
    /// The receiver has no key for this sender and key identifier.
    UnknownKey,
    /// The MIC does not match: forged, damaged, wrong key or wrong sender address.
    BadMic,
    /// Frame counter 0xFFFFFFFF: the standard forbids it (the sender needs a new key).
    CounterExhausted,
    /// The frame does not fit the PSDU or the buffer.
    NoRoom,
    /// Secured at another level than the receiver requires (a weaker MIC, or none of the
    /// encryption): refused before any key is looked up.
    Level {
        got: SecurityLevel,
        required: SecurityLevel,
    },
    /// The block cipher failed (a board's hardware AES aborted or timed out): nothing is
    /// sent, nothing accepted.
    Cipher,
}

impl fmt::Display for SecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SecError::Frame(e) => write!(f, "not a data frame: {e}"),
            SecError::NotSecured => f.write_str("frame is not secured"),
            SecError::Malformed => f.write_str("malformed auxiliary security header"),
            SecError::NoMic => f.write_str("security level without a MIC"),
            SecError::UnknownKey => f.write_str("no key for this sender and key identifier"),
            SecError::BadMic => f.write_str("MIC mismatch"),
            SecError::CounterExhausted => f.write_str("frame counter exhausted"),
            SecError::NoRoom => f.write_str("secured frame does not fit"),
            SecError::Level { got, required } => {
                write!(f, "security level {got:?}, not the required {required:?}")
            }
            SecError::Cipher => f.write_str("block cipher failed"),
        }
    }
}

impl core::error::Error for SecError {}

impl From<FrameError> for SecError {
    fn from(e: FrameError) -> Self {
        SecError::Frame(e)
    }
}

mod field {
    pub type Field = core::ops::Range<usize>;
    /// Security control.
    pub const CONTROL: usize = 0;
    /// Frame counter, little-endian.
    pub const COUNTER: Field = 1..5;
    /// Start of the key identifier (key source, then key index).
    pub const KEY_ID: usize = 5;
}

const CONTROL_LEVEL: u8 = 0b0000_0111;
const CONTROL_KEY_ID_MODE_SHIFT: u8 = 3;
/// Frame counter suppression and ASN in nonce (2015, TSCH) and a reserved bit: zero here.
const CONTROL_RESERVED: u8 = 0b1110_0000;

/// A checked, zero-copy view of an auxiliary security header at the start of `buffer`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AuxHeader<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> AuxHeader<T> {
    /// Checks that `buffer` starts with a whole auxiliary security header with no reserved
    /// bit set. Every getter is then in bounds.
    pub fn new_checked(buffer: T) -> Result<Self, SecError> {
        let bytes = buffer.as_ref();
        let control = *bytes.get(field::CONTROL).ok_or(SecError::Malformed)?;
        if control & CONTROL_RESERVED != 0 {
            return Err(SecError::Malformed);
        }
        let len = field::KEY_ID + key_id_len(control >> CONTROL_KEY_ID_MODE_SHIFT);
        if bytes.len() < len {
            return Err(SecError::Malformed);
        }
        Ok(AuxHeader { buffer })
    }

    /// The buffer given to [`AuxHeader::new_checked`].
    pub fn into_inner(self) -> T {
        self.buffer
    }

    fn bytes(&self) -> &[u8] {
        self.buffer.as_ref()
    }

    /// The security control byte.
    pub fn security_control(&self) -> u8 {
        self.bytes().get(field::CONTROL).copied().unwrap_or(0)
    }

    /// The security level.
    pub fn security_level(&self) -> SecurityLevel {
        SecurityLevel::from_bits(self.security_control() & CONTROL_LEVEL)
    }

    /// The key identifier mode, 0..=3.
    pub fn key_id_mode(&self) -> u8 {
        (self.security_control() >> CONTROL_KEY_ID_MODE_SHIFT) & 0b11
    }

    /// The frame counter.
    pub fn frame_counter(&self) -> u32 {
        match self.bytes().get(field::COUNTER) {
            Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
            _ => 0,
        }
    }

    /// The key source as on the air (empty in modes 0 and 1).
    pub fn key_source(&self) -> &[u8] {
        let id_len = key_id_len(self.key_id_mode());
        let end = field::KEY_ID + id_len.saturating_sub(1);
        self.bytes().get(field::KEY_ID..end).unwrap_or(&[])
    }

    /// The key index (none in mode 0).
    pub fn key_index(&self) -> Option<u8> {
        match key_id_len(self.key_id_mode()) {
            0 => None,
            n => self.bytes().get(field::KEY_ID + n - 1).copied(),
        }
    }

    /// Length of this auxiliary security header.
    pub fn header_len(&self) -> usize {
        field::KEY_ID + key_id_len(self.key_id_mode())
    }
}

/// The fields of an auxiliary security header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AuxRepr {
    pub level: SecurityLevel,
    pub key_id: KeyId,
    pub frame_counter: u32,
}

impl AuxRepr {
    /// Our frames' header: ENC-MIC-64 with a key index.
    pub const fn new(key_index: u8, frame_counter: u32) -> AuxRepr {
        AuxRepr {
            level: SecurityLevel::EncMic64,
            key_id: KeyId::Index(key_index),
            frame_counter,
        }
    }

    /// The fields of a checked header.
    pub fn parse<T: AsRef<[u8]>>(header: &AuxHeader<T>) -> AuxRepr {
        let source = header.key_source();
        let index = header.key_index().unwrap_or(0);
        let key_id = match header.key_id_mode() {
            0 => KeyId::Implicit,
            1 => KeyId::Index(index),
            2 => {
                let mut s = [0u8; 4];
                copy(&mut s, source);
                KeyId::Source4 { source: s, index }
            }
            _ => {
                let mut s = [0u8; 8];
                copy(&mut s, source);
                KeyId::Source8 { source: s, index }
            }
        };
        AuxRepr {
            level: header.security_level(),
            key_id,
            frame_counter: header.frame_counter(),
        }
    }

    /// Length of the header these fields make.
    pub const fn buffer_len(&self) -> usize {
        field::KEY_ID + key_id_len(self.key_id.mode())
    }

    /// Writes the header at the start of `buf`; returns its length.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, SecError> {
        let len = self.buffer_len();
        let buf = buf.get_mut(..len).ok_or(SecError::NoRoom)?;
        let (head, id) = buf
            .split_at_mut_checked(field::KEY_ID)
            .ok_or(SecError::NoRoom)?;
        let control = self.level.bits() | (self.key_id.mode() << CONTROL_KEY_ID_MODE_SHIFT);
        let counter = self.frame_counter.to_le_bytes();
        match head {
            [c, f0, f1, f2, f3] => {
                *c = control;
                [*f0, *f1, *f2, *f3] = counter;
            }
            _ => return Err(SecError::NoRoom),
        }
        // `id` is exactly the key identifier's length (`buffer_len`).
        match (self.key_id, id) {
            (KeyId::Implicit, []) => {}
            (KeyId::Index(index), [i]) => *i = index,
            (KeyId::Source4 { source, index }, id) => emit_key_id(id, &source, index)?,
            (KeyId::Source8 { source, index }, id) => emit_key_id(id, &source, index)?,
            _ => return Err(SecError::NoRoom),
        }
        Ok(len)
    }
}

/// The 64-bit extended address that stands for (PAN id, short address) in the nonce:
/// `PAN id (2) | 00 FF FE 00 | short address (2)`, big-endian (the layout of RFC 4944's
/// interface identifier for a short address, no bit flipped). E.g. PAN 0xBEEF, node 0x0001:
/// `be:ef:00:ff:fe:00:00:01`, which is what Wireshark's "Static Addresses" table of IEEE
/// Writes a key source and index into `id` (exactly their length).
fn emit_key_id(id: &mut [u8], source: &[u8], index: u8) -> Result<(), SecError> {
    let (src, last) = id
        .split_last_mut()
        .map(|(last, src)| (src, last))
        .ok_or(SecError::NoRoom)?;
    copy(src, source).ok_or(SecError::NoRoom)?;
    *last = index;
    Ok(())
}

/// 802.15.4 takes for short address 0x0001 on PAN 0xbeef.
pub const fn ext_addr(pan_id: u16, short: u16) -> [u8; 8] {
    let p = pan_id.to_be_bytes();
    let s = short.to_be_bytes();
    [p[0], p[1], 0x00, 0xFF, 0xFE, 0x00, s[0], s[1]]
}

/// The CCM* nonce: source extended address, frame counter (both big-endian), level.
/// (Out of line: built byte by byte, its four copies inlined cost the nRF52840 image 24 B.)
#[inline(never)]
pub const fn nonce(src_ext: &[u8; 8], frame_counter: u32, level: SecurityLevel) -> [u8; 13] {
    let c = frame_counter.to_be_bytes();
    let a = src_ext;
    [
        a[0],
        a[1],
        a[2],
        a[3],
        a[4],
        a[5],
        a[6],
        a[7],
        c[0],
        c[1],
        c[2],
        c[3],
        level.bits(),
    ]
}

fn seal_with<M: ArraySize + TagSize, C: BlockCipher>(
    key: &[u8; KEY_LEN],
    nonce: &[u8; NONCE_LEN],
    a: &[u8],
    m: &mut [u8],
    mic: &mut [u8],
) -> Result<(), SecError> {
    let fault = Cell::new(false);
    let ccm = Ccm::<OneBlock<'_, C>, M, U13>::from(OneBlock::new(key, &fault));
    let tag = ccm
        .encrypt_inout_detached(&Array::from(*nonce), a, m.into())
        .map_err(|_| SecError::NoRoom)?;
    if fault.get() {
        return Err(SecError::Cipher);
    }
    if mic.len() != tag.len() {
        return Err(SecError::NoRoom);
    }
    mic.copy_from_slice(&tag);
    Ok(())
}

fn open_with<M: ArraySize + TagSize, C: BlockCipher>(
    key: &[u8; KEY_LEN],
    nonce: &[u8; NONCE_LEN],
    a: &[u8],
    m: &mut [u8],
    mic: &[u8],
) -> Result<(), SecError> {
    let fault = Cell::new(false);
    let ccm = Ccm::<OneBlock<'_, C>, M, U13>::from(OneBlock::new(key, &fault));
    let tag = Array::<u8, M>::try_from(mic).map_err(|_| SecError::Malformed)?;
    let opened = ccm
        .decrypt_inout_detached(&Array::from(*nonce), a, m.into(), &tag)
        .map_err(|_| SecError::BadMic);
    if fault.get() {
        // Whatever the MIC check said, a failed block leaves nothing to trust.
        m.fill(0);
        return Err(SecError::Cipher);
    }
    opened
}

/// Splits `body` (MAC header, aux header, payload) into CCM*'s a data and m data: with
/// encryption the payload is m, else it is authenticated as part of a and m is empty.
fn split_a_m(body: &mut [u8], a_len: usize, level: SecurityLevel) -> (&[u8], &mut [u8]) {
    let at = if level.encrypts() {
        a_len.min(body.len())
    } else {
        body.len()
    };
    match body.split_at_mut_checked(at) {
        Some((a, m)) => (a, m),
        None => (&[], &mut []),
    }
}

/// CCM* forward transformation: authenticates `a` and `m`, encrypts `m` in place (empty
/// for the MIC-only levels, whose payload is part of `a`) and writes the MIC (the level's
/// length) to `mic`.
pub(crate) fn seal(
    key: &[u8; KEY_LEN],
    nonce: &[u8; NONCE_LEN],
    level: SecurityLevel,
    a: &[u8],
    m: &mut [u8],
    mic: &mut [u8],
) -> Result<(), SecError> {
    match level.mic_len() {
        4 => seal_with::<U4, SoftAes>(key, nonce, a, m, mic),
        8 => seal_with::<U8, SoftAes>(key, nonce, a, m, mic),
        16 => seal_with::<U16, SoftAes>(key, nonce, a, m, mic),
        _ => Err(SecError::NoMic),
    }
}

/// CCM* inverse transformation of [`seal`]: checks `mic` over `a` and `m`, decrypting `m`
/// in place. On a mismatch `m` is zeroed (no unauthenticated plaintext is left behind).
pub(crate) fn unseal(
    key: &[u8; KEY_LEN],
    nonce: &[u8; NONCE_LEN],
    level: SecurityLevel,
    a: &[u8],
    m: &mut [u8],
    mic: &[u8],
) -> Result<(), SecError> {
    match level.mic_len() {
        4 => open_with::<U4, SoftAes>(key, nonce, a, m, mic),
        8 => open_with::<U8, SoftAes>(key, nonce, a, m, mic),
        16 => open_with::<U16, SoftAes>(key, nonce, a, m, mic),
        _ => Err(SecError::NoMic),
    }
}

/// [`seal`] at ENC-MIC-64 only, with the block cipher `C`: CCM* of its own
/// ([`star::ccm_star_64`], the same transformation as the `ccm` crate's, a fraction of its
/// code: what a node links; [`secure_default`]).
fn seal_default<C: BlockCipher>(
    key: &[u8; KEY_LEN],
    nonce: &[u8; NONCE_LEN],
    level: SecurityLevel,
    a: &[u8],
    m: &mut [u8],
    mic: &mut [u8],
) -> Result<(), SecError> {
    default_level(level)?;
    let tag = star::ccm_star_64(&C::new(key), nonce, a, m, Direction::Seal)?;
    let mic: &mut [u8; star::MIC_LEN] = mic.try_into().map_err(|_| SecError::NoRoom)?;
    *mic = tag;
    Ok(())
}

/// [`unseal`] at ENC-MIC-64 only, with the block cipher `C` (a node's; [`open_default`]).
/// On any error `m` is zeroed.
fn unseal_default<C: BlockCipher>(
    key: &[u8; KEY_LEN],
    nonce: &[u8; NONCE_LEN],
    level: SecurityLevel,
    a: &[u8],
    m: &mut [u8],
    mic: &[u8],
) -> Result<(), SecError> {
    default_level(level)?;
    let opened = match star::ccm_star_64(&C::new(key), nonce, a, m, Direction::Open) {
        Ok(tag) if star::same_mic(&tag, mic) => Ok(()),
        Ok(_) => Err(SecError::BadMic),
        Err(e) => Err(e),
    };
    if opened.is_err() {
        // No unauthenticated (or half-decrypted) plaintext is left behind.
        m.fill(0);
    }
    opened
}

fn default_level(level: SecurityLevel) -> Result<(), SecError> {
    match level {
        SecurityLevel::EncMic64 => Ok(()),
        got => Err(SecError::Level {
            got,
            required: SecurityLevel::EncMic64,
        }),
    }
}

/// [`seal`] or [`seal_default`]: which CCM* instances a caller links.
type Seal = fn(
    &[u8; KEY_LEN],
    &[u8; NONCE_LEN],
    SecurityLevel,
    &[u8],
    &mut [u8],
    &mut [u8],
) -> Result<(), SecError>;
/// [`unseal`] or [`unseal_default`].
type Unseal = fn(
    &[u8; KEY_LEN],
    &[u8; NONCE_LEN],
    SecurityLevel,
    &[u8],
    &mut [u8],
    &[u8],
) -> Result<(), SecError>;

/// Checks what every secured frame needs of its aux header, sending or receiving.
fn check_aux(aux: &AuxRepr) -> Result<(), SecError> {
    if aux.level.mic_len() == 0 {
        return Err(SecError::NoMic);
    }
    if aux.frame_counter == u32::MAX {
        return Err(SecError::CounterExhausted);
    }
    Ok(())
}

/// Secures a data frame: writes the whole PSDU (MAC header with the security bit set, aux
/// header, the payload encrypted if the level says so, MIC, FCS) into `out` and returns its
/// length. `src_ext` is the sender's extended address ([`ext_addr`]).
pub fn secure(
    header: &Header,
    aux: &AuxRepr,
    key: &[u8; KEY_LEN],
    src_ext: [u8; 8],
    payload: &[u8],
    out: &mut [u8],
) -> Result<usize, SecError> {
    with_fcs(out, |mpdu| {
        secure_by(header, aux, key, src_ext, payload, mpdu, seal)
    })
}

/// A PSDU: `secure_mpdu` writes the MPDU into `out` short of the FCS, which is then
/// appended; returns the PSDU length.
fn with_fcs(
    out: &mut [u8],
    secure_mpdu: impl FnOnce(&mut [u8]) -> Result<usize, SecError>,
) -> Result<usize, SecError> {
    let mpdu = out.len().saturating_sub(FCS_LEN);
    let n = secure_mpdu(out.get_mut(..mpdu).ok_or(SecError::NoRoom)?)?;
    Ok(mac::append_fcs(out, n)?)
}

/// [`secure`] at ENC-MIC-64 only, our frames' level ([`AuxRepr::new`]); another level is
/// refused ([`SecError::Level`]). The same frames, one CCM* instance linked instead of
/// three: what a node calls. Software AES ([`SoftAes`]); [`secure_default_with`] takes
/// another block cipher.
pub fn secure_default(
    header: &Header,
    aux: &AuxRepr,
    key: &[u8; KEY_LEN],
    src_ext: [u8; 8],
    payload: &[u8],
    out: &mut [u8],
) -> Result<usize, SecError> {
    secure_default_with::<SoftAes>(header, aux, key, src_ext, payload, out)
}

/// [`secure_default`] with the AES-128 of `C` (a board's hardware cipher): the same
/// frames; a failed block is [`SecError::Cipher`] and nothing is to be sent.
pub fn secure_default_with<C: BlockCipher>(
    header: &Header,
    aux: &AuxRepr,
    key: &[u8; KEY_LEN],
    src_ext: [u8; 8],
    payload: &[u8],
    out: &mut [u8],
) -> Result<usize, SecError> {
    with_fcs(out, |mpdu| {
        secure_default_mpdu_with::<C>(header, aux, key, src_ext, payload, mpdu)
    })
}

/// [`secure_default_with`] writing the MPDU only (no FCS: the radio edge appends it,
/// [`mac::append_fcs`]); returns its length. The MIC covers the same bytes: the FCS is
/// never part of it. What a node calls.
pub fn secure_default_mpdu_with<C: BlockCipher>(
    header: &Header,
    aux: &AuxRepr,
    key: &[u8; KEY_LEN],
    src_ext: [u8; 8],
    payload: &[u8],
    out: &mut [u8],
) -> Result<usize, SecError> {
    secure_by(header, aux, key, src_ext, payload, out, seal_default::<C>)
}

fn secure_by(
    header: &Header,
    aux: &AuxRepr,
    key: &[u8; KEY_LEN],
    src_ext: [u8; 8],
    payload: &[u8],
    out: &mut [u8],
    seal: Seal,
) -> Result<usize, SecError> {
    check_aux(aux)?;
    let a_len = DATA_HEADER_LEN + aux.buffer_len();
    let body_len = a_len + payload.len();
    let mic_len = aux.level.mic_len();
    let total = body_len + mic_len + FCS_LEN;
    if total > MAX_PSDU || out.len() < body_len + mic_len {
        return Err(SecError::NoRoom);
    }
    let header = Header {
        secured: true,
        ..*header
    };
    mac::emit_data_header(&header, out)?;
    aux.emit(out.get_mut(DATA_HEADER_LEN..).ok_or(SecError::NoRoom)?)?;
    copy(
        out.get_mut(a_len..body_len).ok_or(SecError::NoRoom)?,
        payload,
    )
    .ok_or(SecError::NoRoom)?;
    let (body, rest) = out.split_at_mut_checked(body_len).ok_or(SecError::NoRoom)?;
    let mic = rest.get_mut(..mic_len).ok_or(SecError::NoRoom)?;
    let nonce = nonce(&src_ext, aux.frame_counter, aux.level);
    let (a, m) = split_a_m(body, a_len, aux.level);
    seal(key, &nonce, aux.level, a, m, mic)?;
    Ok(body_len + mic_len)
}

/// An authenticated frame: its header fields and its decrypted payload (in the scratch).
#[derive(Debug, PartialEq, Eq)]
pub struct Opened<'a> {
    pub header: Header,
    pub aux: AuxRepr,
    pub payload: &'a [u8],
}

/// Checks and decrypts a secured data frame (FCS included). `lookup` is asked for the key
/// and the sender's extended address once the headers parse; the payload is decrypted into
/// `scratch` (`mac::MAX_PAYLOAD` bytes always suffice). Never panics; on any error no
/// unauthenticated plaintext is left in `scratch`. Replay is the caller's check, on the returned
/// `aux.frame_counter`, and only once this returned `Ok`.
pub fn open<'a, F>(psdu: &[u8], lookup: F, scratch: &'a mut [u8]) -> Result<Opened<'a>, SecError>
where
    F: FnOnce(&Header, &AuxRepr) -> Option<([u8; KEY_LEN], [u8; 8])>,
{
    open_checked(mac::strip_fcs(psdu)?, None, lookup, scratch, unseal)
}

/// [`open`], for a receiver that requires one security level (ours: ENC-MIC-64): a frame
/// claiming another, weaker or stronger, is refused as [`SecError::Level`] before any key
/// is looked up.
pub fn open_at<'a, F>(
    psdu: &[u8],
    required: SecurityLevel,
    lookup: F,
    scratch: &'a mut [u8],
) -> Result<Opened<'a>, SecError>
where
    F: FnOnce(&Header, &AuxRepr) -> Option<([u8; KEY_LEN], [u8; 8])>,
{
    open_checked(
        mac::strip_fcs(psdu)?,
        Some(required),
        lookup,
        scratch,
        unseal,
    )
}

/// [`open_at`] ENC-MIC-64, with one CCM* instance linked instead of three: what a node
/// calls. Software AES ([`SoftAes`]); [`open_default_with`] takes another block cipher.
pub fn open_default<'a, F>(
    psdu: &[u8],
    lookup: F,
    scratch: &'a mut [u8],
) -> Result<Opened<'a>, SecError>
where
    F: FnOnce(&Header, &AuxRepr) -> Option<([u8; KEY_LEN], [u8; 8])>,
{
    open_default_with::<SoftAes, F>(psdu, lookup, scratch)
}

/// [`open_default`] with the AES-128 of `C` (a board's hardware cipher): the same checks;
/// a failed block is [`SecError::Cipher`], with the scratch zeroed.
pub fn open_default_with<'a, C: BlockCipher, F>(
    psdu: &[u8],
    lookup: F,
    scratch: &'a mut [u8],
) -> Result<Opened<'a>, SecError>
where
    F: FnOnce(&Header, &AuxRepr) -> Option<([u8; KEY_LEN], [u8; 8])>,
{
    open_default_mpdu_with::<C, F>(mac::strip_fcs(psdu)?, lookup, scratch)
}

/// [`open_default_with`] of an MPDU (the FCS checked and cut off at the radio edge,
/// [`mac::strip_fcs`]): the same checks of everything the MIC covers. What a node calls.
pub fn open_default_mpdu_with<'a, C: BlockCipher, F>(
    mpdu: &[u8],
    lookup: F,
    scratch: &'a mut [u8],
) -> Result<Opened<'a>, SecError>
where
    F: FnOnce(&Header, &AuxRepr) -> Option<([u8; KEY_LEN], [u8; 8])>,
{
    open_checked(
        mpdu,
        Some(SecurityLevel::EncMic64),
        lookup,
        scratch,
        unseal_default::<C>,
    )
}

fn open_checked<'a, F>(
    mpdu: &[u8],
    required: Option<SecurityLevel>,
    lookup: F,
    scratch: &'a mut [u8],
    unseal: Unseal,
) -> Result<Opened<'a>, SecError>
where
    F: FnOnce(&Header, &AuxRepr) -> Option<([u8; KEY_LEN], [u8; 8])>,
{
    let (header, secured) = match Frame::parse_mpdu(mpdu)? {
        Frame::Data { header, payload } => (header, payload),
        Frame::Ack { .. } => return Err(SecError::Frame(FrameError::Unsupported)),
    };
    if !header.secured {
        return Err(SecError::NotSecured);
    }
    let view = AuxHeader::new_checked(secured)?;
    let aux = AuxRepr::parse(&view);
    check_aux(&aux)?;
    if let Some(required) = required.filter(|r| *r != aux.level) {
        return Err(SecError::Level {
            got: aux.level,
            required,
        });
    }
    let a_len = DATA_HEADER_LEN + view.header_len();
    let mic_len = aux.level.mic_len();
    let n = secured
        .len()
        .checked_sub(view.header_len() + mic_len)
        .ok_or(SecError::Malformed)?;
    let (key, src_ext) = lookup(&header, &aux).ok_or(SecError::UnknownKey)?;
    let body_len = a_len + n;
    let mic = mpdu
        .get(body_len..body_len + mic_len)
        .ok_or(SecError::Malformed)?;
    let payload = mpdu.get(a_len..body_len).ok_or(SecError::Malformed)?;
    let out = scratch.get_mut(..n).ok_or(SecError::NoRoom)?;
    let nonce = nonce(&src_ext, aux.frame_counter, aux.level);
    if aux.level.encrypts() {
        // a: header || aux, from the MPDU; m: the payload, decrypted in the scratch.
        copy(out, payload).ok_or(SecError::Malformed)?;
        let a = mpdu.get(..a_len).ok_or(SecError::Malformed)?;
        unseal(&key, &nonce, aux.level, a, out, mic)?;
    } else {
        // a: header || aux || payload; the payload is handed out only once authentic.
        let a = mpdu.get(..body_len).ok_or(SecError::Malformed)?;
        unseal(&key, &nonce, aux.level, a, &mut [], mic)?;
        copy(out, payload).ok_or(SecError::Malformed)?;
    }
    Ok(Opened {
        header,
        aux,
        payload: out,
    })
}
