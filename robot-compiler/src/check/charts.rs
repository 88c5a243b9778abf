//! Chart types: more states or transitions than a table holds (an error, a warning for a
//! type no chart is of), states unreachable from the initial state (warning), and two
//! transitions from one state on one event whose guards can both hold (warning: the first
//! declared wins, which may not be what was meant). Roles of more charts than a table
//! holds (error).

use std::collections::BTreeMap;

use config_schema::limits::{MAX_CHARTS, MAX_STATES, MAX_TRANSITIONS};

use crate::diag::Diagnostic;
use crate::elab;
use crate::expr;
use crate::model::{ActionDecl, ChartType, Robot};
use crate::source::Source;

pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    // More charts on a role than a table holds: refused before they are elaborated (each
    // brings events its role's tables look up by name).
    for (ri, r) in robot.roles.iter().enumerate() {
        if r.charts.len() > MAX_CHARTS {
            let path = format!("roles[{ri}].charts[{MAX_CHARTS}]");
            let at = match robot.application {
                Some(_) if src.span(&path) == src.span(&format!("roles[{ri}]")) => {
                    src.span(crate::model::APPLICATION_FILE)
                }
                _ => src.span(&path),
            };
            out.push(Diagnostic::error(
                at,
                format!(
                    "role `{}` has {} charts: a table holds at most {MAX_CHARTS} (MAX_CHARTS)",
                    r.name,
                    r.charts.len()
                ),
            ));
        }
    }
    // Parameter values of every instance of each type.
    let mut instances: BTreeMap<&str, Vec<BTreeMap<String, i32>>> = BTreeMap::new();
    for c in robot.roles.iter().flat_map(|r| r.charts.iter()) {
        instances
            .entry(c.type_.as_str())
            .or_default()
            .push(c.params.clone());
    }
    // A type no chart instantiates: its parameters free.
    let free = vec![BTreeMap::new()];
    for (ti, t) in robot.chart_types.iter().enumerate() {
        let used = instances.contains_key(t.name.as_str());
        if !fits(t, ti, used, src, out) {
            continue;
        }
        names(t, ti, src, out);
        unreachable(t, ti, src, out);
        overlaps(
            t,
            ti,
            instances.get(t.name.as_str()).unwrap_or(&free),
            src,
            out,
        );
    }
}

/// Whether a chart type's states and transitions fit a table (if not: an error if a chart
/// is of the type, else a warning; no table holds it, and its other checks, which compare
/// states and transitions in pairs, are skipped).
fn fits(t: &ChartType, ti: usize, used: bool, src: &Source, out: &mut Vec<Diagnostic>) -> bool {
    let mut fits = true;
    for (what, n, max, name) in [
        ("states", t.states.len(), MAX_STATES, "MAX_STATES"),
        (
            "transitions",
            t.transitions.len(),
            MAX_TRANSITIONS,
            "MAX_TRANSITIONS",
        ),
    ] {
        if n > max {
            fits = false;
            let at = type_span(t, src, &format!("chart_types[{ti}].{what}[{max}]"));
            let said = format!(
                "chart type `{}` has {n} {what}: a table holds at most {max} ({name})",
                t.name
            );
            out.push(if used {
                Diagnostic::error(at, said)
            } else {
                Diagnostic::warning(at, format!("{said}; no chart is of it"))
            });
        }
    }
    fits
}

/// The span of `path` inside chart type `t` ([`ChartType::place`]).
fn type_span(t: &ChartType, src: &Source, path: &str) -> std::ops::Range<usize> {
    src.span(t.place(path))
}

