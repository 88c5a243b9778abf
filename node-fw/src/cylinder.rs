//! The pneumatic plant's rules, once: how a cylinder's valve turns output changes into a
//! command, where the rod rests at power-up, which sensor a motion opens or closes, and how
//! long a stroke takes. Pure (`no_std`, no allocation); used by the virtual-time simulator
//! (`crate::sim`, feature `std`), the verifier's state exploration (a [`Position`] is a
//! small `Copy` + `Hash` state) and `config-tool`'s real-time plant.
//!
//! Pins are whatever the caller numbers them by: table output / input indices in the
//! simulator and the verifier, board pins in the real-time plant.

/// How a cylinder's valve is driven.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Valve {
    /// A bistable 5/2 valve with two solenoids (the paper's `Bistabilni_C`): the last
    /// energised decides, de-energising does nothing (both off: the rod keeps going).
    Double { extend: u8, retract: u8 },
    /// A monostable valve with one solenoid: energised extends, released retracts (spring).
    Single { valve: u8 },
}

/// A cylinder's wiring: its valve's outputs and its sensors (limit switches or position
/// sensors, each optional) at home (retracted) and at the end (extended).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Cylinder {
    pub valve: Valve,
    pub home: Option<u8>,
    pub end: Option<u8>,
}

/// Where a rod is: the cylinder's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Position {
    /// Retracted, at the home switch.
    Home,
    /// Extended, at the end switch.
    End,
    /// Moving out.
    Extending,
    /// Moving back.
    Retracting,
}

/// What a valve command did to the rod.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motion {
    /// Toward where it is or is already going: nothing (no motion, no switch edge, no step).
    Nothing,
    /// Left a switch (`from_end`: the end switch, else home): that sensor opens at once.
    Left { from_end: bool },
    /// Turned round mid-travel (no switch changes).
    Reversed,
}

/// What the valve of one cylinder was told in one engine step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// Drive the rod out (`true`) or back.
    Drive(bool),
    /// Both solenoids of a bistable valve energised in one step: the spool does not move.
    Conflict,
}

/// The output changes of one engine step seen by one cylinder's valve (see
/// [`Cylinder::output`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Valves {
    extend_rose: bool,
    retract_rose: bool,
    level: Option<bool>,
}

impl Valves {
    /// What the step's output changes command: the solenoid that rose (both: a conflict), or
    /// a monostable valve's last level; `None` if nothing (a solenoid released).
    pub fn command(self) -> Option<Command> {
        match (self.extend_rose, self.retract_rose, self.level) {
            (true, true, _) => Some(Command::Conflict),
            (true, false, _) => Some(Command::Drive(true)),
            (false, true, _) => Some(Command::Drive(false)),
            (false, false, level) => level.map(Command::Drive),
        }
    }
}

impl Cylinder {
    /// Whether the valve is bistable (two solenoids).
    pub fn double(&self) -> bool {
        matches!(self.valve, Valve::Double { .. })
    }

    /// Records in `step` that output `output` changed to `level`; `false` if the output is
    /// not one of this cylinder's valve.
    pub fn output(&self, step: &mut Valves, output: u8, level: bool) -> bool {
        match self.valve {
            Valve::Double { extend, .. } if extend == output => step.extend_rose |= level,
            Valve::Double { retract, .. } if retract == output => step.retract_rose |= level,
            Valve::Single { valve } if valve == output => step.level = Some(level),
            _ => return false,
        }
        true
    }

    /// The sensor at the end (`true`) or at home, if wired.
    pub fn sensor(&self, end: bool) -> Option<u8> {
        if end {
            self.end
        } else {
            self.home
        }
    }

    /// Power-up with the node's (safe) output levels `outputs` (bit i = output i): the rod
    /// rests out if its monostable valve is energised, else home, and the sensor there (if
    /// wired) is closed. The node reads it as a level (no edge, no event).
    pub fn power_up(&self, outputs: u16) -> (Position, Option<u8>) {
        let out = match self.valve {
            Valve::Single { valve } => outputs & (1 << (valve & 15)) != 0,
            Valve::Double { .. } => false,
        };
        let at = Position::from_command(out);
        (at, self.sensor(out))
    }
}

impl Position {
    /// Where a command `extend` (or retract) leads when it completes.
    pub fn from_command(extend: bool) -> Position {
        if extend {
            Position::End
        } else {
            Position::Home
        }
    }

    /// Whether the rod is on its way (a motion that will arrive).
    pub fn moving(self) -> bool {
        matches!(self, Position::Extending | Position::Retracting)
    }

