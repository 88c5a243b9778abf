//! The emulated internal flash holding the two table slots, the boot counter and the frame
//! counter. Its first part is laid out as the host board's flash file
//! (`node_fw::host::flash`), its last two pages as the host board's frame counter file:
//!
//! ```text
//! 0                   slot 0, slot 1 (Slots::slot_size() bytes each)
//! BOOT_AT             u32 LE boot counter (0xFFFF_FFFF: never booted), rest of the page 0xFF
//! FRAME_COUNTER_AT    two pages: the frame counter's log (node_fw::frame_counter)
//! ```
//! The bytes live in the emulated SSRAM at [`BASE`] with NOR semantics (erase sets 0xFF, a
//! write only clears bits). With semihosting and `flash=FILE` on the semihosting command
//! line, they are loaded from that host file at boot and every erase and write goes through
//! to it before returning: the slots and the frame counter survive a QEMU restart or a kill
//! (a power cut) exactly as the runtime's commit order and the counter's log allow. A file
//! of [`HOST_FILE`] bytes (a host node's flash file, or an older image's) is taken and
//! extended with erased frame counter pages. Without a file everything is erased at every
//! boot.
//!
//! Each region is a [`QemuFlash`] of its own ([`QemuFlash::open`] gives the slots,
//! [`QemuFlash::frame_counter`] the counter's pages), sharing the host file.

use embedded_storage::nor_flash::{ErrorType, NorFlashError, NorFlashErrorKind};
use embedded_storage_async::nor_flash::{NorFlash, ReadNorFlash};
use node_fw::slots::{check_access, Access, Slots};

use crate::semihosting::{self, File};

/// Where the emulated flash is (outside the linker's regions: see memory.x).
pub const BASE: usize = 0x003E_0000;
pub const ERASE_SIZE: usize = 4096;
pub const SLOTS_BYTES: usize = 2 * Slots::<QemuFlash>::slot_size();
/// The boot counter's page.
pub const BOOT_AT: usize = SLOTS_BYTES;
/// The frame counter's two pages (erase-aligned: the slots are whole pages).
pub const FRAME_COUNTER_AT: usize = BOOT_AT + ERASE_SIZE;
pub const FRAME_COUNTER_BYTES: usize = 2 * ERASE_SIZE;
/// The size of a host node's flash file: the slots and the boot page.
pub const HOST_FILE: usize = FRAME_COUNTER_AT;
pub const TOTAL: usize = FRAME_COUNTER_AT + FRAME_COUNTER_BYTES;
/// The transfer page (`node_fw::ota::Staging`): where a pushed table's chunks go as they
/// come, right after the flash regions. Not in the host file: a transfer does not survive
/// a power cut anyway (only what was staged in a slot does).
pub const STAGING_AT: usize = TOTAL;
pub const STAGING_BYTES: usize = ERASE_SIZE;
const _: () = assert!(STAGING_BYTES >= config_schema::limits::MAX_BLOB);
const _: () = assert!(SLOTS_BYTES.is_multiple_of(ERASE_SIZE));

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

/// One region of the emulated flash: the slots, or the frame counter's pages.
pub struct QemuFlash {
    file: Option<File>,
    /// Where the region starts in the flash (and in the file), and its bytes.
    start: usize,
    len: usize,
}

/// Bytes `start..start + len` of the emulated flash.
fn mem(start: usize, len: usize) -> &'static mut [u8] {
    debug_assert!(start + len <= TOTAL);
    // SAFETY: emulated SSRAM outside every linker region. The regions are disjoint and
    // each is used only through its one QemuFlash (created once at boot); the whole flash
    // only by `open`, before any region exists.
    unsafe { core::slice::from_raw_parts_mut((BASE + start) as *mut u8, len) }
}

impl QemuFlash {
    /// The slots, the whole flash loaded from `path` if given (a missing file is created
    /// erased, a host node's file extended).
    pub fn open(path: Option<&[u8]>) -> (QemuFlash, Backing) {
        let (file, backing) = Self::load(path);
        let slots = QemuFlash {
            file,
            start: 0,
            len: SLOTS_BYTES,
        };
        (slots, backing)
    }

