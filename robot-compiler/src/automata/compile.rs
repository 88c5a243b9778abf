//! The compilation of seed paper 004: a selecting automaton -> a network of token-passing
//! charts, one instance of the FB type `SelectingTransition` (`types/selecting-transition.ron`,
//! shipped with the tool) per transition, wired by the paper's rules
//! (docs/selecting-automata.md, "The generation rules"):
//!
//! - an instance per transition t: C = its colour, T = it leaves an initial state, R = it
//!   is a loop, M = a loop's cap (1 otherwise): the paper's four rules (with / without an
//!   initial token, with / without a loop);
//! - set: OutSet of a non-loop t -> Set of every transition leaving to(t);
//! - reset: OutReset of a non-loop t -> Reset of every other transition leaving from(t);
//! - WP of t <- the event of its colour (`part.black`), delivered to the instances in the
//!   automaton's firing order;
//! - Out of t is the automaton's output `NAME.t.Out`; EOS of a final t is emitted as the
//!   automaton's `NAME.EOS`.
//!
//! [`place`] joins the charts of every automaton with a `role` to that role's IR.

use std::collections::BTreeMap;

use config_schema::limits::{EVENT_QUEUE, MAX_CHARTS};

use super::{check, load, Automaton, TransitionId};
use crate::diag::Diagnostic;
use crate::ir::{Ir, RoleIr};
use crate::model::{AutomatonDecl, ChartInstance, ChartType, Robot};
use crate::source::Source;

/// The FB type as it ships with the tool.
pub const FB_TYPE_SOURCE: &str = include_str!("../../types/selecting-transition.ron");
/// Its file name, for diagnostics.
pub const FB_TYPE_FILE: &str = "selecting-transition.ron";
/// The default source of part colours: events `part.COLOUR`.
pub const DEFAULT_PARTS: &str = "part";

/// The FB type, parsed from [`FB_TYPE_SOURCE`].
pub fn fb_type() -> Result<ChartType, String> {
    ron::Options::default()
        .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
        .from_str(FB_TYPE_SOURCE)
        .map_err(|e| format!("{FB_TYPE_FILE}: {e}"))
}

/// The two kinds of arc between instances.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Arc {
    /// OutSet -> Set: passes the token on.
    Set,
    /// OutReset -> Reset: takes the token from a competitor.
    Reset,
}

/// One instance: the chart of transition `transition`, and its parameter values.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Instance {
    pub transition: TransitionId,
    /// `NAME.t1`.
    pub chart: String,
    pub c: i32,
    pub t: bool,
    pub r: bool,
    pub m: i32,
    pub is_final: bool,
}

impl Instance {
    /// The parameter values as a chart instance takes them.
    pub fn params(&self) -> BTreeMap<String, i32> {
        BTreeMap::from([
            (String::from("C"), self.c),
            (String::from("T"), i32::from(self.t)),
            (String::from("R"), i32::from(self.r)),
            (String::from("M"), self.m),
        ])
    }
}

/// An arc `from` -> `to` of kind `arc`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Connection {
    pub from: TransitionId,
    pub to: TransitionId,
    pub arc: Arc,
}

/// The FB network of an automaton: instances in declaration order, arcs by source.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Network {
    pub instances: Vec<Instance>,
    pub connections: Vec<Connection>,
}

impl Network {
    /// Whether the instance of `t` has an arc of kind `arc` going out.
    pub fn emits(&self, t: TransitionId, arc: Arc) -> bool {
        self.connections.iter().any(|c| c.from == t && c.arc == arc)
    }

    /// Events the instance of `t` queues when it takes a part (at most): Out, EOS on a
    /// final transition, OutSet and OutReset if they are wired.
    pub fn emissions(&self, t: TransitionId) -> usize {
        let Some(i) = self.instances.iter().find(|i| i.transition == t) else {
            return 0;
        };
        1 + usize::from(i.is_final)
            + usize::from(self.emits(t, Arc::Set))
            + usize::from(self.emits(t, Arc::Reset))
    }
}

/// The chart name of transition `t` of `a`.
pub fn chart_name(a: &Automaton, t: TransitionId) -> String {
    let id = a.get(t).map_or("?", |t| t.id.as_str());
    format!("{}.{id}", a.name)
}

/// The automaton-level EOS event.
pub fn eos_event(a: &Automaton) -> String {
    format!("{}.EOS", a.name)
}

