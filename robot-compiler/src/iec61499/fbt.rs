//! An IEC 61499-2 basic FB type (`.fbt`: `FBType` with `BasicFB`) -> a chart type
//! ([`ChartType`]) the robot uses like one written in RON (docs/iec61499-xml.md).
//!
//! - the interface: event inputs and outputs (their `With` associations checked against
//!   the variables), input variables (the chart type's parameters: the instance gives
//!   their values), output and internal variables (the chart's variables, with their
//!   `InitialValue`s), of BOOL, SINT, INT, DINT, USINT, UINT or UDINT;
//! - the ECC: `ECState`s in order (the first is the initial state), each `ECAction` its
//!   algorithm's assignments then its output event; `ECTransition`s with conditions as
//!   the tools write them: `EI[guard]`, `EI & guard` (1st edition, FBDK), `[guard]`, `EI`,
//!   `guard`, `1` / `TRUE`;
//! - algorithms in Structured Text ([`super::st`]);
//! - in a type the export marked, the node's services as output events of reserved
//!   names and its timers as the event inputs they start ([`super::services`]).
//!
//! Anything else (another algorithm language, REAL, STRING, adapters, a service or
//! composite FB) is an error naming the element and its line:col; nothing is half
//! imported.

use config_schema::limits::{MAX_CHART_INPUTS, MAX_STATES, MAX_TRANSITIONS, MAX_VARS};
use roxmltree::{Document, Node};

use super::net;
use super::st::{self, Name, StError, Stmt, Ty};
use crate::model::{ActionDecl, ChartType, StateDecl, TransitionDecl, VarDecl, Written};

/// An import error at a line and column (1-based) of the XML file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct XmlError {
    pub line: u32,
    pub col: u32,
    pub message: String,
}

impl std::fmt::Display for XmlError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}: {}", self.line, self.col, self.message)
    }
}

/// The element types of IEC 61499 that are not a basic FB, named in errors.
const OTHER_FB_KINDS: [&str; 3] = ["FBNetwork", "Service", "SimpleFB"];

#[derive(Clone, Copy)]
struct Cx<'a, 'i> {
    doc: &'a Document<'i>,
    /// The lines of the document's text (a place found without scanning it from its
    /// start: roxmltree's `text_pos_at` does, and a large file took seconds).
    lines: &'a net::Lines,
}

impl<'a, 'i> Cx<'a, 'i> {
    fn at(&self, pos: usize, message: impl Into<String>) -> XmlError {
        let p = self.lines.pos(self.doc.input_text(), pos);
        XmlError {
            line: p.line,
            col: p.col,
            message: message.into(),
        }
    }

    /// The line and column of element `n`.
    fn line_col(&self, n: Node<'a, 'i>) -> (u32, u32) {
        let p = self.lines.pos(self.doc.input_text(), n.range().start);
        (p.line, p.col)
    }

    fn node_err(&self, n: Node<'a, 'i>, message: impl Into<String>) -> XmlError {
        self.at(n.range().start, message)
    }

    /// An attribute's value, or an error at the element.
    fn attr(&self, n: Node<'a, 'i>, name: &str) -> Result<&'a str, XmlError> {
        n.attribute(name).ok_or_else(|| {
            self.node_err(
                n,
                format!("`{}` needs the attribute `{name}`", n.tag_name().name()),
            )
        })
    }

    /// An error inside attribute `name` of `n` at byte span `span` of its value.
    fn in_attr(&self, n: Node<'a, 'i>, name: &str, e: StError) -> XmlError {
        let pos = n
            .attributes()
            .find(|a| a.name() == name)
            .map_or(n.range().start, |a| {
                let raw = a.range_value();
                let text = self.doc.input_text().get(raw.clone()).unwrap_or("");
                raw.start + raw_offset(text, e.span.start)
            });
        self.at(pos, e.message)
    }

    /// An error at byte span `span` of the text of element `n`'s children (its text and
    /// CDATA sections, as one string: roxmltree makes them one node, whose range is its
    /// first part's only), found in the element's content as written.
    fn in_text(&self, n: Node<'a, 'i>, e: StError) -> XmlError {
        let pos = n.first_child().map_or(n.range().start, |c| {
            let start = c.range().start;
            let raw = self
                .doc
                .input_text()
                .get(start..n.range().end)
                .unwrap_or("");
            start + raw_offset(raw, e.span.start)
        });
        self.at(pos, e.message)
    }
}

