//! CCM* at ENC-MIC-64 over any [`BlockCipher`]: what a node seals and opens its frames with
//! (`seal_default`, `unseal_default`).
//!
//! The same transformation as the `ccm` crate's `Ccm<_, U8, U13>` (which the general path,
//! every level, keeps using; tests hold the two equal): RFC 3610 with L = 2 (a 13-byte
//! nonce), M = 8. CBC-MAC over B0, the a data with its 2-byte length and the m data (each
//! zero-padded to whole blocks), the MIC its first 8 bytes encrypted with A0's keystream,
//! m encrypted with A1, A2, ... One function for both directions and one block at a time:
//! on a node the `ccm` crate and its CTR, stream and array layers took about 2.5 KB of
//! flash for one instance; this is a few hundred bytes, and it encrypts the same blocks
//! (the same count, so a board cipher sees the same work).

use super::{BlockCipher, SecError, BLOCK_LEN, NONCE_LEN};

/// The MIC length of ENC-MIC-64.
pub(crate) const MIC_LEN: usize = 8;

/// Which way [`ccm_star_64`] runs: the CBC-MAC is always over the plaintext.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Direction {
    /// `m` is plaintext: MAC it, then encrypt it.
    Seal,
    /// `m` is ciphertext: decrypt it, then MAC it.
    Open,
}

/// `x ^= bytes` (up to a block; shorter is zero-padded), then `x = E(x)`.
fn absorb<C: BlockCipher>(
    cipher: &C,
    x: &mut [u8; BLOCK_LEN],
    bytes: &[u8],
) -> Result<(), SecError> {
    for (x, b) in x.iter_mut().zip(bytes) {
        *x ^= *b;
    }
    cipher.encrypt(x).map_err(|_| SecError::Cipher)
}

/// The blocks `flags || nonce || n` (`n` big-endian) of one nonce: B0 and the A`i`, as
/// one big-endian 128-bit number with the flags and the counter zero (put together once
/// from the nonce's bytes, no slice copies: `copy_from_slice` left out of line keeps a
/// panic location, this file's path, in the image).
struct NonceBlocks(u128);

impl NonceBlocks {
    fn new(nonce: &[u8; NONCE_LEN]) -> NonceBlocks {
        let [n0, n1, n2, n3, n4, n5, n6, n7, n8, n9, n10, n11, n12] = *nonce;
        NonceBlocks(u128::from_be_bytes([
            0, n0, n1, n2, n3, n4, n5, n6, n7, n8, n9, n10, n11, n12, 0, 0,
        ]))
    }

    /// The block with `flags` and `n`.
    fn block(&self, flags: u8, n: u16) -> [u8; BLOCK_LEN] {
        (self.0 | u128::from(flags) << 120 | u128::from(n)).to_be_bytes()
    }
}

/// The keystream block A`i`: flags L - 1 = 1, the nonce, the counter `i`.
fn keystream<C: BlockCipher>(
    cipher: &C,
    nonce: &NonceBlocks,
    i: u16,
) -> Result<[u8; BLOCK_LEN], SecError> {
    let mut a = nonce.block(1, i);
    cipher.encrypt(&mut a).map_err(|_| SecError::Cipher)?;
    Ok(a)
}

/// The first block of the a data: its 2-byte length `len`, then its first 14 bytes
/// (`head`; fewer: zero-padded).
fn first_a_block(len: u16, head: &[u8]) -> [u8; BLOCK_LEN] {
    let [l0, l1] = len.to_be_bytes();
    let mut first = [l0, l1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
    let [_, _, rest @ ..] = &mut first;
    for (f, b) in rest.iter_mut().zip(head) {
        *f = *b;
    }
    first
}

/// CCM* at M = 8 under `cipher`: transforms `m` in place (`direction`) and returns the
/// encrypted MIC (to send, or to compare with the received one). `a` and `m` must be
/// below 0xFF00 and 0x1_0000 bytes (a frame is at most 127): else [`SecError::NoRoom`].
/// On any error `m` holds garbage: the caller clears it.
pub(crate) fn ccm_star_64<C: BlockCipher>(
    cipher: &C,
    nonce: &[u8; NONCE_LEN],
    a: &[u8],
    m: &mut [u8],
    direction: Direction,
) -> Result<[u8; MIC_LEN], SecError> {
    let (Ok(a_len), Ok(m_len)) = (u16::try_from(a.len()), u16::try_from(m.len())) else {
        return Err(SecError::NoRoom);
    };
    if a_len >= 0xFF00 {
        return Err(SecError::NoRoom);
    }
    // B0: flags (Adata, M' = (M - 2) / 2 = 3, L' = L - 1 = 1), nonce, l(m).
    let flags = if a.is_empty() { 0 } else { 0x40 } | 0x18 | 0x01;
    let nonce = NonceBlocks::new(nonce);
    let mut x = nonce.block(flags, m_len);
    cipher.encrypt(&mut x).map_err(|_| SecError::Cipher)?;
    if !a.is_empty() {
        // l(a) (2 bytes), then a: the first block holds 14 bytes of it.
        let head = a.get(..BLOCK_LEN - 2).unwrap_or(a);
        let tail = a.get(BLOCK_LEN - 2..).unwrap_or(&[]);
        absorb(cipher, &mut x, &first_a_block(a_len, head))?;
        for block in tail.chunks(BLOCK_LEN) {
            absorb(cipher, &mut x, block)?;
        }
    }
    for (i, block) in m.chunks_mut(BLOCK_LEN).enumerate() {
        // i < 0x1000: m is below 0x1_0000 bytes.
        let s = keystream(cipher, &nonce, i as u16 + 1)?;
        let xor = |block: &mut [u8]| block.iter_mut().zip(&s).for_each(|(b, s)| *b ^= *s);
        if direction == Direction::Open {
            xor(block);
        }
        absorb(cipher, &mut x, block)?;
        if direction == Direction::Seal {
            xor(block);
        }
    }
    let s0 = keystream(cipher, &nonce, 0)?;
    let [t0, t1, t2, t3, t4, t5, t6, t7, ..] =
        (u128::from_ne_bytes(x) ^ u128::from_ne_bytes(s0)).to_ne_bytes();
    Ok([t0, t1, t2, t3, t4, t5, t6, t7])
}

/// Whether `a` and `b` are equal, in time independent of where they differ.
pub(crate) fn same_mic(a: &[u8; MIC_LEN], b: &[u8]) -> bool {
    b.len() == MIC_LEN && a.iter().zip(b).fold(0u8, |d, (a, b)| d | (a ^ b)) == 0
}
