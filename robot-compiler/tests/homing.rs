//! Homing, as the compiler plans it: derived from the actuators and interlocks when the
//! robot declares none, declared otherwise; and the charts it adds.

use robot_compiler::check::check;
use robot_compiler::ir::Ir;
use robot_compiler::Source;

fn ir_of(path: &str, text: &str) -> Ir {
    let src = Source::new(path, text);
    let checked = check(&src);
    assert!(
        !checked.has_errors(),
        "{:?}",
        checked
            .diagnostics
            .iter()
            .map(|d| d.short(&src))
            .collect::<Vec<_>>()
    );
    checked.ir.expect("elaborated")
}

fn paint() -> String {
    let path = format!(
        "{}/../robot-configs/paint-robot.ron",
        env!("CARGO_MANIFEST_DIR")
    );
    std::fs::read_to_string(path).expect("paint robot")
}

fn homing_text(ir: &Ir) -> String {
    ir.homing
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(" ")
}

/// The paint robot declares no homing: VC first (HC and RC may not move while VC is not
/// home), then HC and RC, the sensorless gripper last (it lets the part go once the arm is
/// back over the pick place).
#[test]
fn the_paint_robot_homes_vc_first_and_the_gripper_last() {
    let ir = ir_of("paint-robot.ron", &paint());
    assert_eq!(homing_text(&ir), "VC- HC- RC- GR-");
    assert!(ir.homing_derived);
    assert_eq!(ir.home, Some(0), "VC's role takes HOME (step 1 is VC's)");
}

/// The derived order follows the interlocks, not the declaration order.
#[test]
fn the_interlocks_order_a_derived_homing() {
    let text = paint().replace(
        "never: [\"HC.moving && !VC.home\", \"RC.moving && !VC.home\"]",
        "never: [\"VC.moving && !RC.home\", \"HC.moving && !VC.home\"]",
    );
    assert!(text.contains("VC.moving && !RC.home"));
    let ir = ir_of("paint-robot.ron", &text);
    assert_eq!(homing_text(&ir), "RC- VC- HC- GR-");
}

/// A declared homing is taken as written, and the HOME input is wired to step 1's role.
#[test]
fn a_declared_homing_and_home_input_are_kept() {
    let text = paint()
        .replace(
            "inputs: [(name: \"START\", pin: 4)],",
            "inputs: [(name: \"START\", pin: 4), (name: \"HOME\", pin: 5)],",
        )
        .replace(
            "start: \"START\",",
            "start: \"START\",\n    home: \"HOME\",\n    homing: \"VC- RC- HC- GR-\",",
        );
    let ir = ir_of("paint-robot.ron", &text);
    assert_eq!(homing_text(&ir), "VC- RC- HC- GR-");
    assert!(!ir.homing_derived);
    let vc = &ir.roles[0];
    assert_eq!(vc.home.as_deref(), Some("HOME"));
    assert!(vc
        .inputs
        .iter()
        .any(|i| i.name == "HOME" && i.pin == 5 && i.rise.as_deref() == Some("HOME")));
    // Step 1's chart: starts UNHOMED, rests in IDLE; HOME from either goes to HOMING.
    let chart = vc.charts.iter().find(|c| c.name == "VC").expect("VC chart");
    assert_eq!(chart.states[chart.initial].name, "UNHOMED");
    assert_eq!(chart.states[chart.idle].name, "IDLE");
    let home = vc
        .charts
        .iter()
        .find(|c| c.name == "home")
        .expect("home chart");
    let names: Vec<&str> = home.states.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["WAIT", "HOMING1", "HOMED1"]);
    // Step 1 is skipped when VC already reads home.
    let skip = &home.transitions[0];
    assert_eq!((skip.from, skip.to), (0, 2));
    assert_eq!(skip.guard.as_ref().map(|g| g.0.as_str()), Some("VC.home"));
}
