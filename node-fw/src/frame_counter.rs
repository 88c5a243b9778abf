//! The frame counter a node puts in every secured frame it sends: strictly increasing for
//! ever, across power cuts, with one flash write per [`STEP`] frames (counters are reserved
//! ahead, as OpenThread does).
//!
//! The invariant: every counter handed out is below the largest reservation in flash. At
//! boot the node resumes at that reservation (the counters it may have used before the cut
//! are skipped, at most `STEP`); before it hands out the counter equal to the reservation it
//! writes the next one. A cut during that write leaves the old reservation, and no counter
//! at or above it was handed out.
//!
//! ```text
//! region: two erase sectors, used in turn; each a log of 16-byte records
//! record:
//! 0   u32 LE  MAGIC
//! 4   u32 LE  reserved: every counter handed out is below it
//! 8   u32 LE  !reserved
//! 12  u32 LE  CRC-32 of bytes 0..12
//! ```
//! A torn record fails its check and is skipped (as is the slot it occupies). When a
//! sector is full the other one is erased and the log goes on there; a cut during that
//! erase leaves the full sector, which still holds the largest reservation. A sector
//! filled by failed writes only (the flash failing for a while after a switch) holds no
//! reservation: it is erased itself and the log starts it over, never the other sector,
//! which holds the one the node relies on.
//!
//! Wear (docs/security.md): at 10 frames/s, continuously, for 10 years a node sends
//! 3.2e9 frames, so 3.1e6 reservations of 1024; a 4 KiB sector holds 256 records, so
//! each of the two sectors is erased about 6,000 times, within the nRF52840's 10,000
//! cycles. The counter stops below [`LIMIT`] (2^31: bit 31 of a challenge's nonce marks a
//! greeting), 6.8 years at that rate; there `next` says [`CounterError::Exhausted`], for
//! good: one counter serves every key of the node
//! (so a new generation's link keys do not restart it), and only re-provisioning the node
//! (a new management key, which erases this region with the rest of the node's flash)
//! starts it again at 0.

use crc::{Crc, NoTable, CRC_32_ISO_HDLC};
use embassy_futures::block_on;
use embedded_storage_async::nor_flash::NorFlash;

/// Counters reserved by one flash write.
pub const STEP: u32 = 1024;
/// Every counter handed out is below this: a challenge's nonce is its frame's counter,
/// and bit 31 of a nonce marks a greeting (`crate::restart::GREETING`); a counter with
/// it set would make every challenge of the node read as a boot's greeting.
pub const LIMIT: u32 = 1 << 31;
const RECORD: usize = 16;
const MAGIC: u32 = 0xFC0C_0017;
const CRC: Crc<u32, NoTable> = Crc::<u32, NoTable>::new(&CRC_32_ISO_HDLC);

/// Why no counter can be handed out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CounterError<E> {
    /// The region is not two erase sectors of whole records.
    Geometry,
    /// The counter reached [`LIMIT`]: a new key is needed.
    Exhausted,
    /// The flash failed (the counter was not handed out).
    Flash(E),
}

/// A node's frame counter, persisted in two erase sectors of `F`.
pub struct FrameCounter<F> {
    flash: F,
    sector: u32,
    /// Counters the next write reserves: `full` but after [`FrameCounter::catch_up`]
    /// found another writer (then 1, doubling with each write back to `full`).
    step: u32,
    full: u32,
    /// The sector the log is in, and the offset of its next free record.
    active: u32,
    free: Option<u32>,
    /// The sector whose record holds `reserved` (written and checked: the largest one in
    /// flash).
    holds: u32,
    next: u32,
    reserved: u32,
}

fn encode(reserved: u32) -> [u8; RECORD] {
    let mut r = [0u8; RECORD];
    r[0..4].copy_from_slice(&MAGIC.to_le_bytes());
    r[4..8].copy_from_slice(&reserved.to_le_bytes());
    r[8..12].copy_from_slice(&(!reserved).to_le_bytes());
    let crc = CRC.checksum(&r[0..12]);
    r[12..16].copy_from_slice(&crc.to_le_bytes());
    r
}

