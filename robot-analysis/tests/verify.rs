//! `config-tool verify`: every robot of `robot-configs/` explored exhaustively, and broken
//! robots each caught by the right property with its shortest counterexample.

use robot_analysis::verify::{self, ExploreOptions, Property, Report};
use robot_compiler::{compile, Compiled, Source};

mod common;
use common::{build, load};

fn run(c: &Compiled, lossy: bool) -> Report {
    verify::verify(
        c,
        ExploreOptions {
            lossy,
            ..ExploreOptions::default()
        },
    )
    .expect("model builds")
}

fn run_prompt(c: &Compiled) -> Report {
    verify::verify(
        c,
        ExploreOptions {
            prompt: true,
            ..ExploreOptions::default()
        },
    )
    .expect("model builds")
}

/// Every file of `robot-configs/` passes when the radio is faster than any motion (the
/// simulator's and a healthy link's case); the sequence robots also pass with any delays
/// (below).
#[test]
fn every_robot_of_robot_configs_passes_with_a_prompt_radio() {
    let files = common::robot_configs();
    let mut counts = Vec::new();
    for f in &files {
        let c = build(&load(&format!("../robot-configs/{f}")));
        // The verifier models actuators, not the motors and contacts a robot declares as
        // `plants` (the water-jet transport): those are simulated, not explored, here.
        if !c.robot.plants.is_empty() {
            continue;
        }
        let r = run_prompt(&c);
        assert!(r.ok(), "{f}: {}", r.render(f, 0));
        counts.push((f.as_str(), r.states));
    }
    assert_eq!(
        counts,
        [
            // Every colour sequence of up to 4 balls (verify_sorter.rs).
            ("ball-sorter.ron", 4139),
            // The paper's charts, brought as a 4diac application: the same tables.
            ("paint-robot-4diac.ron", 87),
            ("paint-robot-counted.ron", 125),
            ("paint-robot-double-dip.ron", 376),
            ("paint-robot-paper-charts.ron", 87),
            ("paint-robot-spare-node.ron", 276),
            ("paint-robot-start-on-gr.ron", 280),
            ("paint-robot.ron", 276),
        ]
    );
}

/// (states, transitions, idle states, stopped states) of a report that passed.
fn passes(r: &Report) -> (usize, usize, usize, usize) {
    assert!(r.ok(), "{}", r.render("robot", 0));
    (r.states, r.transitions, r.idle, r.stopped)
}

#[test]
fn the_sequence_robots_of_robot_configs_pass_with_their_state_counts() {
    for (file, lossless, lossy) in [
        (
            "paint-robot.ron",
            (451, 1111, 2, 388),
            (1475, 4360, 2, 1412),
        ),
        (
            "paint-robot-spare-node.ron",
            (451, 1111, 2, 388),
            (1475, 4360, 2, 1412),
        ),
        (
            "paint-robot-double-dip.ron",
            (623, 1557, 2, 548),
            (2063, 6166, 2, 1988),
        ),
        (
            "paint-robot-start-on-gr.ron",
            (455, 1116, 2, 388),
            (1483, 4370, 2, 1416),
        ),
    ] {
        let c = build(&load(&format!("../robot-configs/{file}")));
        assert_eq!(passes(&run(&c, false)), lossless, "{file}");
        assert_eq!(passes(&run(&c, true)), lossy, "{file} lossy");
    }
}

/// The two explicit-chart robots in the paper's position-event style are correct only
/// when a publication is delivered before the next motion ends: with arbitrary radio delays
/// a late `VC.home` reaches HC after RC's `RC.home`, HC ignores RC's event and waits for
/// ever (paper charts) or starts HC+ while HC is still retracting (counted).
#[test]
fn the_position_event_robots_race_on_late_deliveries() {
    let c = build(&load("../robot-configs/paint-robot-paper-charts.ron"));
    let r = run(&c, false);
    let v = r.violation.as_ref().expect("a violation");
    assert_eq!(v.property, Property::Deadlock);
    assert_eq!(v.steps, 16);
    let text = v.trace.join("\n");
    assert!(text.contains(" 16. radio delivers RC -> HC"), "{text}");
    assert!(text.ends_with(
        "state: charts VC[vc=S4] GR[gr=S2] HC[hc=S1] RC[rc=S3]; actuators VC home, GR \
         extending, HC end, RC home; in flight: VC->GR: VC.end; VC->HC: VC.home"
    ));

    let c = build(&load("../robot-configs/paint-robot-counted.ron"));
    let v = run(&c, false).violation.expect("a violation");
    assert_eq!(v.property, Property::DoubleActuation);
    assert_eq!(v.message, "HC+ commanded while HC is still retracting");
    assert_eq!(v.steps, 24);
}

