//! The Embassy runtime around [`NodeCore`]: the same code on every board, generic over the
//! hardware at its seams.
//!
//! - [`Radio`]: send and receive one IEEE 802.15.4 PSDU (half duplex, async);
//! - [`Pins`]: the outputs, addressed by the table's pin numbers (implemented for slices of
//!   `embedded_hal::digital::OutputPin`, index = pin number);
//! - [`Inputs`]: the next input level change (implemented by [`WaitInputs`] for arrays of
//!   `embedded_hal_async::digital::Wait` + `InputPin`, index = pin number);
//! - a `NorFlash` (`embedded-storage-async`) for the two table [`Slots`], whose
//!   operations complete when first polled: the runtime calls the slots' blocking forms
//!   (`Slots::stage_now`, ...: each flash access run to completion in place), so no slot
//!   operation is a state of the runtime's future (a slot is read back into a buffer on
//!   the stack);
//! - a [`Staging`] for a pushed table's chunks ([`run_staged`]: an MCU board's flash
//!   page; [`RamStaging`] otherwise);
//! - `embassy-time` for the time and the timer until [`NodeCore::deadline`].
//!
//! [`run`] boots (outputs safe, the slot activated last, `NodeCore::new`) and then loops:
//! wait for a frame, an input change or the deadline; feed the core; poll it; do what it
//! asks of the flash (stage a pushed table, activate, roll back, confirm: then `staged`,
//! `activated` or `confirmed`); transmit what the core queued. The transmit queue is
//! bounded: a full queue drops the frame and counts it, and a radio that does not take a
//! frame within [`SEND_TIMEOUT_MS`] loses it (counted too), so nothing blocks forever. The
//! protocols above (event links, OTA) resend what is lost.

use core::convert::Infallible;

use config_schema::limits::MAX_BLOB;
use config_schema::link_keys::{decode_deployment, Deployment};
use config_schema::wire::mac::{MAX_MPDU, MAX_PSDU};
use embassy_futures::select::{select3, select_array, Either3};
use embassy_time::{with_timeout, Duration, Instant, Timer, TICK_HZ};
use embedded_hal::digital::{InputPin, OutputPin};
use embedded_hal_async::digital::Wait;
use embedded_storage::nor_flash::{NorFlashError, NorFlashErrorKind};
use embedded_storage_async::nor_flash::NorFlash;
use heapless::Vec;
use log::{info, warn};

use config_schema::wire::msg::RuntimeCounters;

use crate::epoch::Epochs;
use crate::node::{fault_code, FlashRequest, Io, NodeCore};
use crate::ota::{RamStaging, Staging};
use crate::provision::ManagementKey;
use crate::slots::{SlotError, Slots, Survey};

/// Frames the core may queue between two flushes (a poll that retransmits to every peer
/// queues at most `WINDOW` frames per peer).
pub const TX_QUEUE: usize = 32;
/// Bytes of the frames the core may queue between two flushes (each frame takes its
/// length and one byte more): the `TX_QUEUE` event frames of a full retransmission round
/// (8 peers x `link::WINDOW`, at most 33 bytes each secured: 1,088 bytes), or 9 frames of
/// the longest PSDU.
pub const TX_BYTES: usize = 1152;
/// How long the radio may take to accept one frame before it is dropped.
pub const SEND_TIMEOUT_MS: u64 = 100;
/// The longest single sleep of the main loop (the deadline is recomputed after it).
pub const MAX_SLEEP_MS: u64 = 60_000;

/// One PSDU (FCS included): a frame as the medium and the UART carry it.
pub type Psdu = Vec<u8, MAX_PSDU>;

/// What the radio received.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Received {
    /// An MPDU of this many bytes (its FCS checked and cut off at the radio edge).
    Mpdu(usize),
    /// A frame the edge refused (its FCS did not match, or not a PSDU): the core counts it
    /// ([`NodeCore::dropped_at_edge`]).
    Dropped,
}

/// The radio edge in software, for a transport that carries PSDUs (the host medium, the
/// QEMU UART): checks `psdu`'s FCS and copies its MPDU to the start of `buf`.
pub fn mpdu_of(psdu: &[u8], buf: &mut [u8; MAX_PSDU]) -> Received {
    let Ok(mpdu) = config_schema::wire::mac::strip_fcs(psdu) else {
        return Received::Dropped;
    };
    match buf.get_mut(..mpdu.len()) {
        Some(dst) => {
            dst.copy_from_slice(mpdu);
            Received::Mpdu(mpdu.len())
        }
        None => Received::Dropped,
    }
}

/// The radio edge in software on transmit: `mpdu` with its FCS appended, as the medium and
/// the UART carry it (`None`: longer than an MPDU).
pub fn psdu_of(mpdu: &[u8]) -> Option<Psdu> {
    let mut psdu = Psdu::new();
    psdu.extend_from_slice(mpdu).ok()?;
    psdu.extend_from_slice(&[0, 0]).ok()?;
    let n = config_schema::wire::mac::append_fcs(&mut psdu, mpdu.len()).ok()?;
    psdu.truncate(n);
    Some(psdu)
}

