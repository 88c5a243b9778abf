//! Semantic validation: each `Invalid` variant from one precise mutation of a valid table,
//! through `decode` (what a node runs) and `validate` alike.

mod common;

use common::{blob, realistic};
use config_schema::limits::*;
use config_schema::{
    decode, validate, Action, Chart, DecodeError, Expr, ExprError, Input, Invalid, Op, Output,
    Place, Publication, State, Subscription, Table, Transition,
};
use test_tables::route;

/// Applies `mutate` to the realistic table and returns the validation error, checking that
/// `decode` reports the same one.
fn invalid(mutate: impl FnOnce(&mut Table)) -> Invalid {
    let mut t = realistic();
    mutate(&mut t);
    let err = validate(&t).expect_err("the mutation must make the table invalid");
    assert_eq!(decode(&blob(&t)), Err(DecodeError::Invalid(err)));
    err
}

/// Index of the (first) transition of the realistic table's chart 0 that leaves `from` to
/// `to`.
fn transition(t: &Table, from: u8, to: u8) -> usize {
    t.transitions
        .iter()
        .position(|x| x.from == from && x.to == to)
        .unwrap()
}

#[test]
fn the_realistic_table_is_valid() {
    assert_eq!(validate(&realistic()), Ok(()));
    assert_eq!(validate(&Table::empty("empty")), Ok(()));
}

#[test]
fn capacities() {
    assert_eq!(
        invalid(|t| t.events = MAX_EVENTS as u8 + 1),
        Invalid::Capacity {
            what: "events",
            count: 65,
            max: 64
        }
    );
    assert_eq!(
        invalid(|t| t.events = 255),
        Invalid::Capacity {
            what: "events",
            count: 255,
            max: 64
        }
    );
    assert_eq!(
        invalid(|t| t.charts[1].inputs = MAX_CHART_INPUTS as u8 + 1),
        Invalid::Capacity {
            what: "chart inputs",
            count: 33,
            max: 32
        }
    );
    // Exactly at the limit is fine.
    let mut t = realistic();
    t.events = MAX_EVENTS as u8;
    t.charts[1].inputs = MAX_CHART_INPUTS as u8;
    assert_eq!(validate(&t), Ok(()));
}

#[test]
fn events_out_of_range() {
    // The realistic table has 7 events (0..=6).
    assert_eq!(
        invalid(|t| t.start = Some(7)),
        Invalid::Event {
            at: Place::Header,
            event: 7
        }
    );
    assert_eq!(
        invalid(|t| t.home = Some(8)),
        Invalid::Event {
            at: Place::Header,
            event: 8
        }
    );
    assert_eq!(
        invalid(|t| t.boot = Some(7)),
        Invalid::Event {
            at: Place::Header,
            event: 7
        }
    );
    assert_eq!(
        invalid(|t| t.inputs[1].rise = Some(9)),
        Invalid::Event {
            at: Place::Input(1),
            event: 9
        }
    );
    assert_eq!(
        invalid(|t| t.inputs[0].fall = Some(200)),
        Invalid::Event {
            at: Place::Input(0),
            event: 200
        }
    );
    assert_eq!(
        invalid(|t| t.timers[0].event = 7),
        Invalid::Event {
            at: Place::Timer(0),
            event: 7
        }
    );
    assert_eq!(
        invalid(|t| t.routes[5].event = 7),
        Invalid::Event {
            at: Place::Route(5),
            event: 7
        }
    );
    assert_eq!(
        invalid(|t| t.publications[2].event = 8),
        Invalid::Event {
            at: Place::Publication(2),
            event: 8
        }
    );
    assert_eq!(
        invalid(|t| t.subscriptions[1].event = 7),
        Invalid::Event {
            at: Place::Subscription(1),
            event: 7
        }
    );
    // One event fewer: DONE (6) is emitted, routed nowhere, published.
    let e = invalid(|t| t.events = 6);
    assert!(
        matches!(e, Invalid::Event { event: 6, .. }),
        "{e:?} must name event 6"
    );
}

#[test]
fn emitted_events_must_exist() {
    // Action 8 is S4's Emit(DONE).
    assert_eq!(realistic().actions[8], Action::Emit(6));
    assert_eq!(
        invalid(|t| t.actions[8] = Action::Emit(7)),
        Invalid::Event {
            at: Place::Action(8),
            event: 7
        }
    );
}

