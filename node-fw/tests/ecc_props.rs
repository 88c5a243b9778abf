//! Property tests of the interpreter: any table that decodes (generated valid tables, and
//! mutated blobs that still decode) runs under any sequence of stimuli without panicking,
//! and everything it reports stays inside the table.

// The valid-table strategy and blob mutations are shared with config-schema's tests.
mod reference;
#[path = "../../config-schema/tests/strategy/mod.rs"]
mod strategy;

use config_schema::{decode, Level, Op, Output, Publication, Table};
use node_fw::ecc::{Effects, Engine, Fault};
use proptest::collection::vec;
use proptest::prelude::*;
use proptest::strategy::ValueTree;
use proptest::test_runner::TestRunner;

/// Something that happens to a node.
#[derive(Debug, Clone, Copy)]
enum Stimulus {
    Input(u8, bool),
    Timer(u8),
    /// A subscribed (publisher, topic) when `pick` is even and there is one, else raw.
    Remote {
        pick: u8,
        publisher: u8,
        topic: u8,
    },
    Start,
    Event(u8),
    Reset,
}

fn stimulus() -> impl Strategy<Value = Stimulus> {
    prop_oneof![
        6 => (any::<u8>(), any::<bool>()).prop_map(|(i, l)| Stimulus::Input(i, l)),
        3 => any::<u8>().prop_map(Stimulus::Timer),
        3 => (any::<u8>(), any::<u8>(), any::<u8>())
            .prop_map(|(pick, publisher, topic)| Stimulus::Remote { pick, publisher, topic }),
        2 => Just(Stimulus::Start),
        6 => any::<u8>().prop_map(Stimulus::Event),
        1 => Just(Stimulus::Reset),
    ]
}

/// One reported effect, for comparing runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ev {
    Out(u8, bool),
    Publish(u8, u8),
    Start(u8, u32),
    Cancel(u8),
    Fault(Fault),
    Fired(u8, u8, u8, u8),
    Ignored(u8, u8),
}

/// Checks every reported effect against the table, tracks the outputs the reports imply,
/// and records the trace.
struct Check<'t> {
    t: &'t Table,
    outputs: u16,
    trace: Vec<Ev>,
}

/// Bit i: output i is high at `level` (a held output counts as low).
fn levels(t: &Table, level: fn(&Output) -> Level) -> u16 {
    t.outputs
        .iter()
        .enumerate()
        .fold(0, |m, (i, o)| m | (u16::from(level(o) == Level::High) << i))
}

/// Bit i: output i keeps its level at `level`.
fn held(t: &Table, level: fn(&Output) -> Level) -> u16 {
    t.outputs
        .iter()
        .enumerate()
        .fold(0, |m, (i, o)| m | (u16::from(level(o) == Level::Hold) << i))
}

/// The outputs of a faulted engine: the fault level of each that is not held.
fn fault_levels_hold(t: &Table, outputs: u16) -> bool {
    let driven = !held(t, |o| o.fault);
    outputs & driven == levels(t, |o| o.fault) & driven
}

impl Effects for Check<'_> {
    fn output(&mut self, output: u8, value: bool) {
        assert!(
            usize::from(output) < self.t.outputs.len(),
            "output {output}"
        );
        let bit = 1u16 << output;
        assert_ne!(
            self.outputs & bit != 0,
            value,
            "output {output} reported without a change"
        );
        self.outputs ^= bit;
        self.trace.push(Ev::Out(output, value));
    }
    fn publish(&mut self, p: &Publication) {
        assert!(self.t.publications.contains(p), "{p:?}");
        self.trace.push(Ev::Publish(p.event, p.topic));
    }
    fn start_timer(&mut self, timer: u8, ms: u32) {
        assert!(usize::from(timer) < self.t.timers.len(), "timer {timer}");
        self.trace.push(Ev::Start(timer, ms));
    }
    fn cancel_timer(&mut self, timer: u8) {
        assert!(usize::from(timer) < self.t.timers.len(), "timer {timer}");
        self.trace.push(Ev::Cancel(timer));
    }
    fn fault(&mut self, fault: Fault) {
        // A validated expression fails only by dividing by zero (`Div`, `Rem`): never in
        // a table without them.
        let divides = self.t.code.iter().any(|op| matches!(op, Op::Div | Op::Rem));
        assert!(divides || !matches!(fault, Fault::Expr { .. }), "{fault:?}");
        assert!(
            fault_levels_hold(self.t, self.outputs),
            "faulted outside the fault levels"
        );
        self.trace.push(Ev::Fault(fault));
    }
    fn fired(&mut self, chart: u8, transition: u8, from: u8, to: u8) {
        let c = usize::from(chart);
        assert!(c < self.t.charts.len(), "chart {chart}");
        assert!(self
            .t
            .chart_transitions(c)
            .contains(&usize::from(transition)));
        let tr = self.t.transitions[usize::from(transition)];
        assert_eq!((tr.from, tr.to), (from, to));
        assert!(usize::from(to) < self.t.chart_states(c).len());
        self.trace.push(Ev::Fired(chart, transition, from, to));
    }
    fn ignored(&mut self, chart: u8, input: u8) {
        let c = self.t.charts.get(usize::from(chart)).expect("chart exists");
        assert!(input < c.inputs, "chart input {input}");
        self.trace.push(Ev::Ignored(chart, input));
    }
}

