//! The sequence synthesiser: for each sequence of a table (2..8 actuators, repeated steps,
//! back-to-back steps, actuators sharing a node, sensorless actuators), the compiled blobs
//! run in the simulator produce exactly that sequence, cycle after cycle, without a fault.

use robot_analysis::sim;
use robot_compiler::{compile, Source};

/// An actuator of a generated robot: name, role, double acting (else single acting).
struct Act(&'static str, &'static str, bool);

/// A robot for `sequence` with the given actuators; the START button is on `start_role`.
fn robot(sequence: &str, acts: &[Act], start_role: &str) -> String {
    let mut roles: Vec<&str> = acts.iter().map(|a| a.1).collect();
    roles.push(start_role);
    roles.dedup();
    let mut uniq: Vec<&str> = Vec::new();
    for r in roles {
        if !uniq.contains(&r) {
            uniq.push(r);
        }
    }
    let mut nodes = String::new();
    let mut assign = String::new();
    let mut role_text = String::new();
    for (i, r) in uniq.iter().enumerate() {
        nodes += &format!("(name: \"n{i}\", address: {}),\n", 0x20 + i);
        assign += &format!("(\"{r}\", \"n{i}\"),\n");
        let mut actuators = String::new();
        let mut pin = 0;
        for a in acts.iter().filter(|a| a.1 == *r) {
            if a.2 {
                actuators += &format!(
                    "(name: \"{}\", kind: DoubleActing(extend: {}, retract: {}, home: {}, end: {}, out_ms: {}, back_ms: {})),\n",
                    a.0,
                    pin,
                    pin + 1,
                    pin + 2,
                    pin + 3,
                    100 + 10 * pin,
                    120 + 10 * pin
                );
                pin += 4;
            } else {
                actuators += &format!(
                    "(name: \"{}\", kind: SingleActing(valve: {pin}, dwell_ms: 90, out_ms: 60, back_ms: 60)),\n",
                    a.0
                );
                pin += 1;
            }
        }
        let inputs = if *r == start_role {
            format!("inputs: [(name: \"START\", pin: {pin})],")
        } else {
            String::new()
        };
        role_text += &format!("(name: \"{r}\", actuators: [{actuators}], {inputs}),\n");
    }
    format!(
        "Robot(name: \"gen\", network: (pan_id: 0x4242, channel: 20),\n\
         nodes: [{nodes}], assign: [{assign}], roles: [{role_text}],\n\
         start: \"START\", sequence: \"{sequence}\")\n"
    )
}