#[test]
fn missing_variables_timers_outputs() {
    assert_eq!(
        invalid(|t| t.inputs[1].var = Some(4)),
        Invalid::Var {
            at: Place::Input(1),
            var: 4
        }
    );
    // Action 0 is S0's `count := 0`.
    assert_eq!(
        invalid(|t| {
            let Action::Set { expr, .. } = t.actions[0] else {
                panic!("action 0 is a Set")
            };
            t.actions[0] = Action::Set { var: 4, expr };
        }),
        Invalid::Var {
            at: Place::Action(0),
            var: 4
        }
    );
    // Action 2 is S1's StartTimer; action 7 is S4's CancelTimer.
    assert_eq!(
        invalid(|t| t.actions[2] = Action::StartTimer { timer: 1, ms: 5 }),
        Invalid::Timer {
            at: Place::Action(2),
            timer: 1
        }
    );
    assert_eq!(
        invalid(|t| t.actions[7] = Action::CancelTimer(3)),
        Invalid::Timer {
            at: Place::Action(7),
            timer: 3
        }
    );
    // Two outputs: bit 2 is past them, in the mask or in the value.
    assert_eq!(
        invalid(|t| t.actions[1] = Action::Drive {
            mask: 0b111,
            value: 0b001
        }),
        Invalid::Output {
            at: Place::Action(1),
            mask: 0b111
        }
    );
    assert_eq!(
        invalid(|t| t.actions[1] = Action::Drive {
            mask: 0b001,
            value: 0b100
        }),
        Invalid::Output {
            at: Place::Action(1),
            mask: 0b101
        }
    );
}

#[test]
fn states_and_chart_inputs() {
    let t0 = realistic();
    let down = transition(&t0, 1, 2);
    // Chart 0 has 5 states, chart 1 has 2.
    assert_eq!(
        invalid(|t| t.transitions[down].to = 5),
        Invalid::State {
            at: Place::Transition(down as u8),
            state: 5
        }
    );
    assert_eq!(
        invalid(|t| t.transitions[down].from = 9),
        Invalid::State {
            at: Place::Transition(down as u8),
            state: 9
        }
    );
    // Chart 1's transition (the last) may not reach chart 0's states by local index 2.
    let last = t0.transitions.len() - 1;
    assert_eq!(
        invalid(|t| t.transitions[last].to = 2),
        Invalid::State {
            at: Place::Transition(last as u8),
            state: 2
        }
    );
    assert_eq!(
        invalid(|t| t.charts[1].initial = 2),
        Invalid::State {
            at: Place::Chart(1),
            state: 2
        }
    );
    assert_eq!(
        invalid(|t| t.charts[1].idle = 3),
        Invalid::State {
            at: Place::Chart(1),
            state: 3
        }
    );
    // Chart 1 has 2 states: state 1 may rest, state 2 is past them (in memory only: a
    // blob holds one bit a state, so the encoder refuses the mask and no blob has it).
    let mut t = realistic();
    t.charts[1].rests = 0b110;
    assert_eq!(
        validate(&t),
        Err(Invalid::State {
            at: Place::Chart(1),
            state: 2
        })
    );
    t.charts[1].rests = 0b10;
    assert_eq!(validate(&t), Ok(()));
    assert_eq!(decode(&blob(&t)).map(|d| d.charts[1].rests), Ok(0b10));
    // Chart 0 has 5 inputs.
    assert_eq!(
        invalid(|t| t.transitions[down].trigger = Some(5)),
        Invalid::ChartInput {
            at: Place::Transition(down as u8),
            input: 5
        }
    );
    assert_eq!(
        invalid(|t| t.routes[5].input = 1),
        Invalid::ChartInput {
            at: Place::Route(5),
            input: 1
        }
    );
}

#[test]
fn routes_to_missing_charts() {
    assert_eq!(
        invalid(|t| t.routes[3].chart = 2),
        Invalid::Chart {
            at: Place::Route(3),
            chart: 2
        }
    );
    assert_eq!(
        invalid(|t| t.routes[0].chart = 255),
        Invalid::Chart {
            at: Place::Route(0),
            chart: 255
        }
    );
}

