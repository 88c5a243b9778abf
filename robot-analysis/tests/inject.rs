//! `sim --fault`: injected faults are detected (watchdog within the motion timeout, link
//! alarm after the link's retries), every node stops at once, and no actuator moves
//! afterwards but a monostable valve released on fault (a gripper that holds keeps its
//! part). `sim --timeline`: the SVG parses and has one lane per actuator.

use robot_analysis::inject::{self, FaultRun, InjectError, ParseError};
use robot_analysis::timeline;
use robot_compiler::ir::{parse_steps, Step};
use robot_compiler::{compile, Compiled, Source};

fn paint_text() -> String {
    let path = format!(
        "{}/../robot-configs/paint-robot.ron",
        env!("CARGO_MANIFEST_DIR")
    );
    std::fs::read_to_string(&path).expect("robot")
}

fn paint() -> Compiled {
    compile(&Source::new("paint-robot.ron", paint_text())).expect("compiles")
}

/// The paint robot whose gripper says nothing about its levels: its valve drops on fault.
fn paint_dropping() -> Compiled {
    let text = paint_text();
    let said = text.replace("\n                 fault: Hold, start: Hold),", "),");
    assert_ne!(said, text, "the gripper declares its levels");
    compile(&Source::new("paint-robot.ron", said)).expect("compiles")
}

/// `"VC+ GR+"` as steps.
fn steps(text: &str) -> Vec<Step> {
    parse_steps(text)
        .into_iter()
        .map(|(s, _)| s.expect("a step"))
        .collect()
}

fn step(text: &str) -> Step {
    steps(text).remove(0)
}

fn inject(c: &Compiled, spec: &str) -> FaultRun {
    inject::simulate(c, &inject::parse(spec).expect("spec")).expect("runs")
}

fn all_faulted_with_outputs_off(run: &FaultRun) {
    for (role, fault, levels) in &run.outputs {
        assert!(fault.is_some(), "{role} is not faulted");
        assert!(levels.iter().all(|(_, l)| !l), "{role}: {levels:?}");
    }
}

/// Every node faulted, every output off but the gripper, which holds its part.
fn all_faulted_and_the_part_held(run: &FaultRun) {
    for (role, fault, levels) in &run.outputs {
        assert!(fault.is_some(), "{role} is not faulted");
        let held = levels
            .iter()
            .filter(|(_, l)| *l)
            .map(|(name, _)| name.as_str());
        let want: &[&str] = if role == "GR" { &["GR.valve"] } else { &[] };
        assert_eq!(held.collect::<Vec<_>>(), want, "{role}");
    }
}

#[test]
fn a_jammed_actuator_is_caught_by_its_watchdog_and_every_node_stops() {
    let c = paint();
    let run = inject(&c, "stuck:HC@4");
    assert_eq!(run.before_step, Some(step("HC+")));
    assert_eq!(run.steps_before, steps("VC+ GR+ VC-"));
    let d = run.detected.clone().expect("detected");
    assert_eq!(
        (d.role.as_str(), d.how.as_str()),
        ("HC", "motion watchdog (fault 1)")
    );
    // Exactly the motion timeout after HC+ was commanded.
    assert_eq!(d.t_ms - run.commanded_ms.expect("commanded"), 2000);
    assert_eq!(
        run.reactions,
        [
            (2706, String::from("HC: motion watchdog (fault 1)")),
            (2708, String::from("VC: a peer's fault (fault 2)")),
            (2708, String::from("GR: a peer's fault (fault 2)")),
            (2708, String::from("RC: a peer's fault (fault 2)")),
        ]
    );
    // Nothing moves: the gripper holds its part (`fault: Hold`).
    assert_eq!(run.moves_after, []);
    assert!(run.stopped_safely());
    all_faulted_and_the_part_held(&run);
}

/// A gripper that says nothing about its fault level drops the part, as before fault
/// levels existed: its monostable valve is released.
#[test]
fn a_gripper_without_a_fault_level_drops_its_part_on_a_fault() {
    let run = inject(&paint_dropping(), "stuck:HC@4");
    assert_eq!(run.reactions.len(), 4);
    assert_eq!(run.moves_after, [(2708, step("GR-"), true)]);
    assert!(run.stopped_safely());
    all_faulted_with_outputs_off(&run);
}

#[test]
fn a_broken_end_switch_is_caught_within_the_timeout() {
    let c = paint();
    let run = inject(&c, "switch:RC.end@7");
    assert_eq!(run.before_step, Some(step("RC+")));
    let d = run.detected.clone().expect("detected");
    assert_eq!(d.role, "RC");
    assert_eq!(d.t_ms - run.commanded_ms.expect("commanded"), 2000);
    assert_eq!(run.reactions.len(), 4);
    assert_eq!(run.moves_after, []);
    assert!(run.stopped_safely());
    all_faulted_and_the_part_held(&run);
}

#[test]
fn a_stopped_node_raises_a_link_alarm_and_the_machine_stalls_without_moving() {
    let c = paint();
    let run = inject(&c, "stop:GR@2");
    assert_eq!(run.steps_before, steps("VC+"));
    let d = run.detected.clone().expect("detected");
    assert_eq!(
        (d.role.as_str(), d.how.as_str()),
        ("VC", "link alarm: GR does not acknowledge")
    );
    // VC published step1.done when VC reached its end (300 ms); its link gives up after
    // the reliable link's retries.
    assert_eq!(node_fw::sim::link_alarm_ms(), 810);
    assert_eq!(d.t_ms, 300 + 810);
    assert!(run.moves_after.is_empty());
    assert!(run.stopped_safely());
}