fn each_on_own(names: &[&'static str]) -> Vec<Act> {
    names.iter().map(|n| Act(n, n, true)).collect()
}

/// Compiles, simulates `cycles` cycles, and returns (steps of each cycle, publications of
/// each cycle).
fn run(text: &str, cycles: usize) -> (Vec<String>, Vec<usize>) {
    let src = Source::new("gen.ron", text);
    let compiled = match compile(&src) {
        Ok(c) => c,
        Err(d) => panic!(
            "{}\n{}",
            text,
            d.iter()
                .map(|d| d.short(&src))
                .collect::<Vec<_>>()
                .join("\n")
        ),
    };
    let result = sim::simulate(&compiled, cycles).expect("simulation runs");
    assert!(result.ok(), "{}\n{}", text, result.report());
    (
        result
            .cycles
            .iter()
            .map(|c| sim::steps_text(&c.steps))
            .collect(),
        result.cycles.iter().map(|c| c.publications).collect(),
    )
}

/// (sequence, actuators, start role, publications per cycle)
fn table() -> Vec<(&'static str, Vec<Act>, &'static str, usize)> {
    vec![
        // Textbook two-cylinder cycles.
        ("A+ B+ B- A-", each_on_own(&["A", "B"]), "A", 2),
        ("A+ B+ A- B-", each_on_own(&["A", "B"]), "A", 4),
        ("A+ A- B+ B-", each_on_own(&["A", "B"]), "A", 2),
        // Back-to-back steps on one node: nothing crosses the radio.
        (
            "A+ B+ A- B-",
            vec![Act("A", "R", true), Act("B", "R", true)],
            "R",
            0,
        ),
        // START on a node that moves nothing: its START chart publishes `cycle.start` and
        // waits for step 1's `cycle.done`.
        ("A+ B+ B- A-", each_on_own(&["A", "B"]), "PANEL", 4),
        // START on the last step's node: step 1's `cycle.done` reopens the gate there
        // too (its own `step4.done` once did, one publication less, and a press before
        // HOME then started a cycle after homing).
        ("A+ B+ A- B-", each_on_own(&["A", "B"]), "B", 6),
        // Three and four actuators.
        ("A+ B+ C+ A- B- C-", each_on_own(&["A", "B", "C"]), "A", 6),
        ("A+ B+ C+ C- B- A-", each_on_own(&["A", "B", "C"]), "A", 4),
        (
            "A+ B+ C+ D+ D- C- B- A-",
            each_on_own(&["A", "B", "C", "D"]),
            "A",
            6,
        ),
        (
            "A+ C+ B+ A- D+ D- C- B-",
            each_on_own(&["A", "B", "C", "D"]),
            "A",
            7,
        ),
        // Repeated steps: the same actuator several times per cycle (double dip).
        ("A+ B+ B- B+ B- A-", each_on_own(&["A", "B"]), "A", 2),
        ("A+ A- B+ A+ A- B-", each_on_own(&["A", "B"]), "A", 4),
        // A sensorless (dwell-timed) actuator first and in the middle.
        (
            "G+ A+ G- A-",
            vec![Act("G", "G", false), Act("A", "A", true)],
            "G",
            4,
        ),
        // The paper's robot.
        (
            "VC+ GR+ VC- HC+ VC+ VC- RC+ RC- HC- VC+ GR- VC-",
            vec![
                Act("VC", "VC", true),
                Act("GR", "GR", false),
                Act("HC", "HC", true),
                Act("RC", "RC", true),
            ],
            "VC",
            9,
        ),
        // Eight actuators, two per node.
        (
            "A+ B+ C+ D+ E+ F+ G+ H+ H- G- F- E- D- C- B- A-",
            vec![
                Act("A", "R1", true),
                Act("B", "R1", true),
                Act("C", "R2", true),
                Act("D", "R2", true),
                Act("E", "R3", true),
                Act("F", "R3", true),
                Act("G", "R4", true),
                Act("H", "R4", false),
            ],
            "R1",
            6,
        ),
    ]
}

#[test]
fn every_sequence_of_the_table_is_reproduced_in_simulation() {
    let table = table();
    assert!(table.len() >= 12);
    for (sequence, acts, start, publications) in table {
        let text = robot(sequence, &acts, start);
        let (cycles, pubs) = run(&text, 5);
        assert_eq!(cycles, vec![sequence.to_string(); 5], "{sequence}");
        assert_eq!(pubs, vec![publications; 5], "publications of {sequence}");
    }
}

/// With START on any role (also one that moves nothing), every sequence of the table passes
/// `verify --start-anytime`: a press during a cycle costs no publication, so no link fills.
#[test]
fn every_sequence_of_the_table_passes_verify_with_start_anytime_and_start_on_any_node() {
    use robot_analysis::verify::{verify, ExploreOptions};
    for (sequence, acts, _, _) in table() {
        let mut starts: Vec<&str> = acts.iter().map(|a| a.1).collect();
        starts.dedup();
        starts.push("PANEL");
        for start in starts {
            let text = robot(sequence, &acts, start);
            let src = Source::new("gen.ron", text.as_str());
            let c = compile(&src).unwrap_or_else(|_| panic!("{text}"));
            let opts = ExploreOptions {
                start_anytime: true,
                ..ExploreOptions::default()
            };
            let r = verify(&c, opts).expect("model builds");
            assert!(r.ok(), "START on {start}\n{}", r.render("gen.ron", 0));
        }
    }
}

mod random {
    use super::*;
    use proptest::prelude::*;

    const NAMES: [&str; 8] = ["A", "B", "C", "D", "E", "F", "G", "H"];

    /// A valid random cycle over `n` actuators: each step toggles one actuator (so `+` is
    /// always on one at home and `-` on one that is out), every actuator moves, and the
    /// cycle ends with all of them home.
    fn cycle(n: usize, picks: &[usize]) -> Vec<String> {
        let mut out = vec![false; n];
        let mut steps = Vec::new();
        let toggle = |a: usize, out: &mut Vec<bool>, steps: &mut Vec<String>| {
            out[a] = !out[a];
            steps.push(format!("{}{}", NAMES[a], if out[a] { '+' } else { '-' }));
        };
        for a in 0..n {
            toggle(a, &mut out, &mut steps);
            if let Some(&p) = picks.get(a) {
                // Interleave some random toggles early, so actuators overlap.
                toggle(p % n, &mut out, &mut steps);
            }
        }
        for &p in picks.iter().skip(n) {
            toggle(p % n, &mut out, &mut steps);
        }
        for a in 0..n {
            if out[a] {
                toggle(a, &mut out, &mut steps);
            }
        }
        steps
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, .. ProptestConfig::default() })]

        /// Any valid cycle of 2..8 actuators, on 1..n nodes, double or single acting,
        /// with START on any node, is reproduced exactly for 3 cycles.
        #[test]
        fn any_valid_cycle_is_reproduced(
            n in 2usize..=8,
            picks in proptest::collection::vec(0usize..8, 0..16),
            nodes in proptest::collection::vec(0usize..8, 8),
            single in proptest::collection::vec(proptest::bool::weighted(0.25), 8),
            start in 0usize..8,
        ) {
            let steps = cycle(n, &picks);
            let roles = ["R0", "R1", "R2", "R3", "R4", "R5", "R6", "R7"];
            let acts: Vec<Act> = (0..n)
                .map(|a| Act(NAMES[a], roles[nodes[a] % n], !single[a]))
                .collect();
            let sequence = steps.join(" ");
            let text = robot(&sequence, &acts, roles[start % n]);
            let (cycles, _) = run(&text, 3);
            prop_assert_eq!(cycles, vec![sequence; 3]);
        }
    }
}

