//! An engine snapshotted after every stimulus and resumed behaves exactly like one that ran
//! uninterrupted (what the runtime does when it owns its table, and what the verifier hashes).

use config_schema::{Action, Op, Output, Table, Transition};
use node_fw::ecc::{Effects, Engine};
use test_tables::route;

#[derive(Default, Debug, PartialEq)]
struct Rec(Vec<String>);

impl Effects for Rec {
    fn output(&mut self, o: u8, v: bool) {
        self.0.push(format!("out{o}={v}"));
    }
    fn fired(&mut self, c: u8, t: u8, from: u8, to: u8) {
        self.0.push(format!("c{c} t{t} {from}->{to}"));
    }
    fn fault(&mut self, f: node_fw::ecc::Fault) {
        self.0.push(format!("{f:?}"));
    }
}

/// A toggle that counts its presses and faults on the fourth.
fn toggle() -> Table {
    let mut t = Table::empty("T");
    let press = t.push_event().unwrap();
    t.vars.push(0).unwrap();
    t.outputs.push(Output::safe(1, false)).unwrap();
    let inc = t.push_expr(&[Op::Var(0), Op::Const(1), Op::Add]).unwrap();
    let too_many = t.push_expr(&[Op::Var(0), Op::Const(4), Op::Ge]).unwrap();
    let on: &[Action] = &[
        Action::Drive { mask: 1, value: 1 },
        Action::Set { var: 0, expr: inc },
    ];
    let off: &[Action] = &[
        Action::Drive { mask: 1, value: 0 },
        Action::Set { var: 0, expr: inc },
    ];
    let fault: &[Action] = &[Action::Fault(9)];
    let tr = |from, to, trigger, guard| Transition {
        from,
        to,
        trigger,
        guard,
    };
    t.push_chart(
        0,
        1,
        &[off, on, fault],
        &[
            tr(0, 2, None, Some(too_many)),
            tr(1, 2, None, Some(too_many)),
            tr(0, 1, Some(0), None),
            tr(1, 0, Some(0), None),
        ],
    )
    .unwrap();
    route(&mut t, press, 0, 0);
    config_schema::validate(&t).unwrap();
    t
}

#[test]
fn snapshot_and_resume_after_every_stimulus_changes_nothing() {
    let table = toggle();
    let mut whole = Rec::default();
    let mut engine = Engine::new(&table);
    for _ in 0..6 {
        engine.event(0, &mut whole);
    }
    let mut pieces = Rec::default();
    let mut state = Engine::new(&table).snapshot();
    for _ in 0..6 {
        let mut e = Engine::resume(&table, &state);
        e.event(0, &mut pieces);
        state = e.snapshot();
    }
    assert_eq!(pieces, whole);
    assert_eq!(state, engine.snapshot());
    assert_eq!(
        whole.0,
        [
            "c0 t2 0->1",
            "out0=true",
            "c0 t3 1->0",
            "out0=false",
            "c0 t2 0->1",
            "out0=true",
            "c0 t3 1->0",
            "out0=false",
            "c0 t0 0->2",
            "Action { chart: 0, code: 9 }",
        ]
    );
    assert_eq!(state.vars[0], 4);
    assert!(state.fault.is_some());
}
