//! The `check` pass over the robot's control functions (docs/petri-nets.md, "Checks"):
//! what [`super::load`] finds (a row of M that is not one `-1` and one `1`, not one
//! token, unknown places, events and names), then per function: unreachable places,
//! transitions that can never fire, and two transitions that one event enables from one
//! place under conditions that can both hold (the choice rule fires the first declared).
//! [`publications`] lists what conditions read across the radio, for `check` to print.

use std::collections::BTreeSet;

use super::{levels, load, reads, Event, Located, Net, Reads};
use crate::diag::Diagnostic;
use crate::expr::{may_overlap, Ast};
use crate::model::Robot;
use crate::source::Source;

/// The structural pass `check` runs.
pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    if robot.functions.is_empty() {
        return;
    }
    let loaded = load(robot, src);
    if loaded.diagnostics.iter().any(Diagnostic::is_error) {
        out.extend(loaded.diagnostics);
        return;
    }
    let nets = loaded.nets();
    out.extend(loaded.diagnostics);
    let reach: Vec<Vec<bool>> = nets.iter().map(reachable).collect();
    for l in &loaded.functions {
        unreachable(src, l, &reach, out);
        transitions(robot, src, l, &nets, &reach, out);
    }
}

/// The places of a net reachable from its initial place, ignoring events and conditions.
pub fn reachable(net: &Net) -> Vec<bool> {
    let mut seen = vec![false; net.places.len()];
    let mut todo = vec![net.initial];
    while let Some(p) = todo.pop() {
        match seen.get_mut(p) {
            Some(s) if !*s => *s = true,
            _ => continue,
        }
        todo.extend(net.transitions.iter().filter(|t| t.from == p).map(|t| t.to));
    }
    seen
}

fn unreachable(src: &Source, l: &Located, reach: &[Vec<bool>], out: &mut Vec<Diagnostic>) {
    let net = &l.net;
    let Some(fi) = reach.get(l.position) else {
        return;
    };
    for (j, p) in net.places.iter().enumerate() {
        if !fi.get(j).copied().unwrap_or(true) {
            out.push(Diagnostic::warning(
                src.span(&format!("{}[{j}]", l.places)),
                format!(
                    "place `{p}` of function `{}` is unreachable from its initial place `{}`",
                    net.name, net.places[net.initial]
                ),
            ));
        }
    }
}

/// The value of each name of a condition of transition `t` that is known: the
/// function's own places (it is in `from`) and unreachable places of others (never
/// marked).
fn fixed<'a>(
    nets: &'a [Net],
    levels: &'a [String],
    reach: &'a [Vec<bool>],
    own: usize,
    from: usize,
) -> impl Fn(&str) -> Option<i32> + 'a {
    move |name| match reads(nets, levels, name)? {
        Reads::Place { function, place } if function == own => Some(i32::from(place == from)),
        Reads::Place { function, place } => {
            let marked = reach.get(function)?.get(place).copied().unwrap_or(true);
            (!marked).then_some(0)
        }
        Reads::Input(_) => None,
    }
}

/// Whether a condition can hold (none: always).
fn can_hold(when: &Option<(String, Ast)>, fixed: &dyn Fn(&str) -> Option<i32>) -> bool {
    when.as_ref().is_none_or(|(_, a)| may_overlap(a, a, fixed))
}

/// Whether a condition always holds (none: it does).
fn always(when: &Option<(String, Ast)>, fixed: &dyn Fn(&str) -> Option<i32>) -> bool {
    when.as_ref().is_none_or(|(_, a)| {
        let not = Ast::Not(Box::new(a.clone()));
        !may_overlap(&not, &not, fixed)
    })
}

