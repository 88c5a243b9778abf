//! An application (`.sys`) -> the robot's roles, charts and assignments
//! (docs/iec61499-xml.md, "How to bring a 4diac project"):
//!
//! - each resource a role, each device a node (named in the robot's `nodes`);
//! - composite FB instances flattened into the basic FBs inside (`comp.inner`);
//! - each basic FB instance a chart of its resource's role, its `Parameter`s (or input
//!   variables' initial values) the chart's parameters;
//! - each event connection an `on` entry of its destination: `FB.OUT` inside a resource,
//!   `ROLE/FB.OUT` across the mapping (a publication / subscription after lowering);
//! - an `E_DELAY` serving one FB (START from it, EO back to it) that FB's timer;
//! - the robot file's `on` and `actions` feed FB inputs from the plant and make FB
//!   outputs drive it.
//!
//! Anything else is an error at its element; nothing is half imported (the robot is
//! changed only when the whole application imported).

use std::collections::{BTreeMap, BTreeSet};

use super::composite::Composite;
use super::fbt::Interface;
use super::io_fb::IoType;
use super::net::{At, Fb, Network, SysError};
use super::st::{self, Ty};
use super::sys::{self, System};
use crate::model::{
    ActionDecl, ApplicationDecl, ChartInstance, ChartType, Declared, PlacesVar, Robot, Role,
};

/// The event FB library, written for this project in the 4diac style: a `.sys` may use
/// these types without listing them in `fb_types`.
pub const LIBRARY: &[(&str, &str)] = &[
    ("E_CTU", include_str!("../../types/iec61499/E_CTU.fbt")),
    ("E_CTD", include_str!("../../types/iec61499/E_CTD.fbt")),
    ("E_CTUD", include_str!("../../types/iec61499/E_CTUD.fbt")),
    ("E_SR", include_str!("../../types/iec61499/E_SR.fbt")),
    ("E_RS", include_str!("../../types/iec61499/E_RS.fbt")),
    (
        "E_SWITCH",
        include_str!("../../types/iec61499/E_SWITCH.fbt"),
    ),
    ("E_DEMUX", include_str!("../../types/iec61499/E_DEMUX.fbt")),
    (
        "E_PERMIT",
        include_str!("../../types/iec61499/E_PERMIT.fbt"),
    ),
    (
        "E_R_TRIG",
        include_str!("../../types/iec61499/E_R_TRIG.fbt"),
    ),
    (
        "E_F_TRIG",
        include_str!("../../types/iec61499/E_F_TRIG.fbt"),
    ),
    ("E_D_FF", include_str!("../../types/iec61499/E_D_FF.fbt")),
    ("E_T_FF", include_str!("../../types/iec61499/E_T_FF.fbt")),
    ("E_SPLIT", include_str!("../../types/iec61499/E_SPLIT.fbt")),
    ("E_MERGE", include_str!("../../types/iec61499/E_MERGE.fbt")),
];

/// The delay FB folded into the timer of the FB it serves.
const DELAY: &str = "E_DELAY";

/// Service FBs of the 4diac library (their behaviour is not an ECC), named in errors.
const SERVICE: &[&str] = &[
    "E_RESTART",
    "E_CYCLE",
    "E_TRAIN",
    "E_TABLE",
    "E_N_TABLE",
    "E_TIMEOUT",
    "E_STOPWATCH",
    "IX",
    "QX",
    "IW",
    "QW",
    "ID",
    "QD",
];

/// Why the application did not import: an error in one of its files, or in the robot
/// file's `application` entry (at the RON path `path`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum AppError {
    Xml(SysError),
    /// At the value at `path` of the robot file, or the key `key` of the map there.
    Ron {
        path: String,
        key: Option<String>,
        message: String,
    },
}

impl From<SysError> for AppError {
    fn from(e: SysError) -> AppError {
        AppError::Xml(e)
    }
}

fn ron(path: &str, message: impl Into<String>) -> AppError {
    AppError::Ron {
        path: path.to_string(),
        key: None,
        message: message.into(),
    }
}

/// An error at key `key` of the map at `path` of the robot file.
fn ron_key(path: &str, key: &str, message: impl Into<String>) -> AppError {
    AppError::Ron {
        path: path.to_string(),
        key: Some(key.to_string()),
        message: message.into(),
    }
}

/// The FB types an application may instantiate: basic ones with their typed interfaces
/// (the robot's, then the library's as used) and composite ones.
#[derive(Debug, Clone, Default)]
pub struct Types {
    pub basic: Vec<(ChartType, Interface)>,
    pub composites: Vec<Composite>,
    /// The node services types (`ROLE_IO`, [`super::io_fb`]).
    pub ios: Vec<IoType>,
    /// Where each of `basic` is, by name (an application of lifted charts has a type per
    /// FB): the first of a name, checked on use.
    index: BTreeMap<String, usize>,
}

impl Types {
    /// The robot's chart types (written in RON: parameters as DINT, variables as outputs)
    /// and its imported FB types' interfaces.
    pub fn of(robot: &Robot, interfaces: &[(String, Interface)]) -> Types {
        let mut by_name: BTreeMap<&str, &Interface> = BTreeMap::new();
        for (n, i) in interfaces {
            by_name.entry(n.as_str()).or_insert(i);
        }
        let basic = robot
            .chart_types
            .iter()
            .map(|t| {
                let i = (by_name.get(t.name.as_str()))
                    .map(|i| (*i).clone())
                    .unwrap_or_else(|| Interface {
                        inputs: t
                            .params
                            .iter()
                            .map(|p| (p.clone(), Ty::of("DINT").unwrap_or(Ty::Bool), None))
                            .collect(),
                        outputs: t.vars.iter().map(|v| v.name.clone()).collect(),
                        vars: (t.vars.iter())
                            .map(|v| (v.name.clone(), Ty::of("DINT").unwrap_or(Ty::Bool)))
                            .collect(),
                        services: Vec::new(),
                        levels: Vec::new(),
                        places: Vec::new(),
                        values: Vec::new(),
                    });
                (t.clone(), i)
            })
            .collect();
        let mut types = Types {
            basic,
            composites: Vec::new(),
            ios: Vec::new(),
            index: BTreeMap::new(),
        };
        types.reindex();
        types
    }

    fn reindex(&mut self) {
        self.index.clear();
        for (k, (t, _)) in self.basic.iter().enumerate() {
            self.index.entry(t.name.clone()).or_insert(k);
        }
    }

    fn basic(&self, name: &str) -> Option<&(ChartType, Interface)> {
        let indexed = (self.index.get(name))
            .and_then(|k| self.basic.get(*k))
            .filter(|(t, _)| t.name == name);
        // `basic` is public: a type pushed by hand is found all the same.
        indexed.or_else(|| self.basic.iter().find(|(t, _)| t.name == name))
    }

