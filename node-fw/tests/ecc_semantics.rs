//! The ECC execution rules, one test (at least) per rule, each on a small hand-made table and
//! each asserting the exact trace of effects the engine reported.
//!
//! Every table goes through `encode` + `decode` before it runs, so the engine runs exactly
//! what a node would run.

use config_schema::limits::{EVENT_QUEUE, MAX_CASCADE, MAX_CHAIN};
use config_schema::{
    validate, Action, EventId, Expr, Input, Level, Op, Output, Publication, Subscription, Table,
    Timer, Transition,
};
use node_fw::ecc::{Effects, Engine, Fault};
use test_tables::{load, route};

/// One effect reported by the engine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ev {
    Fired { chart: u8, t: u8, from: u8, to: u8 },
    Out { i: u8, v: bool },
    Publish { event: EventId, topic: u8 },
    StartTimer { timer: u8, ms: u32 },
    CancelTimer { timer: u8 },
    Fault(Fault),
    Ignored { chart: u8, input: u8 },
}
use Ev::*;

/// Records every effect in order.
#[derive(Debug, Default)]
struct Rec(Vec<Ev>);

impl Rec {
    fn take(&mut self) -> Vec<Ev> {
        std::mem::take(&mut self.0)
    }
}

impl Effects for Rec {
    fn output(&mut self, output: u8, value: bool) {
        self.0.push(Out {
            i: output,
            v: value,
        });
    }
    fn publish(&mut self, p: &Publication) {
        self.0.push(Publish {
            event: p.event,
            topic: p.topic,
        });
    }
    fn start_timer(&mut self, timer: u8, ms: u32) {
        self.0.push(StartTimer { timer, ms });
    }
    fn cancel_timer(&mut self, timer: u8) {
        self.0.push(CancelTimer { timer });
    }
    fn fault(&mut self, fault: Fault) {
        self.0.push(Ev::Fault(fault));
    }
    fn fired(&mut self, chart: u8, t: u8, from: u8, to: u8) {
        self.0.push(Fired { chart, t, from, to });
    }
    fn ignored(&mut self, chart: u8, input: u8) {
        self.0.push(Ignored { chart, input });
    }
}

fn fired(chart: u8, t: u8, from: u8, to: u8) -> Ev {
    Fired { chart, t, from, to }
}

/// A transition on chart input `input`.
fn on(from: u8, input: u8, to: u8) -> Transition {
    Transition {
        from,
        to,
        trigger: Some(input),
        guard: None,
    }
}

/// A guarded transition on chart input `input`.
fn on_if(from: u8, input: u8, to: u8, guard: Expr) -> Transition {
    Transition {
        guard: Some(guard),
        ..on(from, input, to)
    }
}

/// An event-less transition.
fn always(from: u8, to: u8) -> Transition {
    Transition {
        from,
        to,
        trigger: None,
        guard: None,
    }
}

/// A guarded event-less transition.
fn when(from: u8, to: u8, guard: Expr) -> Transition {
    Transition {
        guard: Some(guard),
        ..always(from, to)
    }
}

/// Outputs on pins 0.. driven to these levels on fault, at start and by homing.
fn outputs(t: &mut Table, safe: &[bool]) {
    for (pin, safe) in safe.iter().enumerate() {
        t.outputs.push(Output::safe(pin as u8, *safe)).unwrap();
    }
}

fn events(t: &mut Table, n: u8) {
    for _ in 0..n {
        t.push_event().unwrap();
    }
}

fn drive(i: u8, v: bool) -> Action {
    Action::Drive {
        mask: 1 << i,
        value: u16::from(v) << i,
    }
}

// ---------------------------------------------------------------------------------------
// Priority, consumed trigger, event-less chains, ignored events
// ---------------------------------------------------------------------------------------

/// Two transitions leave S0 on the same event with true guards: the one declared first fires.
fn priority_table(first_to: u8, second_to: u8) -> Table {
    let mut t = Table::empty("prio");
    events(&mut t, 1);
    outputs(&mut t, &[false, false]);
    t.push_chart(
        0,
        1,
        &[&[], &[drive(0, true)], &[drive(1, true)]],
        &[on(0, 0, first_to), on(0, 0, second_to)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    load(t)
}

#[test]
fn declaration_order_decides_between_matching_transitions() {
    let t = priority_table(1, 2);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 0, 0, 1), Out { i: 0, v: true }]);
    assert_eq!(e.state(0), Some(1));

    // Same transitions, swapped: the other one wins.
    let t = priority_table(2, 1);
    let mut e = Engine::new(&t);
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 0, 0, 2), Out { i: 1, v: true }]);
    assert_eq!(e.state(0), Some(2));
}

#[test]
fn a_false_guard_passes_priority_to_the_next_transition() {
    let mut t = Table::empty("prio");
    events(&mut t, 1);
    t.vars.push(0).unwrap();
    let g = t.push_expr(&[Op::Var(0)]).unwrap();
    t.push_chart(0, 1, &[&[], &[], &[]], &[on_if(0, 0, 1, g), on(0, 0, 2)])
        .unwrap();
    route(&mut t, 0, 0, 0);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 1, 0, 2)]);
}

#[test]
fn the_trigger_is_consumed_by_the_first_transition() {
    // S0 -e-> S1 -e-> S2: one delivery of e moves one step only.
    let mut t = Table::empty("consume");
    events(&mut t, 1);
    t.push_chart(0, 1, &[&[], &[], &[]], &[on(0, 0, 1), on(1, 0, 2)])
        .unwrap();
    route(&mut t, 0, 0, 0);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 0, 0, 1)]);
    assert_eq!(e.state(0), Some(1));
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 1, 1, 2)]);
    assert_eq!(e.state(0), Some(2));
}

#[test]
fn event_less_transitions_chain_until_stable_with_actions_in_order() {
    // A -e-> B -> C -> D, and D -> A only if n > 5 (never here).
    let mut t = Table::empty("chain");
    events(&mut t, 1);
    outputs(&mut t, &[false, false, false]);
    t.vars.push(0).unwrap();
    let inc = t.push_expr(&[Op::Var(0), Op::Const(1), Op::Add]).unwrap();
    let big = t.push_expr(&[Op::Var(0), Op::Const(5), Op::Gt]).unwrap();
    let set = Action::Set { var: 0, expr: inc };
    t.push_chart(
        0,
        1,
        &[
            &[],
            &[drive(0, true), set],
            &[set, drive(1, true)],
            &[drive(0, false), drive(2, true)],
        ],
        &[on(0, 0, 1), always(1, 2), always(2, 3), when(3, 0, big)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    assert_eq!(
        fx.take(),
        [
            fired(0, 0, 0, 1),
            Out { i: 0, v: true },
            fired(0, 1, 1, 2),
            Out { i: 1, v: true },
            fired(0, 2, 2, 3),
            Out { i: 0, v: false },
            Out { i: 2, v: true },
        ]
    );
    assert_eq!(e.state(0), Some(3));
    assert_eq!(e.var(0), Some(2));
    assert_eq!(e.outputs(), 0b110);
}

#[test]
fn event_less_transitions_are_candidates_when_an_event_is_delivered() {
    // Decision (docs/ecc-semantics.md): a delivery considers the current state's transitions
    // on that input AND its event-less ones, in declaration order. The event-less one is
    // declared first here, so it wins; the engine only looks at event-less transitions on a
    // delivery, never spontaneously (S0 -> S1 does not fire at construction).
    let mut t = Table::empty("eventless");
    events(&mut t, 2);
    t.push_chart(0, 2, &[&[], &[], &[]], &[always(0, 1), on(0, 0, 2)])
        .unwrap();
    route(&mut t, 0, 0, 0);
    route(&mut t, 1, 0, 1);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    assert_eq!(e.state(0), Some(0));
    // Input 1 has no transition of its own: the event-less one fires anyway.
    e.event(1, &mut fx);
    assert_eq!(fx.take(), [fired(0, 0, 0, 1)]);

    let mut e = Engine::new(&t);
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 0, 0, 1)]);
    assert_eq!(e.state(0), Some(1));
}

