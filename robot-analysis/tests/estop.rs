//! The emergency stop on the interpreter from the compiled blobs: the painting robot with
//! an e-stop on VC's node. Pressing it mid-cycle faults VC in that engine step and every
//! other node one radio hop later; VC's e-stop alarm cannot be acknowledged while the
//! button is pressed, nothing starts until every fault alarm is acknowledged; after the
//! release, reset, acknowledgement and homing a full cycle runs.

use config_schema::alarm::{AlarmLevel, AlarmSource, FAULT_ESTOP_PEER};
use node_fw::sim::What;
use robot_analysis::sim;
use robot_compiler::Source;

mod common;
use common::build;

/// The painting robot with `estop: "ESTOP"` on VC (pin 5) and its switch for `sim`.
fn robot() -> Source {
    let text = std::fs::read_to_string("../robot-configs/paint-robot.ron").expect("robot");
    let text = text
        .replacen(
            r#"inputs: [(name: "START", pin: 4)],"#,
            r#"inputs: [(name: "START", pin: 4), (name: "ESTOP", pin: 5)], estop: "ESTOP","#,
            1,
        )
        .replacen(
            "    motion_timeout_ms: 2000,",
            "    motion_timeout_ms: 2000,\n    plants: [Switch(name: \"ESTOP\", role: \"VC\", input: \"ESTOP\")],",
            1,
        );
    Source::new("paint-robot-estop.ron", text)
}

#[test]
fn an_estop_faults_every_node_within_one_hop_and_nothing_moves_until_reset_and_ack() {
    let c = build(&robot());
    let tables = sim::tables(&c).expect("blobs decode");
    let (mut world, start) = sim::world(&c, &tables).expect("world");
    let estop = world.plant_by_name("ESTOP").expect("the e-stop switch");
    let node = |role: &str| c.ir.roles.iter().position(|r| r.name == role).expect(role);
    let vc = node("VC");

    world.press(start).expect("START");
    world.run_for(500).expect("runs");
    let mark = world.trace().len();
    world.set_switch(estop, true).expect("pressed");
    world.run_until_idle(10_000).expect("settles");
    let after = &world.trace()[mark..];
    let faults: Vec<(u64, usize, String)> = (after.iter())
        .filter_map(|e| match &e.what {
            What::Fault { node, fault } => Some((e.t_ms, *node, format!("{fault:?}"))),
            _ => None,
        })
        .collect();
    let t = faults[0].0;
    let estop_chart = c.ir.roles[vc]
        .charts
        .iter()
        .position(|ch| ch.name == "estop")
        .expect("VC's estop chart");
    assert_eq!(
        faults[0],
        (t, vc, format!("Action {{ chart: {estop_chart}, code: 3 }}"))
    );
    // Every other node one hop later (the sim's radio delay, 2 ms), each by its own chart.
    let mut others: Vec<(u64, usize)> = faults[1..].iter().map(|f| (f.0, f.1)).collect();
    others.sort();
    let want: Vec<(u64, usize)> = (0..c.ir.roles.len())
        .filter(|&n| n != vc)
        .map(|n| (t + 2, n))
        .collect();
    assert_eq!(others, want, "{faults:?}");
    for f in &faults[1..] {
        assert!(
            f.2.ends_with(&format!("code: {FAULT_ESTOP_PEER} }}")),
            "{f:?}"
        );
    }
    // Nothing moved after the e-stop.
    let steps = world.steps();
    world.run_for(3000).expect("runs");
    assert_eq!(world.steps(), steps);

    // VC's alarm: the e-stop, not acknowledged while pressed.
    let r = world.alarms(vc).expect("alarms");
    let listed: Vec<_> = (r.alarms.iter())
        .map(|a| (a.source, a.level, a.raised_ms, a.acked, a.persists))
        .collect();
    assert_eq!(
        listed,
        [(AlarmSource::EStop, AlarmLevel::Fault, t as u32, false, true)]
    );
    assert_eq!(world.ack(vc), Ok(0));
    // Every other node: a chart fault alarm.
    for n in (0..c.ir.roles.len()).filter(|&n| n != vc) {
        let r = world.alarms(n).expect("alarms");
        assert_eq!(r.alarms.len(), 1);
        assert!(matches!(
            r.alarms[0].source,
            AlarmSource::Chart { code: 0x84, .. }
        ));
    }

    // Released, reset: START is refused while the alarms are latched.
    world.set_switch(estop, false).expect("released");
    for n in 0..c.ir.roles.len() {
        world.reset(n).expect("reset");
    }
    world.run_until_idle(10_000).expect("settles");
    world.home(vc).expect("HOME");
    world.run_until_idle(10_000).expect("homes");
    let steps = world.steps();
    world.press(start).expect("START");
    world.run_until_idle(10_000).expect("settles");
    assert_eq!(world.steps(), steps, "START refused");
    // Acknowledged on every node: a full cycle runs.
    for n in 0..c.ir.roles.len() {
        assert_eq!(world.ack(n), Ok(1));
    }
    let cycle = world.run_cycle(start, 30_000).expect("a cycle");
    assert_eq!(
        cycle.steps.join(" "),
        "VC+ GR+ VC- HC+ VC+ VC- RC+ RC- HC- VC+ GR- VC-"
    );
}
