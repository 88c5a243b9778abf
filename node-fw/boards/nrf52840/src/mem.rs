//! The memory routines the compiler calls (the ARM EABI's `__aeabi_memcpy*` and
//! `__aeabi_memclr*`, and `memcpy`), on the compact loops of [`loops`]: compiler-builtins'
//! are weak symbols, these strong ones are linked instead (1.5 KB less flash,
//! docs/boards.md). The EABI's promise of word alignment (`4`, `8`) is not relied on: the
//! loops check it.

mod loops;

use loops::{clear, copy};

/// # Safety
/// `src` readable and `dst` writable for `n` bytes, not overlapping.
#[no_mangle]
pub unsafe extern "C" fn memcpy(dst: *mut u8, src: *const u8, n: usize) -> *mut u8 {
    // SAFETY: the caller's contract is `copy`'s.
    unsafe { copy(dst, src, n) };
    dst
}

/// # Safety
/// As [`memcpy`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memcpy(dst: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is `copy`'s.
    unsafe { copy(dst, src, n) }
}

/// # Safety
/// As [`memcpy`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memcpy4(dst: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is `copy`'s.
    unsafe { copy(dst, src, n) }
}

/// # Safety
/// As [`memcpy`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memcpy8(dst: *mut u8, src: *const u8, n: usize) {
    // SAFETY: the caller's contract is `copy`'s.
    unsafe { copy(dst, src, n) }
}

/// # Safety
/// `dst` writable for `n` bytes.
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memclr(dst: *mut u8, n: usize) {
    // SAFETY: the caller's contract is `clear`'s.
    unsafe { clear(dst, n) }
}

/// # Safety
/// As [`__aeabi_memclr`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memclr4(dst: *mut u8, n: usize) {
    // SAFETY: the caller's contract is `clear`'s.
    unsafe { clear(dst, n) }
}

/// # Safety
/// As [`__aeabi_memclr`].
#[no_mangle]
pub unsafe extern "C" fn __aeabi_memclr8(dst: *mut u8, n: usize) {
    // SAFETY: the caller's contract is `clear`'s.
    unsafe { clear(dst, n) }
}
