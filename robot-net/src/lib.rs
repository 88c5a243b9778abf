//! A machine over the radio: the tool's radio on a medium ([`radio`]), OTA push and
//! reliable commands ([`push`]), homing ([`home`]), the real-time plant ([`live_plant`], its motors [`live_motor`]), a monitor that
//! reports faults and outputs as they happen ([`watch`]), the monitor's reading of
//! the air, secured frames opened ([`sniff`]), and the test bed that runs a
//! whole machine on this host ([`demo`]).

pub mod demo;
mod error;
pub mod home;
pub mod live_feed;
pub mod live_motor;
pub mod live_plant;
pub mod push;
pub mod radio;
pub mod release;
pub mod show;
pub mod sniff;
pub mod watch;

pub use error::NetError;

use std::time::{Duration, Instant};

/// A century: the end of a wait longer than an `Instant` can hold.
const CENTURY: Duration = Duration::from_secs(100 * 365 * 24 * 3600);

/// `from` + `wait`; past what an `Instant` holds (a `--wait` or `--seconds` of u64::MAX,
/// which panicked `Instant + Duration`), a century from `from`: no end a run reaches.
pub fn deadline(from: Instant, wait: Duration) -> Instant {
    from.checked_add(wait)
        .or_else(|| from.checked_add(CENTURY))
        .unwrap_or(from)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_deadline_past_the_clock_is_a_century_away() {
        let now = Instant::now();
        assert_eq!(
            deadline(now, Duration::from_secs(5)),
            now + Duration::from_secs(5)
        );
        assert_eq!(deadline(now, Duration::MAX), now + CENTURY);
        assert_eq!(deadline(now, Duration::from_secs(u64::MAX)), now + CENTURY);
    }
}
