//! The two table slots in flash. A new table is written to the slot not holding the running
//! one and staged (checked, not running); it becomes the boot table when it is activated,
//! and stays it once confirmed. Every state is one word written once after the erase, so a
//! power cut at any write leaves a slot in the state before or after it, never between.
//!
//! ```text
//! slot (slot_size bytes, erase-aligned; every word u32 LE, in its own 16-byte cell):
//! 0   blob length        written after the blob
//! 16  STAGED marker      the blob is whole and was checked: a table, not running
//! 32  activation serial  written when the node switches to it: the order of activations
//! 48  CONFIRMED marker   the activation is final (an activation on trial is not, yet)
//! 64  REVOKED marker     rolled back or abandoned: never booted again
//! 80  blob               padded with 0xFF to the write size
//! ```
//!
//! At boot the node runs the confirmed, unrevoked slot activated **last** (the highest
//! serial), not the highest generation: a forced downgrade survives a restart. A slot
//! activated but never confirmed is a trial that a power cut interrupted: it is not
//! booted ([`Boot::abandoned`]; the runtime revokes it). A staged slot that was never
//! activated is reported ([`Boot::staged`]) so the tool can finish the switch-over.
//!
//! Every operation is a plain function (`stage_now`, `load_now`, ...), each flash access
//! run to completion in place (`embassy_futures::block_on`: a board's `NorFlash`
//! completes when first polled, docs/boards.md), with the same operation as a future
//! beside it (`stage`, `load`, ...) for async callers. The runtime calls the plain ones:
//! no slot operation is a state machine in the node's image (docs/boards.md, "Where the
//! flash goes").

use config_schema::limits::MAX_BLOB;
use config_schema::link_keys::{decode_deployment, Deployment};
use embassy_futures::block_on;
use embedded_storage::nor_flash::{ErrorType, NorFlashError, NorFlashErrorKind};
use embedded_storage_async::nor_flash::{NorFlash, ReadNorFlash};

/// Bytes before the blob in a slot.
pub const HEADER: usize = 80;
const LEN_AT: u32 = 0;
const STAGED_AT: u32 = 16;
const SERIAL_AT: u32 = 32;
const CONFIRMED_AT: u32 = 48;
const REVOKED_AT: u32 = 64;
/// The staged marker.
pub const STAGED: u32 = 0x57A6_ED02;
/// The confirmed marker.
pub const CONFIRMED: u32 = 0xC0F1_12ED;
/// The revoked marker.
pub const REVOKED: u32 = 0x2E70_CED0;
const ERASED: u32 = u32::MAX;
/// Largest write or read granularity the layout supports.
const MAX_ALIGN: usize = 16;

/// Why the slots cannot be used or written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlotError<E> {
    /// The flash is too small or its granularity does not fit the layout.
    Geometry,
    /// The blob is longer than `MAX_BLOB`.
    TooLong,
    /// The slot holds no staged table to activate (or it was revoked).
    NotStaged,
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
    /// The table, the link keys stored with it (a secured push) if any, and its identity.
    pub deployed: Deployment,
}

/// A staged table: where, and its generation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StagedSlot {
    pub slot: usize,
    pub generation: u32,
}

/// What the slots hold at boot.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Boot {
    /// The table to run: confirmed, not revoked, activated last.
    pub running: Option<Loaded>,
    /// A checked table staged and never activated, to switch to on the tool's word.
    pub staged: Option<StagedSlot>,
    /// A trial a power cut interrupted (activated, never confirmed): not booted.
    pub abandoned: Option<usize>,
    /// The other confirmed table, activated before the running one: what a rollback
    /// returns to.
    pub previous: Option<StagedSlot>,
    /// The serial the next activation takes.
    pub next_serial: u32,
}

/// What the slots hold at boot, as [`Boot`] without the running table: where it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Survey {
    /// The slot to run: confirmed, not revoked, activated last, and it decodes.
    pub running: Option<StagedSlot>,
    pub staged: Option<StagedSlot>,
    pub abandoned: Option<usize>,
    pub previous: Option<StagedSlot>,
    pub next_serial: u32,
}

/// The generation of a deployment blob, if it decodes and validates (the table is not
/// kept: a function of its own, so no caller holds it across an await).
fn generation(blob: &[u8]) -> Option<u32> {
    decode_deployment(blob).ok().map(|d| d.table.generation)
}