/// The paper's generation rules.
pub fn network(a: &Automaton) -> Network {
    let instances = a
        .iter()
        .map(|(id, t)| Instance {
            transition: id,
            chart: chart_name(a, id),
            c: i32::from(t.colour.0),
            t: a.initial.contains(t.from),
            r: t.is_loop(),
            m: if t.is_loop() {
                t.max
                    .map_or(i32::MAX, |m| i32::try_from(m).unwrap_or(i32::MAX))
            } else {
                1
            },
            is_final: t.is_final(),
        })
        .collect();
    let mut connections = Vec::new();
    for (i, t) in a.iter() {
        if t.is_loop() {
            // A loop that takes a part keeps its state active: if a transition leaving
            // the state took the same part, the loop gives the state's transitions their
            // tokens back (after that transition's reset: loops are delivered last).
            if a.iter()
                .any(|(_, u)| !u.is_loop() && u.from == t.from && u.colour == t.colour)
            {
                for (j, u) in a.iter() {
                    if !u.is_loop() && u.from == t.from {
                        connections.push(Connection {
                            from: i,
                            to: j,
                            arc: Arc::Set,
                        });
                    }
                }
            }
            continue;
        }
        for (j, u) in a.iter() {
            if u.from == t.to {
                connections.push(Connection {
                    from: i,
                    to: j,
                    arc: Arc::Set,
                });
            }
        }
        // The paper's rule for nondeterministic automata: a competitor of the same
        // colour is not reset (it took the part too, or is a loop keeping the state).
        for (j, u) in a.iter() {
            if j != i && u.from == t.from && u.colour != t.colour {
                connections.push(Connection {
                    from: i,
                    to: j,
                    arc: Arc::Reset,
                });
            }
        }
    }
    Network {
        instances,
        connections,
    }
}

/// The order a part's event reaches the instances: the automaton's firing order, the
/// transitions that are not loops first, then the loops (so that a loop's arcs come
/// after the resets of the transitions leaving its state).
pub fn delivery_order(a: &Automaton) -> Vec<TransitionId> {
    let order = a.firing_order();
    let is_loop = |t: &TransitionId| a.get(*t).is_some_and(super::Transition::is_loop);
    let (mut out, loops): (Vec<_>, Vec<_>) = order.into_iter().partition(|t| !is_loop(t));
    out.extend(loops);
    out
}

/// A state the network cannot run as the semantics does: a loop and a transition that
/// leaves the state take one colour, and another loop of the state has another colour
/// (when the first loop keeps the state active, giving the state its tokens back would
/// restart the other loop's count). (state, the loop, the leaving transition, the other
/// loop).
pub fn unsupported(
    a: &Automaton,
) -> Option<(super::StateId, TransitionId, TransitionId, TransitionId)> {
    for (l, lt) in a.iter().filter(|(_, t)| t.is_loop()) {
        let leaving = a
            .iter()
            .find(|(_, u)| !u.is_loop() && u.from == lt.from && u.colour == lt.colour);
        let other = a
            .iter()
            .find(|(_, w)| w.is_loop() && w.from == lt.from && w.colour != lt.colour);
        if let (Some((u, _)), Some((w, _))) = (leaving, other) {
            return Some((lt.from, l, u, w));
        }
    }
    None
}

/// The most events one part makes the network queue at once (every instance that takes
/// it queues its [`Network::emissions`] before any is delivered), over every reachable
/// active set (loop counts abstracted) and colour, with that set and colour; `None` if
/// there are too many active sets to look at.
pub fn worst_part(a: &Automaton, net: &Network) -> Option<(usize, super::StateSet, super::Colour)> {
    let sets = check::active_sets(a, check::EXPLORE_LIMIT).ok()?;
    let mut worst = (0, a.initial, super::Colour(0));
    for set in sets {
        for c in 0..a.colours.len() {
            let queued: usize = a
                .iter()
                .filter(|(_, t)| set.contains(t.from) && t.colour.index() == c)
                .map(|(id, _)| net.emissions(id))
                .sum();
            if queued > worst.0 {
                worst = (queued, set, super::Colour(c as u8));
            }
        }
    }
    Some(worst)
}