/// The radio: an IEEE 802.15.4 transceiver, or a connection to a simulated medium. The
/// core deals in MPDUs (frames without their FCS); the radio adds and checks the FCS, in
/// hardware (the nRF52840) or at the transport's edge ([`psdu_of`], [`mpdu_of`]).
#[allow(async_fn_in_trait)]
pub trait Radio {
    type Error: core::fmt::Debug;
    /// Transmits one MPDU (the radio appends the FCS).
    async fn send(&mut self, mpdu: &[u8]) -> Result<(), Self::Error>;
    /// Receives one frame into `buf`: its MPDU, the FCS checked and cut off, or that the
    /// edge dropped it. Must be cancel-safe: the runtime drops an unfinished receive when
    /// an input or a timer wins, losing at most the frame in flight. An error stops the
    /// runtime (the radio is gone).
    async fn receive(&mut self, buf: &mut [u8; MAX_PSDU]) -> Result<Received, Self::Error>;
}

/// The outputs, addressed by the table's pin numbers.
pub trait Pins {
    /// Drives output `pin` to `level` (pins the board does not have are ignored).
    fn set(&mut self, pin: u8, level: bool);
    /// Drives every output to its inactive level: the state before any table is known.
    fn all_off(&mut self);
    /// The node runs table generation `generation` from now on ([`crate::node::Io::running`]).
    fn running(&mut self, _generation: u32) {}
}

/// Output pins indexed by the table's pin numbers (`self[pin]`), inactive when low.
impl<O: OutputPin> Pins for [O] {
    fn set(&mut self, pin: u8, level: bool) {
        if let Some(p) = self.get_mut(usize::from(pin)) {
            let _ = if level { p.set_high() } else { p.set_low() };
        }
    }
    fn all_off(&mut self) {
        for p in self.iter_mut() {
            let _ = p.set_low();
        }
    }
}

impl<O: OutputPin, const N: usize> Pins for [O; N] {
    fn set(&mut self, pin: u8, level: bool) {
        self.as_mut_slice().set(pin, level)
    }
    fn all_off(&mut self) {
        self.as_mut_slice().all_off()
    }
}

impl<P: Pins + ?Sized> Pins for &mut P {
    fn set(&mut self, pin: u8, level: bool) {
        (**self).set(pin, level)
    }
    fn all_off(&mut self) {
        (**self).all_off()
    }
}

/// The inputs: limit switches, buttons.
#[allow(async_fn_in_trait)]
pub trait Inputs {
    /// The levels now (bit = pin number, pins 0..=63), read once at boot before any
    /// change: the table from flash starts from the switches' real positions. What this
    /// returns is not reported again by [`Inputs::change`].
    fn levels(&mut self) -> u64;
    /// Waits for the next change of an input's level; returns (pin, new level). Must be
    /// cancel-safe: a change that happens while no `change` future is pending is reported
    /// by the next call.
    async fn change(&mut self) -> (u8, bool);
}

/// No inputs at all.
impl Inputs for () {
    fn levels(&mut self) -> u64 {
        0
    }
    async fn change(&mut self) -> (u8, bool) {
        core::future::pending().await
    }
}

/// `embedded-hal-async` input pins indexed by the table's pin numbers (`pins[pin]`).
///
/// Levels are the truth and edges only wake it up: each call first compares every pin's
/// level with the last one reported, so an edge that came while nobody waited is not lost
/// (a pulse shorter than one loop turn may be).
pub struct WaitInputs<'a, I, const N: usize> {
    pins: &'a mut [I; N],
    reported: [bool; N],
}

impl<'a, I: Wait + InputPin, const N: usize> WaitInputs<'a, I, N> {
    /// Every pin is taken as reported low until [`Inputs::levels`] reads them.
    pub fn new(pins: &'a mut [I; N]) -> Self {
        WaitInputs {
            pins,
            reported: [false; N],
        }
    }
}

impl<I: Wait + InputPin, const N: usize> Inputs for WaitInputs<'_, I, N> {
    fn levels(&mut self) -> u64 {
        let mut levels = 0u64;
        for (i, (pin, reported)) in self.pins.iter_mut().zip(&mut self.reported).enumerate() {
            *reported = pin.is_high().unwrap_or(false);
            if *reported && i < 64 {
                levels |= 1 << i;
            }
        }
        levels
    }
    async fn change(&mut self) -> (u8, bool) {
        loop {
            for (i, (pin, reported)) in self.pins.iter_mut().zip(&mut self.reported).enumerate() {
                if let Ok(level) = pin.is_high() {
                    if level != *reported {
                        *reported = level;
                        return (i as u8, level);
                    }
                }
            }
            let waits = self.pins.each_mut().map(|p| p.wait_for_any_edge());
            let (result, _) = select_array(waits).await;
            if result.is_err() {
                // A pin that cannot wait: look again later instead of spinning.
                Timer::after_millis(10).await;
            }
        }
    }
}