/// Compiles a generated robot or panics with its diagnostics.
fn compiled(text: &str) -> robot_compiler::Compiled {
    let src = Source::new("gen.ron", text);
    compile(&src).unwrap_or_else(|d| {
        panic!(
            "{text}\n{}",
            d.iter()
                .map(|d| d.short(&src))
                .collect::<Vec<_>>()
                .join("\n")
        )
    })
}

/// Every sequence of the table, with START on each role and on a panel: stopped half way
/// through a cycle and reset (every chart in its initial state, the actuators where they
/// stopped), a START moves nothing; HOME runs the homing steps of the actuators away from
/// home, in homing order, and leaves every chart idle and every actuator home; the next
/// START gives exactly one cycle.
#[test]
fn every_sequence_of_the_table_homes_from_half_way_through_a_cycle() {
    use node_fw::cylinder::Position;
    let mut homed_steps = 0;
    for (sequence, acts, _, _) in table() {
        let mut starts: Vec<&str> = acts.iter().map(|a| a.1).collect();
        starts.dedup();
        starts.push("PANEL");
        for start in starts {
            let text = robot(sequence, &acts, start);
            let c = compiled(&text);
            let tables = sim::tables(&c).expect("tables");
            let (mut world, button) = sim::world(&c, &tables).expect("world");
            let full = world.run_cycle(button, 60_000).expect("a cycle");
            assert_eq!(full.steps.join(" "), sequence, "{text}");
            // Half way through the next cycle: every node reset.
            world.press(button).expect("press");
            world
                .run_for((full.end_ms - full.start_ms) / 2)
                .expect("runs");
            for node in 0..world.node_count() {
                world.reset(node).expect("reset");
            }
            world.run_until_idle(60_000).expect("settles");
            let actuators: Vec<usize> = (0..world.plants().len())
                .filter(|&p| world.plants()[p].travel().is_some())
                .collect();
            let away: Vec<String> = actuators
                .iter()
                .filter(|&&p| world.position(p) != Some(Position::Home))
                .map(|&p| world.plants()[p].name().to_string())
                .collect();
            // Not homed: a START moves nothing.
            let mark = world.trace().len();
            world.press(button).expect("press");
            world.run_until_idle(60_000).expect("settles");
            let moved: Vec<_> = world.trace()[mark..]
                .iter()
                .filter_map(|e| sim::step_of(&e.what))
                .collect();
            assert_eq!(
                moved,
                [],
                "START before homing, {sequence} START on {start}"
            );
            // HOME.
            let home = c.ir.home.expect("a sequence robot homes");
            let mark = world.trace().len();
            world.home(home).expect("home");
            world.run_until_idle(60_000).expect("homes");
            let homed: Vec<String> = world.trace()[mark..]
                .iter()
                .filter_map(|e| sim::step_of(&e.what))
                .map(|s| s.to_string())
                .collect();
            // Switched actuators already home are skipped; a sensorless one is driven home
            // and waited for, which moves it only if it is away.
            let want: Vec<String> =
                c.ir.homing
                    .iter()
                    .filter(|s| away.contains(&s.actuator))
                    .map(|s| s.to_string())
                    .collect();
            assert_eq!(homed, want, "{sequence}, START on {start}, away: {away:?}");
            homed_steps += homed.len();
            for &p in &actuators {
                assert_eq!(world.position(p), Some(Position::Home), "{sequence}");
            }
            for (node, t) in tables.iter().enumerate() {
                let idle: Vec<u8> = t.charts.iter().map(|ch| ch.idle).collect();
                assert_eq!(world.states(node), idle, "{sequence}: node {node} idle");
            }
            let next = world.run_cycle(button, 60_000).expect("a cycle");
            assert_eq!(
                next.steps.join(" "),
                sequence,
                "after homing, START on {start}"
            );
        }
    }
    assert!(
        homed_steps > 20,
        "the cycles stopped with actuators away: {homed_steps}"
    );
}

