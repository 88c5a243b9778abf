//! A proptest strategy for VALID tables, and blob mutations.
//!
//! Used by `config-schema/tests/props.rs` and (through `#[path]`) by
//! `node-fw/tests/ecc_props.rs`.
//!
//! proptest generates a `Raw` description made of plain numbers and expression trees;
//! [`build`] turns it into a table by reducing every index modulo what exists, so the result
//! is valid by construction (and the properties assert it), and shrinking works on numbers.
#![allow(dead_code)]

use config_schema::blob::{HEADER_LEN, TRAILER_LEN};
use config_schema::limits::*;
use config_schema::{
    Action, EventId, Expr, Input, Level, Op, Output, Publication, Route, Subscription, Table,
    Timer, Transition,
};
use proptest::collection::vec;
use proptest::prelude::*;
pub use test_tables::{blob, seal};

/// A well-formed expression, before its indices are reduced.
#[derive(Debug, Clone)]
pub enum Tree {
    Const(i32),
    Var(u8),
    Input(u8),
    Not(Box<Tree>),
    /// `Op::Wrap` to 8 or 16 bits (bit 0 of the number), signed or not (bit 1).
    Wrap(u8, Box<Tree>),
    /// Binary operation number `op % 14` of [`BINARY`].
    Bin(u8, Box<Tree>, Box<Tree>),
}

pub const BINARY: [Op; 14] = [
    Op::And,
    Op::Or,
    Op::Eq,
    Op::Ne,
    Op::Lt,
    Op::Le,
    Op::Gt,
    Op::Ge,
    Op::Add,
    Op::Sub,
    Op::Mul,
    Op::Div,
    Op::Rem,
    Op::And,
];

/// Expression trees of height <= 4: at most 31 operations (MAX_EXPR_LEN is 32) and a stack
/// depth of at most 5 (MAX_STACK is 8).
pub fn tree() -> impl Strategy<Value = Tree> {
    let leaf = prop_oneof![
        3 => (-3i32..10).prop_map(Tree::Const),
        1 => any::<i32>().prop_map(Tree::Const),
        3 => any::<u8>().prop_map(Tree::Var),
        2 => any::<u8>().prop_map(Tree::Input),
    ];
    leaf.prop_recursive(4, 31, 2, |inner| {
        prop_oneof![
            1 => inner.clone().prop_map(|t| Tree::Not(Box::new(t))),
            1 => (any::<u8>(), inner.clone()).prop_map(|(k, t)| Tree::Wrap(k, Box::new(t))),
            4 => (any::<u8>(), inner.clone(), inner)
                .prop_map(|(op, a, b)| Tree::Bin(op, Box::new(a), Box::new(b))),
        ]
    })
}

/// Postfix operations of a tree, with variable and input indices reduced (a variable or an
/// input the table does not have becomes a constant).
pub fn lower(tree: &Tree, vars: usize, inputs: usize, out: &mut Vec<Op>) {
    match tree {
        Tree::Const(c) => out.push(Op::Const(*c)),
        Tree::Var(v) if vars > 0 => out.push(Op::Var(*v % vars as u8)),
        Tree::Input(i) if inputs > 0 => out.push(Op::Input(*i % inputs as u8)),
        Tree::Var(v) | Tree::Input(v) => out.push(Op::Const(i32::from(*v))),
        Tree::Not(a) => {
            lower(a, vars, inputs, out);
            out.push(Op::Not);
        }
        Tree::Wrap(k, a) => {
            lower(a, vars, inputs, out);
            out.push(Op::Wrap {
                bits: if k & 1 == 0 { 8 } else { 16 },
                signed: k & 2 != 0,
            });
        }
        Tree::Bin(op, a, b) => {
            lower(a, vars, inputs, out);
            lower(b, vars, inputs, out);
            out.push(BINARY[usize::from(*op) % BINARY.len()]);
        }
    }
}

#[derive(Debug, Clone)]
pub enum RawAction {
    Set(u8, Tree),
    Drive(u16, u16),
    Emit(u8),
    Publish(u8),
    StartTimer(u8, u32),
    CancelTimer(u8),
    Fault(u8),
}

fn raw_action() -> impl Strategy<Value = RawAction> {
    prop_oneof![
        3 => (any::<u8>(), tree()).prop_map(|(v, t)| RawAction::Set(v, t)),
        3 => (any::<u16>(), any::<u16>()).prop_map(|(m, v)| RawAction::Drive(m, v)),
        3 => any::<u8>().prop_map(RawAction::Emit),
        1 => any::<u8>().prop_map(RawAction::Publish),
        2 => (any::<u8>(), 0u32..5000).prop_map(|(t, ms)| RawAction::StartTimer(t, ms)),
        1 => any::<u8>().prop_map(RawAction::CancelTimer),
        1 => any::<u8>().prop_map(RawAction::Fault),
    ]
}