/// Joins the charts of every automaton that names a `role` to that role, after the
/// role's own charts. Errors at the automaton's `role` (or `parts`).
pub fn place(robot: &Robot, src: &Source, ir: &mut Ir) -> Result<(), Vec<Diagnostic>> {
    if robot.automata.iter().all(|d| d.role.is_none()) {
        return Ok(());
    }
    let ty = fb_type().map_err(|e| vec![Diagnostic::error(src.span(""), e)])?;
    let loaded = load(robot, src);
    let mut diags = loaded.diagnostics;
    for l in &loaded.automata {
        let Some((i, decl)) = robot
            .automata
            .iter()
            .enumerate()
            .find(|(_, d)| d.name == l.automaton.name)
        else {
            continue;
        };
        if decl.role.is_some() {
            if let Err(mut d) = place_one(robot, src, ir, &ty, &l.automaton, decl, i) {
                diags.append(&mut d);
            }
        }
    }
    if diags.iter().any(Diagnostic::is_error) {
        return Err(diags);
    }
    Ok(())
}

/// The robot's automata placed on `role` (for `diagram`).
pub fn placed(robot: &Robot, src: &Source, role: &str) -> Vec<Automaton> {
    load(robot, src)
        .automata
        .into_iter()
        .map(|l| l.automaton)
        .filter(|a| {
            robot
                .automata
                .iter()
                .any(|d| d.name == a.name && d.role.as_deref() == Some(role))
        })
        .collect()
}

fn place_one(
    robot: &Robot,
    src: &Source,
    ir: &mut Ir,
    ty: &ChartType,
    a: &Automaton,
    decl: &AutomatonDecl,
    i: usize,
) -> Result<(), Vec<Diagnostic>> {
    let at = format!("automata[{i}]");
    let role_name = decl.role.as_deref().unwrap_or_default();
    let here = src.span(&format!("{at}.role"));
    let (Some((_, role)), Some(r)) = (
        robot.role(role_name),
        ir.roles.iter_mut().find(|r| r.name == role_name),
    ) else {
        let roles: Vec<&str> = robot.roles.iter().map(|r| r.name.as_str()).collect();
        return Err(vec![Diagnostic::error(
            here,
            format!("unknown role `{role_name}` for automaton `{}`", a.name),
        )
        .help(format!("roles: {}", roles.join(", ")))]);
    };
    let net = network(a);
    let charts = r.charts.len() + net.instances.len();
    if charts > MAX_CHARTS {
        let own = r.charts.len();
        return Err(vec![Diagnostic::error(
            here,
            format!(
                "automaton `{}` needs {} charts (one per transition) on role `{role_name}`, which has {own} of its own: {charts} charts, but a node holds at most MAX_CHARTS = {MAX_CHARTS} (over by {})",
                a.name,
                net.instances.len(),
                charts - MAX_CHARTS
            ),
        )
        .help(format!(
            "place the automaton on a role of its own node (at most {MAX_CHARTS} transitions), split it into automata on several nodes, or give it fewer transitions"
        ))]);
    }
    if let Some((q, l, u, w)) = unsupported(a) {
        let id = |t: TransitionId| a.get(t).map_or("?", |t| t.id.as_str());
        return Err(vec![Diagnostic::error(
            here,
            format!(
                "automaton `{}` cannot be compiled to a token network: in state `{}`, loop `{}` and `{}` (which leaves it) take the same colour, and loop `{}` takes another; when `{}` keeps `{}` active, the tokens it gives back would restart `{}`'s count",
                a.name,
                a.state_name(q),
                id(l),
                id(u),
                id(w),
                id(l),
                a.state_name(q),
                id(w)
            ),
        )
        .help("give the loop and the leaving transition different colours, or move one loop to a state of its own")]);
    }
    if let Some((queued, set, c)) = worst_part(a, &net) {
        if queued > EVENT_QUEUE {
            return Err(vec![Diagnostic::error(
                here,
                format!(
                    "automaton `{}`: a `{}` part with {} active queues {queued} events (Out, EOS, OutSet, OutReset of every transition that takes it), but a node queues at most EVENT_QUEUE = {EVENT_QUEUE} (over by {})",
                    a.name,
                    a.colour_name(c),
                    set.show(a),
                    queued - EVENT_QUEUE
                ),
            )
            .help("split the automaton, or give fewer transitions of one colour from states that are active together")]);
        }
    }
    let parts = decl.parts.as_deref().unwrap_or(DEFAULT_PARTS);
    let colour_event = colour_events(robot, src, &at, a, r, parts)?;
    let fb_src = Source::new(FB_TYPE_FILE, FB_TYPE_SOURCE);
    let base = r.charts.len();
    let mut diags = Vec::new();
    for inst in &net.instances {
        if r.charts.iter().any(|c| c.name == inst.chart) {
            diags.push(Diagnostic::error(
                here.clone(),
                format!(
                    "automaton `{}` makes a chart `{}`, but role `{role_name}` already has one",
                    a.name, inst.chart
                ),
            ));
            continue;
        }
        let t = instance_type(ty, &net, inst);
        let c = ChartInstance {
            name: inst.chart.clone(),
            type_: t.name.clone(),
            params: inst.params(),
            on: BTreeMap::new(),
            timers: BTreeMap::new(),
            more: BTreeMap::new(),
            reads: BTreeMap::new(),
            declared: None,
        };
        let bind = BTreeMap::from([(String::from("EOS"), eos_event(a))]);
        match crate::elab::instantiate(&fb_src, "", role, &c, &t, &bind, &BTreeMap::new(), r, &at) {
            Ok(chart) => r.charts.push(chart),
            Err(mut d) => diags.append(&mut d),
        }
    }
    if !diags.is_empty() {
        return Err(diags);
    }
    let input = |name: &str| ty.inputs.iter().position(|i| i == name).unwrap_or(0);
    let chart_of = |t: TransitionId| base + t.index();
    // WP: each colour's event reaches its instances in delivery order.
    for t in delivery_order(a) {
        let Some(tr) = a.get(t) else { continue };
        let Some(event) = colour_event.get(&tr.colour).cloned() else {
            continue;
        };
        r.event(&event);
        r.routes.push((event, chart_of(t), input("WP")));
    }
    if let Some(out) = &decl.out {
        took_routes(src, &at, a, &net, r, out)?;
    }
    for c in &net.connections {
        let (output, port) = match c.arc {
            Arc::Set => ("OutSet", "Set"),
            Arc::Reset => ("OutReset", "Reset"),
        };
        let event = format!("{}.{output}", chart_name(a, c.from));
        r.event(&event);
        r.routes.push((event, chart_of(c.to), input(port)));
    }
    Ok(())
}

