//! The node's frame counter (`node_fw::frame_counter`): with a flash file, a
//! `FrameCounter` on the flash's own two pages, persisted in the file, so it resumes above
//! everything sent before a kill (a power cut); without one (nothing persists), in RAM from
//! the host clock, as the host board does without a flash file.
//!
//! The runtime asks for counters synchronously; the emulated flash's futures never pend
//! (memory and semihosting calls), so `FrameCounter::next` completes in place.

use node_fw::frame_counter::{CounterError, FrameCounter};

use crate::flash::{Backing, FlashError, QemuFlash};
use crate::semihosting;

/// Where a node's frame counters come from.
pub enum Counter {
    /// Persistent: the flash file's counter pages.
    Flash(FrameCounter<QemuFlash>),
    /// In RAM: the next counter (`None` once used up).
    Ram(Option<u32>),
}

/// Where the counter of a node without a flash file starts: 16 per second since
/// 2026-01-01 (as `node_fw::host::clock_counter_seed`), 0 without a clock. A restart
/// starts above what it sent before unless it sent more than 16 secured frames a second on
/// average.
fn clock_seed() -> u32 {
    const Y2026: u32 = 1_767_225_600;
    semihosting::time().map_or(0, |s| {
        s.saturating_sub(Y2026).saturating_mul(16).min(u32::MAX - 1)
    })
}

impl Counter {
    /// The counter of a flash backed by `backing`, its pages `pages`.
    pub fn open(pages: QemuFlash, backing: Backing) -> Result<Counter, CounterError<FlashError>> {
        match backing {
            Backing::File => FrameCounter::open(pages).map(Counter::Flash),
            Backing::Ram | Backing::FileRefused => Ok(Counter::Ram(Some(clock_seed()))),
        }
    }

    /// The counter the next secured frame gets.
    pub fn start(&self) -> Option<u32> {
        match self {
            Counter::Flash(c) => Some(c.peek()),
            Counter::Ram(next) => *next,
        }
    }

    /// Whether it survives a power cut.
    pub fn persistent(&self) -> bool {
        matches!(self, Counter::Flash(_))
    }

    /// A counter never handed out before (`None`: used up, or the flash failed).
    pub fn next(&mut self) -> Option<u32> {
        match self {
            Counter::Flash(c) => c.next().ok(),
            Counter::Ram(next) => {
                let n = (*next)?;
                *next = n.checked_add(1).filter(|n| *n != u32::MAX);
                Some(n)
            }
        }
    }
}
