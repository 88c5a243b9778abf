//! The `check` pass over the robot's automata (docs/selecting-automata.md, "Checks"):
//! what [`super::load`] finds (bad facts, undeclared states, colours the robot cannot
//! produce, duplicates), then per automaton: loop caps, initial states, determinism,
//! unreachable states, transitions that can never fire, final transitions, and the
//! conflicts of a nondeterministic automaton where firing order matters.

use std::collections::BTreeSet;

use super::{load, Automaton, Located, StateId, StateSet, TransitionId};
use crate::diag::Diagnostic;
use crate::model::Robot;
use crate::source::Source;

/// Active sets [`active_sets`] explores at most before the conflict check gives up.
pub const EXPLORE_LIMIT: usize = 4096;

/// The structural pass `check` runs.
pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    if robot.automata.is_empty() {
        return;
    }
    let loaded = load(robot, src);
    out.extend(loaded.diagnostics);
    for located in &loaded.automata {
        check_one(located, out);
    }
}

/// Every check of one resolved automaton.
pub fn check_one(l: &Located, out: &mut Vec<Diagnostic>) {
    caps(l, out);
    determinism(l, out);
    reachability(l, out);
    conflicts(l, out);
}

/// `from -> to` of a transition, by names.
fn arrow(a: &Automaton, t: TransitionId) -> String {
    a.get(t).map_or(String::new(), |t| {
        format!("{} -> {}", a.state_name(t.from), a.state_name(t.to))
    })
}

fn caps(l: &Located, out: &mut Vec<Diagnostic>) {
    let a = &l.automaton;
    for ((id, t), places) in a.iter().zip(&l.places.transitions) {
        match (t.is_loop(), t.max) {
            (true, None) => out.push(places.whole.error(format!(
                "`max` required on a loop: `{}` ({}) of automaton `{}` would accept any number of `{}` parts; give the most it accepts in a row",
                t.id,
                arrow(a, id),
                a.name,
                a.colour_name(t.colour)
            ))),
            (true, Some(0)) => out.push(places.max.error(format!(
                "loop `{}` of automaton `{}` accepts at most 0 parts: it can never fire (`max` is at least 1)",
                t.id, a.name
            ))),
            (false, Some(_)) => out.push(places.max.error(format!(
                "transition `{}` ({}) of automaton `{}` is not a loop: only a loop takes `max`",
                t.id,
                arrow(a, id),
                a.name
            ))),
            _ => {}
        }
    }
}

/// Pairs of transitions that leave one state on one colour (declaration order).
pub fn choices(a: &Automaton) -> Vec<(TransitionId, TransitionId)> {
    let mut pairs = Vec::new();
    for (i, t) in a.iter() {
        for (j, u) in a.iter().filter(|(j, _)| *j > i) {
            if t.from == u.from && t.colour == u.colour {
                pairs.push((i, j));
            }
        }
    }
    pairs
}

/// Whether the automaton is deterministic: one initial state and no [`choices`].
pub fn is_deterministic(a: &Automaton) -> bool {
    a.initial.len() == 1 && choices(a).is_empty()
}

fn determinism(l: &Located, out: &mut Vec<Diagnostic>) {
    let a = &l.automaton;
    if a.initial.is_empty() {
        out.push(l.places.name.error(format!(
            "automaton `{}` has no initial state: it never takes a part",
            a.name
        )));
    }
    let mut reasons = Vec::new();
    let mut at = Vec::new();
    if a.initial.len() > 1 {
        reasons.push(format!(
            "it has {} initial states {}",
            a.initial.len(),
            a.initial.show(a)
        ));
        at.push(l.places.initial.get(1).unwrap_or(&l.places.name).clone());
    }
    for (t, u) in choices(a) {
        let (Some(tt), Some(uu)) = (a.get(t), a.get(u)) else {
            continue;
        };
        reasons.push(format!(
            "`{}` and `{}` both leave `{}` on `{}`",
            tt.id,
            uu.id,
            a.state_name(tt.from),
            a.colour_name(tt.colour)
        ));
        if let Some(p) = l.places.transitions.get(u.index()) {
            at.push(p.whole.clone());
        }
    }
    match a.deterministic {
        Some(true) => {
            for (reason, place) in reasons.iter().zip(&at) {
                out.push(place.error(format!(
                    "automaton `{}` is declared deterministic but {reason}",
                    a.name
                )));
            }
        }
        None if !reasons.is_empty() => out.push(l.places.name.warning(format!(
            "automaton `{}` is nondeterministic: {}; it runs as its on-line determinisation (declare `deterministic: false` to say so)",
            a.name,
            reasons.join("; ")
        ))),
        _ => {}
    }
}

