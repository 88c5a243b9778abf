//! The emulated internal flash holding the two table slots and the boot counter, laid out
//! as the host board's flash file (`node_fw::host::flash`), so the files are the same:
//!
//! ```text
//! 0              slot 0, slot 1 (Slots::slot_size() bytes each)
//! 2 * slot_size  u32 LE boot counter (0xFFFF_FFFF: never booted), rest of the page 0xFF
//! ```
//! The bytes live in the emulated SSRAM at [`BASE`] with NOR semantics (erase sets 0xFF, a
//! write only clears bits). With semihosting and `flash=FILE` on the semihosting command
//! line, they are loaded from that host file at boot and every erase and write goes through
//! to it before returning: the slots survive a QEMU restart or a kill (a power cut) exactly
//! as the runtime's commit order allows. Without a file they are erased at every boot.

use embedded_storage::nor_flash::{ErrorType, NorFlashError, NorFlashErrorKind};
use embedded_storage_async::nor_flash::{NorFlash, ReadNorFlash};
use node_fw::slots::{check_access, Access, Slots};

use crate::semihosting::{self, File};

/// Where the emulated flash is (outside the linker's regions: see memory.x).
pub const BASE: usize = 0x003E_0000;
pub const ERASE_SIZE: usize = 4096;
pub const SLOTS_BYTES: usize = 2 * Slots::<QemuFlash>::slot_size();
pub const COUNTER_AT: usize = SLOTS_BYTES;
pub const TOTAL: usize = SLOTS_BYTES + ERASE_SIZE;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlashError {
    OutOfBounds,
    NotAligned,
    /// The host file could not be written.
    Host,
}

impl From<Access> for FlashError {
    fn from(a: Access) -> Self {
        match a {
            Access::OutOfBounds => FlashError::OutOfBounds,
            Access::NotAligned => FlashError::NotAligned,
        }
    }
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::Host => NorFlashErrorKind::Other,
        }
    }
}

/// What backs the flash.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backing {
    /// Erased at boot.
    Ram,
    /// A host file (persistent).
    File,
    /// The named file could not be used (not a flash file of this size): erased at boot.
    FileRefused,
}

pub struct QemuFlash {
    file: Option<File>,
}

fn mem() -> &'static mut [u8; TOTAL] {
    // SAFETY: emulated SSRAM outside every linker region, used only through the one
    // QemuFlash (created once at boot).
    unsafe { &mut *(BASE as *mut [u8; TOTAL]) }
}

impl QemuFlash {
    /// The flash, loaded from `path` if given (a missing file is created erased).
    pub fn open(path: Option<&[u8]>) -> (QemuFlash, Backing) {
        let m = mem();
        let Some(path) = path else {
            m.fill(0xFF);
            return (QemuFlash { file: None }, Backing::Ram);
        };
        if let Some(f) = File::open(path, semihosting::MODE_RB_PLUS) {
            if f.len() == Some(TOTAL) && f.read_at(0, m) {
                return (QemuFlash { file: Some(f) }, Backing::File);
            }
            m.fill(0xFF);
            return (QemuFlash { file: None }, Backing::FileRefused);
        }
        m.fill(0xFF);
        match File::open(path, semihosting::MODE_WB_PLUS) {
            Some(f) if f.write_at(0, m) => (QemuFlash { file: Some(f) }, Backing::File),
            _ => (QemuFlash { file: None }, Backing::FileRefused),
        }
    }

    /// Counts this boot in the boot page; `None` without a file (nothing persists).
    pub fn count_boot(&mut self) -> Option<u32> {
        let f = self.file?;
        let m = mem();
        let at = COUNTER_AT;
        let old = u32::from_le_bytes([m[at], m[at + 1], m[at + 2], m[at + 3]]);
        let boots = match old {
            u32::MAX => 1,
            n => n.wrapping_add(1).max(1),
        };
        // An overwrite of one word (as the host board's file): the old or the new count.
        m[at..at + 4].copy_from_slice(&boots.to_le_bytes());
        f.write_at(at, &m[at..at + 4]).then_some(boots)
    }

    fn sync(&self, start: usize, len: usize) -> Result<(), FlashError> {
        match self.file {
            Some(f) if !f.write_at(start, &mem()[start..start + len]) => Err(FlashError::Host),
            _ => Ok(()),
        }
    }
}

impl ErrorType for QemuFlash {
    type Error = FlashError;
}

impl ReadNorFlash for QemuFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let start = check_access(offset, bytes.len(), 1, SLOTS_BYTES)?;
        bytes.copy_from_slice(&mem()[start..start + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        SLOTS_BYTES
    }
}

impl NorFlash for QemuFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if to < from {
            return Err(FlashError::OutOfBounds);
        }
        let start = check_access(from, (to - from) as usize, ERASE_SIZE, SLOTS_BYTES)?;
        let len = (to - from) as usize;
        mem()[start..start + len].fill(0xFF);
        self.sync(start, len)
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let start = check_access(offset, bytes.len(), 4, SLOTS_BYTES)?;
        for (cell, b) in mem()[start..start + bytes.len()].iter_mut().zip(bytes) {
            *cell &= *b;
        }
        self.sync(start, bytes.len())
    }
}