/// Runs `stimuli` on a fresh engine, checking the invariants after each; returns the trace.
/// A drawn index `x` into a list of `n`: in range, or one or two past it (which the engine
/// must ignore).
fn wrap(x: u8, n: usize) -> u8 {
    x % (n as u8).saturating_add(2)
}

/// The (publisher, topic) a `Remote` stimulus comes from: one of the table's
/// subscriptions for an even `pick` (when it has any), else the drawn one.
fn remote_of(t: &Table, pick: u8, publisher: u8, topic: u8) -> (u8, u8) {
    match t.subscriptions.len() {
        n if n > 0 && pick.is_multiple_of(2) => {
            let s = t.subscriptions[usize::from(pick / 2) % n];
            (s.publisher, s.topic)
        }
        _ => (publisher, topic),
    }
}

fn run(t: &Table, stimuli: &[Stimulus]) -> Vec<Ev> {
    let mut e = Engine::new(t);
    let mut fx = Check {
        t,
        outputs: levels(t, |o| o.start),
        trace: Vec::new(),
    };
    assert_eq!(e.outputs(), fx.outputs);
    for s in stimuli {
        match *s {
            Stimulus::Input(i, level) => e.input(wrap(i, t.inputs.len()), level, &mut fx),
            Stimulus::Timer(i) => e.timer_expired(wrap(i, t.timers.len()), &mut fx),
            Stimulus::Remote {
                pick,
                publisher,
                topic,
            } => {
                let (publisher, topic) = remote_of(t, pick, publisher, topic);
                let subscribed = t
                    .subscriptions
                    .iter()
                    .any(|s| s.publisher == publisher && s.topic == topic);
                assert_eq!(e.remote(publisher, topic, &mut fx), subscribed);
            }
            Stimulus::Start => assert_eq!(e.start(&mut fx), t.start.is_some()),
            // A routed event when `ev` is even and there is one, else any id.
            Stimulus::Event(ev) => match t.routes.len() {
                n if n > 0 && ev % 2 == 0 => {
                    e.event(t.routes[usize::from(ev / 2) % n].event, &mut fx)
                }
                _ => e.event(wrap(ev, usize::from(t.events)), &mut fx),
            },
            Stimulus::Reset => {
                let before = e.outputs();
                e.reset(&mut fx);
                assert_eq!(e.fault(), None);
                // Start levels, and a held output keeps its level.
                let kept = held(t, |o| o.start);
                let want = (levels(t, |o| o.start) & !kept) | (before & kept);
                assert_eq!(e.outputs(), want, "reset outside the start levels");
            }
        }
        for c in 0..t.charts.len() {
            let s = e.state(c).expect("every chart has a state");
            assert!(
                usize::from(s) < t.chart_states(c).len(),
                "chart {c} state {s}"
            );
        }
        assert_eq!(e.state(t.charts.len()), None);
        assert_eq!(e.outputs(), fx.outputs, "reported outputs = engine outputs");
        if e.fault().is_some() {
            assert!(fault_levels_hold(t, e.outputs()));
        }
        for v in 0..t.vars.len() {
            assert!(e.var(v).is_some());
        }
    }
    fx.trace
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Generated valid tables under random stimuli: no panic, effects inside the table,
    /// states inside their charts, and the same stimuli give the same trace.
    #[test]
    fn valid_tables_run_inside_their_bounds(
        t in strategy::table(),
        stimuli in vec(stimulus(), 0..40),
    ) {
        let b = strategy::blob(&t);
        let t = decode(&b).expect("a generated table decodes");
        prop_assert_eq!(strategy::interpreter_safe(&t), Ok(()));
        let first = run(&t, &stimuli);
        prop_assert_eq!(run(&t, &stimuli), first);
    }

    /// Mutated blobs: whatever decodes runs inside its bounds.
    #[test]
    fn decodable_mutated_blobs_run_inside_their_bounds(
        b in strategy::mutated_blob(),
        stimuli in vec(stimulus(), 0..40),
    ) {
        if let Ok(t) = decode(&b) {
            prop_assert_eq!(strategy::interpreter_safe(&t), Ok(()));
            run(&t, &stimuli);
        }
    }
}

