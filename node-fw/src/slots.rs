//! The two table slots in flash: a new table is written to the slot not holding the running
//! one and becomes the boot table only when its commit marker, written last, is in place.
//!
//! ```text
//! slot (slot_size bytes, erase-aligned):
//! 0   u32 LE  blob length           written after the blob
//! 16  u32 LE  COMMITTED marker      written last: the "flip"
//! 32  blob                          padded with 0xFF to the write size
//! ```
//! A power cut before the marker leaves that slot uncommitted and the node boots the other
//! one; after it, the node boots the newest committed slot that decodes and validates. So a
//! node always runs the old table or the new one, never a mix.

use config_schema::limits::MAX_BLOB;
use config_schema::link_keys::{decode_deployment, LinkKeys};
use config_schema::Table;
use embedded_storage::nor_flash::{ErrorType, NorFlashError, NorFlashErrorKind};
use embedded_storage_async::nor_flash::{NorFlash, ReadNorFlash};

/// Bytes before the blob in a slot.
pub const HEADER: usize = 32;
const LEN_AT: u32 = 0;
const MARKER_AT: u32 = 16;
/// The commit marker.
pub const COMMITTED: u32 = 0x5A17_C0DE;
/// Largest write or read granularity the layout supports.
const MAX_ALIGN: usize = 16;

/// Why the slots cannot be used or written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlotError<E> {
    /// The flash is too small or its granularity does not fit the layout.
    Geometry,
    /// The blob is longer than `MAX_BLOB`.
    TooLong,
    /// The flash failed.
    Flash(E),
}

/// Two table slots at the start of a NOR flash region.
pub struct Slots<F> {
    flash: F,
    slot_size: u32,
}

/// A table loaded at boot, and where from.
#[derive(Debug, Clone, PartialEq)]
pub struct Loaded {
    pub slot: usize,
    pub table: Table,
    /// The link keys stored with the table (a secured push), if any.
    pub keys: Option<LinkKeys>,
}

fn round_up(n: usize, to: usize) -> usize {
    n.div_ceil(to.max(1)) * to.max(1)
}

impl<F: NorFlash> Slots<F> {
    /// The slot size: a header and the largest blob, rounded up to the erase size.
    pub const fn slot_size() -> usize {
        (HEADER + MAX_BLOB).div_ceil(F::ERASE_SIZE) * F::ERASE_SIZE
    }

    /// Uses the first `2 * slot_size()` bytes of `flash`.
    pub fn new(flash: F) -> Result<Self, SlotError<F::Error>> {
        let size = Self::slot_size();
        if F::WRITE_SIZE > MAX_ALIGN
            || F::READ_SIZE > MAX_ALIGN
            || !MAX_ALIGN.is_multiple_of(F::WRITE_SIZE)
            || !MAX_ALIGN.is_multiple_of(F::READ_SIZE)
            || flash.capacity() < 2 * size
        {
            return Err(SlotError::Geometry);
        }
        Ok(Slots {
            flash,
            slot_size: size as u32,
        })
    }

    /// Gives the flash back.
    pub fn into_inner(self) -> F {
        self.flash
    }

    fn base(&self, slot: usize) -> u32 {
        if slot == 0 {
            0
        } else {
            self.slot_size
        }
    }

    async fn read_word(&mut self, at: u32) -> Result<u32, F::Error> {
        let mut word = [0u8; MAX_ALIGN];
        self.flash
            .read(at, &mut word[..F::READ_SIZE.max(4)])
            .await?;
        Ok(u32::from_le_bytes([word[0], word[1], word[2], word[3]]))
    }

    async fn write_word(&mut self, at: u32, value: u32) -> Result<(), F::Error> {
        let mut word = [0xFFu8; MAX_ALIGN];
        word[..4].copy_from_slice(&value.to_le_bytes());
        self.flash.write(at, &word[..F::WRITE_SIZE.max(4)]).await
    }

    /// Reads slot `slot`'s blob into `buf` if the slot is committed; returns its length.
    pub async fn read_blob(
        &mut self,
        slot: usize,
        buf: &mut [u8; MAX_BLOB + MAX_ALIGN],
    ) -> Result<Option<usize>, F::Error> {
        let base = self.base(slot);
        if self.read_word(base + MARKER_AT).await? != COMMITTED {
            return Ok(None);
        }
        let len = self.read_word(base + LEN_AT).await? as usize;
        if len > MAX_BLOB {
            return Ok(None);
        }
        let padded = round_up(len, F::READ_SIZE);
        self.flash
            .read(base + HEADER as u32, &mut buf[..padded])
            .await?;
        Ok(Some(len))
    }

    /// The newest committed slot whose blob decodes and validates, if any.
    pub async fn load(&mut self) -> Result<Option<Loaded>, F::Error> {
        let mut buf = [0u8; MAX_BLOB + MAX_ALIGN];
        let mut best: Option<Loaded> = None;
        for slot in 0..2 {
            let Some(len) = self.read_blob(slot, &mut buf).await? else {
                continue;
            };
            let Ok((table, keys)) = decode_deployment(&buf[..len]) else {
                continue;
            };
            if best
                .as_ref()
                .is_none_or(|b| table.generation > b.table.generation)
            {
                best = Some(Loaded { slot, table, keys });
            }
        }
        Ok(best)
    }

