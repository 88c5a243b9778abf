//! Seed 001's fig. 9 on the water-jet cutter's material transport
//! (`robot-configs/waterjet-transport.ron`), from the compiled blobs on the node
//! interpreter with the declared plants (the pusher's motor with its continuous position,
//! the belt it moves, the fault contact, the operator's buttons): in step 2 the pusher
//! turns clockwise and moves the belt forward; a fault occurs; the pusher stops at once
//! (on its own node, in the engine step that sensed the fault), so the belt stops (one
//! radio hop later); the operator releases the pusher; pusher and belt return home; the
//! fault is cleared; the operator restarts the automatic transport and a full cycle
//! completes.

use config_schema::alarm::{AlarmLevel, AlarmSource};
use node_fw::sim::{Run, TraceEntry, What, World};
use robot_analysis::sim;
use robot_compiler::Compiled;

mod common;
use common::{build, load};

/// `t: Function: From -> To` for every transition of a control function's chart (the
/// `.seen` charts that follow another node's places are left out).
fn places(c: &Compiled, trace: &[TraceEntry]) -> Vec<String> {
    let functions: Vec<&str> = c.robot.functions.iter().map(|f| f.name.as_str()).collect();
    trace
        .iter()
        .filter_map(|e| match e.what {
            What::Fired {
                node,
                chart,
                from,
                to,
                ..
            } => {
                let ch = &c.ir.roles[node].charts[usize::from(chart)];
                functions.contains(&ch.name.as_str()).then(|| {
                    format!(
                        "{:>5} {}: {} -> {}",
                        e.t_ms,
                        ch.name,
                        ch.states[usize::from(from)].name,
                        ch.states[usize::from(to)].name
                    )
                })
            }
            _ => None,
        })
        .collect()
}

fn plant(world: &World, name: &str) -> usize {
    world.plant_by_name(name).expect(name)
}

/// Runs until nothing is pending.
fn settle(world: &mut World) {
    world.run_until_idle(60_000).expect("settles");
}