#[test]
fn a_chart_that_deadlocks_when_two_events_arrive_in_the_other_order() {
    let c = build(&load("fixtures/verify/order-deadlock.ron"));
    let v = run(&c, false).violation.expect("a violation");
    assert_eq!(v.property, Property::Deadlock);
    assert_eq!(v.steps, 4);
    assert_eq!(
        v.trace[v.trace.len() - 4..],
        [
            "  4. radio delivers Y -> Z",
            "   Z: receives y.OUT from Y",
            "      chart z ignores SECOND (no transition takes it here)",
            "     state: charts X[x=OUT] Y[y=WAIT] Z[z=W0]; actuators X end, Z home; in \
             flight: X->Z: X.end",
        ]
    );
}

#[test]
fn a_missing_interlock_is_caught_and_the_right_order_keeps_it() {
    let src = load("fixtures/verify/interlock.ron");
    let v = run(&build(&src), false).violation.expect("a violation");
    assert_eq!(v.property, Property::Interlock);
    assert_eq!(v.message, "never: \"B.moving && !A.home\" holds");
    assert_eq!(v.steps, 3);
    assert_eq!(
        v.trace
            .iter()
            .filter(|l| !l.starts_with("      ") && !l.starts_with("   "))
            .cloned()
            .collect::<Vec<_>>(),
        [
            "  1. operator presses START (at A)",
            "  2. A reaches its end switch",
            "  3. radio delivers A -> B",
        ]
    );
    assert!(v
        .trace
        .contains(&"      B+: B starts extending".to_string()));
    let fixed = Source::new(
        "interlock-fixed",
        src.text.replace("A+ B+ A- B-", "A+ A- B+ B-"),
    );
    let r = run(&build(&fixed), false);
    assert!(r.ok(), "{}", r.render("fixed", 1));
}

#[test]
fn a_chart_that_refires_on_a_repeated_event_breaks_the_sequence() {
    let c = build(&load("fixtures/verify/refire.ron"));
    let v = run(&c, false).violation.expect("a violation");
    assert_eq!(v.property, Property::Sequence);
    assert_eq!(
        v.message,
        "step 4 of the cycle is B+, the declared sequence says A-"
    );
}

/// A chart that runs the declared cycle twice per START: the second cycle's first step
/// comes after the whole sequence, before START was pressed again (counted modulo the
/// cycle, it wrapped and passed).
#[test]
fn a_chart_that_runs_the_cycle_twice_per_start_breaks_the_sequence() {
    let c = build(&load("fixtures/verify/twice.ron"));
    let v = run(&c, false).violation.expect("a violation");
    assert_eq!(
        (v.property, v.message.as_str()),
        (
            Property::Sequence,
            "step 3 of the cycle is X+, after the 2 declared steps (START was not pressed again)"
        )
    );
}

/// A START that commands nothing: the machine rests again without a step (it passed,
/// having never left its initial state).
#[test]
fn a_start_that_commands_nothing_breaks_the_sequence() {
    let c = build(&load("fixtures/verify/deaf-start.ron"));
    let v = run(&c, false).violation.expect("a violation");
    assert_eq!(
        (v.property, v.message.as_str()),
        (
            Property::Sequence,
            "START pressed at rest and the machine is idle again without a step (the \
             declared sequence has 2)"
        )
    );
    assert_eq!(v.steps, 1);
}

/// More switches than a state has bits for are refused, not explored in part (the ninth
/// was never set, and `verify` passed a robot whose ninth switch breaks the sequence).
#[test]
fn more_switches_than_a_state_holds_are_refused() {
    let c = build(&load("fixtures/verify/nine-switches.ron"));
    let e = verify::verify(&c, ExploreOptions::default()).expect_err("refused");
    assert_eq!(e, verify::ModelError::TooManySwitches(9));
    assert_eq!(e.to_string(), "9 switches: verify handles at most 8");
}

#[test]
fn a_timer_instead_of_a_switch_is_a_double_actuation() {
    let c = build(&load("fixtures/verify/timed-retract.ron"));
    let v = run(&c, false).violation.expect("a violation");
    assert_eq!(v.property, Property::DoubleActuation);
    assert_eq!(v.message, "A- commanded while A is still extending");
    assert_eq!(v.steps, 2);
    assert!(v.trace.contains(&"  2. timer a.T of A expires".to_string()));
}

