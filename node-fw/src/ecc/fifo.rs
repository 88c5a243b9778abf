//! The interpreter's event FIFO: a ring of `EVENT_QUEUE` event ids.

use config_schema::limits::EVENT_QUEUE;
use config_schema::EventId;

const MASK: usize = EVENT_QUEUE - 1;
const _: () = assert!(EVENT_QUEUE.is_power_of_two() && EVENT_QUEUE < 256);

/// Pending events, oldest first.
#[derive(Debug, Clone)]
pub(super) struct Fifo {
    events: [EventId; EVENT_QUEUE],
    head: u8,
    len: u8,
}

/// The FIFO holds `EVENT_QUEUE` events already.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Full;

impl Fifo {
    pub(super) const fn new() -> Fifo {
        Fifo {
            events: [0; EVENT_QUEUE],
            head: 0,
            len: 0,
        }
    }

    pub(super) fn clear(&mut self) {
        self.len = 0;
    }

    /// Whether no event is pending.
    #[inline(always)]
    pub(super) fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Appends `event`, unless the FIFO is full.
    #[inline(always)]
    pub(super) fn push(&mut self, event: EventId) -> Result<(), Full> {
        let len = usize::from(self.len);
        if len >= EVENT_QUEUE {
            return Err(Full);
        }
        self.events[(usize::from(self.head) + len) & MASK] = event;
        self.len += 1;
        Ok(())
    }

    /// Takes the oldest event.
    #[inline(always)]
    pub(super) fn pop(&mut self) -> Option<EventId> {
        if self.len == 0 {
            return None;
        }
        let event = self.events[usize::from(self.head) & MASK];
        self.head = ((usize::from(self.head) + 1) & MASK) as u8;
        self.len -= 1;
        Some(event)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn events_come_out_in_order_across_the_wrap_and_a_full_fifo_refuses() {
        let mut f = Fifo::new();
        for round in 0..3u8 {
            for e in 0..EVENT_QUEUE as u8 {
                assert_eq!(f.push(round * 20 + e), Ok(()));
            }
            assert_eq!(f.push(99), Err(Full));
            for e in 0..5 {
                assert_eq!(f.pop(), Some(round * 20 + e));
            }
            for e in 5..EVENT_QUEUE as u8 {
                assert_eq!(f.pop(), Some(round * 20 + e));
            }
            assert_eq!(f.pop(), None);
            // Leave the head somewhere else for the next round.
            f.push(0).unwrap();
            f.pop();
        }
        f.push(1).unwrap();
        f.clear();
        assert_eq!(f.pop(), None);
    }
}