fn decode(r: &[u8; RECORD]) -> Option<u32> {
    let word = |i: usize| u32::from_le_bytes([r[i], r[i + 1], r[i + 2], r[i + 3]]);
    let reserved = word(4);
    (word(0) == MAGIC && word(8) == !reserved && word(12) == CRC.checksum(&r[0..12]))
        .then_some(reserved)
}

/// What a region holds: its largest reservation (0 in an erased region), the sector that
/// record is in, and that sector's first free record.
struct Log {
    reserved: u32,
    active: u32,
    free: Option<u32>,
}

impl Log {
    fn scan<F: NorFlash>(flash: &mut F, sector: u32) -> Result<Log, CounterError<F::Error>> {
        // The largest reservation, where it is, and each sector's first free record.
        let mut best: Option<(u32, u32)> = None;
        let mut free = [None, None];
        for (s, free) in free.iter_mut().enumerate() {
            let base = s as u32 * sector;
            let mut at = 0;
            while at < sector {
                let mut r = [0u8; RECORD];
                block_on(flash.read(base + at, &mut r)).map_err(CounterError::Flash)?;
                if r.iter().all(|b| *b == 0xFF) {
                    free.get_or_insert(at);
                } else if let Some(v) = decode(&r) {
                    // A record after a free one cannot be: the log is written in order.
                    *free = None;
                    if best.is_none_or(|(b, _)| v > b) {
                        best = Some((v, s as u32));
                    }
                } else {
                    *free = None;
                }
                at += RECORD as u32;
            }
        }
        let (reserved, active) = best.unwrap_or((0, 0));
        Ok(Log {
            reserved,
            active,
            free: free.get(active as usize).copied().flatten(),
        })
    }
}

impl<F: NorFlash> FrameCounter<F> {
    /// Opens the counter of a region of exactly two erase sectors (a fresh, erased region
    /// starts at 0), reserving [`STEP`] counters per write. A plain function, each flash
    /// access run to completion in place (`embassy_futures::block_on`: a board's `NorFlash`
    /// completes when first polled), so no state machine of it is in a board's image.
    pub fn open(flash: F) -> Result<Self, CounterError<F::Error>> {
        Self::open_with_step(flash, STEP)
    }

    /// As [`FrameCounter::open`], with `step` counters per write.
    pub fn open_with_step(mut flash: F, step: u32) -> Result<Self, CounterError<F::Error>> {
        let sector = F::ERASE_SIZE;
        let fits = sector.is_multiple_of(RECORD)
            && RECORD.is_multiple_of(F::WRITE_SIZE)
            && RECORD.is_multiple_of(F::READ_SIZE)
            && flash.capacity() >= 2 * sector
            && step > 0;
        if !fits {
            return Err(CounterError::Geometry);
        }
        let sector = u32::try_from(sector).map_err(|_| CounterError::Geometry)?;
        let log = Log::scan(&mut flash, sector)?;
        Ok(FrameCounter {
            flash,
            sector,
            step,
            full: step,
            active: log.active,
            free: log.free,
            holds: log.active,
            next: log.reserved,
            reserved: log.reserved,
        })
    }

    /// Reads the region again, for a counter whose region another process may write too
    /// (the tool's counter file, shared by every run of the tool with one key file, each
    /// taking it in turn under a lock): a larger reservation than this counter's own,
    /// written by the other, moves this counter up to it (the next counter handed out is
    /// above every one the other may hand out until it reads the region again), and the
    /// log goes on where it now ends. A region that lost this counter's reservation (set
    /// back, or replaced) gets it written again first. Called before each
    /// [`FrameCounter::next`] under that lock, the counters of all the processes are
    /// strictly increasing in the order they are handed out.
    ///
    /// What a jump skips is what the other reserved and did not hand out: so once it has
    /// caught up, a counter reserves one counter a write, then twice as many with each
    /// write, back to its step. Processes that take turns frame by frame then skip none
    /// (a write each); one left alone again soon writes once per step. A node's region is
    /// its own: it never calls this.
    pub fn catch_up(&mut self) -> Result<(), CounterError<F::Error>> {
        let log = Log::scan(&mut self.flash, self.sector)?;
        (self.active, self.free, self.holds) = (log.active, log.free, log.active);
        if log.reserved > self.reserved {
            (self.next, self.reserved) = (log.reserved, log.reserved);
            self.step = 1;
        } else if log.reserved < self.reserved {
            self.persist(self.reserved)?;
        }
        Ok(())
    }

