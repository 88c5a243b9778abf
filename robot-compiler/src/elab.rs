//! Explicit charts -> IR: instantiates the chart types of each role with their parameter
//! values, binds names (variables, inputs, timers, actuators, outputs, events), compiles
//! guards, and turns connections that cross roles into imports (publications /
//! subscriptions after lowering). Problems come back as diagnostics with spans.

use std::collections::BTreeSet;

use crate::diag::Diagnostic;
use crate::expr::{self, Operand};
use crate::ir::{ActionIr, ChartIr, InputIr, Ir, OutputIr, RoleIr, StateIr, TimerIr, TransitionIr};
use crate::model::{ActionDecl, ChartType, Robot, Role};
use crate::source::Source;

/// Why the robot's `start` names no single input.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum StartError {
    #[error("no role has an input `{0}`")]
    NoInput(String),
    #[error("several roles have an input `{0}`: write `ROLE/{0}`")]
    Ambiguous(String),
}

/// Why a role has no node address.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AddressError {
    #[error("role `{0}` is assigned to no node")]
    Unassigned(String),
    #[error("unknown node `{0}`")]
    UnknownNode(String),
}

/// The role index and input name of the robot's `start`, if it has one.
pub fn start_input(robot: &Robot) -> Result<Option<(usize, String)>, StartError> {
    let Some(start) = &robot.start else {
        return Ok(None);
    };
    let found: Vec<usize> = match start.split_once('/') {
        Some((role, input)) => robot
            .role(role)
            .filter(|(_, r)| r.inputs.iter().any(|i| i.name == input))
            .map(|(i, _)| vec![i])
            .unwrap_or_default(),
        None => robot
            .roles
            .iter()
            .enumerate()
            .filter(|(_, r)| r.inputs.iter().any(|i| &i.name == start))
            .map(|(i, _)| i)
            .collect(),
    };
    let name = start.rsplit('/').next().unwrap_or(start).to_string();
    match found.as_slice() {
        [one] => Ok(Some((*one, name))),
        [] => Err(StartError::NoInput(start.clone())),
        _ => Err(StartError::Ambiguous(start.clone())),
    }
}

/// The short address of the node playing `role`.
pub fn address(robot: &Robot, role: &str) -> Result<u16, AddressError> {
    let node = robot
        .assign
        .iter()
        .find(|(r, _)| r == role)
        .map(|(_, n)| n)
        .ok_or_else(|| AddressError::Unassigned(role.to_string()))?;
    robot
        .nodes
        .iter()
        .find(|n| &n.name == node)
        .map(|n| n.address)
        .ok_or_else(|| AddressError::UnknownNode(node.clone()))
}

/// The events a role can raise, by name, for a connection source.
pub fn role_events(robot: &Robot, role: &Role) -> Vec<String> {
    let mut out = Vec::new();
    for i in &role.inputs {
        out.push(i.name.clone());
        out.push(format!("{}.fall", i.name));
    }
    for a in &role.actuators {
        for (s, _, used) in a.kind.pins() {
            if used == crate::model::PinUse::Switch {
                out.push(format!("{}.{s}", a.name));
                out.push(format!("{}.{s}.fall", a.name));
            }
        }
    }
    for c in &role.charts {
        if let Some((_, t)) = robot.chart_type(&c.type_) {
            for o in &t.outputs {
                out.push(format!("{}.{o}", c.name));
            }
        }
    }
    out
}

/// Splits a connection source `ROLE/EVENT` or `EVENT` (of `own`).
pub fn split_source<'a>(source: &'a str, own: &'a str) -> (&'a str, &'a str) {
    source.split_once('/').unwrap_or((own, source))
}