    fn io(&self, name: &str) -> Option<&IoType> {
        self.ios.iter().find(|c| c.name == name)
    }

    fn composite(&self, name: &str) -> Option<&Composite> {
        self.composites.iter().find(|c| c.name == name)
    }

    /// Makes `name` known if the library has it; whether it did.
    fn load_library(&mut self, name: &str, at: &At) -> Result<bool, SysError> {
        let Some((_, text)) = LIBRARY.iter().find(|(n, _)| *n == name) else {
            return Ok(false);
        };
        let typed = super::fbt::import_typed(text)
            .map_err(|e| at.error(format!("library type `{name}`: {e}")))?;
        self.index
            .entry(typed.0.name.clone())
            .or_insert(self.basic.len());
        self.basic.push(typed);
        Ok(true)
    }
}

/// What an application adds to the robot.
#[derive(Debug, Clone)]
pub struct Brought {
    /// Every role: the robot file's, with the charts of their resources, then the other
    /// resources'.
    pub roles: Vec<Role>,
    pub assign: Vec<(String, String)>,
    /// The chart types the charts use that the robot does not have yet (library types,
    /// and per-instance copies where the robot file binds outputs or a delay is folded).
    pub chart_types: Vec<ChartType>,
    /// The chart variables holding a control function's place ([`Interface::places`]).
    pub places: Vec<PlacesVar>,
}

/// One basic FB after flattening: its full name (`comp.inner`), type, parameters and the
/// top-level FB whose mapping places it.
struct Leaf {
    name: String,
    ty: String,
    top: String,
    params: Vec<super::net::Param>,
    at: At,
}

/// A connection between two ports (`FB`, `PORT`), full names.
#[derive(Clone)]
struct Edge {
    from: (String, String),
    to: (String, String),
    at: At,
}

/// The flattened application.
#[derive(Default)]
struct Flat {
    leaves: Vec<Leaf>,
    /// Composite instances (full name) and their types.
    composites: BTreeMap<String, String>,
    /// Node services FBs (full name): the top-level FB whose mapping places them, and
    /// their type.
    ios: BTreeMap<String, (String, String)>,
    /// Parameters of composite instances: (instance, input) -> value.
    cparams: BTreeMap<(String, String), (String, At)>,
    events: Vec<Edge>,
    data: Vec<Edge>,
    /// The event connections from each port, the data connections into each (by index
    /// of `events` / `data`), once expanded ([`Flat::index`]).
    events_from: BTreeMap<(String, String), Vec<usize>>,
    data_into: BTreeMap<(String, String), Vec<usize>>,
}

/// The ports of an FB kind: event inputs, event outputs, data inputs, data outputs.
type Ports = (Vec<String>, Vec<String>, Vec<String>, Vec<String>);

fn delay_ports() -> Ports {
    (
        vec!["START".into(), "STOP".into()],
        vec!["EO".into()],
        vec!["DT".into()],
        Vec::new(),
    )
}

impl Flat {
    /// Expands `net` (of the composite instance `prefix`, typed `iface`; the application's
    /// own network without).
    fn expand(
        &mut self,
        types: &mut Types,
        net: &Network,
        prefix: Option<&str>,
        iface: Option<&Composite>,
        top: Option<&str>,
        stack: &mut Vec<String>,
    ) -> Result<(), SysError> {
        let full = |n: &str| prefix.map_or(n.to_string(), |p| format!("{p}.{n}"));
        let mut ports: BTreeMap<String, (String, Ports)> = BTreeMap::new();
        for fb in &net.fbs {
            if ports.contains_key(&fb.name) {
                return Err(fb.at.error(format!("FB `{}` is declared twice", fb.name)));
            }
            let name = full(&fb.name);
            let top = top.unwrap_or(&fb.name);
            let p = self.fb(types, fb, &name, top, stack)?;
            ports.insert(fb.name.clone(), (fb.ty.clone(), p));
        }
        let end = |text: &str,
                   source: bool,
                   event: bool,
                   at: &At|
         -> Result<(String, String), SysError> {
            let what = match (event, source) {
                (true, true) => "event output",
                (true, false) => "event input",
                (false, true) => "data output",
                (false, false) => "data input",
            };
            match text.split_once('.') {
                Some((fb, port)) => {
                    let Some((ty, (ei, eo, di, dout))) = ports.get(fb) else {
                        return Err(at.error(format!("`{text}`: no FB `{fb}` in this network")));
                    };
                    let list = match (event, source) {
                        (true, true) => eo,
                        (true, false) => ei,
                        (false, true) => dout,
                        (false, false) => di,
                    };
                    if !list.iter().any(|x| x == port) {
                        return Err(at.error(format!(
                            "`{text}`: `{fb}` (of type `{ty}`) has no {what} `{port}`"
                        )));
                    }
                    Ok((full(fb), port.to_string()))
                }
                None => {
                    // A port of the enclosing composite's interface: its inputs are
                    // sources inside, its outputs destinations.
                    let found = iface.is_some_and(|c| {
                        let list = match (event, source) {
                            (true, true) => &c.events_in,
                            (true, false) => &c.events_out,
                            (false, false) => &c.outputs,
                            (false, true) => {
                                return c.inputs.iter().any(|(n, _)| n == text);
                            }
                        };
                        list.iter().any(|x| x == text)
                    });
                    match (found, prefix) {
                        (true, Some(p)) => Ok((p.to_string(), text.to_string())),
                        _ => Err(at.error(format!(
                            "`{text}` names no FB port (`FB.PORT`){}",
                            iface.map_or(String::new(), |c| format!(
                                " nor a {} of `{}`",
                                if source { "input" } else { "output" },
                                c.name
                            ))
                        ))),
                    }
                }
            }
        };
        for (list, event) in [(&net.events, true), (&net.data, false)] {
            for c in list {
                let edge = Edge {
                    from: end(&c.source, true, event, &c.at)?,
                    to: end(&c.dest, false, event, &c.at)?,
                    at: c.at.clone(),
                };
                if event {
                    self.events.push(edge);
                } else {
                    self.data.push(edge);
                }
            }
        }
        Ok(())
    }

