//! Control functions -> charts in the IR (docs/petri-nets.md, "Charts"): one chart per
//! function, places -> states, transitions -> ECC transitions in row order (the choice
//! rule is the ECC's declaration order), each on its event, guarded by its condition.
//!
//! - A place another function reads in a condition on the same role: the owning chart
//!   sets the variable `F.state` (its place's column) on entering each place; `F.P`
//!   reads `F.state == j`.
//! - Across roles: the owning chart emits `F.P` on entering each place in a
//!   [`super::check::Publication`], published to the reading role, whose `F.seen` chart
//!   keeps its own `F.state` from them (`-1`: a place not read there).
//! - A place another function waits for as its event: the owning chart emits `F.P`.
//!
//! Charts of a role: its explicit charts, then the `.seen` charts, then its functions, in
//! declaration order (routes in that order: a `.seen` chart is up to date before a
//! function reads it on the same event).

use std::collections::BTreeSet;

use super::check::{publications, Publication};
use super::{levels, reads, Event, Net, Reads};
use crate::expr::{self, Ast, BinOp, Operand};
use crate::ir::{ActionIr, ChartIr, RoleIr, StateIr, TimerIr, TransitionIr};
use crate::model::{ActionDecl, Robot};

/// The variable holding function `f`'s place on a role that reads it.
pub fn state_var(f: &str) -> String {
    format!("{f}.state")
}

/// The event of function `f` entering place `p`.
pub fn place_event(f: &str, p: &str) -> String {
    format!("{f}.{p}")
}

/// Role events the functions listen to, as (role, event): their inputs must raise them.
pub fn wanted(nets: &[Net]) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for n in nets {
        for t in &n.transitions {
            if let Event::Role { role, event } = &t.event {
                out.push((role.clone(), event.clone()));
            }
        }
    }
    out
}

/// Whether a function on `role` reads function `g`'s places in a condition.
fn read_on(robot: &Robot, nets: &[Net], g: usize, role: &str) -> bool {
    let Some((_, r)) = robot.role(role) else {
        return false;
    };
    let levels = levels(r);
    let by_alarm = crate::alarms::conditions(robot, role).iter().any(|a| {
        let mut names = Vec::new();
        expr::names(a, &mut names);
        names.iter().any(|name| {
            matches!(reads(nets, &levels, name), Some(Reads::Place { function, .. }) if function == g)
        })
    });
    by_alarm || nets.iter().filter(|n| n.role == role).any(|n| {
        n.transitions.iter().any(|t| {
            let mut names = Vec::new();
            if let Some((_, a)) = &t.when {
                expr::names(a, &mut names);
            }
            names.iter().any(|name| {
                matches!(reads(nets, &levels, name), Some(Reads::Place { function, .. }) if function == g)
            })
        })
    })
}

/// The places of `g` whose entry its chart emits: waited for as events anywhere, or
/// published to a role that reads them.
fn emitted(nets: &[Net], pubs: &[Publication], g: usize) -> BTreeSet<usize> {
    let mut out = BTreeSet::new();
    for n in nets {
        for t in &n.transitions {
            if let Event::Place { function, place } = t.event {
                if function == g {
                    out.insert(place);
                }
            }
        }
    }
    for p in pubs.iter().filter(|p| p.function == g) {
        out.extend(p.published.iter().copied());
    }
    out
}

/// The local name of a function's event on its role `r`, importing it if it is another
/// role's.
fn local_event(nets: &[Net], net: &Net, t: &super::Transition, r: &mut RoleIr) -> String {
    let (role, event) = match &t.event {
        Event::Role { role, event } => (role.clone(), event.clone()),
        Event::Timer(k) => (net.role.clone(), place_event(&net.name, &net.timers[*k])),
        Event::Place { function, place } => {
            let g = &nets[*function];
            (g.role.clone(), place_event(&g.name, &g.places[*place]))
        }
    };
    if role == r.name {
        return event;
    }
    import(r, &role, &event)
}

fn import(r: &mut RoleIr, role: &str, event: &str) -> String {
    let local = format!("{role}/{event}");
    if !r.imports.iter().any(|(_, _, l)| *l == local) {
        r.imports
            .push((role.to_string(), event.to_string(), local.clone()));
    }
    local
}

