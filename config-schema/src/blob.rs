//! The table blob: a versioned, length-prefixed, CRC-protected envelope around the
//! bit-packed encoding of a [`Table`] ([`crate::pack`]).
//!
//! ```text
//! offset  size  field
//! 0       1     magic 0xEC
//! 1       1     schema version
//! 2       4     generation (LE)
//! 6       2     payload length N (LE)
//! 8       N     pack(Table)
//! 8+N     4     CRC-32/ISO-HDLC over bytes 0..8+N (LE)
//! ```

use core::fmt;

use serde::{Deserialize, Serialize};

use crate::pack::{self, PackError};
use crate::table::Table;
use crate::validate::{validate, Invalid};

/// First byte of every blob.
pub const MAGIC: [u8; 1] = [0xEC];
/// The schema version this crate reads and writes (2: each output has fault, start and
/// home levels instead of one safe level; 3: each chart has an idle state besides its
/// initial one, and the table the events of the HOME command and of its boot; 4: the
/// table's safety declarations: emergency stop, restart inputs, link alarm policy,
/// declared alarms; 5: the bit-packed payload of [`crate::pack`] in an envelope of 12
/// bytes instead of postcard in one of 16; 6: the packed payload's implicit shapes
/// (routes one per chart input, chart inputs as their transitions use them, chain steps,
/// default levels and safety) and its shorter codes; 7: each chart's resting states
/// besides its idle one, docs/table-format.md).
pub const SCHEMA_VERSION: u16 = 7;
/// Bytes before the payload.
pub const HEADER_LEN: usize = 8;
/// Offset of the payload length (2 bytes, LE) in the header.
pub const LENGTH_AT: usize = 6;
/// Bytes after the payload.
pub const TRAILER_LEN: usize = 4;
/// The CRC of the blob (and of the key block after it). Bit by bit, no lookup table
/// (1 KiB of flash on a node, which checks a table's CRC when it is pushed or activated).
pub const CRC32: crc::Crc<u32, crc::NoTable> =
    crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// The CRC of an OTA transfer as a whole (`ConfigBegin`'s `crc`, checked at its end):
/// CRC-32C (Castagnoli), another polynomial than the sections' [`CRC32`]. A CRC-32/ISO-HDLC
/// over bytes that end with their own CRC-32/ISO-HDLC is its residue, `0x2144DF1C`,
/// whatever they hold, so it would tell no two tables of one length apart (a node answered
/// an edited table's push `Staged` and ran the old one); this one covers the content.
pub const TRANSFER_CRC: crc::Crc<u32, crc::NoTable> =
    crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISCSI);

/// Why a byte string is not a table.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DecodeError {
    /// Shorter than the envelope says (or than an envelope).
    Truncated { len: usize, need: usize },
    /// Not a table blob.
    BadMagic,
    /// Written by a schema version this firmware does not read.
    UnsupportedVersion(u16),
    /// Longer than the envelope says.
    LengthMismatch { len: usize, expected: usize },
    /// The bytes were damaged.
    Crc { stored: u32, computed: u32 },
    /// The payload is not a packed table (or overflows a capacity while decoding).
    Payload(PackError),
    /// The payload has bytes left after the table.
    TrailingBytes(usize),
    /// The table decoded but breaks a semantic rule.
    Invalid(Invalid),
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::Truncated { len, need } => {
                write!(f, "truncated blob: {len} bytes, need {need}")
            }
            DecodeError::BadMagic => write!(f, "not a table blob (bad magic)"),
            DecodeError::UnsupportedVersion(v) => write!(
                f,
                "schema version {v} is not supported (this build reads {SCHEMA_VERSION})"
            ),
            DecodeError::LengthMismatch { len, expected } => {
                write!(f, "blob is {len} bytes, its header says {expected}")
            }
            DecodeError::Crc { stored, computed } => write!(
                f,
                "CRC mismatch: stored {stored:#010x}, computed {computed:#010x}"
            ),
            DecodeError::Payload(e) => write!(f, "malformed table payload: {e}"),
            DecodeError::TrailingBytes(n) => write!(f, "{n} bytes left after the table"),
            DecodeError::Invalid(e) => write!(f, "invalid table: {e}"),
        }
    }
}

impl core::error::Error for DecodeError {}

/// Why a table could not be encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EncodeError {
    /// The output buffer is too small.
    BufferTooSmall,
    /// The payload is longer than a `u16` length.
    TooLarge,
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EncodeError::BufferTooSmall => write!(f, "output buffer too small for the blob"),
            EncodeError::TooLarge => write!(f, "table payload exceeds 65535 bytes"),
        }
    }
}

impl core::error::Error for EncodeError {}

/// A table's identity on the air: the CRC-32 of its blob (the envelope's trailer, over the
/// generation and the packed table, never a key), as `Status` and `Announce` carry it (4
/// bytes, little-endian). The tool compares it with the blob of the robot it was given,
/// compiled at the node's generation: two tables with the same roles and charts are told
/// apart. Only an identity, not a proof (frame security authenticates the node that
/// says it).
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct TableId(pub [u8; 4]);

impl TableId {
    /// What a node without a table reports.
    pub const NONE: TableId = TableId([0; 4]);

    /// The identity of the blob whose CRC-32 is `crc`.
    pub const fn from_crc(crc: u32) -> TableId {
        TableId(crc.to_le_bytes())
    }

