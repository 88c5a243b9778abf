//! The offline front end on robots and inputs it must take or refuse: interlocks over
//! actuators that never move, steps without a completion sensor, sensored single-acting
//! actuators, pins and values out of range, bad bytes, and diagnostics that stay linear
//! and capped on floods of errors.

use robot_analysis::verify;
use robot_compiler::check::check;
use robot_compiler::{compile, Source};

fn paint_text() -> String {
    let path = format!(
        "{}/../robot-configs/paint-robot.ron",
        env!("CARGO_MANIFEST_DIR")
    );
    std::fs::read_to_string(path).expect("robot")
}

/// `line:col: severity: message` of every diagnostic.
fn diagnostics(src: &Source) -> Vec<String> {
    let diags = check(src).diagnostics;
    diags
        .iter()
        .map(|d| {
            let (line, col) = d.line_col(src);
            let sev = if d.is_error() { "error" } else { "warning" };
            format!("{line}:{col}: {sev}: {}", d.message)
        })
        .collect()
}

/// The errors of `src`'s diagnostics, as [`diagnostics`] gives them.
fn errors_of(src: &Source) -> Vec<String> {
    let all = diagnostics(src);
    all.into_iter()
        .filter(|d| d.contains(": error: "))
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
    let errors = errors_of(&src);
    assert_eq!(errors, Vec::<String>::new());
    let c = compile(&src).expect("compiles");
    let sim = robot_analysis::sim::simulate(&c, 3).expect("sim");
    assert!(sim.ok(), "{}", sim.report());
    let model = verify::Model::new(&c).expect("model");
    assert_eq!(model.interlock_count(), 2);
    let report = verify::explore(&model, verify::ExploreOptions::default());
    assert!(report.ok(), "{}", report.render("no-hc", 2));
}

