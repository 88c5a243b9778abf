//! Where the verifier keeps a rod: a [`Pos`] of the plant model, or stopped between its
//! switches, which only a homing exploration starts from (a power cut or a fault mid-stroke
//! with a bistable valve that neither solenoid drives: the rod stays where it is).

use node_fw::cylinder::{Motion, Position as Pos};
use robot_compiler::interlock;

/// A rod's place in the model's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) enum Place {
    Rod(Pos),
    /// At rest between home and end: both switches open, nothing arrives until a command.
    Between,
}

/// Where a rod may be when the machine powers up unhomed (before its valve acts).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rest {
    Home,
    End,
    Between,
}

impl Rest {
    pub const ALL: [Rest; 3] = [Rest::Home, Rest::End, Rest::Between];

    pub fn name(self) -> &'static str {
        match self {
            Rest::Home => "home",
            Rest::End => "end",
            Rest::Between => "between",
        }
    }

    /// The rod's place once its valve acts on it: `drive` is what the valve's start levels
    /// command (`None`: nothing, a bistable valve with no solenoid energised).
    pub(super) fn place(self, drive: Option<bool>) -> Place {
        match (self, drive) {
            (Rest::Home, Some(true)) | (Rest::Between, Some(true)) => Place::Rod(Pos::Extending),
            (Rest::End, Some(false)) | (Rest::Between, Some(false)) => Place::Rod(Pos::Retracting),
            (Rest::Home, _) => Place::Rod(Pos::Home),
            (Rest::End, _) => Place::Rod(Pos::End),
            (Rest::Between, None) => Place::Between,
        }
    }
}

/// A rod's interlock bit (`ACT.home`, `ACT.end`, `ACT.extending`, `ACT.retracting`), as
/// the verifier and `sim` read interlocks.
pub(crate) fn rod_mask(p: Pos) -> u8 {
    match p {
        Pos::Home => interlock::HOME,
        Pos::End => interlock::END,
        Pos::Extending => interlock::EXTENDING,
        Pos::Retracting => interlock::RETRACTING,
    }
}

impl Place {
    /// The interlock bits (`ACT.home` ...): none between the switches at rest.
    pub(super) fn mask(self) -> u8 {
        match self {
            Place::Rod(p) => rod_mask(p),
            Place::Between => 0,
        }
    }

    pub(super) fn moving(self) -> bool {
        matches!(self, Place::Rod(p) if p.moving())
    }

    /// A valve command ([`Pos::command`]); from between, the rod starts without leaving a
    /// switch.
    pub(super) fn command(&mut self, extend: bool) -> Motion {
        match self {
            Place::Rod(p) => p.command(extend),
            Place::Between => {
                *self = Place::Rod(if extend {
                    Pos::Extending
                } else {
                    Pos::Retracting
                });
                Motion::Reversed
            }
        }
    }

    /// [`Pos::finish_travel`]; nothing from between.
    pub(super) fn finish_travel(&mut self) -> Option<bool> {
        match self {
            Place::Rod(p) => p.finish_travel(),
            Place::Between => None,
        }
    }

    /// The sensor levels (home, end).
    pub(super) fn sensors(self) -> (bool, bool) {
        match self {
            Place::Rod(p) => p.sensors(),
            Place::Between => (false, false),
        }
    }

    /// `home`, `end`, `extending`, `retracting`, `between`.
    pub(super) fn name(self) -> &'static str {
        match self {
            Place::Rod(Pos::Home) => "home",
            Place::Rod(Pos::End) => "end",
            Place::Rod(Pos::Extending) => "extending",
            Place::Rod(Pos::Retracting) => "retracting",
            Place::Between => "between",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_valve_moves_a_rod_at_rest_unless_it_already_is_there() {
        assert_eq!(Rest::Home.place(None), Place::Rod(Pos::Home));
        assert_eq!(Rest::Home.place(Some(false)), Place::Rod(Pos::Home));
        assert_eq!(Rest::Home.place(Some(true)), Place::Rod(Pos::Extending));
        assert_eq!(Rest::End.place(Some(true)), Place::Rod(Pos::End));
        assert_eq!(Rest::End.place(Some(false)), Place::Rod(Pos::Retracting));
        assert_eq!(Rest::Between.place(None), Place::Between);
        assert_eq!(Rest::Between.place(Some(true)), Place::Rod(Pos::Extending));
        assert_eq!(
            Rest::Between.place(Some(false)),
            Place::Rod(Pos::Retracting)
        );
    }

    #[test]
    fn a_rod_between_its_switches_starts_on_a_command_and_arrives() {
        let mut p = Place::Between;
        assert_eq!(p.mask(), 0);
        assert!(!p.moving());
        assert_eq!(p.sensors(), (false, false));
        assert_eq!(p.finish_travel(), None);
        assert_eq!(p.command(false), Motion::Reversed);
        assert_eq!(p, Place::Rod(Pos::Retracting));
        assert_eq!(p.finish_travel(), Some(false));
        assert_eq!(p.name(), "home");
    }
}