    /// One FB of a network (full name `name`): a leaf, or a composite expanded; its ports.
    fn fb(
        &mut self,
        types: &mut Types,
        fb: &Fb,
        name: &str,
        top: &str,
        stack: &mut Vec<String>,
    ) -> Result<Ports, SysError> {
        let leaf = |params: Vec<super::net::Param>| Leaf {
            name: name.to_string(),
            ty: fb.ty.clone(),
            top: top.to_string(),
            params,
            at: fb.at.clone(),
        };
        if fb.ty == DELAY {
            self.leaves.push(leaf(fb.params.clone()));
            return Ok(delay_ports());
        }
        if let Some(c) = types.composite(&fb.ty).cloned() {
            if stack.contains(&c.name) {
                return Err(fb
                    .at
                    .error(format!("composite FB type `{}` contains itself", c.name)));
            }
            self.composites.insert(name.to_string(), c.name.clone());
            for p in &fb.params {
                if !c.inputs.iter().any(|(n, _)| *n == p.name) {
                    return Err(p
                        .at
                        .error(format!("`{}` has no input variable `{}`", c.name, p.name)));
                }
                self.cparams.insert(
                    (name.to_string(), p.name.clone()),
                    (p.value.clone(), p.at.clone()),
                );
            }
            stack.push(c.name.clone());
            self.expand(types, &c.net, Some(name), Some(&c), Some(top), stack)?;
            stack.pop();
            return Ok((
                c.events_in.clone(),
                c.events_out.clone(),
                c.inputs.iter().map(|(n, _)| n.clone()).collect(),
                c.outputs.clone(),
            ));
        }
        if let Some(io) = types.io(&fb.ty) {
            if let Some(p) = fb.params.first() {
                return Err(p.at.error(format!(
                    "`{}` has no input variable `{}` (a node services type has events only)",
                    io.name, p.name
                )));
            }
            self.ios
                .insert(name.to_string(), (top.to_string(), fb.ty.clone()));
            return Ok((
                io.events_in.clone(),
                io.events_out.iter().map(|(p, _)| p.clone()).collect(),
                Vec::new(),
                Vec::new(),
            ));
        }
        if types.basic(&fb.ty).is_none() && !types.load_library(&fb.ty, &fb.at)? {
            return Err(fb.at.error(unknown_type(&fb.name, &fb.ty)));
        }
        let Some((t, i)) = types.basic(&fb.ty) else {
            return Err(fb.at.error(unknown_type(&fb.name, &fb.ty)));
        };
        for p in &fb.params {
            if !t.params.contains(&p.name) {
                return Err(p
                    .at
                    .error(format!("`{}` has no input variable `{}`", t.name, p.name)));
            }
        }
        // A timer's expiry and the service events are ports too: only the role's node
        // services FB may connect to them (checked in `bring`).
        let ports = (
            t.inputs.iter().chain(&t.timers).cloned().collect(),
            t.outputs.iter().chain(&i.services).cloned().collect(),
            t.params.clone(),
            i.outputs.clone(),
        );
        self.leaves.push(leaf(fb.params.clone()));
        Ok(ports)
    }

    /// Indexes the connections of the expanded application ([`Flat::events_from`]).
    fn index(&mut self) {
        self.events_from.clear();
        self.data_into.clear();
        for (k, e) in self.events.iter().enumerate() {
            self.events_from.entry(e.from.clone()).or_default().push(k);
        }
        for (k, e) in self.data.iter().enumerate() {
            self.data_into.entry(e.to.clone()).or_default().push(k);
        }
    }

    /// The leaf ports an event reaching `at` ends in (through composite interfaces).
    fn ends(
        &self,
        at: &(String, String),
        seen: &mut BTreeSet<(String, String)>,
    ) -> Vec<(String, String)> {
        if !self.composites.contains_key(&at.0) {
            return vec![at.clone()];
        }
        if !seen.insert(at.clone()) {
            return Vec::new();
        }
        let mut out = Vec::new();
        for k in self.events_from.get(at).into_iter().flatten() {
            if let Some(e) = self.events.get(*k) {
                out.extend(self.ends(&e.to, seen));
            }
        }
        out
    }

    /// Every connection from a basic FB's output to a basic FB's input.
    fn leaf_edges(&self) -> Vec<Edge> {
        let mut out = Vec::new();
        for e in &self.events {
            if self.composites.contains_key(&e.from.0) {
                continue;
            }
            for to in self.ends(&e.to, &mut BTreeSet::new()) {
                out.push(Edge {
                    from: e.from.clone(),
                    to,
                    at: e.at.clone(),
                });
            }
        }
        out
    }

    /// Where the value of data input `to` (of a leaf or a composite instance) given by no
    /// own `Parameter` comes from: a composite instance's parameter (or its input's
    /// initial value) reaching it, or a basic FB's data output connected to it (through
    /// composite interfaces), if any.
    fn data_value(&self, types: &Types, to: &(String, String)) -> Result<Option<Data>, SysError> {
        let into: Vec<&Edge> = (self.data_into.get(to).into_iter().flatten())
            .filter_map(|k| self.data.get(*k))
            .collect();
        let Some(e) = into.first() else {
            return Ok(None);
        };
        if let Some(second) = into.get(1) {
            return Err(second
                .at
                .error(format!("`{}.{}` has a second data connection", to.0, to.1)));
        }
        let from = &e.from;
        let Some(cty) = self.composites.get(&from.0) else {
            return Ok(Some(Data::Var {
                fb: from.0.clone(),
                var: from.1.clone(),
                at: e.at.clone(),
            }));
        };
        if let Some((v, at)) = self.cparams.get(from) {
            return Ok(Some(Data::Literal(v.clone(), at.clone())));
        }
        if let Some(v) = self.data_value(types, from)? {
            return Ok(Some(v));
        }
        let init = types
            .composite(cty)
            .and_then(|c| c.inputs.iter().find(|(n, _)| *n == from.1))
            .and_then(|(_, v)| v.clone());
        Ok(init.map(|v| Data::Literal(v, e.at.clone())))
    }
}

/// Where a data input's value comes from ([`Flat::data_value`]).
enum Data {
    /// A literal as written (a composite instance's parameter or its input's initial
    /// value), at its place.
    Literal(String, At),
    /// Data output `var` of basic FB `fb`, by the connection at `at`: within a resource,
    /// the input reads the FB's variable.
    Var { fb: String, var: String, at: At },
}

/// The keys of a map by (FB, port) from FB `fb`'s first on: its keys are those the range
/// starts with (`take_while` the FB is `fb`).
fn own_range(fb: &str) -> std::ops::RangeFrom<(String, String)> {
    (fb.to_string(), String::new())..
}

/// The library's merge, folded where a chain of them feeds one input.
const MERGE: &str = "E_MERGE";

