//! The latching rules, on a table of two inputs: input 0 the emergency stop, input 1 the
//! cause of a declared fault alarm, input 2 of a declared warning.

extern crate std;
use std::vec::Vec;

use config_schema::alarm::{AlarmDecl, AlarmLevel, AlarmSource, MAX_ALARMS};
use config_schema::{Input, Op, Table};

use super::{Alarms, Reads, Seen, Watch};
use crate::ecc::{EngineState, Fault};

fn table() -> Table {
    let mut t = Table::empty("r");
    for pin in 0..3 {
        let input = Input {
            pin,
            rise: None,
            fall: None,
            var: None,
        };
        t.inputs.push(input).unwrap();
    }
    t.safety.estop = Some(0);
    for (input, level) in [(1, AlarmLevel::Fault), (2, AlarmLevel::Warning)] {
        let when = t.push_expr(&[Op::Input(input)]).unwrap();
        t.safety.alarms.push(AlarmDecl { level, when }).unwrap();
    }
    t
}

fn state(inputs: u16, fault: Option<Fault>) -> EngineState {
    EngineState {
        current: [0; 8],
        vars: [0; 32],
        inputs,
        outputs: 0,
        fault,
    }
}

fn look(a: &mut Alarms, t: &Table, s: &EngineState, links: u8, now: u64) {
    a.observe(
        Seen {
            table: t,
            state: s,
            link_alarms: links,
        },
        now,
    );
}

fn seen<'a>(t: &'a Table, s: &'a EngineState) -> Seen<'a> {
    Seen {
        table: t,
        state: s,
        link_alarms: 0,
    }
}

/// (source, level, raised, acked, persists) of every alarm.
fn listed(
    a: &Alarms,
    t: &Table,
    s: &EngineState,
) -> Vec<(AlarmSource, AlarmLevel, u32, bool, bool)> {
    let r = a.report(7, Some(seen(t, s)), 0);
    assert_eq!(r.ack, 7);
    r.alarms
        .iter()
        .map(|a| (a.source, a.level, a.raised_ms, a.acked, a.persists))
        .collect()
}

const DECLARED: AlarmSource = AlarmSource::Declared { index: 0 };

#[test]
fn a_declared_alarm_latches_once_and_is_refused_an_ack_while_its_cause_persists() {
    let (t, mut a) = (table(), Alarms::default());
    look(&mut a, &t, &state(0, None), 0, 10);
    assert!(a.list().is_empty());
    let on = state(0b010, None);
    look(&mut a, &t, &on, 0, 20);
    look(&mut a, &t, &on, 0, 30);
    assert_eq!(
        listed(&a, &t, &on),
        [(DECLARED, AlarmLevel::Fault, 20, false, true)]
    );
    assert!(a.blocking().is_some());
    assert_eq!(a.ack(seen(&t, &on)), 0);
    assert_eq!(
        listed(&a, &t, &on),
        [(DECLARED, AlarmLevel::Fault, 20, false, true)]
    );

    // The cause goes: still latched until acknowledged, then acknowledged.
    let off = state(0, None);
    look(&mut a, &t, &off, 0, 40);
    assert_eq!(
        listed(&a, &t, &off),
        [(DECLARED, AlarmLevel::Fault, 20, false, false)]
    );
    assert!(a.blocking().is_some());
    assert_eq!(a.ack(seen(&t, &off)), 1);
    assert_eq!(
        listed(&a, &t, &off),
        [(DECLARED, AlarmLevel::Fault, 20, true, false)]
    );
    assert_eq!(a.blocking(), None);

    // It rises again: a new alarm, whose cause persists (the first's ended at 40).
    look(&mut a, &t, &on, 0, 50);
    assert_eq!(
        listed(&a, &t, &on),
        [
            (DECLARED, AlarmLevel::Fault, 20, true, false),
            (DECLARED, AlarmLevel::Fault, 50, false, true)
        ]
    );
}

#[test]
fn a_warning_is_acknowledged_while_its_cause_persists_and_does_not_block() {
    let (t, mut a) = (table(), Alarms::default());
    let on = state(0b100, None);
    look(&mut a, &t, &on, 0, 5);
    let warning = AlarmSource::Declared { index: 1 };
    assert_eq!(
        listed(&a, &t, &on),
        [(warning, AlarmLevel::Warning, 5, false, true)]
    );
    assert_eq!(a.blocking(), None);
    assert_eq!(a.ack(seen(&t, &on)), 1);
    assert_eq!(
        listed(&a, &t, &on),
        [(warning, AlarmLevel::Warning, 5, true, true)]
    );
}

