//! `verify`'s homing proof: from every position the actuators can rest in when the machine
//! comes up unhomed, HOME brings it to idle; damaged tables are caught with the start
//! positions and the shortest counterexample.

use robot_analysis::verify::{self, ExploreOptions, HomingReport, Property};
use robot_compiler::{Compiled, Source};

mod common;
use common::{build, load};

fn homing(c: &Compiled, opts: ExploreOptions) -> Option<HomingReport> {
    let model = verify::Model::new(c).expect("model builds");
    verify::explore_homing(&model, opts)
}

fn paint() -> Compiled {
    build(&load("../robot-configs/paint-robot.ron"))
}

/// The chart named `chart` of role `role`: (role index, the table's transition range).
fn transitions(c: &Compiled, role: &str, chart: &str) -> (usize, std::ops::Range<usize>) {
    let r =
        c.ir.roles
            .iter()
            .position(|r| r.name == role)
            .expect("role");
    let ci = (c.ir.roles[r].charts.iter())
        .position(|x| x.name == chart)
        .expect("chart");
    (r, c.tables[r].chart_transitions(ci))
}

fn state(c: &Compiled, role: usize, chart: &str, name: &str) -> u8 {
    let ch = (c.ir.roles[role].charts.iter())
        .find(|x| x.name == chart)
        .expect("chart");
    ch.states
        .iter()
        .position(|s| s.name == name)
        .expect("state") as u8
}

fn reencode(c: &mut Compiled, role: usize) {
    c.blobs[role] = robot_compiler::compile::encode(&c.tables[role]).expect("encodes");
}

#[test]
fn the_paint_robots_derived_homing_reaches_idle_from_all_81_start_positions() {
    let c = paint();
    let r = homing(&c, ExploreOptions::default()).expect("the paint robot homes");
    assert!(r.ok(), "{}", r.render("paint-robot", 2));
    assert_eq!(r.homing, "VC- HC- RC- GR-");
    // 3^4 positions, GR's held valve high (a reset holds the part) and low (a boot).
    assert_eq!((r.positions, r.held), (81, 1));
    let f = &r.report;
    assert_eq!(
        (f.states, f.transitions, f.idle, f.stopped),
        (1440, 3416, 16, 1008)
    );
    let lossy = homing(
        &c,
        ExploreOptions {
            lossy: true,
            ..ExploreOptions::default()
        },
    )
    .expect("homes");
    assert!(lossy.ok(), "{}", lossy.render("paint-robot", 2));
    assert_eq!(lossy.report.states, 4240);
}

/// Every robot of `robot-configs/`: the sequence robots home from every start position
/// (with any radio delay), the explicit-chart ones have no homing to prove.
#[test]
fn every_robot_of_robot_configs_homes_or_has_no_homing() {
    let files = common::robot_configs();
    let mut seen = Vec::new();
    for f in &files {
        let c = build(&load(&format!("../robot-configs/{f}")));
        let r = homing(&c, ExploreOptions::default());
        if let Some(r) = &r {
            assert!(r.ok(), "{f}: {}", r.render(f, 0));
        }
        seen.push((
            f.as_str(),
            r.map(|r| (r.homing, r.positions, r.report.states)),
        ));
    }
    let h = |s: &str, p, n| Some((String::from(s), p, n));
    assert_eq!(
        seen,
        [
            ("ball-sorter.ron", None),
            ("paint-robot-4diac.ron", None),
            ("paint-robot-counted.ron", None),
            ("paint-robot-double-dip.ron", h("VC- HC- RC- GR-", 81, 1440)),
            ("paint-robot-paper-charts.ron", None),
            ("paint-robot-spare-node.ron", h("VC- HC- RC- GR-", 81, 1440)),
            // A press before HOME meets GR's gate shut: nothing is published (4,320 states
            // while it published START to VC, which homing's end could let through).
            (
                "paint-robot-start-on-gr.ron",
                h("VC- HC- RC- GR-", 81, 1472)
            ),
            ("paint-robot.ron", h("VC- HC- RC- GR-", 81, 1440)),
            ("waterjet-transport.ron", None),
        ]
    );
}

