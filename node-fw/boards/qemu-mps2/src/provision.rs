//! The provisioning area: written once per node, the way a factory programs a node id and
//! a key (QEMU: `-device loader,addr=0x003ff000,data=0xA5010003,data-len=4`, and with a
//! management key four more loaders at `0x003ff004..=0x003ff010`: `config-tool keys
//! provision --board qemu` prints them). Every node boots the same image. The layout and
//! its parser are `node_fw::provision`:
//!
//! ```text
//! 0x003F_F000  word     bits 31..24 0xA5 (magic), 23..16 flags (bit 0: semihosting,
//!                       bit 1: count busy time and stimuli, bit 2: a key follows),
//!                       15..0 the node's 16-bit short address
//! 0x003F_F004  key      16 bytes as four little-endian u32 words (with flag bit 2)
//! ```

use node_fw::provision::{self, ManagementKey, ProvisionError, KEY_WORDS};

pub use node_fw::provision::{FLAG_COUNT, FLAG_SEMIHOSTING};

/// Where the word and the key are (outside the linker's FLASH region: see memory.x).
const WORD_AT: usize = provision::qemu::WORD_AT as usize;
const KEY_AT: usize = provision::qemu::KEY_AT as usize;

pub struct Provision {
    pub addr: u16,
    pub flags: u8,
    /// The management key if the word announces one (an error if its words are blank).
    pub key: Result<Option<ManagementKey>, ProvisionError>,
}

fn word_at(at: usize) -> u32 {
    // SAFETY: words of emulated SSRAM that nothing else uses.
    unsafe { core::ptr::read_volatile(at as *const u32) }
}

/// The provisioning, if the word was written and names a usable address.
pub fn read() -> Option<Provision> {
    let w = provision::parse_word(word_at(WORD_AT)).ok()?;
    let key = if w.has_key() {
        let words: [u32; KEY_WORDS] = core::array::from_fn(|i| word_at(KEY_AT + 4 * i));
        ManagementKey::from_words(words)
            .map(Some)
            .ok_or(ProvisionError::NoKey)
    } else {
        Ok(None)
    };
    Some(Provision {
        addr: w.addr,
        flags: w.flags,
        key,
    })
}