#[test]
fn pool_ranges() {
    // Chart 1 owns no state.
    assert_eq!(
        invalid(|t| t.charts[1].states_end = t.charts[0].states_end),
        Invalid::Range {
            at: Place::Chart(1)
        }
    );
    // Chart 0 claims more states than there are.
    assert_eq!(
        invalid(|t| t.charts[0].states_end = 8),
        Invalid::Range {
            at: Place::Chart(0)
        }
    );
    // Chart 1's transitions end before chart 0's.
    assert_eq!(
        invalid(|t| t.charts[1].transitions_end = 2),
        Invalid::Range {
            at: Place::Chart(1)
        }
    );
    // Chart 1 claims more transitions than there are.
    assert_eq!(
        invalid(|t| t.charts[1].transitions_end = 99),
        Invalid::Range {
            at: Place::Chart(1)
        }
    );
    // A state no chart owns.
    assert_eq!(
        invalid(|t| t.states.push(State { actions_end: 9 }).unwrap()),
        Invalid::Range {
            at: Place::State(7)
        }
    );
    // A transition no chart owns.
    assert_eq!(
        invalid(|t| t
            .transitions
            .push(Transition {
                from: 0,
                to: 0,
                trigger: None,
                guard: None
            })
            .unwrap()),
        Invalid::Range {
            at: Place::Transition(7)
        }
    );
    // State 2's actions end before state 1's.
    assert_eq!(
        invalid(|t| t.states[2].actions_end = 1),
        Invalid::Range {
            at: Place::State(2)
        }
    );
    // The last state's actions end past the pool.
    assert_eq!(
        invalid(|t| t.states[6].actions_end = 99),
        Invalid::Range {
            at: Place::State(6)
        }
    );
    // An action no state owns.
    assert_eq!(
        invalid(|t| t.actions.push(Action::Fault(0)).unwrap()),
        Invalid::Range {
            at: Place::Action(11)
        }
    );
}

/// The realistic table with the guard of S4 -> S1 (event-less) replaced by `ops`.
fn with_guard(ops: &[Op]) -> Invalid {
    invalid(|t| {
        let at = transition(t, 4, 1);
        let g = t.push_expr(ops).unwrap();
        t.transitions[at].guard = Some(g);
    })
}

#[test]
fn malformed_expressions() {
    let at = Place::Transition(transition(&realistic(), 4, 1) as u8);
    let expr = |error| Invalid::Expr { at, error };
    // A guard that reads past its operands.
    assert_eq!(
        with_guard(&[Op::Const(1), Op::And]),
        expr(ExprError::Underflow { at: 1 })
    );
    assert_eq!(with_guard(&[Op::Not]), expr(ExprError::Underflow { at: 0 }));
    assert_eq!(
        with_guard(&[Op::Var(0), Op::Var(1), Op::Add, Op::Lt]),
        expr(ExprError::Underflow { at: 3 })
    );
    // One value too many on the stack.
    let mut deep = vec![Op::Const(1); MAX_STACK + 1];
    deep.extend(vec![Op::And; MAX_STACK]);
    assert_eq!(
        with_guard(&deep),
        expr(ExprError::Overflow { at: MAX_STACK })
    );
    assert_eq!(
        with_guard(&[Op::Const(1), Op::Const(2)]),
        expr(ExprError::Result { depth: 2 })
    );
    assert_eq!(
        with_guard(&[Op::Var(4)]),
        expr(ExprError::Var { at: 0, var: 4 })
    );
    assert_eq!(
        with_guard(&[Op::Const(0), Op::Input(2), Op::Or]),
        expr(ExprError::Input { at: 1, input: 2 })
    );
    let long = {
        let mut ops = vec![Op::Const(1)];
        for _ in 0..MAX_EXPR_LEN / 2 {
            ops.extend([Op::Const(1), Op::And]);
        }
        ops
    };
    assert_eq!(long.len(), MAX_EXPR_LEN + 1);
    assert_eq!(with_guard(&long), expr(ExprError::Length(MAX_EXPR_LEN + 1)));
    // A well-formed expression of exactly MAX_EXPR_LEN - 1 operations is fine.
    let mut t = realistic();
    let at = transition(&t, 4, 1);
    let g = t.push_expr(&long[..MAX_EXPR_LEN - 1]).unwrap();
    t.transitions[at].guard = Some(g);
    assert_eq!(validate(&t), Ok(()));
}