/// The states reachable from the initial ones over transitions.
pub fn reachable_states(a: &Automaton) -> StateSet {
    let mut seen = a.initial;
    loop {
        let next = a
            .transitions
            .iter()
            .filter(|t| seen.contains(t.from))
            .fold(seen, |s, t| s.with(t.to));
        if next == seen {
            return seen;
        }
        seen = next;
    }
}

fn reachability(l: &Located, out: &mut Vec<Diagnostic>) {
    let a = &l.automaton;
    if a.initial.is_empty() {
        return;
    }
    let reach = reachable_states(a);
    for (i, place) in l.places.states.iter().enumerate() {
        let q = StateId(i as u8);
        if !reach.contains(q) {
            out.push(place.warning(format!(
                "state `{}` of automaton `{}` is unreachable from its initial state(s) {}",
                a.state_name(q),
                a.name,
                a.initial.show(a)
            )));
        }
    }
    for ((id, t), places) in a.iter().zip(&l.places.transitions) {
        if !reach.contains(t.from) {
            out.push(places.whole.warning(format!(
                "transition `{}` ({}) of automaton `{}` can never fire: `{}` is unreachable",
                t.id,
                arrow(a, id),
                a.name,
                a.state_name(t.from)
            )));
        }
    }
    let finals: Vec<_> = a.transitions.iter().filter(|t| t.is_final()).collect();
    if finals.is_empty() {
        out.push(l.places.name.warning(format!(
            "automaton `{}` has no final transition: it never selects a sequence (no EOS)",
            a.name
        )));
    } else if finals.iter().all(|t| !reach.contains(t.from)) {
        out.push(l.places.name.warning(format!(
            "no final transition of automaton `{}` can fire: it never selects a sequence (no EOS)",
            a.name
        )));
    }
}

/// The active sets reachable from the initial one, loop counts abstracted (a loop may
/// or may not have reached its cap): a superset of those the semantics reaches. `Err`
/// with the limit if there are more than `limit`.
pub fn active_sets(a: &Automaton, limit: usize) -> Result<BTreeSet<StateSet>, usize> {
    let mut seen = BTreeSet::from([a.initial]);
    let mut todo = vec![a.initial];
    while let Some(set) = todo.pop() {
        for c in 0..a.colours.len() {
            for next in abstract_steps(a, set, c) {
                if seen.insert(next) {
                    if seen.len() > limit {
                        return Err(limit);
                    }
                    todo.push(next);
                }
            }
        }
    }
    Ok(seen)
}

/// The active sets after a part of colour `c` (index) from `set`, for every choice of
/// which of the loops that could keep a state active have reached their cap.
fn abstract_steps(a: &Automaton, set: StateSet, c: usize) -> Vec<StateSet> {
    let on = |t: &&super::Transition| set.contains(t.from) && t.colour.index() == c;
    let (mut left, mut entered, mut kept) = (StateSet::EMPTY, StateSet::EMPTY, StateSet::EMPTY);
    for t in a.transitions.iter().filter(on) {
        if t.is_loop() {
            if t.max != Some(0) {
                kept = kept.with(t.from);
            }
        } else {
            left = left.with(t.from);
            entered = entered.with(t.to);
        }
    }
    let base = set.minus(left).union(entered);
    // States a loop may keep active: any subset of them, up to 2^8 subsets.
    let optional: Vec<StateId> = kept.minus(base).iter().take(8).collect();
    let mut out = Vec::with_capacity(1 << optional.len());
    for mask in 0u32..(1 << optional.len()) {
        let extra = optional
            .iter()
            .enumerate()
            .filter(|(i, _)| mask & (1 << i) != 0)
            .fold(StateSet::EMPTY, |s, (_, &q)| s.with(q));
        out.push(base.union(extra));
    }
    let rest = kept.minus(base).minus(StateSet::of(&optional));
    out.iter_mut().for_each(|s| *s = s.union(rest));
    out
}

