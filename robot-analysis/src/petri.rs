//! The reference modular logic controller (seed 001, docs/petri-nets.md): the paper's
//! algebra evaluated on the matrices directly, the semantics every compiled function
//! chart is tested against.
//!
//! For one function with incidence matrix M (rows = transitions, columns = places), its
//! precondition part F and marking m(k), at an event:
//!
//! - x_e(k) = F (+) m(k): the rows enabled by the marking ((+): the boolean product, AND
//!   for multiply, OR for add);
//! - u(k): per row, its event is the one occurring and its condition holds (evaluated
//!   now, over input levels and the places of every function);
//! - x(k) = choice(x_e(k) & u(k)): **the choice rule** keeps the first such row in
//!   declaration order (none: the event changes nothing);
//! - m(k+1) = m(k) + M^T x(k).
//!
//! A [`Controller`] runs every function of a robot: an occurrence goes to each function
//! in declaration order (each sees the places the ones before it just took); a function
//! entering a place is itself an occurrence (`F.P`), queued and handled after the
//! current one (first in, first out), as the charts' emitted events are.

use std::collections::VecDeque;

use config_schema::limits::MAX_CASCADE;

use robot_compiler::expr;
use robot_compiler::petri::{place_ref, Event, Net};

/// F (+) m: row i is enabled if some place j has F(i, j) and m(j).
pub fn enabled(f: &[Vec<bool>], m: &[u8]) -> Vec<bool> {
    f.iter()
        .map(|row| row.iter().zip(m).any(|(&fij, &mj)| fij && mj != 0))
        .collect()
}

/// The choice rule: of the rows both enabled and whose u holds, the first declared.
pub fn choose(enabled: &[bool], u: &[bool]) -> Vec<bool> {
    let first = enabled.iter().zip(u).position(|(&e, &c)| e && c);
    (0..enabled.len()).map(|i| Some(i) == first).collect()
}

/// m + M^T x; `None` if a place would hold fewer than 0 tokens (x fires a row that is
/// not enabled).
pub fn next(m_matrix: &[Vec<i8>], m: &[u8], x: &[bool]) -> Option<Vec<u8>> {
    (0..m.len())
        .map(|j| {
            let delta: i32 = m_matrix
                .iter()
                .zip(x)
                .filter(|(_, &xi)| xi)
                .map(|(row, _)| i32::from(row.get(j).copied().unwrap_or(0)))
                .sum();
            u8::try_from(i32::from(m[j]) + delta).ok()
        })
        .collect()
}

/// Something that happens to the functions.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Occurrence {
    /// An event of a role: an input edge (`START`, `START.fall`), a switch, a chart output.
    Role { role: String, event: String },
    /// A function's timer expired.
    Timer { function: usize, timer: usize },
    /// A function entered a place.
    Place { function: usize, place: usize },
}

/// A transition that fired: function and row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fired {
    pub function: usize,
    pub row: usize,
}

/// Every function's marking, stepped by occurrences.
#[derive(Debug, Clone)]
pub struct Controller<'n> {
    nets: &'n [Net],
    markings: Vec<Vec<u8>>,
}

impl<'n> Controller<'n> {
    /// Every function at m(0).
    pub fn new(nets: &'n [Net]) -> Self {
        Controller {
            nets,
            markings: nets.iter().map(Net::initial_marking).collect(),
        }
    }

    /// m(k) of function `f`.
    pub fn marking(&self, f: usize) -> &[u8] {
        self.markings.get(f).map_or(&[], Vec::as_slice)
    }

    /// The place holding function `f`'s token.
    pub fn place(&self, f: usize) -> Option<usize> {
        self.marking(f).iter().position(|&x| x != 0)
    }

    /// Whether row `t`'s event is the occurrence, for function `f`.
    fn matches(event: &Event, f: usize, o: &Occurrence) -> bool {
        match (event, o) {
            (Event::Role { role, event }, Occurrence::Role { role: r, event: e }) => {
                role == r && event == e
            }
            (Event::Timer(k), Occurrence::Timer { function, timer }) => {
                f == *function && k == timer
            }
            (
                Event::Place { function, place },
                Occurrence::Place {
                    function: g,
                    place: p,
                },
            ) => function == g && place == p,
            _ => false,
        }
    }

    /// The value of a name of a condition: a function's place (1 if marked), else the
    /// input level `inputs` gives (unknown: 0).
    fn value(&self, name: &str, inputs: &dyn Fn(&str) -> Option<bool>) -> i32 {
        if let Some((g, p)) = place_ref(self.nets, name) {
            return i32::from(self.marking(g).get(p).copied().unwrap_or(0) != 0);
        }
        i32::from(inputs(name).unwrap_or(false))
    }

