//! Explicit charts -> IR: instantiates the chart types of each role with their parameter
//! values, binds names (variables, inputs, timers, actuators, outputs, events), compiles
//! guards, and turns connections that cross roles into imports (publications /
//! subscriptions after lowering). Problems come back as diagnostics with spans.

use std::collections::{BTreeMap, BTreeSet};
use std::ops::Range;

use crate::diag::Diagnostic;
use crate::expr::{self, Operand};
use crate::ir::{ActionIr, ChartIr, InputIr, Ir, RoleIr, StateIr, TimerIr, TransitionIr};
use crate::model::{ActionDecl, ChartInstance, ChartType, Robot, Role};
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
    named_input(robot, robot.start.as_ref())
}

/// The role and input name of the robot's `home` input (`NAME` or `ROLE/NAME`), if it
/// declares one.
pub fn home_input(robot: &Robot) -> Result<Option<(usize, String)>, StartError> {
    named_input(robot, robot.home.as_ref())
}

fn named_input(
    robot: &Robot,
    start: Option<&String>,
) -> Result<Option<(usize, String)>, StartError> {
    let Some(start) = start else {
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
    // A sorting station's classification chart (crate::sorting).
    if let Some(s) = robot.sorting.as_ref().filter(|s| s.role == role.name) {
        out.extend(s.events());
    }
    // What an application brings: node events of their own, timers its charts share.
    out.extend(role.node_events.iter().cloned());
    for t in role.charts.iter().flat_map(|c| c.timers.values()) {
        if !out.contains(t) {
            out.push(t.clone());
        }
    }
    out
}

/// The name of timer `timer` of chart `c` in its role: the role's timer it shares, or
/// its own `CHART.TIMER`.
fn timer_name(c: &ChartInstance, timer: &str) -> String {
    (c.timers.get(timer).cloned()).unwrap_or_else(|| format!("{}.{timer}", c.name))
}

/// Splits a connection source `ROLE/EVENT` or `EVENT` (of `own`).
pub fn split_source<'a>(source: &'a str, own: &'a str) -> (&'a str, &'a str) {
    source.split_once('/').unwrap_or((own, source))
}

/// Elaborates a robot with explicit charts.
pub fn elaborate(robot: &Robot, src: &Source) -> Result<Ir, Vec<Diagnostic>> {
    let mut diags = Vec::new();
    let mut wanted = wanted(robot, src, &mut diags);
    let nets = crate::petri::load(robot, src).nets();
    wanted.extend(crate::petri::compile::wanted(&nets));
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
        let mut r = hardware(robot, role, &wanted);
        if let Some((sr, name)) = &start {
            if *sr == ri {
                r.start = Some(name.clone());
            }
        }
        let pool = var_pool(robot, role, r.vars.len());
        for ci in 0..role.charts.len() {
            match chart(robot, src, &mut r, role, ri, ci, &pool) {
                Ok(chart) => r.charts.push(chart),
                Err(mut d) => diags.append(&mut d),
            }
        }
        routes(robot, src, &mut r, role, ri, &mut diags);
        if let Err(e) = crate::petri::compile::charts(robot, &nets, &mut r) {
            diags.push(Diagnostic::error(src.span("functions"), e));
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
        home: None,
        homing: Vec::new(),
        homing_derived: false,
    })
}

/// Where each variable of the role's charts will be in the role's pool (`CHART.VAR` ->
/// index), the first at `base`: the charts declare theirs in order, so a chart may read
/// the variable of one declared after it ([`ChartInstance::reads`]). Stops at a chart of
/// an unknown type (an error of its own).
fn var_pool(robot: &Robot, role: &Role, base: usize) -> BTreeMap<String, usize> {
    let mut pool = BTreeMap::new();
    let mut k = base;
    for c in &role.charts {
        let Some((_, t)) = robot.chart_type(&c.type_) else {
            break;
        };
        for v in &t.vars {
            pool.insert(format!("{}.{}", c.name, v.name), k);
            k += 1;
        }
    }
    pool
}