#[derive(Debug, Clone)]
pub struct RawTransition {
    pub from: u8,
    pub to: u8,
    pub trigger: Option<u8>,
    pub guard: Option<Tree>,
}

#[derive(Debug, Clone)]
pub struct RawChart {
    pub inputs: u8,
    pub initial: u8,
    /// Resting states besides the idle one (masked to the chart's states).
    pub rests: u8,
    pub states: Vec<Vec<RawAction>>,
    pub transitions: Vec<RawTransition>,
}

fn raw_chart() -> impl Strategy<Value = RawChart> {
    let transition = (
        any::<u8>(),
        any::<u8>(),
        proptest::option::weighted(0.8, any::<u8>()),
        proptest::option::weighted(0.4, tree()),
    )
        .prop_map(|(from, to, trigger, guard)| RawTransition {
            from,
            to,
            trigger,
            guard,
        });
    (
        0u8..5,
        any::<u8>(),
        proptest::option::weighted(0.3, any::<u8>()),
        vec(vec(raw_action(), 0..4), 1..6),
        vec(transition, 0..9),
    )
        .prop_map(|(inputs, initial, rests, states, transitions)| RawChart {
            inputs,
            initial,
            rests: rests.unwrap_or(0),
            states,
            transitions,
        })
}

#[derive(Debug, Clone)]
pub struct Raw {
    pub role: String,
    pub generation: u32,
    pub pan_id: u16,
    pub channel: u8,
    pub events: u8,
    pub start: Option<u8>,
    pub vars: Vec<i32>,
    /// (rise, fall, mirror variable).
    pub inputs: Vec<(Option<u8>, Option<u8>, Option<u8>)>,
    /// (fault, start, home): fault and start are `Level` variant indices 0..3.
    pub outputs: Vec<(u8, u8, bool)>,
    pub timers: Vec<u8>,
    pub peer_base: u16,
    pub peers: usize,
    /// (event, topic, subscriber mask).
    pub publications: Vec<(u8, u8, u8)>,
    /// (publisher, topic, event).
    pub subscriptions: Vec<(u8, u8, u8)>,
    pub charts: Vec<RawChart>,
    /// (event, chart, chart input).
    pub routes: Vec<(u8, u8, u8)>,
}

pub fn raw() -> impl Strategy<Value = Raw> {
    let head = (
        "[A-Za-z0-9_]{0,12}",
        any::<u32>(),
        any::<u16>(),
        11u8..27,
        prop_oneof![4 => 1u8..16, 1 => Just(MAX_EVENTS as u8)],
        proptest::option::of(any::<u8>()),
        vec(-5i32..100, 0..6),
    );
    let pins = (
        vec(
            (
                proptest::option::of(any::<u8>()),
                proptest::option::of(any::<u8>()),
                proptest::option::of(any::<u8>()),
            ),
            0..5,
        ),
        vec((0u8..3, 0u8..3, any::<bool>()), 0..7),
        vec(any::<u8>(), 0..4),
    );
    let radio = (
        0u16..0xF000,
        0usize..4,
        vec((any::<u8>(), any::<u8>(), any::<u8>()), 0..5),
        vec((any::<u8>(), any::<u8>(), any::<u8>()), 0..5),
    );
    let network = (vec(raw_chart(), 1..4), vec(any::<(u8, u8, u8)>(), 0..14));
    (head, pins, radio, network).prop_map(
        |(
            (role, generation, pan_id, channel, events, start, vars),
            (inputs, outputs, timers),
            (peer_base, peers, publications, subscriptions),
            (charts, routes),
        )| Raw {
            role,
            generation,
            pan_id,
            channel,
            events,
            start,
            vars,
            inputs,
            outputs,
            timers,
            peer_base,
            peers,
            publications,
            subscriptions,
            charts,
            routes,
        },
    )
}