/// Fig. 9 on the compiled robot: its whole trace (asserting each stage on the way).
fn fig9(c: &Compiled) -> Vec<TraceEntry> {
    let tables = sim::tables(c).expect("blobs decode");
    let (mut world, start) = sim::world(c, &tables).expect("world");
    let (pusher, belt) = (plant(&world, "PUSHER"), plant(&world, "BELT"));
    let (fault, release, restart) = (
        plant(&world, "FAULT"),
        plant(&world, "RELEASE"),
        plant(&world, "RESTART"),
    );
    let node = |role: &str| c.ir.roles.iter().position(|r| r.name == role).expect(role);
    let (pusher_node, belt_node) = (node("PUSHER"), node("BELT"));
    let cabinet = node("CABINET");

    // (1)-(3): automatic start; in step 2 the pusher turns clockwise, the belt forward.
    world.press(start).expect("START");
    world.run_for(1000).expect("runs");
    assert_eq!(world.run(pusher), Some(Run::Clockwise));
    assert_eq!(world.carriage_um(pusher), Some(199_600));
    assert_eq!(world.carriage_um(belt), Some(199_600));

    // (4)-(6): the fault.
    let mark = world.trace().len();
    world.set_switch(fault, true).expect("fault");
    settle(&mut world);
    let after = &world.trace()[mark..];
    // The pusher stops at once: in the engine step of its own node that sensed the fault,
    // before anything crosses the radio.
    let sensed = (after.iter())
        .position(|e| matches!(e.what, What::Input { node, input: 2, level: true } if node == pusher_node))
        .expect("the fault is sensed");
    let stopped = (after.iter())
        .position(
            |e| matches!(e.what, What::Motor { plant, run: Run::Stopped, .. } if plant == pusher),
        )
        .expect("the pusher stops");
    assert!(sensed < stopped);
    assert_eq!(after[sensed].t_ms, after[stopped].t_ms);
    assert!(!after[sensed..stopped]
        .iter()
        .any(|e| matches!(e.what, What::Deliver { .. })));
    // The belt stops one hop later: on the delivery of the pusher's Stopped.
    let braked = (after.iter())
        .position(|e| matches!(e.what, What::Output { node, output: 0, level: true } if node == belt_node))
        .expect("the belt brakes");
    let hops = after[stopped..braked]
        .iter()
        .filter(|e| matches!(e.what, What::Deliver { to, accepted: true, .. } if to == belt_node))
        .count();
    assert_eq!(hops, 1);
    assert_eq!(after[braked].t_ms, after[stopped].t_ms + 2);
    assert_eq!(world.carriage_um(pusher), Some(199_600));
    assert_eq!(world.carriage_um(belt), Some(199_600));

    // (7)-(9): the operator releases the pusher while the fault persists: pusher and belt
    // return home.
    world.press(release).expect("RELEASE");
    settle(&mut world);
    assert_eq!(world.run(pusher), Some(Run::Stopped));
    assert_eq!(world.carriage_um(pusher), Some(0));
    assert_eq!(world.carriage_um(belt), Some(0));

    // The operator's panel latched the fault alarm one hop after the fault; it cannot be
    // acknowledged while the fault persists.
    let pusher_fault = AlarmSource::Declared { index: 0 };
    let alarm = |world: &World| {
        let r = world.alarms(cabinet).expect("the cabinet's alarms");
        (r.alarms.iter())
            .map(|a| (a.source, a.level, a.raised_ms, a.acked, a.persists))
            .collect::<Vec<_>>()
    };
    assert_eq!(
        alarm(&world),
        [(pusher_fault, AlarmLevel::Fault, 1002, false, true)]
    );
    assert_eq!(world.ack(cabinet), Ok(0));

    // A restart is refused while the fault persists.
    world.press(restart).expect("RESTART");
    settle(&mut world);
    assert_eq!(world.run(pusher), Some(Run::Stopped));

    // (10): the fault is cleared; the restart is refused until the operator acknowledges
    // the alarm; then the automatic transport restarts and a full cycle completes.
    world.set_switch(fault, false).expect("cleared");
    settle(&mut world);
    assert_eq!(
        alarm(&world),
        [(pusher_fault, AlarmLevel::Fault, 1002, false, false)]
    );
    let mark = world.trace().len();
    world.press(restart).expect("RESTART");
    settle(&mut world);
    assert_eq!(world.carriage_um(pusher), Some(0));
    let refused: Vec<String> = (world.trace()[mark..].iter())
        .filter(|e| matches!(e.what, What::Refused { .. }))
        .map(|e| format!("{} {}", e.t_ms, e.what))
        .collect();
    assert_eq!(
        refused,
        [format!(
            "{} node {cabinet} refused input 2: a fault alarm is latched",
            world.trace()[mark].t_ms
        )]
    );
    assert_eq!(world.ack(cabinet), Ok(1));
    assert_eq!(
        alarm(&world),
        [(pusher_fault, AlarmLevel::Fault, 1002, true, false)]
    );
    world.press(restart).expect("RESTART");
    settle(&mut world);
    assert_eq!(world.carriage_um(pusher), Some(0));

    assert!(
        !world
            .trace()
            .iter()
            .any(|e| matches!(e.what, What::Fault { .. })),
        "no node faulted"
    );
    world.take_trace()
}

#[test]
fn the_papers_fault_scenario_stops_the_pusher_at_once_and_a_restart_completes_a_cycle() {
    let c = build(&load("../robot-configs/waterjet-transport.ron"));
    let trace = fig9(&c);
    let got = places(&c, &trace);
    let want = [
        // (1)-(3): step 2, the pusher clockwise, the belt forward.
        "    0 Operation: Manual -> Auto",
        "    0 Transport: ReadyToCut -> Step1",
        "    2 Pusher: Stopped -> Clockwise",
        "    4 Transport: Step1 -> Step2",
        "    4 Belt: Stopped -> Forward",
        // (4)-(6): the fault; the pusher stops at once, the belt one hop later.
        " 1000 FaultDetection: Ok -> Faulted",
        " 1000 Pusher: Clockwise -> Stopped",
        " 1002 Operation: Auto -> Halted",
        " 1002 Transport: Step2 -> ReadyToCut",
        " 1002 Belt: Forward -> Stopped",
        // (7)-(9): the release; pusher and belt home (the belt on its own sensor).
        " 1004 Operation: Halted -> Releasing",
        " 1006 Pusher: Stopped -> CounterClockwise",
        // The fault stays latched until its cause is gone: released, it persists.
        " 1006 FaultDetection: Faulted -> Released",
        " 1008 Belt: Stopped -> Back",
        " 2004 Pusher: CounterClockwise -> Stopped",
        " 2004 Belt: Back -> Stopped",
        // (a restart pressed here is refused: the fault persists) the fault is cleared;
        // a restart at 2058 is refused (the alarm is latched), the operator acknowledges,
        // (10): the restart, and a full transport cycle.
        " 2056 FaultDetection: Released -> Ok",
        " 2108 Operation: Releasing -> Auto",
        " 2108 Transport: ReadyToCut -> Step1",
        " 2110 Pusher: Stopped -> Clockwise",
        " 2112 Transport: Step1 -> Step2",
        " 2112 Belt: Stopped -> Forward",
        " 4110 Pusher: Clockwise -> Stopped",
        " 4110 Belt: Forward -> Stopped",
        " 4112 Transport: Step2 -> Step3",
        " 4114 Pusher: Stopped -> CounterClockwise",
        " 4116 Belt: Stopped -> Back",
        " 6114 Pusher: CounterClockwise -> Stopped",
        " 6114 Belt: Back -> Stopped",
        " 6116 Transport: Step3 -> ReadyToCut",
    ];
    assert_eq!(got, want, "{}", got.join("\n"));
}

