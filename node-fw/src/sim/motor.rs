//! Plants with a continuous position: a motor on two outputs (clockwise / counter-clockwise)
//! moving a carriage over its stroke at a constant speed, with end sensors, and what it
//! moves with it (the belt the pusher pushes). Positions are in micrometres from home; a
//! speed in mm/s is exactly µm per ms of virtual time.

/// Which way a motor runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Run {
    Stopped,
    /// Clockwise: toward the end (position grows).
    Clockwise,
    /// Counter-clockwise: toward home.
    CounterClockwise,
}

impl Run {
    /// The run two outputs command: one of them high runs that way; none, or both (a
    /// conflict), stops the motor.
    pub fn of(cw: bool, ccw: bool) -> Run {
        match (cw, ccw) {
            (true, false) => Run::Clockwise,
            (false, true) => Run::CounterClockwise,
            _ => Run::Stopped,
        }
    }
}

/// A motor drive (the paper's pusher): `cw_out` high runs it clockwise (toward the end),
/// `ccw_out` high counter-clockwise (home); both low stops it at once where it is, both
/// high is a conflict (traced) and stops it. It starts at home, its home sensor high at
/// t = 0 (read at power-up, no edge). Leaving an end drops that sensor at once; reaching an
/// end raises it and the motor stalls there (still commanded, not moving) until told the
/// other way.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Motor {
    /// Its name in step strings (`PUSHER+` when it starts clockwise, `PUSHER-`
    /// counter-clockwise).
    pub name: String,
    /// Node index.
    pub node: usize,
    /// Output index that runs it clockwise.
    pub cw_out: u8,
    /// Output index that runs it counter-clockwise.
    pub ccw_out: u8,
    /// Input index of the sensor at home (position 0), if wired.
    pub home_in: Option<u8>,
    /// Input index of the sensor at the end (position `stroke_mm`), if wired.
    pub end_in: Option<u8>,
    /// Length of the stroke, mm.
    pub stroke_mm: u32,
    /// Speed while it runs, mm/s (both ways; at least 1).
    pub speed_mm_s: u32,
}

/// Something a motor moves with it (the belt the pusher pushes): always at the motor's
/// position, with its own sensors at home and at the end, on its own node.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Driven {
    pub name: String,
    /// Node index of its sensors.
    pub node: usize,
    /// The plant index of the [`Motor`] that moves it.
    pub motor: usize,
    pub home_in: Option<u8>,
    pub end_in: Option<u8>,
}

/// A maintained contact on a node input (a fault contact): it keeps the level it is set to
/// ([`World::set_switch`](super::World::set_switch)); low at t = 0.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Switch {
    pub name: String,
    /// Node index.
    pub node: usize,
    /// Input index.
    pub input: u8,
}

/// Where a motor's carriage is and how it runs: position `at_um` at time `since_ms`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Carriage {
    pub at_um: u64,
    pub since_ms: u64,
    pub run: Run,
}

impl Default for Carriage {
    fn default() -> Carriage {
        Carriage {
            at_um: 0,
            since_ms: 0,
            run: Run::Stopped,
        }
    }
}

/// What a change of run did to the carriage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Change {
    /// It left an end (`Some(true)`: the end, `Some(false)`: home): that sensor opens.
    pub left: Option<bool>,
    /// When it reaches the end it now runs to, if it moves.
    pub arrive_ms: Option<u64>,
}

impl Motor {
    fn stroke_um(&self) -> u64 {
        u64::from(self.stroke_mm) * 1000
    }

    fn speed(&self) -> u64 {
        u64::from(self.speed_mm_s.max(1))
    }

    /// The sensor at the end (`true`) or at home, if wired.
    pub fn sensor(&self, end: bool) -> Option<u8> {
        if end {
            self.end_in
        } else {
            self.home_in
        }
    }

    /// The carriage's position at `now_ms` (on its way, or where it stands).
    pub fn position_um(&self, c: &Carriage, now_ms: u64) -> u64 {
        let moved = now_ms
            .saturating_sub(c.since_ms)
            .saturating_mul(self.speed());
        match c.run {
            Run::Stopped => c.at_um,
            Run::Clockwise => c.at_um.saturating_add(moved).min(self.stroke_um()),
            Run::CounterClockwise => c.at_um.saturating_sub(moved),
        }
    }

    /// Whether the carriage stands at an end: `Some(true)` the end, `Some(false)` home.
    pub fn at_end(&self, at_um: u64) -> Option<bool> {
        if at_um == 0 {
            Some(false)
        } else if at_um >= self.stroke_um() {
            Some(true)
        } else {
            None
        }
    }