/// A valid table from a raw description.
pub fn build(raw: &Raw) -> Table {
    let mut t = Table::empty(&raw.role);
    t.generation = raw.generation;
    t.header.pan_id = raw.pan_id;
    t.header.channel = raw.channel;
    t.events = raw.events.clamp(1, MAX_EVENTS as u8);
    let events = t.events;
    let ev = |e: u8| -> EventId { e % events };
    t.start = raw.start.map(ev);
    t.vars.extend_from_slice(&raw.vars).unwrap();
    let nvars = t.vars.len();
    let var = |v: Option<u8>| v.filter(|_| nvars > 0).map(|v| v % nvars as u8);
    for (i, (rise, fall, v)) in raw.inputs.iter().enumerate() {
        t.inputs
            .push(Input {
                pin: 2 * i as u8,
                rise: rise.map(ev),
                fall: fall.map(ev),
                var: var(*v),
            })
            .unwrap();
    }
    let level = |l: u8| [Level::Low, Level::High, Level::Hold][usize::from(l % 3)];
    for (i, &(fault, start, home)) in raw.outputs.iter().enumerate() {
        t.outputs
            .push(Output {
                pin: 32 + i as u8,
                fault: level(fault),
                start: level(start),
                home,
            })
            .unwrap();
    }
    for e in &raw.timers {
        t.timers.push(Timer { event: ev(*e) }).unwrap();
    }
    for i in 0..raw.peers {
        t.peers.push(raw.peer_base + 3 * i as u16).unwrap();
    }
    let peer_mask = ((1u16 << t.peers.len()) - 1) as u8;
    for (e, topic, mask) in &raw.publications {
        let (event, topic) = (ev(*e), *topic);
        if t.publications
            .iter()
            .any(|p| p.event == event || p.topic == topic)
        {
            continue;
        }
        t.publications
            .push(Publication {
                event,
                topic,
                subscribers: mask & peer_mask,
            })
            .unwrap();
    }
    if !t.peers.is_empty() {
        for (p, topic, e) in &raw.subscriptions {
            let publisher = p % t.peers.len() as u8;
            if t.subscriptions
                .iter()
                .any(|s| s.publisher == publisher && s.topic == *topic)
            {
                continue;
            }
            t.subscriptions
                .push(Subscription {
                    publisher,
                    topic: *topic,
                    event: ev(*e),
                })
                .unwrap();
        }
    }

    let (ninputs, nout, ntimers) = (t.inputs.len(), t.outputs.len(), t.timers.len());
    let out_mask = ((1u32 << nout) - 1) as u16;
    let published: Vec<EventId> = t.publications.iter().map(|p| p.event).collect();
    for chart in &raw.charts {
        let n_states = chart.states.len() as u8;
        let inputs = chart.inputs;
        let mut states: Vec<Vec<Action>> = Vec::new();
        for actions in &chart.states {
            let mut out = Vec::new();
            for a in actions {
                let action = match a {
                    RawAction::Set(v, tree) if nvars > 0 => {
                        let mut ops = Vec::new();
                        lower(tree, nvars, ninputs, &mut ops);
                        match t.push_expr(&ops) {
                            Ok(expr) => Action::Set {
                                var: v % nvars as u8,
                                expr,
                            },
                            Err(_) => Action::Emit(ev(*v)),
                        }
                    }
                    RawAction::Drive(m, v) => Action::Drive {
                        mask: m & out_mask,
                        value: v & out_mask,
                    },
                    RawAction::Publish(e) if !published.is_empty() => {
                        Action::Publish(published[usize::from(*e) % published.len()])
                    }
                    RawAction::StartTimer(tm, ms) if ntimers > 0 => Action::StartTimer {
                        timer: tm % ntimers as u8,
                        ms: *ms,
                    },
                    RawAction::CancelTimer(tm) if ntimers > 0 => {
                        Action::CancelTimer(tm % ntimers as u8)
                    }
                    RawAction::Fault(code) => Action::Fault(*code),
                    RawAction::Set(e, _)
                    | RawAction::Emit(e)
                    | RawAction::Publish(e)
                    | RawAction::StartTimer(e, _)
                    | RawAction::CancelTimer(e) => Action::Emit(ev(*e)),
                };
                out.push(action);
            }
            states.push(out);
        }
        let mut transitions = Vec::new();
        for tr in &chart.transitions {
            let guard: Option<Expr> = tr.guard.as_ref().and_then(|g| {
                let mut ops = Vec::new();
                lower(g, nvars, ninputs, &mut ops);
                t.push_expr(&ops).ok()
            });
            transitions.push(Transition {
                from: tr.from % n_states,
                to: tr.to % n_states,
                trigger: tr.trigger.filter(|_| inputs > 0).map(|i| i % inputs),
                guard,
            });
        }
        let states: Vec<&[Action]> = states.iter().map(Vec::as_slice).collect();
        let at = t
            .push_chart(chart.initial % n_states, inputs, &states, &transitions)
            .unwrap();
        t.charts[usize::from(at)].rests = u32::from(chart.rests) & ((1 << n_states) - 1);
    }
    for (e, c, i) in &raw.routes {
        let chart = c % t.charts.len() as u8;
        let inputs = t.charts[usize::from(chart)].inputs;
        if inputs == 0 {
            continue;
        }
        t.routes
            .push(Route {
                event: ev(*e),
                chart,
                input: i % inputs,
            })
            .unwrap();
    }
    t
}