/// Elaborates a robot with explicit charts.
pub fn elaborate(robot: &Robot, src: &Source) -> Result<Ir, Vec<Diagnostic>> {
    let mut diags = Vec::new();
    // Which (role, event) each connection asks for.
    let mut wanted: BTreeSet<(String, String)> = BTreeSet::new();
    for (ri, role) in robot.roles.iter().enumerate() {
        for (ci, c) in role.charts.iter().enumerate() {
            for (key, source) in &c.on {
                let (r, e) = split_source(source, &role.name);
                let path = format!("roles[{ri}].charts[{ci}].on.{key}");
                match robot.role(r) {
                    None => diags.push(
                        Diagnostic::error(src.span(&path), format!("unknown role `{r}`"))
                            .label("no role has this name"),
                    ),
                    Some((_, rr)) if !role_events(robot, rr).iter().any(|x| x == e) => diags.push(
                        Diagnostic::error(
                            src.span(&path),
                            format!("unknown event `{e}` of role `{r}`"),
                        )
                        .label("no input, switch or chart output has this name")
                        .help(format!(
                            "events of `{r}`: {}",
                            role_events(robot, rr).join(", ")
                        )),
                    ),
                    Some(_) => {
                        wanted.insert((r.to_string(), e.to_string()));
                    }
                }
            }
        }
    }
    let start = match start_input(robot) {
        Ok(s) => s,
        Err(e) => {
            diags.push(Diagnostic::error(src.span("start"), e.to_string()));
            None
        }
    };
    if let Some((r, name)) = &start {
        wanted.insert((robot.roles[*r].name.clone(), name.clone()));
    }
    let mut roles = Vec::new();
    for (ri, role) in robot.roles.iter().enumerate() {
        let address = address(robot, &role.name).unwrap_or_default();
        let mut r = RoleIr {
            name: role.name.clone(),
            address,
            ..RoleIr::default()
        };
        let want = |e: &str| wanted.contains(&(role.name.clone(), e.to_string()));
        // Hardware: every declared pin.
        for a in &role.actuators {
            r.declare_actuator(a, want, want);
        }
        for i in &role.inputs {
            let fall = format!("{}.fall", i.name);
            r.inputs.push(InputIr {
                rise: want(&i.name).then(|| i.name.clone()),
                fall: want(&fall).then_some(fall),
                var: None,
                name: i.name.clone(),
                pin: i.pin,
            });
        }
        for o in &role.outputs {
            r.outputs.push(OutputIr {
                name: o.name.clone(),
                pin: o.pin,
                safe: o.safe,
            });
        }
        for i in r.inputs.clone() {
            for e in [i.rise, i.fall].into_iter().flatten() {
                r.event(&e);
            }
        }
        if let Some((sr, name)) = &start {
            if *sr == ri {
                r.start = Some(name.clone());
            }
        }
        for ci in 0..role.charts.len() {
            match chart(robot, src, &mut r, role, ri, ci) {
                Ok(chart) => r.charts.push(chart),
                Err(mut d) => diags.append(&mut d),
            }
        }
        // Routes from the connections.
        for (ci, c) in role.charts.iter().enumerate() {
            let Some((_, t)) = robot.chart_type(&c.type_) else {
                continue;
            };
            for (key, source) in &c.on {
                let Some(input) = t.inputs.iter().position(|i| i == key) else {
                    diags.push(
                        Diagnostic::error(
                            src.key_span(&format!("roles[{ri}].charts[{ci}].on.{key}")),
                            format!("chart type `{}` has no input event `{key}`", t.name),
                        )
                        .help(format!("its inputs: {}", t.inputs.join(", "))),
                    );
                    continue;
                };
                let (sr, e) = split_source(source, &role.name);
                let local = if sr == role.name {
                    e.to_string()
                } else {
                    let local = format!("{sr}/{e}");
                    if !r.imports.iter().any(|(_, _, l)| *l == local) {
                        r.imports
                            .push((sr.to_string(), e.to_string(), local.clone()));
                    }
                    local
                };
                r.event(&local);
                r.routes.push((local, ci, input));
            }
            // Timer expiries go to the chart input of the timer's name.
            for (k, timer) in t.timers.iter().enumerate() {
                let name = format!("{}.{timer}", c.name);
                r.event(&name);
                r.routes.push((name, ci, t.inputs.len() + k));
            }
        }
        roles.push(r);
    }
    let expect = match &robot.expect {
        Some(text) => crate::ir::parse_steps(text)
            .into_iter()
            .filter_map(|(s, _)| s.ok())
            .collect(),
        None => Vec::new(),
    };
    if !diags.is_empty() {
        return Err(diags);
    }
    Ok(Ir {
        name: robot.name.clone(),
        generation: robot.generation,
        pan_id: robot.network.pan_id,
        channel: robot.network.channel,
        roles,
        start,
        expect,
    })
}

/// An expression error at its span inside the string value at `path`.
pub fn expr_error(src: &Source, path: &str, e: &expr::ExprError) -> Diagnostic {
    let base = string_start(src, path);
    Diagnostic::error(base + e.span.start..base + e.span.end, e.message.clone())
}

