//! Tables and blob helpers shared by the config-schema tests.
#![allow(dead_code)]

#[allow(unused_imports)]
pub use test_tables::{blob, payload, route, seal};

use config_schema::{
    Action, Input, Op, Output, Publication, Subscription, Table, Timer, Transition,
};

/// A realistic role: the vertical cylinder (VC) of the painting robot, in the paper's
/// position-event style, plus a small motion-timeout supervisor chart.
///
/// Events: 0 = VC0 (home switch rise), 1 = VC1 (end switch rise), 2 = GO_UP (remote, from
/// the sequencer peer), 3 = GO_DOWN (remote), 4 = TIMEOUT (timer 0), 5 = START, 6 = DONE
/// (emitted, published).
pub fn realistic() -> Table {
    let mut t = Table::empty("VC");
    t.generation = 0x0102_0304;
    t.header.pan_id = 0xBEEF;
    t.header.channel = 15;
    for _ in 0..7 {
        t.push_event().unwrap();
    }
    t.start = Some(5);
    // var 0: cycle count, var 1: VC0 mirror, var 2: VC1 mirror, var 3: limit M.
    t.vars.extend_from_slice(&[0, 0, 0, 2]).unwrap();
    t.inputs
        .push(Input {
            pin: 2,
            rise: Some(0),
            fall: None,
            var: Some(1),
        })
        .unwrap();
    t.inputs
        .push(Input {
            pin: 3,
            rise: Some(1),
            fall: None,
            var: Some(2),
        })
        .unwrap();
    t.outputs.push(Output::safe(10, false)).unwrap();
    t.outputs.push(Output::safe(11, true)).unwrap();
    t.timers.push(Timer { event: 4 }).unwrap();

    let at_home = t.push_expr(&[Op::Var(1)]).unwrap();
    let below_m = t
        .push_expr(&[
            Op::Var(0),
            Op::Var(3),
            Op::Lt,
            Op::Input(1),
            Op::Not,
            Op::And,
        ])
        .unwrap();
    let inc = t.push_expr(&[Op::Var(0), Op::Const(1), Op::Add]).unwrap();
    let zero = t.push_expr(&[Op::Const(0)]).unwrap();

    // Chart 0, inputs: 0 = START, 1 = GO_UP, 2 = GO_DOWN, 3 = VC0, 4 = VC1.
    // S0 idle -START [at home]-> S1 down -VC1-> S2 bottom [count++] -GO_UP-> S3 up
    // -VC0-> S4 top [emit DONE] -> S1 if count < M && !in1, S4 -GO_DOWN-> S1, S4 -> S0.
    let extend = Action::Drive {
        mask: 0b11,
        value: 0b01,
    };
    let retract = Action::Drive {
        mask: 0b11,
        value: 0b10,
    };
    t.push_chart(
        0,
        5,
        &[
            &[Action::Set { var: 0, expr: zero }],
            &[extend, Action::StartTimer { timer: 0, ms: 1500 }],
            &[Action::CancelTimer(0), Action::Set { var: 0, expr: inc }],
            &[retract, Action::StartTimer { timer: 0, ms: 1500 }],
            &[Action::CancelTimer(0), Action::Emit(6), Action::Publish(1)],
        ],
        &[
            Transition {
                from: 0,
                to: 1,
                trigger: Some(0),
                guard: Some(at_home),
            },
            Transition {
                from: 1,
                to: 2,
                trigger: Some(4),
                guard: None,
            },
            Transition {
                from: 2,
                to: 3,
                trigger: Some(1),
                guard: None,
            },
            Transition {
                from: 3,
                to: 4,
                trigger: Some(3),
                guard: None,
            },
            Transition {
                from: 4,
                to: 1,
                trigger: None,
                guard: Some(below_m),
            },
            Transition {
                from: 4,
                to: 1,
                trigger: Some(2),
                guard: None,
            },
        ],
    )
    .unwrap();
    // Chart 1: timeout supervisor, input 0 = TIMEOUT: S0 -TIMEOUT-> S1 [fault 1].
    t.push_chart(
        0,
        1,
        &[&[], &[Action::Fault(1)]],
        &[Transition {
            from: 0,
            to: 1,
            trigger: Some(0),
            guard: None,
        }],
    )
    .unwrap();
    for (event, chart, input) in [
        (5, 0, 0),
        (2, 0, 1),
        (3, 0, 2),
        (0, 0, 3),
        (1, 0, 4),
        (4, 1, 0),
    ] {
        route(&mut t, event, chart, input);
    }
    t.peers.extend_from_slice(&[0x0001, 0x0003]).unwrap();
    for (event, topic, subscribers) in [(0, 20, 0b01), (1, 21, 0b11), (6, 22, 0b10)] {
        t.publications
            .push(Publication {
                event,
                topic,
                subscribers,
            })
            .unwrap();
    }
    for (publisher, topic, event) in [(0, 10, 2), (0, 11, 3)] {
        t.subscriptions
            .push(Subscription {
                publisher,
                topic,
                event,
            })
            .unwrap();
    }
    t
}
