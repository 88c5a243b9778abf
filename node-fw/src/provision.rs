//! What a node is given at flash time, once per node (never in the image): its address,
//! board flags and its management key (docs/security.md, docs/boards.md). The node never
//! derives a key: the tool derives it from the machine secret and prints what to write
//! (`config-tool keys provision`); this module reads it back. `no_std`, no allocation.
//!
//! The provisioning word (QEMU `0x003F_F000`, nRF52840 UICR `CUSTOMER[0]`):
//!
//! ```text
//! bits 31..24  0xA5     magic: the word was written
//! bits 23..16  flags    bit 0: the emulator has semihosting (QEMU only)
//!                       bit 1: count busy time and stimuli (QEMU only)
//!                       bit 2: a management key follows (KEY words)
//! bits 15..0   address  the node's 16-bit short address (not 0xFFFE, 0xFFFF)
//! ```
//!
//! The key: 16 bytes as four little-endian u32 words, key byte `4i + j` in bits
//! `8j + 7 .. 8j` of word `i` (QEMU: `0x003F_F004..=0x003F_F013`, right after the word;
//! nRF52840: UICR `CUSTOMER[2..=5]`, `0x1000_1088..=0x1000_1097`, after the channel in
//! `CUSTOMER[1]`). All zeros (QEMU's unwritten RAM) and all ones (erased UICR) are refused:
//! the key was not written.
//!
//! The host board's key file (`node-host --key FILE`), one line of text:
//!
//! ```text
//! robot-node-key v1 0x0011 <32 lowercase hex digits>
//! ```

use core::fmt;

/// The magic in bits 31..24 of the provisioning word.
pub const MAGIC: u8 = 0xA5;
/// Flag: the emulator has semihosting (flash file, clock, log). QEMU only.
pub const FLAG_SEMIHOSTING: u8 = 1;
/// Flag: count busy time and stimuli, logged every second. QEMU only.
pub const FLAG_COUNT: u8 = 2;
/// Flag: the four key words after the word hold the node's management key.
pub const FLAG_KEY: u8 = 4;

/// Bytes of a management key (AES-128).
pub const KEY_LEN: usize = 16;
/// The key as u32 words.
pub const KEY_WORDS: usize = KEY_LEN / 4;

/// The QEMU board's provisioning area (emulated SSRAM, written by `-device loader`).
pub mod qemu {
    /// The provisioning word.
    pub const WORD_AT: u32 = 0x003F_F000;
    /// The first of the four key words.
    pub const KEY_AT: u32 = 0x003F_F004;
}

/// The nRF52840's provisioning area: UICR `CUSTOMER` registers (`nrfjprog --memwr`).
pub mod nrf52840 {
    /// `CUSTOMER[0]`: the provisioning word.
    pub const WORD_AT: u32 = 0x1000_1080;
    /// `CUSTOMER[1]`: the radio channel of an unconfigured node (11..=26; erased: 15).
    pub const CHANNEL_AT: u32 = 0x1000_1084;
    /// `CUSTOMER[2]`: the first of the four key words (`CUSTOMER[2..=5]`).
    pub const KEY_AT: u32 = 0x1000_1088;
}

/// A node's management key. `Debug` prints `<secret>`.
#[derive(Clone)]
pub struct ManagementKey([u8; KEY_LEN]);

impl ManagementKey {
    pub fn from_bytes(bytes: [u8; KEY_LEN]) -> ManagementKey {
        ManagementKey(bytes)
    }

    /// The bytes (for the frame codec, and for the tool that writes them).
    pub fn expose(&self) -> &[u8; KEY_LEN] {
        &self.0
    }