/// Valid tables (the structure above, and a worst stimulus within the budget, which
/// `validate` checks last).
pub fn table() -> impl Strategy<Value = Table> {
    raw().prop_map(|r| build(&r)).prop_filter(
        "a worst stimulus over the budget (validate refuses it)",
        |t| config_schema::cost::worst_stimulus(t).cost <= config_schema::cost::STIMULUS_BUDGET,
    )
}

/// One change to a payload.
#[derive(Debug, Clone)]
pub enum Mutation {
    /// Flip bit `bit % 8` of byte `at % len`.
    Flip { at: usize, bit: u8 },
    /// Set byte `at % len` to `value`.
    Set { at: usize, value: u8 },
    /// Keep the first `len % (len + 1)` bytes.
    Truncate { len: usize },
    /// Replace bytes `at..at + n` (clamped) with `bytes`.
    Splice { at: usize, n: usize, bytes: Vec<u8> },
    /// Copy `n` bytes from `from` to `to` (both modulo len), inside the payload.
    Copy { from: usize, to: usize, n: usize },
}

pub fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        4 => (any::<usize>(), any::<u8>()).prop_map(|(at, bit)| Mutation::Flip { at, bit }),
        3 => (any::<usize>(), prop_oneof![0u8..4, any::<u8>()])
            .prop_map(|(at, value)| Mutation::Set { at, value }),
        1 => any::<usize>().prop_map(|len| Mutation::Truncate { len }),
        2 => (any::<usize>(), 0usize..4, vec(any::<u8>(), 0..4))
            .prop_map(|(at, n, bytes)| Mutation::Splice { at, n, bytes }),
        1 => (any::<usize>(), any::<usize>(), 1usize..6)
            .prop_map(|(from, to, n)| Mutation::Copy { from, to, n }),
    ]
}

pub fn mutate(payload: &mut Vec<u8>, m: &Mutation) {
    let len = payload.len();
    match m {
        Mutation::Flip { at, bit } if len > 0 => payload[at % len] ^= 1 << (bit % 8),
        Mutation::Set { at, value } if len > 0 => payload[at % len] = *value,
        Mutation::Truncate { len: keep } => payload.truncate(keep % (len + 1)),
        Mutation::Splice { at, n, bytes } => {
            let at = at % (len + 1);
            let end = (at + n).min(len);
            payload.splice(at..end, bytes.iter().copied());
        }
        Mutation::Copy { from, to, n } if len > 0 => {
            let (from, to) = (from % len, to % len);
            let n = (*n).min(len - from).min(len - to);
            payload.copy_within(from..from + n, to);
        }
        _ => {}
    }
}

/// A valid table's blob with mutations applied to its payload, resealed.
pub fn mutated_blob() -> impl Strategy<Value = Vec<u8>> {
    (table(), vec(mutation(), 1..4)).prop_map(|(t, ms)| {
        let b = blob(&t);
        let mut payload = b[HEADER_LEN..b.len() - TRAILER_LEN].to_vec();
        for m in &ms {
            mutate(&mut payload, m);
        }
        seal(&payload, t.generation)
    })
}

