//! The nRF52840 board's memory copy and clear (`boards/nrf52840/src/mem/loops.rs`, the
//! loops behind its `memcpy` and `__aeabi_mem*`), on the host: every alignment of either
//! end and every length, nothing around the range touched.

#[path = "../boards/nrf52840/src/mem/loops.rs"]
#[allow(dead_code)]
mod loops;

use loops::{clear, copy};

use proptest::prelude::*;

/// Word-aligned backing store, so the tests choose each pointer's alignment.
#[repr(C, align(4))]
struct Buf([u8; 64]);

fn pattern(seed: u8) -> Buf {
    Buf(core::array::from_fn(|i| {
        seed.wrapping_add(i as u8).wrapping_mul(31) | 1
    }))
}

proptest! {
    /// Every alignment of either end and every length: the bytes copied, nothing
    /// around them touched.
    #[test]
    fn copy_is_a_copy(d in 0usize..8, s in 0usize..8, n in 0usize..48, seed: u8) {
        let src = pattern(seed);
        let mut dst = Buf([0xEE; 64]);
        let mut want = dst.0;
        want[d..d + n].copy_from_slice(&src.0[s..s + n]);
        // SAFETY: both ranges lie inside their 64-byte buffers, which do not overlap.
        unsafe { copy(dst.0.as_mut_ptr().add(d), src.0.as_ptr().add(s), n) };
        prop_assert_eq!(dst.0, want);
    }

    #[test]
    fn clear_is_a_clear(d in 0usize..8, n in 0usize..48, seed: u8) {
        let mut dst = pattern(seed);
        let mut want = dst.0;
        want[d..d + n].fill(0);
        // SAFETY: the range lies inside the buffer.
        unsafe { clear(dst.0.as_mut_ptr().add(d), n) };
        prop_assert_eq!(dst.0, want);
    }
}

#[test]
fn an_aligned_copy_takes_the_words_and_the_tail() {
    let src = pattern(7);
    let mut dst = Buf([0; 64]);
    // SAFETY: inside both buffers.
    unsafe { copy(dst.0.as_mut_ptr(), src.0.as_ptr(), 63) };
    assert_eq!(dst.0[..63], src.0[..63]);
    assert_eq!(dst.0[63], 0);
}