/// The state words of one slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SlotState {
    pub staged: bool,
    /// The activation serial, if it was activated.
    pub serial: Option<u32>,
    pub confirmed: bool,
    pub revoked: bool,
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

    fn read_word(&mut self, at: u32) -> Result<u32, F::Error> {
        let mut word = [0u8; MAX_ALIGN];
        block_on(self.flash.read(at, &mut word[..F::READ_SIZE.max(4)]))?;
        Ok(u32::from_le_bytes([word[0], word[1], word[2], word[3]]))
    }

    fn write_word(&mut self, at: u32, value: u32) -> Result<(), SlotError<F::Error>> {
        let mut word = [0xFFu8; MAX_ALIGN];
        word[..4].copy_from_slice(&value.to_le_bytes());
        block_on(self.flash.write(at, &word[..F::WRITE_SIZE.max(4)])).map_err(SlotError::Flash)
    }

    /// The state words of slot `slot`.
    pub fn state_now(&mut self, slot: usize) -> Result<SlotState, F::Error> {
        let base = self.base(slot);
        let serial = self.read_word(base + SERIAL_AT)?;
        Ok(SlotState {
            staged: self.read_word(base + STAGED_AT)? == STAGED,
            serial: (serial != ERASED).then_some(serial),
            confirmed: self.read_word(base + CONFIRMED_AT)? == CONFIRMED,
            revoked: self.read_word(base + REVOKED_AT)? == REVOKED,
        })
    }

    /// Reads slot `slot`'s blob into `buf` if the slot is staged; returns its length.
    pub fn read_blob_now(
        &mut self,
        slot: usize,
        buf: &mut [u8; MAX_BLOB + MAX_ALIGN],
    ) -> Result<Option<usize>, F::Error> {
        let base = self.base(slot);
        if self.read_word(base + STAGED_AT)? != STAGED {
            return Ok(None);
        }
        let len = self.read_word(base + LEN_AT)? as usize;
        if len > MAX_BLOB {
            return Ok(None);
        }
        let padded = round_up(len, F::READ_SIZE);
        block_on(self.flash.read(base + HEADER as u32, &mut buf[..padded]))?;
        Ok(Some(len))
    }

    /// Reads slot `slot`'s blob into `buf` if the slot is staged and the blob fits;
    /// returns its length. (No buffer of its own: the runtime reads into one on its stack.)
    pub fn read_into_now(
        &mut self,
        slot: usize,
        buf: &mut [u8],
    ) -> Result<Option<usize>, F::Error> {
        let base = self.base(slot);
        if self.read_word(base + STAGED_AT)? != STAGED {
            return Ok(None);
        }
        let len = self.read_word(base + LEN_AT)? as usize;
        let Some(dst) = buf.get_mut(..len).filter(|_| len <= MAX_BLOB) else {
            return Ok(None);
        };
        let whole = len / F::READ_SIZE.max(1) * F::READ_SIZE.max(1);
        let (body, tail) = dst.split_at_mut(whole);
        if !body.is_empty() {
            block_on(self.flash.read(base + HEADER as u32, body))?;
        }
        if !tail.is_empty() {
            let mut last = [0u8; MAX_ALIGN];
            let n = F::READ_SIZE.max(1);
            block_on(
                self.flash
                    .read(base + (HEADER + whole) as u32, &mut last[..n]),
            )?;
            tail.copy_from_slice(&last[..tail.len()]);
        }
        Ok(Some(len))
    }

    /// The table (and its keys) staged in slot `slot`, if it decodes and validates.
    pub fn read_table_now(&mut self, slot: usize) -> Result<Option<Loaded>, F::Error> {
        let mut buf = [0u8; MAX_BLOB + MAX_ALIGN];
        let Some(len) = self.read_blob_now(slot, &mut buf)? else {
            return Ok(None);
        };
        Ok(decode_deployment(buf.get(..len).unwrap_or(&[]))
            .ok()
            .map(|d| Loaded { slot, deployed: d }))
    }

    /// What the slots hold: the table to boot, a staged one, an abandoned trial.
    pub fn load_now(&mut self) -> Result<Boot, F::Error> {
        let mut buf = [0u8; MAX_BLOB];
        let survey = self.survey_now(&mut buf)?;
        let mut boot = Boot {
            running: None,
            staged: survey.staged,
            abandoned: survey.abandoned,
            previous: survey.previous,
            next_serial: survey.next_serial,
        };
        if let Some(running) = survey.running {
            boot.running = self.read_table_now(running.slot)?;
        }
        Ok(boot)
    }

    /// What [`Slots::load`] finds, the running table named, not decoded into RAM of its
    /// own: each blob is read into `buf` (at least `MAX_BLOB` bytes) and decoded there, one
    /// at a time, only to be checked. The runtime runs it with a buffer on its stack and
    /// reads the running slot back the same way, so no table and no blob buffer live in
    /// its future.
    pub fn survey_now(&mut self, buf: &mut [u8]) -> Result<Survey, F::Error> {
        let mut survey = Survey::default();
        let mut best: Option<u32> = None;
        for slot in 0..2 {
            let st = self.state_now(slot)?;
            // Numbered above the confirmed tables only: a serial torn by a power cut (the
            // write half applied: 0xFFFF_0001 for 1), whose slot is abandoned, would
            // number the next ones up to the erased word (never activated) within 65,535.
            if let (Some(serial), true, false) = (st.serial, st.confirmed, st.revoked) {
                survey.next_serial = survey.next_serial.max(serial.saturating_add(1));
            }
            if !st.staged || st.revoked {
                continue;
            }
            if let (Some(_), false) = (st.serial, st.confirmed) {
                survey.abandoned = Some(slot);
                continue;
            }
            // Checked when it was staged; its generation is in the envelope. A confirmed
            // slot that no longer decodes is not booted.
            let Some(generation) = self.generation_of(slot, buf)? else {
                continue;
            };
            let here = StagedSlot { slot, generation };
            match st.serial {
                None => survey.staged = Some(here),
                Some(serial) => {
                    if best.is_some_and(|b| b >= serial) {
                        survey.previous = Some(here);
                        continue;
                    }
                    if let Some(old) = survey.running.take() {
                        survey.previous = Some(old);
                    }
                    best = Some(serial);
                    survey.running = Some(here);
                }
            }
        }
        Ok(survey)
    }

    /// The generation of the deployment staged in slot `slot`, if it decodes and
    /// validates (read into `buf`).
    fn generation_of(&mut self, slot: usize, buf: &mut [u8]) -> Result<Option<u32>, F::Error> {
        let Some(len) = self.read_into_now(slot, buf)? else {
            return Ok(None);
        };
        Ok(generation(buf.get(..len).unwrap_or(&[])))
    }

    /// Erases slot `slot` and writes `blob` and its length, not yet staged.
    pub fn persist_now(&mut self, slot: usize, blob: &[u8]) -> Result<(), SlotError<F::Error>> {
        if blob.len() > MAX_BLOB {
            return Err(SlotError::TooLong);
        }
        let base = self.base(slot);
        block_on(self.flash.erase(base, base + self.slot_size)).map_err(SlotError::Flash)?;
        let whole = blob.len() / F::WRITE_SIZE * F::WRITE_SIZE;
        let (body, tail) = blob.split_at(whole);
        if !body.is_empty() {
            block_on(self.flash.write(base + HEADER as u32, body)).map_err(SlotError::Flash)?;
        }
        if !tail.is_empty() {
            let mut last = [0xFFu8; MAX_ALIGN];
            last[..tail.len()].copy_from_slice(tail);
            block_on(
                self.flash
                    .write(base + (HEADER + whole) as u32, &last[..F::WRITE_SIZE]),
            )
            .map_err(SlotError::Flash)?;
        }
        self.write_word(base + LEN_AT, blob.len() as u32)
    }

    /// Persists `blob` in the slot not holding `running` and marks it staged: checked,
    /// not running. Returns the slot written.
    pub fn stage_now(
        &mut self,
        running: Option<usize>,
        blob: &[u8],
    ) -> Result<usize, SlotError<F::Error>> {
        let slot = match running {
            Some(0) => 1,
            _ => 0,
        };
        self.persist_now(slot, blob)?;
        self.write_word(self.base(slot) + STAGED_AT, STAGED)?;
        Ok(slot)
    }

    /// Makes staged slot `slot` the boot table with activation `serial`; unless `trial`,
    /// confirmed at once.
    pub fn activate_now(
        &mut self,
        slot: usize,
        serial: u32,
        trial: bool,
    ) -> Result<(), SlotError<F::Error>> {
        let st = self.state_now(slot).map_err(SlotError::Flash)?;
        if !st.staged || st.revoked || st.serial.is_some() {
            return Err(SlotError::NotStaged);
        }
        let base = self.base(slot);
        self.write_word(base + SERIAL_AT, serial)?;
        if !trial {
            self.write_word(base + CONFIRMED_AT, CONFIRMED)?;
        }
        Ok(())
    }

    /// Confirms slot `slot`'s activation (a trial that passed).
    pub fn confirm_now(&mut self, slot: usize) -> Result<(), SlotError<F::Error>> {
        self.write_word(self.base(slot) + CONFIRMED_AT, CONFIRMED)
    }

    /// Revokes slot `slot`: it never boots again (a rollback, an abandoned trial).
    pub fn revoke_now(&mut self, slot: usize) -> Result<(), SlotError<F::Error>> {
        self.write_word(self.base(slot) + REVOKED_AT, REVOKED)
    }

    /// Stages `blob` beside the running table (in slot `running`, if any) and activates it,
    /// confirmed, with `serial`: the one-step store. Returns the slot written.
    pub fn store_now(
        &mut self,
        running: Option<usize>,
        blob: &[u8],
        serial: u32,
    ) -> Result<usize, SlotError<F::Error>> {
        let slot = self.stage_now(running, blob)?;
        self.activate_now(slot, serial, false)?;
        Ok(slot)
    }

    // The same operations as futures (for callers in async code; each completes when
    // first polled, as the flash does).

    /// [`Slots::state_now`] as a future.
    pub async fn state(&mut self, slot: usize) -> Result<SlotState, F::Error> {
        self.state_now(slot)
    }

    /// [`Slots::read_blob_now`] as a future.
    pub async fn read_blob(
        &mut self,
        slot: usize,
        buf: &mut [u8; MAX_BLOB + MAX_ALIGN],
    ) -> Result<Option<usize>, F::Error> {
        self.read_blob_now(slot, buf)
    }

    /// [`Slots::read_into_now`] as a future.
    pub async fn read_into(
        &mut self,
        slot: usize,
        buf: &mut [u8],
    ) -> Result<Option<usize>, F::Error> {
        self.read_into_now(slot, buf)
    }

    /// [`Slots::read_table_now`] as a future.
    pub async fn read_table(&mut self, slot: usize) -> Result<Option<Loaded>, F::Error> {
        self.read_table_now(slot)
    }

    /// [`Slots::load_now`] as a future.
    pub async fn load(&mut self) -> Result<Boot, F::Error> {
        self.load_now()
    }

    /// [`Slots::survey_now`] as a future.
    pub async fn survey(&mut self, buf: &mut [u8]) -> Result<Survey, F::Error> {
        self.survey_now(buf)
    }

    /// [`Slots::persist_now`] as a future.
    pub async fn persist(&mut self, slot: usize, blob: &[u8]) -> Result<(), SlotError<F::Error>> {
        self.persist_now(slot, blob)
    }

    /// [`Slots::stage_now`] as a future.
    pub async fn stage(
        &mut self,
        running: Option<usize>,
        blob: &[u8],
    ) -> Result<usize, SlotError<F::Error>> {
        self.stage_now(running, blob)
    }

    /// [`Slots::activate_now`] as a future.
    pub async fn activate(
        &mut self,
        slot: usize,
        serial: u32,
        trial: bool,
    ) -> Result<(), SlotError<F::Error>> {
        self.activate_now(slot, serial, trial)
    }

    /// [`Slots::confirm_now`] as a future.
    pub async fn confirm(&mut self, slot: usize) -> Result<(), SlotError<F::Error>> {
        self.confirm_now(slot)
    }

    /// [`Slots::revoke_now`] as a future.
    pub async fn revoke(&mut self, slot: usize) -> Result<(), SlotError<F::Error>> {
        self.revoke_now(slot)
    }

    /// [`Slots::store_now`] as a future.
    pub async fn store(
        &mut self,
        running: Option<usize>,
        blob: &[u8],
        serial: u32,
    ) -> Result<usize, SlotError<F::Error>> {
        self.store_now(running, blob, serial)
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
