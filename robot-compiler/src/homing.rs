//! Homing: the steps that bring every actuator of a sequence robot home from wherever a
//! boot, a power cut, a fault or an activation of a stopped machine left it (home, end or
//! stopped in between), one step at a time, in order.
//!
//! The rule that keeps homing safe is the interlocks' (`never:`): while step k moves its
//! actuator, every actuator homed (or driven) by an earlier step is where that step left
//! it, and every other one may be anywhere at rest. A step breaches an interlock when some
//! such placement makes the interlock hold ([`breaches`]). A robot without a declared
//! `homing` gets one derived ([`derive`](fn@derive)): actuators with a home switch first (a step on
//! one already home is skipped), sensorless ones last (a gripper lets its part go only
//! once everything else is home), each as early as the interlocks allow.

use std::collections::BTreeMap;

use crate::interlock::{self, Atom, Interlock, END, EXTENDING, HOME, RETRACTING};
use crate::ir::{Ir, Step};
use crate::model::{ActuatorKind, ActuatorLevel, Robot};

/// A homing step that lets an interlock hold.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Breach {
    /// The step (0-based).
    pub step: usize,
    /// The interlock (index into the robot's `never`).
    pub interlock: usize,
    /// Where the other actuators are when it holds, e.g. `VC at end`.
    pub witness: String,
}

/// Why no homing sequence could be derived.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DeriveError {
    #[error(
        "no homing order keeps the interlocks: {stuck} cannot move while the others may be \
         anywhere (declare `homing`, e.g. `homing: \"{example}\"`)"
    )]
    Stuck { stuck: String, example: String },
    #[error(
        "interlock never[{index}] `{text}` may hold before HOME, {witness}: a monostable \
         valve drops at a boot (or `start: Retract` drives), and its actuator returns home \
         at once"
    )]
    AtPowerUp {
        index: usize,
        text: String,
        witness: String,
    },
}

/// Where an actuator is before a homing step: known (home or end) after an earlier step,
/// moving (the step's own), anywhere at rest, or (one whose valve returns it home before
/// the charts run: a monostable valve, which drops at a boot, or `start: Retract`) also
/// on its way home.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Place {
    Known(u8),
    Moving(u8),
    Anywhere,
    AnywhereOrReturning,
}

/// Whether actuator `name`'s valve may move it home before homing: a monostable valve
/// (it drops at a boot, whatever its start level says) or `start: Retract`.
fn returns_at_start(robot: &Robot, name: &str) -> bool {
    robot
        .actuator(name)
        .and_then(|(r, i)| robot.roles.get(r)?.actuators.get(i))
        .is_some_and(|a| {
            matches!(a.kind, ActuatorKind::SingleActing { .. }) || a.start == ActuatorLevel::Retract
        })
}

/// Where every plant actuator (`actuators`, plant order) is before HOME: anywhere, on its
/// way home if its valve returns it.
fn power_up(robot: &Robot, actuators: &[String]) -> Vec<Place> {
    actuators
        .iter()
        .map(|a| match returns_at_start(robot, a) {
            true => Place::AnywhereOrReturning,
            false => Place::Anywhere,
        })
        .collect()
}

/// [`power_up`] with every returning actuator at `place` (on its way home, or still at
/// its end before its valve let go).
fn returned(robot: &Robot, actuators: &[String], place: Place) -> Vec<Place> {
    power_up(robot, actuators)
        .into_iter()
        .map(|p| match p {
            Place::AnywhereOrReturning => place,
            other => other,
        })
        .collect()
}

/// The places every plant actuator (`actuators`, plant order) has during step `k`, each
/// not moved by an earlier step where it was before HOME (`start`: [`power_up`]).
fn places(start: &[Place], actuators: &[String], steps: &[Step], k: usize) -> Vec<Place> {
    actuators
        .iter()
        .zip(start)
        .map(|(a, &start)| {
            if steps[k].actuator == *a {
                return Place::Moving(if steps[k].extend {
                    EXTENDING
                } else {
                    RETRACTING
                });
            }
            steps[..k]
                .iter()
                .rev()
                .find(|s| s.actuator == *a)
                .map_or(start, |s| Place::Known(if s.extend { END } else { HOME }))
        })
        .collect()
}

