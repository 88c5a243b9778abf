//! The internal flash (NVMC) pages holding the two table slots and the boot counter.
//!
//! ```text
//! SLOTS_AT                  slot 0, slot 1 (Slots::slot_size() = 8 KiB each)
//! SLOTS_AT + SLOTS_BYTES    boot counter page: word i = the count of the i-th boot since
//!                           the page was erased; the last written word is the count
//! ```
//! NVMC writes block the CPU (a page erase ~85 ms); the runtime persists a table only when
//! one is pushed, so that is the only time the node pauses.

use embassy_nrf::nvmc::Nvmc;
use embedded_storage::nor_flash::{
    ErrorType, NorFlash as BlockingNorFlash, NorFlashError, NorFlashErrorKind,
    ReadNorFlash as BlockingReadNorFlash,
};
use embedded_storage_async::nor_flash::{NorFlash, ReadNorFlash};
use node_fw::slots::Slots;

/// The first byte of the slots (see memory.x).
pub const SLOTS_AT: u32 = 0x000F_B000;
pub const PAGE: usize = 4096;
pub const SLOTS_BYTES: usize = 2 * Slots::<NrfFlash>::slot_size();
const COUNTER_AT: u32 = SLOTS_AT + SLOTS_BYTES as u32;
const COUNTER_WORDS: usize = PAGE / 4;

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

/// The slots region of the internal flash.
pub struct NrfFlash {
    nvmc: Nvmc<'static>,
}

impl NrfFlash {
    pub fn new(nvmc: Nvmc<'static>) -> Self {
        NrfFlash { nvmc }
    }

    fn check(offset: u32, len: usize) -> Result<u32, FlashError> {
        if (offset as usize)
            .checked_add(len)
            .is_none_or(|end| end > SLOTS_BYTES)
        {
            return Err(FlashError::OutOfBounds);
        }
        Ok(SLOTS_AT + offset)
    }

    fn word(&mut self, at: u32) -> u32 {
        let mut w = [0u8; 4];
        let _ = self.nvmc.read(at, &mut w);
        u32::from_le_bytes(w)
    }

    /// Counts this boot (one word written per boot; the page is erased when full) and
    /// returns the count. A power cut during that erase, once in 1024 boots, restarts the
    /// count at 1.
    pub fn count_boot(&mut self) -> u32 {
        let used = (0..COUNTER_WORDS)
            .find(|&i| self.word(COUNTER_AT + 4 * i as u32) == u32::MAX)
            .unwrap_or(COUNTER_WORDS);
        let last = match used {
            0 => 0,
            n => self.word(COUNTER_AT + 4 * (n as u32 - 1)),
        };
        let boots = last.wrapping_add(1).max(1);
        let mut at = used;
        if used == COUNTER_WORDS {
            let _ = self.nvmc.erase(COUNTER_AT, COUNTER_AT + PAGE as u32);
            at = 0;
        }
        let _ = self
            .nvmc
            .write(COUNTER_AT + 4 * at as u32, &boots.to_le_bytes());
        boots
    }
}

impl ErrorType for NrfFlash {
    type Error = FlashError;
}

impl ReadNorFlash for NrfFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let at = Self::check(offset, bytes.len())?;
        self.nvmc.read(at, bytes).map_err(|_| FlashError::Nvmc)
    }

    fn capacity(&self) -> usize {
        SLOTS_BYTES
    }
}

impl NorFlash for NrfFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = PAGE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if to < from {
            return Err(FlashError::OutOfBounds);
        }
        let at = Self::check(from, (to - from) as usize)?;
        if !(from as usize).is_multiple_of(PAGE) || !(to as usize).is_multiple_of(PAGE) {
            return Err(FlashError::NotAligned);
        }
        self.nvmc
            .erase(at, at + (to - from))
            .map_err(|_| FlashError::Nvmc)
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let at = Self::check(offset, bytes.len())?;
        if !(offset as usize).is_multiple_of(4) || !bytes.len().is_multiple_of(4) {
            return Err(FlashError::NotAligned);
        }
        self.nvmc.write(at, bytes).map_err(|_| FlashError::Nvmc)
    }
}