/// A damaged HC table whose homing step no longer skips HC when it is already home
/// (the guarded `WAIT -> HOMED2` retargeted to `HOMING2`): it drives HC back, nothing
/// moves, and only HC's watchdog can end it.
#[test]
fn a_homing_step_that_is_not_skipped_at_home_gets_stuck_from_the_home_position() {
    let mut c = paint();
    let (hc, range) = transitions(&c, "HC", "home");
    let homing2 = state(&c, hc, "home", "HOMING2");
    let skip = range
        .clone()
        .find(|&t| c.tables[hc].transitions[t].guard.is_some())
        .expect("the skip");
    c.tables[hc].transitions[skip].to = homing2;
    reencode(&mut c, hc);
    let r = homing(&c, ExploreOptions::default()).expect("homes");
    assert!(!r.ok());
    let v = r.report.violation.clone().expect("a violation");
    assert_eq!(v.property, Property::Deadlock);
    assert_eq!(
        v.message,
        "homing is stuck here: only a fault or a link alarm can happen next, and the machine \
         is not idle"
    );
    assert_eq!(
        v.start.as_deref(),
        Some("VC home, GR home, HC home, RC home")
    );
    assert_eq!(v.steps, 2);
    assert_eq!(
        v.trace,
        [
            "  1. operator gives the HOME command (at VC)",
            "   VC: HOME command",
            "      chart VC: UNHOMED -> HOMING",
            "      chart home: WAIT -> HOMED1",
            "      publishes home1.done to HC",
            "      chart home: HOMED1 -> WAIT",
            "  2. radio delivers VC -> HC",
            "   HC: receives home1.done from VC",
            "      chart home: WAIT -> HOMING2",
            "      output HC.retract = 1",
            "      starts timer HC.watchdog",
            "     state: charts VC[VC=HOMING fault=RUN home=WAIT] GR[GR=WAIT2 fault=RUN \
             home=WAIT] HC[HC=WAIT4 fault=RUN home=HOMING2] RC[RC=WAIT7 fault=RUN home=WAIT]; \
             actuators VC home, GR home, HC home, RC home; in flight: none",
        ]
    );
    let text = r.render("damaged", 2);
    assert!(
        text.contains(
            "FAILED deadlock freedom: homing is stuck here: only a fault or a link alarm can \
             happen next, and the machine is not idle\nstart positions: VC home, GR home, HC \
             home, RC home\nshortest counterexample (2 steps):\n"
        ),
        "{text}"
    );
}

/// A damaged VC table whose START transition leaves `UNHOMED` instead of `IDLE`: a START
/// before HOME moves VC.
#[test]
fn a_start_that_moves_the_unhomed_machine_is_caught() {
    let mut c = paint();
    let (vc, range) = transitions(&c, "VC", "VC");
    let (idle, unhomed, step1) = (
        state(&c, vc, "VC", "IDLE"),
        state(&c, vc, "VC", "UNHOMED"),
        state(&c, vc, "VC", "STEP1"),
    );
    let t = range
        .clone()
        .find(|&t| {
            let t = &c.tables[vc].transitions[t];
            t.from == idle && t.to == step1
        })
        .expect("IDLE -> STEP1");
    c.tables[vc].transitions[t].from = unhomed;
    reencode(&mut c, vc);
    let v = homing(&c, ExploreOptions::default())
        .expect("homes")
        .report
        .violation
        .expect("a violation");
    assert_eq!(v.property, Property::UnhomedStart);
    assert_eq!(
        v.message,
        "VC+ before HOME: the machine moved while not homed"
    );
    assert_eq!(
        v.start.as_deref(),
        Some("VC home, GR home, HC home, RC home")
    );
    assert_eq!(v.steps, 1);
    assert_eq!(v.trace[0], "  1. operator presses START (at VC)");
    assert!(v
        .trace
        .contains(&"      chart VC: UNHOMED -> STEP1".to_string()));
}

/// A sequence robot of `n` double-acting actuators, two a node, `A0+ .. A(n-1)+` then
/// back.
fn many(n: usize) -> Compiled {
    let nodes = n.div_ceil(2);
    let node_list: String = (0..nodes)
        .map(|k| format!("(name: \"n{k}\", address: {}),", k + 1))
        .collect();
    let assign: String = (0..nodes)
        .map(|k| format!("(\"R{k}\", \"n{k}\"),"))
        .collect();
    let roles: String = (0..nodes)
        .map(|k| {
            let acts: String = (2 * k..(2 * k + 2).min(n))
                .map(|i| {
                    let b = 4 * (i - 2 * k);
                    format!(
                        "(name: \"A{i}\", kind: DoubleActing(extend: {b}, retract: {}, home: {}, \
                         end: {})),",
                        b + 1,
                        b + 2,
                        b + 3
                    )
                })
                .collect();
            let start = if k == 0 {
                ", inputs: [(name: \"START\", pin: 40)]"
            } else {
                ""
            };
            format!("(name: \"R{k}\", actuators: [{acts}]{start}),")
        })
        .collect();
    let sequence: Vec<String> = (0..n)
        .map(|i| format!("A{i}+"))
        .chain((0..n).rev().map(|i| format!("A{i}-")))
        .collect();
    let text = format!(
        "Robot(name: \"many\", network: (pan_id: 0x0101, channel: 11), nodes: [{node_list}], \
         assign: [{assign}], roles: [{roles}], start: \"START\", sequence: \"{}\")",
        sequence.join(" ")
    );
    build(&Source::new("many.ron", text))
}

/// Homing's start positions are made as the search takes them, so `--max-states` bounds
/// the run: 14 actuators (3^14 start positions, all built before the search began) ran
/// out of memory at 3.6 GB whatever `--max-states` said.
#[test]
fn homing_of_many_actuators_stops_at_max_states() {
    let c = many(14);
    let opts = ExploreOptions {
        max_states: 1_000,
        ..ExploreOptions::default()
    };
    let r = homing(&c, opts).expect("homes");
    assert_eq!(r.positions, 4_782_969);
    assert!(r.report.incomplete);
    assert_eq!(r.report.states, 1_000);
}