/// `out: "CHART.INPUT"`: every instance's `Out` also reaches that chart input of the
/// role ("the automaton took this part"), after the instance's own outputs are queued.
fn took_routes(
    src: &Source,
    at: &str,
    a: &Automaton,
    net: &Network,
    r: &mut RoleIr,
    out: &str,
) -> Result<(), Vec<Diagnostic>> {
    let target = out.split_once('.').and_then(|(chart, input)| {
        let ci = r.charts.iter().position(|c| c.name == chart)?;
        let ii = r.charts.get(ci)?.inputs.iter().position(|i| i == input)?;
        Some((ci, ii))
    });
    let Some((ci, ii)) = target else {
        return Err(vec![Diagnostic::error(
            src.span(&format!("{at}.out")),
            format!(
                "automaton `{}`: `{out}` is not an input of a chart of role `{}`",
                a.name, r.name
            ),
        )
        .help("write `CHART.INPUT`, an input of one of the role's charts")]);
    };
    for inst in &net.instances {
        let event = format!("{}.Out", inst.chart);
        r.event(&event);
        r.routes.push((event, ci, ii));
    }
    Ok(())
}

/// The FB type for one instance: its unwired outputs are not emitted (OutSet, OutReset
/// without arcs; EOS off a final transition), so a part queues only what some chart
/// reads.
fn instance_type(ty: &ChartType, net: &Network, inst: &Instance) -> ChartType {
    let keep = |o: &str| match o {
        "OutSet" => net.emits(inst.transition, Arc::Set),
        "OutReset" => net.emits(inst.transition, Arc::Reset),
        "EOS" => inst.is_final,
        _ => true,
    };
    let mut t = ty.clone();
    for s in &mut t.states {
        s.actions
            .retain(|a| !matches!(a, crate::model::ActionDecl::Emit(o) if !keep(o)));
    }
    t
}