/// Why the runtime stopped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Stop<E> {
    /// The radio failed (for the host board: the medium closed the connection).
    Radio(E),
    /// The flash is too small for two slots or its granularity does not fit.
    FlashGeometry,
}

/// What the runtime counted besides the core's counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Frames dropped because the transmit queue was full.
    pub tx_queue_full: u32,
    /// The most frames the transmit queue held (of [`TX_QUEUE`]).
    pub tx_queue_high: u32,
    /// Frames the radio refused or did not take in time.
    pub tx_failed: u32,
    /// Tables persisted and activated.
    pub activations: u32,
    /// Tables that could not be persisted (refused to the tool).
    pub flash_failures: u32,
}

/// What the core was doing, for a [`Probe`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Work {
    /// `NodeCore::receive` of one frame.
    Frame,
    /// `NodeCore::input` of one input change.
    Input,
}

/// Measures the core's work (a board that counts instructions or cycles); `()` does not.
pub trait Probe {
    /// The core starts on a stimulus.
    fn start(&mut self) {}
    /// The core is done with it (the frames it queued not yet sent).
    fn stop(&mut self, _work: Work) {}
}

impl Probe for () {}

/// Why a flash operation of the runtime failed, without the board's error type (what a
/// board's log needs, no `Debug` of its own error).
pub type FlashFailure = SlotError<NorFlashErrorKind>;

fn failure<E: NorFlashError>(e: SlotError<E>) -> FlashFailure {
    match e {
        SlotError::Geometry => SlotError::Geometry,
        SlotError::TooLong => SlotError::TooLong,
        SlotError::NotStaged => SlotError::NotStaged,
        SlotError::Flash(e) => SlotError::Flash(e.kind()),
    }
}

/// What the runtime tells the operator: the boot, activations, flash failures, faults.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Note<'a> {
    /// The slots could not be read at boot: the node boots unconfigured.
    FlashUnreadable(NorFlashErrorKind),
    /// A trial a power cut interrupted (slot `slot`): back to the confirmed table.
    TrialCutShort { slot: usize },
    /// Slot `slot` could not be revoked.
    CannotRevoke {
        slot: usize,
        why: Option<FlashFailure>,
    },
    /// The stored table uses pin `pin`, which the board lacks: it is not run.
    MissingPin { pin: u8 },
    /// A pushed table could not be staged.
    CannotStage(FlashFailure),
    /// Slot `slot` could not be activated.
    CannotActivate { slot: usize, why: FlashFailure },
    /// The node switched (`rollback`: back to the previous table) to `role` `generation`
    /// in slot `slot`.
    Switched {
        rollback: bool,
        role: &'a str,
        generation: u32,
        slot: usize,
    },
    /// The node booted with `role` `generation` from slot `slot`.
    Boot {
        role: &'a str,
        generation: u32,
        slot: usize,
    },
    /// The node booted with no table.
    BootUnconfigured,
    /// `generation` is staged in slot `slot` (at boot).
    Staged { generation: u32, slot: usize },
    /// The engine faulted (status code `code`): outputs safe.
    Fault { code: u8 },
    /// The fault was cleared.
    FaultCleared,
}

/// Where the runtime's [`Note`]s go. The default writes them to the `log` crate (the host,
/// QEMU's semihosting console); a board may print them its own way (the nRF52840: defmt,
/// no `core::fmt` in the image).
pub trait Notes {
    fn note(&mut self, addr: u16, note: Note<'_>) {
        log_note(addr, note);
    }
}

impl Notes for () {}

/// `note` as a `log` record (warnings for failures and faults).
pub fn log_note(addr: u16, note: Note<'_>) {
    match note {
        Note::FlashUnreadable(e) => {
            warn!("node {addr:#06x}: flash unreadable ({e:?}): booting unconfigured")
        }
        Note::TrialCutShort { slot } => warn!(
            "node {addr:#06x}: a trial was cut short (slot {slot}): back to the confirmed table"
        ),
        Note::CannotRevoke { slot, why: None } => {
            warn!("node {addr:#06x}: cannot revoke slot {slot}")
        }
        Note::CannotRevoke { slot, why: Some(e) } => {
            warn!("node {addr:#06x}: cannot revoke slot {slot}: {e:?}")
        }
        Note::MissingPin { pin } => {
            warn!("node {addr:#06x}: the stored table uses pin {pin}, which this board lacks")
        }
        Note::CannotStage(e) => warn!("node {addr:#06x}: cannot stage the pushed table: {e:?}"),
        Note::CannotActivate { slot, why } => {
            warn!("node {addr:#06x}: cannot activate slot {slot}: {why:?}")
        }
        Note::Switched {
            rollback,
            role,
            generation,
            slot,
        } => {
            let what = if rollback {
                "rolled back to"
            } else {
                "activated"
            };
            info!("node {addr:#06x}: {what} role {role} generation {generation} (slot {slot})")
        }
        Note::Boot {
            role,
            generation,
            slot,
        } => info!("node {addr:#06x}: boot: role {role} generation {generation} from slot {slot}"),
        Note::BootUnconfigured => info!("node {addr:#06x}: boot: unconfigured"),
        Note::Staged { generation, slot } => {
            info!("node {addr:#06x}: generation {generation} staged (slot {slot})")
        }
        Note::Fault { code } => warn!("node {addr:#06x}: fault {code:#04x}: outputs safe"),
        Note::FaultCleared => info!("node {addr:#06x}: fault cleared"),
    }
}