/// A transition naming a state its chart type does not have.
pub fn unknown_state(src: &Source, t: &ChartType, path: &str, name: &str) -> Diagnostic {
    let states: Vec<&str> = t.states.iter().map(|s| s.name.as_str()).collect();
    Diagnostic::error(src.span(path), format!("unknown state `{name}`")).help(format!(
        "states of `{}`: {}",
        t.name,
        states.join(", ")
    ))
}

/// A transition triggered by an event its chart type does not have.
pub fn unknown_chart_event(src: &Source, t: &ChartType, path: &str, on: &str) -> Diagnostic {
    let inputs: Vec<&str> = t
        .inputs
        .iter()
        .chain(&t.timers)
        .map(String::as_str)
        .collect();
    Diagnostic::error(
        src.span(path),
        format!(
            "unknown event `{on}`: not an input or timer of chart type `{}`",
            t.name
        ),
    )
    .help(format!("inputs and timers: {}", inputs.join(", ")))
}

/// Offset of a string value's first character (after the opening quote).
pub fn string_start(src: &Source, path: &str) -> usize {
    let span = src.span(path);
    let text = src.slice(span.clone());
    let skip = if text.starts_with('r') {
        text.find('"').map_or(0, |i| i + 1)
    } else {
        usize::from(text.starts_with('"'))
    };
    span.start + skip
}