/// Which (role, event) the connections ask for; an error for each connection from an
/// unknown role or event.
fn wanted(robot: &Robot, src: &Source, diags: &mut Vec<Diagnostic>) -> BTreeSet<(String, String)> {
    let mut wanted = BTreeSet::new();
    // Each role's events, found once (a role of many charts has many sources).
    let mut events: BTreeMap<usize, BTreeSet<String>> = BTreeMap::new();
    for (ri, role) in robot.roles.iter().enumerate() {
        for (ci, c) in role.charts.iter().enumerate() {
            for (key, source) in c.sources() {
                let (r, e) = split_source(source, &role.name);
                let path = format!("roles[{ri}].charts[{ci}].on.{key}");
                let mut known = |at: usize, rr: &Role| {
                    events
                        .entry(at)
                        .or_insert_with(|| role_events(robot, rr).into_iter().collect())
                        .contains(e)
                };
                match robot.role(r) {
                    None => diags.push(
                        Diagnostic::error(src.span(&path), format!("unknown role `{r}`"))
                            .label("no role has this name"),
                    ),
                    Some((at, rr)) if !known(at, rr) => {
                        // A source the robot file's `application.on` gives: at its key
                        // there (the role's block was underlined); one the application's
                        // XML gives: at its connection.
                        let ron = (c.declared.as_ref()).and_then(|d| d.ron_on.get(key));
                        let here = match ron {
                            Some(k) => src.map_key_span("application.on", k),
                            None => src.span(&path),
                        };
                        let d =
                            Diagnostic::error(here, format!("unknown event `{e}` of role `{r}`"))
                                .label("no input, switch or chart output has this name")
                                .help(format!(
                                    "events of `{r}`: {}",
                                    role_events(robot, rr).join(", ")
                                ));
                        diags.push(match ron {
                            Some(_) => d,
                            None => d.of_chart(src, c, Some(key)),
                        });
                    }
                    Some(_) => {
                        wanted.insert((r.to_string(), e.to_string()));
                    }
                }
            }
        }
    }
    wanted
}

/// A role's IR with its hardware: every declared pin, an input raising its events only
/// if some connection (or `start`) wants them.
fn hardware(robot: &Robot, role: &Role, wanted: &BTreeSet<(String, String)>) -> RoleIr {
    let mut r = RoleIr {
        name: role.name.clone(),
        address: address(robot, &role.name).unwrap_or_default(),
        ..RoleIr::default()
    };
    let want = |e: &str| wanted.contains(&(role.name.clone(), e.to_string()));
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
    r.declare_plain_outputs(role);
    for i in r.inputs.clone() {
        for e in [i.rise, i.fall].into_iter().flatten() {
            r.event(&e);
        }
    }
    // The node's boot and the HOME command, when a chart reads them.
    for e in role.node_events.iter().filter(|e| want(e)) {
        r.event(e);
        if e == crate::synth::BOOT_EVENT {
            r.boot = Some(e.clone());
        } else if e == crate::synth::HOME_COMMAND_EVENT && r.home.is_none() {
            r.home = Some(e.clone());
        }
    }
    r
}

