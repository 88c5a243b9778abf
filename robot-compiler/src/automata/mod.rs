//! Selecting automata (docs/selecting-automata.md): A = (Q, T, C, delta, phi, Q0, F), the
//! model a compiler and the reference semantics read, with states, transitions and
//! colours as small integers that index their name tables.
//!
//! - [`prolog`]: the paper's Prolog facts -> [`prolog::Facts`], with exact places.
//! - [`load`]: the robot's `automata:` (RON or facts) -> [`Automaton`]s and the place of
//!   every part of them, or diagnostics.
//! - [`check`]: the `check` pass: determinism, reachability, caps, colours, conflicts.

pub mod check;
pub mod compile;
mod load;
pub mod prolog;

use std::ops::Range;

pub use crate::model::TransitionKind;
pub use load::{facts_dir, from_facts, load, load_with, Loaded, Located, Places, TransitionPlaces};

use crate::diag::Diagnostic;

/// States an automaton has at most: an active set is one 64-bit [`StateSet`].
pub const MAX_STATES: usize = 64;
/// Transitions an automaton has at most (ids are a byte).
pub const MAX_TRANSITIONS: usize = 255;
/// Colours an automaton reads at most (a colour is a byte on the radio).
pub const MAX_COLOURS: usize = 255;

/// A state: an index into [`Automaton::states`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct StateId(pub u8);

/// A transition: an index into [`Automaton::transitions`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TransitionId(pub u8);

/// A colour (part type): an index into [`Automaton::colours`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Colour(pub u8);

impl StateId {
    pub fn index(self) -> usize {
        usize::from(self.0)
    }
}

impl TransitionId {
    pub fn index(self) -> usize {
        usize::from(self.0)
    }
}

impl Colour {
    pub fn index(self) -> usize {
        usize::from(self.0)
    }
}

/// A set of states (at most [`MAX_STATES`]): bit `i` is state `i`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct StateSet(pub u64);

impl StateSet {
    pub const EMPTY: StateSet = StateSet(0);

    pub fn of(states: &[StateId]) -> StateSet {
        states.iter().fold(StateSet::EMPTY, |s, &q| s.with(q))
    }

    /// This set and `q`.
    pub fn with(self, q: StateId) -> StateSet {
        StateSet(self.0 | 1u64.checked_shl(u32::from(q.0)).unwrap_or(0))
    }

    /// This set without `q`.
    pub fn without(self, q: StateId) -> StateSet {
        StateSet(self.0 & !1u64.checked_shl(u32::from(q.0)).unwrap_or(0))
    }

    pub fn contains(self, q: StateId) -> bool {
        self.with(q) == self && q.index() < MAX_STATES
    }

    pub fn union(self, other: StateSet) -> StateSet {
        StateSet(self.0 | other.0)
    }

    pub fn minus(self, other: StateSet) -> StateSet {
        StateSet(self.0 & !other.0)
    }

    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    pub fn len(self) -> usize {
        self.0.count_ones() as usize
    }

    /// The states, in index order.
    pub fn iter(self) -> impl Iterator<Item = StateId> {
        (0..MAX_STATES as u8)
            .map(StateId)
            .filter(move |&q| self.contains(q))
    }

    /// `{s0,s1}`: the names of the states, in index order.
    pub fn show(self, a: &Automaton) -> String {
        let names: Vec<&str> = self.iter().map(|q| a.state_name(q)).collect();
        format!("{{{}}}", names.join(","))
    }
}

/// One transition t: delta(t) = `colour`, phi(t) = `max` on a loop, t in F if `Final`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Transition {
    /// Its id as written (`t1`).
    pub id: String,
    pub from: StateId,
    pub to: StateId,
    pub colour: Colour,
    /// phi(t): parts a loop accepts in a row; `None` on an ordinary transition (and on a
    /// loop `check` refuses; the semantics then caps nothing).
    pub max: Option<u32>,
    pub kind: TransitionKind,
}

impl Transition {
    /// Whether it is a loop (`from == to`).
    pub fn is_loop(&self) -> bool {
        self.from == self.to
    }

