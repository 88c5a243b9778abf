//! The table blob: a versioned, length-prefixed, CRC-protected envelope around the postcard
//! encoding of a [`Table`].
//!
//! ```text
//! offset  size  field
//! 0       4     magic "ECCT"
//! 4       2     schema version (LE)
//! 6       4     generation (LE)
//! 10      2     payload length N (LE)
//! 12      N     postcard(Table)
//! 12+N    4     CRC-32/ISO-HDLC over bytes 0..12+N (LE)
//! ```

use core::fmt;

use crate::table::Table;
use crate::validate::{validate, Invalid};

/// First bytes of every blob.
pub const MAGIC: [u8; 4] = *b"ECCT";
/// The schema version this crate reads and writes (2: each output has fault, start and
/// home levels instead of one safe level; 3: each chart has an idle state besides its
/// initial one, and the table the events of the HOME command and of its boot; 4: the
/// table's safety declarations: emergency stop, restart inputs, link alarm policy,
/// declared alarms).
pub const SCHEMA_VERSION: u16 = 4;
/// Bytes before the payload.
pub const HEADER_LEN: usize = 12;
/// Bytes after the payload.
pub const TRAILER_LEN: usize = 4;
/// The CRC of the blob (and of an OTA transfer as a whole).
pub const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

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
    /// The payload is not a postcard table (or overflows a capacity while decoding).
    Postcard(postcard::Error),
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
            DecodeError::Postcard(e) => write!(f, "malformed table payload: {e}"),
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

/// Encodes `table` as a blob into `buf`; returns the blob's length.
pub fn encode(table: &Table, buf: &mut [u8]) -> Result<usize, EncodeError> {
    let body = buf
        .get_mut(HEADER_LEN..)
        .ok_or(EncodeError::BufferTooSmall)?;
    let payload_len = postcard::to_slice(table, body)
        .map_err(|_| EncodeError::BufferTooSmall)?
        .len();
    let len16 = u16::try_from(payload_len).map_err(|_| EncodeError::TooLarge)?;
    let total = HEADER_LEN + payload_len + TRAILER_LEN;
    if buf.len() < total {
        return Err(EncodeError::BufferTooSmall);
    }
    buf[0..4].copy_from_slice(&MAGIC);
    buf[4..6].copy_from_slice(&SCHEMA_VERSION.to_le_bytes());
    buf[6..10].copy_from_slice(&table.generation.to_le_bytes());
    buf[10..12].copy_from_slice(&len16.to_le_bytes());
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
    if bytes[0..4] != MAGIC {
        return Err(DecodeError::BadMagic);
    }
    let version = u16::from_le_bytes([bytes[4], bytes[5]]);
    if version != SCHEMA_VERSION {
        return Err(DecodeError::UnsupportedVersion(version));
    }
    let generation = u32::from_le_bytes([bytes[6], bytes[7], bytes[8], bytes[9]]);
    let payload_len = usize::from(u16::from_le_bytes([bytes[10], bytes[11]]));
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
    let env = envelope(bytes)?;
    let payload = &bytes[HEADER_LEN..HEADER_LEN + env.payload_len];
    let (mut table, rest): (Table, _) =
        postcard::take_from_bytes(payload).map_err(DecodeError::Postcard)?;
    if !rest.is_empty() {
        return Err(DecodeError::TrailingBytes(rest.len()));
    }
    table.generation = env.generation;
    validate(&table).map_err(DecodeError::Invalid)?;
    Ok(table)
}