#[test]
fn an_event_without_a_transition_is_ignored() {
    let mut t = Table::empty("ignore");
    events(&mut t, 3); // 0 routed with a transition, 1 routed without, 2 not routed
    outputs(&mut t, &[false]);
    t.vars.push(0).unwrap();
    let inc = t.push_expr(&[Op::Var(0), Op::Const(1), Op::Add]).unwrap();
    t.push_chart(
        0,
        2,
        &[&[], &[drive(0, true), Action::Set { var: 0, expr: inc }]],
        &[on(0, 0, 1)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    route(&mut t, 1, 0, 1);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(1, &mut fx);
    assert_eq!(fx.take(), [Ignored { chart: 0, input: 1 }]);
    assert_eq!((e.state(0), e.var(0), e.outputs()), (Some(0), Some(0), 0));
    // Not routed at all, or not an event of this table: nothing happens, nothing traced.
    e.event(2, &mut fx);
    e.event(3, &mut fx);
    e.event(255, &mut fx);
    assert_eq!(fx.take(), []);
    assert_eq!((e.state(0), e.var(0), e.outputs()), (Some(0), Some(0), 0));
    // In S1 event 0 has no transition any more: ignored too.
    e.event(0, &mut fx);
    e.event(0, &mut fx);
    assert_eq!(
        fx.take(),
        [
            fired(0, 0, 0, 1),
            Out { i: 0, v: true },
            Ignored { chart: 0, input: 0 },
        ]
    );
    assert_eq!(e.var(0), Some(1));
}

/// A transition to a state its chart does not have (only a table that skipped validation
/// holds one; here chart 0's S0 -> S2 of its two states, where global state 2 is chart 1's
/// first) moves the chart there and stops: it runs no entry, another chart's neither.
/// Before, the target's global state was taken as it was: chart 1's S0 entry ran for
/// chart 0 and drove its output.
#[test]
fn a_transition_out_of_its_chart_runs_no_entry() {
    let mut t = Table::empty("out");
    events(&mut t, 2);
    outputs(&mut t, &[false]);
    t.push_chart(0, 1, &[&[], &[]], &[on(0, 0, 2)]).unwrap();
    t.push_chart(0, 1, &[&[drive(0, true)], &[]], &[on(0, 0, 1)])
        .unwrap();
    route(&mut t, 0, 0, 0);
    route(&mut t, 1, 1, 0);
    assert!(validate(&t).is_err());
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 0, 0, 2)]);
    assert_eq!((e.state(0), e.state(1), e.outputs()), (Some(2), Some(0), 0));
    // A chart in a state it does not have takes nothing more.
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [Ignored { chart: 0, input: 0 }]);
    // The other chart is unmoved by it.
    e.event(1, &mut fx);
    assert_eq!(fx.take(), [fired(1, 1, 0, 1)]);
}

/// Charts whose states overlap (only a table that skipped validation: here chart 1's end
/// set back, so chart 2's range starts inside chart 0's): the later chart has no state and
/// ignores its inputs, and chart 0's walk runs only its own entries. Before, global state 1
/// was both chart 0's S1 and chart 2's S0: chart 0, entering its S1, took chart 2's
/// event-less transitions and ran their entries (two outputs driven).
#[test]
fn a_chart_overlapping_an_earlier_one_has_no_state() {
    let mut t = Table::empty("overlap");
    events(&mut t, 2);
    outputs(&mut t, &[false, false]);
    t.push_chart(0, 1, &[&[], &[]], &[on(0, 0, 1)]).unwrap();
    t.push_chart(0, 0, &[], &[]).unwrap();
    t.push_chart(
        0,
        1,
        &[&[], &[drive(1, true)], &[drive(0, true)], &[]],
        &[always(0, 3), always(3, 2), on(2, 0, 1)],
    )
    .unwrap();
    t.charts[1].states_end = 1;
    route(&mut t, 0, 0, 0);
    route(&mut t, 1, 2, 0);
    assert!(validate(&t).is_err());
    assert_eq!((t.chart_states(0), t.chart_states(2)), (0..2, 1..6));
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 0, 0, 1)]);
    assert_eq!((e.state(0), e.outputs()), (Some(1), 0));
    e.event(1, &mut fx);
    assert_eq!(fx.take(), [Ignored { chart: 2, input: 0 }]);
    assert_eq!(e.outputs(), 0);
}

// ---------------------------------------------------------------------------------------
// FIFO of emitted events, several charts
// ---------------------------------------------------------------------------------------

#[test]
fn emitted_events_are_delivered_fifo_after_the_emitter_is_stable() {
    // Events: 0 = GO, 1 = X, 2 = Y, 3 = Z.
    // Chart 0: S0 -GO-> S1 [emit X, emit Y], S1 -> S2 [out0 on].
    // Chart 1: S0 -X-> S1 [emit Z], S1 -Y-> S2.
    // Chart 2: S0 -X-> S1, S1 -Y-> S2, S2 -Z-> S3.
    // FIFO: X (c1, c2), Y (c1, c2), Z (c2). If Z were delivered before Y, chart 2 would be
    // in S1 and ignore it; if X were delivered before chart 0 is stable, chart 1 would fire
    // before chart 0's S1 -> S2.
    let (go, x, y, z) = (0, 1, 2, 3);
    let mut t = Table::empty("fifo");
    events(&mut t, 4);
    outputs(&mut t, &[false]);
    t.push_chart(
        0,
        1,
        &[&[], &[Action::Emit(x), Action::Emit(y)], &[drive(0, true)]],
        &[on(0, 0, 1), always(1, 2)],
    )
    .unwrap();
    t.push_chart(
        0,
        2,
        &[&[], &[Action::Emit(z)], &[]],
        &[on(0, 0, 1), on(1, 1, 2)],
    )
    .unwrap();
    t.push_chart(
        0,
        3,
        &[&[], &[], &[], &[]],
        &[on(0, 0, 1), on(1, 1, 2), on(2, 2, 3)],
    )
    .unwrap();
    route(&mut t, go, 0, 0);
    route(&mut t, x, 1, 0);
    route(&mut t, x, 2, 0);
    route(&mut t, y, 1, 1);
    route(&mut t, y, 2, 1);
    route(&mut t, z, 2, 2);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(go, &mut fx);
    assert_eq!(
        fx.take(),
        [
            fired(0, 0, 0, 1),
            fired(0, 1, 1, 2),
            Out { i: 0, v: true },
            fired(1, 2, 0, 1), // X
            fired(2, 4, 0, 1), // X
            fired(1, 3, 1, 2), // Y
            fired(2, 5, 1, 2), // Y
            fired(2, 6, 2, 3), // Z
        ]
    );
    assert_eq!(
        (e.state(0), e.state(1), e.state(2)),
        (Some(2), Some(2), Some(3))
    );
}