#[test]
fn an_actuator_that_never_moves_is_home_for_ever() {
    // HC stays home while VC goes out: this interlock is violated.
    let src = without_hc("\"HC.home && VC.end\"");
    let c = compile(&src).expect("compiles");
    let model = verify::Model::new(&c).expect("model");
    let report = verify::explore(&model, verify::ExploreOptions::default());
    let v = report.violation.expect("violated");
    assert_eq!(v.property, verify::Property::Interlock);
    assert_eq!(v.message, "never: \"HC.home && VC.end\" holds");
    // ... and it never moves.
    let src = without_hc("\"HC.moving || HC.end || !HC.home\"");
    let c = compile(&src).expect("compiles");
    let model = verify::Model::new(&c).expect("model");
    assert!(verify::explore(&model, verify::ExploreOptions::default()).ok());
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

/// A one-role robot with `n` nodes that all have address 0x0001 (`n - 1` errors) and
/// `never` as given.
fn duplicate_addresses(n: usize, never: &str) -> Source {
    let nodes: String = (0..n)
        .map(|i| format!("        (name: \"n{i}\", address: 0x0001),\n"))
        .collect();
    Source::new(
        "dups.ron",
        format!(
            "Robot(\n    name: \"dups\",\n    network: (pan_id: 0x0101, channel: 11),\n    \
             nodes: [\n{nodes}    ],\n    assign: [(\"A\", \"n0\")],\n    roles: [(\n        \
             name: \"A\",\n        actuators: [(name: \"A\", kind: DoubleActing(extend: 0, \
             retract: 1, home: 2, end: 3))],\n        inputs: [(name: \"START\", pin: 4)],\n    \
             )],\n    start: \"START\",\n    sequence: \"A+ A-\",\n    never: [{never}],\n)\n"
        ),
    )
}

#[test]
fn twenty_thousand_duplicate_addresses_are_all_found() {
    let src = duplicate_addresses(20_000, "");
    let diags = check(&src).diagnostics;
    assert_eq!(diags.len(), 19_999);
    assert!(diags.iter().all(|d| d.is_error()));
    let last = diags.last().expect("one");
    assert_eq!(
        last.short(&src),
        "dups.ron:20004:35: error: address 0x0001 is used by nodes `n0` and `n19999`"
    );
    assert_eq!(last.label, "first used at 5:31");
    let out = robot_compiler::diag::render_all(&src, &diags, false);
    assert!(
        out.ends_with("... and 19949 more errors\ndups.ron: 19999 error(s), 0 warning(s)\n"),
        "{}",
        &out[out.len() - 300..]
    );
    assert_eq!(out.matches("  × ").count(), 50);
}

#[test]
fn after_fifty_diagnostics_the_rest_are_counted() {
    let src = duplicate_addresses(53, "");
    let diags = check(&src).diagnostics;
    let out = robot_compiler::diag::render_all(&src, &diags, false);
    let tail = "  × address 0x0001 is used by nodes `n0` and `n50`
    ╭─[dups.ron:55:32]
 54 │         (name: \"n49\", address: 0x0001),
 55 │         (name: \"n50\", address: 0x0001),
    ·                                ───┬──
    ·                                   ╰── first used at 5:31
 56 │         (name: \"n51\", address: 0x0001),
    ╰────

... and 2 more errors
dups.ron: 52 error(s), 0 warning(s)
";
    assert!(out.ends_with(tail), "{out}");
    assert_eq!(out.matches("  × ").count(), 50);
    // Fewer than the cap: all shown, no count.
    let src = duplicate_addresses(3, "");
    let diags = check(&src).diagnostics;
    let out = robot_compiler::diag::render_all(&src, &diags, false);
    assert!(!out.contains("more error"), "{out}");
    assert!(
        out.ends_with("\ndups.ron: 2 error(s), 0 warning(s)\n"),
        "{out}"
    );
    // Errors and warnings beyond the cap are counted apart.
    let mut mixed: Vec<_> = (0..25).flat_map(|_| diags.iter().cloned()).collect();
    mixed.push(robot_compiler::Diagnostic::warning(0..1, "w"));
    mixed.push(robot_compiler::Diagnostic::warning(0..1, "w"));
    let out = robot_compiler::diag::render_all(&src, &mixed, false);
    assert!(
        out.ends_with("\n... and 2 more warnings\ndups.ron: 50 error(s), 2 warning(s)\n"),
        "{out}"
    );
    mixed.insert(0, robot_compiler::Diagnostic::error(0..1, "e"));
    let out = robot_compiler::diag::render_all(&src, &mixed, false);
    assert!(
        out.ends_with(
            "\n... and 1 more error and 2 more warnings\ndups.ron: 51 error(s), 2 warning(s)\n"
        ),
        "{out}"
    );
}

#[test]
fn five_thousand_bad_names_on_one_line_render_short() {
    let never: Vec<String> = (0..5000).map(|i| format!("\"Z{i}.home\"")).collect();
    let src = duplicate_addresses(1, &never.join(", "));
    assert!(src.text.len() > 60_000);
    let diags = check(&src).diagnostics;
    assert_eq!(diags.len(), 5000);
    assert_eq!(
        diags[4999].short(&src),
        format!(
            "dups.ron:15:{}: error: `Z4999.home` is not an interlock name: write \
             `ACTUATOR.home` / `.end` / `.moving` / `.extending` / `.retracting`, \
             `ROLE.CHART.STATE` or `ROLE.fault`",
            src.text
                .lines()
                .nth(14)
                .expect("line 15")
                .find("\"Z4999")
                .expect("there")
                + 2
        )
    );
    // Each rendering shows a window of the 60 kB line, not the line.
    for d in &diags {
        let r = d.render(&src, false);
        assert!(r.len() < 1000, "{r}");
    }
    let last = diags[4999].render(&src, false);
    assert!(last.contains("\"Z4999.home\""), "{last}");
    let out = robot_compiler::diag::render_all(&src, &diags, false);
    assert!(out.ends_with("\n... and 4950 more errors\ndups.ron: 5000 error(s), 0 warning(s)\n"));
    assert!(out.len() < 50_000, "{}", out.len());
}

fn paint_with(from: &str, to: &str) -> Source {
    let text = paint_text();
    assert!(text.contains(from), "{from}");
    Source::new("paint.ron", text.replace(from, to))
}

const GRIPPER: &str = "SingleActing(valve: 0, dwell_ms: 150, out_ms: 100, back_ms: 100)";

#[test]
fn check_warns_of_each_step_without_a_completion_sensor() {
    let src = paint_with("", "");
    assert_eq!(
        diagnostics(&src),
        [
            "61:20: warning: step `GR+` has no completion sensor: a jam of `GR` goes undetected",
            "61:56: warning: step `GR-` has no completion sensor: a jam of `GR` goes undetected",
        ]
    );
    let diags = check(&src).diagnostics;
    assert_eq!(
        diags[0].label,
        "completes after dwell_ms (150 ms), unsupervised"
    );
    assert_eq!(
        diags[0].help.as_deref(),
        Some("if `GR` has a position sensor, declare it (`end: PIN`) to get a motion watchdog")
    );
    // A sensor at the end supervises `GR+`; `GR-` still completes on time alone.
    let src = paint_with(GRIPPER, &GRIPPER.replace(")", ", end: 1)"));
    assert_eq!(
        diagnostics(&src),
        ["61:56: warning: step `GR-` has no completion sensor: a jam of `GR` goes undetected"]
    );
    let src = paint_with(GRIPPER, &GRIPPER.replace(")", ", home: 2, end: 1)"));
    assert_eq!(diagnostics(&src), Vec::<String>::new());
}

#[test]
fn a_sensored_single_acting_actuator_runs_verifies_and_has_a_watchdog() {
    for sensors in [
        ", end: 1",
        ", home: 2, end: 1",
        ", home: 2",
        ", end: 1, timeout_ms: 500",
    ] {
        let src = paint_with(GRIPPER, &GRIPPER.replace(")", &format!("{sensors})")));
        let c = compile(&src).expect("compiles");
        let sim = robot_analysis::sim::simulate(&c, 3).expect("sim");
        assert!(sim.ok(), "{sensors}: {}", sim.report());
        let model = verify::Model::new(&c).expect("model");
        let report = verify::explore(&model, verify::ExploreOptions::default());
        assert!(report.ok(), "{sensors}: {}", report.render("gr", 2));
    }
    // A jammed gripper is now caught by its own watchdog and every node stops.
    let src = paint_with(GRIPPER, &GRIPPER.replace(")", ", end: 1)"));
    let c = compile(&src).expect("compiles");
    let run = robot_analysis::inject::simulate(
        &c,
        &robot_analysis::inject::parse("stuck:GR@2").expect("spec"),
    )
    .expect("runs");
    let d = run.detected.clone().expect("detected");
    assert_eq!(
        (d.role.as_str(), d.how.as_str()),
        ("GR", "motion watchdog (fault 1)")
    );
    assert_eq!(d.t_ms - run.commanded_ms.expect("commanded"), 2000);
    assert_eq!(run.reactions.len(), 4);
    assert!(run.stopped_safely());
    // ... and its own timeout_ms, if given.
    let src = paint_with(GRIPPER, &GRIPPER.replace(")", ", end: 1, timeout_ms: 500)"));
    let c = compile(&src).expect("compiles");
    let run = robot_analysis::inject::simulate(
        &c,
        &robot_analysis::inject::parse("switch:GR.end@2").expect("spec"),
    )
    .expect("runs");
    let d = run.detected.clone().expect("detected");
    assert_eq!(d.t_ms - run.commanded_ms.expect("commanded"), 500);
}

#[test]
fn a_jammed_sensorless_gripper_prints_the_steps_after_the_injection_apart() {
    let c = compile(&paint_with("", "")).expect("compiles");
    let run = robot_analysis::inject::simulate(
        &c,
        &robot_analysis::inject::parse("stuck:GR@3").expect("spec"),
    )
    .expect("runs");
    assert_eq!(
        run.report(),
        "fault: GR jammed at 302 ms (cycle 1, before step 3 VC-)
steps until then: VC+ GR+
steps after the injection: VC- HC+ VC+ VC- RC+ RC- HC- VC+ VC-
NOT DETECTED: no node faulted and no link went into alarm up to 3968 ms, where the run ended
  the jammed motion `GR-` (at 3566 ms) has no completion sensor: it completes after its dwell time whether it moved or not (`check` warns of such steps)
outputs afterwards:
  VC       running                      VC.extend=0 VC.retract=1
  GR       running                      GR.valve=0
  HC       running                      HC.extend=0 HC.retract=1
  RC       running                      RC.extend=0 RC.retract=1
"
    );
    assert!(!run.stopped_safely());
}

#[test]
fn pins_past_the_table_s_pin_range_are_refused() {
    let src = paint_with(
        "inputs: [(name: \"START\", pin: 4)]",
        "inputs: [(name: \"START\", pin: 64)], outputs: [(name: \"L\", pin: 200)]",
    );
    let errors = errors_of(&src);
    assert_eq!(
        errors,
        [
            "31:43: error: pin 64 of `START` is out of range: a table names pins 0..=63",
            "31:76: error: pin 200 of `L` is out of range: a table names pins 0..=63",
        ]
    );
    let src = paint_with(GRIPPER, "SingleActing(valve: 70, dwell_ms: 150, end: 63)");
    let errors = errors_of(&src);
    assert_eq!(
        errors,
        ["39:56: error: pin 70 of `GR.valve` is out of range: a table names pins 0..=63"]
    );
}

/// A node at the tool's own address (0x0100) is refused: the tool's frames and the node's
/// answers to it would reach both. Found: `check` accepted it.
#[test]
fn a_node_at_the_tool_s_address_is_refused() {
    let src = paint_with(
        "(name: \"node-2\", address: 0x0012)",
        "(name: \"node-2\", address: 0x0100)",
    );
    let errors = errors_of(&src);
    assert_eq!(
        errors,
        [
            "10:35: error: address 0x0100 is config-tool's own on the radio: the tool's frames \
          and the answers to them would reach this node too"
        ]
    );
}

#[test]
fn a_zero_motion_timeout_is_refused() {
    let src = paint_with("motion_timeout_ms: 2000", "motion_timeout_ms: 0");
    let errors = errors_of(&src);
    assert_eq!(
        errors,
        ["62:24: error: `motion_timeout_ms` is 0 ms: every motion would fault as soon as it is commanded"]
    );
    let src = paint_with(
        "out_ms: 800, back_ms: 800)",
        "out_ms: 800, back_ms: 800, timeout_ms: 0)",
    );
    let errors = errors_of(&src);
    assert_eq!(
        errors,
        ["47:128: error: the watchdog `timeout_ms` of `HC` is 0 ms: every motion would fault as soon as it is commanded"]
    );
}

/// A stroke the watchdog does not wait for (`out_ms` or `back_ms` at least the motion's
/// watchdog) faults every such motion: a warning (the machine stops safely, as `sim`
/// shows). Found: `check` and `verify` said ok, and `sim` faulted at the first step of
/// every cycle.
#[test]
fn a_stroke_the_watchdog_does_not_wait_for_is_a_warning() {
    let errors = |src: &Source| -> Vec<String> {
        let all = diagnostics(src);
        all.into_iter()
            .filter(|d| d.contains(" would fault"))
            .collect()
    };
    let src = paint_with("out_ms: 300, back_ms: 250", "out_ms: 3000, back_ms: 250");
    assert_eq!(
        errors(&src),
        [
            "29:97: warning: `VC+` takes 3000 ms (`out_ms`) and its watchdog fires at 2000 ms \
          (`motion_timeout_ms`): every `VC+` would fault"
        ]
    );
    let src = paint_with(
        "out_ms: 800, back_ms: 800)",
        "out_ms: 800, back_ms: 800, timeout_ms: 800)",
    );
    assert_eq!(
        errors(&src),
        [
            "47:97: warning: `HC+` takes 800 ms (`out_ms`) and its watchdog fires at 800 ms \
             (`timeout_ms`): every `HC+` would fault",
            "47:111: warning: `HC-` takes 800 ms (`back_ms`) and its watchdog fires at 800 ms \
             (`timeout_ms`): every `HC-` would fault",
        ]
    );
    assert!(errors(&paint_with(
        "out_ms: 800, back_ms: 800)",
        "out_ms: 800, back_ms: 800, timeout_ms: 801)"
    ))
    .is_empty());
}

/// A dwell shorter than the stroke it stands for lets the next step start while the
/// actuator still moves: refused. Found: `sim` said every step was as declared while VC
/// lifted a second before the gripper had closed.
#[test]
fn a_dwell_shorter_than_its_stroke_is_refused() {
    let src = paint_with(
        GRIPPER,
        "SingleActing(valve: 0, dwell_ms: 50, out_ms: 1000, back_ms: 50)",
    );
    let errors = errors_of(&src);
    assert_eq!(
        errors,
        [
            "39:81: error: `GR+` completes after `dwell_ms` (50 ms) but takes 1000 ms \
          (`out_ms`): the next step would start while `GR` still moves"
        ]
    );
    // A position sensor completes the motion instead: its watchdog applies.
    let src = paint_with(
        GRIPPER,
        "SingleActing(valve: 0, dwell_ms: 50, out_ms: 1000, back_ms: 50, end: 5)",
    );
    assert!(diagnostics(&src).iter().all(|d| !d.contains(": error: ")));
}

#[test]
fn an_integer_out_of_bounds_says_the_field_s_range() {
    let cases = [
        (
            "address: 0x0011",
            "address: 0x10011",
            "9:37: error: Integer is out of bounds: `address` takes 0..=65535",
        ),
        (
            "valve: 0,",
            "valve: 300,",
            "39:56: error: Integer is out of bounds: `valve` takes 0..=255",
        ),
        (
            "motion_timeout_ms: 2000",
            "motion_timeout_ms: 99999999999",
            "62:24: error: Integer is out of bounds: `motion_timeout_ms` takes 0..=4294967295",
        ),
    ];
    for (from, to, want) in cases {
        assert_eq!(diagnostics(&paint_with(from, to)), [want]);
    }
}

fn tool(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(args)
        .current_dir(std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".."))
        .output()
        .expect("runs")
}

fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    dir
}

#[test]
fn a_file_that_is_not_utf8_is_an_error_at_the_first_bad_byte() {
    let dir = scratch("not-utf8");
    let path = dir.join("bad.ron");
    let mut bytes = paint_text().into_bytes();
    let at = paint_text().find("paint-robot\"").expect("name");
    bytes[at + 5] = 0xff;
    std::fs::write(&path, &bytes).expect("write");
    let out = tool(&["check", path.to_str().expect("utf-8")]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        format!(
            "{}:4:17: error: the file is not UTF-8 text: byte 0xff at offset {}\n",
            path.display(),
            at + 5
        )
    );
}

#[test]
fn dump_refuses_a_blob_on_channel_200() {
    let c = compile(&paint_with("", "")).expect("compiles");
    let mut table = c.tables[1].clone();
    table.header.channel = 200;
    let blob = robot_compiler::compile::encode(&table).expect("encodes");
    let dir = scratch("channel-200");
    let path = dir.join("GR.bin");
    std::fs::write(&path, blob).expect("write");
    let out = tool(&["dump", path.to_str().expect("utf-8")]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        format!(
            "error: {}: not a valid table blob: invalid table: channel 200 is not an IEEE \
             802.15.4 2.4 GHz channel (11..=26)\n",
            path.display()
        )
    );
}

#[test]
fn check_prints_fifty_diagnostics_then_counts_the_rest() {
    let dir = scratch("cap");
    let path = dir.join("dups.ron");
    std::fs::write(&path, duplicate_addresses(60, "").text).expect("write");
    let out = tool(&["check", path.to_str().expect("utf-8")]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.matches("  × address 0x0001").count(), 50);
    assert!(
        err.ends_with(&format!(
            "\n... and 9 more errors\n{}: 59 error(s), 0 warning(s)\n",
            path.display()
        )),
        "{err}"
    );
}

#[test]
fn the_real_time_plant_drives_a_single_acting_actuator_s_sensor() {
    let src = paint_with(GRIPPER, &GRIPPER.replace(")", ", end: 1)"));
    let c = compile(&src).expect("compiles");
    let actuators = robot_net::live_plant::actuators(&c).expect("actuators");
    let gr = actuators.iter().find(|a| a.name == "GR").expect("GR");
    assert_eq!(
        (gr.valves, gr.double, gr.home, gr.end),
        ((0, 0), false, None, Some(1))
    );
}
