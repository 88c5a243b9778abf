//! The `check` pass over the robot's control functions (docs/petri-nets.md, "Checks"):
//! what [`load`](mod@super::load) finds (a row of M that is not one `-1` and one `1`, not one
//! token, unknown places, events and names), then per function: unreachable places,
//! transitions that can never fire, and two transitions that one event enables from one
//! place under conditions that can both hold (the choice rule fires the first declared).
//! [`publications`] lists what conditions read across the radio, for `check` to print.

use std::collections::BTreeSet;

use super::compile::rewrite;
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

/// A condition of transition `from` of function `own` as `check` compares it: places
/// read as the function's place variable (two places of one function never hold
/// together), its own places and unreachable places of others known.
fn compared(
    when: &Option<(String, Ast)>,
    nets: &[Net],
    levels: &[String],
    reach: &[Vec<bool>],
    (own, from): (usize, usize),
) -> Option<Ast> {
    let (_, ast) = when.as_ref()?;
    let known = |f: usize, p: usize| {
        let marked = reach.get(f)?.get(p).copied().unwrap_or(true);
        (!marked).then_some(0)
    };
    Some(rewrite(ast, nets, levels, (own, from), &known))
}

/// Whether a condition can hold (none: always).
fn can_hold(when: &Option<Ast>) -> bool {
    when.as_ref().is_none_or(|a| may_overlap(a, a, &|_| None))
}

/// Whether a condition always holds (none: it does).
fn always(when: &Option<Ast>) -> bool {
    when.as_ref().is_none_or(|a| {
        let not = Ast::Not(Box::new(a.clone()));
        !may_overlap(&not, &not, &|_| None)
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
    let conditions: Vec<Option<Ast>> = (net.transitions.iter())
        .map(|t| compared(&t.when, nets, &levels, reach, (own, t.from)))
        .collect();
    for (k, t) in net.transitions.iter().enumerate() {
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
            (!can_hold(&conditions[k])).then(|| {
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
                .zip(&conditions)
                .find(|(u, c)| u.from == t.from && u.event == t.event && always(c))
                .map(|(u, _)| {
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
            let both = match (&conditions[j], &conditions[k]) {
                (Some(a), Some(b)) => may_overlap(a, b, &|_| None),
                (Some(a), None) | (None, Some(a)) => can_hold(&Some(a.clone())),
                (None, None) => true,
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
            // A declared alarm on this role reads places like a condition.
            for ast in crate::alarms::conditions(robot, &role.name) {
                let mut names = Vec::new();
                crate::expr::names(&ast, &mut names);
                for name in &names {
                    if let Some(Reads::Place { function, place }) = reads(nets, &levels, name) {
                        if function == g {
                            read.insert(place);
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

#[cfg(test)]
mod tests {
    use crate::source::Source;

    /// A robot whose function `F` leaves `a` on `X` twice, under `first` and `second`.
    fn robot(first: &str, second: &str) -> String {
        format!(
            r#"Robot(
    name: "choice", network: (pan_id: 0x0101, channel: 11),
    nodes: [(name: "n1", address: 0x0001)], assign: [("R", "n1")],
    roles: [(name: "R", inputs: [(name: "X", pin: 0), (name: "Y", pin: 1)])],
    functions: [
        (name: "G", role: "R", places: ["s", "t", "u"], initial: "s", transitions: [
            (on: "Y", from: "s", to: "t"), (on: "Y", from: "t", to: "s")]),
        (name: "F", role: "R", places: ["a", "b", "c"], initial: "a", transitions: [
            (on: "X", from: "a", to: "b", when: "{first}"),
            (on: "X", from: "a", to: "c", when: "{second}"),
            (on: "Y", from: "b", to: "a"), (on: "Y", from: "c", to: "a")]),
    ],
)"#
        )
    }

    fn warnings(first: &str, second: &str) -> Vec<String> {
        let src = Source::new("choice.ron", robot(first, second));
        crate::check::check(&src)
            .diagnostics
            .iter()
            .map(|d| d.message.clone())
            .collect()
    }

    /// Two places of one function never hold together, an unreachable place never
    /// holds, a function is in the place its transition leaves: no choice to report.
    /// Otherwise the choice rule's pick is named.
    #[test]
    fn the_choice_rule_is_reported_only_where_both_conditions_can_hold() {
        let u = "place `u` of function `G` is unreachable from its initial place `s`";
        let choice = "transitions `t1` and `t2` of function `F` both leave `a` on `X` under conditions that can both hold: the choice rule fires `t1`, declared first";
        assert_eq!(warnings("G.s", "G.t"), [u]);
        assert_eq!(warnings("G.s && X", "!X"), [u]);
        assert_eq!(warnings("F.a && G.s", "F.b"), [
            u,
            "transition `t2` of function `F` can never fire: its condition `F.b` never holds in `a`",
        ]);
        assert_eq!(warnings("G.u", "G.s"), [
            u,
            "transition `t1` of function `F` can never fire: its condition `G.u` never holds in `a`",
        ]);
        assert_eq!(warnings("G.s", "X"), [u, choice]);
        assert_eq!(warnings("G.s", "G.s || G.t"), [u, choice]);
    }
}