/// Three charts that each take S0 -e-> S1 and drive their own output; `order` is the route
/// order of the event.
fn fan_out_table(order: [u8; 3]) -> Table {
    let mut t = Table::empty("fanout");
    events(&mut t, 1);
    outputs(&mut t, &[false, false, false]);
    for c in 0..3u8 {
        t.push_chart(0, 1, &[&[], &[drive(c, true)]], &[on(0, 0, 1)])
            .unwrap();
    }
    for c in order {
        route(&mut t, 0, c, 0);
    }
    load(t)
}

#[test]
fn charts_receive_the_same_event_in_route_order() {
    let t = fan_out_table([2, 0, 1]);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    assert_eq!(
        fx.take(),
        [
            fired(2, 2, 0, 1),
            Out { i: 2, v: true },
            fired(0, 0, 0, 1),
            Out { i: 0, v: true },
            fired(1, 1, 0, 1),
            Out { i: 1, v: true },
        ]
    );
    let t = fan_out_table([1, 2, 0]);
    let mut e = Engine::new(&t);
    e.event(0, &mut fx);
    assert_eq!(
        fx.take(),
        [
            fired(1, 1, 0, 1),
            Out { i: 1, v: true },
            fired(2, 2, 0, 1),
            Out { i: 2, v: true },
            fired(0, 0, 0, 1),
            Out { i: 0, v: true },
        ]
    );
}

