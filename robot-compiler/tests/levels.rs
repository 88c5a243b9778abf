//! Fault, start and home levels: from the robot format (per actuator, per plain output)
//! into each table's outputs, and shown by `dump` and `diagram`.

use config_schema::{Level, Output};
use robot_compiler::{compile, diagram, dump, Source};

fn root(path: &str) -> String {
    format!("{}/../{path}", env!("CARGO_MANIFEST_DIR"))
}

fn load(path: &str) -> Source {
    let text = std::fs::read_to_string(root(path)).unwrap_or_else(|e| panic!("{path}: {e}"));
    Source::new(path, text)
}

fn outputs(src: &Source, role: &str) -> Vec<Output> {
    let c = compile(src).unwrap_or_else(|d| panic!("{d:?}"));
    let i =
        c.ir.roles
            .iter()
            .position(|r| r.name == role)
            .expect("role");
    c.tables[i].outputs.to_vec()
}

fn out(pin: u8, fault: Level, start: Level, home: bool) -> Output {
    Output {
        pin,
        fault,
        start,
        home,
    }
}

/// The paper's gripper holds its part on fault and at start; the cylinders, which say
/// nothing, drive every solenoid off as before, and homing retracts them.
#[test]
fn the_paint_robots_gripper_holds_and_the_cylinders_keep_their_safe_levels() {
    for file in [
        "paint-robot.ron",
        "paint-robot-double-dip.ron",
        "paint-robot-paper-charts.ron",
        "paint-robot-counted.ron",
        "paint-robot-spare-node.ron",
        "paint-robot-start-on-gr.ron",
    ] {
        let src = load(&format!("robot-configs/{file}"));
        assert_eq!(
            outputs(&src, "GR"),
            [out(0, Level::Hold, Level::Hold, false)],
            "{file}"
        );
        assert_eq!(
            outputs(&src, "VC"),
            [
                out(0, Level::Low, Level::Low, false),
                out(1, Level::Low, Level::Low, true),
            ],
            "{file}"
        );
    }
}

/// Each actuator level on both kinds of valve, and a plain output's `safe` with its
/// overrides.
#[test]
fn actuator_and_output_levels_lower_into_the_table() {
    let src = load("tests/fixtures/small-charts.ron");
    let text = src
        .text
        .replace(
            "kind: DoubleActing(extend: 0, retract: 1, home: 2, end: 3))],\n            inputs",
            "kind: DoubleActing(extend: 0, retract: 1, home: 2, end: 3), fault: Retract, start: Extend)],\n            \
             outputs: [(name: \"LAMP\", pin: 5, safe: true, fault: Hold), (name: \"HORN\", pin: 6, fault: High, start: Hold, home: High)],\n            inputs",
        )
        .replace(
            "(name: \"B\", kind: DoubleActing(extend: 0, retract: 1, home: 2, end: 3))",
            "(name: \"B\", kind: SingleActing(valve: 0, dwell_ms: 100, home: 2, end: 3), fault: Extend, start: Hold)",
        );
    let src = Source::new("levels.ron", text);
    assert_eq!(
        outputs(&src, "A"),
        [
            out(0, Level::Low, Level::High, false),
            out(1, Level::High, Level::Low, true),
            out(5, Level::Hold, Level::High, true),
            out(6, Level::High, Level::Hold, true),
        ]
    );
    assert_eq!(
        outputs(&src, "B"),
        [out(0, Level::High, Level::Hold, false)]
    );
}

#[test]
fn dump_and_diagram_show_the_levels() {
    let src = load("robot-configs/paint-robot.ron");
    let c = compile(&src).expect("compiles");
    let text = dump::dump(&c.blobs[1]).expect("dumps");
    assert!(
        text.contains("\noutput out0: pin 0  fault hold  start hold  home 0\n"),
        "{text}"
    );
    let text = dump::dump(&c.blobs[0]).expect("dumps");
    assert!(
        text.contains(
            "\noutput out0: pin 0  fault 0  start 0  home 0\noutput out1: pin 1  fault 0  start 0  home 1\n"
        ),
        "{text}"
    );
    let dot = diagram::dot(&c.ir, "GR").expect("GR");
    assert!(
        dot.contains(
            "  outputs [shape=note, label=\"outputs: fault / start / home\\l  GR.valve (pin 0): hold / hold / 0\\l\"];\n"
        ),
        "{dot}"
    );
}

/// A sequence robot's plain outputs (a lamp lit on fault, as robot-format.md's example
/// declares on VC) are in its tables with their levels, after the valves. Synthesis left
/// them out: `check` said ok, and the lamp was in no table.
#[test]
fn a_sequence_robots_plain_outputs_are_in_its_tables() {
    let text = std::fs::read_to_string(root("robot-configs/paint-robot.ron")).unwrap();
    let vc = "inputs: [(name: \"START\", pin: 4)],";
    assert!(text.contains(vc), "paint-robot.ron's VC");
    let with = |output: &str| {
        let edited = text.replacen(vc, &format!("{vc}\n            outputs: [{output}],"), 1);
        Source::new("lamp.ron", edited)
    };
    let src = with("(name: \"LAMP\", pin: 5, safe: false, fault: High)");
    assert_eq!(
        outputs(&src, "VC"),
        [
            out(0, Level::Low, Level::Low, false),
            out(1, Level::Low, Level::Low, true),
            out(5, Level::High, Level::Low, false),
        ]
    );
    let src = with("(name: \"LAMP\", pin: 5, safe: true)");
    assert_eq!(
        outputs(&src, "VC")[2],
        out(5, Level::High, Level::High, true)
    );
}
