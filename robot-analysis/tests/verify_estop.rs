//! `verify` of the emergency stop: the painting robot with an e-stop on VC's node
//! (`tests/fixtures/paint-robot-estop.ron`) explored with the press at any time of the
//! cycle: VC faults in the engine step that senses it, every other node in the step that
//! receives VC's `estop` (one hop, from VC itself), and no node it reached moves. Damaged
//! tables are caught with their shortest counterexamples.

use config_schema::alarm::{FAULT_ESTOP, FAULT_ESTOP_PEER};
use config_schema::Action;
use robot_analysis::verify::{self, ExploreOptions, Property, Report};
use robot_compiler::Compiled;

mod common;
use common::{build, load};

fn robot() -> Compiled {
    build(&load("fixtures/paint-robot-estop.ron"))
}

fn run(c: &Compiled) -> Report {
    verify::verify(c, ExploreOptions::default()).expect("model builds")
}

fn role(c: &Compiled, name: &str) -> usize {
    c.ir.roles.iter().position(|r| r.name == name).expect(name)
}

fn reencode(c: &mut Compiled, role: usize) {
    c.blobs[role] = robot_compiler::compile::encode(&c.tables[role]).expect("encodes");
}

/// Replaces role `r`'s `Fault(code)` action (its e-stop chart's) with `with`.
fn replace_fault(c: &mut Compiled, r: usize, code: u8, with: Action) {
    let a = (c.tables[r].actions.iter())
        .position(|a| *a == Action::Fault(code))
        .expect("the e-stop chart's fault action");
    c.tables[r].actions[a] = with;
    reencode(c, r);
}

#[test]
fn the_painting_robot_with_an_estop_passes_every_press_stops_every_node_in_one_hop() {
    let c = robot();
    let r = run(&c);
    let text = r.render("paint-robot-estop.ron", 2);
    assert!(r.ok(), "{text}");
    assert_eq!(r.estop.as_deref(), Some("VC/ESTOP"));
    // The cycle's 451 states, each with the e-stop pressed in it, and what follows (2,788
    // before the states after the cycle's last step were told apart from those before
    // its first).
    assert_eq!((r.states, r.transitions, r.idle), (2796, 9106, 2), "{text}");
    assert!(
        text.ends_with(
            "ok: deadlock freedom, sequence conformance, 2 interlock(s), no double actuation, \
             no engine fault, a fault stops every node, the e-stop (VC/ESTOP) stops every node \
             within one hop and nothing moves after it\n"
        ),
        "{text}"
    );
    // The robot without the e-stop: the press is not explored.
    let plain = build(&load("../robot-configs/paint-robot.ron"));
    let r = run(&plain);
    assert_eq!((r.states, r.estop), (451, None));
}

#[test]
fn an_estop_node_that_does_not_fault_at_once_is_caught_on_the_press() {
    let mut c = robot();
    let vc = role(&c, "VC");
    replace_fault(&mut c, vc, FAULT_ESTOP, Action::CancelTimer(0));
    let v = run(&c).violation.expect("caught");
    assert_eq!(
        (v.property, v.message.as_str(), v.steps),
        (
            Property::EStop,
            "VC did not fault in the engine step that sensed its e-stop",
            1
        )
    );
    assert_eq!(v.trace[0], "  1. operator presses the e-stop (at VC/ESTOP)");
}

#[test]
fn an_estop_that_does_not_reach_a_node_directly_is_caught() {
    let mut c = robot();
    let (vc, hc) = (role(&c, "VC"), role(&c, "HC"));
    let hc_addr = c.ir.roles[hc].address;
    let peer = (c.tables[vc].peers.iter())
        .position(|a| *a == hc_addr)
        .expect("HC is VC's peer");
    let estop = (c.ir.roles[vc].events.iter())
        .position(|e| e == "estop")
        .expect("VC's estop event");
    let p = (c.tables[vc].publications.iter())
        .position(|p| usize::from(p.event) == estop)
        .expect("VC publishes estop");
    c.tables[vc].publications[p].subscribers &= !(1 << peer);
    reencode(&mut c, vc);
    let v = run(&c).violation.expect("caught");
    assert_eq!(
        (v.property, v.message.as_str(), v.steps),
        (
            Property::EStop,
            "the e-stop does not reach HC in one hop: VC publishes no `estop` to it",
            1
        )
    );
}

