//! A node's link epochs, and the boot counter that reserves them in flash.
//!
//! Every numbering of the node's event links takes the next epoch (a table installed, an
//! operator's reset of stuck links, a link numbered again for a peer that booted), and a
//! subscriber takes only epochs newer than the last it took (serial order on `u16`), so a
//! boot must start above every epoch of the boots before it. A board with a persisted boot
//! counter starts boot `n` at `n x 256` ([`of_boot`]): the epochs of one boot are
//! reserved by the count the next boot will read. A boot that takes more than that keeps
//! its reservation ahead of it: once fewer than [`RESERVE_AHEAD`] reserved epochs are
//! left, the node asks its board to count one more boot ([`Epochs::wants_count`], the
//! runtime's `FlashRequest::CountBoot`), which moves the next boot's first epoch 256
//! further. A node that stays up while a peer reboots hundreds of times then starts its
//! next boot above them all. Without a counter (the clock's epochs of a test node) nothing
//! is reserved. See `docs/node-runtime.md`, "Epoch".

use crate::link::before;

/// Epochs a boot count reserves.
pub const PER_BOOT: u32 = 256;

/// The boot counter is asked to count once fewer than this many reserved epochs are left:
/// half a boot's, so a flash that fails a count is asked again at each of the many
/// epochs still reserved.
pub const RESERVE_AHEAD: u16 = 128;

/// The first epoch of boot number `boots` of a board's persisted boot counter.
pub fn of_boot(boots: u32) -> u16 {
    boots.wrapping_mul(PER_BOOT) as u16
}

/// The node's newest epoch and how far its boot counter reserves epochs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Epochs {
    current: u16,
    /// The first epoch this boot may not take: the next boot's first as the counter
    /// stands (`None`: nothing persists, nothing is reserved).
    end: Option<u16>,
    /// The epoch at which the counter was last asked: not asked again before the node
    /// takes another epoch (a count that failed, or that moved nothing).
    asked: Option<u16>,
}

impl Epochs {
    /// Epochs from `first` on, none reserved (no persisted boot counter: the clock's).
    pub fn unreserved(first: u16) -> Self {
        Epochs {
            current: first,
            end: None,
            asked: None,
        }
    }

    /// Boot number `boots` of a persisted boot counter: epochs from [`of_boot`]`(boots)`,
    /// up to the next boot's first.
    pub fn counted(boots: u32) -> Self {
        Epochs {
            current: of_boot(boots),
            end: Some(of_boot(boots.wrapping_add(1))),
            asked: None,
        }
    }

    /// Boot number `boots` of a persisted boot counter that failed to persist it (the next
    /// boot would read the same count): epochs from [`of_boot`]`(boots)`, none reserved, so
    /// the counter is asked at once ([`Epochs::wants_count`]).
    pub fn uncounted(boots: u32) -> Self {
        let first = of_boot(boots);
        Epochs {
            current: first,
            end: Some(first),
            asked: None,
        }
    }

    /// The newest epoch taken (the boot's first before any).
    pub fn current(&self) -> u16 {
        self.current
    }

    /// The first epoch the reservation does not cover (`None`: nothing is reserved).
    pub fn end(&self) -> Option<u16> {
        self.end
    }

    /// Takes the next epoch.
    pub fn take(&mut self) -> u16 {
        self.current = self.current.wrapping_add(1);
        self.current
    }

    /// Takes the next epoch, or `wanted` if that is newer (serial order).
    pub fn take_at_least(&mut self, wanted: u16) -> u16 {
        let next = self.current.wrapping_add(1);
        self.current = if before(next, wanted) { wanted } else { next };
        self.current
    }

    /// Whether the board should count a boot now: fewer than [`RESERVE_AHEAD`] reserved
    /// epochs are left (or none: the boot took more than it had), and the counter was not
    /// asked at this epoch already.
    pub fn wants_count(&self) -> bool {
        let Some(end) = self.end else {
            return false;
        };
        let left = end.wrapping_sub(self.current) as i16;
        left <= RESERVE_AHEAD as i16 && self.asked != Some(self.current)
    }