    /// A valve command `extend` (or retract): the rod leaves a switch, turns round
    /// mid-travel (at once, no deceleration), or, toward where it is or is going, does
    /// nothing.
    pub fn command(&mut self, extend: bool) -> Motion {
        let (next, motion) = match (*self, extend) {
            (Position::Home, false) | (Position::End, true) => return Motion::Nothing,
            (Position::Extending, true) | (Position::Retracting, false) => return Motion::Nothing,
            (Position::Home, true) => (Position::Extending, Motion::Left { from_end: false }),
            (Position::End, false) => (Position::Retracting, Motion::Left { from_end: true }),
            (Position::Extending, false) => (Position::Retracting, Motion::Reversed),
            (Position::Retracting, true) => (Position::Extending, Motion::Reversed),
        };
        *self = next;
        motion
    }

    /// The rod reaches the end it was moving to: `Some(true)` at the end, `Some(false)` at
    /// home (its sensor closes); `None` if it was not moving.
    pub fn finish_travel(&mut self) -> Option<bool> {
        let end = match *self {
            Position::Extending => true,
            Position::Retracting => false,
            Position::Home | Position::End => return None,
        };
        *self = Position::from_command(end);
        Some(end)
    }

    /// The sensor levels (home, end) for this position: closed at rest there, both open
    /// while moving.
    pub fn sensors(self) -> (bool, bool) {
        (self == Position::Home, self == Position::End)
    }
}

/// The valve commands of one engine step of a node: `outputs` are the step's output changes
/// in order, `cylinders` the node's cylinders (an index of the caller's, the wiring). Per
/// cylinder that a change reached, in the order first reached, what its valve was told.
#[cfg(feature = "std")]
pub fn commands(
    cylinders: &[(usize, Cylinder)],
    outputs: impl IntoIterator<Item = (u8, bool)>,
) -> std::vec::Vec<(usize, Command)> {
    let mut steps: std::vec::Vec<(usize, Valves)> = std::vec::Vec::new();
    for (output, level) in outputs {
        for &(i, cylinder) in cylinders {
            let at = steps.iter().position(|s| s.0 == i);
            let mut step = at
                .and_then(|k| steps.get(k))
                .map_or_else(Valves::default, |s| s.1);
            if cylinder.output(&mut step, output, level) {
                match at.and_then(|k| steps.get_mut(k)) {
                    Some(s) => s.1 = step,
                    None => steps.push((i, step)),
                }
            }
        }
    }
    steps
        .into_iter()
        .filter_map(|(i, s)| Some((i, s.command()?)))
        .collect()
}

/// Stroke positions are fractions of `FULL`.
pub const FULL: u64 = 1_000_000;

/// A rod on a clock: its [`Position`] with the timing of a motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rod {
    Home,
    End,
    /// Moving from stroke position `from` at `t0` to the end (or home) at `arrive`.
    Moving {
        to_end: bool,
        from: u64,
        t0: u64,
        arrive: u64,
    },
}

/// What a valve command did to a [`Rod`], with the arrival time of a motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Toward where it is or is going: nothing.
    Nothing,
    /// Left a switch (`from_end`: the end switch, else home) and arrives at `arrive`.
    Left { from_end: bool, arrive: u64 },
    /// Turned round mid-travel; arrives at `arrive`.
    Reversed { arrive: u64 },
}

impl Rod {
    pub fn position(self) -> Position {
        match self {
            Rod::Home => Position::Home,
            Rod::End => Position::End,
            Rod::Moving { to_end: true, .. } => Position::Extending,
            Rod::Moving { to_end: false, .. } => Position::Retracting,
        }
    }

    /// Stroke position (0 = home, `FULL` = end) at time `now`.
    pub fn stroke(self, now: u64) -> u64 {
        match self {
            Rod::Home => 0,
            Rod::End => FULL,
            Rod::Moving {
                to_end,
                from,
                t0,
                arrive,
            } => {
                let target = if to_end { FULL } else { 0 };
                if now >= arrive || arrive <= t0 {
                    return target;
                }
                let frac = u128::from(now.saturating_sub(t0));
                let span = u128::from(arrive - t0);
                let dist = u128::from(target.abs_diff(from));
                let moved = (dist * frac / span) as u64;
                if to_end {
                    from + moved
                } else {
                    from.saturating_sub(moved)
                }
            }
        }
    }

    /// Applies a valve command at `now` (`extend`: toward the end), by the rules of
    /// [`Position::command`]. `ms` = (extend, retract) full-stroke times: a motion covers
    /// the rest of the stroke (after a reversal, the part already covered) at the speed of
    /// its direction.
    pub fn command(&mut self, now: u64, extend: bool, ms: (u64, u64)) -> Outcome {
        let motion = self.position().command(extend);
        if motion == Motion::Nothing {
            return Outcome::Nothing;
        }
        let pos = self.stroke(now);
        let target = if extend { FULL } else { 0 };
        let full_ms = if extend { ms.0 } else { ms.1 };
        let dist = u128::from(target.abs_diff(pos));
        let time = (dist * u128::from(full_ms)).div_ceil(u128::from(FULL)) as u64;
        let arrive = now + time;
        *self = Rod::Moving {
            to_end: extend,
            from: pos,
            t0: now,
            arrive,
        };
        match motion {
            Motion::Left { from_end } => Outcome::Left { from_end, arrive },
            _ => Outcome::Reversed { arrive },
        }
    }

