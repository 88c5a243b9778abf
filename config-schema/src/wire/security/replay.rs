//! The receiver's replay guard: per (sender, key index) the last frame counter accepted.
//!
//! Fixed capacity, no allocation. A frame is accepted only with a counter above the last
//! one accepted from that sender under that key; the first frame of a pair is accepted at
//! any counter, so across a reboot the table must be restored (persisted, or re-seeded
//! through an authenticated exchange) before frames are taken: that is the node's design,
//! not this table's. A full table never evicts (forgetting a pair would let its old frames
//! in again): it refuses new pairs with [`ReplayError::Full`] until
//! [`ReplayGuard::retire_key`] drops a key no longer in use.
//!
//! Call [`ReplayGuard::check_and_accept`] only with a counter whose frame passed its MIC:
//! an unauthenticated counter would let a forger push a sender's counter up and lock it out.

use core::fmt;

use heapless::vec::VecView;

/// One (sender, key index) pair and the last counter accepted from it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Entry {
    /// The sender's short address.
    pub sender: u16,
    /// The key index of the key its frames used (0 for key identifier mode 0).
    pub key_index: u8,
    /// The highest frame counter accepted.
    pub last: u32,
}

/// Why a frame counter is refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReplayError {
    /// Not above `last`, the counter accepted before from this sender under this key.
    Replayed { last: u32 },
    /// A new (sender, key index) pair, and the table is full.
    Full,
}

impl fmt::Display for ReplayError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReplayError::Replayed { last } => {
                write!(f, "replayed frame counter (last accepted {last})")
            }
            ReplayError::Full => f.write_str("replay table full"),
        }
    }
}

impl core::error::Error for ReplayError {}

/// Up to `N` (sender, key index) pairs with their last accepted frame counter.
#[derive(Debug, Clone, Default)]
pub struct ReplayGuard<const N: usize> {
    entries: heapless::Vec<Entry, N>,
}

impl<const N: usize> ReplayGuard<N> {
    /// An empty table.
    pub const fn new() -> Self {
        ReplayGuard {
            entries: heapless::Vec::new(),
        }
    }

    /// Whether `counter` would be accepted, without recording it.
    pub fn check(&self, sender: u16, key_index: u8, counter: u32) -> Result<(), ReplayError> {
        check(self.entries.as_view(), sender, key_index, counter)
    }

    /// Accepts `counter` if it is above the last one from (sender, key index), and records
    /// it; a refused counter changes nothing.
    pub fn check_and_accept(
        &mut self,
        sender: u16,
        key_index: u8,
        counter: u32,
    ) -> Result<(), ReplayError> {
        check_and_accept(self.entries.as_mut_view(), sender, key_index, counter)
    }

    /// The last counter accepted from (sender, key index).
    pub fn last(&self, sender: u16, key_index: u8) -> Option<u32> {
        find(self.entries.as_view(), sender, key_index).map(|e| e.last)
    }

    /// Drops every pair of `key_index` (a key no longer accepted), making room.
    pub fn retire_key(&mut self, key_index: u8) {
        self.entries.retain(|e| e.key_index != key_index);
    }

    /// The pairs, in the order they were first accepted (what a node persists).
    pub fn iter(&self) -> impl Iterator<Item = &Entry> {
        self.entries.iter()
    }