    /// A counter never handed out before, by this node, whatever power cuts came between
    /// (a plain function, as [`FrameCounter::open`]).
    // Not an iterator: the counter ends in an error, and a flash failure is not the end.
    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> Result<u32, CounterError<F::Error>> {
        if self.next >= self.reserved {
            let reserve = (self.next.checked_add(self.step))
                .filter(|r| *r <= LIMIT)
                .ok_or(CounterError::Exhausted)?;
            self.persist(reserve)?;
            self.reserved = reserve;
            self.step = self.step.saturating_mul(2).min(self.full);
        }
        let n = self.next;
        self.next += 1;
        Ok(n)
    }

    /// Moves the counter to `flash`, a region that stands for its own (the tool's counter
    /// file replaced under a running run, by a rename: a restored copy), and catches up
    /// with it ([`FrameCounter::catch_up`]): a larger reservation there moves the counter
    /// up, a smaller one gets the counter's own written first. Gives the old region back.
    pub fn move_to(&mut self, flash: F) -> Result<F, CounterError<F::Error>> {
        let old = core::mem::replace(&mut self.flash, flash);
        self.catch_up()?;
        Ok(old)
    }

    /// The counter `next` will hand out.
    pub fn peek(&self) -> u32 {
        self.next
    }

    /// Gives the flash back.
    pub fn into_inner(self) -> F {
        self.flash
    }

    fn persist(&mut self, reserve: u32) -> Result<(), CounterError<F::Error>> {
        let at = match self.free {
            Some(at) => at,
            None => {
                // The active sector is full: the log goes on in the other one, unless the
                // reservation the node relies on is there (every write since the switch
                // failed): then the active sector, which holds none, starts over.
                let next = if self.holds == self.active {
                    1 - self.active
                } else {
                    self.active
                };
                let base = next * self.sector;
                block_on(self.flash.erase(base, base + self.sector))
                    .map_err(CounterError::Flash)?;
                self.active = next;
                0
            }
        };
        let base = self.active * self.sector;
        // Past this point the slot is used, written whole or torn.
        let after = at + RECORD as u32;
        self.free = (after < self.sector).then_some(after);
        block_on(self.flash.write(base + at, &encode(reserve))).map_err(CounterError::Flash)?;
        self.holds = self.active;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;
    use crate::slots::RamFlash;

    type Flash = RamFlash<2048>;

    fn open(flash: Flash, step: u32) -> FrameCounter<Flash> {
        FrameCounter::open_with_step(flash, step).expect("opens")
    }

    #[test]
    fn a_record_is_its_bytes() {
        assert_eq!(
            encode(0x0000_0400),
            [
                0x17, 0x00, 0x0C, 0xFC, 0x00, 0x04, 0x00, 0x00, 0xFF, 0xFB, 0xFF, 0xFF, 0x30, 0xBE,
                0x56, 0x44
            ]
        );
        assert_eq!(decode(&encode(0x0000_0400)), Some(0x400));
        assert_eq!(decode(&[0xFF; RECORD]), None);
    }

    #[test]
    fn counters_resume_above_everything_handed_out_after_a_reboot() {
        let mut c = open(Flash::new(), 8);
        let first: Vec<u32> = (0..20).map(|_| c.next().unwrap()).collect();
        assert_eq!(first, (0..20).collect::<Vec<_>>());
        let mut c = open(c.into_inner(), 8);
        // 20 handed out, 24 reserved: the reboot skips to the reservation.
        assert_eq!(c.next(), Ok(24));
    }

    #[test]
    fn a_power_cut_at_any_write_never_hands_out_a_counter_twice() {
        // Runs long enough to fill and switch sectors several times (64 records each).
        for cut in 1..300 {
            let mut flash = Flash::new();
            flash.fail_after = Some(cut);
            let mut c = open(flash, 4);
            let mut seen = Vec::new();
            while let Ok(n) = c.next() {
                seen.push(n);
            }
            let mut flash = c.into_inner();
            flash.fail_after = None;
            let mut c = open(flash, 4);
            for _ in 0..600 {
                seen.push(c.next().expect("powered"));
            }
            assert!(
                seen.windows(2).all(|w| w[0] < w[1]),
                "cut at write {cut}: {seen:?}"
            );
        }
    }

    /// A flash whose writes fail (writing nothing) while `failing`; erases work.
    struct Failing {
        flash: Flash,
        failing: bool,
    }

    impl embedded_storage_async::nor_flash::ErrorType for Failing {
        type Error = crate::slots::PowerCut;
    }

    impl embedded_storage_async::nor_flash::ReadNorFlash for Failing {
        const READ_SIZE: usize = 1;
        async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
            self.flash.read(offset, bytes).await
        }
        fn capacity(&self) -> usize {
            self.flash.capacity()
        }
    }