#[test]
fn expression_references_outside_the_code_pool() {
    let code_len = realistic().code.len();
    let at = transition(&realistic(), 4, 1);
    assert_eq!(
        invalid(|t| t.transitions[at].guard = Some(Expr { start: 0, len: 0 })),
        Invalid::Expr {
            at: Place::Transition(at as u8),
            error: ExprError::Length(0)
        }
    );
    assert_eq!(
        invalid(|t| t.transitions[at].guard = Some(Expr {
            start: code_len as u8 - 1,
            len: 2
        })),
        Invalid::Expr {
            at: Place::Transition(at as u8),
            error: ExprError::OutOfCode {
                end: code_len + 1,
                code_len
            }
        }
    );
    // Assignments are checked too (action 4 is S2's `count := count + 1`).
    assert_eq!(
        invalid(|t| t.actions[4] = Action::Set {
            var: 0,
            expr: Expr { start: 250, len: 9 }
        }),
        Invalid::Expr {
            at: Place::Action(4),
            error: ExprError::OutOfCode { end: 259, code_len }
        }
    );
}

#[test]
fn radio_links() {
    // Two peers: bit 2 of a subscriber mask names a third.
    assert_eq!(
        invalid(|t| t.publications[1].subscribers = 0b101),
        Invalid::Peer {
            at: Place::Publication(1),
            peer: 2
        }
    );
    assert_eq!(
        invalid(|t| t.publications[0].subscribers = 0x80),
        Invalid::Peer {
            at: Place::Publication(0),
            peer: 7
        }
    );
    assert_eq!(
        invalid(|t| t.subscriptions[0].publisher = 2),
        Invalid::Peer {
            at: Place::Subscription(0),
            peer: 2
        }
    );
    // `Publish` of an event that has no publication (action 9 is S4's Publish(VC1)).
    assert_eq!(realistic().actions[9], Action::Publish(1));
    assert_eq!(
        invalid(|t| t.actions[9] = Action::Publish(5)),
        Invalid::NotPublished {
            at: Place::Action(9),
            event: 5
        }
    );
}

#[test]
fn duplicates() {
    assert_eq!(
        invalid(|t| t.inputs[1].pin = 2),
        Invalid::Duplicate {
            at: Place::Input(1)
        }
    );
    assert_eq!(
        invalid(|t| t.outputs.push(Output::safe(10, false)).unwrap()),
        Invalid::Duplicate {
            at: Place::Output(2)
        }
    );
    // A pin is an input or an output, not both.
    assert_eq!(
        invalid(|t| t.outputs[1].pin = t.inputs[0].pin),
        Invalid::Duplicate {
            at: Place::Output(1)
        }
    );
    assert_eq!(
        invalid(|t| t.peers[1] = 0x0001),
        Invalid::Duplicate { at: Place::Peer(1) }
    );
    assert_eq!(
        invalid(|t| t.peers[0] = 0xFFFF),
        Invalid::Duplicate { at: Place::Peer(0) },
        "the broadcast address is not a peer"
    );
    // Same topic, or same event, published twice.
    assert_eq!(
        invalid(|t| t.publications[2].topic = 20),
        Invalid::Duplicate {
            at: Place::Publication(2)
        }
    );
    assert_eq!(
        invalid(|t| t.publications[2].event = 1),
        Invalid::Duplicate {
            at: Place::Publication(2)
        }
    );
    // The same (publisher, topic) subscribed twice.
    assert_eq!(
        invalid(|t| t.subscriptions[1].topic = 10),
        Invalid::Duplicate {
            at: Place::Subscription(1)
        }
    );
    // The same topic from different publishers is two subscriptions.
    let mut t = realistic();
    t.subscriptions
        .push(Subscription {
            publisher: 1,
            topic: 10,
            event: 2,
        })
        .unwrap();
    assert_eq!(validate(&t), Ok(()));
}