fn chart(
    robot: &Robot,
    src: &Source,
    r: &mut RoleIr,
    role: &Role,
    ri: usize,
    ci: usize,
) -> Result<ChartIr, Vec<Diagnostic>> {
    let c = &role.charts[ci];
    let at = format!("roles[{ri}].charts[{ci}]");
    let Some((ti, t)) = robot.chart_type(&c.type_) else {
        return Err(vec![Diagnostic::error(
            src.span(&format!("{at}.type")),
            format!("unknown chart type `{}`", c.type_),
        )
        .help(format!(
            "chart types: {}",
            robot
                .chart_types
                .iter()
                .map(|t| t.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ))]);
    };
    let mut diags = Vec::new();
    let tp = format!("chart_types[{ti}]");
    for p in &t.params {
        if !c.params.contains_key(p) {
            diags.push(Diagnostic::error(
                src.span(&format!("{at}.params")),
                format!("parameter `{p}` of chart type `{}` has no value", t.name),
            ));
        }
    }
    for p in c.params.keys() {
        if !t.params.contains(p) {
            diags.push(Diagnostic::error(
                src.key_span(&format!("{at}.params.{p}")),
                format!("chart type `{}` has no parameter `{p}`", t.name),
            ));
        }
    }
    let param = |n: &str| c.params.get(n).copied();
    // Variables: `chart.var` in the node's pool.
    let var_base = r.vars.len();
    for (vi, v) in t.vars.iter().enumerate() {
        let path = format!("{tp}.vars[{vi}].init");
        let init = match expr::parse(&v.init) {
            Ok(ast) => match expr::eval(&ast, &|n| param(n)) {
                Some(x) => x,
                None => {
                    diags.push(Diagnostic::error(
                        src.span(&path),
                        format!(
                            "the initial value of `{}` may only use numbers and parameters",
                            v.name
                        ),
                    ));
                    0
                }
            },
            Err(e) => {
                diags.push(expr_error(src, &path, &e));
                0
            }
        };
        r.vars.push((format!("{}.{}", c.name, v.name), init));
    }
    let timer_base = r.timers.len();
    for timer in &t.timers {
        let name = format!("{}.{timer}", c.name);
        r.timers.push(TimerIr {
            name: name.clone(),
            event: name,
        });
    }
    let inputs_snapshot = r.inputs.clone();
    let resolve = |n: &str| -> Option<Operand> {
        if let Some(i) = t.vars.iter().position(|v| v.name == n) {
            return Some(Operand::Var((var_base + i) as u8));
        }
        if let Some(x) = param(n) {
            return Some(Operand::Const(x));
        }
        inputs_snapshot
            .iter()
            .position(|i| i.name == n)
            .map(|i| Operand::Input(i as u8))
    };
    let state_of = |name: &str| t.states.iter().position(|s| s.name == name);
    let mut states = Vec::new();
    for (si, s) in t.states.iter().enumerate() {
        let mut actions = Vec::new();
        for (ai, a) in s.actions.iter().enumerate() {
            let path = format!("{tp}.states[{si}].actions[{ai}]");
            let here = src.span(&path);
            let err = |m: String| Diagnostic::error(here.clone(), m);
            let out_index = |name: &str| r.outputs.iter().position(|o| o.name == name);
            match a {
                ActionDecl::Set(var, text) => {
                    let Some(v) = t.vars.iter().position(|x| &x.name == var) else {
                        diags.push(err(format!(
                            "`{var}` is not a variable of chart type `{}`",
                            t.name
                        )));
                        continue;
                    };
                    let ops = expr::parse(text).and_then(|ast| expr::compile(&ast, &resolve));
                    match ops {
                        Ok(ops) => actions.push(ActionIr::Set {
                            var: var_base + v,
                            text: text.clone(),
                            ops,
                        }),
                        Err(e) => diags.push(expr_error(src, &format!("{path}[1]"), &e)),
                    }
                }
                ActionDecl::Emit(o) => {
                    if t.outputs.contains(o) {
                        let e = format!("{}.{o}", c.name);
                        r.event(&e);
                        actions.push(ActionIr::Emit(e));
                    } else {
                        diags.push(err(format!(
                            "`{o}` is not an output event of chart type `{}`",
                            t.name
                        )));
                    }
                }
                ActionDecl::Extend(name) | ActionDecl::Retract(name) => {
                    let extend = matches!(a, ActionDecl::Extend(_));
                    let sign = if extend { '+' } else { '-' };
                    let label = format!("{name}{sign}");
                    if let Some(w) = r.actuator(name) {
                        let (mask, value) = w.drive(extend);
                        actions.push(ActionIr::Drive { mask, value, label });
                    } else {
                        diags.push(err(format!(
                            "role `{}` has no actuator `{name}` (chart `{}`)",
                            role.name, c.name
                        )));
                    }
                }
                ActionDecl::Out(name, level) => match out_index(name) {
                    Some(o) => actions.push(ActionIr::Drive {
                        mask: 1 << o,
                        value: if *level { 1 << o } else { 0 },
                        label: format!("{name}={}", u8::from(*level)),
                    }),
                    None => diags.push(err(format!(
                        "role `{}` has no output `{name}` (chart `{}`)",
                        role.name, c.name
                    ))),
                },
                ActionDecl::StartTimer(name, _) | ActionDecl::CancelTimer(name)
                    if !t.timers.contains(name) =>
                {
                    diags.push(err(format!(
                        "`{name}` is not a timer of chart type `{}`",
                        t.name
                    )));
                }
                ActionDecl::StartTimer(name, ms) => {
                    let k = t.timers.iter().position(|x| x == name).unwrap_or(0);
                    actions.push(ActionIr::StartTimer {
                        timer: timer_base + k,
                        ms: *ms,
                    });
                }
                ActionDecl::CancelTimer(name) => {
                    let k = t.timers.iter().position(|x| x == name).unwrap_or(0);
                    actions.push(ActionIr::CancelTimer(timer_base + k));
                }
                ActionDecl::Fault(code) => actions.push(ActionIr::Fault(*code)),
            }
        }
        states.push(StateIr {
            name: s.name.clone(),
            actions,
        });
    }
    let inputs: Vec<String> = t.inputs.iter().chain(t.timers.iter()).cloned().collect();
    let mut transitions = Vec::new();
    for (k, tr) in t.transitions.iter().enumerate() {
        let path = format!("{tp}.transitions[{k}]");
        let from = state_of(&tr.from);
        let to = state_of(&tr.to);
        for (name, found, field) in [(&tr.from, from, "from"), (&tr.to, to, "to")] {
            if found.is_none() {
                diags.push(unknown_state(src, t, &format!("{path}.{field}"), name));
            }
        }
        let trigger = match &tr.on {
            Some(on) => match inputs.iter().position(|i| i == on) {
                Some(i) => Some(i),
                None => {
                    diags.push(unknown_chart_event(src, t, &format!("{path}.on"), on));
                    None
                }
            },
            None => None,
        };
        let guard = match &tr.when {
            Some(text) => match expr::parse(text).and_then(|ast| expr::compile(&ast, &resolve)) {
                Ok(ops) => Some((text.clone(), ops)),
                Err(e) => {
                    diags.push(expr_error(src, &format!("{path}.when"), &e));
                    None
                }
            },
            None => None,
        };
        if let (Some(from), Some(to)) = (from, to) {
            transitions.push(TransitionIr {
                from,
                to,
                trigger,
                guard,
            });
        }
    }
    if !diags.is_empty() {
        return Err(diags);
    }
    Ok(ChartIr {
        name: c.name.clone(),
        inputs,
        initial: 0,
        states,
        transitions,
    })
}
