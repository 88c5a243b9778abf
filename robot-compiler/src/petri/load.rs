//! The robot's `functions:` -> [`Net`]s: names resolved to indices, the matrix form read
//! into transitions, every part's path kept for diagnostics. A function whose structure
//! is not a state machine with one token (a row of M that is not exactly one `-1` and one
//! `1`, an m(0) without exactly one token, an unknown place) is an error here and is left
//! out; its events and conditions are resolved against every function that loaded.

use std::ops::Range;

use super::model::{FunctionDecl, MatrixDecl};
use super::{levels, place_ref, reads, Event, Net, Transition};
use crate::diag::Diagnostic;
use crate::elab::{expr_error, role_events, StrMap};
use crate::expr::{self, Ast};
use crate::model::{ActionDecl, Robot};
use crate::source::Source;

/// A loaded function and where its parts are written.
#[derive(Debug, Clone, PartialEq)]
pub struct Located {
    pub net: Net,
    /// Its index in the robot's `functions`.
    pub index: usize,
    /// Its index among the functions that loaded (what [`Event::Place`] and
    /// [`super::Reads`] index).
    pub position: usize,
    /// The path of its place names (`functions[i].places` or `functions[i].matrix.places`).
    pub places: String,
    /// The path of each transition (row), by transition.
    pub rows: Vec<String>,
    /// Written as a matrix.
    pub matrix: bool,
}

impl Located {
    /// The path of the function (`functions[i]`).
    pub fn path(&self) -> String {
        format!("functions[{}]", self.index)
    }

    /// The path of a transition's field: `from` / `to` in the place form, the row in the
    /// matrix form.
    pub fn field(&self, t: usize, field: &str) -> String {
        let row = self.rows.get(t).cloned().unwrap_or_else(|| self.path());
        match (self.matrix, field) {
            (true, "from" | "to") => format!("{row}.row"),
            _ => format!("{row}.{field}"),
        }
    }
}

/// Every function that loaded, in declaration order, and every problem found.
#[derive(Debug, Clone, Default)]
pub struct Loaded {
    pub functions: Vec<Located>,
    pub diagnostics: Vec<Diagnostic>,
}

impl Loaded {
    /// The nets alone, in order (what [`Event::Place`] and [`super::Reads`] index).
    pub fn nets(&self) -> Vec<Net> {
        self.functions.iter().map(|l| l.net.clone()).collect()
    }
}

/// Resolves the robot's control functions.
pub fn load(robot: &Robot, src: &Source) -> Loaded {
    let mut out = Loaded::default();
    let mut names: Vec<(&str, usize)> = Vec::new();
    // Functions left out: what names them is not reported again.
    let mut failed: Vec<&str> = Vec::new();
    for (i, decl) in robot.functions.iter().enumerate() {
        let path = format!("functions[{i}]");
        if let Some(&(_, first)) = names.iter().find(|(n, _)| *n == decl.name) {
            out.diagnostics.push(crate::check::duplicate(
                src,
                "function",
                &decl.name,
                &format!("functions[{first}].name"),
                &format!("{path}.name"),
            ));
            continue;
        }
        names.push((&decl.name, i));
        let mut diags = Vec::new();
        match structure(robot, src, decl, i, &mut diags) {
            Some(mut net) if diags.is_empty() => {
                net.position = out.functions.len();
                out.functions.push(net);
            }
            _ => failed.push(decl.name.as_str()),
        }
        out.diagnostics.append(&mut diags);
    }
    let nets = out.nets();
    let mut diags = Vec::new();
    for l in &mut out.functions {
        resolve(robot, src, &nets, l, &mut diags);
    }
    let of_failed = |d: &Diagnostic| {
        let text = src.slice(d.span.clone());
        let text = text.trim_matches('"');
        let function = text.split('/').next_back().unwrap_or(text);
        let function = function.split('.').next().unwrap_or(function);
        failed.contains(&function)
    };
    out.diagnostics
        .extend(diags.into_iter().filter(|d| !of_failed(d)));
    out
}