/// The positions an actuator anywhere at rest may have: home, end, stopped in between;
/// one whose valve returns it, also on its way home.
const AT_REST: [u8; 4] = [HOME, END, 0, RETRACTING];

/// A placement of the free names of `lock` under which it holds, if one exists.
fn holds_somewhere(lock: &Interlock, places: &[Place], names: &[String]) -> Option<String> {
    // The free dimensions: actuators anywhere (3 positions, 4 for one on its way home),
    // chart states (2 values).
    let mut free_plants: Vec<(usize, usize)> = Vec::new();
    let mut free_charts: Vec<Atom> = Vec::new();
    for atom in lock.names.values() {
        match *atom {
            Atom::Position { plant, .. } => {
                let radix = match places.get(plant) {
                    Some(Place::Anywhere) => 3,
                    Some(Place::AnywhereOrReturning) => 4,
                    _ => continue,
                };
                if !free_plants.iter().any(|(p, _)| *p == plant) {
                    free_plants.push((plant, radix));
                }
            }
            Atom::Chart { .. } => free_charts.push(*atom),
            Atom::Fault { .. } | Atom::Const(_) => {}
        }
    }
    // Each interlock names a few things: the product stays small; past 2^12 placements
    // assume the worst (a breach) rather than spend the time.
    let combos = (free_plants.iter())
        .try_fold(1usize, |n, (_, radix)| n.checked_mul(*radix))
        .and_then(|n| n.checked_mul(1usize.checked_shl(free_charts.len() as u32)?));
    let Some(combos) = combos.filter(|&n| n <= 4096) else {
        return Some(String::from("(too many placements to search)"));
    };
    for n in 0..combos {
        let mut rest = n;
        let mut at: BTreeMap<usize, u8> = BTreeMap::new();
        for &(p, radix) in &free_plants {
            at.insert(p, AT_REST[rest % radix]);
            rest /= radix;
        }
        let charts: Vec<(Atom, bool)> = free_charts
            .iter()
            .map(|&c| {
                let v = rest % 2 == 1;
                rest /= 2;
                (c, v)
            })
            .collect();
        let read = |atom: Atom| match atom {
            Atom::Position { plant, mask } => {
                let pos = match places.get(plant) {
                    Some(Place::Known(p) | Place::Moving(p)) => *p,
                    _ => at.get(&plant).copied().unwrap_or(HOME),
                };
                pos & mask != 0
            }
            Atom::Chart { .. } => charts.iter().any(|(c, v)| *c == atom && *v),
            Atom::Fault { .. } => false,
            Atom::Const(v) => v,
        };
        if lock.holds(&read) {
            let witness: Vec<String> = free_plants
                .iter()
                .map(|(p, _)| {
                    let name = names.get(*p).map_or("?", String::as_str);
                    match at.get(p).copied().unwrap_or(0) {
                        HOME => format!("{name} home"),
                        END => format!("{name} at its end"),
                        RETRACTING => format!("{name} on its way home"),
                        _ => format!("{name} stopped between home and end"),
                    }
                })
                .collect();
            return Some(if witness.is_empty() {
                String::from("wherever the others are")
            } else {
                format!("with {}", witness.join(", "))
            });
        }
    }
    None
}

/// Every (step, interlock) pair where the step lets the interlock hold; `interlocks` are
/// (index in `never`, interlock).
pub fn breaches(
    robot: &Robot,
    ir: &Ir,
    interlocks: &[(usize, Interlock)],
    steps: &[Step],
) -> Vec<Breach> {
    let actuators = interlock::actuator_names(ir);
    let start = power_up(robot, &actuators);
    let mut out = Vec::new();
    for k in 0..steps.len() {
        let places = places(&start, &actuators, steps, k);
        for (i, lock) in interlocks {
            if let Some(witness) = holds_somewhere(lock, &places, &actuators) {
                out.push(Breach {
                    step: k,
                    interlock: *i,
                    witness,
                });
            }
        }
    }
    out
}