/// Adds the `.seen` charts and function charts of role `r` (after its explicit charts).
pub fn charts(robot: &Robot, nets: &[Net], r: &mut RoleIr) -> Result<(), String> {
    let pubs = publications(robot, nets);
    // Variables first: every chart may read every other's.
    for (g, n) in nets.iter().enumerate() {
        let here = n.role == r.name && read_on(robot, nets, g, &r.name);
        let seen = pubs
            .iter()
            .any(|p| p.function == g && p.to == r.name && !p.read.is_empty());
        if here || seen {
            r.vars.push((state_var(&n.name), n.initial as i32));
        }
    }
    let role = r.name.clone();
    for p in pubs.iter().filter(|p| p.to == role && !p.read.is_empty()) {
        seen_chart(nets, p, r)?;
    }
    for (g, n) in nets.iter().enumerate().filter(|(_, n)| n.role == role) {
        function_chart(robot, nets, &pubs, g, n, r)?;
    }
    Ok(())
}

fn var(r: &RoleIr, f: &str) -> Result<usize, String> {
    let name = state_var(f);
    r.vars
        .iter()
        .position(|(v, _)| *v == name)
        .ok_or_else(|| format!("no variable `{name}` on role `{}`", r.name))
}

fn set(r: &RoleIr, f: &str, value: i32) -> Result<ActionIr, String> {
    Ok(ActionIr::Set {
        var: var(r, f)?,
        text: value.to_string(),
        ops: vec![config_schema::Op::Const(value)],
    })
}

/// The chart keeping the place of a function of another role from its publications.
fn seen_chart(nets: &[Net], p: &Publication, r: &mut RoleIr) -> Result<(), String> {
    let g = &nets[p.function];
    let read: BTreeSet<usize> = p.read.iter().copied().collect();
    // States: each place read, then `other`.
    let mut states: Vec<(String, i32)> = p
        .read
        .iter()
        .map(|&j| (g.places[j].clone(), j as i32))
        .collect();
    let other = states.len();
    states.push((String::from("other"), -1));
    let state_of = |j: usize| p.read.iter().position(|&x| x == j).unwrap_or(other);
    let ci = r.charts.len();
    let mut inputs = Vec::new();
    let mut transitions = Vec::new();
    for &q in &p.published {
        let local = import(r, &g.role, &place_event(&g.name, &g.places[q]));
        r.event(&local);
        let input = inputs.len();
        inputs.push(place_event(&g.name, &g.places[q]));
        r.routes.push((local, ci, input));
        let to = state_of(q);
        for from in (0..states.len()).filter(|&s| s != to) {
            transitions.push(TransitionIr {
                from,
                to,
                trigger: Some(input),
                guard: None,
            });
        }
    }
    transitions.sort_by_key(|t| t.from);
    let mut ir_states = Vec::new();
    for (name, value) in &states {
        ir_states.push(StateIr {
            name: name.clone(),
            actions: vec![set(r, &g.name, *value)?],
        });
    }
    let initial = if read.contains(&g.initial) {
        state_of(g.initial)
    } else {
        other
    };
    // It rests where the function does: in the state of each of its resting places.
    let mut rests: Vec<usize> = g.rests.iter().map(|&j| state_of(j)).collect();
    rests.retain(|&st| st != initial);
    rests.sort_unstable();
    rests.dedup();
    r.charts.push(ChartIr {
        name: format!("{}.seen", g.name),
        inputs,
        initial,
        idle: initial,
        rests,
        states: ir_states,
        transitions,
    });
    Ok(())
}

/// A condition of a transition of function `own` leaving `from`, with each place
/// rewritten to its reading: `F.P` -> `F.state == j` (one variable per function, so two
/// of its places never hold together), the function's own places to whether it is in
/// them; `known` may give a place's value outright (`check`: an unreachable place, 0).
pub fn rewrite(
    ast: &Ast,
    nets: &[Net],
    levels: &[String],
    (own, from): (usize, usize),
    known: &dyn Fn(usize, usize) -> Option<i32>,
) -> Ast {
    ast.map_names(&|n, span| match reads(nets, levels, n)? {
        Reads::Place { function, place } if function == own => {
            Some(Ast::Int(i32::from(place == from)))
        }
        Reads::Place { function, place } => Some(match known(function, place) {
            Some(v) => Ast::Int(v),
            None => Ast::Bin(
                BinOp::Eq,
                Box::new(Ast::Name(state_var(&nets[function].name), span.clone())),
                Box::new(Ast::Int(place as i32)),
            ),
        }),
        _ => None,
    })
}