#[test]
fn a_chart_sees_its_own_emitted_event_only_after_it_is_stable() {
    // S0 -GO-> S1 [emit E], S1 -> S2, S1 -E-> S9 (never: E arrives when the chart is in S2),
    // S2 -E-> S3.
    let mut t = Table::empty("self");
    events(&mut t, 2);
    t.push_chart(
        0,
        2,
        &[&[], &[Action::Emit(1)], &[], &[]],
        &[on(0, 0, 1), always(1, 2), on(1, 1, 3), on(2, 1, 3)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    route(&mut t, 1, 0, 1);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    assert_eq!(
        fx.take(),
        [fired(0, 0, 0, 1), fired(0, 1, 1, 2), fired(0, 3, 2, 3)]
    );
}

// ---------------------------------------------------------------------------------------
// Guards and assignments
// ---------------------------------------------------------------------------------------

/// The value `ops` assigns to a variable (via a `Set` action), with inputs at `levels`.
fn assigned(ops: &[Op], levels: &[bool]) -> i32 {
    let mut t = Table::empty("eval");
    events(&mut t, 1);
    t.vars.extend_from_slice(&[0, 7, -3]).unwrap();
    for (pin, _) in levels.iter().enumerate() {
        t.inputs
            .push(Input {
                pin: pin as u8,
                rise: None,
                fall: None,
                var: None,
            })
            .unwrap();
    }
    let expr = t.push_expr(ops).unwrap();
    t.push_chart(
        0,
        1,
        &[&[], &[Action::Set { var: 0, expr }]],
        &[on(0, 0, 1)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    let t = load(t);
    let mut e = Engine::new(&t);
    for (i, level) in levels.iter().enumerate() {
        e.input(i as u8, *level, &mut ());
    }
    e.event(0, &mut ());
    assert_eq!(e.state(0), Some(1));
    e.var(0).unwrap()
}

/// Whether a transition guarded by `ops` fires.
fn holds(ops: &[Op]) -> bool {
    let mut t = Table::empty("guard");
    events(&mut t, 1);
    let g = t.push_expr(ops).unwrap();
    t.push_chart(0, 1, &[&[], &[]], &[on_if(0, 0, 1, g)])
        .unwrap();
    route(&mut t, 0, 0, 0);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    match e.state(0) {
        Some(1) => {
            assert_eq!(fx.take(), [fired(0, 0, 0, 1)]);
            true
        }
        _ => {
            assert_eq!(fx.take(), [Ignored { chart: 0, input: 0 }]);
            false
        }
    }
}

fn bin(a: i32, b: i32, op: Op) -> Vec<Op> {
    vec![Op::Const(a), Op::Const(b), op]
}

#[test]
fn every_op_evaluates_exactly() {
    use Op::*;
    let cases: &[(&[Op], i32)] = &[
        (&[Const(-42)], -42),
        (&[Var(1)], 7),
        (&[Var(2)], -3),
        (&[Const(0), Not], 1),
        (&[Const(5), Not], 0),
        (&[Const(-1), Not], 0),
    ];
    for (ops, want) in cases {
        assert_eq!(assigned(ops, &[]), *want, "{ops:?}");
    }
    let binary = [
        (2, -1, And, 1),
        (0, 5, And, 0),
        (5, 0, And, 0),
        (0, 0, Or, 0),
        (0, -7, Or, 1),
        (3, 0, Or, 1),
        (3, 3, Eq, 1),
        (2, 3, Eq, 0),
        (3, 3, Ne, 0),
        (2, 3, Ne, 1),
        (2, 3, Lt, 1),
        (3, 3, Lt, 0),
        (4, 3, Lt, 0),
        (2, 3, Le, 1),
        (3, 3, Le, 1),
        (4, 3, Le, 0),
        (4, 3, Gt, 1),
        (3, 3, Gt, 0),
        (2, 3, Gt, 0),
        (3, 3, Ge, 1),
        (4, 3, Ge, 1),
        (2, 3, Ge, 0),
        (-5, 3, Lt, 1), // signed comparison
        (2, 3, Add, 5),
        (i32::MAX, 1, Add, i32::MIN), // wraps
        (2, 3, Sub, -1),              // a - b, operand order
        (i32::MIN, 1, Sub, i32::MAX), // wraps
    ];
    for (a, b, op, want) in binary {
        assert_eq!(assigned(&bin(a, b, op), &[]), want, "{a} {op:?} {b}");
    }
    // Inputs read as 0 / 1.
    assert_eq!(assigned(&[Input(0)], &[false, true]), 0);
    assert_eq!(assigned(&[Input(1)], &[false, true]), 1);
    // A nested expression: (v1 - 2) * ... -> ((7 - 2) >= 5) && !(in0) == 1 with in0 low.
    let nested = [Var(1), Const(2), Sub, Const(5), Ge, Input(0), Not, And];
    assert_eq!(assigned(&nested, &[false]), 1);
    assert_eq!(assigned(&nested, &[true]), 0);
}

#[test]
fn a_guard_holds_when_non_zero() {
    assert!(holds(&[Op::Const(1)]));
    assert!(holds(&[Op::Const(2)]));
    assert!(holds(&[Op::Const(-1)]));
    assert!(!holds(&[Op::Const(0)]));
    assert!(holds(&bin(1, 2, Op::Lt)));
    assert!(!holds(&bin(2, 1, Op::Lt)));
    assert!(holds(&bin(3, 2, Op::Sub)));
    assert!(!holds(&bin(2, 2, Op::Sub)));
}

#[test]
fn guards_read_mirrored_inputs_and_input_levels() {
    // Input 0 (pin 4) mirrored in var 1, no events; input 1 (pin 5) read with Op::Input.
    // S0 -e [v1 == 1]-> S1, S0 -e [in1]-> S2, S0 -e-> S3.
    let mut t = Table::empty("inputs");
    events(&mut t, 1);
    t.vars.extend_from_slice(&[0, 0]).unwrap();
    t.inputs
        .push(Input {
            pin: 4,
            rise: None,
            fall: None,
            var: Some(1),
        })
        .unwrap();
    t.inputs
        .push(Input {
            pin: 5,
            rise: None,
            fall: None,
            var: None,
        })
        .unwrap();
    let mirrored = t.push_expr(&[Op::Var(1), Op::Const(1), Op::Eq]).unwrap();
    let level = t.push_expr(&[Op::Input(1)]).unwrap();
    t.push_chart(
        0,
        1,
        &[&[], &[], &[], &[]],
        &[on_if(0, 0, 1, mirrored), on_if(0, 0, 2, level), on(0, 0, 3)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    let t = load(t);
    let run = |in0: bool, in1: bool| {
        let mut e = Engine::new(&t);
        let mut fx = Rec::default();
        e.input(0, in0, &mut fx);
        e.input(1, in1, &mut fx);
        assert_eq!(fx.take(), [], "inputs without events raise nothing");
        assert_eq!(e.var(1), Some(i32::from(in0)));
        assert_eq!(e.inputs(), u16::from(in0) | u16::from(in1) << 1);
        e.event(0, &mut fx);
        e.state(0).unwrap()
    };
    assert_eq!(run(false, false), 3);
    assert_eq!(run(false, true), 2);
    assert_eq!(run(true, false), 1);
    assert_eq!(run(true, true), 1);
}

#[test]
fn assignments_count_and_guards_see_the_new_value() {
    // S0 -e-> S1 [n := n + 1]; S1 -[n < 3]-> S0; S1 -[n >= 3]-> S2 [out0 on].
    let mut t = Table::empty("count");
    events(&mut t, 1);
    outputs(&mut t, &[false]);
    t.vars.push(0).unwrap();
    let inc = t.push_expr(&[Op::Var(0), Op::Const(1), Op::Add]).unwrap();
    let lt = t.push_expr(&[Op::Var(0), Op::Const(3), Op::Lt]).unwrap();
    let ge = t.push_expr(&[Op::Var(0), Op::Const(3), Op::Ge]).unwrap();
    t.push_chart(
        0,
        1,
        &[&[], &[Action::Set { var: 0, expr: inc }], &[drive(0, true)]],
        &[on(0, 0, 1), when(1, 0, lt), when(1, 2, ge)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    for n in 1..=2 {
        e.event(0, &mut fx);
        assert_eq!(fx.take(), [fired(0, 0, 0, 1), fired(0, 1, 1, 0)]);
        assert_eq!((e.var(0), e.state(0)), (Some(n), Some(0)));
    }
    e.event(0, &mut fx);
    assert_eq!(
        fx.take(),
        [fired(0, 0, 0, 1), fired(0, 2, 1, 2), Out { i: 0, v: true }]
    );
    assert_eq!((e.var(0), e.state(0)), (Some(3), Some(2)));
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [Ignored { chart: 0, input: 0 }]);
}

// ---------------------------------------------------------------------------------------
// Bounds and faults
// ---------------------------------------------------------------------------------------

/// Outputs: out0 safe low, out1 safe high. Timers 0 and 1 (events 1 and 2, unrouted).
/// Events: 0 = GO, 1, 2 = timer events, 3 = LATER (routed to chart 0 input 1).
fn fault_base() -> Table {
    let mut t = Table::empty("fault");
    events(&mut t, 4);
    outputs(&mut t, &[false, true]);
    t.timers.push(Timer { event: 1 }).unwrap();
    t.timers.push(Timer { event: 2 }).unwrap();
    t
}

/// The entry actions of the "running" state: out0 on, out1 off, timer 0 started.
const RUN: [Action; 2] = [
    Action::Drive {
        mask: 0b11,
        value: 0b01,
    },
    Action::StartTimer { timer: 0, ms: 500 },
];
const RUN_TRACE: [Ev; 3] = [
    Out { i: 0, v: true },
    Out { i: 1, v: false },
    StartTimer { timer: 0, ms: 500 },
];
/// What going to the safe state from RUN reports.
fn safe_trace(fault: Fault) -> [Ev; 5] {
    [
        Out { i: 0, v: false },
        Out { i: 1, v: true },
        CancelTimer { timer: 0 },
        CancelTimer { timer: 1 },
        Ev::Fault(fault),
    ]
}

/// After a fault: events, edges, timers and remote events are ignored, states unchanged.
fn assert_stays_faulted(e: &mut Engine, fault: Fault) {
    let states: Vec<_> = (0..e.table().charts.len()).map(|c| e.state(c)).collect();
    let mut fx = Rec::default();
    for ev in 0..e.table().events {
        e.event(ev, &mut fx);
    }
    e.timer_expired(0, &mut fx);
    e.timer_expired(1, &mut fx);
    e.start(&mut fx);
    assert_eq!(fx.take(), []);
    assert_eq!(e.fault(), Some(fault));
    assert_eq!(e.outputs(), 0b10);
    let after: Vec<_> = (0..e.table().charts.len()).map(|c| e.state(c)).collect();
    assert_eq!(states, after);
}

/// A chart whose chain S1 [n := n + 1] -[n < limit]-> S1 fires `limit - 1` event-less steps.
fn chain_table(limit: i32) -> Table {
    let mut t = fault_base();
    t.vars.push(0).unwrap();
    let inc = t.push_expr(&[Op::Var(0), Op::Const(1), Op::Add]).unwrap();
    let more = t
        .push_expr(&[Op::Var(0), Op::Const(limit), Op::Lt])
        .unwrap();
    t.push_chart(
        0,
        2,
        &[&[], &[RUN[0], RUN[1], Action::Set { var: 0, expr: inc }]],
        &[on(0, 0, 1), when(1, 1, more), on(1, 1, 0)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    route(&mut t, 3, 0, 1);
    load(t)
}

#[test]
fn a_chain_of_max_chain_event_less_steps_is_allowed() {
    let t = chain_table(MAX_CHAIN as i32 + 1);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    let trace = fx.take();
    let loops = trace.iter().filter(|ev| **ev == fired(0, 1, 1, 1)).count();
    assert_eq!(loops, MAX_CHAIN);
    assert_eq!(e.fault(), None);
    assert_eq!(e.var(0), Some(MAX_CHAIN as i32 + 1));
}

#[test]
fn an_event_less_loop_faults_with_chain_limit() {
    let t = chain_table(i32::MAX);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    let mut want = vec![fired(0, 0, 0, 1)];
    want.extend(RUN_TRACE);
    for _ in 0..MAX_CHAIN {
        // Re-entering S1 runs its actions again; out0/out1 and the timer are unchanged
        // levels but the timer is restarted.
        want.push(fired(0, 1, 1, 1));
        want.push(StartTimer { timer: 0, ms: 500 });
    }
    let fault = Fault::ChainLimit { chart: 0 };
    want.extend(safe_trace(fault));
    assert_eq!(fx.take(), want);
    assert_eq!(e.fault(), Some(fault));
    assert_eq!(e.var(0), Some(MAX_CHAIN as i32 + 1));
    assert_stays_faulted(&mut e, fault);
    assert_eq!(e.state(0), Some(1));
}

/// An event-less loop without a guard (taken without a choice, fused when the index is
/// built) counts towards `MAX_CHAIN` like a guarded one: S0 -GO-> S1 [n := n + 1], S1 -> S1.
#[test]
fn an_unguarded_event_less_loop_faults_with_chain_limit() {
    let mut t = fault_base();
    t.vars.push(0).unwrap();
    let inc = t.push_expr(&[Op::Var(0), Op::Const(1), Op::Add]).unwrap();
    t.push_chart(
        0,
        2,
        &[&[], &[Action::Set { var: 0, expr: inc }]],
        &[on(0, 0, 1), always(1, 1)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    let mut want = vec![fired(0, 0, 0, 1)];
    want.extend(std::iter::repeat_n(fired(0, 1, 1, 1), MAX_CHAIN));
    let fault = Fault::ChainLimit { chart: 0 };
    // The outputs are at their fault levels already: only the timers are cancelled.
    want.push(CancelTimer { timer: 0 });
    want.push(CancelTimer { timer: 1 });
    want.push(Ev::Fault(fault));
    assert_eq!(fx.take(), want);
    assert_eq!(e.fault(), Some(fault));
    assert_eq!(e.var(0), Some(MAX_CHAIN as i32 + 1));
}

/// Of a state's event-less transitions the first whose guard holds is taken, also when a
/// later one always holds: S1 -[n = 1]-> S2, S1 -> S3 (and a constant-true guard is
/// taken like a missing one).
#[test]
fn an_always_true_event_less_transition_waits_behind_a_guarded_one() {
    let build = |first_guard: i32| {
        let mut t = fault_base();
        t.vars.push(0).unwrap();
        let one = t.push_expr(&[Op::Var(0), Op::Const(1), Op::Eq]).unwrap();
        let yes = t.push_expr(&[Op::Const(first_guard)]).unwrap();
        let set = t.push_expr(&[Op::Const(1)]).unwrap();
        t.push_chart(
            0,
            4,
            &[&[], &[], &[], &[]],
            &[
                on(0, 0, 1),
                when(1, 2, one),
                when(1, 3, yes),
                on(2, 1, 0),
                on(3, 1, 0),
            ],
        )
        .unwrap();
        push_setter(&mut t, set);
        route(&mut t, 0, 0, 0);
        route(&mut t, 3, 1, 0);
        route(&mut t, 3, 0, 1);
        load(t)
    };
    let t = build(7);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 0, 0, 1), fired(0, 2, 1, 3)]);
    e.event(3, &mut fx);
    e.event(0, &mut fx);
    assert_eq!(
        fx.take(),
        [
            fired(1, 5, 0, 0),
            fired(0, 4, 3, 0),
            fired(0, 0, 0, 1),
            fired(0, 1, 1, 2)
        ]
    );
    // A constant-false guard never holds: the chart rests in S1.
    let t = build(0);
    let mut e = Engine::new(&t);
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 0, 0, 1)]);
    assert_eq!(e.state(0), Some(1));
}

/// Pushes a chart of one state that sets variable 0 to `expr` whenever its input 0 fires
/// (S0 -in0-> S0 [v0 := expr]).
fn push_setter(t: &mut Table, expr: Expr) {
    t.push_chart(0, 1, &[&[Action::Set { var: 0, expr }]], &[on(0, 0, 0)])
        .unwrap();
}

/// Chart 0: S0 -GO-> S1 [RUN, emit X * `emits`, out0 off]; X (event 3) is counted by
/// chart 1: S0 -X-> S0 [n := n + 1].
fn storm_table(emits: usize) -> Table {
    let mut t = fault_base();
    t.vars.push(0).unwrap();
    let inc = t.push_expr(&[Op::Var(0), Op::Const(1), Op::Add]).unwrap();
    let mut s1 = RUN.to_vec();
    s1.extend(std::iter::repeat_n(Action::Emit(3), emits));
    s1.push(drive(0, false));
    t.push_chart(0, 1, &[&[], &s1], &[on(0, 0, 1)]).unwrap();
    push_setter(&mut t, inc);
    route(&mut t, 0, 0, 0);
    route(&mut t, 3, 1, 0);
    // X is published: a publication must not go out for an event that was not queued.
    // (Sixteen frames in one stimulus are over the time bound: `decode` would refuse this
    // table; the interpreter still bounds it at run time.)
    t.peers.push(0x0002).unwrap();
    t.publications
        .push(Publication {
            event: 3,
            topic: 30,
            subscribers: 1,
        })
        .unwrap();
    test_tables::load_untimed(t)
}

#[test]
fn a_full_queue_is_allowed() {
    let t = storm_table(EVENT_QUEUE);
    assert!(
        matches!(
            config_schema::validate(&t),
            Err(config_schema::Invalid::Slow { .. })
        ),
        "sixteen frames in one stimulus: over the time bound"
    );
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    let mut want = vec![fired(0, 0, 0, 1)];
    want.extend(RUN_TRACE);
    want.extend(
        [Publish {
            event: 3,
            topic: 30,
        }; EVENT_QUEUE],
    );
    want.push(Out { i: 0, v: false });
    want.extend([fired(1, 1, 0, 0); EVENT_QUEUE]);
    assert_eq!(fx.take(), want);
    assert_eq!(e.fault(), None);
    assert_eq!(e.var(0), Some(EVENT_QUEUE as i32));
}

#[test]
fn an_emit_storm_faults_with_queue_full() {
    let t = storm_table(EVENT_QUEUE + 1);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    let mut want = vec![fired(0, 0, 0, 1)];
    want.extend(RUN_TRACE);
    // Only the queued events are published; the one that did not fit faults the node,
    // and the actions after it (out0 off) do not run. Nothing queued is delivered.
    want.extend(
        [Publish {
            event: 3,
            topic: 30,
        }; EVENT_QUEUE],
    );
    let fault = Fault::QueueFull { event: 3 };
    want.extend(safe_trace(fault));
    assert_eq!(fx.take(), want);
    assert_eq!(e.var(0), Some(0));
    assert_stays_faulted(&mut e, fault);
}

#[test]
fn a_ping_pong_emit_cycle_faults_with_cascade() {
    // Chart 0: S0 -GO-> S1 [RUN, emit Q]; S1 -P-> S1 [emit Q]. Chart 1: S0 -Q-> S0 [emit P].
    // Each delivery fires once and emits once, so the queue never fills, but the stimulus
    // never ends.
    let (go, p, q) = (0, 3, 2);
    let mut t = fault_base();
    t.push_chart(
        0,
        2,
        &[&[], &[RUN[0], RUN[1], Action::Emit(q)]],
        &[on(0, 0, 1), on(1, 1, 1)],
    )
    .unwrap();
    t.push_chart(0, 1, &[&[Action::Emit(p)]], &[on(0, 0, 0)])
        .unwrap();
    route(&mut t, go, 0, 0);
    route(&mut t, p, 0, 1);
    route(&mut t, q, 1, 0);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(go, &mut fx);
    let mut want = vec![fired(0, 0, 0, 1)];
    want.extend(RUN_TRACE);
    // GO was delivery 1; Q, P, Q, ... are deliveries 2..=MAX_CASCADE.
    for d in 2..=MAX_CASCADE {
        if d % 2 == 0 {
            want.push(fired(1, 2, 0, 0));
        } else {
            want.extend([fired(0, 1, 1, 1), StartTimer { timer: 0, ms: 500 }]);
        }
    }
    let fault = Fault::Cascade { event: go };
    want.extend(safe_trace(fault));
    assert_eq!(fx.take(), want);
    assert_stays_faulted(&mut e, fault);
}

#[test]
fn a_fault_action_stops_the_step_and_the_node() {
    // Chart 0: S0 -GO-> S1 [RUN, fault 7, out0 on]. Chart 1 also routed GO, after chart 0.
    let mut t = fault_base();
    t.push_chart(
        0,
        1,
        &[&[], &[RUN[0], RUN[1], Action::Fault(7), drive(0, true)]],
        &[on(0, 0, 1)],
    )
    .unwrap();
    t.push_chart(0, 1, &[&[], &[]], &[on(0, 0, 1)]).unwrap();
    route(&mut t, 0, 0, 0);
    route(&mut t, 0, 1, 0);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    let mut want = vec![fired(0, 0, 0, 1)];
    want.extend(RUN_TRACE);
    let fault = Fault::Action { chart: 0, code: 7 };
    want.extend(safe_trace(fault));
    assert_eq!(fx.take(), want);
    assert_eq!(e.state(1), Some(0), "the rest of the delivery is dropped");
    assert_stays_faulted(&mut e, fault);
}

#[test]
fn reset_restores_the_initial_state_and_clears_a_fault() {
    // Input 0 mirrored in var 1; var 0 starts at 10 and counts. S0 -GO-> S1 [RUN, n+=1],
    // S1 -LATER-> S2 [fault 3].
    let mut t = fault_base();
    t.vars.extend_from_slice(&[10, 0]).unwrap();
    t.inputs
        .push(Input {
            pin: 9,
            rise: None,
            fall: None,
            var: Some(1),
        })
        .unwrap();
    let inc = t.push_expr(&[Op::Var(0), Op::Const(1), Op::Add]).unwrap();
    t.push_chart(
        0,
        2,
        &[
            &[],
            &[RUN[0], RUN[1], Action::Set { var: 0, expr: inc }],
            &[Action::Fault(3)],
        ],
        &[on(0, 0, 1), on(1, 1, 2)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    route(&mut t, 3, 0, 1);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    assert_eq!((e.outputs(), e.var(0), e.var(1)), (0b10, Some(10), Some(0)));
    e.input(0, true, &mut fx);
    e.event(0, &mut fx);
    assert_eq!(fx.take()[0], fired(0, 0, 0, 1));
    assert_eq!(
        (e.state(0), e.var(0), e.outputs()),
        (Some(1), Some(11), 0b01)
    );

    // Reset from a running state: timers cancelled, changed outputs reported.
    e.reset(&mut fx);
    assert_eq!(
        fx.take(),
        [
            CancelTimer { timer: 0 },
            CancelTimer { timer: 1 },
            Out { i: 0, v: false },
            Out { i: 1, v: true },
        ]
    );
    // Initial state and variables; the input keeps its level and its mirror.
    assert_eq!(
        (e.state(0), e.var(0), e.var(1), e.outputs(), e.inputs()),
        (Some(0), Some(10), Some(1), 0b10, 0b1)
    );

    // Reset from a fault: outputs are already safe, so only the timers are reported.
    e.event(0, &mut fx);
    e.event(3, &mut fx);
    let fault = Fault::Action { chart: 0, code: 3 };
    assert_eq!(fx.take().last(), Some(&Ev::Fault(fault)));
    assert_stays_faulted(&mut e, fault);
    e.reset(&mut fx);
    assert_eq!(
        fx.take(),
        [CancelTimer { timer: 0 }, CancelTimer { timer: 1 }]
    );
    assert_eq!(e.fault(), None);
    assert_eq!(
        (e.state(0), e.var(0), e.outputs()),
        (Some(0), Some(10), 0b10)
    );
    // Events are processed again.
    e.event(0, &mut fx);
    let mut want = vec![fired(0, 0, 0, 1)];
    want.extend(RUN_TRACE);
    assert_eq!(fx.take(), want);
}

/// A gripper (out0: fault `Hold`, start `Hold`), a warning lamp (out1: fault `High`, start
/// `Low`) and a beacon (out2: fault `Low`, start `High`). S0 -GO-> S1 [out0 on (close),
/// timer 0] -LATER-> S2 [fault 5].
fn levels_table() -> Table {
    let mut t = fault_base();
    t.outputs.clear();
    let levels = [
        (Level::Hold, Level::Hold, false),
        (Level::High, Level::Low, false),
        (Level::Low, Level::High, true),
    ];
    for (pin, (fault, start, home)) in levels.into_iter().enumerate() {
        let pin = pin as u8;
        let o = Output {
            pin,
            fault,
            start,
            home,
        };
        t.outputs.push(o).unwrap();
    }
    let close = Action::Drive {
        mask: 0b001,
        value: 0b001,
    };
    t.push_chart(
        0,
        2,
        &[&[], &[close, RUN[1]], &[Action::Fault(5)]],
        &[on(0, 0, 1), on(1, 1, 2)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    route(&mut t, 3, 0, 1);
    load(t)
}

#[test]
fn a_fault_drives_the_fault_levels_and_a_held_output_keeps_its_level() {
    let t = levels_table();
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    assert_eq!(
        e.outputs(),
        0b100,
        "start levels; the held gripper starts low"
    );
    e.event(0, &mut fx);
    assert_eq!(e.outputs(), 0b101, "the gripper closed");
    fx.take();
    e.event(3, &mut fx);
    let fault = Fault::Action { chart: 0, code: 5 };
    assert_eq!(
        fx.take(),
        [
            fired(0, 1, 1, 2),
            // The gripper holds (nothing reported), the lamp lights, the beacon goes off.
            Out { i: 1, v: true },
            Out { i: 2, v: false },
            CancelTimer { timer: 0 },
            CancelTimer { timer: 1 },
            Ev::Fault(fault),
        ]
    );
    assert_eq!(e.outputs(), 0b011, "the gripper holds its part");
    // A reset drives the start levels; the held gripper still holds.
    e.reset(&mut fx);
    assert_eq!(
        fx.take(),
        [
            CancelTimer { timer: 0 },
            CancelTimer { timer: 1 },
            Out { i: 1, v: false },
            Out { i: 2, v: true },
        ]
    );
    assert_eq!((e.outputs(), e.fault(), e.state(0)), (0b101, None, Some(0)));
}

#[test]
fn a_new_table_holds_the_levels_it_is_given_for_its_held_outputs() {
    let t = levels_table();
    // The previous table left every pin high: the gripper keeps it, the others start at
    // their start levels.
    let e = Engine::new_holding(&t, 0b111);
    assert_eq!(e.outputs(), 0b101);
    let e = Engine::new_holding(&t, 0b010);
    assert_eq!(e.outputs(), 0b100);
    // A table that holds nothing ignores them.
    let mut plain = Table::empty("plain");
    outputs(&mut plain, &[false, true]);
    let plain = load(plain);
    assert_eq!(Engine::new_holding(&plain, 0b11).outputs(), 0b10);
}

// ---------------------------------------------------------------------------------------
// Timers, inputs, publications, remote events, outputs
// ---------------------------------------------------------------------------------------

#[test]
fn timers_are_requested_cancelled_and_raise_their_event_on_expiry() {
    // Timer 0 raises event 1 (published, topic 11); timer 1 raises event 2 (not published).
    // S0 -GO-> S1 [start t0 250 ms, start t1 40 ms, cancel t1]; S1 -T0-> S2 [out0 on].
    let mut t = Table::empty("timers");
    events(&mut t, 3);
    outputs(&mut t, &[false]);
    t.timers.push(Timer { event: 1 }).unwrap();
    t.timers.push(Timer { event: 2 }).unwrap();
    t.peers.push(0x0010).unwrap();
    t.publications
        .push(Publication {
            event: 1,
            topic: 11,
            subscribers: 1,
        })
        .unwrap();
    t.push_chart(
        0,
        2,
        &[
            &[],
            &[
                Action::StartTimer { timer: 0, ms: 250 },
                Action::StartTimer { timer: 1, ms: 40 },
                Action::CancelTimer(1),
            ],
            &[drive(0, true)],
        ],
        &[on(0, 0, 1), on(1, 1, 2)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    route(&mut t, 1, 0, 1);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    assert_eq!(
        fx.take(),
        [
            fired(0, 0, 0, 1),
            StartTimer { timer: 0, ms: 250 },
            StartTimer { timer: 1, ms: 40 },
            CancelTimer { timer: 1 },
        ]
    );
    e.timer_expired(0, &mut fx);
    assert_eq!(
        fx.take(),
        [
            Publish {
                event: 1,
                topic: 11
            },
            fired(0, 1, 1, 2),
            Out { i: 0, v: true }
        ]
    );
    // A timer the table does not have: nothing.
    e.timer_expired(2, &mut fx);
    assert_eq!(fx.take(), []);
}

#[test]
fn input_edges_raise_their_events_once_per_edge() {
    // Input 0: rise -> event 0, fall -> event 1. S0 -rise-> S1 -fall-> S0.
    let mut t = Table::empty("edges");
    events(&mut t, 2);
    t.inputs
        .push(Input {
            pin: 3,
            rise: Some(0),
            fall: Some(1),
            var: None,
        })
        .unwrap();
    t.push_chart(0, 2, &[&[], &[]], &[on(0, 0, 1), on(1, 1, 0)])
        .unwrap();
    route(&mut t, 0, 0, 0);
    route(&mut t, 1, 0, 1);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.input(0, false, &mut fx); // already low: no edge
    e.input(0, true, &mut fx);
    e.input(0, true, &mut fx); // still high: no edge
    e.input(0, false, &mut fx);
    e.input(1, true, &mut fx); // not an input of this table
    assert_eq!(fx.take(), [fired(0, 0, 0, 1), fired(0, 1, 1, 0)]);
    assert_eq!(e.inputs(), 0);
}

/// Events: 0 = input rise, 1 = timer expiry, 2 = emitted, 3 = remote (subscribed from peer 1,
/// topic 7), 4 = START, 5 = raised from outside / `Publish` action, 6 = emitted without a
/// publication. Events 0..=5 all have a publication (topic 100 + event).
///
/// One chart: S0 -input k-> S(k+1) [var0 := k] -> S0, so var0 and the trace tell which
/// event arrived; S1 also emits 2 and 6 and publishes 5.
fn publication_table() -> Table {
    let mut t = Table::empty("pubs");
    events(&mut t, 7);
    t.start = Some(4);
    t.inputs
        .push(Input {
            pin: 0,
            rise: Some(0),
            fall: None,
            var: None,
        })
        .unwrap();
    t.timers.push(Timer { event: 1 }).unwrap();
    t.peers.extend_from_slice(&[0x0001, 0x0002]).unwrap();
    for (event, topic) in [(0, 100), (1, 101), (2, 102), (3, 103), (4, 104), (5, 105)] {
        t.publications
            .push(Publication {
                event,
                topic,
                subscribers: 0b11,
            })
            .unwrap();
    }
    t.subscriptions
        .push(Subscription {
            publisher: 1,
            topic: 7,
            event: 3,
        })
        .unwrap();
    t.vars.push(-1).unwrap();
    let mut states: Vec<Vec<Action>> = vec![vec![]];
    let mut transitions = vec![];
    for k in 0..6u8 {
        let value = t.push_expr(&[Op::Const(i32::from(k))]).unwrap();
        let mut actions = vec![Action::Set {
            var: 0,
            expr: value,
        }];
        if k == 0 {
            actions.push(Action::Emit(2));
            actions.push(Action::Emit(6));
            actions.push(Action::Publish(5));
        }
        states.push(actions);
        transitions.push(on(0, k, k + 1));
        transitions.push(always(k + 1, 0));
    }
    let states: Vec<&[Action]> = states.iter().map(Vec::as_slice).collect();
    t.push_chart(0, 7, &states, &transitions).unwrap();
    for event in 0..7 {
        route(&mut t, event, 0, event);
    }
    load(t)
}

#[test]
fn locally_originated_events_are_published_remote_ones_are_not() {
    let t = publication_table();
    let mut fx = Rec::default();

    // Input edge: published before it is delivered; its state emits 2 (published) and 6
    // (no publication) and publishes 5 without delivering it.
    let mut e = Engine::new(&t);
    e.input(0, true, &mut fx);
    assert_eq!(
        fx.take(),
        [
            Publish {
                event: 0,
                topic: 100
            },
            fired(0, 0, 0, 1),
            Publish {
                event: 2,
                topic: 102
            },
            Publish {
                event: 5,
                topic: 105
            },
            fired(0, 1, 1, 0),
            fired(0, 4, 0, 3), // 2 delivered
            fired(0, 5, 3, 0),
            Ignored { chart: 0, input: 6 }, // 6 delivered, no transition
        ]
    );
    assert_eq!(e.var(0), Some(2));

    // Timer expiry: published.
    e.timer_expired(0, &mut fx);
    assert_eq!(
        fx.take(),
        [
            Publish {
                event: 1,
                topic: 101
            },
            fired(0, 2, 0, 2),
            fired(0, 3, 2, 0),
        ]
    );

    // Remote event (peer 1, topic 7): delivered, not published back.
    assert!(e.remote(1, 7, &mut fx));
    assert_eq!(fx.take(), [fired(0, 6, 0, 4), fired(0, 7, 4, 0)]);
    assert_eq!(e.var(0), Some(3));

    // The START command stands for the START button wired to this node: published.
    assert!(e.start(&mut fx));
    assert_eq!(
        fx.take(),
        [
            Publish {
                event: 4,
                topic: 104
            },
            fired(0, 8, 0, 5),
            fired(0, 9, 5, 0)
        ]
    );
    // An event from outside: delivered, not published.
    e.event(5, &mut fx);
    assert_eq!(fx.take(), [fired(0, 10, 0, 6), fired(0, 11, 6, 0)]);
    assert_eq!(e.var(0), Some(5));
}

#[test]
fn remote_events_need_a_matching_subscription() {
    let t = publication_table();
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    assert!(
        !e.remote(0, 7, &mut fx),
        "topic 7 is subscribed from peer 1, not 0"
    );
    assert!(!e.remote(1, 8, &mut fx), "unknown topic");
    assert!(!e.remote(5, 7, &mut fx), "unknown peer");
    assert_eq!(fx.take(), []);
    assert_eq!((e.state(0), e.var(0)), (Some(0), Some(-1)));

    let mut no_start = Table::empty("nostart");
    no_start.push_event().unwrap();
    let no_start = load(no_start);
    let mut e = Engine::new(&no_start);
    assert!(!e.start(&mut fx));
    assert_eq!(fx.take(), []);
}

#[test]
fn drive_reports_only_changed_outputs() {
    // S0 -e-> S1 [drive 0b0111 := 0b0101], S1 -e-> S2 [drive 0b0110 := 0b0110],
    // S2 -e-> S3 [drive 0b1111 := 0b1110], S3 -e-> S4 [drive 0b0110 := 0b0110] (no change).
    let mut t = Table::empty("drive");
    events(&mut t, 1);
    outputs(&mut t, &[false, false, false, true]);
    t.push_chart(
        0,
        1,
        &[
            &[],
            &[Action::Drive {
                mask: 0b0111,
                value: 0b0101,
            }],
            &[Action::Drive {
                mask: 0b0110,
                value: 0b0110,
            }],
            &[Action::Drive {
                mask: 0b1111,
                value: 0b1110,
            }],
            &[Action::Drive {
                mask: 0b0110,
                value: 0b0110,
            }],
        ],
        &[on(0, 0, 1), on(1, 0, 2), on(2, 0, 3), on(3, 0, 4)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    let t = load(t);
    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    assert_eq!(e.outputs(), 0b1000, "outputs start in the safe state");
    e.event(0, &mut fx);
    assert_eq!(
        fx.take(),
        [
            fired(0, 0, 0, 1),
            Out { i: 0, v: true },
            Out { i: 2, v: true }
        ]
    );
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 1, 1, 2), Out { i: 1, v: true }]);
    assert_eq!(e.outputs(), 0b1111);
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 2, 2, 3), Out { i: 0, v: false }]);
    assert_eq!(e.outputs(), 0b1110);
    e.event(0, &mut fx);
    assert_eq!(fx.take(), [fired(0, 3, 3, 4)]);
    assert_eq!(e.outputs(), 0b1110);
}

#[test]
fn construction_reports_nothing_and_starts_safe() {
    let t = storm_table(1);
    let mut e = Engine::new(&t);
    assert_eq!(
        (e.state(0), e.state(1), e.state(2)),
        (Some(0), Some(0), None)
    );
    assert_eq!((e.outputs(), e.inputs(), e.fault()), (0b10, 0, None));
    assert_eq!((e.var(0), e.var(1)), (Some(0), None));
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    assert_eq!(e.fault(), None);
}

#[test]
fn an_expression_that_cannot_be_evaluated_faults_the_node() {
    // Only a table that skipped validation can hold one: here a guard and an assignment
    // that read past their operands. Chart 0: S0 -GO-> S1 [RUN], S1 -[bad]-> S2;
    // S0 -LATER-> S3 [v := bad].
    let build = || {
        let mut t = fault_base();
        t.vars.push(5).unwrap();
        let bad = t.push_expr(&[Op::Const(1), Op::And]).unwrap();
        t.push_chart(
            0,
            2,
            &[
                &[],
                &[RUN[0], RUN[1]],
                &[],
                &[drive(0, true), Action::Set { var: 0, expr: bad }],
            ],
            &[on(0, 0, 1), when(1, 2, bad), on(0, 1, 3)],
        )
        .unwrap();
        route(&mut t, 0, 0, 0);
        route(&mut t, 3, 0, 1);
        t
    };
    let t = build();
    assert!(validate(&t).is_err());
    let fault = Fault::Expr { chart: 0 };

    let mut e = Engine::new(&t);
    let mut fx = Rec::default();
    e.event(0, &mut fx);
    let mut want = vec![fired(0, 0, 0, 1)];
    want.extend(RUN_TRACE);
    want.extend(safe_trace(fault));
    assert_eq!(fx.take(), want);
    assert_eq!(e.state(0), Some(1));
    assert_stays_faulted(&mut e, fault);

    let mut e = Engine::new(&t);
    e.event(3, &mut fx);
    assert_eq!(
        fx.take(),
        [
            fired(0, 2, 0, 3),
            Out { i: 0, v: true },
            Out { i: 0, v: false },
            CancelTimer { timer: 0 },
            CancelTimer { timer: 1 },
            Ev::Fault(fault),
        ]
    );
    assert_eq!(e.var(0), Some(5));
}