    /// The CRC-32 this identity is.
    pub const fn crc(self) -> u32 {
        u32::from_le_bytes(self.0)
    }

    /// The identity of `table` (at its `generation`): its blob encoded and its CRC taken.
    /// For the tool and tests; a node takes the identity from the blob it decoded
    /// ([`crate::link_keys::Deployment`]).
    pub fn of(table: &Table) -> Result<TableId, EncodeError> {
        TableId::at(table, table.generation)
    }

    /// The identity `table` has as generation `generation` (what a node running it at
    /// that generation reports).
    pub fn at(table: &Table, generation: u32) -> Result<TableId, EncodeError> {
        let mut buf = [0u8; crate::limits::MAX_TABLE_BLOB];
        let len = encode_as(table, generation, &mut buf)?;
        let crc = buf
            .get(len.saturating_sub(TRAILER_LEN)..len)
            .ok_or(EncodeError::BufferTooSmall)?;
        Ok(TableId([crc[0], crc[1], crc[2], crc[3]]))
    }
}

impl fmt::Debug for TableId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "TableId({:#010x})", self.crc())
    }
}

impl fmt::Display for TableId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:08x}", self.crc())
    }
}

/// Encodes `table` as a blob into `buf`; returns the blob's length.
pub fn encode(table: &Table, buf: &mut [u8]) -> Result<usize, EncodeError> {
    encode_as(table, table.generation, buf)
}

/// [`encode`] as generation `generation` (the envelope's; the table's own is not read):
/// what `table` is as the blob of another generation, without a copy of it.
pub fn encode_as(table: &Table, generation: u32, buf: &mut [u8]) -> Result<usize, EncodeError> {
    let body = buf
        .get_mut(HEADER_LEN..)
        .ok_or(EncodeError::BufferTooSmall)?;
    let payload_len = pack::encode(table, body, None).map_err(|_| EncodeError::BufferTooSmall)?;
    let len16 = u16::try_from(payload_len).map_err(|_| EncodeError::TooLarge)?;
    let total = HEADER_LEN + payload_len + TRAILER_LEN;
    if buf.len() < total {
        return Err(EncodeError::BufferTooSmall);
    }
    let version = u8::try_from(SCHEMA_VERSION).map_err(|_| EncodeError::TooLarge)?;
    buf[0] = MAGIC[0];
    buf[1] = version;
    buf[2..6].copy_from_slice(&generation.to_le_bytes());
    buf[LENGTH_AT..HEADER_LEN].copy_from_slice(&len16.to_le_bytes());
    let crc = CRC32.checksum(&buf[..HEADER_LEN + payload_len]);
    buf[HEADER_LEN + payload_len..total].copy_from_slice(&crc.to_le_bytes());
    Ok(total)
}

/// The envelope fields of a blob, read without decoding the payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Envelope {
    pub version: u16,
    pub generation: u32,
    pub payload_len: usize,
    pub crc: u32,
}

/// Checks the envelope (magic, version, length, CRC) and returns its fields.
pub fn envelope(bytes: &[u8]) -> Result<Envelope, DecodeError> {
    let need = HEADER_LEN + TRAILER_LEN;
    if bytes.len() < need {
        return Err(DecodeError::Truncated {
            len: bytes.len(),
            need,
        });
    }
    if bytes[0..1] != MAGIC {
        return Err(DecodeError::BadMagic);
    }
    let version = u16::from(bytes[1]);
    if version != SCHEMA_VERSION {
        return Err(DecodeError::UnsupportedVersion(version));
    }
    let generation = u32::from_le_bytes([bytes[2], bytes[3], bytes[4], bytes[5]]);
    let payload_len = usize::from(u16::from_le_bytes([bytes[6], bytes[7]]));
    let expected = HEADER_LEN + payload_len + TRAILER_LEN;
    if bytes.len() < expected {
        return Err(DecodeError::Truncated {
            len: bytes.len(),
            need: expected,
        });
    }
    if bytes.len() > expected {
        return Err(DecodeError::LengthMismatch {
            len: bytes.len(),
            expected,
        });
    }
    let body_end = HEADER_LEN + payload_len;
    let stored = u32::from_le_bytes([
        bytes[body_end],
        bytes[body_end + 1],
        bytes[body_end + 2],
        bytes[body_end + 3],
    ]);
    let computed = CRC32.checksum(&bytes[..body_end]);
    if stored != computed {
        return Err(DecodeError::Crc { stored, computed });
    }
    Ok(Envelope {
        version,
        generation,
        payload_len,
        crc: stored,
    })
}

/// Decodes and validates a blob. Never panics, whatever the bytes.
pub fn decode(bytes: &[u8]) -> Result<Table, DecodeError> {
    decode_identified(bytes).map(|(table, _)| table)
}

/// [`decode`], with the table's identity on the air (the blob's CRC, checked once).
pub fn decode_identified(bytes: &[u8]) -> Result<(Table, TableId), DecodeError> {
    let env = envelope(bytes)?;
    let payload = &bytes[HEADER_LEN..HEADER_LEN + env.payload_len];
    let (mut table, rest) = pack::decode(payload).map_err(DecodeError::Payload)?;
    if rest != 0 {
        return Err(DecodeError::TrailingBytes(rest));
    }
    table.generation = env.generation;
    validate(&table).map_err(DecodeError::Invalid)?;
    Ok((table, TableId::from_crc(env.crc)))
}