/// The byte of `raw` (XML as written: character and entity references, CDATA sections,
/// comments and processing instructions, line ends of two characters) where byte
/// `decoded` of the text it stands for is.
fn raw_offset(raw: &str, decoded: usize) -> usize {
    let (mut at, mut out) = (0, 0);
    let b = raw.as_bytes();
    while at < b.len() && out < decoded {
        let rest = raw.get(at..).unwrap_or("");
        if let Some(cdata) = rest.strip_prefix("<![CDATA[") {
            let body = cdata.find("]]>").unwrap_or(cdata.len());
            let take = body.min(decoded - out);
            out += take;
            at += 9 + take;
            if out < decoded {
                at += 3;
            }
            // Where the decoded text goes on, after the section's end.
            continue;
        }
        let skipped = [("<!--", "-->"), ("<?", "?>")]
            .into_iter()
            .find_map(|(open, close)| {
                rest.strip_prefix(open)
                    .map(|r| open.len() + r.find(close).map_or(r.len(), |k| k + close.len()))
            });
        if let Some(len) = skipped {
            at += len;
            continue;
        }
        let (raw_len, text_len) = match rest.chars().next() {
            Some('&') => {
                let end = rest.find(';').map_or(rest.len(), |k| k + 1);
                let decoded_char = match rest.get(1..end - 1).unwrap_or("") {
                    "lt" | "gt" | "amp" | "quot" | "apos" => Some('<'),
                    r => r
                        .strip_prefix("#x")
                        .map(|h| u32::from_str_radix(h, 16))
                        .or_else(|| r.strip_prefix('#').map(str::parse::<u32>))
                        .and_then(Result::ok)
                        .and_then(char::from_u32),
                };
                (end, decoded_char.map_or(end, char::len_utf8))
            }
            Some('\r') if rest.starts_with("\r\n") => (2, 1),
            Some(c) => (c.len_utf8(), c.len_utf8()),
            None => break,
        };
        at += raw_len;
        out += text_len;
    }
    at
}

/// Element children of `n` (comments and text skipped).
fn elements<'a, 'i>(n: Node<'a, 'i>) -> impl Iterator<Item = Node<'a, 'i>> {
    n.children().filter(Node::is_element)
}

fn child<'a, 'i>(n: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    elements(n).find(|c| c.tag_name().name() == name)
}

/// One declared variable.
struct Var {
    name: String,
    ty: Ty,
    init: Option<String>,
    /// The role input whose level it reads, by its `Comment` (in a marked type only).
    level: Option<String>,
    /// The function and places it holds, by its `Comment` (in a marked type only).
    places: Option<(String, Vec<String>)>,
    /// The FB and variable whose value it reads, by its `Comment` (in a marked type
    /// only).
    value: Option<(String, String)>,
}

/// The typed interface of an imported basic FB type, beyond its chart type: what an
/// application (`.sys`) needs to give its instances' parameters and check its connections.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Interface {
    /// The input variables (the chart type's parameters, in order): name, type, and the
    /// `InitialValue` as a chart literal (a parameter without a value takes it, else 0).
    pub inputs: Vec<(String, Ty, Option<String>)>,
    /// The output variables' names.
    pub outputs: Vec<String>,
    /// The output and internal variables with their types (what a data connection from
    /// an instance of the type reads).
    pub vars: Vec<(String, Ty)>,
    /// The output events that are node services (of a type marked
    /// [`super::services::MARK`]): in an application, each may connect to its role's
    /// node services FB (`ROLE_IO`) only.
    pub services: Vec<String>,
    /// (input variable, role input): the BOOL input variables of a marked type that read
    /// the level of one of their role's inputs (`Comment="level of VC.home"`,
    /// [`bind_levels`]).
    pub levels: Vec<(String, String)>,
    /// (variable, function, its places in column order): the variables of a marked type
    /// that hold a control function's place (`Comment="places of F: A B"`), which the
    /// robot's alarms read as `F.A` again.
    pub places: Vec<(String, String, Vec<String>)>,
    /// (input variable, FB, its variable): the input variables of a marked type that
    /// read another chart's variable (`Comment="value of FB.VAR"`): in an application,
    /// the instance reads FB's variable ([`crate::model::ChartInstance::reads`]).
    pub values: Vec<(String, String, String)>,
}

