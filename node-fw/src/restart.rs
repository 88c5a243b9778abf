//! A peer's restart, told and heard (docs/radio-protocol.md, "A peer's restart").
//!
//! A node that boots with its table has started its charts over: its peers' charts may be
//! waiting, in the middle of a cycle or of homing, for an event it will now never send.
//! So it tells them, with a greeting: a `Challenge` whose nonce has [`GREETING`] set. On
//! a secured robot that is its handshake's challenge (the nonce's other bits the frame's
//! counter, or a retry's the first greeting's: `PeerSecurity::challenge`; answered as any
//! challenge); on a robot without link keys a challenge in clear
//! (no answer: [`Greetings`] sends it [`GREETINGS`] times, a copy making up for a loss).
//! A peer takes the first copy it hears of one restart ([`Heard::first`]); a node under
//! way then faults (`config_schema::alarm::FAULT_PEER_RESTART`) instead of stalling, and
//! one at rest carries on.

use config_schema::limits::MAX_PEERS;
use config_schema::Table;

use crate::peer_security::{GREET_EVERY_MS, GREET_TRIES};

/// Bit 31 of a `Challenge`'s nonce: the sender booted (its greeting). A secured nonce is
/// otherwise a challenge frame's counter (below 2^31: `crate::frame_counter::LIMIT`; that
/// frame's, or a repeated one's, `crate::peer_security::PeerSecurity::challenge`); a
/// nonce in clear without it is an epoch asked for ([`crate::link::Receiver::ask`]).
pub const GREETING: u32 = 1 << 31;

/// A secured greeting's nonce when the sender's charts started over by a `Reset` while
/// under way, not by a boot: exactly this (a boot's greeting is its frame's counter with
/// [`GREETING`], which only the one counter 2^30 would make this). The sender kept its
/// links' receivers and its floors, so the peer numbers nothing again (the `renumber` of
/// `crate::peer_security::Verdict::Answer`) and only learns that the sender's charts
/// started over.
/// (A greeting in clear is `GREETING` alone: nothing is numbered again in clear.)
pub const RESET_GREETING: u32 = GREETING | 1 << 30;

/// How many greetings a node without link keys sends each peer after it boots, one per
/// [`GREET_EVERY_MS`] (a secured node greets as often, until answered).
pub const GREETINGS: u8 = GREET_TRIES;

/// Within this many ms of booting, a node has greeted its peers for the last time
/// (secured or not): a tool that sends a machine under way waits until every node has
/// been up this long, so that no copy of a greeting reaches a node already under way.
pub const GREETED_WITHIN_MS: u64 = GREETINGS as u64 * GREET_EVERY_MS;

/// Copies of a greeting heard within this many ms of the first are the same restart.
pub const SAME_RESTART_MS: u32 = 2 * GREETED_WITHIN_MS as u32;

/// Whether a node running `table`, its charts in states `current` (not faulted), is under
/// way: a chart of it is neither in a resting state (its idle one or another) nor in its
/// initial state (a cycle or homing under way). Such a node waits for its peers' events.
pub fn under_way(table: &Table, current: &[u8]) -> bool {
    (table.charts.iter().zip(current)).any(|(c, &at)| !c.rests_in(at) && at != c.initial)
}

/// The greetings a node without link keys still has to send after its boot.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Greetings {
    left: u8,
    next: u64,
}

impl Greetings {
    /// The node booted (or was reset under way) at `now`: greet from now on.
    pub fn boot(&mut self, now: u64) {
        *self = Greetings {
            left: GREETINGS,
            next: now,
        };
    }

    /// Whether a round of greetings is due at `now` (then counted as sent).
    pub fn due(&mut self, now: u64) -> bool {
        if self.left == 0 || now < self.next {
            return false;
        }
        self.left -= 1;
        self.next = now + GREET_EVERY_MS;
        true
    }

    /// When the next round is due, if any is.
    pub fn deadline(&self) -> Option<u64> {
        (self.left > 0).then_some(self.next)
    }
}

/// The restarts heard, per peer (by index into the table's peers): when the last one was
/// first heard (ms, wrapping).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Heard {
    /// Bit i: a restart of peer i was heard.
    heard: u8,
    at: [u32; MAX_PEERS],
}