    /// The board counted a boot: `boots` is the count it persisted (the next boot reads
    /// it and counts one more), `None`: the count failed. A count that moved the
    /// reservation on is asked for again at once if it still does not cover the epochs
    /// taken (a jump to a wanted epoch, or counts that failed for a while, may need
    /// several); one that failed, or moved nothing, is asked again once another epoch is
    /// taken.
    #[inline(never)]
    pub fn counted_boot(&mut self, boots: Option<u32>) {
        let end = boots.map(|boots| of_boot(boots.wrapping_add(1)));
        // Only ever further. A counter that went back (restored, or corrupted) leaves
        // the reservation where it was: the next boot may then start below it, which
        // this boot cannot mend in the epochs it has.
        match end.filter(|&end| self.end.is_none_or(|e| before(e, end))) {
            Some(end) => self.end = Some(end),
            None => self.asked = Some(self.current),
        }
    }
}

impl From<u16> for Epochs {
    fn from(first: u16) -> Self {
        Epochs::unreserved(first)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boot_n_starts_at_n_times_256_and_reserves_up_to_the_next() {
        let e = Epochs::counted(3);
        assert_eq!((e.current(), e.end()), (768, Some(1024)));
        assert_eq!(of_boot(256), 0, "wraps with the u16 (serial order)");
        let e = Epochs::counted(255);
        assert_eq!((e.current(), e.end()), (65_280, Some(0)));
    }

    #[test]
    fn a_boot_whose_count_was_not_persisted_asks_for_one_at_once() {
        let mut e = Epochs::uncounted(4);
        assert_eq!((e.current(), e.end()), (1024, Some(1024)));
        assert!(e.wants_count());
        e.counted_boot(None);
        assert!(!e.wants_count(), "asked again at the next epoch");
        e.take();
        assert!(e.wants_count());
        // Persisted now: the count the boot read, reserving its epochs.
        e.counted_boot(Some(4));
        assert_eq!(e.end(), Some(1280));
        assert!(!e.wants_count());
    }

    #[test]
    fn the_counter_is_asked_once_half_the_reserved_epochs_are_taken() {
        let mut e = Epochs::counted(1);
        for _ in 0..127 {
            e.take();
            assert!(!e.wants_count(), "at {}", e.current());
        }
        assert_eq!(e.take(), 384);
        assert!(e.wants_count());
        e.counted_boot(Some(2));
        assert_eq!(e.end(), Some(768));
        assert!(!e.wants_count());
        // The next boot (count 3) starts at 768, above every epoch this one takes; asked
        // again at 640.
        for _ in 0..255 {
            e.take();
            assert!(!e.wants_count(), "at {}", e.current());
        }
        assert_eq!(e.take(), 640);
        assert!(e.wants_count());
    }

    #[test]
    fn a_failed_count_is_asked_again_at_the_next_epoch_not_before() {
        let mut e = Epochs::counted(1);
        for _ in 0..200 {
            e.take();
        }
        assert!(e.wants_count());
        e.counted_boot(None);
        assert!(!e.wants_count());
        e.take();
        assert!(e.wants_count());
        // Past the reservation (the flash kept failing): still asked, at every epoch.
        for _ in 0..100 {
            e.take();
        }
        assert_eq!(e.current(), 557);
        assert!(e.wants_count());
        e.counted_boot(Some(2));
        assert_eq!(e.end(), Some(768));
        assert!(!e.wants_count());
    }

    /// A jump to a wanted epoch far past the reservation (a peer's ask on a robot
    /// without link keys), or a flash that failed many counts: the counter is asked until
    /// the reservation covers the epochs taken again, each count moving it 256 on.
    #[test]
    fn counts_are_asked_for_until_the_reservation_covers_what_was_taken() {
        let mut e = Epochs::counted(1);
        let mut boots = 1;
        e.take();
        e.take_at_least(1000);
        let mut asked = 0;
        while e.wants_count() {
            boots += 1;
            asked += 1;
            e.counted_boot(Some(boots));
        }
        assert_eq!((asked, boots, e.end()), (3, 4, Some(1280)));
        assert!(before(e.current(), of_boot(boots + 1)));
        assert_eq!(of_boot(boots + 1) - e.current(), 280);
    }

    #[test]
    fn a_counter_that_went_back_reserves_nothing() {
        let mut e = Epochs::counted(5);
        for _ in 0..200 {
            e.take();
        }
        e.counted_boot(Some(1));
        assert_eq!(e.end(), Some(1536));
        assert!(!e.wants_count(), "asked at this epoch");
    }

    /// What a boot may do to its epochs.
    #[derive(Debug, Clone, Copy)]
    enum Step {
        /// A table, a reset, a renumbering.
        Take,
        /// A renumbering to an epoch asked for, this far past the newest.
        Wanted(u16),
        /// The flash starts or stops failing the counts.
        Flash(bool),
    }

    use proptest::prelude::*;

    proptest! {
        /// Whatever a boot takes (up to 16,000 epochs, jumps to asked-for epochs
        /// included) while its flash fails counts for a while, once the flash works and
        /// the node takes one more epoch, the next boot starts above every epoch this
        /// one took; and the counter was counted no more than the epochs taken need (its
        /// wear: one count per 256 epochs, and one at most for each stretch the flash
        /// failed or the node jumped).
        #[test]
        fn the_next_boot_starts_above_every_epoch_this_one_took(
            boots in 1u32..100_000,
            steps in proptest::collection::vec(
                prop_oneof![
                    8 => Just(Step::Take),
                    1 => (2u16..600).prop_map(Step::Wanted),
                    1 => proptest::bool::ANY.prop_map(Step::Flash),
                ],
                0..400,
            ),
            repeat in 1usize..40,
        ) {
            let mut e = Epochs::counted(boots);
            let first = e.current();
            let (mut counter, mut counts, mut working, mut stretches) = (boots, 0u32, true, 0u32);
            let count = |e: &mut Epochs, working: bool, counter: &mut u32, counts: &mut u32| {
                while e.wants_count() {
                    if working {
                        *counter += 1;
                        *counts += 1;
                    }
                    e.counted_boot(working.then_some(*counter));
                }
            };
            for step in steps.iter().cycle().take(steps.len() * repeat) {
                // Up to 16,000 epochs (serial order compares within 32,767).
                if e.current().wrapping_sub(first) >= 16_000 - 600 {
                    break;
                }
                match *step {
                    Step::Take => {
                        e.take();
                    }
                    Step::Wanted(ahead) => {
                        stretches += 1;
                        e.take_at_least(e.current().wrapping_add(ahead));
                    }
                    Step::Flash(w) => {
                        stretches += u32::from(working && !w);
                        working = w;
                    }
                }
                count(&mut e, working, &mut counter, &mut counts);
            }
            e.take();
            count(&mut e, true, &mut counter, &mut counts);
            let taken = u32::from(e.current().wrapping_sub(first));
            prop_assert!(
                before(e.current(), of_boot(counter + 1)),
                "took up to {}, the next boot starts at {}", e.current(), of_boot(counter + 1)
            );
            prop_assert!(counts <= taken / 256 + 1 + stretches, "{counts} counts for {taken}");
        }
    }

    #[test]
    fn a_wanted_epoch_is_taken_if_newer_and_unreserved_epochs_ask_nothing() {
        let mut e = Epochs::unreserved(65_530);
        assert_eq!(e.take_at_least(3), 3, "newer across the wrap");
        assert_eq!(e.take_at_least(1), 4, "older: the next");
        for _ in 0..1000 {
            e.take();
        }
        assert!(!e.wants_count());
    }
}
