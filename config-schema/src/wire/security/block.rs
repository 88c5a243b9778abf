//! The block cipher behind CCM*: AES-128, one block at a time.
//!
//! CCM* only ever encrypts blocks (CBC-MAC and CTR), and its CBC-MAC is serial. The `aes`
//! crate's software backend also has a two-block-parallel path, which CTR would take: a
//! second instance of the whole fixsliced cipher for little gain on a node (a frame's
//! keystream is a few blocks). [`OneBlock`] offers `ccm` the one-block path only: the same
//! AES-128, the same bytes, half the code.

use aes::cipher::consts::{U1, U16};
use aes::cipher::{
    Block, BlockCipherEncBackend, BlockCipherEncClosure, BlockCipherEncrypt, BlockSizeUser, InOut,
    KeyInit, ParBlocksSizeUser,
};
use aes::Aes128;

use super::KEY_LEN;

/// AES-128 encryption of single blocks under one expanded key.
#[derive(Clone)]
pub(crate) struct OneBlock(Aes128);

impl OneBlock {
    /// The key schedule of `key`.
    pub(crate) fn new(key: &[u8; KEY_LEN]) -> OneBlock {
        OneBlock(Aes128::new(&(*key).into()))
    }
}

impl BlockSizeUser for OneBlock {
    type BlockSize = U16;
}

impl BlockCipherEncrypt for OneBlock {
    fn encrypt_with_backend(&self, f: impl BlockCipherEncClosure<BlockSize = U16>) {
        f.call(&Backend(&self.0))
    }
}

struct Backend<'a>(&'a Aes128);

impl BlockSizeUser for Backend<'_> {
    type BlockSize = U16;
}

impl ParBlocksSizeUser for Backend<'_> {
    type ParBlocksSize = U1;
}

impl BlockCipherEncBackend for Backend<'_> {
    fn encrypt_block(&self, block: InOut<'_, '_, Block<Self>>) {
        self.0.encrypt_block_inout(block);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// FIPS-197 appendix C.1: AES-128 of 00112233..ff under 00010203..0f, through the
    /// adapter (one block and, as CTR would ask, several).
    #[test]
    fn one_block_is_aes_128() {
        let key: [u8; 16] = core::array::from_fn(|i| i as u8);
        let plain: [u8; 16] = core::array::from_fn(|i| (i as u8) * 0x11);
        let want = [
            0x69, 0xc4, 0xe0, 0xd8, 0x6a, 0x7b, 0x04, 0x30, 0xd8, 0xcd, 0xb7, 0x80, 0x70, 0xb4,
            0xc5, 0x5a,
        ];
        let c = OneBlock::new(&key);
        let mut b = Block::<OneBlock>::from(plain);
        c.encrypt_block(&mut b);
        assert_eq!(b.as_slice(), &want);
        let mut blocks = [Block::<OneBlock>::from(plain); 3];
        c.encrypt_blocks(&mut blocks);
        for b in blocks {
            assert_eq!(b.as_slice(), &want);
        }
    }
}