/// The node event of each colour the automaton reads: `PARTS.COLOUR` of its role, or,
/// for `parts: "ROLE/PARTS"`, that role's `PARTS.COLOUR` imported (an error at `parts`
/// if that role raises no such event).
fn colour_events(
    robot: &Robot,
    src: &Source,
    at: &str,
    a: &Automaton,
    r: &mut RoleIr,
    parts: &str,
) -> Result<BTreeMap<super::Colour, String>, Vec<Diagnostic>> {
    let (from, prefix) = crate::elab::split_source(parts, &r.name);
    let mut out = BTreeMap::new();
    let colours: Vec<super::Colour> = a.transitions.iter().map(|t| t.colour).collect();
    for c in colours {
        let event = format!("{prefix}.{}", a.colour_name(c));
        if from == r.name {
            out.insert(c, event);
            continue;
        }
        let raised = robot
            .role(from)
            .map(|(_, source)| crate::elab::role_events(robot, source));
        if !raised.is_some_and(|raised| raised.contains(&event)) {
            return Err(vec![Diagnostic::error(
                src.span(&format!("{at}.parts")),
                format!(
                    "automaton `{}` reads `{from}/{event}`, but role `{from}` raises no such event",
                    a.name
                ),
            )
            .help("a part of each colour is an event `PARTS.COLOUR` (a chart `PARTS` with an output per colour)")]);
        }
        let local = format!("{from}/{event}");
        if !r.imports.iter().any(|(_, _, l)| *l == local) {
            r.imports.push((from.to_string(), event, local.clone()));
        }
        out.insert(c, local);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::automata::from_facts;

    const FIG1: &str = "state(s0). state(s1).
transition(t1,s0,s1,black,_,ordinary). transition(t2,s0,s0,orange,999,ordinary).
transition(t3,s1,s1,gray,2,ordinary). transition(t4,s1,s0,black,_,final).
initial_state(s0).";

    fn robot(automaton: &str) -> String {
        format!(
            r#"Robot(
    name: "sorter",
    network: (pan_id: 0x0101, channel: 11),
    nodes: [(name: "n1", address: 0x0001)],
    assign: [("sorter", "n1")],
    roles: [(name: "sorter")],
    colours: ["black", "gray", "orange"],
    automata: [{automaton}],
)"#
        )
    }

    fn errors(text: &str) -> Vec<String> {
        let src = Source::new("sorter.ron", text);
        match crate::compile(&src) {
            Ok(_) => Vec::new(),
            Err(d) => d
                .iter()
                .filter(|d| d.is_error())
                .map(|d| d.message.clone())
                .collect(),
        }
    }

    /// The shipped type parses and has the paper's interface and six states (plus START).
    #[test]
    fn the_fb_type_has_the_papers_interface() {
        let t = fb_type().expect("parses");
        assert_eq!(t.inputs, ["Set", "Reset", "WP", "Setup"]);
        assert_eq!(t.outputs, ["OutSet", "OutReset", "Out", "EOS"]);
        assert_eq!(t.params, ["C", "T", "R", "M"]);
        let states: Vec<&str> = t.states.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(
            states,
            ["START", "Reset", "Setup", "Set", "WP", "WP1", "WP2"]
        );
    }

    /// Fig. 1's network: the parameters of the paper's four rules and every arc.
    #[test]
    fn fig1_network_by_the_rules() {
        let a = from_facts("fig1", FIG1).expect("facts").automaton;
        let net = network(&a);
        let params: Vec<(String, i32, bool, bool, i32, bool)> = net
            .instances
            .iter()
            .map(|i| (i.chart.clone(), i.c, i.t, i.r, i.m, i.is_final))
            .collect();
        let want = [
            ("fig1.t1", 0, true, false, 1, false),
            ("fig1.t2", 1, true, true, 999, false),
            ("fig1.t3", 2, false, true, 2, false),
            ("fig1.t4", 0, false, false, 1, true),
        ];
        let want: Vec<_> = want
            .iter()
            .map(|&(n, c, t, r, m, f)| (n.to_string(), c, t, r, m, f))
            .collect();
        assert_eq!(params, want);
        let arcs: Vec<String> = net
            .connections
            .iter()
            .map(|c| {
                let id = |t: TransitionId| a.get(t).expect("t").id.clone();
                format!("{} -{:?}-> {}", id(c.from), c.arc, id(c.to))
            })
            .collect();
        assert_eq!(
            arcs,
            [
                "t1 -Set-> t3",
                "t1 -Set-> t4",
                "t1 -Reset-> t2",
                "t4 -Set-> t1",
                "t4 -Set-> t2",
                "t4 -Reset-> t3",
            ]
        );
        assert_eq!(delivery_order(&a).len(), 4);
    }

    /// Nine transitions on one node: the error names MAX_CHARTS, by how much, what to do.
    #[test]
    fn too_many_charts_for_a_node() {
        let ts: Vec<String> = (0..9)
            .map(|k| format!("transition(t{k},s0,s1,black,_,final)."))
            .collect();
        let decl = format!(
            "(name: \"big\", role: \"sorter\", deterministic: false, facts: \"state(s0). state(s1). {} initial_state(s0).\")",
            ts.join(" ")
        );
        assert_eq!(
            errors(&robot(&decl)),
            ["automaton `big` needs 9 charts (one per transition) on role `sorter`, which has 0 of its own: 9 charts, but a node holds at most MAX_CHARTS = 8 (over by 1)"]
        );
    }

    #[test]
    fn unknown_role() {
        let decl = format!("(name: \"fig1\", role: \"nowhere\", facts: \"{FIG1}\")");
        assert_eq!(
            errors(&robot(&decl)),
            ["unknown role `nowhere` for automaton `fig1`"]
        );
    }

    /// A loop and a leaving transition of one colour beside a loop of another colour.
    #[test]
    fn a_state_the_network_cannot_run() {
        let decl =
            "(name: \"x\", role: \"sorter\", deterministic: false, facts: \"state(s0). state(s1).
transition(a,s0,s0,black,2,ordinary). transition(b,s0,s1,black,_,final).
transition(c,s0,s0,gray,2,ordinary). initial_state(s0).\")";
        assert_eq!(
            errors(&robot(decl)),
            ["automaton `x` cannot be compiled to a token network: in state `s0`, loop `a` and `b` (which leaves it) take the same colour, and loop `c` takes another; when `a` keeps `s0` active, the tokens it gives back would restart `c`'s count"]
        );
    }

    pub(super) fn fig1_robot() -> String {
        robot(&format!(
            "(name: \"fig1\", role: \"sorter\", facts: \"{FIG1}\")"
        ))
    }

    /// Fig. 1 on its role: four charts, its colour events and the automaton's EOS.
    #[test]
    fn fig1_joins_its_role() {
        let text = fig1_robot();
        let c = crate::compile(&Source::new("sorter.ron", text.as_str())).expect("compiles");
        let r = &c.ir.roles[0];
        let charts: Vec<&str> = r.charts.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(charts, ["fig1.t1", "fig1.t2", "fig1.t3", "fig1.t4"]);
        for e in [
            "part.black",
            "part.gray",
            "part.orange",
            "fig1.EOS",
            "fig1.t1.Out",
        ] {
            assert!(r.events.iter().any(|x| x == e), "{e}: {:?}", r.events);
        }
        assert!(!r.events.iter().any(|x| x == "fig1.t1.EOS"));
    }
}