/// A marked type's input variables that read their role's input levels
/// ([`Interface::levels`]) made reads of those inputs: no longer parameters, each name in
/// a guard or assignment the input's (`VC_home_2` -> `VC.home`), as the chart the type
/// was lifted from reads them.
pub fn bind_levels(t: &mut ChartType, i: &mut Interface) {
    if i.levels.is_empty() {
        return;
    }
    let levels = std::mem::take(&mut i.levels);
    let of = |n: &str| levels.iter().find(|(p, _)| p == n).map(|(_, l)| l.clone());
    t.params.retain(|p| of(p).is_none());
    i.inputs.retain(|(p, _, _)| of(p).is_none());
    for text in t.expressions_mut() {
        if let Ok(ast) = crate::expr::parse(text) {
            *text = super::export::lift::print(&rename_names(ast, &of));
        }
    }
}

/// `a` with each name `of` renames renamed.
fn rename_names(a: crate::expr::Ast, of: &dyn Fn(&str) -> Option<String>) -> crate::expr::Ast {
    use crate::expr::Ast;
    let b = |x: Box<Ast>| Box::new(rename_names(*x, of));
    match a {
        Ast::Name(n, span) => Ast::Name(of(&n).unwrap_or(n), span),
        Ast::Not(x) => Ast::Not(b(x)),
        Ast::Neg(x) => Ast::Neg(b(x)),
        Ast::Bin(op, x, y) => Ast::Bin(op, b(x), b(y)),
        Ast::Wrap {
            bits,
            signed,
            of: x,
        } => Ast::Wrap {
            bits,
            signed,
            of: b(x),
        },
        other => other,
    }
}

/// Parses the `.fbt` text into a chart type.
pub fn import(text: &str) -> Result<ChartType, XmlError> {
    import_typed(text).map(|(t, _)| t)
}