/// The net of one function, without its events resolved.
fn structure(
    robot: &Robot,
    src: &Source,
    decl: &FunctionDecl,
    i: usize,
    diags: &mut Vec<Diagnostic>,
) -> Option<Located> {
    let path = format!("functions[{i}]");
    let name = &decl.name;
    if name.is_empty() || name.contains(['.', '/', ' ']) {
        diags.push(Diagnostic::error(
            src.span(&format!("{path}.name")),
            format!("function name `{name}` may not be empty nor hold `.`, `/` or spaces"),
        ));
    }
    if robot.role(&decl.role).is_none() {
        diags.push(
            Diagnostic::error(
                src.span(&format!("{path}.role")),
                format!("unknown role `{}`", decl.role),
            )
            .label("no role has this name"),
        );
    } else if let Some((_, role)) = robot.role(&decl.role) {
        let clash = role
            .charts
            .iter()
            .map(|c| &c.name)
            .chain(role.actuators.iter().map(|a| &a.name));
        if clash.into_iter().any(|n| n == name) {
            diags.push(Diagnostic::error(
                src.span(&format!("{path}.name")),
                format!(
                    "function `{name}` has the name of a chart or actuator of role `{}`",
                    decl.role
                ),
            ));
        }
    }
    let placed = !decl.places.is_empty() || decl.initial.is_some() || !decl.transitions.is_empty();
    let mut l = match (&decl.matrix, placed) {
        (Some(_), true) => {
            diags.push(Diagnostic::error(
                src.key_span(&format!("{path}.matrix")),
                format!("function `{name}` is given both as a `matrix` and as `places` / `transitions`: give one"),
            ));
            return None;
        }
        (Some(m), false) => from_matrix(src, decl, m, i, diags)?,
        (None, _) => from_places(src, decl, i, diags)?,
    };
    for (k, t) in decl.timers.iter().enumerate() {
        if decl.timers[..k].contains(t) {
            diags.push(Diagnostic::error(
                src.span(&format!("{path}.timers[{k}]")),
                format!("duplicate timer `{t}` of function `{name}`"),
            ));
        } else if l.net.places.iter().any(|p| p == t) {
            // `F.X` is both the place's entry and the timer's expiry: one event, whose
            // routes took the one for the other (the timed place was left at once).
            diags.push(Diagnostic::error(
                src.span(&format!("{path}.timers[{k}]")),
                format!(
                    "timer `{t}` of function `{name}` is named as one of its places: \
                     `{name}.{t}` would be both the place's entry and the timer's expiry"
                ),
            ));
        }
    }
    l.net.rests = resting_places(src, decl, &l.net, &path, diags);
    l.net.timers = decl.timers.clone();
    l.net.actions = vec![Vec::new(); l.net.places.len()];
    for (place, actions) in &decl.actions {
        let at = format!("{path}.actions.{place}");
        let Some(p) = l.net.place(place) else {
            diags.push(unknown_place(src, &l.net, src.key_span(&at), place));
            continue;
        };
        for (ai, a) in actions.iter().enumerate() {
            let here = src.span(&format!("{at}[{ai}]"));
            match a {
                ActionDecl::Set(..) | ActionDecl::Emit(_) => diags.push(Diagnostic::error(
                    here,
                    "a control function has no variables nor output events: its places are read by name and its place changes are events",
                )),
                ActionDecl::StartTimer(t, _) | ActionDecl::CancelTimer(t)
                    if !decl.timers.contains(t) =>
                {
                    diags.push(Diagnostic::error(
                        here,
                        format!("`{t}` is not a timer of function `{name}`"),
                    ))
                }
                _ => {}
            }
        }
        l.net.actions[p] = actions.clone();
    }
    Some(l)
}

/// The places `rest` names besides the initial one (a table marks a chart's resting
/// states in 32 bits: only the first 32 places can be one).
fn resting_places(
    src: &Source,
    decl: &FunctionDecl,
    net: &Net,
    path: &str,
    diags: &mut Vec<Diagnostic>,
) -> Vec<usize> {
    let mut rests = Vec::new();
    for (k, place) in decl.rest.iter().enumerate() {
        let here = src.span(&format!("{path}.rest[{k}]"));
        match net.place(place) {
            None => diags.push(unknown_place(src, net, here, place)),
            Some(j) if j >= 32 => diags.push(Diagnostic::error(
                here,
                format!(
                    "place `{place}` of function `{}` is number {} of its places: only the first 32 can be resting places",
                    net.name,
                    j + 1
                ),
            )),
            Some(j) if j != net.initial && !rests.contains(&j) => rests.push(j),
            Some(_) => {}
        }
    }
    rests
}

