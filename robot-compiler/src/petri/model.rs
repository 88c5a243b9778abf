//! Control functions as written in the robot file (`functions:`), as serde types.
//! docs/robot-format.md ("Control functions") documents them; [`load`](mod@super::load) resolves
//! them into [`super::Net`]s.

use std::collections::BTreeMap;

use serde::Deserialize;

use crate::model::ActionDecl;

/// One control function: a state-machine Petri net placed on a role, given either as
/// `places` / `initial` / `transitions` or directly as its `matrix`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FunctionDecl {
    pub name: String,
    /// The role whose node runs it.
    pub role: String,
    /// Its places (states), in column order of M.
    #[serde(default)]
    pub places: Vec<String>,
    /// The place holding the token in m(0).
    #[serde(default)]
    pub initial: Option<String>,
    /// The places besides the initial one where the function also rests between cycles:
    /// a mode the operator selected and that stays selected from one cycle to the next
    /// (the machine is idle, ready for START, with the function there).
    #[serde(default)]
    pub rest: Vec<String>,
    /// Its transitions, in row order of M (and in the choice rule's order).
    #[serde(default)]
    pub transitions: Vec<NetTransitionDecl>,
    /// The net as its incidence matrix instead of `places` and `transitions`.
    #[serde(default)]
    pub matrix: Option<MatrixDecl>,
    /// Timers; a timer's expiry is an event of the function of the timer's name.
    #[serde(default)]
    pub timers: Vec<String>,
    /// What entering a place does: place -> actions (`Extend`, `Retract`, `Out`,
    /// `StartTimer`, `CancelTimer`, `Fault`).
    #[serde(default)]
    pub actions: BTreeMap<String, Vec<ActionDecl>>,
}

/// A transition: `from` -> `to` when the event `on` occurs and the condition `when` holds.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NetTransitionDecl {
    /// Its row name in M (default `t1`, `t2`, ... by position).
    #[serde(default)]
    pub name: Option<String>,
    /// The event: an input edge of the role (`BELT_HOME`, `BELT_HOME.fall`, a switch), a
    /// timer of the function, another function's place (`Pusher.Stopped`: entering it),
    /// or `ROLE/EVENT` of another role.
    pub on: String,
    pub from: String,
    pub to: String,
    /// The condition: over the role's inputs and functions' places (`Pusher.Stopped`).
    #[serde(default)]
    pub when: Option<String>,
}

/// The paper's form: columns = places, rows = transitions (events), entries -1
/// (the place is the event's precondition), 1 (the place results from it), 0.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MatrixDecl {
    /// Column names.
    pub places: Vec<String>,
    /// The rows of M.
    pub rows: Vec<MatrixRowDecl>,
    /// m(0): one entry per place.
    pub marking: Vec<i32>,
}

/// One row of M: its event, condition and entries.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MatrixRowDecl {
    /// Its row name (default `t1`, `t2`, ... by position).
    #[serde(default)]
    pub name: Option<String>,
    /// The event, as a transition's `on`.
    pub on: String,
    /// The condition, as a transition's `when`.
    #[serde(default)]
    pub when: Option<String>,
    /// One entry per place: -1, 0 or 1.
    pub row: Vec<i32>,
}