/// [`import`], with the type's typed [`Interface`].
pub fn import_typed(text: &str) -> Result<(ChartType, Interface), XmlError> {
    let doc = super::net::document(text).map_err(|(at, message)| XmlError {
        line: at.line,
        col: at.col,
        message,
    })?;
    let lines = net::Lines::of(text);
    let cx = Cx {
        doc: &doc,
        lines: &lines,
    };
    let root = doc.root_element();
    if root.tag_name().name() != "FBType" {
        return Err(cx.node_err(
            root,
            format!(
                "`{}` is not a function block type (`FBType`)",
                root.tag_name().name()
            ),
        ));
    }
    let name = cx.attr(root, "Name")?.to_string();
    for kind in OTHER_FB_KINDS {
        if let Some(n) = child(root, kind) {
            return Err(cx.node_err(
                n,
                format!(
                    "`{name}` is a {kind} FB type: only basic FB types (`BasicFB`) are supported"
                ),
            ));
        }
    }
    let Some(basic) = child(root, "BasicFB") else {
        return Err(cx.node_err(
            root,
            format!("`{name}` has no `BasicFB`: only basic FB types are supported"),
        ));
    };
    let interface = child(root, "InterfaceList")
        .ok_or_else(|| cx.node_err(root, format!("`{name}` has no `InterfaceList`")))?;
    for n in elements(interface) {
        match n.tag_name().name() {
            "EventInputs" | "EventOutputs" | "InputVars" | "OutputVars" => {}
            "Sockets" | "Plugs" if elements(n).next().is_some() => {
                return Err(cx.node_err(n, "adapters (sockets and plugs) are not supported"));
            }
            "InOutVars" if elements(n).next().is_some() => {
                return Err(cx.node_err(n, "in-out variables (`InOutVars`) are not supported"));
            }
            "Sockets" | "Plugs" | "InOutVars" => {}
            // Read nowhere (an `InternalVars` belongs to the `BasicFB`): refused, not
            // dropped unsaid.
            other => {
                return Err(cx.node_err(n, format!("unknown element `{other}` in `InterfaceList`")))
            }
        }
    }
    // `most`: variables a list may have (the table's variables; parameters, the input
    // variables, are constants of each instance and take none).
    let vars_of = |list: Option<Node<'_, '_>>, most: usize| -> Result<Vec<Var>, XmlError> {
        let mut out = Vec::new();
        for v in list.into_iter().flat_map(elements) {
            if v.tag_name().name() != "VarDeclaration" {
                return Err(cx.node_err(v, format!("unexpected `{}`", v.tag_name().name())));
            }
            // Refused here, in linear time, not after every one was read.
            if out.len() == most {
                return Err(cx.node_err(
                    v,
                    format!("more than {MAX_VARS} variables: a table holds at most {MAX_VARS} (MAX_VARS)"),
                ));
            }
            let vname = cx.attr(v, "Name")?.to_string();
            let tname = cx.attr(v, "Type")?;
            let Some(ty) = Ty::of(tname) else {
                return Err(cx.node_err(
                    v,
                    format!(
                        "`{vname}` is of type {tname}: supported are BOOL, SINT, INT, DINT, \
                         USINT, UINT and UDINT"
                    ),
                ));
            };
            if v.attribute("ArraySize").is_some_and(|s| !s.is_empty()) {
                return Err(cx.node_err(v, format!("`{vname}` is an array: not supported")));
            }
            let init = match v.attribute("InitialValue").filter(|s| !s.trim().is_empty()) {
                Some(text) => Some(
                    st::literal(text.trim(), ty).map_err(|e| cx.in_attr(v, "InitialValue", e))?,
                ),
                None => None,
            };
            let level = (v.attribute("Comment"))
                .and_then(super::services::level_of)
                .filter(|_| ty == Ty::Bool)
                .map(str::to_string);
            let places = (v.attribute("Comment")).and_then(super::services::places_of);
            let value = (v.attribute("Comment"))
                .and_then(super::services::value_of)
                .filter(|_| ty != Ty::Bool)
                .map(|(fb, var)| (fb.to_string(), var.to_string()));
            out.push(Var {
                name: vname,
                ty,
                init,
                level,
                places,
                value,
            });
        }
        Ok(out)
    };
    let inputs = vars_of(child(interface, "InputVars"), usize::MAX)?;
    let outputs = vars_of(child(interface, "OutputVars"), MAX_VARS)?;
    let internal = vars_of(child(basic, "InternalVars"), MAX_VARS)?;
    let mut names: Vec<Name> = Vec::new();
    let mut events_in = Vec::new();
    let mut events_out = Vec::new();
    // Event inputs are chart inputs (at most `MAX_CHART_INPUTS`, refused at the first one
    // past); event outputs are not counted here: the node services among them
    // (`START_T_150`, ...) become actions, not events.
    for (list, out, most) in [
        ("EventInputs", &mut events_in, MAX_CHART_INPUTS),
        ("EventOutputs", &mut events_out, usize::MAX),
    ] {
        for e in child(interface, list).into_iter().flat_map(elements) {
            if out.len() == most {
                return Err(cx.node_err(
                    e,
                    format!(
                        "more than {most} events in `{list}`: a table holds at most {most} \
                         (MAX_CHART_INPUTS)"
                    ),
                ));
            }
            let ename = cx.attr(e, "Name")?.to_string();
            out.push((ename, e));
        }
    }
    // A chart this project exported: its reserved output events are node services, and
    // the event inputs they start or stop are its timers (`super::services`).
    let marked = child(root, "Identification")
        .and_then(|i| i.attribute("Classification"))
        .is_some_and(|c| c == super::services::MARK);
    let in_names: Vec<String> = events_in.iter().map(|(n, _)| n.clone()).collect();
    let timers: Vec<String> = if marked {
        in_names
            .iter()
            .filter(|i| {
                events_out
                    .iter()
                    .any(|(o, _)| super::services::timer_of(o, &in_names) == Some(*i))
            })
            .cloned()
            .collect()
    } else {
        Vec::new()
    };
    let service = |out: &str| {
        marked
            .then(|| super::services::action(out, &timers))
            .flatten()
    };
    for (vars, writable) in [(&inputs, false), (&outputs, true), (&internal, true)] {
        for v in vars.iter() {
            names.push(Name {
                name: v.name.clone(),
                ty: v.ty,
                writable,
            });
        }
    }
    // One namespace for events and variables, case-insensitive as IEC 61131-3 has it.
    let mut seen = std::collections::HashSet::new();
    for (n, node) in events_in
        .iter()
        .chain(events_out.iter())
        .map(|(n, e)| (n.clone(), *e))
        .chain(names.iter().map(|n| (n.name.clone(), interface)))
    {
        if !seen.insert(n.to_ascii_lowercase()) {
            return Err(cx.node_err(node, format!("`{n}` is declared twice")));
        }
    }
    // `With`: each names a variable of its side (inputs with input events, outputs with
    // output events). Data arrives with its event: with parameters for the input
    // variables, the sampled value is the instance's.
    for ((_, e), vars) in events_in
        .iter()
        .map(|x| (x, &inputs))
        .chain(events_out.iter().map(|x| (x, &outputs)))
    {
        for w in elements(*e).filter(|w| w.tag_name().name() == "With") {
            let var = cx.attr(w, "Var")?;
            if !vars.iter().any(|v| v.name == var) {
                return Err(cx.node_err(
                    w,
                    format!("`With` names `{var}`, which is not a variable of this side of the interface"),
                ));
            }
        }
    }
    // Algorithms: Structured Text only.
    let mut algorithms: Vec<(String, Vec<Stmt>)> = Vec::new();
    for a in elements(basic).filter(|a| a.tag_name().name() == "Algorithm") {
        let aname = cx.attr(a, "Name")?.to_string();
        let Some(body) = elements(a).next() else {
            return Err(cx.node_err(a, format!("algorithm `{aname}` has no body")));
        };
        if body.tag_name().name() != "ST" {
            return Err(cx.node_err(
                body,
                format!(
                    "algorithm `{aname}` is in {}: only Structured Text (`ST`) is supported",
                    body.tag_name().name()
                ),
            ));
        }
        let (text, err_at): (String, Box<dyn Fn(StError) -> XmlError + '_>) =
            match body.attribute("Text") {
                Some(t) => (
                    t.to_string(),
                    Box::new(move |e| cx.in_attr(body, "Text", e)),
                ),
                None => {
                    let t: String = body.children().filter_map(|c| c.text()).collect();
                    (t, Box::new(move |e: StError| cx.in_text(body, e)))
                }
            };
        let statements = st::algorithm(&text, &names).map_err(err_at)?;
        algorithms.push((aname, statements));
    }
    let ecc =
        child(basic, "ECC").ok_or_else(|| cx.node_err(basic, format!("`{name}` has no `ECC`")))?;
    let mut states: Vec<StateDecl> = Vec::new();
    // Per state: what it does when entered, in order (assignments, choices, emits).
    let mut bodies: Vec<(Vec<Step>, Node<'_, '_>)> = Vec::new();
    // Where each `ECState` and `ECTransition` is, in order.
    let mut state_at: Vec<(String, (u32, u32))> = Vec::new();
    let mut transition_at: Vec<(u32, u32)> = Vec::new();
    let mut idle = None;
    let mut rests = Vec::new();
    for s in elements(ecc).filter(|s| s.tag_name().name() == "ECState") {
        if states.len() == MAX_STATES {
            return Err(cx.node_err(
                s,
                format!("an ECC of more than {MAX_STATES} states: a table holds at most {MAX_STATES} (MAX_STATES)"),
            ));
        }
        let sname = cx.attr(s, "Name")?.to_string();
        if marked && !states.is_empty() && s.attribute("Comment") == Some(super::services::IDLE) {
            idle = Some(sname.clone());
        }
        if marked && s.attribute("Comment") == Some(super::services::REST) {
            if states.len() >= 32 {
                return Err(cx.node_err(
                    s,
                    format!("resting state `{sname}` is not among the ECC's first 32: a table marks only those"),
                ));
            }
            rests.push(sname.clone());
        }
        if states.iter().any(|d: &StateDecl| d.name == sname) {
            return Err(cx.node_err(s, format!("state `{sname}` is declared twice")));
        }
        let mut body = Vec::new();
        for a in elements(s).filter(|a| a.tag_name().name() == "ECAction") {
            if let Some(alg) = a.attribute("Algorithm").filter(|x| !x.is_empty()) {
                let Some((_, stmts)) = algorithms.iter().find(|(n, _)| n == alg) else {
                    return Err(cx.node_err(a, format!("no algorithm `{alg}`")));
                };
                body.extend(stmts.iter().cloned().map(Step::Stmt));
            }
            if let Some(out) = a.attribute("Output").filter(|x| !x.is_empty()) {
                if !events_out.iter().any(|(n, _)| n == out) {
                    return Err(cx.node_err(a, format!("`{out}` is not an output event")));
                }
                body.push(Step::Act(
                    service(out).unwrap_or_else(|| ActionDecl::Emit(out.to_string())),
                ));
            }
        }
        state_at.push((sname.clone(), cx.line_col(s)));
        states.push(StateDecl {
            name: sname,
            actions: Vec::new(),
        });
        bodies.push((body, s));
    }
    if states.is_empty() {
        return Err(cx.node_err(ecc, "the ECC has no state"));
    }
    let mut transitions = Vec::new();
    for t in elements(ecc).filter(|t| t.tag_name().name() == "ECTransition") {
        if transitions.len() == MAX_TRANSITIONS {
            return Err(cx.node_err(
                t,
                format!(
                    "an ECC of more than {MAX_TRANSITIONS} transitions: a table holds at most \
                     {MAX_TRANSITIONS} (MAX_TRANSITIONS)"
                ),
            ));
        }
        let mut ends = Vec::new();
        for field in ["Source", "Destination"] {
            let s = cx.attr(t, field)?;
            if !states.iter().any(|d| d.name == s) {
                return Err(cx.in_attr(
                    t,
                    field,
                    StError {
                        message: format!("no state `{s}`"),
                        span: 0..0,
                    },
                ));
            }
            ends.push(s.to_string());
        }
        let cond = cx.attr(t, "Condition")?;
        let (on, when) =
            condition(cond, &events_in, &names).map_err(|e| cx.in_attr(t, "Condition", e))?;
        transition_at.push(cx.line_col(t));
        transitions.push(TransitionDecl {
            from: ends[0].clone(),
            to: ends[1].clone(),
            on,
            when,
        });
    }
    let (states, transitions) = split(states, bodies, transitions, &cx)?;
    let written = written(&states, &transitions, &state_at, &transition_at);
    let vars = outputs
        .iter()
        .chain(internal.iter())
        .map(|v| VarDecl {
            name: v.name.clone(),
            init: v.init.clone().unwrap_or_else(|| String::from("0")),
        })
        .collect();
    let interface = Interface {
        inputs: inputs
            .iter()
            .map(|v| (v.name.clone(), v.ty, v.init.clone()))
            .collect(),
        outputs: outputs.iter().map(|v| v.name.clone()).collect(),
        vars: (outputs.iter().chain(internal.iter()))
            .map(|v| (v.name.clone(), v.ty))
            .collect(),
        services: events_out
            .iter()
            .filter(|(n, _)| service(n).is_some())
            .map(|(n, _)| n.clone())
            .collect(),
        levels: (inputs.iter())
            .filter(|_| marked)
            .filter_map(|v| Some((v.name.clone(), v.level.clone()?)))
            .collect(),
        values: (inputs.iter())
            .filter(|_| marked)
            .filter_map(|v| {
                let (fb, var) = v.value.clone()?;
                Some((v.name.clone(), fb, var))
            })
            .collect(),
        places: (outputs.iter().chain(internal.iter()))
            .filter(|_| marked)
            .filter_map(|v| {
                let (f, places) = v.places.clone()?;
                Some((v.name.clone(), f, places))
            })
            .collect(),
    };
    let chart = ChartType {
        name,
        params: inputs.iter().map(|v| v.name.clone()).collect(),
        inputs: in_names
            .iter()
            .filter(|n| !timers.contains(n))
            .cloned()
            .collect(),
        outputs: events_out
            .iter()
            .filter(|(n, _)| service(n).is_none())
            .map(|(n, _)| n.clone())
            .collect(),
        vars,
        timers,
        states,
        transitions,
        idle,
        rests,
        imported: None,
        written: Some(written),
        specializes: None,
    };
    Ok((chart, interface))
}

/// Where the states and transitions [`split`] made were written (`file` left for the
/// importer to fill in): a state at its `ECState` (a chain's `S.k` at `S`'s), one of the
/// ECC's transitions at its `ECTransition` (they come last, in order), a chain's at its
/// state's.
fn written(
    states: &[StateDecl],
    transitions: &[TransitionDecl],
    state_at: &[(String, (u32, u32))],
    transition_at: &[(u32, u32)],
) -> Written {
    let find = |name: &str| state_at.iter().find(|(n, _)| n == name).map(|(_, at)| *at);
    let at = |name: &str| (find(name).or_else(|| find(name.rsplit_once('.')?.0))).unwrap_or((0, 0));
    let chains = transitions.len().saturating_sub(transition_at.len());
    Written {
        file: String::new(),
        states: states.iter().map(|s| at(&s.name)).collect(),
        transitions: (transitions.iter().enumerate())
            .map(|(k, t)| match k.checked_sub(chains) {
                Some(i) => transition_at.get(i).copied().unwrap_or((0, 0)),
                None => at(&t.from),
            })
            .collect(),
    }
}

/// What a state does when entered: a statement of one of its algorithms, or its output
/// event (emitted, or a node service).
enum Step {
    Stmt(Stmt),
    Act(ActionDecl),
}

/// The states with their actions. A state whose algorithms only assign and emit does so
/// on entry. One that chooses (`IF`, `CASE`) becomes a small chain: its entry `S.0` runs
/// what comes before the first choice; each arm is a state `S.k` entered by an
/// event-less transition guarded by its condition (and the negation of the arms before
/// it: the guards are disjoint); the arms meet where the choice ends; the last meeting
/// point is `S` itself, which keeps the state's own transitions (transitions into `S` go
/// to `S.0`). An ECC rests in `S` after its actions, as the standard's does; the chain
/// runs within the one stimulus (run to completion).
fn split(
    mut states: Vec<StateDecl>,
    bodies: Vec<(Vec<Step>, Node<'_, '_>)>,
    mut transitions: Vec<TransitionDecl>,
    cx: &Cx<'_, '_>,
) -> Result<(Vec<StateDecl>, Vec<TransitionDecl>), XmlError> {
    let mut extra: Vec<StateDecl> = Vec::new();
    let mut chains: Vec<TransitionDecl> = Vec::new();
    for (si, (body, node)) in bodies.into_iter().enumerate() {
        let name = states[si].name.clone();
        let mut chain = Chain {
            base: name.clone(),
            states: vec![StateDecl {
                name: format!("{name}.0"),
                actions: Vec::new(),
            }],
            transitions: Vec::new(),
        };
        let mut at = 0;
        for step in body {
            match step {
                Step::Act(a) => chain.states[at].actions.push(a),
                Step::Stmt(st) => match chain.run(at, &st) {
                    Some(end) => at = end,
                    None => {
                        return Err(cx.node_err(
                            node,
                            format!(
                                "state `{name}` chooses among so many arms that its chain takes \
                                 more than {MAX_STATES} states: a table holds at most \
                                 {MAX_STATES} (MAX_STATES)"
                            ),
                        ))
                    }
                },
            }
        }
        if chain.states.len() == 1 {
            // Nothing chose: the state does it all on entry.
            states[si].actions = chain.states.remove(0).actions;
            continue;
        }
        // The last meeting point is the state itself.
        let last = chain.states[at].name.clone();
        let mut generated: Vec<StateDecl> = chain.states;
        let rest_actions = std::mem::take(&mut generated[at].actions);
        generated.remove(at);
        let rename = |n: &str| {
            if n == last {
                name.clone()
            } else {
                n.to_string()
            }
        };
        for t in &mut chain.transitions {
            t.from = rename(&t.from);
            t.to = rename(&t.to);
        }
        let taken =
            |n: &str| states.iter().any(|d| d.name == n) || extra.iter().any(|d| d.name == n);
        if let Some(clash) = generated.iter().find(|g| taken(&g.name)) {
            return Err(cx.node_err(
                node,
                format!(
                    "state `{}` chooses, and its chain's state `{}` is taken by another state",
                    name, clash.name
                ),
            ));
        }
        for t in &mut transitions {
            if t.to == name {
                t.to = format!("{name}.0");
            }
        }
        states[si].actions = rest_actions;
        // The entry takes the state's place (it may be the initial state).
        let entry = generated.remove(0);
        let own = std::mem::replace(&mut states[si], entry);
        extra.push(own);
        extra.extend(generated);
        chains.extend(chain.transitions);
    }
    states.extend(extra);
    // The chains' event-less transitions first: they fire as soon as their state is
    // entered, before any of the state's own.
    chains.extend(transitions);
    Ok((states, chains))
}

/// The states and transitions one choosing state becomes.
struct Chain {
    base: String,
    states: Vec<StateDecl>,
    transitions: Vec<TransitionDecl>,
}

impl Chain {
    /// A new state of the chain; `None` past [`MAX_STATES`] (no table holds the chain: it
    /// stops there, so that the guards it builds, each longer than the one before, stay
    /// bounded).
    fn state(&mut self) -> Option<usize> {
        if self.states.len() > MAX_STATES {
            return None;
        }
        self.states.push(StateDecl {
            name: format!("{}.{}", self.base, self.states.len()),
            actions: Vec::new(),
        });
        Some(self.states.len() - 1)
    }

    fn go(&mut self, from: usize, to: usize, when: Option<String>) {
        self.transitions.push(TransitionDecl {
            from: self.states[from].name.clone(),
            to: self.states[to].name.clone(),
            on: None,
            when,
        });
    }

    /// Runs `st` from state `at`; the state where it ends (`None`: the chain took more
    /// than [`MAX_STATES`] states).
    fn run(&mut self, at: usize, st: &Stmt) -> Option<usize> {
        match st {
            Stmt::Assign(v, e) => {
                self.states[at]
                    .actions
                    .push(ActionDecl::Set(v.clone(), e.clone()));
                Some(at)
            }
            Stmt::If { arms, otherwise } => {
                let join = self.state()?;
                let mut before: Vec<String> = Vec::new();
                let guard = |before: &[String], cond: Option<&str>| {
                    let mut parts: Vec<String> = before.iter().map(|c| format!("(!{c})")).collect();
                    parts.extend(cond.map(str::to_string));
                    parts.join(" && ")
                };
                for (cond, body) in arms {
                    let start = self.state()?;
                    self.go(at, start, Some(guard(&before, Some(cond))));
                    let mut end = start;
                    for s in body {
                        end = self.run(end, s)?;
                    }
                    self.go(end, join, None);
                    before.push(cond.clone());
                }
                let rest = guard(&before, None);
                if otherwise.is_empty() {
                    self.go(at, join, Some(rest));
                } else {
                    let start = self.state()?;
                    self.go(at, start, Some(rest));
                    let mut end = start;
                    for s in otherwise {
                        end = self.run(end, s)?;
                    }
                    self.go(end, join, None);
                }
                Some(join)
            }
        }
    }
}

/// A transition condition -> (event input, guard).
fn condition(
    text: &str,
    events: &[(String, Node<'_, '_>)],
    names: &[Name],
) -> Result<(Option<String>, Option<String>), StError> {
    let trimmed = text.trim();
    let lead = text.len() - text.trim_start().len();
    let shift = |mut e: StError, by: usize| {
        e.span = e.span.start + by..e.span.end + by;
        e
    };
    if trimmed == "1" || trimmed.eq_ignore_ascii_case("TRUE") {
        return Ok((None, None));
    }
    let word_end = trimmed
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(trimmed.len());
    let word = &trimmed[..word_end];
    let event = events
        .iter()
        .find(|(n, _)| !word.is_empty() && n.eq_ignore_ascii_case(word))
        .map(|(n, _)| n.clone());
    let Some(event) = event else {
        if !word.is_empty() && trimmed[word_end..].trim_start().starts_with('[') {
            return Err(StError {
                message: format!("`{word}` is not an event input of this FB type"),
                span: lead..lead + word_end,
            });
        }
        // `[guard]` or a bare guard.
        let (inner, at) = match trimmed.strip_prefix('[') {
            Some(rest) => match rest.strip_suffix(']') {
                Some(inner) => (inner, lead + 1),
                None => {
                    return Err(StError {
                        message: String::from("`[` without its `]`"),
                        span: lead..lead + 1,
                    })
                }
            },
            None => (trimmed, lead),
        };
        let guard = st::condition(inner, names).map_err(|e| shift(e, at))?;
        return Ok((None, Some(guard)));
    };
    let rest = &trimmed[word_end..];
    let rest_at = lead + word_end;
    let after = rest.trim_start();
    let after_at = rest_at + (rest.len() - after.len());
    if after.is_empty() {
        return Ok((Some(event), None));
    }
    let (guard, at) = if let Some(g) = after.strip_prefix('[') {
        match g.trim_end().strip_suffix(']') {
            Some(inner) => (inner, after_at + 1),
            None => {
                return Err(StError {
                    message: String::from("`[` without its `]`"),
                    span: after_at..after_at + 1,
                })
            }
        }
    } else if let Some(g) = after.strip_prefix('&') {
        (g, after_at + 1)
    } else if let Some(g) = after
        .get(..3)
        .filter(|and| and.eq_ignore_ascii_case("AND"))
        .and_then(|_| after.get(3..))
    {
        (g, after_at + 3)
    } else {
        return Err(StError {
            message: format!("expected `[guard]` or `& guard` after the event `{event}`"),
            span: after_at..after_at + 1,
        });
    };
    let guard = st::condition(guard, names).map_err(|e| shift(e, at))?;
    Ok((Some(event), Some(guard)))
}
