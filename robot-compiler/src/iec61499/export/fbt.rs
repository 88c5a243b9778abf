//! A chart type as an IEC 61499-2 basic FB type (`.fbt`), in the element order and with
//! the attributes Eclipse 4diac IDE writes: the interface (event inputs with their `With`
//! associations, event outputs, input variables: the parameters), the internal
//! variables, the ECC (the first state is the initial one) and one ST algorithm per run
//! of assignments. The node's services are output events of reserved names
//! ([`crate::iec61499::services`]).

use std::collections::BTreeMap;

use super::st::{self, Kind};
use super::xml::Writer;
use super::ExportError;
use crate::expr;
use crate::iec61499::services;
use crate::model::{ActionDecl, ChartType};

/// A chart type to write, with the ST type of each parameter (DINT unless said) and a
/// comment for the type.
pub struct FbSpec<'a> {
    pub ty: &'a ChartType,
    pub comment: String,
    pub bools: &'a [String],
    /// (parameter, role input): the BOOL parameters that read a role input's level, each
    /// written with its `Comment` ([`services::level_comment`]).
    pub levels: &'a [(String, String)],
    /// (parameter, comment): the DINT parameters that read another chart's variable,
    /// each written with its `Comment` ([`services::value_comment`]).
    pub values: &'a [(String, String)],
    /// (variable, comment): the variables holding a control function's place, each
    /// written with its `Comment` ([`services::places_comment`]).
    pub places: &'a [(String, String)],
    /// The `VersionInfo` date (`YYYY-MM-DD`).
    pub date: &'a str,
}

/// Whether `name` is an IEC 61131-3 identifier (letters, digits, single underscores, not
/// starting with a digit).
pub fn is_identifier(name: &str) -> bool {
    let b = name.as_bytes();
    !b.is_empty()
        && !b[0].is_ascii_digit()
        && b.iter().all(|c| c.is_ascii_alphanumeric() || *c == b'_')
        && !name.contains("__")
        && !name.ends_with('_')
        && !is_keyword(name)
}

/// The keywords of IEC 61131-3 that structured text and its declarations read (statements,
/// operators, literals, SFC's steps, variable sections) and its elementary type names,
/// upper case: not identifiers, whatever their case. (Words only a configuration reads,
/// `ON`, `AT`, `WITH`, are common event names: not listed.)
const KEYWORDS: &[&str] = &[
    "ACTION",
    "AND",
    "ARRAY",
    "BOOL",
    "BY",
    "BYTE",
    "CASE",
    "DATE",
    "DATE_AND_TIME",
    "DINT",
    "DO",
    "DT",
    "DWORD",
    "ELSE",
    "ELSIF",
    "END_ACTION",
    "END_CASE",
    "END_FOR",
    "END_FUNCTION",
    "END_FUNCTION_BLOCK",
    "END_IF",
    "END_REPEAT",
    "END_STEP",
    "END_STRUCT",
    "END_TRANSITION",
    "END_TYPE",
    "END_VAR",
    "END_WHILE",
    "EXIT",
    "FALSE",
    "FOR",
    "FUNCTION",
    "FUNCTION_BLOCK",
    "IF",
    "INITIAL_STEP",
    "INT",
    "LINT",
    "LREAL",
    "LWORD",
    "MOD",
    "NOT",
    "OF",
    "OR",
    "REAL",
    "REPEAT",
    "RETURN",
    "SINT",
    "STEP",
    "STRING",
    "STRUCT",
    "THEN",
    "TIME",
    "TIME_OF_DAY",
    "TO",
    "TOD",
    "TRANSITION",
    "TRUE",
    "TYPE",
    "UDINT",
    "UINT",
    "ULINT",
    "UNTIL",
    "USINT",
    "VAR",
    "VAR_EXTERNAL",
    "VAR_GLOBAL",
    "VAR_IN_OUT",
    "VAR_INPUT",
    "VAR_OUTPUT",
    "VAR_TEMP",
    "WHILE",
    "WORD",
    "WSTRING",
    "XOR",
];

/// Whether `name` is a keyword of IEC 61131-3 (any case).
pub fn is_keyword(name: &str) -> bool {
    KEYWORDS.iter().any(|k| k.eq_ignore_ascii_case(name))
}