#[test]
fn a_lost_link_raises_a_link_alarm_and_nothing_moves_after_it() {
    let c = paint();
    let run = inject(&c, "link:VC->GR@10");
    assert_eq!(
        run.steps_before,
        steps("VC+ GR+ VC- HC+ VC+ VC- RC+ RC- HC-")
    );
    // Step 10 is VC's own: it still moves; the hand-over to GR is what is lost.
    assert_eq!(run.steps_after, steps("VC+"));
    let d = run.detected.clone().expect("detected");
    assert_eq!(d.role, "VC");
    assert!(run.moves_after.is_empty());
    // GR still holds the part: its node never heard step10.done.
    assert_eq!(run.outputs[1].2, [(String::from("GR.valve"), true)]);
}

#[test]
fn fault_specs_parse_or_say_what_is_wrong() {
    let s = inject::parse("switch:HC.end@2.4").expect("parses");
    assert_eq!((s.cycle, s.step), (2, 4));
    let err = inject::parse("stuck:HC").unwrap_err();
    assert_eq!(
        err,
        ParseError::NoStep {
            spec: "stuck:HC".into()
        }
    );
    assert_eq!(
        err.to_string(),
        "`stuck:HC`: no `@STEP`: write KIND:TARGET@STEP or KIND:TARGET@CYCLE.STEP, KIND one \
         of stuck (an actuator), switch (ACT.end or ACT.home), stop (a role), link (FROM->TO)"
    );
    assert_eq!(
        inject::parse("stuck:HC@0").unwrap_err().to_string(),
        "`stuck:HC@0`: `0` is not a step or cycle number (1 to 10000)"
    );
    let c = paint();
    let err = inject::simulate(&c, &inject::parse("stuck:XX@1").expect("parses")).unwrap_err();
    assert_eq!(err, InjectError::NoMovingActuator("XX".into()));
    assert_eq!(err.to_string(), "no moving actuator `XX`");
    let err = inject::simulate(&c, &inject::parse("stuck:HC@13").expect("parses")).unwrap_err();
    assert_eq!(
        err.to_string(),
        "the cycle has 12 steps: there is no step 13"
    );
}

#[test]
fn a_fault_in_the_second_cycle_leaves_the_first_intact() {
    let c = paint();
    let run = inject(&c, "stuck:VC@2.1");
    assert_eq!(run.steps_before, Vec::<Step>::new());
    let d = run.detected.clone().expect("detected");
    assert_eq!(d.role, "VC");
    assert_eq!(d.t_ms - run.commanded_ms.expect("commanded"), 2000);
    assert!(run.stopped_safely());
}

fn lanes(svg: &str, kind: &str) -> Vec<String> {
    let doc = roxmltree::Document::parse(svg).expect("the SVG parses");
    let class = format!("lane {kind}");
    doc.descendants()
        .filter(|n| n.attribute("class") == Some(class.as_str()))
        .map(|n| n.attribute("data-name").unwrap_or("").to_string())
        .collect()
}

#[test]
fn the_timeline_parses_and_has_one_lane_per_actuator_and_per_chart() {
    let c = paint();
    let trace = timeline::run(&c, 2).expect("runs");
    let svg = timeline::svg(&c, &trace).expect("draws");
    assert_eq!(lanes(&svg, "actuator"), ["VC", "GR", "HC", "RC"]);
    assert_eq!(
        lanes(&svg, "chart"),
        [
            "VC.VC", "VC.fault", "VC.home", "GR.GR", "GR.fault", "GR.home", "HC.HC", "HC.fault",
            "HC.home", "RC.RC", "RC.fault", "RC.home"
        ]
    );
    assert_eq!(lanes(&svg, "radio"), ["radio"]);
    // Two cycles of 9 publications: one tick each.
    let doc = roxmltree::Document::parse(&svg).expect("parses");
    let radio = doc
        .descendants()
        .find(|n| n.attribute("class") == Some("lane radio"))
        .expect("radio lane");
    assert_eq!(
        radio.children().filter(|n| n.has_tag_name("line")).count(),
        18
    );
}

#[test]
fn the_timeline_of_a_fault_marks_it_and_shades_the_stopped_charts() {
    let c = paint();
    let run = inject(&c, "stuck:HC@4");
    let svg = timeline::svg(&c, &run.trace).expect("draws");
    let doc = roxmltree::Document::parse(&svg).expect("parses");
    let faulted = doc
        .descendants()
        .filter(|n| n.attribute("class") == Some("faulted"))
        .count();
    assert_eq!(
        faulted, 12,
        "every chart of every node shaded after its fault"
    );
    let marks = doc
        .descendants()
        .filter(|n| n.attribute("class") == Some("mark"))
        .count();
    assert_eq!(marks, 5, "the injection and four faults");
}

/// A fault detected before the step it was injected before is commanded (the water-jet
/// transport's belt node stopped before step 2: PUSHER's link alarm comes at 812 ms, step 2
/// at 2006 ms) is said to come that long before it. The report said `0 ms after`.
#[test]
fn a_detection_before_the_step_is_commanded_says_how_long_before() {
    let path = format!(
        "{}/../robot-configs/waterjet-transport.ron",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).expect("robot");
    let c = compile(&Source::new("waterjet-transport.ron", text)).expect("compiles");
    let report = inject(&c, "stop:BELT@2").report();
    let line = report
        .lines()
        .find(|l| l.starts_with("detected at"))
        .expect("detected");
    assert_eq!(
        line,
        "detected at 812 ms by PUSHER: link alarm: BELT does not acknowledge, 1194 ms before \
         step 2 was commanded"
    );
}
