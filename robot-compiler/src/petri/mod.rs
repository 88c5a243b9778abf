//! Control functions as state-machine Petri nets (seed 001, docs/petri-nets.md): each a
//! set of places (states, one token marks the active one) and transitions (events with
//! conditions), held as the incidence matrix M the paper's modular logic controller
//! evaluates, and compiled into one chart per function.
//!
//! - [`model`]: the robot file's `functions:` as serde types.
//! - [`load`](mod@load): `functions:` -> [`Net`]s with the place in the file of every part, or
//!   diagnostics (a row that is not one `-1` and one `1`, not one token, unknown names).
//! - [`check`]: the `check` pass: reachability, dead transitions, the choice rule,
//!   publications across the radio.
//! - [`compile`]: nets -> charts in the IR (called by the explicit-chart elaboration).
//! - [`matrix`]: M, F, m(0), x and u as tables or CSV (`config-tool matrix`).

pub mod check;
pub mod compile;
pub mod load;
pub mod matrix;
pub mod model;

pub use load::{load, Loaded, Located};

use crate::expr::Ast;
use crate::model::ActionDecl;

/// Airtime of one radio hop between nodes, microseconds: an event frame and its ack,
/// secured, as the radio bench measures it (docs/config-tool.md, "Performance"). A
/// condition read across the radio sees the other function's place this much later.
pub const HOP_AIRTIME_US: u32 = 2470;

/// Wall latency of one hop on host processes, at most, microseconds (the same bench).
pub const HOP_WALL_MAX_US: u32 = 8200;

/// One control function: a state machine Petri net on a role.
#[derive(Debug, Clone, PartialEq)]
pub struct Net {
    pub name: String,
    /// The role whose node runs it.
    pub role: String,
    /// Place names: the columns of M.
    pub places: Vec<String>,
    /// The place marked in m(0).
    pub initial: usize,
    /// The places besides the initial one where the function rests between cycles (a
    /// mode kept from one cycle to the next), in declaration order.
    pub rests: Vec<usize>,
    /// The transitions: the rows of M, in declaration order (the choice rule's order).
    pub transitions: Vec<Transition>,
    pub timers: Vec<String>,
    /// Each place's entry actions, by place.
    pub actions: Vec<Vec<ActionDecl>>,
}

/// One transition (a row of M).
#[derive(Debug, Clone, PartialEq)]
pub struct Transition {
    /// Its row name.
    pub name: String,
    /// The event as written.
    pub on: String,
    pub event: Event,
    /// The precondition place (-1 in its row).
    pub from: usize,
    /// The resulting place (1 in its row).
    pub to: usize,
    /// The condition as written and parsed; none: always.
    pub when: Option<(String, Ast)>,
}

/// What a transition's event is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Event {
    /// An event of a role: an input or switch edge, a chart output; `role` is the
    /// function's own unless written `ROLE/EVENT`.
    Role { role: String, event: String },
    /// The expiry of the function's timer (an index into [`Net::timers`]).
    Timer(usize),
    /// Another function (index into the robot's nets) entering one of its places.
    Place { function: usize, place: usize },
}

/// What a name in a condition reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reads<'a> {
    /// Whether function `function` is in place `place`.
    Place { function: usize, place: usize },
    /// The level of an input of the function's role.
    Input(&'a str),
}

impl Net {
    /// M: one row per transition, one column per place; -1 at its precondition, 1 at
    /// its result.
    pub fn incidence(&self) -> Vec<Vec<i8>> {
        self.transitions
            .iter()
            .map(|t| {
                (0..self.places.len())
                    .map(|j| i8::from(j == t.to) - i8::from(j == t.from))
                    .collect()
            })
            .collect()
    }

    /// F, the precondition part of M: 1 where M is -1.
    pub fn precondition(&self) -> Vec<Vec<bool>> {
        self.incidence()
            .iter()
            .map(|row| row.iter().map(|&e| e < 0).collect())
            .collect()
    }

    /// m(0): one token, in the initial place.
    pub fn initial_marking(&self) -> Vec<u8> {
        (0..self.places.len())
            .map(|j| u8::from(j == self.initial))
            .collect()
    }

    pub fn place(&self, name: &str) -> Option<usize> {
        self.places.iter().position(|p| p == name)
    }
}

/// `F.P` -> (function index, place index) among `nets`.
pub fn place_ref(nets: &[Net], name: &str) -> Option<(usize, usize)> {
    let (f, p) = name.split_once('.')?;
    let fi = nets.iter().position(|n| n.name == f)?;
    Some((fi, nets[fi].place(p)?))
}

/// What `name` in a condition of a function on `role` reads: a function's place
/// (`F.P`) or an input of the role (`levels`: the role's input and switch names).
pub fn reads<'a>(nets: &[Net], levels: &[String], name: &'a str) -> Option<Reads<'a>> {
    if let Some((function, place)) = place_ref(nets, name) {
        return Some(Reads::Place { function, place });
    }
    levels
        .iter()
        .any(|l| l == name)
        .then_some(Reads::Input(name))
}

/// The names a condition of a function on `role` may read as input levels: the role's
/// plain inputs and its actuators' switches (`ACT.home`, `ACT.end`).
pub fn levels(role: &crate::model::Role) -> Vec<String> {
    let mut out: Vec<String> = role.inputs.iter().map(|i| i.name.clone()).collect();
    for a in &role.actuators {
        for (field, _, used) in a.kind.pins() {
            if used == crate::model::PinUse::Switch {
                out.push(format!("{}.{field}", a.name));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::{Event, Net, Transition};

    fn row(name: &str, from: usize, to: usize) -> Transition {
        Transition {
            name: name.to_string(),
            on: String::from("E"),
            event: Event::Timer(0),
            from,
            to,
            when: None,
        }
    }

    /// M has one -1 (precondition) and one 1 (result) per row; F is its -1 part; m(0)
    /// one token.
    #[test]
    fn incidence_precondition_and_initial_marking() {
        let net = Net {
            name: String::from("F"),
            role: String::from("R"),
            places: vec![String::from("a"), String::from("b"), String::from("c")],
            initial: 1,
            rests: Vec::new(),
            transitions: vec![row("t1", 1, 2), row("t2", 2, 0)],
            timers: vec![String::from("E")],
            actions: vec![Vec::new(); 3],
        };
        assert_eq!(net.incidence(), [[0, -1, 1], [1, 0, -1]]);
        assert_eq!(
            net.precondition(),
            [[false, true, false], [false, false, true]]
        );
        assert_eq!(net.initial_marking(), [0, 1, 0]);
        assert_eq!(net.place("c"), Some(2));
        assert_eq!(super::place_ref(&[net], "F.b"), Some((0, 1)));
    }
}
