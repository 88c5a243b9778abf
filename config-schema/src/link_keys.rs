//! The link key block: the keys a node secures its events with, delivered after its table
//! blob inside the (secured) table transfer and persisted with it in the same flash slot.
//!
//! A transfer (and a slot) is the blob, then optionally this block:
//!
//! ```text
//! offset   size  field
//! 0        4     magic "ECCK"
//! 4        4     generation (LE): the blob's
//! 8        1     N, the number of peers (at most MAX_PEERS)
//! 9        34*N  per peer: address (u16 LE), send key (16), receive key (16)
//! 9+34N    4     CRC-32/ISO-HDLC over bytes 0..9+34N (LE)
//! ```
//!
//! The send key secures what this node sends to the peer (its events, and its
//! acknowledgements of the peer's events); the receive key opens what the peer sends.
//! The tool derives them per generation and direction (`robot-keys`); the node never
//! derives a key. The block names exactly the table's peers, each once.
//!
//! [`LinkKeys`]'s `Debug` never shows a key.

use core::fmt;

use heapless::Vec;

use crate::blob::{self, TableId, CRC32, HEADER_LEN, LENGTH_AT, TRAILER_LEN};
use crate::limits::MAX_PEERS;
use crate::table::Table;
use crate::wire::security::KEY_LEN;
use crate::DecodeError;

/// First bytes of a key block.
pub const MAGIC: [u8; 4] = *b"ECCK";
/// Bytes before the entries.
pub const HEAD_LEN: usize = 9;
/// Bytes of one peer's entry.
pub const ENTRY_LEN: usize = 2 + 2 * KEY_LEN;
/// The largest block.
pub const MAX_LEN: usize = HEAD_LEN + MAX_PEERS * ENTRY_LEN + 4;

mod field {
    pub type Field = core::ops::Range<usize>;
    pub const MAGIC: Field = 0..4;
    pub const GENERATION: Field = 4..8;
    pub const COUNT: usize = 8;
    pub const PEER: Field = 0..2;
    pub const SEND: Field = 2..18;
    pub const RECEIVE: Field = 18..34;
}

/// The keys of one peer.
#[derive(Clone, PartialEq, Eq)]
pub struct PeerKeys {
    pub peer: u16,
    /// Secures what this node sends to `peer`.
    pub send: [u8; KEY_LEN],
    /// Opens what `peer` sends to this node.
    pub receive: [u8; KEY_LEN],
}

impl fmt::Debug for PeerKeys {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "PeerKeys {{ peer: {:#06x}, keys: <secret> }}", self.peer)
    }
}

/// A node's link keys for one generation.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct LinkKeys {
    pub generation: u32,
    pub peers: Vec<PeerKeys, MAX_PEERS>,
}

/// Why a key block was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeyBlockError {
    /// Shorter than its count says, or than a block.
    Truncated { len: usize, need: usize },
    /// Bytes after the block.
    TrailingBytes(usize),
    /// Not a key block.
    BadMagic,
    /// More peers than a table may have.
    TooManyPeers(u8),
    /// The bytes were damaged.
    Crc { stored: u32, computed: u32 },
    /// For another generation than the table it came with.
    Generation { table: u32, keys: u32 },
    /// A peer of the table has no keys, or the block names a node that is not a peer, or
    /// one twice.
    Peers,
}

impl fmt::Display for KeyBlockError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            KeyBlockError::Truncated { len, need } => {
                write!(f, "truncated key block: {len} bytes, need {need}")
            }
            KeyBlockError::TrailingBytes(n) => write!(f, "{n} bytes after the key block"),
            KeyBlockError::BadMagic => write!(f, "not a key block (bad magic)"),
            KeyBlockError::TooManyPeers(n) => {
                write!(f, "key block for {n} peers, at most {MAX_PEERS}")
            }
            KeyBlockError::Crc { stored, computed } => write!(
                f,
                "key block CRC mismatch: stored {stored:#010x}, computed {computed:#010x}"
            ),
            KeyBlockError::Generation { table, keys } => write!(
                f,
                "key block of generation {keys} with a table of generation {table}"
            ),
            KeyBlockError::Peers => write!(f, "the key block does not name exactly the peers"),
        }
    }
}

impl core::error::Error for KeyBlockError {}

/// Why a transfer (or a slot) is not a table with its keys.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DeployError {
    Table(DecodeError),
    Keys(KeyBlockError),
}

impl fmt::Display for DeployError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DeployError::Table(e) => e.fmt(f),
            DeployError::Keys(e) => e.fmt(f),
        }
    }
}

impl core::error::Error for DeployError {}

impl LinkKeys {
    /// The keys of `peer`, if any.
    pub fn of(&self, peer: u16) -> Option<&PeerKeys> {
        self.peers.iter().find(|k| k.peer == peer)
    }

    /// The encoded block's length.
    pub fn encoded_len(&self) -> usize {
        HEAD_LEN + self.peers.len() * ENTRY_LEN + TRAILER_LEN
    }