/// The E_MERGEs whose `EO` feeds one chart input and nothing else, folded (IEC 61499's
/// way of giving an input several sources, as `export` writes it): each taken out of the
/// leaves, its chain's edges replaced by an edge from each source it joins (through the
/// E_MERGEs feeding its `EI1`, then `EI2`) to the input at the chain's end, where the
/// chain's last edge was; and per such input, its sources in that order. Any other
/// E_MERGE stays a chart.
#[allow(clippy::type_complexity)]
fn fold_merges(
    edges: Vec<Edge>,
    flat: &mut Flat,
    types: &Types,
) -> (Vec<Edge>, BTreeMap<(String, String), Vec<(String, String)>>) {
    let merge_type = types.basic(MERGE).is_some_and(|(t, _)| {
        t.inputs == ["EI1", "EI2"] && t.outputs == ["EO"] && t.params.is_empty()
    });
    let leaves: BTreeMap<&str, &Leaf> = (flat.leaves.iter().rev())
        .map(|l| (l.name.as_str(), l))
        .collect();
    // The edges from each FB and into each port, in order.
    let mut from_fb: BTreeMap<&str, Vec<&Edge>> = BTreeMap::new();
    let mut into_port: BTreeMap<(&str, &str), Vec<&Edge>> = BTreeMap::new();
    for e in &edges {
        from_fb.entry(e.from.0.as_str()).or_default().push(e);
        (into_port.entry((e.to.0.as_str(), e.to.1.as_str())))
            .or_default()
            .push(e);
    }
    let into = |fb: &str, port: &str| into_port.get(&(fb, port)).map_or(0, Vec::len);
    // A merge whose EO has one edge and each EI at most one.
    let mut folded: BTreeSet<String> = (flat.leaves.iter())
        .filter(|l| merge_type && l.ty == MERGE)
        .filter(|l| {
            let outs = from_fb.get(l.name.as_str()).map_or(0, Vec::len);
            outs == 1 && into(&l.name, "EI1") <= 1 && into(&l.name, "EI2") <= 1
        })
        .map(|l| l.name.clone())
        .collect();
    // Where each chain ends: a chart input (a loop or another FB: not folded). Each merge
    // is walked once: a chain's merges share its end.
    let mut ends: BTreeMap<String, Option<(String, String)>> = BTreeMap::new();
    for m in &folded {
        let mut path: Vec<&str> = Vec::new();
        let mut on_path: BTreeSet<&str> = BTreeSet::new();
        let mut at = m.as_str();
        let end = loop {
            if let Some(known) = ends.get(at) {
                break known.clone();
            }
            if !on_path.insert(at) {
                break None;
            }
            path.push(at);
            let Some(e) = from_fb.get(at).and_then(|list| list.first()) else {
                break None;
            };
            if !folded.contains(&e.to.0) {
                break (leaves.get(e.to.0.as_str()))
                    .filter(|l| l.ty != DELAY)
                    .map(|_| e.to.clone());
            }
            at = e.to.0.as_str();
        };
        for p in path {
            ends.insert(p.to_string(), end.clone());
        }
    }
    folded.retain(|m| ends.get(m).is_some_and(Option::is_some));
    fn sources<'e>(
        m: &str,
        into_port: &BTreeMap<(&str, &str), Vec<&'e Edge>>,
        folded: &BTreeSet<String>,
        depth: usize,
        out: &mut Vec<&'e Edge>,
    ) {
        for port in ["EI1", "EI2"] {
            for e in into_port.get(&(m, port)).into_iter().flatten() {
                if folded.contains(&e.from.0) && depth > 0 {
                    sources(&e.from.0, into_port, folded, depth - 1, out);
                } else {
                    out.push(e);
                }
            }
        }
    }
    let mut joined: BTreeMap<(String, String), Vec<(String, String)>> = BTreeMap::new();
    let mut out: Vec<Edge> = Vec::new();
    for e in &edges {
        let (from, to) = (folded.contains(&e.from.0), folded.contains(&e.to.0));
        if from && !to {
            // The chain's last edge: the sources it joins, in order.
            let mut list = Vec::new();
            sources(&e.from.0, &into_port, &folded, folded.len(), &mut list);
            let joins = joined.entry(e.to.clone()).or_default();
            for s in list {
                joins.push(s.from.clone());
                out.push(Edge {
                    from: s.from.clone(),
                    to: e.to.clone(),
                    at: s.at.clone(),
                });
            }
        } else if !from && !to {
            out.push(e.clone());
        }
    }
    flat.leaves.retain(|l| !folded.contains(&l.name));
    (out, joined)
}

/// An edge from a node services FB's output to a chart input, with the node event.
type PlantEdge = (Edge, String);

/// The edges of the node services FBs (`ROLE_IO`, [`super::io_fb`]) taken out of `edges`:
/// the other edges, and each from a node services FB's output to a chart input with the
/// node event it is. Into a node services FB go the service events of the charts of its
/// role, and from it a timer's expiry to the timer's own chart: the charts' types say
/// both already; a timer's expiry is also the role's timer event the output stands for
/// (`VC.watchdog`), which every chart it feeds shares (the third part: (FB, timer) -> the
/// role's timer event). Any other edge touching a node services FB, a timer or a service
/// is an error.
#[allow(clippy::type_complexity)]
fn node_services(
    edges: Vec<Edge>,
    flat: &Flat,
    leaf_of: &BTreeMap<&str, &Leaf>,
    types: &Types,
    role_of: &dyn Fn(&str) -> String,
) -> Result<
    (
        Vec<Edge>,
        Vec<PlantEdge>,
        BTreeMap<(String, String), String>,
    ),
    SysError,
> {
    let basic = |fb: &str| leaf_of.get(fb).and_then(|l| types.basic(&l.ty));
    let event_of = |fb: &str, port: &str| {
        (flat.ios.get(fb))
            .and_then(|(_, ty)| types.io(ty))
            .and_then(|io| io.events_out.iter().find(|(p, _)| p == port))
            .map(|(_, e)| e.clone())
    };
    let mut kept = Vec::new();
    let mut plant = Vec::new();
    let mut shared = BTreeMap::new();
    for e in edges {
        let (from, to) = (
            format!("{}.{}", e.from.0, e.from.1),
            format!("{}.{}", e.to.0, e.to.1),
        );
        let from_io = flat.ios.contains_key(&e.from.0);
        let to_io = flat.ios.contains_key(&e.to.0);
        let timer = basic(&e.to.0).is_some_and(|(t, _)| t.timers.contains(&e.to.1));
        let service = basic(&e.from.0).is_some_and(|(_, i)| i.services.contains(&e.from.1));
        let same = role_of(&e.from.0) == role_of(&e.to.0);
        let err = |m: String| Err(e.at.error(m));
        match (from_io, to_io) {
            (true, true) => return err(format!("`{from}` -> `{to}` joins two node services FBs")),
            (true, false) if timer && same => {
                let event = event_of(&e.from.0, &e.from.1).unwrap_or_default();
                shared.insert(e.to.clone(), event);
            }
            (true, false) if timer => {
                return err(format!(
                    "`{to}` is a timer of `{}`: its expiry comes from the node services FB of \
                     its own resource, not `{from}`",
                    e.to.0
                ))
            }
            (true, false) if basic(&e.to.0).is_none() => {
                return err(format!(
                    "`{from}` -> `{to}`: a node services FB feeds the inputs of basic FBs only"
                ))
            }
            (true, false) => {
                let event = event_of(&e.from.0, &e.from.1).unwrap_or_default();
                plant.push((e, event));
            }
            (false, true) if service && same => {}
            (false, true) => {
                return err(format!(
                    "`{to}` takes the node services of its resource's charts (`EXTEND_A`, \
                     `START_T_150`, ... of a type marked `{}`): `{from}` is none",
                    super::services::MARK
                ))
            }
            (false, false) if timer => {
                return err(format!(
                    "`{to}` is a timer of `{}` (its `START_` / `STOP_` events): only the node \
                     services FB of its resource connects to it",
                    e.to.0
                ))
            }
            (false, false) if service => {
                return err(format!(
                    "`{from}` is a node service: it connects to the node services FB of its \
                     resource only"
                ))
            }
            (false, false) => kept.push(e),
        }
    }
    Ok((kept, plant, shared))
}

