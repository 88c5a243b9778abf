//! `push` on a lossless medium needs no retransmission, however many nodes share the air
//! and however long the tables (issue: 27 to 45 retries per node for the tables of a
//! 64-step, 8-actuator robot, from a timeout shorter than the shared air takes).

mod e2e_support;

use config_schema::limits::MAX_BLOB;
use config_schema::wire::msg::Refusal;
use node_fw::ota::Progress;
use robot_compiler::{compile, Source};
use robot_net::push::{self, Target};

use e2e_support::*;

/// Eight double-acting cylinders A..H on eight nodes, 64 steps.
fn eight_actuators() -> robot_compiler::Compiled {
    let names = ["A", "B", "C", "D", "E", "F", "G", "H"];
    let nodes: Vec<String> = (0..8)
        .map(|i| format!("(name: \"n{i}\", address: {:#06x})", 0x21 + i))
        .collect();
    let assign: Vec<String> = names
        .iter()
        .enumerate()
        .map(|(i, a)| format!("(\"{a}\", \"n{i}\")"))
        .collect();
    let roles: Vec<String> = names
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let start = if i == 0 {
                ", inputs: [(name: \"START\", pin: 4)]"
            } else {
                ""
            };
            format!(
                "(name: \"{a}\", actuators: [(name: \"{a}\", kind: DoubleActing(extend: 0, \
                 retract: 1, home: 2, end: 3, out_ms: 60, back_ms: 60))]{start})"
            )
        })
        .collect();
    let half: Vec<String> = names
        .iter()
        .map(|a| format!("{a}+"))
        .chain(names.iter().map(|a| format!("{a}-")))
        .collect();
    let sequence = vec![half.join(" "); 4].join(" ");
    let text = format!(
        "Robot(name: \"eight\", network: (pan_id: 0x1234, channel: 15), nodes: [{}], \
         assign: [{}], roles: [{}], start: \"START\", sequence: \"{sequence}\", \
         motion_timeout_ms: 2000)",
        nodes.join(", "),
        assign.join(", "),
        roles.join(", ")
    );
    let c = compile::compile(&Source::new("eight.ron", text)).expect("compiles");
    assert_eq!(c.ir.expect.len(), 64);
    c.with_generation(1).expect("re-encodes")
}

#[test]
fn eight_tables_at_once_take_no_retry_on_a_lossless_medium() {
    let c = eight_actuators();
    let mut bed = bring_up(&c, options(medium::Config::default(), None));
    let outcomes = push_and_home(&mut bed, &c);
    let retries: Vec<(String, u32)> = outcomes
        .iter()
        .map(|o| (o.role.clone(), o.stats.retries))
        .collect();
    assert_eq!(
        retries,
        ["A", "B", "C", "D", "E", "F", "G", "H"].map(|r| (r.to_string(), 0))
    );
    assert_running(&mut bed, &c);
    bed.stop();
}

#[test]
fn tables_at_the_blob_limit_take_no_retry_on_a_lossless_medium() {
    let c = eight_actuators();
    let mut bed = bring_up(&c, options(medium::Config::default(), None));
    // Blobs of the largest length a node takes (not tables: every node refuses them at
    // the end, after the whole transfer).
    let targets: Vec<Target> =
        c.ir.roles
            .iter()
            .enumerate()
            .map(|(i, r)| Target {
                role: r.name.clone(),
                addr: r.address,
                blob: vec![i as u8; MAX_BLOB],
                generation: 1,
            })
            .collect();
    let outcomes = push::push(bed.radio(), &targets, false, &mut |_, _, _| {}).expect("push");
    let got: Vec<(Progress, u32, u32)> = outcomes
        .iter()
        .map(|o| (o.progress, o.stats.retries, o.stats.bytes))
        .collect();
    assert_eq!(
        got,
        vec![(Progress::Refused(Refusal::Invalid), 0, MAX_BLOB as u32); 8]
    );
    bed.stop();
}

