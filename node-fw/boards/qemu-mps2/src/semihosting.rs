//! ARM semihosting (QEMU `-semihosting-config enable=on,target=native`): the host files
//! behind the emulated flash, the wall clock, and the log. Only used when the provisioning
//! word says the emulator has it: without a debugger or an emulator, `bkpt 0xAB` faults.

use core::sync::atomic::{AtomicBool, Ordering};

static ENABLED: AtomicBool = AtomicBool::new(false);

const SYS_OPEN: u32 = 0x01;
const SYS_WRITE0: u32 = 0x04;
const SYS_WRITE: u32 = 0x05;
const SYS_READ: u32 = 0x06;
const SYS_SEEK: u32 = 0x0A;
const SYS_FLEN: u32 = 0x0C;
const SYS_TIME: u32 = 0x11;
const SYS_GET_CMDLINE: u32 = 0x15;

/// `fopen` modes.
pub const MODE_RB_PLUS: u32 = 3;
pub const MODE_WB_PLUS: u32 = 7;

pub fn enable() {
    ENABLED.store(true, Ordering::Relaxed);
}

pub fn enabled() -> bool {
    ENABLED.load(Ordering::Relaxed)
}

/// # Safety
/// `arg` must point to what operation `op` expects; semihosting must be enabled.
unsafe fn call(op: u32, arg: *const u32) -> i32 {
    let r: i32;
    core::arch::asm!("bkpt 0xAB", inlateout("r0") op as i32 => r, in("r1") arg, options(nostack));
    r
}

/// Writes a NUL-terminated string to the emulator's console.
pub fn write0(s: &[u8]) {
    if enabled() && s.last() == Some(&0) {
        // SAFETY: a NUL-terminated string.
        unsafe { call(SYS_WRITE0, s.as_ptr().cast()) };
    }
}

/// Seconds since 1970 on the host.
pub fn time() -> Option<u32> {
    // SAFETY: SYS_TIME takes no argument.
    enabled().then(|| unsafe { call(SYS_TIME, core::ptr::null()) } as u32)
}

/// The emulator's semihosting command line (`-semihosting-config ...,arg=A,arg=B`: "A B").
pub fn cmdline(buf: &mut [u8]) -> Option<&[u8]> {
    if !enabled() {
        return None;
    }
    let mut block = [buf.as_mut_ptr() as u32, buf.len() as u32];
    // SAFETY: the block names a writable buffer and its length.
    let r = unsafe { call(SYS_GET_CMDLINE, block.as_mut_ptr()) };
    let n = block[1] as usize;
    (r == 0 && n <= buf.len()).then(|| &buf[..n])
}

/// A host file.
#[derive(Debug, Clone, Copy)]
pub struct File(u32);

impl File {
    /// Opens `name` (no NUL) with `mode`.
    pub fn open(name: &[u8], mode: u32) -> Option<File> {
        let mut z = [0u8; 128];
        if !enabled() || name.len() >= z.len() {
            return None;
        }
        z[..name.len()].copy_from_slice(name);
        let block = [z.as_ptr() as u32, mode, name.len() as u32];
        // SAFETY: NUL-terminated name, mode, length.
        let h = unsafe { call(SYS_OPEN, block.as_ptr()) };
        (h >= 0).then_some(File(h as u32))
    }

    pub fn len(&self) -> Option<usize> {
        let block = [self.0];
        // SAFETY: a handle.
        let n = unsafe { call(SYS_FLEN, block.as_ptr()) };
        (n >= 0).then_some(n as usize)
    }

    fn seek(&self, at: usize) -> bool {
        let block = [self.0, at as u32];
        // SAFETY: a handle and a position.
        unsafe { call(SYS_SEEK, block.as_ptr()) == 0 }
    }

    /// Reads exactly `buf.len()` bytes at `at`.
    pub fn read_at(&self, at: usize, buf: &mut [u8]) -> bool {
        if !self.seek(at) {
            return false;
        }
        let block = [self.0, buf.as_mut_ptr() as u32, buf.len() as u32];
        // SAFETY: a handle and a writable buffer; returns the bytes not read.
        unsafe { call(SYS_READ, block.as_ptr()) == 0 }
    }

    /// Writes all of `buf` at `at` (it reaches the host file before this returns).
    pub fn write_at(&self, at: usize, buf: &[u8]) -> bool {
        if !self.seek(at) {
            return false;
        }
        let block = [self.0, buf.as_ptr() as u32, buf.len() as u32];
        // SAFETY: a handle and a buffer; returns the bytes not written.
        unsafe { call(SYS_WRITE, block.as_ptr()) == 0 }
    }
}