/// The robot's node a device stands for: the node of its name, or else the one node whose
/// name made an IEC 61131-3 identifier is it (`node-1` exported as `node_1`).
fn node_of(robot: &Robot, device: &str) -> Option<String> {
    if let Some(n) = robot.nodes.iter().find(|n| n.name == device) {
        return Some(n.name.clone());
    }
    let like: Vec<&str> = (robot.nodes.iter())
        .filter(|n| super::export::fbt::identifier(&n.name) == device)
        .map(|n| n.name.as_str())
        .collect();
    match like.as_slice() {
        [one] => Some(one.to_string()),
        _ => None,
    }
}

fn unknown_type(fb: &str, ty: &str) -> String {
    let service = SERVICE.contains(&ty)
        || ["PUBLISH", "SUBSCRIBE", "CLIENT", "SERVER"]
            .iter()
            .any(|p| ty.starts_with(p));
    if service {
        format!(
            "FB `{fb}` is of type `{ty}`, a service FB: not supported (only basic and \
             composite FB types, and E_DELAY)"
        )
    } else {
        format!(
            "FB `{fb}` is of type `{ty}`: no basic or composite FB type of that name in the \
             robot's `fb_types`, its `chart_types` or the library"
        )
    }
}

/// A `TIME` literal (`T#150ms`, `TIME#1s500ms`) in whole milliseconds: each unit once at
/// most, the larger first (IEC 61131-3), so `T#150ms150ms` or `T#1ms1h` is no time.
pub fn time_ms(text: &str) -> Option<u32> {
    let t = text.trim();
    let (head, body) = t.split_once('#')?;
    if !["T", "TIME"].iter().any(|p| head.eq_ignore_ascii_case(p)) {
        return None;
    }
    let body = body.replace('_', "").to_ascii_lowercase();
    let mut us: u64 = 0;
    // The scale of the last unit: the next one must be smaller.
    let mut last = u64::MAX;
    let mut rest = body.as_str();
    if rest.is_empty() {
        return None;
    }
    while !rest.is_empty() {
        let digits = rest
            .find(|c: char| !c.is_ascii_digit())
            .unwrap_or(rest.len());
        let n: u64 = rest[..digits].parse().ok()?;
        rest = &rest[digits..];
        let unit = rest
            .find(|c: char| c.is_ascii_digit())
            .unwrap_or(rest.len());
        let scale: u64 = match &rest[..unit] {
            "d" => 86_400_000_000,
            "h" => 3_600_000_000,
            "m" => 60_000_000,
            "s" => 1_000_000,
            "ms" => 1_000,
            "us" => 1,
            _ => return None,
        };
        if scale >= last {
            return None;
        }
        last = scale;
        us = us.checked_add(n.checked_mul(scale)?)?;
        rest = &rest[unit..];
    }
    if !us.is_multiple_of(1000) {
        return None;
    }
    u32::try_from(us / 1000).ok()
}

