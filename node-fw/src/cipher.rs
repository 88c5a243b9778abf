//! The AES-128 block cipher under the node's frame security ([`NodeCipher`]): the `aes`
//! crate in software, its key schedules kept for the keys in use (computed once per key,
//! not once per frame), or, with the feature `board-aes`, the board's hardware unit (the
//! nRF52840's AES-ECB), which the board installs once at boot with `install` before it
//! runs the node. The codec is the same (`config_schema::wire::security`); only the block
//! cipher differs, and with `board-aes` the software AES is not linked.
//!
//! A block the board's cipher fails (or any block before `install`) is
//! `SecError::Cipher`: the frame is not sent, or not accepted.

#[cfg(feature = "board-aes")]
use core::cell::Cell;

#[cfg(feature = "board-aes")]
use config_schema::wire::security::{BlockCipher, CipherFault, BLOCK_LEN, KEY_LEN};

/// The block cipher the node secures and opens its frames with.
#[cfg(not(feature = "board-aes"))]
pub type NodeCipher = kept::KeptSoftAes;
#[cfg(not(feature = "board-aes"))]
pub use kept::{work as aes_work, AesWork, SCHEDULES};

#[cfg(not(feature = "board-aes"))]
mod kept;

/// Forgets the key schedules the node's cipher keeps, wiped (software AES; a hardware
/// unit keeps none): the node's link keys changed.
pub fn forget_keys() {
    #[cfg(not(feature = "board-aes"))]
    kept::forget();
}

/// The block cipher the node secures and opens its frames with.
#[cfg(feature = "board-aes")]
pub type NodeCipher = BoardAes;

/// A board's AES-128: encrypts `block` in place under `key`, or fails.
#[cfg(feature = "board-aes")]
pub type BlockFn = fn(&[u8; KEY_LEN], &mut [u8; BLOCK_LEN]) -> Result<(), CipherFault>;

#[cfg(feature = "board-aes")]
static BOARD_AES: critical_section::Mutex<Cell<Option<BlockFn>>> =
    critical_section::Mutex::new(Cell::new(None));

/// Makes `f` the node's AES-128 (once, at boot, before the node runs).
#[cfg(feature = "board-aes")]
pub fn install(f: BlockFn) {
    critical_section::with(|cs| BOARD_AES.borrow(cs).set(Some(f)));
}

/// Whether a board cipher is installed.
#[cfg(feature = "board-aes")]
pub fn installed() -> bool {
    critical_section::with(|cs| BOARD_AES.borrow(cs).get()).is_some()
}

/// The installed board cipher under one key (a hardware unit takes the key with every
/// block: no key schedule).
#[cfg(feature = "board-aes")]
pub struct BoardAes {
    key: [u8; KEY_LEN],
    f: Option<BlockFn>,
}

#[cfg(feature = "board-aes")]
impl BlockCipher for BoardAes {
    fn new(key: &[u8; KEY_LEN]) -> Self {
        BoardAes {
            key: *key,
            f: critical_section::with(|cs| BOARD_AES.borrow(cs).get()),
        }
    }

    fn encrypt(&self, block: &mut [u8; BLOCK_LEN]) -> Result<(), CipherFault> {
        self.f.ok_or(CipherFault).and_then(|f| f(&self.key, block))
    }
}

#[cfg(all(test, feature = "board-aes"))]
mod tests {
    use super::*;
    use config_schema::wire::security::fips197::{CIPHER, KEY, PLAIN};
    use config_schema::wire::security::SoftAes;

    fn soft(key: &[u8; KEY_LEN], block: &mut [u8; BLOCK_LEN]) -> Result<(), CipherFault> {
        SoftAes::new(key).encrypt(block)
    }

    /// Before a board installs its cipher every block fails (nothing is sent in clear or
    /// with a garbage MIC); after, the node's cipher is the board's.
    #[test]
    fn the_board_cipher_is_the_installed_one() {
        let mut b = PLAIN;
        if !installed() {
            assert_eq!(NodeCipher::new(&KEY).encrypt(&mut b), Err(CipherFault));
        }
        install(soft);
        assert!(installed());
        let mut b = PLAIN;
        assert_eq!(NodeCipher::new(&KEY).encrypt(&mut b), Ok(()));
        assert_eq!(b, CIPHER);
    }
}