/// A tampered compiled table (VC's START transition retargeted from `STEP1` to `STEP5`,
/// skipping GR+ VC- HC+), re-encoded into the blob the nodes would receive.
#[test]
fn a_tampered_compiled_table_breaks_the_sequence() {
    let mut c = build(&load("../robot-configs/paint-robot.ron"));
    let chart = &c.ir.roles[0].charts[0];
    let step5 = chart
        .states
        .iter()
        .position(|s| s.name == "STEP5")
        .expect("STEP5") as u8;
    let t = c.tables[0]
        .transitions
        .iter()
        .position(|t| t.from == 0 && t.to == 1)
        .expect("IDLE -> STEP1");
    c.tables[0].transitions[t].to = step5;
    c.blobs[0] = robot_compiler::compile::encode(&c.tables[0]).expect("encodes");
    let v = run(&c, false).violation.expect("a violation");
    assert_eq!(v.property, Property::Sequence);
    assert_eq!(
        v.message,
        "step 2 of the cycle is VC-, the declared sequence says GR+"
    );
    assert_eq!(v.steps, 2);
    assert!(v
        .trace
        .contains(&"      chart VC: IDLE -> STEP5".to_string()));
}

/// `file` compiled, its VC's `fault` publication tampered so that it no longer reaches
/// RC.
fn vc_fault_misses_rc(file: &str) -> Compiled {
    let mut c = build(&load(file));
    let fault = c.ir.roles[0].event_id("fault").expect("fault event") as u8;
    let rc = c.ir.roles.iter().position(|r| r.name == "RC").expect("RC");
    let rc_peer = c.tables[0]
        .peers
        .iter()
        .position(|a| *a == c.ir.roles[rc].address)
        .expect("RC is a peer of VC");
    let p = c.tables[0]
        .publications
        .iter_mut()
        .find(|p| p.event == fault)
        .expect("fault is published");
    assert_eq!(p.subscribers.count_ones(), 3);
    p.subscribers &= !(1 << rc_peer);
    c.blobs[0] = robot_compiler::compile::encode(&c.tables[0]).expect("encodes");
    c
}

/// A tampered table whose `fault` publication no longer reaches RC: when VC's watchdog
/// fires, RC goes on running.
#[test]
fn a_fault_publication_that_misses_a_node_is_caught() {
    let c = vc_fault_misses_rc("../robot-configs/paint-robot.ron");
    let v = run(&c, false).violation.expect("a violation");
    assert_eq!(v.property, Property::FaultStop);
    assert_eq!(v.message, "VC faulted but RC is still running");
    // START, VC's watchdog expires at once, VC's rod completes its stroke, the fault
    // reaches GR and HC: nothing more can happen, RC still runs.
    assert_eq!(v.steps, 5);
    assert!(v
        .trace
        .contains(&"  2. timer VC.watchdog of VC expires".to_string()));
}

/// The same miss is caught whatever the operator may still press: START at any time, an
/// e-stop (both offered in every state, so no state was without a next move and the
/// property was never looked at: it was reported as holding).
#[test]
fn a_missed_fault_is_caught_with_start_at_any_time_and_with_an_estop() {
    let c = vc_fault_misses_rc("../robot-configs/paint-robot.ron");
    let anytime = ExploreOptions {
        start_anytime: true,
        ..ExploreOptions::default()
    };
    let v = verify::verify(&c, anytime).expect("model builds");
    let v = v.violation.expect("a violation with --start-anytime");
    assert_eq!(
        (v.property, v.message.as_str()),
        (Property::FaultStop, "VC faulted but RC is still running")
    );
    let c = vc_fault_misses_rc("../tests/fixtures/paint-robot-estop.ron");
    let v = run(&c, false)
        .violation
        .expect("a violation with an e-stop");
    assert_eq!(
        (v.property, v.message.as_str()),
        (Property::FaultStop, "VC faulted but RC is still running")
    );
}