    /// u(k) of function `f` for occurrence `o`.
    pub fn conditions(
        &self,
        f: usize,
        o: &Occurrence,
        inputs: &dyn Fn(&str) -> Option<bool>,
    ) -> Vec<bool> {
        let Some(net) = self.nets.get(f) else {
            return Vec::new();
        };
        net.transitions
            .iter()
            .map(|t| {
                Self::matches(&t.event, f, o)
                    && t.when.as_ref().is_none_or(|(_, ast)| {
                        expr::eval(ast, &|n| Some(self.value(n, inputs))).is_some_and(|v| v != 0)
                    })
            })
            .collect()
    }

    /// One occurrence and every place change it causes, to completion; `inputs` gives
    /// the input levels (after the edge). The transitions fired, in order.
    pub fn occur(
        &mut self,
        o: Occurrence,
        inputs: &dyn Fn(&str) -> Option<bool>,
    ) -> Result<Vec<Fired>, Endless> {
        self.occur_all(vec![o], inputs)
    }

    /// Simultaneous occurrences (one input edge sensed by the nodes of several roles),
    /// queued in this order, and every place change they cause, to completion; or
    /// [`Endless`] past [`MAX_CASCADE`] place changes (where a node faults: it never
    /// returned).
    pub fn occur_all(
        &mut self,
        occurrences: Vec<Occurrence>,
        inputs: &dyn Fn(&str) -> Option<bool>,
    ) -> Result<Vec<Fired>, Endless> {
        let mut fired = Vec::new();
        let mut queue = VecDeque::from(occurrences);
        let mut changes = 0;
        while let Some(o) = queue.pop_front() {
            if matches!(o, Occurrence::Place { .. }) {
                changes += 1;
                if changes > MAX_CASCADE {
                    return Err(Endless);
                }
            }
            for (f, net) in self.nets.iter().enumerate() {
                let xe = enabled(&net.precondition(), self.marking(f));
                let u = self.conditions(f, &o, inputs);
                let x = choose(&xe, &u);
                let Some(row) = x.iter().position(|&b| b) else {
                    continue;
                };
                if let Some(m) = next(&net.incidence(), self.marking(f), &x) {
                    self.markings[f] = m;
                }
                fired.push(Fired { function: f, row });
                if let Some(place) = self.place(f) {
                    queue.push_back(Occurrence::Place { function: f, place });
                }
            }
        }
        Ok(fired)
    }
}

/// More place changes for one occurrence than a node processes events for one stimulus
/// ([`MAX_CASCADE`]): the functions enter places on each other's entries without end.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("more than {MAX_CASCADE} place changes for one occurrence: the functions' place events cycle (a node faults: Cascade)")]
pub struct Endless;

#[cfg(test)]
mod tests {
    use super::{choose, enabled, next};

    /// The algebra on a three-place function: F (+) m, the choice rule, M^T x.
    #[test]
    fn the_algebra_on_one_function() {
        // Rows: a: P0 -> P1, b: P0 -> P2, c: P1 -> P0.
        let m_matrix = vec![vec![-1, 1, 0], vec![-1, 0, 1], vec![1, -1, 0]];
        let f: Vec<Vec<bool>> = m_matrix
            .iter()
            .map(|r| r.iter().map(|&e| e < 0).collect())
            .collect();
        let m0 = [1, 0, 0];
        assert_eq!(enabled(&f, &m0), [true, true, false]);
        // a and b both enabled and their conditions hold: the first declared fires.
        let x = choose(&enabled(&f, &m0), &[true, true, true]);
        assert_eq!(x, [true, false, false]);
        assert_eq!(next(&m_matrix, &m0, &x), Some(vec![0, 1, 0]));
        // Only b's condition holds.
        let x = choose(&enabled(&f, &m0), &[false, true, true]);
        assert_eq!(next(&m_matrix, &m0, &x), Some(vec![0, 0, 1]));
        // c holds but is not enabled: nothing fires.
        let x = choose(&enabled(&f, &m0), &[false, false, true]);
        assert_eq!(x, [false, false, false]);
        assert_eq!(next(&m_matrix, &m0, &x), Some(m0.to_vec()));
        // Firing a row that is not enabled takes a token that is not there.
        assert_eq!(next(&m_matrix, &m0, &[false, false, true]), None);
    }
}