fn transitions(
    robot: &Robot,
    src: &Source,
    l: &Located,
    nets: &[Net],
    reach: &[Vec<bool>],
    out: &mut Vec<Diagnostic>,
) {
    let net = &l.net;
    let own = l.position;
    let levels = robot
        .role(&net.role)
        .map(|(_, r)| levels(r))
        .unwrap_or_default();
    let mut dead = BTreeSet::new();
    for (k, t) in net.transitions.iter().enumerate() {
        let fixed = fixed(nets, &levels, reach, own, t.from);
        let here = src.span(l.rows.get(k).map_or("", String::as_str));
        let why = if !reach[own].get(t.from).copied().unwrap_or(true) {
            Some(format!("its place `{}` is unreachable", net.places[t.from]))
        } else if let Event::Place { function, place } = t.event {
            let marked = reach
                .get(function)
                .and_then(|r| r.get(place))
                .copied()
                .unwrap_or(true);
            (!marked).then(|| {
                format!(
                    "its event `{}` never occurs: place `{}` of function `{}` is unreachable",
                    t.on, nets[function].places[place], nets[function].name
                )
            })
        } else {
            None
        };
        let why = why.or_else(|| {
            (!can_hold(&t.when, &fixed)).then(|| {
                format!(
                    "its condition `{}` never holds in `{}`",
                    t.when.as_ref().map_or("", |w| w.0.as_str()),
                    net.places[t.from]
                )
            })
        });
        let why = why.or_else(|| {
            net.transitions[..k]
                .iter()
                .find(|u| u.from == t.from && u.event == t.event && always(&u.when, &fixed))
                .map(|u| {
                    format!(
                        "`{}`, declared before it, leaves `{}` on `{}` whenever it is enabled (the choice rule takes the first declared)",
                        u.name, net.places[t.from], t.on
                    )
                })
        });
        if let Some(why) = why {
            dead.insert(k);
            out.push(Diagnostic::warning(
                here,
                format!(
                    "transition `{}` of function `{}` can never fire: {why}",
                    t.name, net.name
                ),
            ));
            continue;
        }
        for (j, u) in net.transitions[..k].iter().enumerate() {
            if dead.contains(&j) || u.from != t.from || u.event != t.event {
                continue;
            }
            let both = match (&u.when, &t.when) {
                (Some((_, a)), Some((_, b))) => may_overlap(a, b, &fixed),
                _ => true,
            };
            if both {
                out.push(Diagnostic::warning(
                    src.span(l.rows.get(k).map_or("", String::as_str)),
                    format!(
                        "transitions `{}` and `{}` of function `{}` both leave `{}` on `{}` under conditions that can both hold: the choice rule fires `{}`, declared first",
                        u.name, t.name, net.name, net.places[t.from], t.on, u.name
                    ),
                ));
            }
        }
    }
}

/// A function's place changes one role reads across the radio: the places its
/// conditions read (`read`) and the place changes published to it (`published`: entering
/// a read place, and leaving one for a place not read).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Publication {
    /// The function (index among the nets) and its role.
    pub function: usize,
    /// The role whose functions read it.
    pub to: String,
    /// Places read by conditions of `to`'s functions.
    pub read: Vec<usize>,
    /// Places read as events by `to`'s functions.
    pub events: Vec<usize>,
    /// Places whose entry is published to `to`.
    pub published: Vec<usize>,
}

/// Every function's places read from another role, by (function, reading role).
pub fn publications(robot: &Robot, nets: &[Net]) -> Vec<Publication> {
    let mut out = Vec::new();
    for (g, gn) in nets.iter().enumerate() {
        for role in &robot.roles {
            if role.name == gn.role {
                continue;
            }
            let levels = levels(role);
            let mut read = BTreeSet::new();
            let mut events = BTreeSet::new();
            for n in nets.iter().filter(|n| n.role == role.name) {
                for t in &n.transitions {
                    if let Event::Place { function, place } = t.event {
                        if function == g {
                            events.insert(place);
                        }
                    }
                    let mut names = Vec::new();
                    if let Some((_, a)) = &t.when {
                        crate::expr::names(a, &mut names);
                    }
                    for name in &names {
                        if let Some(Reads::Place { function, place }) = reads(nets, &levels, name) {
                            if function == g {
                                read.insert(place);
                            }
                        }
                    }
                }
            }
            if read.is_empty() && events.is_empty() {
                continue;
            }
            let mut published: BTreeSet<usize> = read.union(&events).copied().collect();
            for t in &gn.transitions {
                if read.contains(&t.from) && !read.contains(&t.to) {
                    published.insert(t.to);
                }
            }
            out.push(Publication {
                function: g,
                to: role.name.clone(),
                read: read.into_iter().collect(),
                events: events.into_iter().collect(),
                published: published.into_iter().collect(),
            });
        }
    }
    out
}

/// What `check` prints for each publication: which place changes cross the radio, to
/// which role, and the delay a condition reading them implies (one radio hop).
pub fn publication_lines(robot: &Robot, nets: &[Net]) -> Vec<String> {
    publications(robot, nets)
        .iter()
        .map(|p| {
            let g = &nets[p.function];
            let names = |v: &[usize]| {
                v.iter()
                    .map(|&j| format!("{}.{}", g.name, g.places[j]))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            let mut why = Vec::new();
            if !p.read.is_empty() {
                why.push(format!("conditions read {}", names(&p.read)));
            }
            if !p.events.is_empty() {
                why.push(format!("events {}", names(&p.events)));
            }
            format!(
                "function {} (role {}) publishes {} to role {} ({}): one radio hop later: {:.2} ms of airtime (at most {:.1} ms on host processes)",
                g.name,
                g.role,
                names(&p.published),
                p.to,
                why.join("; "),
                f64::from(super::HOP_AIRTIME_US) / 1000.0,
                f64::from(super::HOP_WALL_MAX_US) / 1000.0,
            )
        })
        .collect()
}