/// The frames the core queued since the last flush: appended while the core runs, all
/// sent (in order) before it runs again, so one linear buffer of [`TX_BYTES`] holds them
/// (each as its length byte and its bytes), at most [`TX_QUEUE`] of them.
struct TxQueue {
    bytes: [u8; TX_BYTES],
    /// Bytes in use (`bytes[..end]`), frames in them, and where the next to send starts.
    end: usize,
    frames: usize,
    head: usize,
}

impl TxQueue {
    const fn new() -> Self {
        TxQueue {
            bytes: [0; TX_BYTES],
            end: 0,
            frames: 0,
            head: 0,
        }
    }

    /// Appends `mpdu`; `false` (nothing queued) if the queue is full.
    fn push(&mut self, mpdu: &[u8]) -> bool {
        let Ok(len) = u8::try_from(mpdu.len()) else {
            return false;
        };
        let Some(dst) = self.bytes.get_mut(self.end..self.end + 1 + mpdu.len()) else {
            return false;
        };
        if self.frames >= TX_QUEUE {
            return false;
        }
        if let Some((first, rest)) = dst.split_first_mut() {
            *first = len;
            rest.copy_from_slice(mpdu);
        }
        self.end += 1 + mpdu.len();
        self.frames += 1;
        true
    }

    fn len(&self) -> usize {
        self.frames
    }

    /// The next frame to send.
    fn front(&self) -> Option<&[u8]> {
        let len = usize::from(*self.bytes.get(self.head).filter(|_| self.head < self.end)?);
        self.bytes.get(self.head + 1..self.head + 1 + len)
    }

    /// Drops the frame [`TxQueue::front`] gave; the queue starts over once empty.
    fn pop(&mut self) {
        let len = self.front().map_or(0, <[u8]>::len);
        self.head += 1 + len;
        self.frames = self.frames.saturating_sub(1);
        if self.head >= self.end || self.frames == 0 {
            self.head = 0;
            self.end = 0;
            self.frames = 0;
        }
    }
}

/// The core's view of the board: pins directly, frames into the bounded queue.
struct CoreIo<'a, P> {
    pins: &'a mut P,
    tx: TxQueue,
    stats: &'a mut Stats,
    counter: &'a mut dyn FnMut() -> Option<u32>,
}

impl<P: Pins> Io for CoreIo<'_, P> {
    /// The core sends MPDUs ([`Io::transmit_mpdu`]); a PSDU is queued as its MPDU.
    fn transmit(&mut self, psdu: &[u8]) {
        match config_schema::wire::mac::strip_fcs(psdu) {
            Ok(mpdu) => self.transmit_mpdu(mpdu),
            Err(_) => crate::count(&mut self.stats.tx_failed),
        }
    }
    fn transmit_mpdu(&mut self, mpdu: &[u8]) {
        if mpdu.len() > MAX_MPDU {
            crate::count(&mut self.stats.tx_failed);
            return;
        }
        if !self.tx.push(mpdu) {
            crate::count(&mut self.stats.tx_queue_full);
        }
        self.stats.tx_queue_high = self.stats.tx_queue_high.max(self.tx.len() as u32);
    }
    fn set_pin(&mut self, pin: u8, level: bool) {
        self.pins.set(pin, level);
    }
    fn running(&mut self, generation: u32) {
        self.pins.running(generation);
    }
    fn next_frame_counter(&mut self) -> Option<u32> {
        (self.counter)()
    }
    fn runtime_counters(&self) -> RuntimeCounters {
        RuntimeCounters {
            tx_queue_full: self.stats.tx_queue_full,
            tx_queue_high: u8::try_from(self.stats.tx_queue_high).unwrap_or(u8::MAX),
            tx_failed: self.stats.tx_failed,
            flash_failures: self.stats.flash_failures,
        }
    }
}

/// The mask of table pins `0..count` (every pin a table may name from 64 on).
pub const fn pin_range(count: usize) -> u64 {
    if count >= 64 {
        u64::MAX
    } else {
        (1u64 << count) - 1
    }
}

