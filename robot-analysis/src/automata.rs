//! The reference semantics of a selecting automaton (docs/selecting-automata.md): it runs
//! the automaton directly on a string of colours, as the on-line determinisation the
//! paper describes: a set of active states, a colour that fires nothing ignored, loop
//! caps, final transitions emitting EOS. A compiled network is tested against it.
//!
//! One part of colour `c` in configuration (A, n):
//!
//! - fired = every transition t with from(t) in A, colour(t) = c and, for a loop,
//!   n(t) < max(t); all of them fire together (synchronously), listed in the automaton's
//!   [`Automaton::firing_order`];
//! - nothing fired: the part is ignored, nothing changes;
//! - otherwise A' = (A minus the sources of fired non-loops) plus the targets of every
//!   fired transition; a loop counts the part (n + 1); entering a state by a non-loop,
//!   or leaving it, starts its loops' counts again at 0. A loop that reached its cap
//!   takes no more parts until its state is entered again; the state stays active;
//! - every fired final transition is an EOS.

use robot_compiler::automata::{Automaton, Colour, StateSet, TransitionId};

/// The run state: the active states and each loop's count in the current visit of its
/// state (0 for a transition that is not a loop).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Config {
    pub active: StateSet,
    /// By transition index.
    pub counts: Vec<u32>,
}

/// What one part did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Step {
    pub colour: Colour,
    /// The transitions that took the part, in firing order (empty: ignored).
    pub fired: Vec<TransitionId>,
    /// The active states after it.
    pub active: StateSet,
    /// The final transitions among `fired`: each ends a selected sequence (EOS).
    pub eos: Vec<TransitionId>,
}

impl Step {
    /// Whether the automaton took the part (some transition fired).
    pub fn taken(&self) -> bool {
        !self.fired.is_empty()
    }

    /// Whether the part ended a selected sequence.
    pub fn is_eos(&self) -> bool {
        !self.eos.is_empty()
    }
}

impl Config {
    /// Q0, every count 0.
    pub fn initial(a: &Automaton) -> Config {
        Config {
            active: a.initial,
            counts: vec![0; a.transitions.len()],
        }
    }

    /// Runs one part of colour `c` (a colour the automaton does not know fires nothing).
    pub fn step(&mut self, a: &Automaton, c: Colour) -> Step {
        let count = |counts: &[u32], t: TransitionId| counts.get(t.index()).copied().unwrap_or(0);
        let fired: Vec<TransitionId> = a
            .firing_order()
            .into_iter()
            .filter(|&id| {
                a.get(id).is_some_and(|t| {
                    self.active.contains(t.from)
                        && t.colour == c
                        && (!t.is_loop() || t.max.is_none_or(|m| count(&self.counts, id) < m))
                })
            })
            .collect();
        if fired.is_empty() {
            return Step {
                colour: c,
                fired,
                active: self.active,
                eos: Vec::new(),
            };
        }
        let (mut left, mut entered, mut fresh) =
            (StateSet::EMPTY, StateSet::EMPTY, StateSet::EMPTY);
        for t in fired.iter().filter_map(|&id| a.get(id)) {
            entered = entered.with(t.to);
            if !t.is_loop() {
                left = left.with(t.from);
                fresh = fresh.with(t.to);
            }
        }
        self.active = self.active.minus(left).union(entered);
        for (id, t) in a.iter().filter(|(_, t)| t.is_loop()) {
            let Some(n) = self.counts.get_mut(id.index()) else {
                continue;
            };
            if fresh.contains(t.from) || !self.active.contains(t.from) {
                *n = 0;
            } else if fired.contains(&id) {
                *n = n.saturating_add(1);
            }
        }
        let eos = fired
            .iter()
            .copied()
            .filter(|&id| a.get(id).is_some_and(|t| t.is_final()))
            .collect();
        Step {
            colour: c,
            fired,
            active: self.active,
            eos,
        }
    }
}

/// Runs a whole string of colours from Q0: one [`Step`] per part.
pub fn run(a: &Automaton, input: &[Colour]) -> Vec<Step> {
    let mut config = Config::initial(a);
    input.iter().map(|&c| config.step(a, c)).collect()
}

/// The 0-based positions of the parts that ended a selected sequence.
pub fn eos_positions(steps: &[Step]) -> Vec<usize> {
    steps
        .iter()
        .enumerate()
        .filter(|(_, s)| s.is_eos())
        .map(|(i, _)| i)
        .collect()
}
