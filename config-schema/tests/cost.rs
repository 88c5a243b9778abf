//! The worst-case work of one stimulus (`config_schema::cost`): exact figures for small
//! tables, the cascade and chain bounds, and the table of issue 16 (a START that cost half a
//! billion instructions) refused by `validate`, saying by how much.

mod common;

use config_schema::cost::{weights as w, worst_stimulus, Worst, STIMULUS_BUDGET};
use config_schema::limits::{MAX_CASCADE, MAX_CHAIN};
use config_schema::{validate, Action, Input, Invalid, Op, Output, Publication, Table, Transition};

fn on(from: u8, to: u8, trigger: Option<u8>) -> Transition {
    Transition {
        from,
        to,
        trigger,
        guard: None,
    }
}

/// One chart: S0 -(in0)[3-op guard]-> S1, which drives two outputs; e0 routed to it.
fn small() -> Table {
    let mut t = Table::empty("r");
    let e0 = t.push_event().unwrap();
    t.inputs
        .push(Input {
            pin: 3,
            rise: None,
            fall: None,
            var: None,
        })
        .unwrap();
    t.outputs.push(Output::safe(1, false)).unwrap();
    t.outputs.push(Output::safe(2, false)).unwrap();
    let g = t.push_expr(&[Op::Input(0), Op::Not, Op::Not]).unwrap();
    let mut tr = on(0, 1, Some(0));
    tr.guard = Some(g);
    let drive = Action::Drive {
        mask: 0b11,
        value: 0b01,
    };
    t.push_chart(0, 1, &[&[], &[drive]], &[tr]).unwrap();
    common::route(&mut t, e0, 0, 0);
    t
}

#[test]
fn a_small_table_costs_exactly_its_dispatch() {
    let t = small();
    let select = w::TRANSITION + 3 * w::OP;
    let fire = w::FIRE + w::ACTION + 2 * w::PIN;
    let dispatch = w::EVENT + w::ROUTE + w::DELIVER + select + fire;
    assert_eq!(
        worst_stimulus(&t),
        Worst {
            cost: w::STIMULUS + dispatch,
            event: 0,
            cascade: 1
        }
    );
    assert_eq!(validate(&t), Ok(()));
}

/// A published stimulus pays a frame per subscriber.
#[test]
fn each_frame_of_a_publication_is_counted() {
    let mut t = small();
    t.peers.extend_from_slice(&[0x11, 0x12]).unwrap();
    t.publications
        .push(Publication {
            event: 0,
            topic: 1,
            subscribers: 0b11,
        })
        .unwrap();
    let before = worst_stimulus(&small()).cost;
    assert_eq!(worst_stimulus(&t).cost, before + 2 * w::FRAME);
}

/// A chart whose state emits the event that brought it there: the whole cascade.
#[test]
fn an_emit_cycle_counts_as_the_whole_cascade() {
    let mut t = Table::empty("r");
    let e0 = t.push_event().unwrap();
    t.push_chart(0, 1, &[&[Action::Emit(e0)]], &[on(0, 0, Some(0))])
        .unwrap();
    common::route(&mut t, e0, 0, 0);
    let worst = worst_stimulus(&t);
    let dispatch = w::EVENT + w::ROUTE + w::DELIVER + w::TRANSITION + w::FIRE + w::ACTION;
    assert_eq!(worst.cascade, MAX_CASCADE as u32);
    assert_eq!(worst.cost, w::STIMULUS + MAX_CASCADE as u64 * dispatch);
}

/// Event-less transitions: a path of two counts two fires; a cycle counts `MAX_CHAIN`.
#[test]
fn an_eventless_chain_counts_its_longest_path_or_the_chain_limit() {
    let chain = |back: bool| {
        let mut t = Table::empty("r");
        let e0 = t.push_event().unwrap();
        let mut transitions = vec![on(0, 1, Some(0)), on(1, 2, None), on(2, 3, None)];
        if back {
            transitions.push(on(3, 1, None));
        }
        t.push_chart(0, 1, &[&[], &[], &[], &[]], &transitions)
            .unwrap();
        common::route(&mut t, e0, 0, 0);
        worst_stimulus(&t).cost
    };
    let select = |n: u64| n * w::TRANSITION;
    let base = w::STIMULUS + w::EVENT + w::ROUTE + w::DELIVER;
    // Three transitions: the triggered fire, two event-less ones, the select that finds none.
    assert_eq!(chain(false), base + 3 * (select(3) + w::FIRE) + select(3));
    let cycle = 1 + MAX_CHAIN as u64;
    assert_eq!(
        chain(true),
        base + cycle * (select(4) + w::FIRE) + select(4)
    );
}

/// Issue 16's table: 124 transitions with long guards that never hold, 94 routes of one
/// event, a cascade through a chart that emits: one START cost 512 million instructions on
/// the QEMU Cortex-M3. `validate` (so `decode`, on the node) refuses it and says by how much.
#[test]
fn the_table_of_half_a_billion_instructions_is_refused() {
    let mut t = Table::empty("r");
    let start = t.push_event().unwrap();
    t.start = Some(start);
    let mut ops = vec![Op::Const(0)];
    for _ in 0..15 {
        ops.extend([Op::Const(0), Op::Or]);
    }
    let n = ops.len() as u64;
    assert_eq!(n, 31);
    let never = t.push_expr(&ops).unwrap();
    let mut transitions: Vec<Transition> = (0..123)
        .map(|_| Transition {
            guard: Some(never),
            ..on(0, 1, Some(0))
        })
        .collect();
    transitions.push(on(0, 0, Some(0)));
    t.push_chart(0, 1, &[&[Action::Emit(start)], &[]], &transitions)
        .unwrap();
    for _ in 0..94 {
        common::route(&mut t, start, 0, 0);
    }
    let worst = worst_stimulus(&t);
    assert_eq!(worst.cascade, MAX_CASCADE as u32);
    let select = 123 * (w::TRANSITION + n * w::OP) + w::TRANSITION;
    let deliver = w::DELIVER + select + w::FIRE + w::ACTION;
    let dispatch = w::EVENT + 94 * w::ROUTE + 94 * deliver;
    assert_eq!(worst.cost, w::STIMULUS + MAX_CASCADE as u64 * dispatch);
    let refused = validate(&t).unwrap_err();
    assert_eq!(
        refused,
        Invalid::Slow {
            event: start,
            cost: worst.cost,
            budget: STIMULUS_BUDGET
        }
    );
    assert_eq!(
        refused.to_string(),
        format!(
            "a stimulus of event 0 may cost {} instructions, over the budget of 64000 (1 ms \
             at 64 MHz) by {}",
            worst.cost,
            worst.cost - 64_000
        )
    );
}