#[test]
fn the_estop_is_one_fault_alarm_that_persists_while_pressed() {
    let (t, mut a) = (table(), Alarms::default());
    // Pressed: the node faults in the same stimulus (its e-stop chart); one alarm.
    let fault = Some(Fault::Action { chart: 2, code: 3 });
    let pressed = state(0b001, fault);
    look(&mut a, &t, &pressed, 0, 100);
    let estop = (AlarmSource::EStop, AlarmLevel::Fault, 100, false, true);
    assert_eq!(listed(&a, &t, &pressed), [estop]);
    assert_eq!(a.ack(seen(&t, &pressed)), 0);
    // Released, still faulted: the e-stop's cause is gone.
    let released = state(0, fault);
    look(&mut a, &t, &released, 0, 200);
    assert_eq!(a.ack(seen(&t, &released)), 1);
    assert_eq!(a.blocking(), None);
}

#[test]
fn a_chart_fault_raises_a_fault_alarm_until_the_reset() {
    let (t, mut a) = (table(), Alarms::default());
    let faulted = state(0, Some(Fault::Action { chart: 1, code: 1 }));
    look(&mut a, &t, &faulted, 0, 2460);
    let source = AlarmSource::Chart {
        chart: 1,
        code: 0x81,
    };
    assert_eq!(
        listed(&a, &t, &faulted),
        [(source, AlarmLevel::Fault, 2460, false, true)]
    );
    assert_eq!(a.ack(seen(&t, &faulted)), 0);
    let reset = state(0, None);
    look(&mut a, &t, &reset, 0, 3000);
    assert_eq!(a.ack(seen(&t, &reset)), 1);
    assert_eq!(
        listed(&a, &t, &reset),
        [(source, AlarmLevel::Fault, 2460, true, false)]
    );
    // The interpreter's own bounds name no chart.
    look(
        &mut a,
        &t,
        &state(0, Some(Fault::QueueFull { event: 3 })),
        0,
        4000,
    );
    assert_eq!(
        a.list()[1].source,
        AlarmSource::Chart {
            chart: super::NO_CHART,
            code: 2
        }
    );
}

/// A fault not acknowledged, a reset, then another fault of another code: the first
/// alarm's cause ended with the reset. It showed `cause persists` and was refused an ack
/// (the node was faulted again, by another cause).
#[test]
fn a_fault_alarm_ends_with_its_reset_whatever_the_next_faults_code() {
    let (t, mut a) = (table(), Alarms::default());
    let first = AlarmSource::Chart {
        chart: 1,
        code: 0x81,
    };
    let second = AlarmSource::Chart {
        chart: 2,
        code: 0x82,
    };
    look(
        &mut a,
        &t,
        &state(0, Some(Fault::Action { chart: 1, code: 1 })),
        0,
        100,
    );
    look(&mut a, &t, &state(0, None), 0, 200);
    let again = state(0, Some(Fault::Action { chart: 2, code: 2 }));
    look(&mut a, &t, &again, 0, 300);
    assert_eq!(
        listed(&a, &t, &again),
        [
            (first, AlarmLevel::Fault, 100, false, false),
            (second, AlarmLevel::Fault, 300, false, true)
        ]
    );
    assert_eq!(a.ack(seen(&t, &again)), 1);
    assert_eq!(
        listed(&a, &t, &again),
        [
            (first, AlarmLevel::Fault, 100, true, false),
            (second, AlarmLevel::Fault, 300, false, true)
        ]
    );
}

#[test]
fn a_link_alarm_is_a_warning_or_with_link_fault_a_fault() {
    let mut t = table();
    let mut a = Alarms::default();
    let s = state(0, None);
    look(&mut a, &t, &s, 0b100, 1);
    assert_eq!(a.list()[0].source, AlarmSource::Link { peer: 2 });
    assert_eq!(a.list()[0].level, AlarmLevel::Warning);
    t.safety.link_fault = true;
    look(&mut a, &t, &s, 0b101, 2);
    assert_eq!(a.list()[1].source, AlarmSource::Link { peer: 0 });
    assert_eq!(a.list()[1].level, AlarmLevel::Fault);
    // Fault alarm on peer 0 persists while its link is in alarm.
    assert_eq!(
        a.ack(Seen {
            table: &t,
            state: &s,
            link_alarms: 0b001
        }),
        1
    );
    assert!(a.blocking().is_some());
}