    /// Erases slot `slot` and writes `blob` and its length, without the commit marker.
    pub async fn persist(&mut self, slot: usize, blob: &[u8]) -> Result<(), SlotError<F::Error>> {
        if blob.len() > MAX_BLOB {
            return Err(SlotError::TooLong);
        }
        let base = self.base(slot);
        self.flash
            .erase(base, base + self.slot_size)
            .await
            .map_err(SlotError::Flash)?;
        let whole = blob.len() / F::WRITE_SIZE * F::WRITE_SIZE;
        let (body, tail) = blob.split_at(whole);
        if !body.is_empty() {
            self.flash
                .write(base + HEADER as u32, body)
                .await
                .map_err(SlotError::Flash)?;
        }
        if !tail.is_empty() {
            let mut last = [0xFFu8; MAX_ALIGN];
            last[..tail.len()].copy_from_slice(tail);
            self.flash
                .write(base + (HEADER + whole) as u32, &last[..F::WRITE_SIZE])
                .await
                .map_err(SlotError::Flash)?;
        }
        self.write_word(base + LEN_AT, blob.len() as u32)
            .await
            .map_err(SlotError::Flash)
    }

    /// Writes slot `slot`'s commit marker: from now on it is a boot candidate.
    pub async fn commit(&mut self, slot: usize) -> Result<(), SlotError<F::Error>> {
        let base = self.base(slot);
        self.write_word(base + MARKER_AT, COMMITTED)
            .await
            .map_err(SlotError::Flash)
    }

    /// Stores a new table beside the running one (in slot `running`, if any): persist to
    /// the other slot, then commit. Returns the slot written.
    pub async fn store(
        &mut self,
        running: Option<usize>,
        blob: &[u8],
    ) -> Result<usize, SlotError<F::Error>> {
        let slot = match running {
            Some(0) => 1,
            _ => 0,
        };
        self.persist(slot, blob).await?;
        self.commit(slot).await?;
        Ok(slot)
    }
}

/// Why a NOR flash access is refused before it reaches the memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// It runs past the region.
    OutOfBounds,
    /// Its offset or length is not a multiple of the granularity.
    NotAligned,
}

/// Checks an access of `len` bytes at `offset` in a region of `capacity` bytes with
/// granularity `align` (what every `NorFlash` implementation must refuse); returns the
/// offset as an index.
pub fn check_access(
    offset: u32,
    len: usize,
    align: usize,
    capacity: usize,
) -> Result<usize, Access> {
    let start = offset as usize;
    if start.checked_add(len).is_none_or(|end| end > capacity) {
        return Err(Access::OutOfBounds);
    }
    if !start.is_multiple_of(align) || !len.is_multiple_of(align) {
        return Err(Access::NotAligned);
    }
    Ok(start)
}

/// A NOR flash in RAM (erase sets bytes to 0xFF, writes can only clear bits), for the host,
/// the simulator and tests. `fail_after` cuts the power: the write that would exceed it
/// is applied only halfway and every later operation fails.
#[derive(Debug, Clone)]
pub struct RamFlash<const N: usize> {
    pub bytes: [u8; N],
    /// Writes allowed before the simulated power cut (`None`: never).
    pub fail_after: Option<usize>,
    writes: usize,
}

/// The simulated power cut.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PowerCut;

impl NorFlashError for PowerCut {
    fn kind(&self) -> NorFlashErrorKind {
        NorFlashErrorKind::Other
    }
}

impl<const N: usize> Default for RamFlash<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> RamFlash<N> {
    pub const fn new() -> Self {
        RamFlash {
            bytes: [0xFF; N],
            fail_after: None,
            writes: 0,
        }
    }

    fn range(&self, offset: u32, len: usize) -> Result<core::ops::Range<usize>, PowerCut> {
        let start = check_access(offset, len, 1, N).map_err(|_| PowerCut)?;
        Ok(start..start + len)
    }

    fn powered(&mut self) -> Result<(), PowerCut> {
        match self.fail_after {
            Some(n) if self.writes >= n => Err(PowerCut),
            _ => Ok(()),
        }
    }
}

impl<const N: usize> ErrorType for RamFlash<N> {
    type Error = PowerCut;
}

impl<const N: usize> ReadNorFlash for RamFlash<N> {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), PowerCut> {
        let range = self.range(offset, bytes.len())?;
        bytes.copy_from_slice(&self.bytes[range]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        N
    }
}

impl<const N: usize> NorFlash for RamFlash<N> {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = 1024;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), PowerCut> {
        self.powered()?;
        let range = self.range(from, to.saturating_sub(from) as usize)?;
        self.bytes[range].fill(0xFF);
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), PowerCut> {
        self.powered()?;
        let range = self.range(offset, bytes.len())?;
        self.writes += 1;
        let cut = self.fail_after.is_some_and(|n| self.writes >= n);
        let applied = if cut { bytes.len() / 2 } else { bytes.len() };
        for (dst, src) in self.bytes[range].iter_mut().zip(&bytes[..applied]) {
            *dst &= *src;
        }
        if cut {
            Err(PowerCut)
        } else {
            Ok(())
        }
    }
}