/// The paint robot (`security: Off`, so the tool runs without keys) on a bed of host
/// nodes, spare included, pushed and homed; `dir` holds the robot files.
fn paint_homed(dir: &TempDir) -> (robot_net::demo::Bed, robot_compiler::Compiled) {
    let (_, paint) = unsecured_robot(dir, "paint-robot.ron");
    let mut opts = options(medium::Config::default(), None);
    opts.secured = false;
    let mut bed = bring_up(&paint, opts);
    push_and_home(&mut bed, &paint);
    (bed, paint)
}

/// VC's cylinder jams from the first step on and the machine is started: VC's watchdog
/// faults it, and every other node on its fault; returns once all are faulted.
fn faulted(bed: &mut robot_net::demo::Bed, paint: &robot_compiler::Compiled) {
    let actuators = robot_net::live_plant::actuators(paint).expect("actuators");
    let vc = actuators.iter().position(|a| a.name == "VC").expect("VC");
    bed.set_plant_injected(
        actuators,
        Some(robot_net::live_plant::Injection {
            after: 0,
            actuator: vc,
            kind: robot_net::live_plant::Jam::Stuck,
        }),
    )
    .expect("plant");
    bed.press_start(paint).expect("START");
    for r in &paint.ir.roles {
        wait_until(bed, r.address, |s| s.fault.is_some());
    }
}

/// What a push says of node-1 released after it ran VC of generation 1.
const RELEASED_VC_1: &str = "node 0x0011 (node-1) plays no role in this robot: released (it \
                             ran VC of generation 1; now no table runs there, its outputs \
                             are off)";

/// The VC role moved to the spare node (`paint-robot-spare-node.ron`, pushed from the
/// command line): the node that lost it kept running its old table (nothing told it
/// otherwise), and a START to it moved the cylinder still wired to it; `push` said
/// nothing of it. Now `push` releases each node of the robot that plays no role in it and
/// still runs one: a table with nothing in it, at once, its outputs low; and says so.
#[test]
fn a_push_releases_a_node_of_the_robot_that_plays_no_role_and_still_runs_one() {
    let dir = TempDir::new("push-lost-role");
    let (mut bed, _) = paint_homed(&dir);
    let (moved, _) = unsecured_robot(&dir, "paint-robot-spare-node.ron");
    let moved = moved.to_str().expect("utf-8 path");
    assert_eq!(status(&mut bed, 0x0011).role.as_str(), "VC");
    let m = bed.medium().addr().to_string();
    // On trial: named, not released (a rollback finds the machine as it was).
    let (code, out, err) = run_tool(&[
        "push",
        moved,
        "--medium",
        &m,
        "--generation",
        "2",
        "--trial",
    ]);
    assert_eq!((code, err.as_str()), (Some(0), ""), "{out}");
    assert_eq!(
        out.lines().last(),
        Some(
            "node 0x0011 (node-1) plays no role in this robot but runs VC of generation 1: \
             released when the trial is confirmed (config-tool confirm)"
        ),
        "{out}"
    );
    assert_eq!(status(&mut bed, 0x0011).role.as_str(), "VC");
    // Confirmed: released.
    let (code, out, err) = run_tool(&["confirm", moved, "--medium", &m]);
    assert_eq!((code, err.as_str()), (Some(0), ""), "{out}");
    assert_eq!(out.lines().last(), Some(RELEASED_VC_1), "{out}");
    let released = status(&mut bed, 0x0011);
    assert_eq!(
        (
            released.role.as_str(),
            released.generation,
            released.states.len()
        ),
        ("", 2, 0)
    );
    let (code, found, _) = run_tool(&["scan", "--medium", &m]);
    assert_eq!(code, Some(0));
    assert!(
        found.contains("0x0011  firmware 1  generation 2  (no role)\n"),
        "{found}"
    );
    // Released, it has nothing to say at the next push; nor once it is off (asked for 1 s,
    // it did not answer: no role moved in this push).
    for generation in ["3", "4"] {
        let (code, out, err) =
            run_tool(&["push", moved, "--medium", &m, "--generation", generation]);
        assert_eq!((code, err.as_str()), (Some(0), ""), "{out}");
        assert_eq!(
            out.lines().last(),
            Some("switched: every node runs the new generation"),
            "{out}"
        );
        bed.kill_node(0x0011);
    }
    bed.stop();
}