#[test]
fn a_full_list_keeps_the_oldest_fault_alarms_and_counts_the_dropped() {
    let (t, mut a) = (table(), Alarms::default());
    let s = state(0, None);
    // A warning (link 7), then fault alarms from links 0..: with link_fault off they are
    // warnings, so raise faults through chart faults and resets instead.
    look(&mut a, &t, &s, 0b1000_0000, 0);
    for i in 0..MAX_ALARMS as u8 {
        let f = state(0, Some(Fault::Action { chart: i, code: i }));
        look(&mut a, &t, &f, 0b1000_0000, 10 + u64::from(i));
        look(&mut a, &t, &s, 0b1000_0000, 10 + u64::from(i));
    }
    // The warning made room for the eighth fault; the ninth is dropped.
    let f = state(0, Some(Fault::Action { chart: 9, code: 9 }));
    look(&mut a, &t, &f, 0b1000_0000, 99);
    assert_eq!(a.list().len(), MAX_ALARMS);
    assert!(a.list().iter().all(|x| x.level == AlarmLevel::Fault));
    let times: Vec<u32> = a.list().iter().map(|x| x.raised_ms).collect();
    assert_eq!(times, [10, 11, 12, 13, 14, 15, 16, 17]);
    assert_eq!(a.dropped(), 1);
    assert_eq!(a.report(0, None, 0).dropped, 1);
    // Acknowledged alarms make room first.
    assert_eq!(a.ack(seen(&t, &s)), MAX_ALARMS);
    look(&mut a, &t, &s, 0b1100_0000, 120);
    assert_eq!(a.list().len(), MAX_ALARMS);
    assert_eq!(a.list()[0].raised_ms, 11);
    assert_eq!(
        a.list()[MAX_ALARMS - 1].source,
        AlarmSource::Link { peer: 6 }
    );
}

#[test]
fn garbage_conditions_never_hold() {
    let mut t = table();
    // A condition past the code pool (a table that skipped validation).
    t.safety.alarms[0].when.start = 200;
    let mut a = Alarms::default();
    look(&mut a, &t, &state(0xFFFF, None), 0xFF, 0);
    assert!(a.list().iter().all(|x| x.source != DECLARED));
}

/// A look told the state did not change compares the links only: the node core must say
/// when it wrote the state (a declared cause that rose unseen is raised at the next look
/// that is told).
#[test]
fn a_look_without_a_state_change_compares_the_links_only() {
    let (t, mut a) = (table(), Alarms::default());
    // The first look after a table reads everything, whatever it is told.
    assert_eq!(a.look(seen(&t, &state(0b010, None)), 5, false), 1);
    assert_eq!(a.list()[0].source, DECLARED);
    let warned = state(0b110, None);
    assert_eq!(a.look(seen(&t, &warned), 6, false), 0);
    let links = Seen {
        link_alarms: 0b1,
        ..seen(&t, &warned)
    };
    assert_eq!(a.look(links, 7, false), 1);
    assert_eq!(a.list()[1].source, AlarmSource::Link { peer: 0 });
    assert_eq!(a.look(links, 8, true), 1);
    let source = AlarmSource::Declared { index: 1 };
    assert_eq!((a.list()[2].source, a.list()[2].raised_ms), (source, 8));
    // A new table: its causes are read afresh at the next look (the declared fault alarm,
    // still latched, is the same alarm; the acknowledged link and warning rise anew).
    a.new_table();
    assert_eq!(a.ack(links), 2);
    assert_eq!(a.look(links, 9, false), 2);
    assert_eq!(a.list().len(), 5);
}

/// What a stimulus that runs the engine in place tells the look: on a table without
/// declared alarms only the fault and the emergency stop's input are read, so another
/// input's edge is no change; with declared alarms every stimulus is one.
#[test]
fn only_the_fault_and_the_estop_input_are_a_change_without_declared_alarms() {
    let mut t = table();
    t.safety.alarms.clear();
    let idle = state(0b000, None);
    let watch = Watch::of(&t);
    let reads = Reads::of(watch, &idle);
    assert!(!reads.changed(watch, &state(0b110, None)));
    assert!(reads.changed(watch, &state(0b001, None)));
    assert!(reads.changed(watch, &state(0b000, Some(Fault::Expr { chart: 0 }))));
    t.safety.estop = None;
    let watch = Watch::of(&t);
    assert!(!Reads::of(watch, &idle).changed(watch, &state(0b111, None)));
    let watch = Watch::of(&table());
    assert!(Reads::of(watch, &idle).changed(watch, &idle));
}

