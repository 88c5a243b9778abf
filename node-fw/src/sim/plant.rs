//! Plant models: what the nodes' pins are wired to in the simulated world.
//!
//! A plant is attached to pins of one node by index (`Table::outputs` / `Table::inputs`
//! indices of that node's table). Travel times are in milliseconds of virtual time.

/// A double-acting cylinder with a bistable 5/2 valve (the paper's `Bistabilni_C`).
///
/// - Valve: energising `extend_out` commands "extend", energising `retract_out` commands
///   "retract"; the last energised solenoid decides, de-energising does nothing (both off:
///   the rod keeps going). Both solenoids energised by one engine step is a conflict: the
///   spool does not move (traced as [`What::Conflict`](super::What::Conflict)).
/// - The rod starts at home, home switch high at t = 0 (read at power-up, no edge).
/// - Leaving a switch drops it at once; reaching the far end raises the other switch after
///   the travel time (`extend_ms` home -> end, `retract_ms` end -> home).
/// - A command toward the position the rod holds (or is already moving to) does nothing:
///   no motion, no switch edge, no step in the trace.
/// - A reversal mid-travel turns the rod round at once (no deceleration): it goes back over
///   the part of the stroke already covered at the speed of the new direction, and counts
///   as a new step (`VC-` after `VC+`). No switch changes at the reversal itself.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DoubleActing {
    /// The actuator's name in step strings ("VC" gives "VC+" / "VC-").
    pub name: String,
    /// Node index (into the world's node list).
    pub node: usize,
    /// Output index of the extend solenoid.
    pub extend_out: u8,
    /// Output index of the retract solenoid.
    pub retract_out: u8,
    /// Input index of the home (retracted) limit switch, if wired.
    pub home_in: Option<u8>,
    /// Input index of the end (extended) limit switch, if wired.
    pub end_in: Option<u8>,
    /// Full stroke time home -> end.
    pub extend_ms: u64,
    /// Full stroke time end -> home.
    pub retract_ms: u64,
}

/// A single-acting actuator with a monostable valve (the gripper): output high extends
/// (closes), low retracts (opens, by spring). A zero-length pulse (high and low again within
/// one engine step) does nothing. Reversal mid-travel as for [`DoubleActing`]. Usually it
/// has no sensors; an optional position sensor at either end behaves as a limit switch of a
/// [`DoubleActing`] (high at rest at home from t = 0, dropped on leaving, raised on
/// arrival).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SingleActing {
    /// The actuator's name in step strings.
    pub name: String,
    /// Node index.
    pub node: usize,
    /// Output index of the valve solenoid.
    pub out: u8,
    /// Input index of a position sensor at home (retracted), if wired.
    pub home_in: Option<u8>,
    /// Input index of a position sensor at the end (extended), if wired.
    pub end_in: Option<u8>,
    /// Full stroke time out (reported through [`Position`] and the sensors, if any).
    pub extend_ms: u64,
    /// Full stroke time back.
    pub retract_ms: u64,
}

/// A push button on a node input: a press is a pulse, high at once, low `press_ms` later.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Button {
    pub name: String,
    /// Node index.
    pub node: usize,
    /// Input index.
    pub input: u8,
    /// How long a press holds the input high.
    pub press_ms: u64,
}

impl Button {
    /// A button with a 50 ms press.
    pub fn new(name: &str, node: usize, input: u8) -> Button {
        Button {
            name: name.to_string(),
            node,
            input,
            press_ms: 50,
        }
    }
}

/// One plant model attached to a node.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Plant {
    DoubleActing(DoubleActing),
    SingleActing(SingleActing),
    Button(Button),
}

impl Plant {
    /// The plant's name.
    pub fn name(&self) -> &str {
        match self {
            Plant::DoubleActing(p) => &p.name,
            Plant::SingleActing(p) => &p.name,
            Plant::Button(p) => &p.name,
        }
    }

    /// The node it is attached to.
    pub fn node(&self) -> usize {
        match self {
            Plant::DoubleActing(p) => p.node,
            Plant::SingleActing(p) => p.node,
            Plant::Button(p) => p.node,
        }
    }

    /// The outputs it reads.
    pub fn outputs(&self) -> Vec<u8> {
        match self {
            Plant::DoubleActing(p) => vec![p.extend_out, p.retract_out],
            Plant::SingleActing(p) => vec![p.out],
            Plant::Button(_) => vec![],
        }
    }

    /// The inputs it drives.
    pub fn inputs(&self) -> Vec<u8> {
        match self {
            Plant::DoubleActing(p) => p.home_in.into_iter().chain(p.end_in).collect(),
            Plant::SingleActing(p) => p.home_in.into_iter().chain(p.end_in).collect(),
            Plant::Button(p) => vec![p.input],
        }
    }

    /// The node and the (home, end) switch inputs of an actuator.
    pub fn switches(&self) -> Option<(usize, Option<u8>, Option<u8>)> {
        match self {
            Plant::DoubleActing(p) => Some((p.node, p.home_in, p.end_in)),
            Plant::SingleActing(p) => Some((p.node, p.home_in, p.end_in)),
            Plant::Button(_) => None,
        }
    }

    /// Travel times (extend, retract) of an actuator.
    pub fn travel(&self) -> Option<(u64, u64)> {
        match self {
            Plant::DoubleActing(p) => Some((p.extend_ms, p.retract_ms)),
            Plant::SingleActing(p) => Some((p.extend_ms, p.retract_ms)),
            Plant::Button(_) => None,
        }
    }
}

impl From<DoubleActing> for Plant {
    fn from(p: DoubleActing) -> Plant {
        Plant::DoubleActing(p)
    }
}

impl From<SingleActing> for Plant {
    fn from(p: SingleActing) -> Plant {
        Plant::SingleActing(p)
    }
}

impl From<Button> for Plant {
    fn from(p: Button) -> Plant {
        Plant::Button(p)
    }
}

/// Where an actuator's rod is.
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

/// Stroke positions are fractions of `FULL`.
pub const FULL: u64 = 1_000_000;

/// The rod of an actuator.
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

/// What a valve command did to the rod.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Toward where it is or is going: nothing.
    Nothing,
    /// Left a switch (`from_end`: the end switch, else home) and arrives at `arrive`.
    Left { from_end: bool, arrive: u64 },
    /// Turned round mid-travel; arrives at `arrive`.
    Reversed { arrive: u64 },
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

    /// Applies a valve command at `now` (`extend`: toward the end). `ms` = (extend, retract)
    /// full-stroke times.
    pub fn command(&mut self, now: u64, extend: bool, ms: (u64, u64)) -> Outcome {
        let (holds, from_switch) = match *self {
            Rod::Home => (!extend, Some(false)),
            Rod::End => (extend, Some(true)),
            Rod::Moving { to_end, .. } => (to_end == extend, None),
        };
        if holds {
            // Toward the position it holds, or the way it is already going: nothing.
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
        match from_switch {
            Some(from_end) => Outcome::Left { from_end, arrive },
            None => Outcome::Reversed { arrive },
        }
    }

    /// The rod reached the end it was moving to.
    pub fn arrive(&mut self) -> Option<bool> {
        match *self {
            Rod::Moving { to_end, .. } => {
                *self = if to_end { Rod::End } else { Rod::Home };
                Some(to_end)
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
