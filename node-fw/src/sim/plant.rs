//! Plant models: what the nodes' pins are wired to in the simulated world.
//!
//! A plant is attached to pins of one node by index (`Table::outputs` / `Table::inputs`
//! indices of that node's table). Travel times are in milliseconds of virtual time. The
//! rules (valve, power-up, sensors, travel) are [`crate::cylinder`]'s.

use super::motor::{Driven, Motor, Switch};
use crate::cylinder::{Cylinder, Valve};

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
    /// Full stroke time out (reported through [`Position`](crate::cylinder::Position) and
    /// the sensors, if any).
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
    /// A motor with a continuous position ([`Motor`]).
    Motor(Motor),
    /// What a motor moves with it ([`Driven`]).
    Driven(Driven),
    /// A maintained contact ([`Switch`]).
    Switch(Switch),
}

impl Plant {
    /// The plant's name.
    pub fn name(&self) -> &str {
        match self {
            Plant::DoubleActing(p) => &p.name,
            Plant::SingleActing(p) => &p.name,
            Plant::Button(p) => &p.name,
            Plant::Motor(p) => &p.name,
            Plant::Driven(p) => &p.name,
            Plant::Switch(p) => &p.name,
        }
    }

    /// The node it is attached to.
    pub fn node(&self) -> usize {
        match self {
            Plant::DoubleActing(p) => p.node,
            Plant::SingleActing(p) => p.node,
            Plant::Button(p) => p.node,
            Plant::Motor(p) => p.node,
            Plant::Driven(p) => p.node,
            Plant::Switch(p) => p.node,
        }
    }

    /// The outputs it reads.
    pub fn outputs(&self) -> Vec<u8> {
        match self {
            Plant::DoubleActing(p) => vec![p.extend_out, p.retract_out],
            Plant::SingleActing(p) => vec![p.out],
            Plant::Motor(p) => vec![p.cw_out, p.ccw_out],
            Plant::Button(_) | Plant::Driven(_) | Plant::Switch(_) => vec![],
        }
    }

    /// The inputs it drives.
    pub fn inputs(&self) -> Vec<u8> {
        match self {
            Plant::DoubleActing(p) => p.home_in.into_iter().chain(p.end_in).collect(),
            Plant::SingleActing(p) => p.home_in.into_iter().chain(p.end_in).collect(),
            Plant::Button(p) => vec![p.input],
            Plant::Motor(p) => p.home_in.into_iter().chain(p.end_in).collect(),
            Plant::Driven(p) => p.home_in.into_iter().chain(p.end_in).collect(),
            Plant::Switch(p) => vec![p.input],
        }
    }

    /// The node and the (home, end) switch inputs of what moves (a cylinder, a motor, what
    /// a motor drives).
    pub fn switches(&self) -> Option<(usize, Option<u8>, Option<u8>)> {
        match self {
            Plant::DoubleActing(p) => Some((p.node, p.home_in, p.end_in)),
            Plant::SingleActing(p) => Some((p.node, p.home_in, p.end_in)),
            Plant::Motor(p) => Some((p.node, p.home_in, p.end_in)),
            Plant::Driven(p) => Some((p.node, p.home_in, p.end_in)),
            _ => None,
        }
    }

    /// An actuator's wiring, for the rules of [`crate::cylinder`].
    pub fn cylinder(&self) -> Option<Cylinder> {
        match self {
            Plant::DoubleActing(p) => Some(Cylinder {
                valve: Valve::Double {
                    extend: p.extend_out,
                    retract: p.retract_out,
                },
                home: p.home_in,
                end: p.end_in,
            }),
            Plant::SingleActing(p) => Some(Cylinder {
                valve: Valve::Single { valve: p.out },
                home: p.home_in,
                end: p.end_in,
            }),
            _ => None,
        }
    }

    /// Travel times (extend, retract) of an actuator.
    pub fn travel(&self) -> Option<(u64, u64)> {
        match self {
            Plant::DoubleActing(p) => Some((p.extend_ms, p.retract_ms)),
            Plant::SingleActing(p) => Some((p.extend_ms, p.retract_ms)),
            _ => None,
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

impl From<Motor> for Plant {
    fn from(p: Motor) -> Plant {
        Plant::Motor(p)
    }
}

impl From<Driven> for Plant {
    fn from(p: Driven) -> Plant {
        Plant::Driven(p)
    }
}

impl From<Switch> for Plant {
    fn from(p: Switch) -> Plant {
        Plant::Switch(p)
    }
}
