//! `compile`, `dump`, `diagram` and `sim` of the robot-configs and small robots: every
//! config compiles deterministically and reproduces its declared sequence for 20 cycles
//! through its compiled blobs; the radio plan of the paint robot; role reassignment only
//! changes peer addresses; interlocks, watchdog faults and sequence diffs in `sim`.

use node_fw::sim::World;
use robot_analysis::sim;
use robot_compiler::{diagram, dump, Source};

mod common;
use common::{build, load};

fn configs() -> Vec<String> {
    (common::robot_configs().into_iter())
        .map(|n| format!("../robot-configs/{n}"))
        .collect()
}

#[test]
fn every_config_reproduces_its_sequence_for_20_cycles_through_its_blobs() {
    // A sorting station sorts a feed instead of repeating a cycle: tests/sorter.rs.
    let mut sequences = 0;
    for path in configs()
        .into_iter()
        .filter(|p| !p.ends_with("ball-sorter.ron"))
    {
        let c = build(&load(&path));
        // Robots of control functions declare no sequence (the water-jet transport):
        // tested on their own.
        if c.ir.expect.is_empty() {
            continue;
        }
        sequences += 1;
        let result = sim::simulate(&c, 20).expect("sim runs");
        assert!(result.ok(), "{path}\n{}", result.report());
        assert_eq!(result.cycles.len(), 20, "{path}");
        let declared = &c.ir.expect;
        assert!(declared.len() >= 12, "{path}");
        for cycle in &result.cycles {
            assert_eq!(&cycle.steps, declared, "{path}");
            assert!(cycle.faults.is_empty(), "{path}");
        }
    }
    assert_eq!(sequences, 7);
}

/// The water-jet transport (control functions, a motor plant) runs 20 transport cycles
/// through its blobs: each turns the pusher out and back, the same time, no fault.
#[test]
fn the_waterjet_transport_runs_20_cycles_through_its_blobs() {
    let c = build(&load("../robot-configs/waterjet-transport.ron"));
    let result = sim::simulate(&c, 20).expect("sim runs");
    assert!(result.ok(), "{}", result.report());
    assert_eq!(result.cycles.len(), 20);
    for cycle in &result.cycles {
        let steps: Vec<String> = cycle.steps.iter().map(|s| s.to_string()).collect();
        assert_eq!(steps, ["PUSHER+", "PUSHER-"]);
        assert_eq!(cycle.duration_ms, 4008);
        assert_eq!(cycle.publications, 10);
        assert!(cycle.faults.is_empty());
    }
}

/// The counted robot's chart types give the cycle its parameters ask for.
#[test]
fn parameterised_charts_follow_their_parameters() {
    let base = load("../robot-configs/paint-robot-counted.ron");
    for (dips, shakes) in [(1, 1), (2, 2), (3, 1), (1, 3), (4, 2)] {
        let mut steps = vec!["VC+", "GR+", "VC-", "HC+"];
        for _ in 0..dips {
            steps.extend(["VC+", "VC-"]);
        }
        for _ in 0..shakes {
            steps.extend(["RC+", "RC-"]);
        }
        steps.extend(["HC-", "VC+", "GR-", "VC-"]);
        let expect = steps.join(" ");
        let text = base
            .text
            .replace("\"DIPS\": 2", &format!("\"DIPS\": {dips}"))
            .replace("\"SHAKES\": 2", &format!("\"SHAKES\": {shakes}"))
            .replace(
                "expect: \"VC+ GR+ VC- HC+ VC+ VC- VC+ VC- RC+ RC- RC+ RC- HC- VC+ GR- VC-\"",
                &format!("expect: \"{expect}\""),
            );
        let c = build(&Source::new("counted.ron", text));
        let result = sim::simulate(&c, 5).expect("sim runs");
        assert!(result.ok(), "{dips} {shakes}\n{}", result.report());
        for cycle in &result.cycles {
            assert_eq!(sim::steps_text(&cycle.steps), expect);
        }
    }
}

#[test]
fn compile_is_byte_for_byte_deterministic() {
    for path in configs() {
        let a = build(&load(&path));
        let b = build(&load(&path));
        assert_eq!(a.blobs, b.blobs, "{path}");
        assert_eq!(a.tables, b.tables, "{path}");
    }
}

