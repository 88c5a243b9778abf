//! The internal flash (NVMC) pages holding the OTA transfer page, the frame counter, the
//! two table slots and the boot counter: the last 32 KiB, outside memory.x.
//!
//! ```text
//! 0x000F_8000  STAGING_AT        the OTA transfer page (node_fw::ota::Staging): a pushed
//!                                table's chunks as they come, read memory-mapped
//! 0x000F_9000  FRAME_COUNTER_AT  two pages: the frame counter's log (node_fw::frame_counter)
//! 0x000F_B000  SLOTS_AT          slot 0, slot 1 (Slots::slot_size() = 8 KiB each)
//! 0x000F_F000  BOOT_AT           boot counter page: word i = the count of the i-th boot
//!                                since the page was erased; the last written word is the
//!                                count
//! 0x0010_0000                    end of flash
//! ```
//! Each region is an [`NrfFlash`] of its own ([`NrfFlash::new`] gives the slots,
//! [`NrfFlash::frame_counter`] the counter's pages), sharing the one NVMC. NVMC writes
//! block the CPU (a page erase ~85 ms): the runtime persists a table only when one is
//! pushed, the frame counter writes one 16-byte record per 1024 secured frames (a page
//! erase per 256 records), and the boot counter one word per boot and per 256 link epochs
//! a long boot takes (`node_fw::epoch`; a page erase per 1024 words), so those are the
//! only times the node pauses.

use core::cell::RefCell;

use embassy_nrf::nvmc::Nvmc;
use embedded_storage::nor_flash::{
    ErrorType, NorFlash as BlockingNorFlash, NorFlashError, NorFlashErrorKind,
    ReadNorFlash as BlockingReadNorFlash,
};
use embedded_storage_async::nor_flash::{NorFlash, ReadNorFlash};
use node_fw::slots::Slots;

pub const PAGE: usize = 4096;
/// The frame counter's two pages: the first byte not the linker's (see memory.x).
pub const FRAME_COUNTER_AT: u32 = 0x000F_9000;
pub const FRAME_COUNTER_BYTES: usize = 2 * PAGE;
/// The first byte of the slots.
pub const SLOTS_AT: u32 = FRAME_COUNTER_AT + FRAME_COUNTER_BYTES as u32;
pub const SLOTS_BYTES: usize = 2 * Slots::<NrfFlash>::slot_size();
const BOOT_AT: u32 = SLOTS_AT + SLOTS_BYTES as u32;
const BOOT_WORDS: usize = PAGE / 4;
const _: () = assert!(SLOTS_AT == 0x000F_B000 && BOOT_AT + PAGE as u32 == 0x0010_0000);
/// The OTA transfer page: the first byte not the linker's (see memory.x).
pub const STAGING_AT: u32 = FRAME_COUNTER_AT - PAGE as u32;
const _: () = assert!(PAGE >= config_schema::limits::MAX_BLOB && STAGING_AT == 0x000F_8000);

#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum FlashError {
    OutOfBounds,
    NotAligned,
    Nvmc,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::Nvmc => NorFlashErrorKind::Other,
        }
    }
}

/// One region of the internal flash: the slots, or the frame counter's pages.
pub struct NrfFlash {
    nvmc: &'static RefCell<Nvmc<'static>>,
    at: u32,
    len: usize,
}

impl NrfFlash {
    /// The slots (and the boot counter page behind them).
    pub fn new(nvmc: &'static RefCell<Nvmc<'static>>) -> Self {
        NrfFlash {
            nvmc,
            at: SLOTS_AT,
            len: SLOTS_BYTES,
        }
    }

    /// The frame counter's pages (call once: the region has one owner).
    #[cfg_attr(not(feature = "frame-security"), allow(dead_code))]
    pub fn frame_counter(&self) -> NrfFlash {
        NrfFlash {
            nvmc: self.nvmc,
            at: FRAME_COUNTER_AT,
            len: FRAME_COUNTER_BYTES,
        }
    }

    /// The boot counter's page ([`NrfFlash::count_boot`]; call once: the page has one
    /// owner).
    pub fn boot_counter(&self) -> NrfFlash {
        NrfFlash {
            nvmc: self.nvmc,
            at: BOOT_AT,
            len: PAGE,
        }
    }

    fn check(&self, offset: u32, len: usize) -> Result<u32, FlashError> {
        if (offset as usize)
            .checked_add(len)
            .is_none_or(|end| end > self.len)
        {
            return Err(FlashError::OutOfBounds);
        }
        Ok(self.at + offset)
    }

    /// The NVMC (one task uses the flash, and no borrow is held across an await: the
    /// NVMC's operations block, so this never finds it taken).
    fn nvmc(&self) -> Result<core::cell::RefMut<'static, Nvmc<'static>>, FlashError> {
        self.nvmc.try_borrow_mut().map_err(|_| FlashError::Nvmc)
    }