    /// Runs the carriage `run` from `now_ms` on: it stops where it is, or sets off toward
    /// an end (leaving the one it stands at, if any).
    pub fn change(&self, c: &mut Carriage, run: Run, now_ms: u64) -> Change {
        let at = self.position_um(c, now_ms);
        let before = self.at_end(at);
        *c = Carriage {
            at_um: at,
            since_ms: now_ms,
            run,
        };
        let target = match run {
            Run::Stopped => None,
            Run::Clockwise => Some((true, self.stroke_um().saturating_sub(at))),
            Run::CounterClockwise => Some((false, at)),
        };
        match target {
            Some((end, left)) if left > 0 => Change {
                left: before.filter(|b| *b != end),
                arrive_ms: Some(now_ms.saturating_add(left.div_ceil(self.speed()))),
            },
            _ => Change {
                left: None,
                arrive_ms: None,
            },
        }
    }

    /// The carriage reaches the end it runs to at `now_ms`: it stands there (still
    /// commanded). Returns which end (`true`: the end), or `None` if it was not running.
    pub fn arrive(&self, c: &mut Carriage, now_ms: u64) -> Option<bool> {
        let end = match c.run {
            Run::Stopped => return None,
            Run::Clockwise => true,
            Run::CounterClockwise => false,
        };
        c.at_um = if end { self.stroke_um() } else { 0 };
        c.since_ms = now_ms;
        Some(end)
    }
}

#[cfg(test)]
mod tests {
    use super::{Carriage, Change, Motor, Run};

    fn pusher() -> Motor {
        Motor {
            name: "PUSHER".into(),
            node: 0,
            cw_out: 0,
            ccw_out: 1,
            home_in: Some(0),
            end_in: Some(1),
            stroke_mm: 400,
            speed_mm_s: 200,
        }
    }

    #[test]
    fn two_outputs_run_it_one_way_or_stop_it() {
        assert_eq!(Run::of(true, false), Run::Clockwise);
        assert_eq!(Run::of(false, true), Run::CounterClockwise);
        assert_eq!(Run::of(false, false), Run::Stopped);
        assert_eq!(Run::of(true, true), Run::Stopped);
    }

    #[test]
    fn the_position_grows_at_its_speed_stops_where_told_and_returns() {
        let m = pusher();
        let mut c = Carriage::default();
        // 400 mm at 200 mm/s: the end 2000 ms later; leaving home opens its sensor.
        let out = m.change(&mut c, Run::Clockwise, 100);
        assert_eq!(
            out,
            Change {
                left: Some(false),
                arrive_ms: Some(2100)
            }
        );
        assert_eq!(m.position_um(&c, 600), 100_000);
        // Stopped at 700 ms: 120 mm, and it stays there.
        let stop = m.change(&mut c, Run::Stopped, 700);
        assert_eq!(
            stop,
            Change {
                left: None,
                arrive_ms: None
            }
        );
        assert_eq!(m.position_um(&c, 5000), 120_000);
        assert_eq!(m.at_end(120_000), None);
        // Back home: 120 mm take 600 ms; no sensor opens mid-way.
        let back = m.change(&mut c, Run::CounterClockwise, 1000);
        assert_eq!(
            back,
            Change {
                left: None,
                arrive_ms: Some(1600)
            }
        );
        assert_eq!(m.arrive(&mut c, 1600), Some(false));
        assert_eq!(m.position_um(&c, 9000), 0);
        assert_eq!(m.at_end(0), Some(false));
    }

    #[test]
    fn toward_the_end_it_stands_at_nothing_moves() {
        let m = pusher();
        let mut c = Carriage::default();
        let none = Change {
            left: None,
            arrive_ms: None,
        };
        assert_eq!(m.change(&mut c, Run::CounterClockwise, 10), none);
        assert_eq!(m.position_um(&c, 500), 0);
        m.change(&mut c, Run::Clockwise, 0);
        assert_eq!(m.arrive(&mut c, 2000), Some(true));
        assert_eq!(m.position_um(&c, 3000), 400_000);
        assert_eq!(m.change(&mut c, Run::Clockwise, 3000), none);
        // From the end, back: the end sensor opens.
        assert_eq!(
            m.change(&mut c, Run::CounterClockwise, 3000),
            Change {
                left: Some(true),
                arrive_ms: Some(5000)
            }
        );
    }
}