    /// Writes the block into `buf`; returns its length (`None`: `buf` is too small).
    pub fn encode(&self, buf: &mut [u8]) -> Option<usize> {
        let len = self.encoded_len();
        let out = buf.get_mut(..len)?;
        out[field::MAGIC].copy_from_slice(&MAGIC);
        out[field::GENERATION].copy_from_slice(&self.generation.to_le_bytes());
        out[field::COUNT] = self.peers.len() as u8;
        for (k, entry) in self
            .peers
            .iter()
            .zip(out[HEAD_LEN..len - TRAILER_LEN].chunks_exact_mut(ENTRY_LEN))
        {
            entry[field::PEER].copy_from_slice(&k.peer.to_le_bytes());
            entry[field::SEND].copy_from_slice(&k.send);
            entry[field::RECEIVE].copy_from_slice(&k.receive);
        }
        let crc = CRC32.checksum(&out[..len - TRAILER_LEN]);
        out[len - TRAILER_LEN..].copy_from_slice(&crc.to_le_bytes());
        Some(len)
    }

    /// Reads a whole block. Never panics, whatever the bytes.
    pub fn decode(bytes: &[u8]) -> Result<LinkKeys, KeyBlockError> {
        let truncated = |need| KeyBlockError::Truncated {
            len: bytes.len(),
            need,
        };
        let head = bytes.get(..HEAD_LEN).ok_or(truncated(HEAD_LEN))?;
        if head[field::MAGIC] != MAGIC {
            return Err(KeyBlockError::BadMagic);
        }
        let count = head[field::COUNT];
        if usize::from(count) > MAX_PEERS {
            return Err(KeyBlockError::TooManyPeers(count));
        }
        let body_end = HEAD_LEN + usize::from(count) * ENTRY_LEN;
        let len = body_end + TRAILER_LEN;
        let block = bytes.get(..len).ok_or(truncated(len))?;
        if bytes.len() > len {
            return Err(KeyBlockError::TrailingBytes(bytes.len() - len));
        }
        let (body, crc) = block.split_at(body_end);
        let stored = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
        let computed = CRC32.checksum(body);
        if stored != computed {
            return Err(KeyBlockError::Crc { stored, computed });
        }
        let mut gen = [0u8; 4];
        gen.copy_from_slice(&head[field::GENERATION]);
        let mut keys = LinkKeys {
            generation: u32::from_le_bytes(gen),
            peers: Vec::new(),
        };
        for entry in body[HEAD_LEN..].chunks_exact(ENTRY_LEN) {
            let mut k = PeerKeys {
                peer: u16::from_le_bytes([entry[0], entry[1]]),
                send: [0; KEY_LEN],
                receive: [0; KEY_LEN],
            };
            k.send.copy_from_slice(&entry[field::SEND]);
            k.receive.copy_from_slice(&entry[field::RECEIVE]);
            // `count` is at most MAX_PEERS: there is room.
            let _ = keys.peers.push(k);
        }
        Ok(keys)
    }

    /// Whether the block names exactly `table`'s peers, each once, for its generation.
    pub fn check(&self, table: &Table) -> Result<(), KeyBlockError> {
        if self.generation != table.generation {
            return Err(KeyBlockError::Generation {
                table: table.generation,
                keys: self.generation,
            });
        }
        let exact = self.peers.len() == table.peers.len()
            && table
                .peers
                .iter()
                .all(|&p| self.peers.iter().filter(|k| k.peer == p).count() == 1);
        if exact {
            Ok(())
        } else {
            Err(KeyBlockError::Peers)
        }
    }
}

/// Splits a transfer (or a slot) into the table blob and what follows it (empty, or a
/// key block), by the blob's own length field.
pub fn split(bytes: &[u8]) -> Result<(&[u8], &[u8]), DecodeError> {
    let head = bytes.get(..HEADER_LEN).ok_or(DecodeError::Truncated {
        len: bytes.len(),
        need: HEADER_LEN + TRAILER_LEN,
    })?;
    let payload_len = usize::from(u16::from_le_bytes([
        head.get(LENGTH_AT).copied().unwrap_or(0),
        head.get(LENGTH_AT + 1).copied().unwrap_or(0),
    ]));
    let blob_len = HEADER_LEN + payload_len + TRAILER_LEN;
    if bytes.len() < blob_len {
        return Err(DecodeError::Truncated {
            len: bytes.len(),
            need: blob_len,
        });
    }
    Ok(bytes.split_at(blob_len))
}

/// A decoded transfer (or flash slot): the table, its link keys if a block followed, and
/// the table's identity on the air (its blob's CRC).
#[derive(Debug, Clone, PartialEq)]
pub struct Deployment {
    pub table: Table,
    pub keys: Option<LinkKeys>,
    pub id: TableId,
}

