//! The block cipher behind CCM*: AES-128, one block at a time, from any implementation.
//!
//! CCM* only ever encrypts blocks (CBC-MAC and CTR), and its CBC-MAC is serial. The `aes`
//! crate's software backend also has a two-block-parallel path, which CTR would take: a
//! second instance of the whole fixsliced cipher for little gain on a node (a frame's
//! keystream is a few blocks). [`BlockCipher`] is what CCM* needs of AES-128 (encrypt one
//! block, perhaps fail): [`SoftAes`] is the `aes` crate's (host, QEMU, tool), a board may
//! bring its own (the nRF52840's AES-ECB peripheral). [`OneBlock`] offers it to `ccm` as
//! the one-block path only, and remembers a failure for the codec to report.

use core::cell::Cell;

use aes::cipher::consts::{U1, U16};
use aes::cipher::{
    Block, BlockCipherEncBackend, BlockCipherEncClosure, BlockCipherEncrypt, BlockSizeUser, InOut,
    KeyInit, ParBlocksSizeUser,
};
use aes::Aes128;

use super::KEY_LEN;

/// AES block length.
pub const BLOCK_LEN: usize = 16;

/// The block cipher failed (a hardware cipher aborted or never finished): nothing it
/// produced may be used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CipherFault;

/// AES-128 encryption of single blocks under one key: all CCM* needs of its cipher.
pub trait BlockCipher: Sized {
    /// The cipher under `key` (a software key schedule, or a copy for a hardware unit).
    fn new(key: &[u8; KEY_LEN]) -> Self;
    /// Encrypts `block` in place; on `Err` its contents are garbage.
    fn encrypt(&self, block: &mut [u8; BLOCK_LEN]) -> Result<(), CipherFault>;
}

/// AES-128 in software: the `aes` crate (its compact backend where the board's build sets
/// `aes_backend_soft="compact"`). Never fails.
#[derive(Clone)]
pub struct SoftAes(Aes128);

impl BlockCipher for SoftAes {
    fn new(key: &[u8; KEY_LEN]) -> SoftAes {
        SoftAes(Aes128::new(&(*key).into()))
    }

    fn encrypt(&self, block: &mut [u8; BLOCK_LEN]) -> Result<(), CipherFault> {
        self.0.encrypt_block(block.into());
        Ok(())
    }
}

/// A [`BlockCipher`] as the `cipher` crate's block encryptor `ccm` takes, one block at a
/// time; a failed block sets `fault` (which the codec checks once `ccm` returns).
pub(crate) struct OneBlock<'f, C> {
    cipher: C,
    fault: &'f Cell<bool>,
}

impl<'f, C: BlockCipher> OneBlock<'f, C> {
    /// The cipher under `key`, reporting to `fault`.
    pub(crate) fn new(key: &[u8; KEY_LEN], fault: &'f Cell<bool>) -> Self {
        OneBlock {
            cipher: C::new(key),
            fault,
        }
    }
}

impl<C> BlockSizeUser for OneBlock<'_, C> {
    type BlockSize = U16;
}

impl<C: BlockCipher> BlockCipherEncrypt for OneBlock<'_, C> {
    fn encrypt_with_backend(&self, f: impl BlockCipherEncClosure<BlockSize = U16>) {
        f.call(&Backend(self))
    }
}

struct Backend<'a, 'f, C>(&'a OneBlock<'f, C>);

impl<C> BlockSizeUser for Backend<'_, '_, C> {
    type BlockSize = U16;
}

impl<C> ParBlocksSizeUser for Backend<'_, '_, C> {
    type ParBlocksSize = U1;
}

impl<C: BlockCipher> BlockCipherEncBackend for Backend<'_, '_, C> {
    fn encrypt_block(&self, mut block: InOut<'_, '_, Block<Self>>) {
        let mut b: [u8; BLOCK_LEN] = (*block.get_in()).into();
        if self.0.cipher.encrypt(&mut b).is_err() {
            self.0.fault.set(true);
        }
        *block.get_out() = b.into();
    }
}

/// The known answer of FIPS-197 appendix C.1 (AES-128 of 00112233..ff under
/// 00010203..0f), against which every [`BlockCipher`] is tested: the software one here, a
/// board's where it installs its own.
pub mod fips197 {
    pub const KEY: [u8; 16] = [
        0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, 0x09, 0x0a, 0x0b, 0x0c, 0x0d, 0x0e,
        0x0f,
    ];
    pub const PLAIN: [u8; 16] = [
        0x00, 0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88, 0x99, 0xaa, 0xbb, 0xcc, 0xdd, 0xee,
        0xff,
    ];
    pub const CIPHER: [u8; 16] = [
        0x69, 0xc4, 0xe0, 0xd8, 0x6a, 0x7b, 0x04, 0x30, 0xd8, 0xcd, 0xb7, 0x80, 0x70, 0xb4, 0xc5,
        0x5a,
    ];
}

#[cfg(test)]
mod tests {
    use super::*;

    use super::fips197::{CIPHER, KEY, PLAIN};

    #[test]
    fn soft_aes_is_aes_128() {
        let mut b = PLAIN;
        assert_eq!(SoftAes::new(&KEY).encrypt(&mut b), Ok(()));
        assert_eq!(b, CIPHER);
    }

    /// Through the adapter: one block and, as CTR would ask, several; no fault.
    #[test]
    fn one_block_is_aes_128() {
        let fault = Cell::new(false);
        let c = OneBlock::<SoftAes>::new(&KEY, &fault);
        let mut b = Block::<OneBlock<SoftAes>>::from(PLAIN);
        c.encrypt_block(&mut b);
        assert_eq!(b.as_slice(), &CIPHER);
        let mut blocks = [Block::<OneBlock<SoftAes>>::from(PLAIN); 3];
        c.encrypt_blocks(&mut blocks);
        for b in blocks {
            assert_eq!(b.as_slice(), &CIPHER);
        }
        assert!(!fault.get());
    }
}