fn function_chart(
    robot: &Robot,
    nets: &[Net],
    pubs: &[Publication],
    g: usize,
    n: &Net,
    r: &mut RoleIr,
) -> Result<(), String> {
    let levels = robot
        .role(&n.role)
        .map(|(_, role)| levels(role))
        .unwrap_or_default();
    let ci = r.charts.len();
    let timer_base = r.timers.len();
    for t in &n.timers {
        let name = place_event(&n.name, t);
        r.timers.push(TimerIr {
            name: name.clone(),
            event: name.clone(),
        });
        r.event(&name);
    }
    let sets_var = read_on(robot, nets, g, &n.role);
    let emits = emitted(nets, pubs, g);
    let mut states = Vec::new();
    for (j, p) in n.places.iter().enumerate() {
        let mut actions = Vec::new();
        if sets_var {
            actions.push(set(r, &n.name, j as i32)?);
        }
        if emits.contains(&j) {
            let e = place_event(&n.name, p);
            r.event(&e);
            actions.push(ActionIr::Emit(e));
        }
        for a in n.actions.get(j).into_iter().flatten() {
            actions.push(action(n, r, timer_base, a)?);
        }
        states.push(StateIr {
            name: p.clone(),
            actions,
        });
    }
    let mut inputs: Vec<String> = Vec::new();
    let mut transitions = Vec::new();
    for t in &n.transitions {
        let local = local_event(nets, n, t, r);
        let input = match inputs.iter().position(|i| *i == local) {
            Some(i) => i,
            None => {
                inputs.push(local.clone());
                r.event(&local);
                r.routes.push((local, ci, inputs.len() - 1));
                inputs.len() - 1
            }
        };
        let guard = match &t.when {
            Some((text, ast)) => {
                let ast = rewrite(ast, nets, &levels, (g, t.from), &|_, _| None);
                let resolve = |name: &str| {
                    if let Some(v) = r.vars.iter().position(|(v, _)| v == name) {
                        return u8::try_from(v).ok().map(Operand::Var);
                    }
                    let i = r.inputs.iter().position(|i| i.name == name)?;
                    u8::try_from(i).ok().map(Operand::Input)
                };
                let ops = expr::bytecode(&ast, &resolve).map_err(|e| e.message)?;
                Some((text.clone(), ops))
            }
            None => None,
        };
        transitions.push(TransitionIr {
            from: t.from,
            to: t.to,
            trigger: Some(input),
            guard,
        });
    }
    r.charts.push(ChartIr {
        name: n.name.clone(),
        inputs,
        initial: n.initial,
        idle: n.initial,
        rests: n.rests.clone(),
        states,
        transitions,
    });
    Ok(())
}

fn action(n: &Net, r: &mut RoleIr, timer_base: usize, a: &ActionDecl) -> Result<ActionIr, String> {
    let timer = |name: &str| {
        n.timers
            .iter()
            .position(|t| t == name)
            .map(|k| timer_base + k)
            .ok_or_else(|| format!("`{name}` is not a timer of function `{}`", n.name))
    };
    Ok(match a {
        ActionDecl::Extend(name) | ActionDecl::Retract(name) => {
            let extend = matches!(a, ActionDecl::Extend(_));
            let w = r.actuator(name).ok_or_else(|| {
                format!(
                    "role `{}` has no actuator `{name}` (function `{}`)",
                    r.name, n.name
                )
            })?;
            let (mask, value) = w.drive(extend);
            let label = format!("{name}{}", if extend { '+' } else { '-' });
            ActionIr::Drive { mask, value, label }
        }
        ActionDecl::Out(name, level) => {
            let o = r
                .outputs
                .iter()
                .position(|o| o.name == *name)
                .ok_or_else(|| {
                    format!(
                        "role `{}` has no output `{name}` (function `{}`)",
                        r.name, n.name
                    )
                })?;
            let bit = crate::ir::OutputIndex(o).bit();
            ActionIr::Drive {
                mask: bit,
                value: if *level { bit } else { 0 },
                label: format!("{name}={}", u8::from(*level)),
            }
        }
        ActionDecl::StartTimer(name, ms) => ActionIr::StartTimer {
            timer: timer(name)?,
            ms: *ms,
        },
        ActionDecl::CancelTimer(name) => ActionIr::CancelTimer(timer(name)?),
        ActionDecl::Fault(code) => ActionIr::Fault(*code),
        ActionDecl::Set(..) | ActionDecl::Emit(_) => {
            return Err(format!(
                "function `{}`: a control function has no variables nor output events",
                n.name
            ))
        }
    })
}