#[test]
fn every_blob_decodes_to_the_table_it_was_compiled_from() {
    for path in configs() {
        let c = build(&load(&path));
        for (blob, table) in c.blobs.iter().zip(&c.tables) {
            assert_eq!(
                &config_schema::decode(blob).expect("decodes"),
                table,
                "{path}"
            );
        }
    }
}

#[test]
fn the_paint_robot_sends_nine_step_events_per_cycle_each_to_one_node() {
    let c = build(&load("../robot-configs/paint-robot.ron"));
    let radio: Vec<String> = robot_compiler::compile::radio_events(&c.ir)
        .into_iter()
        .map(|(from, ev, to)| format!("{from}->{to}:{ev}"))
        .collect();
    assert_eq!(
        radio,
        [
            "VC->GR:step1.done",
            "VC->HC:step3.done",
            "VC->RC:step6.done",
            "VC->GR:step10.done",
            "GR->VC:step11.done",
            "GR->VC:step2.done",
            "HC->VC:step9.done",
            "HC->VC:step4.done",
            "RC->HC:step8.done",
        ]
    );
    let result = sim::simulate(&c, 3).expect("sim runs");
    for cycle in &result.cycles {
        assert_eq!(cycle.publications, 9);
    }
    // Each step event goes to exactly one subscriber; `fault` (sent only on a watchdog
    // fault) goes to every other role.
    for (t, r) in c.tables.iter().zip(&c.ir.roles) {
        for p in &t.publications {
            let fault = r.events[usize::from(p.event)] == "fault";
            assert_eq!(p.subscribers.count_ones(), if fault { 3 } else { 1 });
        }
    }
}

#[test]
fn moving_a_role_to_the_spare_node_changes_only_peer_addresses() {
    let a = build(&load("../robot-configs/paint-robot.ron"));
    let b = build(&load("../robot-configs/paint-robot-spare-node.ron"));
    // VC's own table does not contain its address: byte-identical.
    assert_eq!(a.blobs[0], b.blobs[0]);
    assert_eq!(a.ir.roles[0].address, 0x0011);
    assert_eq!(b.ir.roles[0].address, 0x0015);
    for (ta, tb) in a.tables.iter().zip(&b.tables).skip(1) {
        let mut patched = ta.clone();
        for p in patched.peers.iter_mut() {
            if *p == 0x0011 {
                *p = 0x0015;
            }
        }
        assert_eq!(&patched, tb);
        assert_ne!(ta.peers, tb.peers);
    }
}

#[test]
fn a_start_during_a_cycle_is_ignored_until_the_cycle_is_complete() {
    // A+ B+ A- B-: A is home again before B-, so A waits in CYCLE_END for step4.done.
    let c = build(&load("fixtures/small-sequence.ron").clone_with("A+ B+ B- A-", "A+ B+ A- B-"));
    let (plants, button) = sim::plants(&c).expect("plants");
    let specs = robot_analysis::sim::node_specs(&c, &c.tables);
    let mut world = World::new(&specs, plants).expect("world");
    world.press(button).expect("press");
    // Press again every 100 ms while the cycle runs (A+ 0-200 ms, B+ 202-402, A- 402-602,
    // B- 604-804): never a second A+, even after A is home at 602.
    for _ in 0..7 {
        world.run_for(100).expect("runs");
        world.press(button).expect("press");
    }
    world.run_until_idle(60_000).expect("idle");
    assert_eq!(world.steps(), ["A+", "B+", "A-", "B-"]);
    // After the cycle, START works again.
    world.press(button).expect("press");
    world.run_until_idle(60_000).expect("idle");
    assert_eq!(
        world.steps(),
        ["A+", "B+", "A-", "B-", "A+", "B+", "A-", "B-"]
    );
}

trait CloneWith {
    fn clone_with(&self, from: &str, to: &str) -> Source;
}

impl CloneWith for Source {
    fn clone_with(&self, from: &str, to: &str) -> Source {
        assert!(self.text.contains(from));
        Source::new(self.name.clone(), self.text.replacen(from, to, 1))
    }
}