mod props {
    use super::*;
    use proptest::prelude::*;

    /// One stimulus: the e-stop and declared causes (inputs 0..3), variable 0 (a declared
    /// cause over 1), the state of chart 0 (read by no alarm), a chart fault, the links in
    /// alarm, whether the operator acknowledges after it.
    fn step() -> impl Strategy<Value = (u16, i32, u8, Option<u8>, u8, bool)> {
        (
            0u16..8,
            0i32..3,
            0u8..3,
            proptest::option::of(0u8..3),
            0u8..16,
            any::<bool>(),
        )
    }

    /// Whether an engine state `now` changed what the alarms read since `before`: the
    /// inputs and the fault; the table's variables too if it declares alarms (their
    /// conditions read inputs and variables). The first proptest's notion of a change,
    /// exact in the variables, where the node core's [`Reads`] takes every stimulus of a
    /// table that declares alarms as one (and compares the e-stop's input only).
    fn reads_changed(table: &Table, before: &EngineState, now: &EngineState) -> bool {
        before.fault != now.fault
            || before.inputs != now.inputs
            || (!table.safety.alarms.is_empty()
                && (before.vars.iter().take(table.vars.len()))
                    .zip(&now.vars)
                    .any(|(x, y)| x != y))
    }

    /// After one stimulus: a look at everything (`full`) and the node core's look told
    /// `changed` (`lean`) give the same count, list and drops, and the same count to an
    /// acknowledgement if the operator gives one (`ack`).
    fn same_alarms(
        full: &mut Alarms,
        lean: &mut Alarms,
        seen: Seen<'_>,
        now: u64,
        changed: bool,
        ack: bool,
    ) -> Result<(), TestCaseError> {
        prop_assert_eq!(full.observe(seen, now), lean.look(seen, now, changed));
        prop_assert_eq!(full.list(), lean.list());
        prop_assert_eq!(full.dropped(), lean.dropped());
        if ack {
            prop_assert_eq!(full.ack(seen), lean.ack(seen));
        }
        Ok(())
    }

    proptest! {
        /// The node core's look (told whether the state changed) raises exactly the alarms
        /// of a look at everything after every stimulus, at the same moments, and returns
        /// the same counts: a missed or an extra alarm fails here.
        #[test]
        fn looking_only_at_what_changed_raises_the_same_alarms(
            steps in proptest::collection::vec(step(), 1..60),
        ) {
            let mut t = table();
            t.vars.push(0).unwrap();
            let when = t.push_expr(&[Op::Var(0), Op::Const(1), Op::Gt]).unwrap();
            let level = AlarmLevel::Warning;
            t.safety.alarms.push(AlarmDecl { level, when }).unwrap();
            let (mut full, mut lean) = (Alarms::default(), Alarms::default());
            let mut before: Option<EngineState> = None;
            for (now, (inputs, var, chart, fault, links, ack)) in steps.into_iter().enumerate() {
                let fault = fault.map(|c| Fault::Action { chart: c, code: c });
                let mut s = state(inputs, fault);
                (s.vars[0], s.current[0]) = (var, chart);
                // What the node core tells the look.
                let changed = before.as_ref().is_none_or(|b| reads_changed(&t, b, &s));
                let seen = Seen { table: &t, state: &s, link_alarms: links };
                same_alarms(&mut full, &mut lean, seen, now as u64, changed, ack)?;
                before = Some(s);
            }
        }

        /// The same with the node core's own [`Reads`] taken before each stimulus, on a
        /// table with or without declared alarms: every input (the e-stop's and the
        /// others) and the fault may change at each step.
        #[test]
        fn the_node_cores_reads_raise_the_same_alarms(
            declared in any::<bool>(),
            steps in proptest::collection::vec(step(), 1..60),
        ) {
            let mut t = table();
            if !declared {
                t.safety.alarms.clear();
            }
            let (mut full, mut lean) = (Alarms::default(), Alarms::default());
            let watch = Watch::of(&t);
            let mut before: Option<Reads> = None;
            for (now, (inputs, _, _, fault, links, ack)) in steps.into_iter().enumerate() {
                let fault = fault.map(|c| Fault::Action { chart: c, code: c });
                let s = state(inputs, fault);
                let changed = before.is_none_or(|b| b.changed(watch, &s));
                let seen = Seen { table: &t, state: &s, link_alarms: links };
                same_alarms(&mut full, &mut lean, seen, now as u64, changed, ack)?;
                before = Some(Reads::of(watch, &s));
            }
        }
    }
}