    /// Whether it is a final transition (emits EOS).
    pub fn is_final(&self) -> bool {
        self.kind == TransitionKind::Final
    }
}

/// A resolved selecting automaton: every reference is a valid index (at most
/// [`MAX_STATES`] states, [`MAX_TRANSITIONS`] transitions, [`MAX_COLOURS`] colours).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Automaton {
    pub name: String,
    /// C: the colour names; [`Colour`] indexes them.
    pub colours: Vec<String>,
    /// Q: the state names; [`StateId`] indexes them.
    pub states: Vec<String>,
    /// T, in declaration order; [`TransitionId`] indexes them.
    pub transitions: Vec<Transition>,
    /// Q0.
    pub initial: StateSet,
    /// The declared firing order of conflicting transitions (first fires first).
    pub priority: Vec<TransitionId>,
    /// What the robot declares: `Some(true)` deterministic, `Some(false)` not.
    pub deterministic: Option<bool>,
}

impl Automaton {
    pub fn colour(&self, name: &str) -> Option<Colour> {
        position(&self.colours, name).map(Colour)
    }

    pub fn state(&self, name: &str) -> Option<StateId> {
        position(&self.states, name).map(StateId)
    }

    pub fn transition(&self, id: &str) -> Option<TransitionId> {
        self.transitions
            .iter()
            .position(|t| t.id == id)
            .and_then(|i| u8::try_from(i).ok())
            .map(TransitionId)
    }

    pub fn colour_name(&self, c: Colour) -> &str {
        self.colours.get(c.index()).map_or("?", String::as_str)
    }

    pub fn state_name(&self, q: StateId) -> &str {
        self.states.get(q.index()).map_or("?", String::as_str)
    }

    pub fn get(&self, t: TransitionId) -> Option<&Transition> {
        self.transitions.get(t.index())
    }

    /// Every transition with its id, in declaration order.
    pub fn iter(&self) -> impl Iterator<Item = (TransitionId, &Transition)> {
        self.transitions
            .iter()
            .enumerate()
            .take(MAX_TRANSITIONS)
            .map(|(i, t)| (TransitionId(i as u8), t))
    }

    /// The order transitions fire in within one part: the declared priority first, then
    /// the others in declaration order.
    pub fn firing_order(&self) -> Vec<TransitionId> {
        let mut order = self.priority.clone();
        order.extend(
            self.iter()
                .map(|(t, _)| t)
                .filter(|t| !self.priority.contains(t)),
        );
        order
    }

    /// Whether some transition is final.
    pub fn selects(&self) -> bool {
        self.transitions.iter().any(Transition::is_final)
    }
}

fn position(names: &[String], name: &str) -> Option<u8> {
    names
        .iter()
        .position(|n| n == name)
        .and_then(|i| u8::try_from(i).ok())
}

/// Where a part of an automaton is written: a span of the robot file, or a line and
/// column of a facts file (diagnostics about it then sit at the robot's `facts_file` and
/// name the file's place first).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Place {
    Robot(Range<usize>),
    File {
        /// The file as the robot names it.
        name: String,
        line: usize,
        col: usize,
        /// The robot's `facts_file` value.
        at: Range<usize>,
    },
}

impl Place {
    pub fn error(&self, message: impl Into<String>) -> Diagnostic {
        let (span, message) = self.parts(message.into());
        Diagnostic::error(span, message)
    }

    pub fn warning(&self, message: impl Into<String>) -> Diagnostic {
        let (span, message) = self.parts(message.into());
        Diagnostic::warning(span, message)
    }

    /// `line:col` in its file (the robot's when `src` is the robot file).
    pub fn line_col(&self, src: &crate::Source) -> String {
        match self {
            Place::Robot(span) => {
                let (line, col) = src.line_col(span.start);
                format!("{line}:{col}")
            }
            Place::File {
                name, line, col, ..
            } => format!("{name}:{line}:{col}"),
        }
    }

    fn parts(&self, message: String) -> (Range<usize>, String) {
        match self {
            Place::Robot(span) => (span.clone(), message),
            Place::File {
                name,
                line,
                col,
                at,
            } => (at.clone(), format!("{name}:{line}:{col}: {message}")),
        }
    }
}