fn unknown_place(src: &Source, net: &Net, span: Range<usize>, name: &str) -> Diagnostic {
    let _ = src;
    Diagnostic::error(span, format!("unknown place `{name}`")).help(format!(
        "places of `{}`: {}",
        net.name,
        net.places.join(", ")
    ))
}

/// A function's places (as the columns of M): duplicates are errors.
fn columns(src: &Source, places: &[String], path: &str, diags: &mut Vec<Diagnostic>) {
    for (j, p) in places.iter().enumerate() {
        if let Some(first) = places[..j].iter().position(|q| q == p) {
            diags.push(crate::check::duplicate(
                src,
                "place",
                p,
                &format!("{path}[{first}]"),
                &format!("{path}[{j}]"),
            ));
        }
    }
}

fn empty_net(decl: &FunctionDecl, places: &[String]) -> Net {
    Net {
        name: decl.name.clone(),
        role: decl.role.clone(),
        places: places.to_vec(),
        initial: 0,
        rests: Vec::new(),
        transitions: Vec::new(),
        timers: Vec::new(),
        actions: Vec::new(),
    }
}

/// The row name of transition `k`: its own or `t1`, `t2`, ...
fn row_name(name: &Option<String>, k: usize) -> String {
    name.clone().unwrap_or_else(|| format!("t{}", k + 1))
}

fn parse_when(
    src: &Source,
    when: &Option<String>,
    path: &str,
    diags: &mut Vec<Diagnostic>,
) -> Option<(String, Ast)> {
    let text = when.as_ref()?;
    match expr::parse(text) {
        Ok(ast) => Some((text.clone(), ast)),
        Err(e) => {
            diags.push(expr_error(src, path, &e));
            None
        }
    }
}

fn from_places(
    src: &Source,
    decl: &FunctionDecl,
    i: usize,
    diags: &mut Vec<Diagnostic>,
) -> Option<Located> {
    let path = format!("functions[{i}]");
    if decl.places.is_empty() {
        diags.push(
            Diagnostic::error(
                src.span(&format!("{path}.name")),
                format!("function `{}` has no places", decl.name),
            )
            .help("give `places`, `initial` and `transitions`, or its `matrix`"),
        );
        return None;
    }
    columns(src, &decl.places, &format!("{path}.places"), diags);
    let mut net = empty_net(decl, &decl.places);
    match &decl.initial {
        None => diags.push(Diagnostic::error(
            src.span(&format!("{path}.name")),
            format!(
                "function `{}` has no `initial` place: m(0) needs exactly one token",
                decl.name
            ),
        )),
        Some(p) => match net.place(p) {
            Some(j) => net.initial = j,
            None => diags.push(unknown_place(
                src,
                &net,
                src.span(&format!("{path}.initial")),
                p,
            )),
        },
    }
    let mut rows = Vec::new();
    for (k, t) in decl.transitions.iter().enumerate() {
        let at = format!("{path}.transitions[{k}]");
        let from = net.place(&t.from);
        let to = net.place(&t.to);
        for (name, found, field) in [(&t.from, from, "from"), (&t.to, to, "to")] {
            if found.is_none() {
                diags.push(unknown_place(
                    src,
                    &net,
                    src.span(&format!("{at}.{field}")),
                    name,
                ));
            }
        }
        let name = row_name(&t.name, k);
        if from.is_some() && from == to {
            diags.push(Diagnostic::error(
                src.span(&at),
                format!(
                    "transition `{name}` of function `{}` leads from `{}` to itself: it has no row in M (a state machine's row has one -1 and one 1)",
                    decl.name, t.from
                ),
            ));
        }
        let when = parse_when(src, &t.when, &format!("{at}.when"), diags);
        net.transitions.push(Transition {
            name,
            on: t.on.clone(),
            event: Event::Role {
                role: decl.role.clone(),
                event: t.on.clone(),
            },
            from: from.unwrap_or(0),
            to: to.unwrap_or(0),
            when,
        });
        rows.push(at);
    }
    duplicate_rows(src, &net, &rows, diags);
    Some(Located {
        net,
        index: i,
        position: 0,
        places: format!("{path}.places"),
        rows,
        matrix: false,
    })
}