    fn word(&mut self, at: u32) -> u32 {
        let mut w = [0u8; 4];
        if let Ok(mut nvmc) = self.nvmc() {
            let _ = nvmc.read(at, &mut w);
        }
        u32::from_le_bytes(w)
    }

    /// Counts this boot (one word written per boot; the page is erased when full) and
    /// returns the count, and whether it was written. A power cut during that erase, once
    /// in 1024 boots, restarts the count at 1 (the epochs of boot 1025 are boot 1's: the
    /// link epochs wrap every 256 boots).
    pub fn count_boot(&mut self) -> (u32, bool) {
        let used = (0..BOOT_WORDS)
            .find(|&i| self.word(BOOT_AT + 4 * i as u32) == u32::MAX)
            .unwrap_or(BOOT_WORDS);
        let last = match used {
            0 => 0,
            n => self.word(BOOT_AT + 4 * (n as u32 - 1)),
        };
        let boots = last.wrapping_add(1).max(1);
        let mut at = used;
        let Ok(mut nvmc) = self.nvmc() else {
            return (boots, false);
        };
        if used == BOOT_WORDS {
            if nvmc.erase(BOOT_AT, BOOT_AT + PAGE as u32).is_err() {
                return (boots, false);
            }
            at = 0;
        }
        let written = nvmc.write(BOOT_AT + 4 * at as u32, &boots.to_le_bytes());
        (boots, written.is_ok())
    }
}

impl ErrorType for NrfFlash {
    type Error = FlashError;
}

impl ReadNorFlash for NrfFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let at = self.check(offset, bytes.len())?;
        self.nvmc()?.read(at, bytes).map_err(|_| FlashError::Nvmc)
    }

    fn capacity(&self) -> usize {
        self.len
    }
}

impl NorFlash for NrfFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = PAGE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if to < from {
            return Err(FlashError::OutOfBounds);
        }
        let at = self.check(from, (to - from) as usize)?;
        if !(from as usize).is_multiple_of(PAGE) || !(to as usize).is_multiple_of(PAGE) {
            return Err(FlashError::NotAligned);
        }
        self.nvmc()?
            .erase(at, at + (to - from))
            .map_err(|_| FlashError::Nvmc)
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let at = self.check(offset, bytes.len())?;
        if !(offset as usize).is_multiple_of(4) || !bytes.len().is_multiple_of(4) {
            return Err(FlashError::NotAligned);
        }
        self.nvmc()?.write(at, bytes).map_err(|_| FlashError::Nvmc)
    }
}

/// The OTA transfer page: chunks are written as they come (word by word, the last one
/// padded with 0xFF), and the whole blob is checked and persisted where it lies
/// (memory-mapped flash): the node holds no blob in RAM. One erase per transfer.
pub struct NrfStaging {
    nvmc: &'static RefCell<Nvmc<'static>>,
}

impl NrfStaging {
    /// The transfer page (call once: the page has one owner).
    pub fn new(flash: &NrfFlash) -> Self {
        NrfStaging { nvmc: flash.nvmc }
    }

    fn write(&mut self, at: u32, words: &[u8]) -> bool {
        match self.nvmc.try_borrow_mut() {
            Ok(mut nvmc) => words.is_empty() || nvmc.write(at, words).is_ok(),
            Err(_) => false,
        }
    }
}

impl node_fw::ota::Staging for NrfStaging {
    fn clear(&mut self) -> bool {
        match self.nvmc.try_borrow_mut() {
            Ok(mut nvmc) => nvmc.erase(STAGING_AT, STAGING_AT + PAGE as u32).is_ok(),
            Err(_) => false,
        }
    }

    fn put(&mut self, offset: usize, data: &[u8]) -> bool {
        if offset.checked_add(data.len()).is_none_or(|end| end > PAGE) || !offset.is_multiple_of(4)
        {
            return false;
        }
        let Some((body, tail)) = data.split_at_checked(data.len() / 4 * 4) else {
            return false;
        };
        let at = STAGING_AT + offset as u32;
        let mut last = [0xFFu8; 4];
        last.iter_mut().zip(tail).for_each(|(d, s)| *d = *s);
        self.write(at, body) && (tail.is_empty() || self.write(at + body.len() as u32, &last))
    }

    fn get(&self, len: usize) -> &[u8] {
        if len > PAGE {
            return &[];
        }
        // SAFETY: the transfer page is internal flash, memory-mapped, outside every linker
        // region, written only through this NrfStaging (`&mut self`), so no write happens
        // while the slice is borrowed.
        unsafe { core::slice::from_raw_parts(STAGING_AT as *const u8, len) }
    }
}