/// The routes of a role's charts: each connection to its chart input (a connection from
/// another role is imported), each timer's expiry to the input of the timer's name.
fn routes(
    robot: &Robot,
    src: &Source,
    r: &mut RoleIr,
    role: &Role,
    ri: usize,
    diags: &mut Vec<Diagnostic>,
) {
    for (ci, c) in role.charts.iter().enumerate() {
        let Some((_, t)) = robot.chart_type(&c.type_) else {
            continue;
        };
        for (key, source) in c.sources() {
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
        for (k, timer) in t.timers.iter().enumerate() {
            let name = timer_name(c, timer);
            r.event(&name);
            r.routes.push((name, ci, t.inputs.len() + k));
        }
    }
}

/// An expression error at its span inside the string value at `path`.
pub fn expr_error(src: &Source, path: &str, e: &expr::ExprError) -> Diagnostic {
    Diagnostic::error(
        StrMap::new(src, path).span(e.span.clone()),
        e.message.clone(),
    )
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

/// Where the text of the RON string at `path` lies in the file: a span of the string's
/// value (escapes decoded) mapped to the bytes of the file that wrote it.
pub struct StrMap {
    /// The file offset of the value's first byte.
    start: usize,
    /// After each escape: (offset in the value, offset in the literal after the quote).
    escapes: Vec<(usize, usize)>,
}

impl StrMap {
    /// The string at `path` (raw strings `r#"..."#` have no escapes).
    pub fn new(src: &Source, path: &str) -> StrMap {
        let span = src.span(path);
        let text = src.slice(span.clone());
        let (skip, escaped) = if text.starts_with('r') {
            (text.find('"').map_or(0, |i| i + 1), false)
        } else {
            (usize::from(text.starts_with('"')), true)
        };
        let mut escapes = Vec::new();
        if escaped {
            let body = text.get(skip..).unwrap_or("").as_bytes();
            let (mut raw, mut value) = (0, 0);
            while let Some(&b) = body.get(raw) {
                if b == b'"' {
                    break;
                }
                if b != b'\\' {
                    raw += 1;
                    value += 1;
                    continue;
                }
                // `\u{X..}`: the char's UTF-8 length; `\xNN` and one-char escapes: one byte;
                // a line continuation (`\` at the end of a line): nothing, the next line's
                // leading whitespace skipped.
                let continued = match (body.get(raw + 1), body.get(raw + 2)) {
                    (Some(b'\n'), _) => Some(2),
                    (Some(b'\r'), Some(b'\n')) => Some(3),
                    _ => None,
                };
                if let Some(newline) = continued {
                    raw += newline;
                    while body.get(raw).is_some_and(u8::is_ascii_whitespace) {
                        raw += 1;
                    }
                    escapes.push((value, raw));
                    continue;
                }
                let (len, decoded) = match body.get(raw + 1) {
                    Some(b'u') => {
                        let close = body
                            .get(raw..)
                            .unwrap_or(&[])
                            .iter()
                            .position(|&c| c == b'}');
                        let code = close.and_then(|c| {
                            let hex = std::str::from_utf8(body.get(raw + 3..raw + c)?).ok()?;
                            char::from_u32(u32::from_str_radix(hex, 16).ok()?)
                        });
                        (close.map_or(2, |c| c + 1), code.map_or(1, char::len_utf8))
                    }
                    Some(b'x') => (4, 1),
                    _ => (2, 1),
                };
                raw += len;
                value += decoded;
                escapes.push((value, raw));
            }
        }
        StrMap {
            start: span.start + skip,
            escapes,
        }
    }

    /// The file offset of byte `offset` of the value.
    pub fn at(&self, offset: usize) -> usize {
        let k = self.escapes.partition_point(|&(value, _)| value <= offset);
        match k.checked_sub(1).and_then(|k| self.escapes.get(k)) {
            Some(&(value, raw)) => self.start + raw + (offset - value),
            None => self.start + offset,
        }
    }

    /// The file span of a span of the value.
    pub fn span(&self, span: Range<usize>) -> Range<usize> {
        self.at(span.start)..self.at(span.end)
    }
}

/// Instantiates chart `ci` of role `ri` (its type with the instance's parameters) into
/// `r`: its variables and timers join the role's pools.
fn chart(
    robot: &Robot,
    src: &Source,
    r: &mut RoleIr,
    role: &Role,
    ri: usize,
    ci: usize,
    pool: &BTreeMap<String, usize>,
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
    instantiate(
        src,
        &format!("chart_types[{ti}]"),
        role,
        c,
        t,
        &BTreeMap::new(),
        pool,
        r,
        &at,
    )
}

/// Instantiates chart type `t` (written at `tp` of `src`) as chart `c` of `role` into `r`
/// (`at`: the instance's path). `bind` names the event a chart output is emitted as
/// (default `CHART.OUTPUT`): the generated charts of an automaton emit its `EOS` so.
/// `pool`: where the role's charts' variables are (`CHART.VAR` -> index, [`var_pool`]),
/// for the parameters the instance reads from another chart's variable.
#[allow(clippy::too_many_arguments)]
pub(crate) fn instantiate(
    src: &Source,
    tp: &str,
    role: &Role,
    c: &ChartInstance,
    t: &ChartType,
    bind: &BTreeMap<String, String>,
    pool: &BTreeMap<String, usize>,
    r: &mut RoleIr,
    at: &str,
) -> Result<ChartIr, Vec<Diagnostic>> {
    let mut cx = ChartCx {
        src,
        role,
        c,
        t,
        tp: tp.to_string(),
        bind,
        pool,
        var_base: r.vars.len(),
        timers: Vec::new(),
        inputs: Vec::new(),
        diags: Vec::new(),
    };
    cx.params(at);
    cx.declare(r);
    let mut states = Vec::new();
    for (si, s) in t.states.iter().enumerate() {
        let mut actions = Vec::new();
        for (ai, a) in s.actions.iter().enumerate() {
            actions.extend(cx.action(r, &format!("{}.states[{si}].actions[{ai}]", cx.tp), a));
        }
        states.push(StateIr {
            name: s.name.clone(),
            actions,
        });
    }
    let inputs: Vec<String> = t.inputs.iter().chain(t.timers.iter()).cloned().collect();
    let transitions = (0..t.transitions.len())
        .filter_map(|k| cx.transition(&inputs, k))
        .collect();
    if !cx.diags.is_empty() {
        return Err(cx.diags);
    }
    let idle = (t.idle.as_ref())
        .and_then(|i| t.states.iter().position(|s| s.name == *i))
        .unwrap_or(0);
    let rests = (t.rests.iter())
        .filter_map(|r| t.states.iter().position(|s| s.name == *r))
        .collect();
    Ok(ChartIr {
        name: c.name.clone(),
        inputs,
        initial: 0,
        idle,
        rests,
        states,
        transitions,
    })
}

/// One chart instance being elaborated: its type, where its variables and timers start in
/// the role's pools, and the problems found.
struct ChartCx<'a> {
    src: &'a Source,
    role: &'a Role,
    c: &'a ChartInstance,
    t: &'a ChartType,
    /// The path of the chart type (`chart_types[i]`).
    tp: String,
    /// Outputs emitted as another event than `CHART.OUTPUT`.
    bind: &'a BTreeMap<String, String>,
    /// The role's variables (`CHART.VAR` -> index) the instance's reads name.
    pool: &'a BTreeMap<String, usize>,
    var_base: usize,
    /// The role's timer of each of the type's timers.
    timers: Vec<usize>,
    /// The role's inputs (expressions may read them).
    inputs: Vec<InputIr>,
    diags: Vec<Diagnostic>,
}

impl ChartCx<'_> {
    fn param(&self, n: &str) -> Option<i32> {
        self.c.params.get(n).copied()
    }

    /// Every parameter of the type has a value, every value a parameter (`at`: the
    /// instance's path).
    fn params(&mut self, at: &str) {
        let (src, c, t) = (self.src, self.c, self.t);
        for (p, var) in &c.reads {
            if !t.params.contains(p) {
                self.diags.push(Diagnostic::error(
                    src.span(at),
                    format!(
                        "chart type `{}` has no parameter `{p}` (chart `{}` reads `{var}` into it)",
                        t.name, c.name
                    ),
                ));
            } else if !self.pool.contains_key(var) {
                self.diags.push(Diagnostic::error(
                    src.span(at),
                    format!(
                        "parameter `{p}` of chart `{}` reads `{var}`: no chart of role `{}` has \
                         that variable",
                        c.name, self.role.name
                    ),
                ));
            }
        }
        for p in &t.params {
            if !c.params.contains_key(p) && !c.reads.contains_key(p) {
                self.diags.push(Diagnostic::error(
                    src.span(&format!("{at}.params")),
                    format!("parameter `{p}` of chart type `{}` has no value", t.name),
                ));
            }
        }
        for p in c.params.keys() {
            if !t.params.contains(p) {
                self.diags.push(Diagnostic::error(
                    src.key_span(&format!("{at}.params.{p}")),
                    format!("chart type `{}` has no parameter `{p}`", t.name),
                ));
            }
        }
    }

    /// Adds the chart's variables (`chart.var`, with their initial values) and timers to
    /// the role's pools.
    fn declare(&mut self, r: &mut RoleIr) {
        let (src, c, t) = (self.src, self.c, self.t);
        for (vi, v) in t.vars.iter().enumerate() {
            let path = format!("{}.vars[{vi}].init", self.tp);
            let init = match expr::parse(&v.init) {
                Ok(ast) => match expr::eval(&ast, &|n| self.param(n)) {
                    Some(x) => x,
                    None => {
                        self.diags.push(Diagnostic::error(
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
                    self.diags.push(expr_error(src, &path, &e));
                    0
                }
            };
            r.vars.push((format!("{}.{}", c.name, v.name), init));
        }
        self.timers.clear();
        for timer in &t.timers {
            let name = timer_name(c, timer);
            let k = match r.timers.iter().position(|x| x.name == name) {
                Some(k) => k,
                None => {
                    r.timers.push(TimerIr {
                        name: name.clone(),
                        event: name,
                    });
                    r.timers.len() - 1
                }
            };
            self.timers.push(k);
        }
        self.inputs = r.inputs.clone();
    }

    /// What a name of an expression reads: a variable of the chart, a parameter (a
    /// constant, or the role's variable it reads) or an input of the role.
    fn resolve(&self, n: &str) -> Option<Operand> {
        if let Some(i) = self.t.vars.iter().position(|v| v.name == n) {
            return Some(Operand::Var((self.var_base + i) as u8));
        }
        if let Some(var) = self.c.reads.get(n) {
            // A variable the pool lacks is an error of `params` already: no second one.
            let k = self.pool.get(var);
            return Some(k.map_or(Operand::Const(0), |k| Operand::Var(*k as u8)));
        }
        if let Some(x) = self.param(n) {
            return Some(Operand::Const(x));
        }
        self.inputs
            .iter()
            .position(|i| i.name == n)
            .map(|i| Operand::Input(i as u8))
    }

    /// An expression's bytecode, or an error at its place inside the string at `path`.
    fn bytecode(&mut self, text: &str, path: &str) -> Option<Vec<config_schema::Op>> {
        match expr::parse(text).and_then(|ast| expr::bytecode(&ast, &|n| self.resolve(n))) {
            Ok(ops) => Some(ops),
            Err(e) => {
                self.diags.push(expr_error(self.src, path, &e));
                None
            }
        }
    }

    /// One action of a state (at `path`), or none and an error.
    fn action(&mut self, r: &mut RoleIr, path: &str, a: &ActionDecl) -> Option<ActionIr> {
        let (c, t, role) = (self.c, self.t, self.role);
        let here = self.src.span(path);
        let message = match a {
            ActionDecl::Set(var, text) => {
                let Some(v) = t.vars.iter().position(|x| &x.name == var) else {
                    let m = format!("`{var}` is not a variable of chart type `{}`", t.name);
                    self.diags.push(Diagnostic::error(here, m));
                    return None;
                };
                let ops = self.bytecode(text, &format!("{path}[1]"))?;
                return Some(ActionIr::Set {
                    var: self.var_base + v,
                    text: text.clone(),
                    ops,
                });
            }
            ActionDecl::Emit(o) if t.outputs.contains(o) => {
                let e = self
                    .bind
                    .get(o)
                    .cloned()
                    .unwrap_or_else(|| format!("{}.{o}", c.name));
                r.event(&e);
                return Some(ActionIr::Emit(e));
            }
            ActionDecl::Emit(o) => {
                format!("`{o}` is not an output event of chart type `{}`", t.name)
            }
            ActionDecl::Extend(name) | ActionDecl::Retract(name) => {
                let extend = matches!(a, ActionDecl::Extend(_));
                let sign = if extend { '+' } else { '-' };
                let label = format!("{name}{sign}");
                if let Some(w) = r.actuator(name) {
                    let (mask, value) = w.drive(extend);
                    return Some(ActionIr::Drive { mask, value, label });
                }
                format!(
                    "role `{}` has no actuator `{name}` (chart `{}`)",
                    role.name, c.name
                )
            }
            ActionDecl::Out(name, level) => {
                if let Some(o) = r.outputs.iter().position(|o| o.name == *name) {
                    return Some(ActionIr::Drive {
                        mask: 1 << o,
                        value: if *level { 1 << o } else { 0 },
                        label: format!("{name}={}", u8::from(*level)),
                    });
                }
                format!(
                    "role `{}` has no output `{name}` (chart `{}`)",
                    role.name, c.name
                )
            }
            ActionDecl::StartTimer(name, _) | ActionDecl::CancelTimer(name)
                if !t.timers.contains(name) =>
            {
                format!("`{name}` is not a timer of chart type `{}`", t.name)
            }
            ActionDecl::StartTimer(name, ms) => {
                let k = t.timers.iter().position(|x| x == name).unwrap_or(0);
                return Some(ActionIr::StartTimer {
                    timer: self.timers.get(k).copied().unwrap_or(0),
                    ms: *ms,
                });
            }
            ActionDecl::CancelTimer(name) => {
                let k = t.timers.iter().position(|x| x == name).unwrap_or(0);
                return Some(ActionIr::CancelTimer(
                    self.timers.get(k).copied().unwrap_or(0),
                ));
            }
            ActionDecl::Fault(code) => return Some(ActionIr::Fault(*code)),
        };
        self.diags.push(Diagnostic::error(here, message));
        None
    }

    /// Transition `k` of the chart type (`inputs`: the chart's input events), or none if
    /// a state it names does not exist.
    fn transition(&mut self, inputs: &[String], k: usize) -> Option<TransitionIr> {
        let (src, t) = (self.src, self.t);
        let tr = &t.transitions[k];
        let path = format!("{}.transitions[{k}]", self.tp);
        let state_of = |name: &str| t.states.iter().position(|s| s.name == name);
        let from = state_of(&tr.from);
        let to = state_of(&tr.to);
        for (name, found, field) in [(&tr.from, from, "from"), (&tr.to, to, "to")] {
            if found.is_none() {
                self.diags
                    .push(unknown_state(src, t, &format!("{path}.{field}"), name));
            }
        }
        let trigger = match &tr.on {
            Some(on) => match inputs.iter().position(|i| i == on) {
                Some(i) => Some(i),
                None => {
                    self.diags
                        .push(unknown_chart_event(src, t, &format!("{path}.on"), on));
                    None
                }
            },
            None => None,
        };
        let guard = match &tr.when {
            Some(text) => self
                .bytecode(text, &format!("{path}.when"))
                .map(|ops| (text.clone(), ops)),
            None => None,
        };
        Some(TransitionIr {
            from: from?,
            to: to?,
            trigger,
            guard,
        })
    }
}