    /// How many pairs are recorded.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether no pair is recorded.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

// The work of every `ReplayGuard<N>`, on its entries whatever `N`: one copy in an image
// with tables of several sizes (a node has one per PAN).

fn find(entries: &VecView<Entry>, sender: u16, key_index: u8) -> Option<&Entry> {
    entries
        .iter()
        .find(|e| e.sender == sender && e.key_index == key_index)
}

fn check(
    entries: &VecView<Entry>,
    sender: u16,
    key_index: u8,
    counter: u32,
) -> Result<(), ReplayError> {
    match find(entries, sender, key_index) {
        Some(e) if counter <= e.last => Err(ReplayError::Replayed { last: e.last }),
        Some(_) => Ok(()),
        None if entries.is_full() => Err(ReplayError::Full),
        None => Ok(()),
    }
}

fn check_and_accept(
    entries: &mut VecView<Entry>,
    sender: u16,
    key_index: u8,
    counter: u32,
) -> Result<(), ReplayError> {
    let found = entries
        .iter_mut()
        .find(|e| e.sender == sender && e.key_index == key_index);
    match found {
        Some(e) if counter <= e.last => Err(ReplayError::Replayed { last: e.last }),
        Some(e) => {
            e.last = counter;
            Ok(())
        }
        None => entries
            .push(Entry {
                sender,
                key_index,
                last: counter,
            })
            .map_err(|_| ReplayError::Full),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_counter_must_rise_per_sender_and_key() {
        let mut g = ReplayGuard::<4>::new();
        assert_eq!(g.check_and_accept(0x0001, 1, 0), Ok(()));
        assert_eq!(
            g.check_and_accept(0x0001, 1, 0),
            Err(ReplayError::Replayed { last: 0 })
        );
        assert_eq!(g.check_and_accept(0x0001, 1, 7), Ok(()));
        assert_eq!(
            g.check_and_accept(0x0001, 1, 6),
            Err(ReplayError::Replayed { last: 7 })
        );
        assert_eq!(
            g.check_and_accept(0x0001, 1, 7),
            Err(ReplayError::Replayed { last: 7 })
        );
        // Another key index and another sender have their own counters.
        assert_eq!(g.check_and_accept(0x0001, 2, 3), Ok(()));
        assert_eq!(g.check_and_accept(0x0002, 1, 3), Ok(()));
        assert_eq!(g.last(0x0001, 1), Some(7));
        assert_eq!(g.last(0x0001, 2), Some(3));
        assert_eq!(g.last(0x0003, 1), None);
        assert_eq!(g.check_and_accept(0x0001, 1, u32::MAX - 1), Ok(()));
        assert_eq!(
            g.check_and_accept(0x0001, 1, 8),
            Err(ReplayError::Replayed { last: u32::MAX - 1 })
        );
    }

    #[test]
    fn check_alone_records_nothing() {
        let mut g = ReplayGuard::<2>::new();
        assert_eq!(g.check(0x0001, 1, 5), Ok(()));
        assert!(g.is_empty());
        g.check_and_accept(0x0001, 1, 5).unwrap();
        assert_eq!(
            g.check(0x0001, 1, 5),
            Err(ReplayError::Replayed { last: 5 })
        );
        assert_eq!(g.check(0x0001, 1, 6), Ok(()));
        assert_eq!(g.last(0x0001, 1), Some(5));
    }

    #[test]
    fn a_full_table_refuses_new_pairs_and_never_forgets_old_ones() {
        let mut g = ReplayGuard::<2>::new();
        g.check_and_accept(0x0001, 1, 10).unwrap();
        g.check_and_accept(0x0002, 1, 20).unwrap();
        assert_eq!(g.check(0x0003, 1, 0), Err(ReplayError::Full));
        assert_eq!(g.check_and_accept(0x0003, 1, 0), Err(ReplayError::Full));
        assert_eq!(g.len(), 2);
        // The known pairs keep working, and keep refusing replays.
        assert_eq!(g.check_and_accept(0x0001, 1, 11), Ok(()));
        assert_eq!(
            g.check_and_accept(0x0002, 1, 20),
            Err(ReplayError::Replayed { last: 20 })
        );
        // Retiring key 1 makes room; key 2's pairs stay.
        g.check_and_accept(0x0001, 1, 12).unwrap();
        g.retire_key(1);
        assert!(g.is_empty());
        assert_eq!(g.check_and_accept(0x0003, 2, 0), Ok(()));
        g.check_and_accept(0x0004, 1, 0).unwrap();
        g.retire_key(1);
        let left: heapless::Vec<Entry, 2> = g.iter().copied().collect();
        assert_eq!(
            left.as_slice(),
            &[Entry {
                sender: 0x0003,
                key_index: 2,
                last: 0
            }]
        );
    }

    mod props {
        use super::super::*;
        use proptest::prelude::*;

        proptest! {
            /// Against a model: accepted exactly when the counter is above every counter
            /// accepted before from that pair; the table never holds more than N pairs.
            #[test]
            fn accepts_exactly_the_rising_counters(
                frames in proptest::collection::vec((0u16..4, 0u8..3, 0u32..50), 0..200),
            ) {
                let mut g = ReplayGuard::<8>::new();
                let mut model: [[Option<u32>; 3]; 4] = [[None; 3]; 4];
                let mut pairs = 0;
                for (sender, key, counter) in frames {
                    let slot = &mut model[usize::from(sender)][usize::from(key)];
                    let expect = match *slot {
                        Some(last) if counter <= last => Err(ReplayError::Replayed { last }),
                        None if pairs == 8 => Err(ReplayError::Full),
                        _ => Ok(()),
                    };
                    prop_assert_eq!(g.check_and_accept(sender, key, counter), expect);
                    if expect.is_ok() {
                        if slot.is_none() {
                            pairs += 1;
                        }
                        *slot = Some(counter);
                    }
                    prop_assert!(g.len() <= 8);
                }
            }
        }
    }
}