/// The bytes of the runtime's own parts of its future (besides the [`NodeCore`] and the
/// board's seams), as this build lays them out (docs/boards.md).
pub fn footprint() -> [(&'static str, usize); 3] {
    use core::mem::size_of;
    [
        ("transmit queue", size_of::<TxQueue>()),
        ("receive buffer", MAX_PSDU),
        ("Stats", size_of::<Stats>()),
    ]
}

/// The hardware of one node.
pub struct Board<R, P, I, F> {
    pub radio: R,
    pub outputs: P,
    pub inputs: I,
    pub flash: F,
    /// The table pin numbers the board has (bit n: pin n): the node refuses a table that
    /// names any other (`Refusal::Pin`), and does not run one from flash.
    pub pin_mask: u64,
}

fn now_ms() -> u64 {
    Instant::now().as_millis()
}

const fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// Ticks per `TICK_PER_MS.1` ms: `Duration::from_millis`'s reduced fraction.
const TICK_PER_MS: (u64, u64) = {
    let g = gcd(TICK_HZ, 1000);
    (TICK_HZ / g, 1000 / g)
};

/// `ms` (at most [`MAX_SLEEP_MS`]) as `Duration::from_millis(ms)`, rounded up the same
/// way, computed in `u32` where the tick rate lets it (the nRF52840's 32,768 Hz): a
/// Cortex-M divides a `u32` in one instruction, a `u64` division links 0.9 KB.
fn sleep_for(ms: u64) -> Duration {
    let (num, den) = TICK_PER_MS;
    if MAX_SLEEP_MS * num + den <= u32::MAX as u64 {
        let ms = ms.min(MAX_SLEEP_MS) as u32;
        Duration::from_ticks(u64::from((ms * num as u32).div_ceil(den as u32)))
    } else {
        Duration::from_millis(ms)
    }
}

/// The running engine's fault code, if faulted.
fn fault_of<S: Staging>(core: &NodeCore<S>) -> Option<u8> {
    core.engine_state().and_then(|s| s.fault).map(fault_code)
}

/// What the runtime keeps of the slots: the one running, the one staged, the next
/// activation's serial.
#[derive(Debug, Clone, Copy, Default)]
struct SlotsAt {
    running: Option<usize>,
    staged: Option<usize>,
    /// The other slot, confirmed: what a rollback returns to.
    previous: Option<usize>,
    /// The running slot is on trial (activated, not confirmed).
    trial: bool,
    next_serial: u32,
    /// The boot could not read the slots (it runs no table): none is staged until they
    /// are read (a table staged then went over the one confirmed, with a serial below
    /// it, and the next boot ran the older table).
    unread: bool,
}

impl SlotsAt {
    /// Where the slots are, as `survey` read them.
    fn of(survey: &Survey) -> SlotsAt {
        SlotsAt {
            running: survey.running.map(|l| l.slot),
            staged: survey.staged.map(|s| s.slot),
            previous: survey.previous.map(|p| p.slot),
            trial: false,
            next_serial: survey.next_serial,
            unread: false,
        }
    }
}

/// Reads slot `slot`'s blob into a buffer on the stack and hands it to `f` (`None`: the
/// slot holds no blob, or the flash failed). Run to completion in place
/// (`Slots::read_into_now`: every board's flash completes at once, see docs/boards.md),
/// so the 4 KiB buffer is never part of the runtime's future.
fn with_slot<F: NorFlash, R>(
    slots: &mut Slots<F>,
    slot: usize,
    f: impl FnOnce(&[u8]) -> R,
) -> Option<R> {
    let mut buf = [0u8; MAX_BLOB];
    let len = slots.read_into_now(slot, &mut buf).ok().flatten()?;
    buf.get(..len).map(f)
}

/// The deployment (table and link keys) in slot `slot`, if it decodes; one copy of the
/// read and the decode for every caller.
#[inline(never)]
fn deployment<F: NorFlash>(slots: &mut Slots<F>, slot: usize) -> Option<Deployment> {
    with_slot(slots, slot, |blob| decode_deployment(blob).ok()).flatten()
}

/// Whether slot `slot` holds a deployment that decodes (the table is not kept).
fn decodes<F: NorFlash>(slots: &mut Slots<F>, slot: usize) -> bool {
    deployment(slots, slot).is_some()
}

/// What the slots hold (read into a buffer on the stack: [`with_slot`]).
fn survey<F: NorFlash, N: Notes>(addr: u16, slots: &mut Slots<F>, notes: &mut N) -> Option<Survey> {
    let mut buf = [0u8; MAX_BLOB];
    match slots.survey_now(&mut buf) {
        Ok(survey) => Some(survey),
        Err(e) => {
            notes.note(addr, Note::FlashUnreadable(e.kind()));
            None
        }
    }
}

/// The node on the slot activated last (an unreadable flash boots unconfigured), with a
/// staged table reported; a trial a power cut interrupted is revoked. The slots are read
/// and the running table decoded outside the runtime's future ([`with_slot`]).
fn load<F: NorFlash, S: Staging, N: Notes>(
    addr: u16,
    pin_mask: u64,
    epochs: Epochs,
    slots: &mut Slots<F>,
    staging: S,
    notes: &mut N,
) -> (NodeCore<S>, SlotsAt) {
    let read = survey(addr, slots, notes);
    let survey = read.unwrap_or_default();
    if let Some(slot) = survey.abandoned {
        notes.note(addr, Note::TrialCutShort { slot });
        if slots.revoke_now(slot).is_err() {
            notes.note(addr, Note::CannotRevoke { slot, why: None });
        }
    }
    let at = SlotsAt {
        unread: read.is_none(),
        ..SlotsAt::of(&survey)
    };
    let core = boot_core(addr, pin_mask, epochs, slots, &survey, staging, notes);
    (core, at)
}

/// The boot node: the running slot's table (none: unconfigured) with its keys, the
/// staged or previous generation noted.
fn boot_core<F: NorFlash, S: Staging, N: Notes>(
    addr: u16,
    pin_mask: u64,
    epochs: Epochs,
    slots: &mut Slots<F>,
    survey: &Survey,
    staging: S,
    notes: &mut N,
) -> NodeCore<S> {
    let deployed = survey.running.and_then(|r| deployment(slots, r.slot));
    if let Some(pin) = deployed
        .as_ref()
        .and_then(|d| d.table.missing_pin(pin_mask))
    {
        notes.note(addr, Note::MissingPin { pin });
    }
    let mut core = NodeCore::staging_in(addr, pin_mask, deployed, epochs, staging);
    if let Some(staged) = survey.staged {
        core = core.with_staged(staged.generation);
    } else if let Some(previous) = survey.previous {
        core = core.with_previous(previous.generation);
    }
    core
}

/// Does what the core asks of the flash (the slots, or `count_boot`: the board's boot
/// counter, if it has one), and tells it how it went.
fn serve_flash<F: NorFlash, P: Pins, S: Staging, N: Notes>(
    addr: u16,
    core: &mut NodeCore<S>,
    slots: &mut Slots<F>,
    at: &mut SlotsAt,
    io: &mut CoreIo<'_, P>,
    notes: &mut N,
    count_boot: &mut Option<&mut dyn FnMut() -> Option<u32>>,
) {
    match core.flash_request() {
        None => {}
        Some(FlashRequest::CountBoot) => {
            // As many counts as the epochs taken need: each moves the reservation 256 on
            // (129 from the farthest behind, 32,768), and one that fails or moves nothing
            // ends the asking until the next epoch. Bounded here too.
            for _ in 0..256 {
                let boots = count_boot.as_mut().and_then(|count| count());
                io.stats.flash_failures += u32::from(boots.is_none());
                if !core.boot_counted(boots) {
                    break;
                }
            }
        }
        Some(FlashRequest::Stage(blob)) => {
            // Slots the boot could not read: read them now (the table running before is
            // kept, and a new one is numbered above it), or stage nothing.
            if at.unread {
                if let Some(survey) = survey(addr, slots, notes) {
                    *at = SlotsAt::of(&survey);
                }
            }
            let staged = match at.unread {
                true => Err(SlotError::Flash(NorFlashErrorKind::Other)),
                false => slots.stage_now(at.running, blob).map_err(failure),
            };
            let ok = match staged {
                Ok(slot) => {
                    at.staged = Some(slot);
                    // It went over the previous table.
                    at.previous = None;
                    true
                }
                Err(e) => {
                    notes.note(addr, Note::CannotStage(e));
                    crate::count(&mut io.stats.flash_failures);
                    // Its erase may have gone over the previous table: no rollback to it.
                    at.previous = None;
                    false
                }
            };
            core.staged(ok, io);
        }
        Some(FlashRequest::Confirm) => {
            let ok = match at.running {
                Some(slot) => slots.confirm_now(slot).is_ok(),
                None => false,
            };
            if ok {
                at.trial = false;
            } else {
                crate::count(&mut io.stats.flash_failures);
            }
            core.confirmed(ok, io);
        }
        Some(FlashRequest::Rollback) => {
            let read = match (at.previous, at.running) {
                // Revoked first: a power cut after it boots the previous table too.
                (Some(slot), Some(running)) if decodes(slots, slot) => {
                    match slots.revoke_now(running) {
                        Ok(()) => {
                            at.running = Some(slot);
                            at.previous = None;
                            at.trial = false;
                            Some(slot)
                        }
                        Err(e) => {
                            let why = Some(failure(e));
                            notes.note(addr, Note::CannotRevoke { slot: running, why });
                            None
                        }
                    }
                }
                _ => None,
            };
            switched(addr, core, slots, at, io, read, true, notes);
        }
        Some(FlashRequest::Activate { trial }) => {
            let read = match at.staged {
                Some(slot) if decodes(slots, slot) => {
                    match slots.activate_now(slot, at.next_serial, trial) {
                        Ok(()) => {
                            at.next_serial = at.next_serial.wrapping_add(1);
                            if !at.trial {
                                at.previous = at.running;
                            }
                            at.running = Some(slot);
                            at.staged = None;
                            at.trial = trial;
                            Some(slot)
                        }
                        Err(e) => {
                            let why = failure(e);
                            notes.note(addr, Note::CannotActivate { slot, why });
                            // Its serial may be written: no longer staged (the core forgets
                            // it too, so that a push stages it again), revoked if the
                            // flash lets (else the next boot revokes it as a trial cut
                            // short).
                            let _ = slots.revoke_now(slot);
                            at.staged = None;
                            None
                        }
                    }
                }
                _ => None,
            };
            switched(addr, core, slots, at, io, read, false, notes);
        }
    }
}

/// The slot `read` (`None`: the flash failed) is the boot table now: the core switches
/// to it, read back and decoded here, after the last await, so the table never lives in
/// the runtime's future.
#[allow(clippy::too_many_arguments)]
fn switched<F: NorFlash, P: Pins, S: Staging, N: Notes>(
    addr: u16,
    core: &mut NodeCore<S>,
    slots: &mut Slots<F>,
    at: &SlotsAt,
    io: &mut CoreIo<'_, P>,
    read: Option<usize>,
    rollback: bool,
    notes: &mut N,
) {
    let deployed = read.and_then(|slot| deployment(slots, slot));
    let ok = deployed.is_some();
    if !ok {
        crate::count(&mut io.stats.flash_failures);
    }
    core.activated(deployed, now_ms(), io);
    if let Some(t) = core.table().filter(|_| ok) {
        crate::count(&mut io.stats.activations);
        let note = Note::Switched {
            rollback,
            role: &t.header.role,
            generation: t.generation,
            slot: at.running.unwrap_or(0),
        };
        notes.note(addr, note);
    }
}

/// Where a boot's link epochs start, and the board's persisted boot counter that reserves
/// them ([`crate::epoch`], `docs/node-runtime.md`, "Epoch").
pub enum Boot<'a> {
    /// No persisted counter: epochs from this one on (the clock's), newer than the
    /// previous boot's with room for what this boot takes; none reserved.
    Epoch(u16),
    /// Boot number `boots` of the board's persisted counter (epochs from `boots x 256`);
    /// `count` counts one more boot and returns the count it persisted (`None`: it
    /// failed), when the node has taken most of the epochs its count reserves. Not
    /// `persisted` (the board failed to write count `boots`: the next boot would read the
    /// same), nothing is reserved and the node has `count` count again at once.
    Counted {
        boots: u32,
        persisted: bool,
        count: &'a mut dyn FnMut() -> Option<u32>,
    },
}