#[cfg(test)]
mod diagram_tests {
    use super::*;

    /// `diagram` draws fig. 1 as its FB network (set and reset arcs, colour events, EOS)
    /// and the FB type's ECC once, not the four instance charts.
    #[test]
    fn diagram_draws_the_network_and_the_ecc() {
        let text = super::tests::fig1_robot();
        let src = Source::new("sorter.ron", text.as_str());
        let c = crate::compile(&src).expect("compiles");
        let automata = placed(&c.robot, &src, "sorter");
        let dot = crate::diagram::dot_with_automata(&c.ir, &automata, "sorter").expect("dot");
        for line in [
            "    n0t0 [shape=box, style=\"\", label=\"fig1.t1\\ls0 -> s1\\lC=black T=1 R=0 M=1\\l\"];",
            "    n0t3 [shape=box, style=\"\", label=\"fig1.t4\\ls1 -> s0\\lC=black T=0 R=0 M=1\\lEOS\\l\"];",
            "    n0t0 -> n0t2 [label=\"OutSet -> Set\"];",
            "    n0t0 -> n0t1 [label=\"OutReset -> Reset\", style=dashed];",
            "    n0c0 -> n0t3 [label=\"WP\", style=dotted];",
            "    n0t3 -> n0eos [label=\"EOS\", style=dotted];",
            "    label=\"ECC of FB type SelectingTransition\";",
            "    ts0 -> ts4 [label=\"WP [token]\"];",
            "    ts4 -> ts5 [label=\"[R && count + 1 < M]\"];",
        ] {
            assert!(dot.lines().any(|l| l == line), "{line}\n{dot}");
        }
        assert!(!dot.contains("cluster_0 "), "{dot}");
    }
}
