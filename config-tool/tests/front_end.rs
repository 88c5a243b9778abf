//! The offline front end on robots and inputs it must take or refuse: interlocks over
//! actuators that never move, steps without a completion sensor, sensored single-acting
//! actuators, pins and values out of range, bad bytes, and diagnostics that stay linear
//! and capped on floods of errors.

use config_tool::check::check;
use config_tool::{compile, verify, Source};

fn paint_text() -> String {
    let path = format!(
        "{}/../robot-configs/paint-robot.ron",
        env!("CARGO_MANIFEST_DIR")
    );
    std::fs::read_to_string(path).expect("robot")
}

/// `line:col: severity: message` of every diagnostic.
fn diagnostics(src: &Source) -> Vec<String> {
    let (_, diags) = check(src);
    diags
        .iter()
        .map(|d| {
            let (line, col) = d.line_col(src);
            let sev = if d.is_error() { "error" } else { "warning" };
            format!("{line}:{col}: {sev}: {}", d.message)
        })
        .collect()
}

/// The paint robot without HC in its sequence, with `never` replaced.
fn without_hc(never: &str) -> Source {
    let text = paint_text()
        .replace(
            "\"VC+ GR+ VC- HC+ VC+ VC- RC+ RC- HC- VC+ GR- VC-\"",
            "\"VC+ GR+ VC- VC+ VC- RC+ RC- VC+ GR- VC-\"",
        )
        .replace(
            "never: [\"HC.moving && !VC.home\", \"RC.moving && !VC.home\"]",
            &format!("never: [{never}]"),
        );
    Source::new("no-hc.ron", text)
}

#[test]
fn an_interlock_may_name_an_actuator_the_sequence_never_moves() {
    let src = without_hc("\"HC.moving && !VC.home\", \"RC.moving && !VC.home\"");
    let errors: Vec<String> = diagnostics(&src)
        .into_iter()
        .filter(|d| d.contains(": error: "))
        .collect();
    assert_eq!(errors, Vec::<String>::new());
    let c = compile(&src).expect("compiles");
    let sim = config_tool::sim::simulate(&c, 3).expect("sim");
    assert!(sim.ok(), "{}", sim.report());
    let model = verify::Model::new(&c).expect("model");
    assert_eq!(model.interlock_count(), 2);
    let report = verify::explore(&model, verify::Options::default());
    assert!(report.ok(), "{}", report.render("no-hc", 2));
}

#[test]
fn an_actuator_that_never_moves_is_home_for_ever() {
    // HC stays home while VC goes out: this interlock is violated.
    let src = without_hc("\"HC.home && VC.end\"");
    let c = compile(&src).expect("compiles");
    let model = verify::Model::new(&c).expect("model");
    let report = verify::explore(&model, verify::Options::default());
    let v = report.violation.expect("violated");
    assert_eq!(v.property, verify::Property::Interlock);
    assert_eq!(v.message, "never: \"HC.home && VC.end\" holds");
    // ... and it never moves.
    let src = without_hc("\"HC.moving || HC.end || !HC.home\"");
    let c = compile(&src).expect("compiles");
    let model = verify::Model::new(&c).expect("model");
    assert!(verify::explore(&model, verify::Options::default()).ok());
}

#[test]
fn a_role_fault_is_an_interlock_name_when_an_actuator_has_the_role_s_name() {
    let text = paint_text().replace(
        "never: [\"HC.moving && !VC.home\", \"RC.moving && !VC.home\"]",
        "never: [\"HC.fault && HC.moving\"]",
    );
    let src = Source::new("paint.ron", text);
    let c = compile(&src).expect("compiles");
    let model = verify::Model::new(&c).expect("model");
    assert_eq!(model.interlock_count(), 1);
}