#[test]
fn a_motion_that_outlasts_its_timeout_faults_the_node_and_fails_sim() {
    let src = load("fixtures/small-sequence.ron").clone_with(
        "(name: \"B\", kind: DoubleActing(extend: 0, retract: 1, home: 2, end: 3))",
        "(name: \"B\", kind: DoubleActing(extend: 0, retract: 1, home: 2, end: 3, out_ms: 2500))",
    );
    // With its own, longer timeout the slow cylinder is fine.
    let slow_ok = src.clone_with("out_ms: 2500)", "out_ms: 2500, timeout_ms: 3000)");
    let result = sim::simulate(&build(&slow_ok), 3).expect("sim runs");
    assert!(result.ok(), "{}", result.report());
    let c = build(&src);
    let result = sim::simulate(&c, 3).expect("sim runs");
    assert!(!result.ok());
    assert_eq!(result.cycles.len(), 1, "stops at the first bad cycle");
    let cycle = &result.cycles[0];
    // B+ started, never reached its end switch within 2000 ms: B's node faulted, its
    // outputs went safe, it published `fault`, and A faulted on it one radio hop later
    // (code 2); nothing else moved.
    assert_eq!(sim::steps_text(&cycle.steps), "A+ B+");
    assert_eq!(
        cycle.faults,
        [
            "at 2202 ms: role B faulted: Action { chart: 1, code: 1 }",
            "at 2204 ms: role A faulted: Action { chart: 1, code: 2 }"
        ]
    );
}

#[test]
fn sim_reports_a_readable_diff_when_the_sequence_differs() {
    let src = load("fixtures/small-charts.ron")
        .clone_with("expect: \"A+ B+ B- A-\"", "expect: \"A+ B+ A- B-\"");
    let c = build(&src);
    let result = sim::simulate(&c, 2).expect("sim runs");
    assert!(!result.ok());
    assert_eq!(
        result.report(),
        "cycle   1:    804 ms   2 publications  A+ B+ B- A-\n  \
         step  expected  observed\n     \
         1  A+        A+      \n     \
         2  B+        B+      \n     \
         3  A-        B-        <-- differs\n     \
         4  B-        A-        <-- differs\n\
         FAILED: 1 of 1 cycle(s) differ from the declared sequence\n"
    );
}

#[test]
fn dump_shows_the_decoded_table_and_names_a_bad_blob_clearly() {
    let c = build(&load("fixtures/small-sequence.ron"));
    let text = dump::dump(&c.blobs[1]).expect("dumps");
    let expected = format!(
        "blob: {} bytes (payload {}), schema 7, generation 0, CRC-32 {:#010x}\n",
        c.blobs[1].len(),
        c.blobs[1].len() - 12,
        u32::from_le_bytes(c.blobs[1][c.blobs[1].len() - 4..].try_into().expect("4"))
    ) + "role B  generation 0  pan 0x0101  channel 11
events 10  start -  home -  boot e9
input in0: pin 2  rise e0  fall -  mirror -
input in1: pin 3  rise e1  fall -  mirror -
output out0: pin 0  fault 0  start 0  home 0
output out1: pin 1  fault 0  start 0  home 1
timer t0: expiry e2
chart 0: 3 inputs, initial S0, idle S0
  S0: cancel t0; emit e3
  S1: drive out0=1,out1=0; start t0 2000 ms
  S2: drive out0=0,out1=1; start t0 2000 ms
  T0: S0 --in0--> S1
  T1: S1 --in1--> S2
  T2: S2 --in2--> S0
chart 1: 2 inputs, initial S0, idle S0
  S0: 
  S1: emit e4; fault 1
  S2: fault 2
  T3: S0 --in0--> S1
  T4: S0 --in1--> S2
chart 2: 2 inputs, initial S0, idle S0
  S0: 
  S1: drive out0=0,out1=1; start t0 2000 ms
  S2: cancel t0; emit e5
  T5: S0 --in0 [in0]--> S2
  T6: S0 --in0--> S1
  T7: S1 --in1--> S2
  T8: S2 --(no event)--> S0
route e6 -> chart 0 in0
route e1 -> chart 0 in1
route e0 -> chart 0 in2
route e2 -> chart 1 in0
route e7 -> chart 1 in1
route e8 -> chart 2 in0
route e0 -> chart 2 in1
peer p0: 0x0001
publish e3 as topic 0 to peers 0b00000001
publish e4 as topic 1 to peers 0b00000001
publish e5 as topic 2 to peers 0b00000001
publish e9 as topic 3 to peers 0b00000001
subscribe p0 topic 0 -> e6
subscribe p0 topic 1 -> e7
subscribe p0 topic 2 -> e8
safety: estop -  on link alarm stall  restart -
";
    assert_eq!(text, expected);
    let mut bad = c.blobs[1].clone();
    bad[20] ^= 0x40;
    let err = dump::dump(&bad).expect_err("corrupt");
    assert!(
        err.to_string().starts_with("CRC mismatch: stored 0x"),
        "{err}"
    );
    assert_eq!(
        dump::dump(b"ECCT\x01\x00").expect_err("short").to_string(),
        "truncated blob: 6 bytes, need 12"
    );
    assert_eq!(
        dump::dump(&[0u8; 20]).expect_err("magic").to_string(),
        "not a table blob (bad magic)"
    );
}