/// Names inside a chart type (states and events of its transitions) and the syntax of its
/// expressions. Names that depend on the role (inputs read by guards, actuators) are
/// checked when the charts are elaborated.
fn names(t: &ChartType, ti: usize, src: &Source, out: &mut Vec<Diagnostic>) {
    let tp = format!("chart_types[{ti}]");
    let syntax = |path: String, text: &str, out: &mut Vec<Diagnostic>| {
        if let Err(e) = expr::parse(text) {
            out.push(elab::expr_error(src, &path, &e));
        }
    };
    for (vi, v) in t.vars.iter().enumerate() {
        syntax(format!("{tp}.vars[{vi}].init"), &v.init, out);
    }
    for (si, s) in t.states.iter().enumerate() {
        for (ai, a) in s.actions.iter().enumerate() {
            if let ActionDecl::Set(_, text) = a {
                syntax(format!("{tp}.states[{si}].actions[{ai}][1]"), text, out);
            }
        }
    }
    for (k, tr) in t.transitions.iter().enumerate() {
        let path = format!("{tp}.transitions[{k}]");
        for (name, field) in [(&tr.from, "from"), (&tr.to, "to")] {
            if !t.states.iter().any(|s| &s.name == name) {
                out.push(elab::unknown_state(
                    src,
                    t,
                    &format!("{path}.{field}"),
                    name,
                ));
            }
        }
        if let Some(on) = &tr.on {
            if !t.inputs.contains(on) && !t.timers.contains(on) {
                out.push(elab::unknown_chart_event(src, t, &format!("{path}.on"), on));
            }
        }
        if let Some(text) = &tr.when {
            syntax(format!("{path}.when"), text, out);
        }
    }
}

fn unreachable(t: &ChartType, ti: usize, src: &Source, out: &mut Vec<Diagnostic>) {
    // A type made of another for an FB instance has that one's states and transitions:
    // its warning is the other's.
    if t.specializes.is_some() {
        return;
    }
    let Some(initial) = t.states.first() else {
        out.push(Diagnostic::error(
            type_span(t, src, &format!("chart_types[{ti}].states")),
            format!("chart type `{}` has no states", t.name),
        ));
        return;
    };
    let mut reached = vec![initial.name.as_str()];
    let mut k = 0;
    while k < reached.len() {
        let from = reached[k];
        for tr in t.transitions.iter().filter(|tr| tr.from == from) {
            if !reached.contains(&tr.to.as_str()) {
                reached.push(&tr.to);
            }
        }
        k += 1;
    }
    for (si, s) in t.states.iter().enumerate() {
        if !reached.contains(&s.name.as_str()) {
            out.push(
                Diagnostic::warning(
                    type_span(t, src, &format!("chart_types[{ti}].states[{si}].name")),
                    written_at(
                        t.state_written(si),
                        format!(
                            "state `{}` of chart type `{}` is unreachable from its initial state `{}`",
                            s.name, t.name, initial.name
                        ),
                    ),
                )
                .label("no transition leads here"),
            );
        }
    }
}

/// `message` about a chart type, after `file:line:col: ` if the type was read from a file
/// ([`ChartType::written`]) where that place is (as the import's errors say it).
fn written_at(at: Option<String>, message: String) -> String {
    match at {
        Some(at) => format!("{at}: {message}"),
        None => message,
    }
}

fn overlaps(
    t: &ChartType,
    ti: usize,
    instances: &[BTreeMap<String, i32>],
    src: &Source,
    out: &mut Vec<Diagnostic>,
) {
    let always = expr::Ast::Int(1);
    let guards: Vec<Option<expr::Ast>> = t
        .transitions
        .iter()
        .map(|tr| match &tr.when {
            Some(text) => expr::parse(text).ok(),
            None => Some(always.clone()),
        })
        .collect();
    for (j, b) in t.transitions.iter().enumerate() {
        for (i, a) in t.transitions.iter().enumerate().take(j) {
            if a.from != b.from || a.on != b.on {
                continue;
            }
            let (Some(ga), Some(gb)) = (&guards[i], &guards[j]) else {
                continue;
            };
            let both = instances.iter().any(|params| {
                let fixed = |n: &str| params.get(n).copied();
                expr::may_overlap(ga, gb, &fixed)
            });
            if both {
                let on = match &b.on {
                    Some(e) => format!("on `{e}`"),
                    None => String::from("without an event"),
                };
                let path = format!("chart_types[{ti}].transitions");
                let other = t.transition_written(i).unwrap_or_else(|| {
                    let (line, col) =
                        src.line_col(type_span(t, src, &format!("{path}[{i}]")).start);
                    format!("{line}:{col}")
                });
                out.push(
                    Diagnostic::warning(
                        type_span(t, src, &format!("{path}[{j}]")),
                        written_at(
                            t.transition_written(j),
                            format!(
                                "transitions `{} -> {}` and `{} -> {}` leave `{}` {on} and both guards can hold: the first declared wins",
                                a.from, a.to, b.from, b.to, b.from
                            ),
                        ),
                    )
                    .label(format!("overlaps the transition at {other}")),
                );
            }
        }
    }
}