impl Heard {
    /// A greeting of peer `peer` at `now`: whether it tells a restart not heard yet (not
    /// a copy or a retry of one heard within [`SAME_RESTART_MS`]).
    pub fn first(&mut self, peer: usize, now: u64) -> bool {
        let (Some(at), Some(bit)) = (self.at.get_mut(peer), 1u8.checked_shl(peer as u32)) else {
            return false;
        };
        let now = now as u32;
        if self.heard & bit != 0 && now.wrapping_sub(*at) < SAME_RESTART_MS {
            return false;
        }
        self.heard |= bit;
        *at = now;
        true
    }

    /// A new table runs: its peers are numbered anew.
    pub fn forget(&mut self) {
        self.heard = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_boot_sends_five_rounds_of_greetings_a_hundred_ms_apart() {
        let mut g = Greetings::default();
        assert_eq!((g.deadline(), g.due(0)), (None, false));
        g.boot(1_000);
        let due: heapless::Vec<u64, 8> = (1_000..2_000).filter(|&t| g.due(t)).collect();
        assert_eq!(due, [1_000, 1_100, 1_200, 1_300, 1_400]);
        assert_eq!(g.deadline(), None);
    }

    #[test]
    fn copies_of_one_restart_are_heard_once_and_a_later_restart_again() {
        let mut h = Heard::default();
        assert!(h.first(2, 10_000));
        assert!(!h.first(2, 10_000), "a duplicated copy");
        assert!(!h.first(2, 10_400), "the last retry");
        assert!(!h.first(2, 10_999));
        assert!(h.first(1, 10_500), "another peer's");
        assert!(h.first(2, 11_000), "the peer booted again");
        assert!(!h.first(MAX_PEERS, 20_000), "no such peer");
        h.forget();
        assert!(h.first(2, 11_001), "a new table's peer");
    }

    #[test]
    fn the_clock_wrapping_past_u32_does_not_hide_a_restart() {
        let mut h = Heard::default();
        let t = u64::from(u32::MAX) - 100;
        assert!(h.first(0, t));
        assert!(!h.first(0, t + 200), "across the wrap, the same restart");
        assert!(h.first(0, t + 1_100));
    }

    /// The greeting in clear as it goes on the air (docs/radio-protocol.md's table).
    #[test]
    fn a_greeting_in_clear_is_these_bytes() {
        use config_schema::wire::mac::{self, Header, MAX_PAYLOAD, MAX_PSDU};
        use config_schema::wire::msg::Message;
        let mut payload = [0u8; MAX_PAYLOAD];
        let n = Message::Challenge { nonce: GREETING }
            .emit(&mut payload)
            .unwrap();
        let header = Header {
            seq: 7,
            pan_id: 0x4242,
            dst: 0x0002,
            src: 0x0001,
            ack_request: false,
            secured: false,
        };
        let mut psdu = [0u8; MAX_PSDU];
        let len = mac::emit_data(&header, &payload[..n], &mut psdu).unwrap();
        let mpdu = &psdu[..len - 2]; // the FCS is the radio's
        assert_eq!(
            mpdu,
            [
                0x41, 0x98, 0x07, 0x42, 0x42, 0x02, 0x00, 0x01, 0x00, 0x0A, 0x80, 0x80, 0x80, 0x80,
                0x08
            ]
        );
    }

    /// A chart in a resting state besides its idle one (a mode kept between cycles) is
    /// not under way; in any other state but idle and initial it is.
    #[test]
    fn a_chart_in_one_of_its_resting_states_is_not_under_way() {
        use config_schema::Table;
        let mut t = Table::empty("r");
        t.push_chart(0, 0, &[&[], &[], &[], &[]], &[]).unwrap();
        t.charts[0].idle = 1;
        t.charts[0].rests = 1 << 2;
        let under_way: heapless::Vec<bool, 4> = (0..4).map(|s| under_way(&t, &[s])).collect();
        assert_eq!(under_way, [false, false, false, true]);
    }

    #[test]
    fn a_greeting_is_bit_31_and_the_greetings_end_within_half_a_second() {
        assert_eq!(GREETING, 0x8000_0000);
        assert_eq!((GREETED_WITHIN_MS, SAME_RESTART_MS), (500, 1_000));
    }
}