/// Decodes and validates a transfer: the table, and its link keys if a block follows (which
/// must name exactly the table's peers, for its generation). Never panics.
pub fn decode_deployment(bytes: &[u8]) -> Result<Deployment, DeployError> {
    let (blob, rest) = split(bytes).map_err(DeployError::Table)?;
    let (table, id) = blob::decode_identified(blob).map_err(DeployError::Table)?;
    let keys = if rest.is_empty() {
        None
    } else {
        let keys = LinkKeys::decode(rest).map_err(DeployError::Keys)?;
        keys.check(&table).map_err(DeployError::Keys)?;
        Some(keys)
    };
    Ok(Deployment { table, keys, id })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys() -> LinkKeys {
        let mut k = LinkKeys {
            generation: 7,
            peers: Vec::new(),
        };
        k.peers
            .push(PeerKeys {
                peer: 0x0012,
                send: [0x11; 16],
                receive: [0x22; 16],
            })
            .unwrap();
        k
    }

    /// The bytes of a one-peer block, literally.
    #[test]
    fn a_one_peer_block_is_these_bytes() {
        let mut buf = [0u8; MAX_LEN];
        let n = keys().encode(&mut buf).unwrap();
        assert_eq!(n, 9 + 34 + 4);
        assert_eq!(&buf[..9], b"ECCK\x07\x00\x00\x00\x01");
        assert_eq!(&buf[9..11], &[0x12, 0x00]);
        assert_eq!(&buf[11..27], &[0x11; 16]);
        assert_eq!(&buf[27..43], &[0x22; 16]);
        let crc = CRC32.checksum(&buf[..43]);
        assert_eq!(&buf[43..47], &crc.to_le_bytes());
        assert_eq!(LinkKeys::decode(&buf[..n]).unwrap(), keys());
    }

    #[test]
    fn damaged_blocks_are_refused_by_their_reason() {
        let mut buf = [0u8; MAX_LEN];
        let n = keys().encode(&mut buf).unwrap();
        let b = &buf[..n];
        assert_eq!(
            LinkKeys::decode(&b[..n - 1]),
            Err(KeyBlockError::Truncated {
                len: n - 1,
                need: n
            })
        );
        let mut long = b.to_vec_in_test();
        long.push(0).unwrap();
        assert_eq!(
            LinkKeys::decode(&long),
            Err(KeyBlockError::TrailingBytes(1))
        );
        let mut flipped = b.to_vec_in_test();
        flipped[20] ^= 1;
        assert!(matches!(
            LinkKeys::decode(&flipped),
            Err(KeyBlockError::Crc { .. })
        ));
        let mut magic = b.to_vec_in_test();
        magic[0] = b'X';
        assert_eq!(LinkKeys::decode(&magic), Err(KeyBlockError::BadMagic));
        let mut many = b.to_vec_in_test();
        many[8] = 9;
        assert_eq!(LinkKeys::decode(&many), Err(KeyBlockError::TooManyPeers(9)));
    }

    /// A deployment's identity is its blob's CRC (the blob's last four bytes): the same
    /// with a key block after it or without one, never a function of a key.
    #[test]
    fn a_deployment_is_identified_by_its_blob_alone() {
        let mut table = Table::empty("VC");
        table.generation = 7;
        table.peers.push(0x0012).unwrap();
        let mut buf = [0u8; 512];
        let n = blob::encode(&table, &mut buf).unwrap();
        let crc = TableId(buf[n - 4..n].try_into().unwrap());
        let plain = decode_deployment(&buf[..n]).unwrap();
        assert_eq!((plain.id, plain.keys), (crc, None));
        let k = keys().encode(&mut buf[n..]).unwrap();
        let keyed = decode_deployment(&buf[..n + k]).unwrap();
        assert_eq!((keyed.id, keyed.keys.is_some()), (crc, true));
        assert_eq!(TableId::of(&table), Ok(crc));
        // The identity at a generation is the blob's at it, whatever the table says.
        let unnumbered = Table {
            generation: 0,
            ..table.clone()
        };
        assert_eq!(TableId::at(&unnumbered, 7), Ok(crc));
        // Other keys, the same identity.
        buf[n + HEAD_LEN + 2] ^= 0xFF;
        let crc_at = n + k - TRAILER_LEN;
        let fixed = CRC32.checksum(&buf[n..crc_at]).to_le_bytes();
        buf[crc_at..n + k].copy_from_slice(&fixed);
        assert_eq!(decode_deployment(&buf[..n + k]).unwrap().id, crc);
    }

    #[test]
    fn debug_never_shows_a_key() {
        let shown = alloc_free_debug(&keys());
        assert!(!shown.contains("17"), "{shown}");
        assert!(shown.contains("<secret>"), "{shown}");
    }

    fn alloc_free_debug(k: &LinkKeys) -> heapless::String<256> {
        use fmt::Write;
        let mut s = heapless::String::new();
        write!(s, "{k:?}").unwrap();
        s
    }

    trait ToVecInTest {
        fn to_vec_in_test(&self) -> heapless::Vec<u8, MAX_LEN>;
    }

    impl ToVecInTest for [u8] {
        fn to_vec_in_test(&self) -> heapless::Vec<u8, MAX_LEN> {
            heapless::Vec::from_slice(self).unwrap()
        }
    }
}