fn duplicate_rows(src: &Source, net: &Net, rows: &[String], diags: &mut Vec<Diagnostic>) {
    for (k, t) in net.transitions.iter().enumerate() {
        if let Some(first) = net.transitions[..k].iter().position(|u| u.name == t.name) {
            diags.push(crate::check::duplicate(
                src,
                "transition",
                &t.name,
                &format!("{}.name", rows[first]),
                &format!("{}.name", rows[k]),
            ));
        }
    }
}

fn from_matrix(
    src: &Source,
    decl: &FunctionDecl,
    m: &MatrixDecl,
    i: usize,
    diags: &mut Vec<Diagnostic>,
) -> Option<Located> {
    let path = format!("functions[{i}].matrix");
    let f = &decl.name;
    if m.places.is_empty() {
        diags.push(Diagnostic::error(
            src.span(&format!("{path}.places")),
            format!("function `{f}` has no places"),
        ));
        return None;
    }
    columns(src, &m.places, &format!("{path}.places"), diags);
    let mut net = empty_net(decl, &m.places);
    let n = m.places.len();
    if m.marking.len() != n {
        diags.push(Diagnostic::error(
            src.span(&format!("{path}.marking")),
            format!(
                "m(0) of function `{f}` has {} entries for {n} places",
                m.marking.len()
            ),
        ));
    } else if let Some((k, x)) = (m.marking.iter().enumerate()).find(|(_, &x)| x != 0 && x != 1) {
        // Named where it is: a count of them all overflowed (`i32::MAX` tokens), and
        // said a negative entry's function held too few.
        diags.push(Diagnostic::error(
            src.span(&format!("{path}.marking[{k}]")),
            format!("m(0) of function `{f}` puts {x} tokens in a place: a state machine's place holds 0 or 1 (one entry 1, the others 0)"),
        ));
    } else if let tokens @ (0 | 2..) = m.marking.iter().filter(|&&x| x == 1).count() {
        diags.push(Diagnostic::error(
            src.span(&format!("{path}.marking")),
            format!("m(0) of function `{f}` holds {tokens} tokens: a state machine holds exactly one (one entry 1, the others 0)"),
        ));
    } else {
        net.initial = m.marking.iter().position(|&x| x == 1).unwrap_or(0);
    }
    let mut rows = Vec::new();
    for (k, r) in m.rows.iter().enumerate() {
        let at = format!("{path}.rows[{k}]");
        let name = row_name(&r.name, k);
        let here = src.span(&format!("{at}.row"));
        let (mut from, mut to) = (Vec::new(), Vec::new());
        if r.row.len() != n {
            diags.push(Diagnostic::error(
                here,
                format!(
                    "row `{name}` of M of function `{f}` has {} entries for {n} places",
                    r.row.len()
                ),
            ));
        } else if let Some(j) = r.row.iter().position(|x| !(-1..=1).contains(x)) {
            diags.push(Diagnostic::error(
                src.span(&format!("{at}.row[{j}]")),
                format!(
                    "entry {} of row `{name}` of M of function `{f}`: an entry of M is -1, 0 or 1",
                    r.row[j]
                ),
            ));
        } else {
            for (j, &x) in r.row.iter().enumerate() {
                match x {
                    -1 => from.push(j),
                    1 => to.push(j),
                    _ => {}
                }
            }
            if from.len() != 1 || to.len() != 1 {
                diags.push(Diagnostic::error(
                    here,
                    format!(
                        "row `{name}` of M of function `{f}` has {} entries -1 and {} entries 1: a state machine's row has exactly one -1 (its precondition) and one 1 (its result)",
                        from.len(),
                        to.len()
                    ),
                ));
            }
        }
        let when = parse_when(src, &r.when, &format!("{at}.when"), diags);
        net.transitions.push(Transition {
            name,
            on: r.on.clone(),
            event: Event::Role {
                role: decl.role.clone(),
                event: r.on.clone(),
            },
            from: from.first().copied().unwrap_or(0),
            to: to.first().copied().unwrap_or(0),
            when,
        });
        rows.push(at);
    }
    duplicate_rows(src, &net, &rows, diags);
    Some(Located {
        net,
        index: i,
        position: 0,
        places: format!("{path}.places"),
        rows,
        matrix: true,
    })
}