/// Runs `stimuli` on the engine and on the reference walk (docs/ecc-semantics.md read
/// literally, `tests/reference`), which must report the same effects and be in the same
/// state after each stimulus. Returns the trace.
fn against_reference(t: &Table, stimuli: &[Stimulus]) -> Vec<Ev> {
    let mut e = Engine::new(t);
    let mut r = reference::Reference::new(t);
    let (mut fe, mut fr) = (Loose(Vec::new()), Loose(Vec::new()));
    for (at, s) in stimuli.iter().enumerate() {
        match *s {
            Stimulus::Input(i, level) => {
                let i = wrap(i, t.inputs.len());
                e.input(i, level, &mut fe);
                r.input(i, level, &mut fr);
            }
            Stimulus::Timer(i) => {
                let i = wrap(i, t.timers.len());
                e.timer_expired(i, &mut fe);
                r.timer_expired(i, &mut fr);
            }
            Stimulus::Remote {
                pick,
                publisher,
                topic,
            } => {
                let (publisher, topic) = remote_of(t, pick, publisher, topic);
                assert_eq!(
                    e.remote(publisher, topic, &mut fe),
                    r.remote(publisher, topic, &mut fr)
                );
            }
            Stimulus::Start => assert_eq!(e.start(&mut fe), r.start(&mut fr)),
            Stimulus::Event(ev) => {
                let ev = match t.routes.len() {
                    n if n > 0 && ev % 2 == 0 => t.routes[usize::from(ev / 2) % n].event,
                    _ => wrap(ev, usize::from(t.events)),
                };
                e.event(ev, &mut fe);
                r.event(ev, &mut fr);
            }
            Stimulus::Reset => {
                e.reset(&mut fe);
                r.reset(&mut fr);
            }
        }
        assert_eq!(fe.0, fr.0, "effects after stimulus {at} ({s:?})");
        let state = e.snapshot();
        assert_eq!(
            &state.current[..t.charts.len()],
            &r.current[..],
            "states after {at}"
        );
        assert_eq!(state.vars, r.vars, "variables after {at}");
        assert_eq!(
            (state.inputs, state.outputs),
            (r.inputs, r.outputs),
            "pins after {at}"
        );
        assert_eq!(state.fault, r.fault, "fault after {at}");
    }
    fe.0
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Generated valid tables: the engine (its compiled index, lowered expressions) does
    /// exactly what the reference walk over the bare table does.
    #[test]
    fn valid_tables_run_as_the_reference_walk(
        t in strategy::table(),
        stimuli in vec(stimulus(), 0..40),
    ) {
        let t = decode(&strategy::blob(&t)).expect("a generated table decodes");
        against_reference(&t, &stimuli);
    }

    /// Mutated blobs that decode (so pass validation): the same.
    #[test]
    fn decodable_mutated_blobs_run_as_the_reference_walk(
        b in strategy::mutated_blob(),
        stimuli in vec(stimulus(), 0..40),
    ) {
        if let Ok(t) = decode(&b) {
            against_reference(&t, &stimuli);
        }
    }
}

