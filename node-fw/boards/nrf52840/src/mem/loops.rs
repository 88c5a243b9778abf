//! The compact memory copy and clear behind the board's `memcpy` / `__aeabi_memcpy*` /
//! `__aeabi_memclr*` (`super`): a word loop when both ends
//! are word aligned, else a byte loop, about 100 bytes of code instead of
//! compiler-builtins' 1.6 KB, which unroll and realign for speed (docs/boards.md, "Where
//! the flash goes").
//!
//! The node copies little: frames of at most 127 bytes, and a table (about 5 KB) when it
//! activates one, so a few cycles more per word do not matter; copies of small fixed size
//! the compiler inlines and never calls these for.
//!
//! The loops read and write through `read_volatile` / `write_volatile`, so the optimizer
//! cannot recognize them as a copy or a clear and turn them back into a call to the
//! routine they implement.

use core::ptr::{read_volatile, write_volatile};

/// Copies `n` bytes from `src` to `dst`, a word at a time while both are word aligned.
///
/// # Safety
/// `memcpy`'s contract: `src` readable and `dst` writable for `n` bytes, the two not
/// overlapping.
#[inline]
pub unsafe fn copy(dst: *mut u8, src: *const u8, n: usize) {
    let mut i = 0;
    if (dst as usize | src as usize) & 3 == 0 {
        while n - i >= 4 {
            // SAFETY: both word aligned (checked above, `i` a multiple of 4), in bounds.
            unsafe {
                write_volatile(
                    dst.add(i).cast::<u32>(),
                    read_volatile(src.add(i).cast::<u32>()),
                )
            };
            i += 4;
        }
    }
    while i < n {
        // SAFETY: in bounds (the caller's contract).
        unsafe { write_volatile(dst.add(i), read_volatile(src.add(i))) };
        i += 1;
    }
}

/// Clears `n` bytes at `dst`, a word at a time while it is word aligned.
///
/// # Safety
/// `dst` writable for `n` bytes.
#[inline]
pub unsafe fn clear(dst: *mut u8, n: usize) {
    let mut i = 0;
    if dst as usize & 3 == 0 {
        while n - i >= 4 {
            // SAFETY: word aligned (checked above, `i` a multiple of 4), in bounds.
            unsafe { write_volatile(dst.add(i).cast::<u32>(), 0) };
            i += 4;
        }
    }
    while i < n {
        // SAFETY: in bounds (the caller's contract).
        unsafe { write_volatile(dst.add(i), 0) };
        i += 1;
    }
}

// Tested on the host: node-fw/tests/board_mem.rs includes this file.
