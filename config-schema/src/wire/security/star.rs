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

/// The block `flags || nonce || n` (`n` big-endian): B0 and the A`i`. Put together from
/// its parts, no slice copies: `copy_from_slice` left out of line keeps a panic location
/// (this file's path) in the image.
fn nonce_block(flags: u8, nonce: &[u8; NONCE_LEN], n: u16) -> [u8; BLOCK_LEN] {
    let [n0, n1, n2, n3, n4, n5, n6, n7, n8, n9, n10, n11, n12] = *nonce;
    let [c0, c1] = n.to_be_bytes();
    [
        flags, n0, n1, n2, n3, n4, n5, n6, n7, n8, n9, n10, n11, n12, c0, c1,
    ]
}

/// The keystream block A`i`: flags L - 1 = 1, the nonce, the counter `i` (big-endian).
fn keystream<C: BlockCipher>(
    cipher: &C,
    nonce: &[u8; NONCE_LEN],
    i: u16,
) -> Result<[u8; BLOCK_LEN], SecError> {
    let mut a = nonce_block(1, nonce, i);
    cipher.encrypt(&mut a).map_err(|_| SecError::Cipher)?;
    Ok(a)
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
    let mut x = nonce_block(flags, nonce, m_len);
    cipher.encrypt(&mut x).map_err(|_| SecError::Cipher)?;
    if !a.is_empty() {
        // l(a) (2 bytes), then a: the first block holds 14 bytes of it.
        let head = a.get(..BLOCK_LEN - 2).unwrap_or(a);
        let tail = a.get(BLOCK_LEN - 2..).unwrap_or(&[]);
        let [l0, l1] = a_len.to_be_bytes();
        let mut first = [0u8; BLOCK_LEN];
        for (f, b) in first.iter_mut().zip([l0, l1].iter().chain(head)) {
            *f = *b;
        }
        absorb(cipher, &mut x, &first)?;
        for block in tail.chunks(BLOCK_LEN) {
            absorb(cipher, &mut x, block)?;
        }
    }
    for (i, block) in m.chunks_mut(BLOCK_LEN).enumerate() {
        // i < 0x1000: m is below 0x1_0000 bytes.
        let s = keystream(cipher, nonce, i as u16 + 1)?;
        let xor = |block: &mut [u8]| block.iter_mut().zip(&s).for_each(|(b, s)| *b ^= *s);
        if direction == Direction::Open {
            xor(block);
        }
        absorb(cipher, &mut x, block)?;
        if direction == Direction::Seal {
            xor(block);
        }
    }
    let s0 = keystream(cipher, nonce, 0)?;
    let mut mic = [0u8; MIC_LEN];
    for ((t, x), s) in mic.iter_mut().zip(&x).zip(&s0) {
        *t = x ^ s;
    }
    Ok(mic)
}

/// Whether `a` and `b` are equal, in time independent of where they differ.
pub(crate) fn same_mic(a: &[u8; MIC_LEN], b: &[u8]) -> bool {
    b.len() == MIC_LEN && a.iter().zip(b).fold(0u8, |d, (a, b)| d | (a ^ b)) == 0
}