/// VC moved to the spare while VC's old node was off (a failed node, sent for repair):
/// the push said nothing of it, and once the node was on again it ran VC beside the spare
/// (its START input and valves live) with `scan` showing it as VC and `status` calling it
/// `not a node of this robot`. Now the push names the silent node and the way to release
/// it, `scan` and `status` say it plays no role but runs VC, and the next push releases it.
#[test]
fn a_node_a_role_moved_away_from_while_it_was_off_is_named_until_released() {
    let dir = TempDir::new("push-off-node");
    let flash = TempDir::new("push-off-node-flash");
    let (_, paint) = unsecured_robot(&dir, "paint-robot.ron");
    let mut opts = options(medium::Config::default(), Some(&flash));
    opts.secured = false;
    let mut bed = bring_up(&paint, opts);
    push_and_home(&mut bed, &paint);
    bed.start_node(0x0015).expect("the spare's process");
    bed.wait_for_nodes(&[0x0015])
        .expect("the spare announces itself");
    let (moved, _) = unsecured_robot(&dir, "paint-robot-spare-node.ron");
    let moved = moved.to_str().expect("utf-8 path");
    let m = bed.medium().addr().to_string();
    bed.kill_node(0x0011);
    let (code, out, err) = run_tool(&["push", moved, "--medium", &m, "--generation", "2"]);
    assert_eq!((code, err.as_str()), (Some(0), ""), "{out}");
    assert_eq!(
        out.lines().last(),
        Some(
            "node 0x0011 (node-1) plays no role in this robot and did not answer: if it is \
             off and runs a table (a role moved away from it), it runs that table again when \
             it is on: push again then to release it"
        ),
        "{out}"
    );
    // On again, from its flash: VC of generation 1.
    bed.start_node(0x0011).expect("node-1 again");
    assert_eq!(status(&mut bed, 0x0011).role.as_str(), "VC");
    let (code, found, _) = run_tool(&["scan", moved, "--medium", &m]);
    assert_eq!(code, Some(0));
    assert!(
        found.contains(
            "0x0011  firmware 1  generation 1  VC  plays no role in this robot but runs VC of \
             generation 1: push again to release it\n"
        ),
        "{found}"
    );
    let (code, said, _) = run_tool(&["status", moved, "--node", "0x0011", "--medium", &m]);
    assert_eq!(code, Some(0));
    assert!(
        said.contains(
            "  homing: plays no role in this robot but runs VC of generation 1: push again to \
             release it\n"
        ),
        "{said}"
    );
    let (code, out, err) = run_tool(&["push", moved, "--medium", &m, "--generation", "3"]);
    assert_eq!((code, err.as_str()), (Some(0), ""), "{out}");
    assert_eq!(out.lines().last(), Some(RELEASED_VC_1), "{out}");
    bed.stop();
}

/// A push to a faulted machine (VC's cylinder jammed: its watchdog faulted it, and the
/// others on its fault) waited the whole `--wait` (60 s) for an idle point a faulted
/// machine never reaches, then said `the machine was not idle within --wait` with no node
/// named. Now it asks the nodes first and says at once which are faulted and the ways
/// out; the tables stay staged, and `--now` switches them.
#[test]
fn a_push_to_a_faulted_machine_names_the_faulted_nodes_at_once() {
    let dir = TempDir::new("push-faulted");
    let (mut bed, paint) = paint_homed(&dir);
    let (dip, _) = unsecured_robot(&dir, "paint-robot-double-dip.ron");
    let dip = dip.to_str().expect("utf-8 path");
    faulted(&mut bed, &paint);
    let m = bed.medium().addr().to_string();
    let (code, out, err) = run_tool(&["push", dip, "--medium", &m, "--generation", "2"]);
    assert_eq!(
        (code, err.as_str()),
        (
            Some(3),
            "error: nodes 0x0011 (VC, 0x81), 0x0012 (GR, 0x82), 0x0013 (HC, 0x82), 0x0014 \
             (RC, 0x82) are faulted: a faulted machine does not reach its idle point, so \
             nothing switched (the tables stay staged): push again with --now to switch at \
             once, or reset each (config-tool reset --node 0x0011; config-tool reset --node \
             0x0012; config-tool reset --node 0x0013; config-tool reset --node 0x0014), \
             acknowledge the alarms (config-tool ack), home, and push again\n"
        ),
        "{out}"
    );
    assert_eq!(
        out.lines().filter(|l| l.ends_with("  staged")).count(),
        4,
        "{out}"
    );
    let (code, out, err) = run_tool(&["push", dip, "--medium", &m, "--generation", "2", "--now"]);
    assert_eq!((code, err.as_str()), (Some(0), ""), "{out}");
    bed.stop();
}