#[test]
fn a_chart_that_moves_on_the_estop_instead_of_faulting_is_caught_with_its_counterexample() {
    let mut c = robot();
    let hc = role(&c, "HC");
    // HC's e-stop chart drives HC's extend solenoid (output 0) instead of faulting.
    replace_fault(
        &mut c,
        hc,
        FAULT_ESTOP_PEER,
        Action::Drive { mask: 1, value: 1 },
    );
    let v = run(&c).violation.expect("caught");
    assert_eq!(
        (v.property, v.message.as_str(), v.steps),
        (
            Property::EStop,
            "HC+ commanded by HC after the e-stop reached it",
            2
        )
    );
    assert_eq!(
        v.trace,
        [
            "  1. operator presses the e-stop (at VC/ESTOP)",
            "   VC: input ESTOP rises",
            "      chart estop: RUN -> STOP",
            "      publishes estop to GR, HC, RC",
            "      FAULT Action { chart: 3, code: 3 }: outputs safe",
            "  2. radio delivers VC -> HC",
            "   HC: receives estop from VC",
            "      chart estop: RUN -> STOP",
            "      output HC.extend = 1",
            "      HC+: HC starts extending",
            "   HC: input HC.home falls",
            "     state: charts VC[VC=IDLE fault=RUN home=WAIT estop=STOP] FAULT Action { chart: \
             3, code: 3 } GR[GR=WAIT2 fault=RUN home=WAIT estop=RUN] HC[HC=WAIT4 fault=RUN \
             home=WAIT estop=STOP] RC[RC=WAIT7 fault=RUN home=WAIT estop=RUN]; actuators VC \
             home, GR home, HC extending, RC home; in flight: VC->GR: estop; VC->RC: estop",
        ]
    );
}

/// The painting robot with `on_link_alarm: Fault`.
fn link_fault_robot() -> Compiled {
    let src = load("../robot-configs/paint-robot.ron");
    let text = src.text.replacen(
        "    motion_timeout_ms: 2000,\n",
        "    motion_timeout_ms: 2000,\n    on_link_alarm: Fault,\n",
        1,
    );
    build(&robot_compiler::Source::new(
        "paint-robot-link-fault.ron",
        text,
    ))
}

fn lossy(c: &Compiled) -> Report {
    let opts = ExploreOptions {
        lossy: true,
        ..ExploreOptions::default()
    };
    verify::verify(c, opts).expect("model builds")
}

#[test]
fn with_on_link_alarm_fault_a_link_alarm_faults_its_node_and_a_table_that_lost_it_is_caught() {
    let c = link_fault_robot();
    let r = lossy(&c);
    assert!(r.ok(), "{}", r.render("paint-robot-link-fault.ron", 2));
    // As many states as the stalling robot (docs/verification.md): a node faulted on its
    // link alarm does nothing more, as a stalled one waits.
    assert_eq!((r.states, r.transitions), (1475, 4360));

    // VC's table without `link_fault`: its first link alarm leaves it running.
    let mut c = link_fault_robot();
    let vc = role(&c, "VC");
    c.tables[vc].safety.link_fault = false;
    reencode(&mut c, vc);
    let v = lossy(&c).violation.expect("caught");
    assert_eq!(
        (v.property, v.message.as_str(), v.steps),
        (
            Property::LinkFault,
            "VC's link to GR is in alarm and VC still runs (the robot says on_link_alarm: Fault)",
            3
        )
    );
}