/// A description whose VC no longer hears RC's fault (as the IEC 61499 export once
/// brought the paint robot back: one peer's fault of three), its table likewise: when
/// RC's watchdog fires, VC goes on running. VC hears the other nodes' faults, so it takes
/// part in the machine's stop and must hear RC's too (the description alone said nothing
/// was missing). The faults named as a robot imported from IEC 61499 names them, by the
/// fault chart's output (`HC_fault.fault`): the property held for every imported robot,
/// whatever its tables did, as it knew only the name `fault`.
#[test]
fn a_node_that_hears_faults_but_not_one_nodes_is_caught() {
    let mut c = build(&load("../robot-configs/paint-robot.ron"));
    let rc = c.ir.roles.iter().position(|r| r.name == "RC").expect("RC");
    let rc_addr = c.ir.roles[rc].address;
    for r in &mut c.ir.roles {
        for (from, ev, _) in &mut r.imports {
            if ev == "fault" {
                *ev = format!("{from}_fault.fault");
            }
        }
    }
    let vc = &mut c.ir.roles[0];
    let before = vc.imports.len();
    vc.imports
        .retain(|(from, ev, _)| !(from == "RC" && ev == "RC_fault.fault"));
    assert_eq!(vc.imports.len(), before - 1);
    let rc_fault = c.ir.roles[rc].event_id("fault").expect("RC's fault") as u8;
    let topic = (c.tables[rc].publications.iter())
        .find(|p| p.event == rc_fault)
        .expect("RC publishes its fault")
        .topic;
    let t = &mut c.tables[0];
    let rc_peer = t
        .peers
        .iter()
        .position(|a| *a == rc_addr)
        .expect("RC is a peer") as u8;
    let subscribed = t.subscriptions.len();
    t.subscriptions
        .retain(|s| (s.publisher, s.topic) != (rc_peer, topic));
    assert_eq!(t.subscriptions.len(), subscribed - 1);
    c.blobs[0] = robot_compiler::compile::encode(&c.tables[0]).expect("encodes");
    let v = run(&c, false).violation.expect("a violation");
    assert_eq!(v.property, Property::FaultStop);
    assert_eq!(
        v.message,
        "RC faulted but VC is still running (it does not hear that node's fault)"
    );
}

/// With START pressed at any time, the small explicit-chart robot's mover extends again
/// while it is still retracting: its chart returns to IDLE before A is home.
#[test]
fn a_start_during_the_cycle_is_explored_with_start_anytime() {
    let anytime = |c: &Compiled| {
        verify::verify(
            c,
            ExploreOptions {
                start_anytime: true,
                ..ExploreOptions::default()
            },
        )
        .expect("model builds")
    };
    let paint = build(&load("../robot-configs/paint-robot.ron"));
    // (469 states before a press after the cycle's last step was told apart from none: a
    // step after the last one is a new cycle only if START was pressed again.)
    assert_eq!(passes(&anytime(&paint)), (504, 1752, 2, 436));
    // START on another node than step 1's: its node gates the button, so a press during a
    // cycle costs no publication (it used to fill the GR -> VC link: bounded links).
    let on_gr = build(&load("../robot-configs/paint-robot-start-on-gr.ron"));
    assert_eq!(passes(&anytime(&on_gr)), (512, 1771, 2, 436));
    let small = build(&load("fixtures/small-charts.ron"));
    let v = anytime(&small).violation.expect("a violation");
    assert_eq!(v.property, Property::DoubleActuation);
    assert_eq!(v.message, "A+ commanded while A is still retracting");
    assert_eq!(v.steps, 7);
    assert!(v
        .trace
        .contains(&"  7. operator presses START (at A)".to_string()));
}

/// A counter that is never reset makes the state space infinite: the run stops at
/// `max_states`, says so, and names the variable.
#[test]
fn an_unbounded_counter_stops_the_exploration_and_is_named() {
    let small = build(&load("fixtures/small-charts.ron"));
    let r = verify::verify(
        &small,
        ExploreOptions {
            max_states: 1000,
            ..ExploreOptions::default()
        },
    )
    .expect("model builds");
    assert!(r.incomplete);
    assert!(!r.ok());
    assert_eq!(r.states, 1000);
    assert_eq!(r.growing, ["A.a.count = 143"]);
}

#[test]
fn an_unknown_interlock_name_is_a_diagnostic() {
    let src = load("fixtures/verify/interlock.ron");
    let bad = Source::new(
        "bad-interlock",
        src.text
            .replace("B.moving && !A.home", "B.moving && !A.down"),
    );
    let diags = match compile(&bad) {
        Ok(_) => panic!("compiles"),
        Err(d) => d,
    };
    let text: Vec<String> = diags.iter().map(|d| d.short(&bad)).collect();
    assert_eq!(
        text,
        ["bad-interlock:24:27: error: `A.down`: an actuator has `.home`, `.end`, `.moving`, `.extending`, \
          `.retracting`, not `.down`"]
    );
}