/// After a watchdog's fault, every node reset: `start` said `not homed: run config-tool
/// home`, and `home` then refused for the fault alarm still latched on VC. Now `start`
/// names the alarm first (acknowledging it comes before homing); once acknowledged, it
/// says the machine is not homed.
#[test]
fn a_start_after_the_resets_names_the_latched_alarm_before_homing() {
    let dir = TempDir::new("start-latched");
    let (paint_file, _) = unsecured_robot(&dir, "paint-robot.ron");
    let paint_file = paint_file.to_str().expect("utf-8 path");
    let (mut bed, paint) = paint_homed(&dir);
    faulted(&mut bed, &paint);
    for r in &paint.ir.roles {
        bed.command(r.address, config_schema::wire::msg::Command::Reset)
            .expect("reset");
    }
    let m = bed.medium().addr().to_string();
    let (code, out, err) = run_tool(&["start", paint_file, "--medium", &m]);
    assert_eq!(
        (code, out.as_str(), err.as_str()),
        (
            Some(6),
            "",
            "error: node 0x0011 (VC) has a fault alarm latched: chart `fault`: its motion \
             watchdog expired (code 0x81) (not acknowledged: config-tool ack), then home \
             (config-tool home); START was not sent\n"
        )
    );
    bed.alarms(&paint, true).expect("acknowledged");
    let (code, _, err) = run_tool(&["start", paint_file, "--medium", &m]);
    assert_eq!(
        (code, err.as_str()),
        (
            Some(6),
            "error: not homed: run config-tool home; START was not sent\n"
        )
    );
    bed.stop();
}

/// A push while the machine is under way and stays so (HC's end switch never closes, its
/// watchdog ten minutes): the switch-over waited out `--wait` and said `the machine was
/// not idle within --wait`, every node `staged, not switched`, with no word of which
/// node kept it. Now the nodes that were not at their idle point are named, on their
/// lines and in the error.
#[test]
fn a_push_that_finds_no_idle_point_names_the_nodes_under_way() {
    let dir = TempDir::new("push-not-idle");
    let (bed, _) = under_way_for_good(&dir);
    let (dip, _) = unsecured_robot(&dir, "paint-robot-double-dip.ron");
    let dip = dip.to_str().expect("utf-8 path");
    let m = bed.medium().addr().to_string();
    let (code, out, err) = run_tool(&[
        "push",
        dip,
        "--medium",
        &m,
        "--generation",
        "2",
        "--wait",
        "1",
    ]);
    assert_eq!(code, Some(3), "{out}");
    // HC waits for its end switch; VC and GR wait at points of the cycle under way; RC,
    // whose steps come later, rests at its idle point.
    let ends: Vec<&str> = (out.lines())
        .filter(|l| l.contains("staged, not switched"))
        .map(|l| l.split_once("  staged").map_or(l, |(_, end)| end))
        .collect();
    let under_way = ", not switched: not at its idle point";
    assert_eq!(
        ends,
        [under_way, under_way, under_way, ", not switched"],
        "{out}"
    );
    assert_eq!(
        err,
        "error: the machine was not idle within --wait: 0x0011 (VC), 0x0012 (GR), 0x0013 \
         (HC) were not at their idle points; nothing switched (the tables stay staged; push \
         again, or --now for a stopped machine)\n"
    );
    bed.stop();
}