/// Runs node `addr` on `board` until the radio fails. `epoch` must be newer than the
/// previous boot's (serial order on `u16`, with room for the tables this boot installs,
/// each of which takes the next epoch): see `docs/node-runtime.md`.
pub async fn run<R, P, I, F>(
    addr: u16,
    epoch: u16,
    board: Board<R, P, I, F>,
) -> (Stop<R::Error>, Stats)
where
    R: Radio,
    P: Pins,
    I: Inputs,
    F: NorFlash,
{
    run_probed(addr, epoch, board, &mut ()).await
}

/// [`run`], with `probe` around the core's handling of every frame and input change.
pub async fn run_probed<R, P, I, F, Q>(
    addr: u16,
    epoch: u16,
    board: Board<R, P, I, F>,
    probe: &mut Q,
) -> (Stop<R::Error>, Stats)
where
    R: Radio,
    P: Pins,
    I: Inputs,
    F: NorFlash,
    Q: Probe,
{
    run_secured(addr, Boot::Epoch(epoch), board, probe, None).await
}

/// What a provisioned node secures its management traffic with: its key, and the source
/// of its frame counters (`crate::frame_counter::FrameCounter` on the board's flash;
/// `None` when exhausted or the flash failed: the frame is not sent, and counted).
pub struct Security<'a> {
    pub key: ManagementKey,
    pub counter: &'a mut dyn FnMut() -> Option<u32>,
}