    impl NorFlash for Failing {
        const WRITE_SIZE: usize = 4;
        const ERASE_SIZE: usize = 1024;
        async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
            self.flash.erase(from, to).await
        }
        async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
            match self.failing {
                true => Err(crate::slots::PowerCut),
                false => self.flash.write(offset, bytes).await,
            }
        }
    }

    /// The flash fails every write for a while just after the log filled a sector (each
    /// failed write uses a slot of the other one), then the power is cut. Before, once
    /// the failed writes had filled that sector too, the next one erased the full sector,
    /// which held the only reservation: the node booted at counter 0 and handed out again
    /// every counter it had used (the nonces of its secured frames). Now the sector of
    /// failed writes starts over, and the node resumes above everything handed out.
    #[test]
    fn writes_failing_for_a_while_then_a_power_cut_never_hand_out_a_counter_twice() {
        for failed in [1, 63, 64, 65, 127, 128, 129, 200] {
            let flash = Failing {
                flash: Flash::new(),
                failing: false,
            };
            let mut c = FrameCounter::open_with_step(flash, 4).expect("opens");
            // Sector 0 full: 64 records of 4 counters.
            let handed: Vec<u32> = (0..64 * 4).map(|_| c.next().expect("next")).collect();
            assert_eq!(handed.last(), Some(&255));
            c.flash.failing = true;
            for _ in 0..failed {
                assert!(matches!(c.next(), Err(CounterError::Flash(_))));
            }
            // The power is cut; the next boot's flash works.
            let mut flash = c.into_inner();
            flash.failing = false;
            let mut c = FrameCounter::open_with_step(flash, 4).expect("opens");
            assert_eq!(c.next(), Ok(256), "after {failed} failed writes");
        }
    }

    #[test]
    fn the_log_alternates_sectors_and_survives_many_reboots() {
        let mut flash = Flash::new();
        let mut last = None;
        for _ in 0..500 {
            let mut c = open(flash, 3);
            for _ in 0..5 {
                let n = c.next().expect("next");
                assert!(last.is_none_or(|l| n > l));
                last = Some(n);
            }
            flash = c.into_inner();
        }
        // 500 boots of 2 writes each: each sector of 64 records was erased several times.
        assert!(last.is_some_and(|l| l >= 500 * 5));
    }

    #[test]
    fn garbage_in_the_region_is_skipped_and_the_counter_is_used_up_before_it_wraps() {
        let mut flash = Flash::new();
        flash.bytes[..64].fill(0x00);
        flash.bytes[64..80].copy_from_slice(&encode(u32::MAX - 2));
        let mut c = open(flash, 8);
        assert_eq!(c.next(), Err(CounterError::Exhausted));
        let mut c = open(Flash::new(), 1);
        assert_eq!(c.next(), Ok(0));
    }

    /// A counter with bit 31 set would make the node's every challenge read as a boot's
    /// greeting (its nonce is the counter; `restart::GREETING` is bit 31): the last
    /// counter handed out is 2^31 - 1, and a region that reserved past it (an older
    /// image's) hands out none.
    #[test]
    fn the_counter_stops_below_bit_31() {
        let mut flash = Flash::new();
        flash.bytes[..16].copy_from_slice(&encode(LIMIT - 2));
        let mut c = open(flash, 1);
        assert_eq!(c.next(), Ok(LIMIT - 2));
        assert_eq!(c.next(), Ok(LIMIT - 1));
        assert_eq!(c.next(), Err(CounterError::Exhausted));
        let mut flash = Flash::new();
        flash.bytes[..16].copy_from_slice(&encode(LIMIT + 5));
        assert_eq!(open(flash, 1).next(), Err(CounterError::Exhausted));
    }

    /// Two counters over one region, taking turns (the tool's runs with one key file, each
    /// calling `catch_up` before `next` under the counter file's lock): every counter is
    /// above every one handed out before it, by either, and a counter alone in its region
    /// goes on in its reservation.
    #[test]
    fn counters_sharing_a_region_catch_up_with_each_other() {
        let mut a = open(Flash::new(), 8);
        let mut handed = Vec::new();
        let mut turn = |c: &mut FrameCounter<Flash>, flash: Flash| {
            c.flash = flash;
            c.catch_up().expect("reads");
            let n = c.next().expect("next");
            handed.push(n);
            core::mem::take(&mut c.flash)
        };
        let flash = core::mem::take(&mut a.flash);
        let flash = turn(&mut a, flash);
        let flash = turn(&mut a, flash);
        // The second run opens while the first runs: both read reservation 8.
        let mut b = open(flash.clone(), 8);
        let flash = turn(&mut b, flash);
        let flash = turn(&mut a, flash);
        let flash = turn(&mut a, flash);
        let flash = turn(&mut b, flash);
        let flash = turn(&mut b, flash);
        let flash = turn(&mut a, flash);
        // Each jump to the other's reservation, then a write a counter: two that take
        // turns skip nothing.
        assert_eq!(handed, [0, 1, 8, 16, 17, 19, 20, 22]);
        // A third run, later, starts above all of them.
        let mut c = open(flash, 8);
        assert_eq!(c.next(), Ok(23));
        // Left alone, the jumped counter's writes grow back to a step each.
        let mut writes = 0;
        let mut flash = core::mem::take(&mut a.flash);
        let mut last = a.reserved;
        for _ in 0..64 {
            a.flash = flash;
            a.catch_up().expect("reads");
            a.next().expect("next");
            writes += usize::from(a.reserved != last);
            last = a.reserved;
            flash = core::mem::take(&mut a.flash);
        }
        assert_eq!((writes, a.step), (10, 8));
    }

    /// A region set back under a counter (a copy of the file from before put back) gets
    /// the counter's reservation again before it hands out another: a power cut then does
    /// not start below what it handed out.
    #[test]
    fn a_region_set_back_gets_the_reservation_written_again() {
        let mut c = open(Flash::new(), 8);
        let old = c.flash.clone();
        assert_eq!(c.next(), Ok(0));
        c.flash = old;
        c.catch_up().expect("reads");
        assert_eq!(c.next(), Ok(1));
        assert_eq!(open(c.into_inner(), 8).next(), Ok(8));
    }

    /// A counter moved to a region that holds less (a file replaced under it by an older
    /// copy) writes its own reservation there first: a later open starts above everything
    /// it handed out. Moved to one that holds more, it goes on above that.
    #[test]
    fn a_counter_moved_to_another_region_keeps_above_both() {
        let mut c = open(Flash::new(), 8);
        let older = c.flash.clone();
        for n in 0..12 {
            assert_eq!(c.next(), Ok(n));
        }
        c.move_to(older).expect("moves");
        assert_eq!(c.next(), Ok(12));
        assert_eq!(open(c.flash.clone(), 8).next(), Ok(16));
        let mut ahead = open(Flash::new(), 8);
        ahead.flash.bytes[..16].copy_from_slice(&encode(40));
        c.move_to(ahead.into_inner()).expect("moves");
        assert_eq!(c.next(), Ok(40));
    }

    #[test]
    fn a_region_that_is_not_two_sectors_is_refused() {
        let r = FrameCounter::open(RamFlash::<1024>::new());
        assert!(matches!(r, Err(CounterError::Geometry)));
    }
}