    /// The key as the four words to write, in address order.
    pub fn words(&self) -> [u32; KEY_WORDS] {
        let b = &self.0;
        core::array::from_fn(|i| {
            u32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]])
        })
    }

    /// The key read back from its four words; `None` if they were never written (all
    /// zeros or all ones).
    pub fn from_words(words: [u32; KEY_WORDS]) -> Option<ManagementKey> {
        if words.iter().all(|w| *w == 0) || words.iter().all(|w| *w == u32::MAX) {
            return None;
        }
        let mut bytes = [0u8; KEY_LEN];
        for (chunk, w) in bytes.chunks_exact_mut(4).zip(words) {
            chunk.copy_from_slice(&w.to_le_bytes());
        }
        Some(ManagementKey(bytes))
    }
}

impl fmt::Debug for ManagementKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("ManagementKey(<secret>)")
    }
}

/// The provisioning word, read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Word {
    pub addr: u16,
    pub flags: u8,
}

impl Word {
    /// The word to write.
    pub fn encode(self) -> u32 {
        u32::from(MAGIC) << 24 | u32::from(self.flags) << 16 | u32::from(self.addr)
    }

    /// Whether the key words are to be read.
    pub fn has_key(self) -> bool {
        self.flags & FLAG_KEY != 0
    }
}

/// Why a node's provisioning is not usable (the node stays off the air).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProvisionError {
    /// No magic: the word was never written.
    NoWord,
    /// The address is 0xFFFE or 0xFFFF (reserved by IEEE 802.15.4).
    ReservedAddress(u16),
    /// The word says a key follows, but the key words are blank.
    NoKey,
}

impl fmt::Display for ProvisionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ProvisionError::NoWord => f.write_str("no provisioning word (no node id)"),
            ProvisionError::ReservedAddress(a) => {
                write!(f, "provisioned address {a:#06x} is reserved")
            }
            ProvisionError::NoKey => {
                f.write_str("the provisioning word announces a key but the key words are blank")
            }
        }
    }
}

/// Parses the provisioning word.
pub fn parse_word(word: u32) -> Result<Word, ProvisionError> {
    if (word >> 24) as u8 != MAGIC {
        return Err(ProvisionError::NoWord);
    }
    let addr = word as u16;
    if addr >= 0xFFFE {
        return Err(ProvisionError::ReservedAddress(addr));
    }
    Ok(Word {
        addr,
        flags: (word >> 16) as u8,
    })
}

/// The whole provisioning: the word and, if it announces one, the key (`key_words` reads
/// the four words after it, called only then).
pub fn read(
    word: u32,
    key_words: impl FnOnce() -> [u32; KEY_WORDS],
) -> Result<(Word, Option<ManagementKey>), ProvisionError> {
    let w = parse_word(word)?;
    if !w.has_key() {
        return Ok((w, None));
    }
    let key = ManagementKey::from_words(key_words()).ok_or(ProvisionError::NoKey)?;
    Ok((w, Some(key)))
}

/// The first words of a host key file, and its version.
pub const NODE_KEY_TAG: &str = "robot-node-key v1 ";

/// A host key file's line (`Display` writes it, newline included).
pub struct NodeKeyLine<'a> {
    pub addr: u16,
    pub key: &'a ManagementKey,
}

impl fmt::Display for NodeKeyLine<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{NODE_KEY_TAG}{:#06x} ", self.addr)?;
        for b in self.key.expose() {
            write!(f, "{b:02x}")?;
        }
        f.write_str("\n")
    }
}

/// What is wrong with a host key file, and the byte where it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KeyFileError {
    pub at: usize,
    pub what: KeyFileProblem,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeyFileProblem {
    /// Does not start with `robot-node-key v1 `.
    NotANodeKey,
    /// Not `0x` and four hex digits, or a reserved address.
    Address,
    /// Not one space and 32 hex digits.
    Key,
    /// The key is blank (all zeros or all ones).
    BlankKey,
    /// Something after the key.
    Trailing,
}

impl fmt::Display for KeyFileProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            KeyFileProblem::NotANodeKey => {
                "not a node key (expected `robot-node-key v1 0xAAAA` and 32 hex digits; \
                 `config-tool keys provision --board host --out FILE` writes one)"
            }
            KeyFileProblem::Address => "expected the node's address as 0x and 4 hex digits",
            KeyFileProblem::Key => "expected a space and 32 hex digits (the 16 key bytes)",
            KeyFileProblem::BlankKey => "the key is blank (all zeros or all ones)",
            KeyFileProblem::Trailing => "expected the end of the line after the key",
        })
    }
}