    fn load(path: Option<&[u8]>) -> (Option<File>, Backing) {
        let m = mem(0, TOTAL);
        m.fill(0xFF);
        let Some(path) = path else {
            return (None, Backing::Ram);
        };
        if let Some(f) = File::open(path, semihosting::MODE_RB_PLUS) {
            let loaded = match f.len() {
                Some(TOTAL) => f.read_at(0, m),
                // The slots and the boot page; the counter pages are appended, erased.
                Some(HOST_FILE) => {
                    f.read_at(0, &mut m[..HOST_FILE]) && f.write_at(HOST_FILE, &m[HOST_FILE..])
                }
                _ => false,
            };
            if loaded {
                return (Some(f), Backing::File);
            }
            m.fill(0xFF);
            return (None, Backing::FileRefused);
        }
        match File::open(path, semihosting::MODE_WB_PLUS) {
            Some(f) if f.write_at(0, m) => (Some(f), Backing::File),
            _ => (None, Backing::FileRefused),
        }
    }

    /// The frame counter's pages (call once: the region has one owner).
    pub fn frame_counter(&self) -> QemuFlash {
        QemuFlash {
            file: self.file,
            start: FRAME_COUNTER_AT,
            len: FRAME_COUNTER_BYTES,
        }
    }

    /// The boot page, for its counter ([`QemuFlash::count_boot`]; call once: the page has
    /// one owner).
    pub fn boot_counter(&self) -> QemuFlash {
        QemuFlash {
            file: self.file,
            start: BOOT_AT,
            len: ERASE_SIZE,
        }
    }

    /// Counts this boot in the boot page; `None` without a file (nothing persists).
    pub fn count_boot(&mut self) -> Option<u32> {
        let f = self.file?;
        let m = mem(BOOT_AT, 4);
        let old = u32::from_le_bytes([m[0], m[1], m[2], m[3]]);
        let boots = match old {
            u32::MAX => 1,
            n => n.wrapping_add(1).max(1),
        };
        // An overwrite of one word (as the host board's file): the old or the new count.
        m.copy_from_slice(&boots.to_le_bytes());
        f.write_at(BOOT_AT, m).then_some(boots)
    }

    /// This region's bytes.
    fn bytes(&self) -> &'static mut [u8] {
        mem(self.start, self.len)
    }

    /// Writes bytes `at..at + len` of this region through to the file.
    fn sync(&self, at: usize, len: usize) -> Result<(), FlashError> {
        match self.file {
            Some(f) if !f.write_at(self.start + at, &self.bytes()[at..at + len]) => {
                Err(FlashError::Host)
            }
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
        let start = check_access(offset, bytes.len(), 1, self.len)?;
        bytes.copy_from_slice(&self.bytes()[start..start + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.len
    }
}

impl NorFlash for QemuFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if to < from {
            return Err(FlashError::OutOfBounds);
        }
        let start = check_access(from, (to - from) as usize, ERASE_SIZE, self.len)?;
        let len = (to - from) as usize;
        self.bytes()[start..start + len].fill(0xFF);
        self.sync(start, len)
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let start = check_access(offset, bytes.len(), 4, self.len)?;
        for (cell, b) in self.bytes()[start..start + bytes.len()]
            .iter_mut()
            .zip(bytes)
        {
            *cell &= *b;
        }
        self.sync(start, bytes.len())
    }
}

/// The transfer page, NOR semantics (erase sets 0xFF, a write only clears bits),
/// memory-mapped: the node checks and persists a pushed blob where its chunks were put,
/// holding none in RAM.
pub struct QemuStaging(());

impl QemuStaging {
    /// The transfer page (call once: the page has one owner).
    pub fn new() -> Self {
        QemuStaging(())
    }

    fn page() -> &'static mut [u8] {
        // SAFETY: emulated SSRAM outside every linker region and past the flash regions
        // (memory.x), used only through the one QemuStaging.
        unsafe { core::slice::from_raw_parts_mut((BASE + STAGING_AT) as *mut u8, STAGING_BYTES) }
    }
}

impl node_fw::ota::Staging for QemuStaging {
    fn clear(&mut self) -> bool {
        Self::page().fill(0xFF);
        true
    }

    fn put(&mut self, offset: usize, data: &[u8]) -> bool {
        let Some(cells) = Self::page().get_mut(offset..offset + data.len()) else {
            return false;
        };
        for (cell, b) in cells.iter_mut().zip(data) {
            *cell &= *b;
        }
        true
    }

    fn get(&self, len: usize) -> &[u8] {
        Self::page().get(..len).unwrap_or(&[])
    }
}