/// A power cut of one node alone (GR's, whose monostable valve drops the part): at rest, the
/// machine is no longer homed (VC's chart is back in `UNHOMED`; a START moves nothing; HOME
/// then an exact cycle); during a cycle (after GR's first step, HC+ under way) GR's
/// greeting faults the nodes under way (VC, HC: `0x86`) and nothing more moves (before,
/// the cycle ran on to `VC+` of step 10 and stalled there, waiting for GR-); after a reset
/// the machine is not homed.
#[test]
fn a_power_cut_of_one_node_unhomes_the_machine_at_rest_and_faults_a_cycle_under_way() {
    let text = std::fs::read_to_string(format!(
        "{}/../robot-configs/paint-robot.ron",
        env!("CARGO_MANIFEST_DIR")
    ))
    .expect("paint robot");
    let c = compiled(&text);
    let tables = sim::tables(&c).expect("tables");
    let (mut world, button) = sim::world(&c, &tables).expect("world");
    let role = |name: &str| {
        c.ir.roles
            .iter()
            .position(|r| r.name == name)
            .expect("role")
    };
    let (vc, gr) = (role("VC"), role("GR"));
    let home = c.ir.home.expect("home");
    let sequence = "VC+ GR+ VC- HC+ VC+ VC- RC+ RC- HC- VC+ GR- VC-";
    let cycle =
        |w: &mut node_fw::sim::World| w.run_cycle(button, 60_000).expect("cycle").steps.join(" ");
    assert_eq!(cycle(&mut world), sequence);
    // At rest.
    world.reboot(gr).expect("reboot");
    world.run_until_idle(60_000).expect("settles");
    assert_eq!(
        world.states(vc)[0],
        tables[vc].charts[0].initial,
        "VC not homed"
    );
    let steps = |w: &node_fw::sim::World, from: usize| {
        w.trace()[from..]
            .iter()
            .filter_map(|e| sim::step_of(&e.what))
            .map(|s| s.to_string())
            .collect::<Vec<_>>()
    };
    let mark = world.trace().len();
    world.press(button).expect("press");
    world.run_until_idle(60_000).expect("settles");
    assert_eq!(steps(&world, mark), Vec::<String>::new());
    world.home(home).expect("home");
    world.run_until_idle(60_000).expect("homes");
    assert_eq!(cycle(&mut world), sequence);
    // During a cycle, after VC+ GR+ VC- HC+: GR's chart waits for `step1.done` again.
    let mark = world.trace().len();
    world.press(button).expect("press");
    while steps(&world, mark).len() < 4 {
        world.step().expect("runs");
    }
    world.reboot(gr).expect("reboot");
    world.run_until_idle(60_000).expect("stops");
    assert_eq!(
        steps(&world, mark).join(" "),
        "VC+ GR+ VC- HC+",
        "nothing moves after the restart"
    );
    let faults: Vec<(String, Option<u8>)> = (0..world.node_count())
        .map(|n| {
            let fault = world.engine(n).fault().map(node_fw::node::fault_code);
            (c.ir.roles[n].name.clone(), fault)
        })
        .collect();
    let restarted = 0x80 | config_schema::alarm::FAULT_PEER_RESTART;
    let expected: Vec<(String, Option<u8>)> = [
        ("VC", Some(restarted)),
        ("GR", None),
        ("HC", Some(restarted)),
        ("RC", None),
    ]
    .into_iter()
    .map(|(r, f)| (r.to_string(), f))
    .collect();
    assert_eq!(faults, expected);
    // The fault's flow: reset, acknowledge (the faults' alarms are latched), home.
    for node in 0..world.node_count() {
        world.reset(node).expect("reset");
        world.ack(node).expect("ack");
    }
    world.run_until_idle(60_000).expect("settles");
    world.home(home).expect("home");
    world.run_until_idle(60_000).expect("homes");
    assert_eq!(cycle(&mut world), sequence);
}