#[test]
fn the_first_problem_in_table_order_is_reported() {
    // A bad route and a bad transition: validation reports the transition (charts are
    // checked before routes), and a bad input before both.
    let down = transition(&realistic(), 1, 2);
    assert_eq!(
        invalid(|t| {
            t.routes[0].chart = 9;
            t.transitions[down].to = 9;
        }),
        Invalid::State {
            at: Place::Transition(down as u8),
            state: 9
        }
    );
    assert_eq!(
        invalid(|t| {
            t.routes[0].chart = 9;
            t.transitions[down].to = 9;
            t.inputs[0].var = Some(99);
        }),
        Invalid::Var {
            at: Place::Input(0),
            var: 99
        }
    );
}

#[test]
fn builders_keep_the_pools_consistent() {
    let mut t = Table::empty("a-role-name-longer-than-12");
    assert_eq!(t.header.role.as_str(), "a-role-name-");
    let e = t.push_event().unwrap();
    let g = t.push_expr(&[Op::Input(0)]).unwrap();
    t.inputs
        .push(Input {
            pin: 1,
            rise: Some(e),
            fall: None,
            var: None,
        })
        .unwrap();
    let c = t
        .push_chart(
            0,
            1,
            &[&[], &[Action::Fault(1)]],
            &[Transition {
                from: 0,
                to: 1,
                trigger: Some(0),
                guard: Some(g),
            }],
        )
        .unwrap();
    route(&mut t, e, c, 0);
    assert_eq!(validate(&t), Ok(()));
    assert_eq!(
        t.charts[0],
        Chart {
            states_end: 2,
            transitions_end: 1,
            inputs: 1,
            initial: 0,
            idle: 0,
            rests: 0
        }
    );
    assert_eq!(t.chart_states(0), 0..2);
    assert_eq!(t.state_actions(1), 0..1);
    assert_eq!(t.publication(e), None);
    t.peers.push(1).unwrap();
    t.publications
        .push(Publication {
            event: e,
            topic: 1,
            subscribers: 1,
        })
        .unwrap();
    assert_eq!(t.publication(e).map(|p| p.topic), Some(1));
    // Events stop at MAX_EVENTS.
    while t.push_event().is_ok() {}
    assert_eq!(usize::from(t.events), MAX_EVENTS);
    // A chart that does not fit leaves the pools as they were.
    let before = t.clone();
    let many: Vec<&[Action]> = vec![&[]; MAX_STATES];
    assert!(t.push_chart(0, 0, &many, &[]).is_err());
    assert_eq!(t, before);
}

#[test]
fn pins_past_the_bitmap_are_refused_so_no_pin_aliases_another() {
    // Pin 64 would be bit 0 of the node's pin levels, pin 200 bit 8.
    assert_eq!(
        invalid(|t| t.inputs[1].pin = 64),
        Invalid::Pin {
            at: Place::Input(1),
            pin: 64
        }
    );
    assert_eq!(
        invalid(|t| t.outputs[0].pin = 200),
        Invalid::Pin {
            at: Place::Output(0),
            pin: 200
        }
    );
    assert_eq!(
        Invalid::Pin {
            at: Place::Input(1),
            pin: 64
        }
        .to_string(),
        "input #1: pin 64 is out of range (0..=63)"
    );
    let mut t = realistic();
    t.inputs[0].pin = (MAX_PINS - 1) as u8;
    assert_eq!(validate(&t), Ok(()), "pin 63 is the last one");
}

#[test]
fn missing_pin_names_the_first_pin_a_board_lacks() {
    let t = realistic();
    assert_eq!(t.missing_pin(u64::MAX), None);
    let used = t
        .inputs
        .iter()
        .map(|i| i.pin)
        .chain(t.outputs.iter().map(|o| o.pin));
    let mask = used.fold(0u64, |m, p| m | 1 << p);
    assert_eq!(t.missing_pin(mask), None);
    let last_output = t.outputs.last().unwrap().pin;
    assert_eq!(t.missing_pin(mask & !(1 << last_output)), Some(last_output));
    assert_eq!(t.missing_pin(0), Some(t.inputs[0].pin));
    let mut wide = t.clone();
    wide.outputs[0].pin = 64;
    assert_eq!(wide.missing_pin(u64::MAX), Some(64), "no board has pin 64");
}