/// Brings the application `sys` into `robot` (its `application` entry `decl`), with the
/// FB types `types`.
pub fn bring(
    robot: &Robot,
    decl: &ApplicationDecl,
    sys: &System,
    types: &mut Types,
) -> Result<Brought, AppError> {
    // Devices and resources: nodes and roles.
    // role -> (device, node)
    let mut places: BTreeMap<String, (String, String)> = BTreeMap::new();
    let mut order: Vec<String> = Vec::new();
    for d in &sys.devices {
        let Some(node) = node_of(robot, &d.name) else {
            return Err(d
                .at
                .error(format!(
                    "device `{}` is no node of the robot: add it to the robot file's `nodes` \
                     with its 802.15.4 short address",
                    d.name
                ))
                .into());
        };
        for r in &d.resources {
            if places.contains_key(&r.name) {
                return Err(r
                    .at
                    .error(format!(
                        "a second resource `{}`: each resource is a role, so their names are \
                         unique in the system",
                        r.name
                    ))
                    .into());
            }
            places.insert(r.name.clone(), (d.name.clone(), node.clone()));
            order.push(r.name.clone());
        }
    }
    // The mapping: each application FB onto one resource.
    let mut mapped: BTreeMap<String, String> = BTreeMap::new(); // top FB -> role
    let app_fbs: BTreeSet<&str> = sys.net.fbs.iter().map(|f| f.name.as_str()).collect();
    for m in &sys.mapping {
        if !app_fbs.contains(m.fb.as_str()) {
            return Err(m
                .at
                .error(format!(
                    "maps `{}`: no FB of that name in the application",
                    m.fb
                ))
                .into());
        }
        match places.get(&m.resource) {
            Some((d, _)) if *d == m.device => {}
            _ => {
                return Err(m
                    .at
                    .error(format!(
                        "maps onto `{}.{}`: no such resource",
                        m.device, m.resource
                    ))
                    .into())
            }
        }
        if mapped.insert(m.fb.clone(), m.resource.clone()).is_some() {
            return Err(m.at.error(format!("`{}` is mapped twice", m.fb)).into());
        }
    }
    for fb in &sys.net.fbs {
        if !mapped.contains_key(&fb.name) {
            return Err(fb
                .at
                .error(format!(
                    "FB `{}` is mapped to no resource (no `Mapping From=\"{}.{}\"`)",
                    fb.name, sys.app, fb.name
                ))
                .into());
        }
    }
    // A resource's own network: the mapped FBs' copies (as 4diac keeps them), an idle
    // E_RESTART, and the PUBLISH / SUBSCRIBE pairs of the connections the mapping cuts (as
    // `export` writes them); anything else would be lost.
    let by_source = super::io_fb::by_source(&sys.net);
    for d in &sys.devices {
        for r in &d.resources {
            for fb in &r.net.fbs {
                let ours = mapped.get(&fb.name) == Some(&r.name);
                if let Some(topic) = super::io_fb::pub_sub(fb) {
                    super::io_fb::check_pub_sub(fb, topic, &r.name, &by_source, &mapped)?;
                    continue;
                }
                if !ours && !sys::idle_restart(fb, &r.net) {
                    return Err(fb
                        .at
                        .error(format!(
                            "FB `{}` of resource `{}` is not in the application: put it in the \
                             application and map it",
                            fb.name, r.name
                        ))
                        .into());
                }
            }
        }
    }
    let mut flat = Flat::default();
    flat.expand(types, &sys.net, None, None, None, &mut Vec::new())?;
    flat.index();
    let edges = flat.leaf_edges();
    let (edges, joined) = fold_merges(edges, &mut flat, types);
    // The leaves by name (the first of a name: names are unique in a network, and a
    // composite's are prefixed).
    let leaf_of: BTreeMap<&str, &Leaf> = (flat.leaves.iter().rev())
        .map(|l| (l.name.as_str(), l))
        .collect();
    let role_of = |leaf: &str| -> String {
        (leaf_of.get(leaf))
            .map(|l| &l.top)
            .or_else(|| flat.ios.get(leaf).map(|(top, _)| top))
            .and_then(|top| mapped.get(top))
            .cloned()
            .unwrap_or_default()
    };
    let is_delay = |leaf: &str| leaf_of.get(leaf).is_some_and(|l| l.ty == DELAY);
    // Fan-in: one source per event input, or the sources an E_MERGE chain joins.
    let mut fed: BTreeMap<(String, String), At> = BTreeMap::new();
    for e in &edges {
        let first = joined.get(&e.to).and_then(|s| s.first()) == Some(&e.from);
        let several = joined.contains_key(&e.to) && !first;
        if !several && fed.insert(e.to.clone(), e.at.clone()).is_some() {
            return Err(e
                .at
                .error(format!(
                    "`{}.{}` has a second event connection: join its sources with an E_MERGE",
                    e.to.0, e.to.1
                ))
                .into());
        }
    }
    let (edges, plant_edges, shared_timers) =
        node_services(edges, &flat, &leaf_of, types, &role_of)?;
    // The edges from each FB port and into each FB, in order (by index of `edges`).
    let mut edges_from: BTreeMap<(&str, &str), Vec<usize>> = BTreeMap::new();
    let mut edges_into: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (k, e) in edges.iter().enumerate() {
        (edges_from.entry((e.from.0.as_str(), e.from.1.as_str())))
            .or_default()
            .push(k);
        edges_into.entry(e.to.0.as_str()).or_default().push(k);
    }
    let from_port = |fb: &str, port: &str| -> Vec<&Edge> {
        (edges_from.get(&(fb, port)).into_iter().flatten())
            .filter_map(|k| edges.get(*k))
            .collect()
    };
    let into_fb = |fb: &str| -> Vec<&Edge> {
        (edges_into.get(fb).into_iter().flatten())
            .filter_map(|k| edges.get(*k))
            .collect()
    };
    let mut plant_into: BTreeMap<&str, Vec<&PlantEdge>> = BTreeMap::new();
    for p in &plant_edges {
        plant_into.entry(p.0.to.0.as_str()).or_default().push(p);
    }
    // The node events of their own (`boot`, `home`) the charts read, per role.
    let mut node_events: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for (e, event) in &plant_edges {
        let node = (flat.ios.get(&e.from.0))
            .and_then(|(_, ty)| types.io(ty))
            .is_some_and(|io| io.node_events.contains(&e.from.1));
        let list = node_events.entry(role_of(&e.from.0)).or_default();
        if node && !list.contains(event) {
            list.push(event.clone());
        }
    }
    // Per basic FB: what its outputs become, its timers.
    let mut acts: BTreeMap<(String, String), ActionDecl> = BTreeMap::new();
    let mut timers: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for d in flat.leaves.iter().filter(|l| l.ty == DELAY) {
        let fold = |msg: &str| {
            d.at.error(format!(
                "E_DELAY `{}` {msg}: an E_DELAY is the timer of one FB (START, and STOP if \
                 used, from that FB's outputs, EO to one of its inputs, on its resource)",
                d.name
            ))
        };
        let into = |port: &str| {
            (into_fb(&d.name).into_iter())
                .filter(|e| e.to.1 == port)
                .collect::<Vec<_>>()
        };
        let starts = into("START");
        let [start] = starts.as_slice() else {
            return Err(fold("is not started by one FB output").into());
        };
        let owner = start.from.0.clone();
        // An E_DELAY's one event output is `EO`.
        let eo: Vec<&Edge> = from_port(&d.name, "EO");
        let [eo] = eo.as_slice() else {
            return Err(fold("does not end in one event input").into());
        };
        let stops = into("STOP");
        if eo.to.0 != owner
            || stops.iter().any(|s| s.from.0 != owner)
            || role_of(&d.name) != role_of(&owner)
            || is_delay(&owner)
        {
            return Err(fold("serves more than one FB").into());
        }
        let dt = d.params.iter().find(|p| p.name == "DT");
        let Some(ms) = dt.and_then(|p| time_ms(&p.value)) else {
            return Err(dt
                .map_or(&d.at, |p| &p.at)
                .error(format!(
                    "E_DELAY `{}` needs its `DT` as a TIME in whole milliseconds (`T#150ms`)",
                    d.name
                ))
                .into());
        };
        let timer = eo.to.1.clone();
        for (s, action) in std::iter::once((start, ActionDecl::StartTimer(timer.clone(), ms)))
            .chain(
                stops
                    .iter()
                    .map(|s| (s, ActionDecl::CancelTimer(timer.clone()))),
            )
        {
            if from_port(&s.from.0, &s.from.1).len() > 1 {
                return Err(s
                    .at
                    .error(format!(
                        "`{}.{}` drives E_DELAY `{}` and other inputs: give the delay its own output",
                        s.from.0, s.from.1, d.name
                    ))
                    .into());
            }
            acts.insert(s.from.clone(), action);
        }
        timers.entry(owner).or_default().push(timer);
    }
    // The robot file's bindings.
    let leaf_type = |fb: &str| -> Option<&ChartType> {
        let l = leaf_of.get(fb).filter(|l| l.ty != DELAY)?;
        types.basic(&l.ty).map(|(t, _)| t)
    };
    let split = |key: &str, path: &str| -> Result<(String, String, ChartType), AppError> {
        let Some((fb, port)) = key.rsplit_once('.') else {
            return Err(ron_key(
                path,
                key,
                format!("`{key}` names no FB port (`FB.EVENT`)"),
            ));
        };
        let Some(t) = leaf_type(fb) else {
            return Err(ron_key(
                path,
                key,
                format!("`{key}`: no basic FB `{fb}` in the application"),
            ));
        };
        Ok((fb.to_string(), port.to_string(), t.clone()))
    };
    let mut plant_on: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    for (key, source) in &decl.on {
        let (fb, port, t) = split(key, "application.on")?;
        if !t.inputs.contains(&port) {
            return Err(ron_key(
                "application.on",
                key,
                format!("`{key}`: `{}` has no event input `{port}`", t.name),
            ));
        }
        if fed.contains_key(&(fb.clone(), port.clone())) {
            return Err(ron_key(
                "application.on",
                key,
                format!("`{key}` is fed by the application already"),
            ));
        }
        plant_on.entry(fb).or_default().insert(port, source.clone());
    }
    for (key, action) in &decl.actions {
        let (fb, port, t) = split(key, "application.actions")?;
        if !t.outputs.contains(&port) {
            return Err(ron_key(
                "application.actions",
                key,
                format!("`{key}`: `{}` has no event output `{port}`", t.name),
            ));
        }
        let end = (fb.clone(), port.clone());
        if !from_port(&end.0, &end.1).is_empty() || acts.contains_key(&end) {
            return Err(ron_key(
                "application.actions",
                key,
                format!("`{key}` is connected in the application already"),
            ));
        }
        if !matches!(
            action,
            ActionDecl::Extend(_)
                | ActionDecl::Retract(_)
                | ActionDecl::Out(..)
                | ActionDecl::Fault(_)
        ) {
            return Err(ron_key(
                "application.actions",
                key,
                format!("`{key}`: an output event may `Extend`, `Retract`, `Out` or `Fault`"),
            ));
        }
        if let Some(unknown) = unknown_target(robot, &role_of(&fb), action) {
            return Err(ron_key(
                "application.actions",
                key,
                format!("`{key}`: {unknown}"),
            ));
        }
        acts.insert(end, action.clone());
    }
    // The charts.
    let mut roles: Vec<Role> = robot.roles.clone();
    let mut role_names: BTreeSet<String> = roles.iter().map(|r| r.name.clone()).collect();
    for name in &order {
        if role_names.insert(name.clone()) {
            roles.push(Role {
                name: name.clone(),
                actuators: Vec::new(),
                inputs: Vec::new(),
                outputs: Vec::new(),
                charts: Vec::new(),
                estop: None,
                node_events: Vec::new(),
            });
        }
    }
    for r in &mut roles {
        if let Some(events) = node_events.remove(&r.name) {
            r.node_events = events;
        }
    }
    let mut chart_types: Vec<ChartType> = Vec::new();
    // The names of the robot's chart types and of those brought so far.
    let mut type_names: BTreeSet<String> =
        robot.chart_types.iter().map(|x| x.name.clone()).collect();
    // Each role's place in `roles` (the first of a name).
    let mut role_at: BTreeMap<String, usize> = BTreeMap::new();
    for (k, r) in roles.iter().enumerate() {
        role_at.entry(r.name.clone()).or_insert(k);
    }
    let mut place_vars: Vec<PlacesVar> = Vec::new();
    for l in flat.leaves.iter().filter(|l| l.ty != DELAY) {
        let Some((t, iface)) = types.basic(&l.ty).cloned() else {
            continue;
        };
        let role = role_of(&l.name);
        let mut params = BTreeMap::new();
        let mut reads = BTreeMap::new();
        for (input, ty, init) in &iface.inputs {
            let own = l
                .params
                .iter()
                .find(|p| p.name == *input)
                .map(|p| Data::Literal(p.value.clone(), p.at.clone()));
            let given = match own {
                Some(v) => Some(v),
                None => flat.data_value(types, &(l.name.clone(), input.clone()))?,
            };
            let given = match given {
                Some(Data::Var { fb, var, at }) => {
                    let from_role = role_of(&fb);
                    if from_role != role {
                        return Err(at
                            .error(format!(
                                "data connection `{fb}.{var}` -> `{}.{input}` crosses resources \
                                 (`{fb}` is on `{from_role}`, `{}` on `{role}`): events between \
                                 nodes carry no data; map both FBs onto one resource, or give \
                                 `{input}` a parameter",
                                l.name, l.name
                            ))
                            .into());
                    }
                    let from_ty = (leaf_of.get(fb.as_str()))
                        .and_then(|f| types.basic(&f.ty))
                        .and_then(|(_, i)| i.vars.iter().find(|(n, _)| *n == var))
                        .map(|(_, t)| *t);
                    if let Some(from_ty) = from_ty.filter(|f| !st::holds(*ty, *f)) {
                        return Err(at
                            .error(format!(
                                "data connection `{fb}.{var}` -> `{}.{input}`: `{var}` is {} \
                                 and `{input}` {}, which does not hold every value of it",
                                l.name,
                                from_ty.name(),
                                ty.name()
                            ))
                            .into());
                    }
                    reads.insert(input.clone(), format!("{fb}.{var}"));
                    continue;
                }
                Some(Data::Literal(text, at)) => Some((text, at)),
                None => None,
            };
            if let (None, Some((_, fb, var))) =
                (&given, iface.values.iter().find(|(p, _, _)| p == input))
            {
                let found = leaf_type(fb).filter(|_| role_of(fb) == role);
                let Some(ft) = found else {
                    return Err(l
                        .at
                        .error(format!(
                            "input `{input}` of `{}` (of type `{}`) reads `{fb}.{var}` (its \
                             `Comment`): no basic FB `{fb}` on its resource `{role}`",
                            l.name, t.name
                        ))
                        .into());
                };
                if !ft.vars.iter().any(|v| v.name == *var) {
                    return Err(l
                        .at
                        .error(format!(
                            "input `{input}` of `{}` (of type `{}`) reads `{fb}.{var}` (its \
                             `Comment`): `{fb}` (of type `{}`) has no variable `{var}`",
                            l.name, t.name, ft.name
                        ))
                        .into());
                }
                reads.insert(input.clone(), format!("{fb}.{var}"));
                continue;
            }
            let value = match given {
                Some((text, at)) => st::literal(text.trim(), *ty).map_err(|e| {
                    at.error(format!(
                        "parameter `{input}` of `{}`: {}",
                        l.name, e.message
                    ))
                })?,
                None => init.clone().unwrap_or_else(|| String::from("0")),
            };
            let v: i32 = value.parse().map_err(|_| {
                l.at.error(format!(
                    "parameter `{input}` of `{}`: `{value}` is out of range",
                    l.name
                ))
            })?;
            params.insert(input.clone(), v);
        }
        let mut on = plant_on.remove(&l.name).unwrap_or_default();
        // Where the chart is declared, and the connection into each input (the first).
        let mut declared = Declared {
            fb: l.at.place(),
            on: BTreeMap::new(),
            ron_on: (on.keys())
                .map(|port| (port.clone(), format!("{}.{port}", l.name)))
                .collect(),
        };
        let plant_here = plant_into
            .get(l.name.as_str())
            .map_or(&[][..], Vec::as_slice);
        for e in plant_here.iter().map(|x| &x.0).chain(into_fb(&l.name)) {
            (declared.on)
                .entry(e.to.1.clone())
                .or_insert_with(|| e.at.place());
        }
        for (e, event) in plant_here.iter().copied() {
            let from_role = role_of(&e.from.0);
            on.insert(
                e.to.1.clone(),
                if from_role == role {
                    event.clone()
                } else {
                    format!("{from_role}/{event}")
                },
            );
        }
        // An input an E_MERGE chain feeds: its sources in the chain's order, the first
        // in `on`, the others its further sources.
        let mut several: BTreeMap<String, Vec<(usize, String)>> = BTreeMap::new();
        let rank = |e: &Edge| {
            let list = joined.get(&e.to)?;
            list.iter().position(|s| *s == e.from)
        };
        for (e, event) in plant_here.iter().copied() {
            if let Some(k) = rank(e) {
                let from_role = role_of(&e.from.0);
                let text = if from_role == role {
                    event.clone()
                } else {
                    format!("{from_role}/{event}")
                };
                several.entry(e.to.1.clone()).or_default().push((k, text));
            }
        }
        for e in into_fb(&l.name) {
            if is_delay(&e.from.0) {
                continue;
            }
            let from_role = role_of(&e.from.0);
            let event = format!("{}.{}", e.from.0, e.from.1);
            let text = if from_role == role {
                event
            } else {
                format!("{from_role}/{event}")
            };
            match rank(e) {
                Some(k) => several.entry(e.to.1.clone()).or_default().push((k, text)),
                None => {
                    on.insert(e.to.1.clone(), text);
                }
            }
        }
        let mut more = BTreeMap::new();
        for (input, mut list) in several {
            list.sort_by_key(|x| x.0);
            let mut texts = list.into_iter().map(|x| x.1);
            if let Some(first) = texts.next() {
                on.insert(input.clone(), first);
            }
            more.insert(input, texts.collect::<Vec<_>>());
        }
        let own_acts: Vec<(&String, &ActionDecl)> = (acts.range(own_range(&l.name)))
            .take_while(|((fb, _), _)| *fb == l.name)
            .map(|((_, o), a)| (o, a))
            .collect();
        let own_timers = timers.get(&l.name).cloned().unwrap_or_default();
        let type_name = if own_acts.is_empty() && own_timers.is_empty() {
            if type_names.insert(t.name.clone()) {
                chart_types.push(t.clone());
            }
            t.name.clone()
        } else {
            let mut s = t.clone();
            s.specializes = Some(t.name.clone());
            // `TYPE_FB`: an IEC 61131-3 identifier (so the robot exports back to 4diac),
            // made unique against the types already there.
            s.name = format!("{}_{}", t.name, l.name);
            let mut k = 2;
            while type_names.contains(&s.name) {
                s.name = format!("{}_{}_{k}", t.name, l.name);
                k += 1;
            }
            type_names.insert(s.name.clone());
            s.outputs.retain(|o| !own_acts.iter().any(|(x, _)| *x == o));
            s.inputs.retain(|i| !own_timers.contains(i));
            s.timers.extend(own_timers.iter().cloned());
            for st in &mut s.states {
                for a in &mut st.actions {
                    if let ActionDecl::Emit(o) = a {
                        if let Some((_, b)) = own_acts.iter().find(|(x, _)| *x == o) {
                            *a = (*b).clone();
                        }
                    }
                }
            }
            let n = s.name.clone();
            chart_types.push(s);
            n
        };
        for (var, function, names) in &iface.places {
            place_vars.push(PlacesVar {
                role: role.clone(),
                function: function.clone(),
                places: names.clone(),
                var: format!("{}.{var}", l.name),
            });
        }
        if let Some(r) = role_at.get(&role).and_then(|k| roles.get_mut(*k)) {
            let timers = (shared_timers.range(own_range(&l.name)))
                .take_while(|((fb, _), _)| *fb == l.name)
                .map(|((_, t), event)| (t.clone(), event.clone()))
                .collect();
            r.charts.push(ChartInstance {
                name: l.name.clone(),
                type_: type_name,
                params,
                on,
                timers,
                more,
                reads,
                declared: Some(declared),
            });
        }
    }
    // Assignments: the robot file's for its other roles, the mapping's for resources.
    let mut assign: Vec<(String, String)> = Vec::new();
    for (role, node) in &robot.assign {
        match places.get(role) {
            Some((d, n)) if n != node => {
                return Err(ron(
                    "assign",
                    format!(
                        "role `{role}` is assigned to `{node}`, but the application places its \
                         resource on device `{d}`"
                    ),
                ))
            }
            Some(_) => {}
            None => assign.push((role.clone(), node.clone())),
        }
    }
    for name in &order {
        if let Some((_, node)) = places.get(name) {
            assign.push((name.clone(), node.clone()));
        }
    }
    Ok(Brought {
        roles,
        assign,
        chart_types,
        places: place_vars,
    })
}