/// The lanes of an SVG: (kind, name) of every `<g class="lane KIND" data-name="NAME">`.
fn lanes(svg: &str) -> Vec<(String, String)> {
    svg.lines()
        .filter_map(|l| {
            let rest = l.strip_prefix(r#"<g class="lane "#)?;
            let (kind, rest) = rest.split_once('"')?;
            let name = rest.strip_prefix(r#" data-name=""#)?.split('"').next()?;
            Some((kind.to_string(), name.to_string()))
        })
        .collect()
}

/// `sim --timeline` draws fig. 9: a lane per continuous position (the pusher's and the
/// belt's, the same stroke over time), a lane per control function's place (not the
/// `.seen` charts mirroring another node's function), the radio.
#[test]
fn the_timeline_of_fig_9_has_a_lane_per_function_and_per_position() {
    let c = build(&load("../robot-configs/waterjet-transport.ron"));
    let trace = fig9(&c);
    let svg = robot_analysis::timeline::svg(&c, &trace).expect("svg");
    let want = [
        ("position", "PUSHER"),
        ("position", "BELT"),
        ("chart", "CABINET.Operation"),
        ("chart", "CABINET.Transport"),
        ("chart", "PUSHER.Pusher"),
        ("chart", "PUSHER.FaultDetection"),
        ("chart", "BELT.Belt"),
        ("radio", "radio"),
    ];
    let want: Vec<(String, String)> = want
        .iter()
        .map(|(k, n)| (k.to_string(), n.to_string()))
        .collect();
    assert_eq!(lanes(&svg), want);
    // The pusher's position: out to 199.6 mm, stopped by the fault, home, then a full
    // stroke out and back.
    let pusher = svg
        .split(r#"data-name="PUSHER">"#)
        .nth(1)
        .and_then(|s| s.split("points=\"").nth(1))
        .and_then(|s| s.split('"').next())
        .expect("the pusher's polyline");
    assert_eq!(
        pusher,
        "150.0,70.0 150.4,70.0 329.9,57.0 330.9,57.0 510.4,70.0 510.4,70.0 529.5,70.0 889.2,44.0 \
         889.2,44.0 889.9,44.0 1249.6,70.0 1249.6,70.0 1250.0,70.0"
    );
}

/// A pusher whose stroke takes 1,000 s (1,000 mm at 1 mm/s): a cycle may take as long as
/// its plants' strokes too, not only its timers' and actuators' (`sim` gave up at 600 s:
/// "not idle by the time limit").
#[test]
fn a_cycle_of_a_slow_motor_plant_is_simulated_to_its_end() {
    let text = load("../robot-configs/waterjet-transport.ron").text;
    let at = text.find("stroke_mm: ").expect("a motor plant");
    let end = at + text[at..].find(')').expect("its end");
    let slow = format!(
        "{}stroke_mm: 1000, speed_mm_s: 1{}",
        &text[..at],
        &text[end..]
    );
    let c = build(&robot_compiler::Source::new("slow.ron", slow));
    let run = sim::simulate(&c, 1).expect("one cycle");
    let durations: Vec<u64> = run.cycles.iter().map(|c| c.duration_ms).collect();
    assert_eq!(durations, [2_000_008]);
}