/// An oracle independent of `validate`: every index the interpreter will follow in `t` is
/// inside the table. Returns the first problem found.
pub fn interpreter_safe(t: &Table) -> Result<(), String> {
    let events = usize::from(t.events);
    let ev = |e: u8, what: &str| {
        if usize::from(e) < events {
            Ok(())
        } else {
            Err(format!("{what}: event {e} of {events}"))
        }
    };
    let expr = |e: Expr, what: &str| {
        let (start, end) = (
            usize::from(e.start),
            usize::from(e.start) + usize::from(e.len),
        );
        let ops = t
            .code
            .get(start..end)
            .ok_or(format!("{what}: expression past the code"))?;
        config_schema::guard::check(ops, t.vars.len(), t.inputs.len())
            .map_err(|err| format!("{what}: {err:?}"))
    };
    if usize::from(t.events) > MAX_EVENTS {
        return Err("events over capacity".into());
    }
    if let Some(e) = t.start {
        ev(e, "start")?;
    }
    for i in &t.inputs {
        for e in [i.rise, i.fall].into_iter().flatten() {
            ev(e, "input")?;
        }
        if i.var.is_some_and(|v| usize::from(v) >= t.vars.len()) {
            return Err("input mirror variable".into());
        }
    }
    for tm in &t.timers {
        ev(tm.event, "timer")?;
    }
    let mut state_start = 0;
    let mut transition_start = 0;
    for (c, chart) in t.charts.iter().enumerate() {
        let states = t.chart_states(c);
        let transitions = t.chart_transitions(c);
        if states.start != state_start || states.is_empty() || states.end > t.states.len() {
            return Err(format!("chart {c} states {states:?}"));
        }
        if transitions.start != transition_start || transitions.end > t.transitions.len() {
            return Err(format!("chart {c} transitions {transitions:?}"));
        }
        (state_start, transition_start) = (states.end, transitions.end);
        let n = states.len();
        if usize::from(chart.initial) >= n {
            return Err(format!("chart {c} initial state"));
        }
        if n < 32 && chart.rests >> n != 0 {
            return Err(format!("chart {c} resting states"));
        }
        for tr in &t.transitions[transitions] {
            if usize::from(tr.from) >= n || usize::from(tr.to) >= n {
                return Err(format!("chart {c} transition {tr:?}"));
            }
            if tr.trigger.is_some_and(|i| i >= chart.inputs) {
                return Err(format!("chart {c} trigger {tr:?}"));
            }
            if let Some(g) = tr.guard {
                expr(g, "guard")?;
            }
        }
    }
    for s in 0..t.states.len() {
        let r = t.state_actions(s);
        if r.end > t.actions.len() || (s > 0 && r.start != t.state_actions(s - 1).end) {
            return Err(format!("state {s} actions {r:?}"));
        }
    }
    let outputs = (1u32 << t.outputs.len()) - 1;
    for a in &t.actions {
        match *a {
            Action::Set { var, expr: e } => {
                if usize::from(var) >= t.vars.len() {
                    return Err("Set variable".into());
                }
                expr(e, "Set")?;
            }
            Action::Drive { mask, value } => {
                if u32::from(mask | value) & !outputs != 0 {
                    return Err(format!("Drive {mask:#x} {value:#x}"));
                }
            }
            Action::Emit(e) | Action::Publish(e) => ev(e, "emit/publish")?,
            Action::StartTimer { timer, .. } | Action::CancelTimer(timer) => {
                if usize::from(timer) >= t.timers.len() {
                    return Err(format!("timer {timer}"));
                }
            }
            Action::Fault(_) => {}
        }
    }
    for r in &t.routes {
        ev(r.event, "route")?;
        let chart = t.charts.get(usize::from(r.chart)).ok_or("route chart")?;
        if r.input >= chart.inputs {
            return Err("route chart input".into());
        }
    }
    for p in &t.publications {
        ev(p.event, "publication")?;
        if u32::from(p.subscribers) >> t.peers.len() != 0 {
            return Err("publication subscriber".into());
        }
    }
    for s in &t.subscriptions {
        ev(s.event, "subscription")?;
        if usize::from(s.publisher) >= t.peers.len() {
            return Err("subscription publisher".into());
        }
    }
    Ok(())
}

/// A valid table with mutations applied to its fields rather than to its packed bits: the
/// table's postcard form (byte-aligned, one value per field) mutated and read back, then
/// encoded as a blob (the wide form where the compact one cannot hold it). `None` when the
/// mutated bytes are no table (postcard refuses them) or the table no blob. Every blob it
/// gives parses, so what it tests is the validator: whatever it lets through must be safe.
pub fn field_mutated_blob() -> impl Strategy<Value = Option<Vec<u8>>> {
    // One byte of the form flipped or set (mostly to a small value): a field's value.
    let field = prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(at, bit)| Mutation::Flip { at, bit }),
        (any::<usize>(), prop_oneof![0u8..8, any::<u8>()])
            .prop_map(|(at, value)| Mutation::Set { at, value }),
    ];
    (table(), field).prop_map(|(t, m)| {
        let mut form = [0u8; 8 * 1024];
        let used = postcard::to_slice(&t, &mut form).ok()?.len();
        let mut bytes = form[..used].to_vec();
        mutate(&mut bytes, &m);
        let (mut mutated, _) = postcard::take_from_bytes::<Table>(&bytes).ok()?;
        mutated.generation = t.generation;
        let mut buf = [0u8; 8 * 1024];
        let n = config_schema::blob::encode(&mutated, &mut buf).ok()?;
        Some(buf[..n].to_vec())
    })
}