/// Over a fixed-seed sample, the comparison with the reference covers firing, publishing,
/// chains and faults (not only tables that ignore everything).
#[test]
fn the_reference_comparison_sees_the_engine_work() {
    let mut runner = TestRunner::deterministic();
    let tables = strategy::table();
    let stimuli = vec(stimulus(), 20..60);
    let (n, mut fired, mut set, mut faulted) = (300, 0, 0, 0);
    for _ in 0..n {
        let t = tables.new_tree(&mut runner).unwrap().current();
        let t = decode(&strategy::blob(&t)).expect("a generated table decodes");
        let s = stimuli.new_tree(&mut runner).unwrap().current();
        let trace = against_reference(&t, &s);
        fired += usize::from(trace.iter().any(|e| matches!(e, Ev::Fired(..))));
        faulted += usize::from(trace.iter().any(|e| matches!(e, Ev::Fault(_))));
        let sets = t
            .actions
            .iter()
            .any(|a| matches!(a, config_schema::Action::Set { .. }));
        set += usize::from(sets && trace.iter().any(|e| matches!(e, Ev::Fired(..))));
    }
    println!("of {n} tables against the reference: {fired} fired, {set} with assignments, {faulted} faulted");
    assert!(fired >= n / 3, "{fired}");
    assert!(set >= n / 10, "{set}");
    assert!(faulted >= n / 10, "{faulted}");
}

/// The generator is only useful if its tables do things: over a fixed-seed sample, count the
/// runs that fire transitions, publish, and fault.
#[test]
fn generated_tables_exercise_the_engine() {
    let mut runner = TestRunner::deterministic();
    let tables = strategy::table();
    let stimuli = vec(stimulus(), 20..60);
    let (n, mut fired, mut published, mut faulted, mut chained) = (500, 0, 0, 0, 0);
    for _ in 0..n {
        let t = tables.new_tree(&mut runner).unwrap().current();
        let s = stimuli.new_tree(&mut runner).unwrap().current();
        let trace = run(&t, &s);
        let count = |f: fn(&Ev) -> bool| usize::from(trace.iter().any(f));
        fired += count(|e| matches!(e, Ev::Fired(..)));
        published += count(|e| matches!(e, Ev::Publish(..)));
        faulted += count(|e| matches!(e, Ev::Fault(_)));
        chained += count(|e| matches!(e, Ev::Fault(Fault::ChainLimit { .. })));
    }
    println!(
        "of {n} generated tables: {fired} fired, {published} published, {faulted} faulted \
         ({chained} on the chain limit)"
    );
    assert!(fired >= n / 3, "{fired}");
    assert!(published >= n / 10, "{published}");
    assert!(faulted >= n / 10, "{faulted}");
}

/// The same over a fixed-seed sample, so that a known number of mutated tables (not a
/// chance few) actually run; prints how many did.
#[test]
fn a_fixed_sample_of_mutated_tables_runs() {
    let mut runner = TestRunner::deterministic();
    let blobs = strategy::mutated_blob();
    let stimuli = vec(stimulus(), 20..60);
    let (n, mut ran, mut faulted, mut fired) = (1500, 0, 0, 0);
    for _ in 0..n {
        let b = blobs.new_tree(&mut runner).unwrap().current();
        let s = stimuli.new_tree(&mut runner).unwrap().current();
        if let Ok(t) = decode(&b) {
            assert_eq!(strategy::interpreter_safe(&t), Ok(()));
            let trace = run(&t, &s);
            ran += 1;
            faulted += usize::from(trace.iter().any(|e| matches!(e, Ev::Fault(_))));
            fired += usize::from(trace.iter().any(|e| matches!(e, Ev::Fired(..))));
        }
    }
    println!(
        "of {n} mutated blobs {ran} decoded and ran; {fired} fired a transition, {faulted} faulted"
    );
    assert!(ran >= n / 20, "{ran}");
    assert!(fired >= ran / 4, "{fired}");
}

/// One damage done to a table's structure, bypassing `validate`.
#[derive(Debug, Clone, Copy)]
struct Damage {
    what: u8,
    at: usize,
    a: u8,
    b: u8,
    mask: u16,
}

fn damage() -> impl Strategy<Value = Damage> {
    (
        any::<u8>(),
        any::<usize>(),
        any::<u8>(),
        any::<u8>(),
        any::<u16>(),
    )
        .prop_map(|(what, at, a, b, mask)| Damage {
            what,
            at,
            a,
            b,
            mask,
        })
}

fn pick<T, const N: usize>(v: &mut heapless::Vec<T, N>, at: usize) -> Option<&mut T> {
    let n = v.len();
    (n > 0).then(|| &mut v[at % n])
}