/// `name` made an identifier: other characters become `_`, runs of `_` one, a leading
/// digit gets an `N`.
pub fn identifier(name: &str) -> String {
    let mut s = String::new();
    for c in name.chars() {
        let c = if c.is_ascii_alphanumeric() { c } else { '_' };
        if !(c == '_' && (s.is_empty() || s.ends_with('_'))) {
            s.push(c);
        }
    }
    while s.ends_with('_') {
        s.pop();
    }
    if s.is_empty() || s.as_bytes()[0].is_ascii_digit() {
        s.insert(0, 'N');
    }
    s
}

/// `t` with each variable whose name clashes with another of its names (IEC 61131-3
/// names are case-insensitive: `dips` and the parameter `DIPS` are one name) renamed
/// `NAME_V` (`_V2`, ...), in every assignment and guard. Variables are the chart's own:
/// no connection names them, and the tables do not either.
pub fn rename_clashing_vars(t: &ChartType) -> ChartType {
    let mut t = t.clone();
    let mut taken: Vec<String> = std::iter::once(&t.name)
        .chain(&t.params)
        .chain(&t.inputs)
        .chain(&t.timers)
        .chain(&t.outputs)
        .map(|n| n.to_ascii_uppercase())
        .collect();
    let mut renames: BTreeMap<String, String> = BTreeMap::new();
    for v in &mut t.vars {
        let mut name = v.name.clone();
        let mut k = 1;
        while taken.contains(&name.to_ascii_uppercase()) || is_keyword(&name) {
            name = if k == 1 {
                format!("{}_V", v.name)
            } else {
                format!("{}_V{k}", v.name)
            };
            k += 1;
        }
        taken.push(name.to_ascii_uppercase());
        if name != v.name {
            renames.insert(std::mem::replace(&mut v.name, name.clone()), name);
        }
    }
    if renames.is_empty() {
        return t;
    }
    for s in &mut t.states {
        for a in &mut s.actions {
            if let ActionDecl::Set(var, _) = a {
                if let Some(n) = renames.get(var.as_str()) {
                    *var = n.clone();
                }
            }
        }
    }
    rename_in_expressions(&mut t, &renames);
    t
}

/// Each name of `renames` renamed in every expression of `t`.
fn rename_in_expressions(t: &mut ChartType, renames: &BTreeMap<String, String>) {
    for text in t.expressions_mut() {
        if let Ok(mut ast) = expr::parse(text) {
            rename(&mut ast, renames);
            *text = super::lift::print(&ast);
        }
    }
}

/// `t` with each name its guards and assignments read that is neither a parameter nor a
/// variable (a role input's level, `A.home`: robot-format.md) made a BOOL parameter named
/// as an identifier (`A_home`), and the (parameter, role input) pairs: the levels of
/// [`FbSpec::levels`], each written with its comment, which the import binds back to
/// reads of the input ([`crate::iec61499::fbt::bind_levels`]).
pub fn levels_as_params(t: &ChartType) -> (ChartType, Vec<(String, String)>) {
    let mut read = Vec::new();
    for text in t.expressions() {
        if let Ok(ast) = expr::parse(text) {
            expr::names(&ast, &mut read);
        }
    }
    let own = |n: &str| t.params.iter().any(|p| p == n) || t.vars.iter().any(|v| v.name == n);
    read.retain(|n| !own(n));
    if read.is_empty() {
        return (t.clone(), Vec::new());
    }
    let mut taken: Vec<String> = std::iter::once(&t.name)
        .chain(&t.params)
        .chain(&t.inputs)
        .chain(&t.timers)
        .chain(&t.outputs)
        .chain(t.vars.iter().map(|v| &v.name))
        .map(|n| n.to_ascii_uppercase())
        .collect();
    let mut renames: BTreeMap<String, String> = BTreeMap::new();
    let mut levels = Vec::new();
    let mut t = t.clone();
    for input in read {
        let base = identifier(&input);
        let (mut name, mut k) = (base.clone(), 2);
        while taken.contains(&name.to_ascii_uppercase()) || is_keyword(&name) {
            name = format!("{base}_{k}");
            k += 1;
        }
        taken.push(name.to_ascii_uppercase());
        t.params.push(name.clone());
        levels.push((name.clone(), input.clone()));
        renames.insert(input, name);
    }
    rename_in_expressions(&mut t, &renames);
    (t, levels)
}

fn rename(ast: &mut expr::Ast, renames: &BTreeMap<String, String>) {
    use expr::Ast;
    match ast {
        Ast::Int(_) => {}
        Ast::Name(n, _) => {
            if let Some(r) = renames.get(n.as_str()) {
                *n = r.clone();
            }
        }
        Ast::Not(a) | Ast::Neg(a) | Ast::Wrap { of: a, .. } => rename(a, renames),
        Ast::Bin(_, a, b) => {
            rename(a, renames);
            rename(b, renames);
        }
    }
}