/// A conflict: `enters` leads into the state `leaves` leaves, on one colour, and both
/// source states can be active together, so firing `enters` first would hand the part
/// on twice. The paper's fix: `leaves` fires first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Conflict {
    pub enters: TransitionId,
    pub leaves: TransitionId,
}

/// Every conflict of the automaton (empty if it is deterministic), or `Err` if there are
/// more than [`EXPLORE_LIMIT`] active sets to look at.
pub fn find_conflicts(a: &Automaton) -> Result<Vec<Conflict>, usize> {
    if is_deterministic(a) {
        return Ok(Vec::new());
    }
    let sets = active_sets(a, EXPLORE_LIMIT)?;
    let mut out = Vec::new();
    for (i, t) in a.iter().filter(|(_, t)| !t.is_loop()) {
        for (j, u) in a.iter() {
            if i != j
                && t.to == u.from
                && t.colour == u.colour
                && sets
                    .iter()
                    .any(|s| s.contains(t.from) && s.contains(u.from))
            {
                out.push(Conflict {
                    enters: i,
                    leaves: j,
                });
            }
        }
    }
    Ok(out)
}

/// Whether the declared priority fires `leaves` before `enters`.
pub fn resolved(a: &Automaton, c: Conflict) -> bool {
    let at = |t| a.priority.iter().position(|&p| p == t);
    matches!((at(c.leaves), at(c.enters)), (Some(l), Some(e)) if l < e)
}

/// A priority that resolves every conflict (each `leaves` before its `enters`), if one
/// exists (the conflicts form no cycle).
pub fn suggest_priority(conflicts: &[Conflict]) -> Option<Vec<TransitionId>> {
    let mut involved: Vec<TransitionId> = Vec::new();
    for c in conflicts {
        for t in [c.leaves, c.enters] {
            if !involved.contains(&t) {
                involved.push(t);
            }
        }
    }
    involved.sort();
    let mut order = Vec::new();
    while !involved.is_empty() {
        // A transition no remaining conflict needs to fire after another.
        let pos = involved.iter().position(|&t| {
            !conflicts
                .iter()
                .any(|c| c.enters == t && involved.contains(&c.leaves))
        })?;
        order.push(involved.remove(pos));
    }
    Some(order)
}

fn conflicts(l: &Located, out: &mut Vec<Diagnostic>) {
    let a = &l.automaton;
    let found = match find_conflicts(a) {
        Ok(found) => found,
        Err(limit) => {
            out.push(l.places.name.warning(format!(
                "automaton `{}` has more than {limit} reachable active sets: its conflicts are not checked",
                a.name
            )));
            return;
        }
    };
    let unresolved: Vec<Conflict> = found.iter().copied().filter(|&c| !resolved(a, c)).collect();
    if unresolved.is_empty() {
        return;
    }
    let help = match suggest_priority(&found) {
        Some(order) => {
            let ids: Vec<String> = order
                .iter()
                .filter_map(|&t| a.get(t))
                .map(|t| format!("\"{}\"", t.id))
                .collect();
            format!("declare `priority: [{}]` (a transition that leaves a state fires before one that enters it)", ids.join(", "))
        }
        None => String::from(
            "no firing order resolves these conflicts: they form a cycle; split the automaton or give the transitions different colours",
        ),
    };
    for c in unresolved {
        let (Some(t), Some(u)) = (a.get(c.enters), a.get(c.leaves)) else {
            continue;
        };
        let Some(place) = l.places.transitions.get(c.enters.index()) else {
            continue;
        };
        out.push(
            place
                .whole
                .error(format!(
                    "conflict in automaton `{}`: `{}` ({}) enters and `{}` ({}) leaves `{}` on `{}`, and `{}` and `{}` can be active together: the firing order matters (`{}` must fire first)",
                    a.name,
                    t.id,
                    arrow(a, c.enters),
                    u.id,
                    arrow(a, c.leaves),
                    a.state_name(t.to),
                    a.colour_name(t.colour),
                    a.state_name(t.from),
                    a.state_name(t.to),
                    u.id
                ))
                .help(help.clone()),
        );
    }
}