/// [`run_probed`], with the management key: the config PAN is secured
/// ([`NodeCore::with_management_key`]), and the link epochs of `boot`.
pub async fn run_secured<R, P, I, F, Q>(
    addr: u16,
    boot: Boot<'_>,
    board: Board<R, P, I, F>,
    probe: &mut Q,
    security: Option<Security<'_>>,
) -> (Stop<R::Error>, Stats)
where
    R: Radio,
    P: Pins,
    I: Inputs,
    F: NorFlash,
    Q: Probe,
{
    // Held here, lent to the core: one copy in the future, not one per async layer.
    let mut staging = RamStaging::new();
    run_staged(addr, boot, board, probe, security, &mut staging, &mut ()).await
}

/// [`run_secured`], staging pushed tables in `staging` instead of a RAM buffer of the
/// runtime's own (an MCU board: a memory-mapped flash page, see [`Staging`]), its
/// [`Note`]s to `notes` (`()`: the `log` crate).
pub async fn run_staged<R, P, I, F, Q, S, N>(
    addr: u16,
    boot: Boot<'_>,
    board: Board<R, P, I, F>,
    probe: &mut Q,
    security: Option<Security<'_>>,
    staging: S,
    notes: &mut N,
) -> (Stop<R::Error>, Stats)
where
    R: Radio,
    P: Pins,
    I: Inputs,
    F: NorFlash,
    Q: Probe,
    S: Staging,
    N: Notes,
{
    let mut stats = Stats::default();
    let parts = Parts {
        stats: &mut stats,
        probe,
        security,
        staging,
        notes,
    };
    match run_inner(addr, boot, board, parts).await {
        Ok(never) => match never {},
        Err(stop) => (stop, stats),
    }
}