/// Applies `d` to `t`: an index or a range of the table set to an arbitrary value.
fn apply(t: &mut Table, d: Damage) {
    use config_schema::{Action, Expr, Op};
    let expr = Expr {
        start: d.a,
        len: d.b % 40,
    };
    match d.what % 16 {
        0 => pick(&mut t.transitions, d.at).map(|x| x.to = d.a),
        1 => pick(&mut t.transitions, d.at).map(|x| x.from = d.a),
        2 => pick(&mut t.transitions, d.at).map(|x| x.trigger = Some(d.a)),
        3 => pick(&mut t.transitions, d.at).map(|x| x.guard = Some(expr)),
        4 => pick(&mut t.actions, d.at).map(|x| *x = Action::Set { var: d.b, expr }),
        5 => pick(&mut t.actions, d.at).map(|x| {
            *x = Action::Drive {
                mask: d.mask,
                value: !d.mask ^ u16::from(d.a),
            }
        }),
        6 => pick(&mut t.actions, d.at).map(|x| *x = Action::StartTimer { timer: d.a, ms: 1 }),
        7 => pick(&mut t.actions, d.at).map(|x| *x = Action::Emit(d.a)),
        8 => pick(&mut t.charts, d.at).map(|x| x.states_end = d.a),
        9 => pick(&mut t.charts, d.at).map(|x| x.transitions_end = d.a),
        10 => pick(&mut t.charts, d.at).map(|x| x.initial = d.a),
        11 => pick(&mut t.states, d.at).map(|x| x.actions_end = d.a),
        12 => pick(&mut t.routes, d.at).map(|x| {
            x.chart = d.a;
            x.input = d.b;
        }),
        13 => pick(&mut t.code, d.at).map(|x| {
            *x =
                [Op::Not, Op::And, Op::Var(d.a), Op::Input(d.a), Op::Const(1)][usize::from(d.b) % 5]
        }),
        14 => pick(&mut t.inputs, d.at).map(|x| x.var = Some(d.a)),
        _ => {
            t.events = d.a;
            Some(())
        }
    };
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Defence in depth: the engine does not panic even on a table that skipped validation
    /// (indices and ranges set to arbitrary values), and it stays deterministic.
    #[test]
    fn unvalidated_tables_never_panic_the_engine(
        t in strategy::table(),
        damage in vec(damage(), 1..6),
        stimuli in vec(stimulus(), 0..40),
    ) {
        let mut t = t;
        for d in damage {
            apply(&mut t, d);
        }
        let go = || {
            let mut e = Engine::new(&t);
            let mut fx = Loose(Vec::new());
            for s in &stimuli {
                match *s {
                    Stimulus::Input(i, level) => e.input(i, level, &mut fx),
                    Stimulus::Timer(i) => e.timer_expired(i, &mut fx),
                    Stimulus::Remote { publisher, topic, .. } => {
                        e.remote(publisher, topic, &mut fx);
                    }
                    Stimulus::Start => {
                        e.start(&mut fx);
                    }
                    Stimulus::Event(ev) => e.event(ev, &mut fx),
                    Stimulus::Reset => e.reset(&mut fx),
                }
                for c in 0..t.charts.len() {
                    assert!(e.state(c).is_some());
                }
            }
            fx.0
        };
        let first = go();
        prop_assert_eq!(go(), first);
    }
}

/// Records effects without checking them against the table.
struct Loose(Vec<Ev>);

impl Effects for Loose {
    fn output(&mut self, output: u8, value: bool) {
        self.0.push(Ev::Out(output, value));
    }
    fn publish(&mut self, p: &Publication) {
        self.0.push(Ev::Publish(p.event, p.topic));
    }
    fn start_timer(&mut self, timer: u8, ms: u32) {
        self.0.push(Ev::Start(timer, ms));
    }
    fn cancel_timer(&mut self, timer: u8) {
        self.0.push(Ev::Cancel(timer));
    }
    fn fault(&mut self, fault: Fault) {
        self.0.push(Ev::Fault(fault));
    }
    fn fired(&mut self, chart: u8, transition: u8, from: u8, to: u8) {
        self.0.push(Ev::Fired(chart, transition, from, to));
    }
    fn ignored(&mut self, chart: u8, input: u8) {
        self.0.push(Ev::Ignored(chart, input));
    }
}