#[test]
fn diagram_draws_states_with_actions_and_labelled_transitions() {
    let c = build(&load("fixtures/small-charts.ron"));
    assert_eq!(
        diagram::dot(&c.ir, "A").expect("dot"),
        r#"digraph "A" {
  rankdir=LR;
  node [shape=box, style=rounded, fontname="Helvetica"];
  edge [fontname="Helvetica", fontsize=10];
  outputs [shape=note, label="outputs: fault / start / home\l  A.extend (pin 0): 0 / 0 / 0\l  A.retract (pin 1): 0 / 0 / 1\l"];
  subgraph cluster_0 {
    label="a";
    c0s0 [label="IDLE", peripheries=2, style=bold];
    c0s1 [label="OUT\l  drive A+\l  a.count := count + 1\l"];
    c0s2 [label="IN\l  drive A-\l"];
    c0s0 -> c0s1 [label="GO [count < M || true]"];
    c0s1 -> c0s2 [label="BACK"];
    c0s2 -> c0s0 [label="[true]"];
  }
}
"#
    );
    assert_eq!(
        diagram::dot(&c.ir, "Z").expect_err("no role").to_string(),
        "unknown role `Z` (roles: A, B)"
    );
}

/// A sequence robot with a plant on an input its synthesised charts do not read (a door
/// button, wired and declared, not yet used): `check` took it, then `sim` and `verify`
/// failed (`plant DOOR: no input DOOR on role VC`). The node reads the input; nothing
/// listens to it.
#[test]
fn a_plant_on_an_input_the_sequence_does_not_read_simulates() {
    let src = load("../robot-configs/paint-robot.ron");
    let text = src
        .text
        .replace(
            "inputs: [(name: \"START\", pin: 4)],",
            "inputs: [(name: \"START\", pin: 4), (name: \"DOOR\", pin: 5)],",
        )
        .replace(
            "    start: \"START\",",
            "    plants: [Button(name: \"DOOR\", role: \"VC\", input: \"DOOR\")],\n    start: \"START\",",
        );
    let c = build(&Source::new("door.ron", text));
    let vc = &c.ir.roles[0];
    assert!(vc
        .inputs
        .iter()
        .any(|i| i.name == "DOOR" && i.pin == 5 && i.rise.is_none()));
    let r = sim::simulate(&c, 2).expect("simulates");
    assert!(r.ok(), "{}", r.report());
    let v = robot_analysis::verify::verify(&c, robot_analysis::verify::ExploreOptions::default())
        .expect("model builds");
    assert!(v.ok(), "{}", v.render("door", 0));
}

/// `dump` shows the table's safety declarations: the restart input and the declared alarm
/// with its condition (two blobs that differed only there dumped the same text).
#[test]
fn dump_shows_the_safety_declarations() {
    let c = build(&load("../robot-configs/waterjet-transport.ron"));
    let cabinet =
        c.ir.roles
            .iter()
            .position(|r| r.name == "CABINET")
            .expect("CABINET");
    let text = dump::dump(&c.blobs[cabinet]).expect("dumps");
    let safety: Vec<&str> = text
        .lines()
        .skip_while(|l| !l.starts_with("safety:"))
        .collect();
    assert_eq!(
        safety,
        [
            // RESTART is the cabinet's third input; places Faulted and Released are 1 and
            // 2 of FaultDetection, whose state is v2.
            "safety: estop -  on link alarm stall  restart in2",
            "alarm a0: Fault when v2 == 1 || v2 == 2",
        ],
        "{text}"
    );
}