/// What `action` of an FB on `role` names that the role does not have (an actuator that
/// `Extend` or `Retract` moves, an output `Out` drives): said where the robot file binds
/// it, not at the robot.
fn unknown_target(robot: &Robot, role: &str, action: &ActionDecl) -> Option<String> {
    let r = robot.roles.iter().find(|r| r.name == role);
    let (what, name, have): (&str, &str, Vec<&str>) = match action {
        ActionDecl::Extend(a) | ActionDecl::Retract(a) => (
            "actuator",
            a,
            r.map_or(Vec::new(), |r| {
                r.actuators.iter().map(|x| x.name.as_str()).collect()
            }),
        ),
        ActionDecl::Out(o, _) => (
            "output",
            o,
            r.map_or(Vec::new(), |r| {
                r.outputs.iter().map(|x| x.name.as_str()).collect()
            }),
        ),
        _ => return None,
    };
    if have.contains(&name) {
        return None;
    }
    Some(match have.is_empty() {
        true => format!("no {what} `{name}` (role `{role}` has no {what}s)"),
        false => format!(
            "no {what} `{name}` (role `{role}`'s {what}s are {})",
            have.join(", ")
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::time_ms;

    #[test]
    fn time_literals_in_milliseconds() {
        assert_eq!(time_ms("T#150ms"), Some(150));
        assert_eq!(time_ms("TIME#1s500ms"), Some(1500));
        assert_eq!(time_ms("t#2m"), Some(120_000));
        assert_eq!(time_ms("T#1_000ms"), Some(1000));
        assert_eq!(time_ms("T#1500us"), None);
        assert_eq!(time_ms("150"), None);
        assert_eq!(time_ms("T#"), None);
        assert_eq!(time_ms("T#5x"), None);
        assert_eq!(time_ms("T#1h2m3s4ms"), Some(3_723_004));
        // Each unit once, the larger first.
        assert_eq!(time_ms("T#150ms150ms"), None);
        assert_eq!(time_ms("T#1s1s"), None);
        assert_eq!(time_ms("T#1ms1h"), None);
        assert_eq!(time_ms("T#1m1h"), None);
    }
}