/// What [`run_inner`] runs with besides the board.
struct Parts<'a, 'k, Q, S, N> {
    stats: &'a mut Stats,
    probe: &'a mut Q,
    security: Option<Security<'k>>,
    staging: S,
    notes: &'a mut N,
}

async fn run_inner<R, P, I, F, Q, S, N>(
    addr: u16,
    boot: Boot<'_>,
    board: Board<R, P, I, F>,
    parts: Parts<'_, '_, Q, S, N>,
) -> Result<Infallible, Stop<R::Error>>
where
    R: Radio,
    P: Pins,
    I: Inputs,
    F: NorFlash,
    Q: Probe,
    S: Staging,
    N: Notes,
{
    let Parts {
        stats,
        probe,
        security,
        staging,
        notes,
    } = parts;
    let Board {
        mut radio,
        mut outputs,
        mut inputs,
        flash,
        pin_mask,
    } = board;
    outputs.all_off();
    let mut slots = Slots::new(flash).map_err(|_| Stop::FlashGeometry)?;
    let (epochs, mut count_boot) = match boot {
        Boot::Epoch(first) => (Epochs::unreserved(first), None),
        Boot::Counted {
            boots,
            persisted,
            count,
        } => match persisted {
            true => (Epochs::counted(boots), Some(count)),
            false => (Epochs::uncounted(boots), Some(count)),
        },
    };
    let (mut core, mut at) = load(addr, pin_mask, epochs, &mut slots, staging, notes);
    let mut no_counter = || None;
    let counter: &mut dyn FnMut() -> Option<u32> = match security {
        Some(Security { key, counter }) => {
            core = core.with_management_key(key);
            counter
        }
        None => &mut no_counter,
    };
    core.seed_pins(inputs.levels());
    let mut io = CoreIo {
        pins: &mut outputs,
        tx: TxQueue::new(),
        stats,
        counter,
    };
    core.boot(&mut io);
    let booted = match core.table() {
        Some(t) => Note::Boot {
            role: &t.header.role,
            generation: t.generation,
            slot: at.running.unwrap_or(0),
        },
        None => Note::BootUnconfigured,
    };
    notes.note(addr, booted);
    if core.staged_generation() != 0 {
        let note = Note::Staged {
            generation: core.staged_generation(),
            slot: at.staged.unwrap_or(0),
        };
        notes.note(addr, note);
    }
    let mut fault = fault_of(&core);
    let mut rx = [0u8; MAX_PSDU];
    loop {
        core.poll(now_ms(), &mut io);

        serve_flash(
            addr,
            &mut core,
            &mut slots,
            &mut at,
            &mut io,
            notes,
            &mut count_boot,
        );

        let now = fault_of(&core);
        if now != fault {
            match now {
                Some(code) => notes.note(addr, Note::Fault { code }),
                None => notes.note(addr, Note::FaultCleared),
            }
            fault = now;
        }

        while let Some(mpdu) = io.tx.front() {
            let sent = with_timeout(Duration::from_millis(SEND_TIMEOUT_MS), radio.send(mpdu)).await;
            if !matches!(sent, Ok(Ok(()))) {
                crate::count(&mut io.stats.tx_failed);
            }
            io.tx.pop();
        }

        let sleep = core.deadline().saturating_sub(now_ms()).min(MAX_SLEEP_MS);
        match select3(
            radio.receive(&mut rx),
            inputs.change(),
            Timer::after(sleep_for(sleep)),
        )
        .await
        {
            Either3::First(Ok(Received::Mpdu(n))) => {
                let mpdu = rx.get(..n).unwrap_or(&rx);
                probe.start();
                core.receive_mpdu(mpdu, now_ms(), &mut io);
                probe.stop(Work::Frame);
            }
            Either3::First(Ok(Received::Dropped)) => core.dropped_at_edge(),
            Either3::First(Err(e)) => return Err(Stop::Radio(e)),
            Either3::Second((pin, level)) => {
                probe.start();
                core.input(pin, level, now_ms(), &mut io);
                probe.stop(Work::Input);
            }
            Either3::Third(()) => {}
        }
    }
}