/// The interlocks (index in `never`, and where the actuators are) that the node's own
/// return of an actuator may break before HOME (a monostable valve drops at a boot: a
/// gripper opening while the arm is down): one that holds with the returning actuators on
/// their way home and the others anywhere, and never with the returning ones still at
/// their end. (Where a power cut left the actuators is not the node's doing: an
/// interlock that holds there without a motion is homing's to end.)
pub fn at_power_up(
    robot: &Robot,
    ir: &Ir,
    interlocks: &[(usize, Interlock)],
) -> Vec<(usize, String)> {
    let actuators = interlock::actuator_names(ir);
    let moving = returned(robot, &actuators, Place::Moving(RETRACTING));
    let still = returned(robot, &actuators, Place::Known(END));
    interlocks
        .iter()
        .filter(|(_, lock)| holds_somewhere(lock, &still, &actuators).is_none())
        .filter_map(|(i, lock)| {
            let witness = holds_somewhere(lock, &moving, &actuators)?;
            // The returning actuators it names, on their way home.
            let mut returning: Vec<String> = (lock.names.values())
                .filter_map(|atom| match *atom {
                    Atom::Position { plant, .. } if moving.get(plant) != still.get(plant) => {
                        actuators.get(plant).map(|a| format!("{a} on its way home"))
                    }
                    _ => None,
                })
                .collect();
            returning.sort();
            returning.dedup();
            Some((*i, format!("{witness}, {}", returning.join(", "))))
        })
        .collect()
}

/// The moving actuators a homing sequence leaves away from home (or never moves).
pub fn not_homed(ir: &Ir, steps: &[Step]) -> Vec<String> {
    interlock::actuator_names(ir)
        .into_iter()
        .filter(|a| {
            steps
                .iter()
                .rev()
                .find(|s| s.actuator == *a)
                .is_none_or(|s| s.extend)
        })
        .collect()
}

/// A homing sequence for `ir`'s actuators that breaches none of `interlocks` (module doc).
pub fn derive(
    robot: &Robot,
    ir: &Ir,
    interlocks: &[(usize, Interlock)],
) -> Result<Vec<Step>, DeriveError> {
    if let Some((index, witness)) = at_power_up(robot, ir, interlocks).into_iter().next() {
        let text = robot.never.get(index).cloned().unwrap_or_default();
        return Err(DeriveError::AtPowerUp {
            index,
            text,
            witness,
        });
    }
    let actuators = interlock::actuator_names(ir);
    let start = power_up(robot, &actuators);
    let switched = |a: &str| {
        robot
            .actuator(a)
            .and_then(|(r, i)| robot.roles.get(r)?.actuators.get(i))
            .is_some_and(|x| x.kind.completion_switch(false).is_some())
    };
    let mut todo: Vec<&String> = actuators.iter().filter(|a| switched(a)).collect();
    todo.extend(actuators.iter().filter(|a| !switched(a)));
    let mut steps: Vec<Step> = Vec::new();
    while !todo.is_empty() {
        let pick = todo.iter().position(|a| {
            let mut next = steps.clone();
            next.push(Step {
                actuator: (*a).clone(),
                extend: false,
            });
            let k = next.len() - 1;
            let places = places(&start, &actuators, &next, k);
            interlocks
                .iter()
                .all(|(_, l)| holds_somewhere(l, &places, &actuators).is_none())
        });
        let Some(i) = pick else {
            let stuck: Vec<String> = todo.iter().map(|a| format!("{a}-")).collect();
            let example: Vec<String> = steps
                .iter()
                .map(ToString::to_string)
                .chain(stuck.iter().cloned())
                .collect();
            return Err(DeriveError::Stuck {
                stuck: stuck.join(", "),
                example: example.join(" "),
            });
        };
        let a = todo.remove(i);
        steps.push(Step {
            actuator: a.clone(),
            extend: false,
        });
    }
    Ok(steps)
}

/// The robot's interlocks that resolve on `ir` (a bad one is `check`'s to report).
pub fn resolved_interlocks(robot: &Robot, ir: &Ir) -> Vec<(usize, Interlock)> {
    let scope = interlock::Scope::of(robot, ir);
    robot
        .never
        .iter()
        .enumerate()
        .filter_map(|(i, text)| scope.interlock(text).ok().map(|l| (i, l)))
        .collect()
}