fn hex_digit(d: u8) -> Option<u8> {
    match d {
        b'0'..=b'9' => Some(d - b'0'),
        b'a'..=b'f' => Some(d - b'a' + 10),
        b'A'..=b'F' => Some(d - b'A' + 10),
        _ => None,
    }
}

/// Hex digits at `s[at..at + 2 * out.len()]` into `out`, or the first bad digit's index.
fn hex_into(s: &[u8], at: usize, out: &mut [u8]) -> Result<(), usize> {
    for (i, o) in out.iter_mut().enumerate() {
        let j = at + 2 * i;
        let hi = s.get(j).and_then(|d| hex_digit(*d)).ok_or(j)?;
        let lo = s.get(j + 1).and_then(|d| hex_digit(*d)).ok_or(j + 1)?;
        *o = hi << 4 | lo;
    }
    Ok(())
}

/// Parses a host key file: the address it is for and the key.
pub fn parse_node_key(text: &str) -> Result<(u16, ManagementKey), KeyFileError> {
    let err = |at, what| KeyFileError { at, what };
    let s = text.as_bytes();
    if !text.starts_with(NODE_KEY_TAG) {
        return Err(err(0, KeyFileProblem::NotANodeKey));
    }
    let mut at = NODE_KEY_TAG.len();
    if s.get(at..at + 2) != Some(b"0x".as_slice()) {
        return Err(err(at, KeyFileProblem::Address));
    }
    let mut addr = [0u8; 2];
    hex_into(s, at + 2, &mut addr).map_err(|j| err(j, KeyFileProblem::Address))?;
    let addr = u16::from_be_bytes(addr);
    if addr >= 0xFFFE {
        return Err(err(at, KeyFileProblem::Address));
    }
    at += 6;
    if s.get(at) != Some(&b' ') {
        return Err(err(at, KeyFileProblem::Key));
    }
    at += 1;
    let mut key = [0u8; KEY_LEN];
    hex_into(s, at, &mut key).map_err(|j| err(j, KeyFileProblem::Key))?;
    if key.iter().all(|b| *b == 0) || key.iter().all(|b| *b == 0xFF) {
        return Err(err(at, KeyFileProblem::BlankKey));
    }
    at += 2 * KEY_LEN;
    match s.get(at..) {
        Some(b"" | b"\n" | b"\r\n") => Ok((addr, ManagementKey(key))),
        _ => Err(err(at, KeyFileProblem::Trailing)),
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::format;
    use std::string::ToString;

    use super::*;

    fn key() -> ManagementKey {
        ManagementKey::from_bytes(core::array::from_fn(|i| 0x10 + i as u8))
    }

    #[test]
    fn key_words_are_little_endian_in_address_order() {
        assert_eq!(
            key().words(),
            [0x1312_1110, 0x1716_1514, 0x1b1a_1918, 0x1f1e_1d1c]
        );
        let back = ManagementKey::from_words(key().words()).unwrap();
        assert_eq!(back.expose(), key().expose());
    }

    #[test]
    fn blank_key_words_are_no_key() {
        assert!(ManagementKey::from_words([0; 4]).is_none());
        assert!(ManagementKey::from_words([u32::MAX; 4]).is_none());
        // One written word is a key (a derived key is blank with probability 2^-127).
        assert!(ManagementKey::from_words([0, 0, 0, 1]).is_some());
        assert!(ManagementKey::from_words([u32::MAX, u32::MAX, 0, u32::MAX]).is_some());
    }

    #[test]
    fn the_word_round_trips_and_bad_words_are_refused() {
        let w = Word {
            addr: 0x0011,
            flags: FLAG_SEMIHOSTING | FLAG_KEY,
        };
        assert_eq!(w.encode(), 0xA505_0011);
        assert_eq!(parse_word(0xA505_0011), Ok(w));
        assert_eq!(parse_word(0xA500_0011).map(Word::has_key), Ok(false));
        assert_eq!(parse_word(0), Err(ProvisionError::NoWord));
        assert_eq!(parse_word(u32::MAX), Err(ProvisionError::NoWord));
        assert_eq!(
            parse_word(0xA500_FFFE),
            Err(ProvisionError::ReservedAddress(0xFFFE))
        );
    }

    #[test]
    fn the_key_is_read_only_when_the_word_announces_it() {
        let (w, k) = read(0xA501_0011, || panic!("no key words to read")).unwrap();
        assert_eq!((w.addr, k.is_none()), (0x0011, true));
        let (_, k) = read(0xA505_0011, || key().words()).unwrap();
        assert_eq!(k.unwrap().expose(), key().expose());
        assert_eq!(
            read(0xA504_0011, || [u32::MAX; 4]).unwrap_err(),
            ProvisionError::NoKey
        );
        assert_eq!(
            read(0xA505_0011, || [0; 4]).unwrap_err(),
            ProvisionError::NoKey
        );
    }

    #[test]
    fn debug_never_shows_the_key() {
        assert_eq!(format!("{:?}", key()), "ManagementKey(<secret>)");
    }

    #[test]
    fn a_host_key_file_round_trips() {
        let text = NodeKeyLine {
            addr: 0x0011,
            key: &key(),
        }
        .to_string();
        assert_eq!(
            text,
            "robot-node-key v1 0x0011 101112131415161718191a1b1c1d1e1f\n"
        );
        let (addr, k) = parse_node_key(&text).unwrap();
        assert_eq!((addr, k.expose()), (0x0011, key().expose()));
        assert!(parse_node_key(text.trim_end()).is_ok());
        assert!(parse_node_key(&text.replace('\n', "\r\n")).is_ok());
        let (addr, k) =
            parse_node_key("robot-node-key v1 0x00AB 101112131415161718191A1B1C1D1E1F").unwrap();
        assert_eq!((addr, k.expose()), (0x00AB, key().expose()));
    }

    #[test]
    fn bad_host_key_files_say_where() {
        let good = "robot-node-key v1 0x0011 101112131415161718191a1b1c1d1e1f\n";
        let e = |t: &str| parse_node_key(t).unwrap_err();
        let at = |at, what| KeyFileError { at, what };
        assert_eq!(
            e("robot-machine-secret v1 00"),
            at(0, KeyFileProblem::NotANodeKey)
        );
        assert_eq!(e(""), at(0, KeyFileProblem::NotANodeKey));
        assert_eq!(
            e(&good.replace("0x0011", "11")),
            at(18, KeyFileProblem::Address)
        );
        assert_eq!(
            e(&good.replace("0x0011", "0x00g1")),
            at(22, KeyFileProblem::Address)
        );
        assert_eq!(
            e(&good.replace("0x0011", "0xffff")),
            at(18, KeyFileProblem::Address)
        );
        assert_eq!(
            e(&good.replace("0011 ", "0011:")),
            at(24, KeyFileProblem::Key)
        );
        assert_eq!(e(&good.replace("1f\n", "\n")), at(55, KeyFileProblem::Key));
        assert_eq!(
            e(&good.replace("1e1f", "1e1fé")),
            at(57, KeyFileProblem::Trailing)
        );
        assert_eq!(
            e(&good.replace('\n', " x")),
            at(57, KeyFileProblem::Trailing)
        );
        assert_eq!(
            e(&format!("{NODE_KEY_TAG}0x0011 {}", "0".repeat(32))),
            at(25, KeyFileProblem::BlankKey)
        );
        // Multi-byte characters where digits belong: an error, no panic.
        assert_eq!(e(&good.replace("1011", "éé")), at(25, KeyFileProblem::Key));
    }
}