    /// The rod reached the end it was moving to ([`Position::finish_travel`]).
    pub fn arrive(&mut self) -> Option<bool> {
        let end = self.position().finish_travel()?;
        *self = if end { Rod::End } else { Rod::Home };
        Some(end)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DA: Cylinder = Cylinder {
        valve: Valve::Double {
            extend: 0,
            retract: 1,
        },
        home: Some(2),
        end: Some(3),
    };
    const SA: Cylinder = Cylinder {
        valve: Valve::Single { valve: 4 },
        home: None,
        end: Some(5),
    };

    fn step(c: &Cylinder, changes: &[(u8, bool)]) -> Option<Command> {
        let mut v = Valves::default();
        for &(o, level) in changes {
            c.output(&mut v, o, level);
        }
        v.command()
    }

    #[test]
    fn a_bistable_valve_follows_the_solenoid_that_rose() {
        assert_eq!(step(&DA, &[(0, true)]), Some(Command::Drive(true)));
        assert_eq!(step(&DA, &[(1, true)]), Some(Command::Drive(false)));
        assert_eq!(step(&DA, &[(0, false)]), None);
        assert_eq!(
            step(&DA, &[(0, false), (1, true)]),
            Some(Command::Drive(false))
        );
        assert_eq!(step(&DA, &[(0, true), (1, true)]), Some(Command::Conflict));
        assert!(!DA.output(&mut Valves::default(), 4, true));
    }

    #[test]
    fn a_monostable_valve_follows_its_last_level() {
        assert_eq!(step(&SA, &[(4, true)]), Some(Command::Drive(true)));
        assert_eq!(step(&SA, &[(4, false)]), Some(Command::Drive(false)));
        assert_eq!(
            step(&SA, &[(4, true), (4, false)]),
            Some(Command::Drive(false))
        );
        assert_eq!(step(&SA, &[(0, true)]), None);
    }

    #[test]
    fn power_up_rests_where_the_safe_outputs_hold_the_rod() {
        assert_eq!(DA.power_up(0b1), (Position::Home, Some(2)));
        assert_eq!(SA.power_up(0), (Position::Home, None));
        assert_eq!(SA.power_up(1 << 4), (Position::End, Some(5)));
    }

    #[test]
    fn motions_leave_reverse_or_do_nothing_and_arrive() {
        let mut p = Position::Home;
        assert_eq!(p.command(false), Motion::Nothing);
        assert_eq!(p.command(true), Motion::Left { from_end: false });
        assert_eq!(p.sensors(), (false, false));
        assert_eq!(p.command(true), Motion::Nothing);
        assert_eq!(p.command(false), Motion::Reversed);
        assert_eq!(p, Position::Retracting);
        assert_eq!(p.finish_travel(), Some(false));
        assert_eq!(p.sensors(), (true, false));
        assert_eq!(p.finish_travel(), None);
        let mut p = Position::End;
        assert_eq!(p.command(false), Motion::Left { from_end: true });
    }

    #[test]
    fn command_toward_held_position_does_nothing() {
        let mut rod = Rod::Home;
        assert_eq!(rod.command(5, false, (300, 200)), Outcome::Nothing);
        assert_eq!(rod, Rod::Home);
        let mut rod = Rod::End;
        assert_eq!(rod.command(5, true, (300, 200)), Outcome::Nothing);
        assert_eq!(rod, Rod::End);
    }

    #[test]
    fn command_in_the_direction_of_motion_does_nothing() {
        let mut rod = Rod::Home;
        assert_eq!(
            rod.command(0, true, (300, 200)),
            Outcome::Left {
                from_end: false,
                arrive: 300
            }
        );
        let before = rod;
        assert_eq!(rod.command(100, true, (300, 200)), Outcome::Nothing);
        assert_eq!(rod, before);
    }

    #[test]
    fn reversal_goes_back_over_the_covered_stroke_at_the_new_speed() {
        let mut rod = Rod::Home;
        rod.command(0, true, (300, 600));
        // A third of the stroke out after 100 ms; back at 600 ms per stroke: 200 ms.
        assert_eq!(rod.stroke(100), FULL / 3);
        assert_eq!(
            rod.command(100, false, (300, 600)),
            Outcome::Reversed { arrive: 300 }
        );
        assert_eq!(rod.position(), Position::Retracting);
        assert_eq!(rod.arrive(), Some(false));
        assert_eq!(rod, Rod::Home);
    }
}