/// The output events of `t`: its outputs, then each service its states ask for, in
/// order of first use.
pub fn output_events(t: &ChartType) -> Vec<String> {
    let mut out = t.outputs.clone();
    for a in t.states.iter().flat_map(|s| &s.actions) {
        if let Some(e) = services::event(a) {
            if !out.contains(&e) {
                out.push(e);
            }
        }
    }
    out
}

/// The `.fbt` text of one chart type.
pub fn write(spec: &FbSpec<'_>) -> Result<String, ExportError> {
    let t = spec.ty;
    let fail = |what: String| ExportError::Type {
        ty: t.name.clone(),
        message: what,
    };
    let outputs = output_events(t);
    let events: Vec<&String> = t
        .inputs
        .iter()
        .chain(&t.timers)
        .chain(&outputs)
        .chain(&t.params)
        .chain(t.vars.iter().map(|v| &v.name))
        .collect();
    let mut seen: Vec<String> = Vec::new();
    for n in std::iter::once(&t.name).chain(events.iter().copied()) {
        if !is_identifier(n) {
            return Err(fail(format!("`{n}` is not an IEC 61131-3 identifier")));
        }
        let upper = n.to_ascii_uppercase();
        if n != &t.name && seen.contains(&upper) {
            return Err(fail(format!(
                "`{n}` is declared twice (IEC 61131-3 names are case-insensitive)"
            )));
        }
        seen.push(upper);
    }
    for o in &t.outputs {
        if services::is_reserved(o) {
            return Err(fail(format!(
                "output `{o}` has a name reserved for the node's services"
            )));
        }
    }
    let kinds: BTreeMap<&str, Kind> = t
        .params
        .iter()
        .map(|p| {
            let k = if spec.bools.contains(p) {
                Kind::Bool
            } else {
                Kind::Int
            };
            (p.as_str(), k)
        })
        .chain(t.vars.iter().map(|v| (v.name.as_str(), Kind::Int)))
        .collect();
    let names = |n: &str| kinds.get(n).map(|k| (n.to_string(), *k));
    let expression = |text: &str, want: Kind, at: &str| {
        expr::parse(text)
            .map_err(|e| e.message)
            .and_then(|ast| st::st(&ast, want, &names))
            .map_err(|m| fail(format!("{at}: {m}")))
    };
    let mut w = Writer::new("FBType");
    w.open("FBType", &[("Name", &t.name), ("Comment", &spec.comment)]);
    w.empty(
        "Identification",
        &[("Standard", "61499-2"), ("Classification", services::MARK)],
    );
    w.empty(
        "VersionInfo",
        &[
            ("Organization", "ecc-nodes"),
            ("Version", "1.0"),
            ("Author", "config-tool export-4diac"),
            ("Date", spec.date),
        ],
    );
    w.open("InterfaceList", &[]);
    let event_list = |w: &mut Writer, list: &'static str, names: &[&String], with: &[String]| {
        if names.is_empty() {
            return;
        }
        w.open(list, &[]);
        for n in names {
            if with.is_empty() {
                w.empty("Event", &[("Name", n), ("Type", "Event"), ("Comment", "")]);
            } else {
                w.open("Event", &[("Name", n), ("Type", "Event"), ("Comment", "")]);
                for v in with {
                    w.empty("With", &[("Var", v)]);
                }
                w.close();
            }
        }
        w.close();
    };
    let inputs: Vec<&String> = t.inputs.iter().chain(&t.timers).collect();
    event_list(&mut w, "EventInputs", &inputs, &t.params);
    let outs: Vec<&String> = outputs.iter().collect();
    event_list(&mut w, "EventOutputs", &outs, &[]);
    if !t.params.is_empty() {
        w.open("InputVars", &[]);
        for p in &t.params {
            let ty = if kinds.get(p.as_str()) == Some(&Kind::Bool) {
                "BOOL"
            } else {
                "DINT"
            };
            let comment = (spec.levels.iter())
                .find(|(n, _)| n == p)
                .map(|(_, i)| services::level_comment(i))
                .or_else(|| {
                    (spec.values.iter())
                        .find(|(n, _)| n == p)
                        .map(|(_, c)| c.clone())
                })
                .unwrap_or_default();
            w.empty(
                "VarDeclaration",
                &[("Name", p), ("Type", ty), ("Comment", &comment)],
            );
        }
        w.close();
    }
    w.close();
    w.open("BasicFB", &[]);
    if !t.vars.is_empty() {
        w.open("InternalVars", &[]);
        for v in &t.vars {
            let init = expr::parse(&v.init)
                .ok()
                .and_then(|a| expr::eval(&a, &|_| None))
                .ok_or_else(|| {
                    fail(format!(
                        "the initial value of `{}` (`{}`) is not a number: ST's InitialValue \
                         is a literal",
                        v.name, v.init
                    ))
                })?;
            let comment = (spec.places.iter())
                .find(|(n, _)| *n == v.name)
                .map_or("", |(_, c)| c.as_str());
            w.empty(
                "VarDeclaration",
                &[
                    ("Name", &v.name),
                    ("Type", "DINT"),
                    ("InitialValue", &init.to_string()),
                    ("Comment", comment),
                ],
            );
        }
        w.close();
    }
    w.open("ECC", &[]);
    let mut algorithms: Vec<(String, String)> = Vec::new();
    for (si, s) in t.states.iter().enumerate() {
        if !is_identifier(&s.name) {
            return Err(fail(format!("state `{}` is not an identifier", s.name)));
        }
        let (x, y) = place(si);
        let comment = if si == 0 {
            "Initial State"
        } else if t.idle.as_ref() == Some(&s.name) {
            services::IDLE
        } else if t.rests.contains(&s.name) {
            services::REST
        } else {
            ""
        };
        let mut actions: Vec<(Option<String>, Option<String>)> = Vec::new();
        let mut pending: Vec<String> = Vec::new();
        for (ai, a) in s.actions.iter().enumerate() {
            let event = match a {
                ActionDecl::Set(var, text) => {
                    let rhs = expression(text, Kind::Int, &format!("state `{}`", s.name))?;
                    if !kinds.contains_key(var.as_str()) || t.params.contains(var) {
                        return Err(fail(format!("state `{}` sets `{var}`", s.name)));
                    }
                    pending.push(format!("{var} := {rhs};"));
                    let _ = ai;
                    continue;
                }
                ActionDecl::Emit(o) => o.clone(),
                other => services::event(other).unwrap_or_default(),
            };
            let alg = (!pending.is_empty()).then(|| {
                let name = format!("{}_{}", s.name, algorithms.len() + 1);
                algorithms.push((name.clone(), pending.join("\n")));
                pending.clear();
                name
            });
            actions.push((alg, Some(event)));
        }
        if !pending.is_empty() {
            let name = format!("{}_{}", s.name, algorithms.len() + 1);
            algorithms.push((name.clone(), pending.join("\n")));
            actions.push((Some(name), None));
        }
        let attrs = [
            ("Name", s.name.as_str()),
            ("Comment", comment),
            ("x", &x),
            ("y", &y),
        ];
        if actions.is_empty() {
            w.empty("ECState", &attrs);
            continue;
        }
        w.open("ECState", &attrs);
        for (alg, out) in &actions {
            let mut a: Vec<(&str, &str)> = Vec::new();
            if let Some(alg) = alg {
                a.push(("Algorithm", alg));
            }
            if let Some(out) = out {
                a.push(("Output", out));
            }
            w.empty("ECAction", &a);
        }
        w.close();
    }
    for tr in &t.transitions {
        let guard = match &tr.when {
            Some(g) => Some(expression(
                g,
                Kind::Bool,
                &format!("the guard of {} -> {}", tr.from, tr.to),
            )?),
            None => None,
        };
        let condition = match (&tr.on, guard) {
            (Some(e), Some(g)) => format!("{e}[{g}]"),
            (Some(e), None) => e.clone(),
            (None, Some(g)) => format!("[{g}]"),
            (None, None) => String::from("1"),
        };
        w.empty(
            "ECTransition",
            &[
                ("Source", &tr.from),
                ("Destination", &tr.to),
                ("Condition", &condition),
                ("Comment", ""),
                ("x", "0"),
                ("y", "0"),
            ],
        );
    }
    w.close();
    for (name, text) in &algorithms {
        w.open("Algorithm", &[("Name", name), ("Comment", "")]);
        w.empty("ST", &[("Text", text)]);
        w.close();
    }
    Ok(w.finish())
}

/// Where 4diac draws state `i` of an ECC: a grid, four to a row.
fn place(i: usize) -> (String, String) {
    let (col, row) = (i % 4, i / 4);
    ((400 + col * 700).to_string(), (400 + row * 500).to_string())
}