/// Resolves the events and condition names of one function against every net.
fn resolve(
    robot: &Robot,
    src: &Source,
    nets: &[Net],
    l: &mut Located,
    diags: &mut Vec<Diagnostic>,
) {
    let Some((_, role)) = robot.role(&l.net.role) else {
        return;
    };
    let levels = levels(role);
    for k in 0..l.net.transitions.len() {
        let on = l.net.transitions[k].on.clone();
        let on_path = l.field(k, "on");
        match event(robot, nets, &l.net, &on) {
            Ok(e) => l.net.transitions[k].event = e,
            Err(message) => diags.push(
                Diagnostic::error(src.span(&on_path), message)
                    .help(events_help(robot, nets, &l.net)),
            ),
        }
        if let Some((_, ast)) = &l.net.transitions[k].when {
            let base = StrMap::new(src, &l.field(k, "when"));
            let mut found = Vec::new();
            spans(ast, &mut found);
            for (name, span) in found {
                if reads(nets, &levels, &name).is_some() {
                    continue;
                }
                let message = match name.split_once('.') {
                    Some((f, p)) if nets.iter().any(|n| n.name == f) => format!("function `{f}` has no place `{p}`"),
                    _ if nets.iter().any(|n| n.name == name) => {
                        format!("`{name}` is a function: name one of its places, `{name}.PLACE`")
                    }
                    _ => format!(
                        "unknown name `{name}`: not a place of a function (`FUNCTION.PLACE`) nor an input of role `{}`",
                        l.net.role
                    ),
                };
                diags.push(Diagnostic::error(base.span(span.clone()), message));
            }
        }
    }
}

fn events_help(robot: &Robot, nets: &[Net], net: &Net) -> String {
    let mut all: Vec<String> = net.timers.clone();
    if let Some((_, role)) = robot.role(&net.role) {
        all.extend(role_events(robot, role));
    }
    for n in nets.iter().filter(|n| n.name != net.name) {
        all.extend(n.places.iter().map(|p| format!("{}.{p}", n.name)));
    }
    format!("events of function `{}`: {}", net.name, all.join(", "))
}

/// What `on` names for function `net`.
fn event(robot: &Robot, nets: &[Net], net: &Net, on: &str) -> Result<Event, String> {
    if let Some((r, e)) = on.split_once('/') {
        let Some((_, role)) = robot.role(r) else {
            return Err(format!("unknown role `{r}`"));
        };
        if role_events(robot, role).iter().any(|x| x == e) {
            return Ok(Event::Role {
                role: r.to_string(),
                event: e.to_string(),
            });
        }
        return Err(format!("unknown event `{e}` of role `{r}`"));
    }
    if let Some(t) = net.timers.iter().position(|t| t == on) {
        return Ok(Event::Timer(t));
    }
    if let Some((function, place)) = place_ref(nets, on) {
        if nets[function].name == net.name {
            return Err(format!("`{on}` is a place of function `{}` itself: its own place changes are not its events", net.name));
        }
        return Ok(Event::Place { function, place });
    }
    if let Some((f, p)) = on.split_once('.') {
        if nets.iter().any(|n| n.name == f) {
            return Err(format!("function `{f}` has no place `{p}`"));
        }
    }
    if let Some((_, role)) = robot.role(&net.role) {
        if role_events(robot, role).iter().any(|x| x == on) {
            return Ok(Event::Role {
                role: net.role.clone(),
                event: on.to_string(),
            });
        }
    }
    Err(format!(
        "unknown event `{on}` of function `{}`: not an input, switch or chart output of role `{}`, a timer, or a function's place",
        net.name, net.role
    ))
}

/// Every name of an AST with its span in the text, in order.
pub fn spans(ast: &Ast, out: &mut Vec<(String, Range<usize>)>) {
    match ast {
        Ast::Int(_) => {}
        Ast::Name(n, s) => out.push((n.clone(), s.clone())),
        Ast::Not(a) | Ast::Neg(a) | Ast::Wrap { of: a, .. } => spans(a, out),
        Ast::Bin(_, a, b) => {
            spans(a, out);
            spans(b, out);
        }
    }
}
