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
    let (_, diags) = check(&src);
    assert_eq!(diags.len(), 19_999);
    assert!(diags.iter().all(|d| d.is_error()));
    let last = diags.last().expect("one");
    assert_eq!(
        last.short(&src),
        "dups.ron:20004:35: error: address 0x0001 is used by nodes `n0` and `n19999`"
    );
    assert_eq!(last.label, "first used at 5:31");
    let out = config_tool::diag::render_all(&src, &diags, false);
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
    let (_, diags) = check(&src);
    let out = config_tool::diag::render_all(&src, &diags, false);
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
    let (_, diags) = check(&src);
    let out = config_tool::diag::render_all(&src, &diags, false);
    assert!(!out.contains("more error"), "{out}");
    assert!(
        out.ends_with("\ndups.ron: 2 error(s), 0 warning(s)\n"),
        "{out}"
    );
    // Errors and warnings beyond the cap are counted apart.
    let mut mixed: Vec<_> = (0..25).flat_map(|_| diags.iter().cloned()).collect();
    mixed.push(config_tool::Diagnostic::warning(0..1, "w"));
    mixed.push(config_tool::Diagnostic::warning(0..1, "w"));
    let out = config_tool::diag::render_all(&src, &mixed, false);
    assert!(
        out.ends_with("\n... and 2 more warnings\ndups.ron: 50 error(s), 2 warning(s)\n"),
        "{out}"
    );
    mixed.insert(0, config_tool::Diagnostic::error(0..1, "e"));
    let out = config_tool::diag::render_all(&src, &mixed, false);
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
    let (_, diags) = check(&src);
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
    let out = config_tool::diag::render_all(&src, &diags, false);
    assert!(out.ends_with("\n... and 4950 more errors\ndups.ron: 5000 error(s), 0 warning(s)\n"));
    assert!(out.len() < 50_000, "{}", out.len());
}
