//! `check` diagnostics: one broken RON file per check (tests/fixtures/broken), each
//! asserting the exact messages with their line:col, all problems of a file at once; the
//! rendered miette form; and the good files passing.

use robot_compiler::check::check;
use robot_compiler::Source;

fn fixture(path: &str) -> Source {
    let full = format!("{}/../tests/fixtures/{path}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&full).unwrap_or_else(|e| panic!("{full}: {e}"));
    Source::new(path, text)
}

/// `line:col: severity: message` of every diagnostic of a file.
fn diagnostics(path: &str) -> Vec<String> {
    let src = fixture(path);
    let diags = check(&src).diagnostics;
    diags
        .iter()
        .map(|d| {
            let (line, col) = d.line_col(&src);
            let sev = if d.is_error() { "error" } else { "warning" };
            format!("{line}:{col}: {sev}: {}", d.message)
        })
        .collect()
}

/// `line:col: message` of every diagnostic of a source.
fn located(src: &Source) -> Vec<String> {
    check(src)
        .diagnostics
        .iter()
        .map(|d| {
            let (line, col) = d.line_col(src);
            format!("{line}:{col}: {}", d.message)
        })
        .collect()
}

/// (file, every diagnostic as `line:col: severity: message`), one file per check.
const BROKEN: &[(&str, &[&str])] = &[
    ("syntax.ron", &["7:21: error: Expected comma"]),
    // It said `Expected opening `(` for struct `Role``, at the comment after the last item.
    ("truncated.ron", &[
        "15:11: error: Unexpected end of RON: the file ends before the `[` opened at 10:12 is closed (is it cut short?)",
    ]),
    ("unknown-role.ron", &[
        "9:28: error: unknown role `C`",
        "17:19: error: role `B` is assigned to no node",
    ]),
    ("unknown-node.ron", &["9:33: error: unknown node `n3`"]),
    ("unknown-event.ron", &["15:95: error: unknown event `b.FINISHED` of role `B`"]),
    ("unknown-state.ron", &[
        "49:24: warning: state `DONE` of chart type `Follower` is unreachable from its initial state `WAIT`",
        "54:34: error: unknown state `FINISH`",
    ]),
    ("unknown-input.ron", &["21:12: error: no role has an input `STRAT`"]),
    ("unknown-pin-name.ron", &["47:41: error: role `B` has no actuator `C` (chart `b`)"]),
    ("duplicate-role.ron", &[
        "9:28: error: unknown role `B`",
        "17:19: error: duplicate role name `A`",
    ]),
    ("duplicate-key.ron", &["15:66: error: duplicate key `M`"]),
    ("role-name-path.ron", &[
        "17:19: error: role name \"../B\": letters, digits, `_` and `-` only (it names the role's blob file, ROLE.bin)",
    ]),
    // It said `the table of role ... is too big: role name needs 13 but MAX_ROLE_NAME is
    // 12 (over by 1)`, and to move charts to another role.
    ("role-name-long.ron", &[
        "17:19: error: role name \"B_is_too_long\" is 13 bytes: at most 12 (a node reports it in its status): shorten it",
    ]),
    ("role-name-wide.ron", &[
        "17:19: error: role name \"ΩΩΩΩΩΩΩ\" is 14 bytes: at most 12 (a node reports it in its status): shorten it",
    ]),
    ("pin-twice.ron", &["14:43: error: pin 3 of role `A` is used twice: by `A.end` and `START`"]),
    ("role-unassigned.ron", &["17:19: error: role `B` is assigned to no node"]),
    ("role-twice.ron", &[
        "9:41: error: duplicate assignment of role `A`",
        "9:46: error: duplicate use of node `n2`",
    ]),
    ("bad-network.ron", &[
        "4:23: error: PAN id 0xffff is the broadcast PAN id",
        "4:40: error: channel 27 is not an IEEE 802.15.4 2.4 GHz channel",
    ]),
    ("address-twice.ron", &["7:31: error: address 0x0001 is used by nodes `n1` and `n2`"]),
    ("step-undeclared.ron", &["22:22: error: unknown actuator `C`"]),
    ("step-already-out.ron", &["22:22: error: `A+`: `A` is already out"]),
    ("cycle-not-home.ron", &[
        "22:16: error: `A` is still out at the end of the cycle: the cycle cannot repeat",
    ]),
    ("subscribed-unpublished.ron", &[
        "15:95: error: `B/b.DONE` is subscribed here but nobody publishes it: no state of chart `b` emits `DONE`",
    ]),
    ("published-unused.ron", &["20:29: warning: chart `b` publishes `DONE` but nobody uses it"]),
    ("unreachable-state.ron", &[
        "49:24: warning: state `DONE` of chart type `Follower` is unreachable from its initial state `WAIT`",
    ]),
    ("overlapping-guards.ron", &[
        "39:17: warning: transitions `IN -> IDLE` and `IN -> OUT` leave `IN` without an event and both guards can hold: the first declared wins",
    ]),
    ("capacity.ron", &[
        "12:19: error: the table of role `A` is too big: actions needs 190 but MAX_ACTIONS is 160 (over by 30)",
        "12:19: error: the table of role `A` is too big: states needs 100 but MAX_STATES is 96 (over by 4)",
    ]),
    ("guard-syntax.ron", &["36:68: error: expected a value, a name or `(`, found `&&`"]),
    ("guard-too-deep.ron", &[
        "36:60: error: this expression needs 11 values on the stack at once, a node evaluates \
         on 8: nest it to the left (`(a + b) + c` needs 2, `a + (b + c)` 3) or name a part \
         of it in a variable",
    ]),
    ("many-problems.ron", &[
        "7:31: error: address 0x0001 is used by nodes `n1` and `n2`",
        "14:43: error: pin 2 of role `A` is used twice: by `A.home` and `START`",
        "36:71: error: expected a value, a name or `(`, found the end of the expression",
        "54:46: error: unknown event `HOMED`: not an input or timer of chart type `Follower`",
    ]),
    ("trial-zero.ron", &[
        "5:20: error: a trial of 0 seconds rolls back at once: give it the time the operator needs to see the new sequence run",
    ]),
    ("trial-cycles-zero.ron", &[
        "5:19: error: a trial of 0 cycles rolls back at once: give it the cycles the operator needs to see the new sequence run",
    ]),
    ("unsecured.ron", &[
        "5:15: warning: frame security is off: anyone in radio range can push a table to these nodes, press START or forge their events",
    ]),
    ("home-hold.ron", &[
        "15:65: error: `home` of output `LAMP` is `Hold`: homing drives an output to a level",
    ]),
    ("level-unknown.ron", &[
        "18:104: error: Unexpected variant named `Open` in enum `ActuatorLevel`, expected one of `Off`, `Hold`, `Extend`, or `Retract` instead",
    ]),
    ("homing-breaks-interlock.ron", &[
        "24:14: error: homing step `B-` breaks interlock never[0] `B.moving && !A.home` with A at its end",
    ]),
    ("homing-incomplete.ron", &[
        "23:13: error: homing leaves `B` away from home: the cycle could start from there",
    ]),
    ("homing-unknown-step.ron", &[
        "23:17: error: unknown actuator `C`",
        "23:20: error: `X` is not a step: write an actuator name and `+` or `-`, e.g. `VC+`",
    ]),
    ("home-input-unknown.ron", &["23:11: error: no role has an input `HOMEX`"]),
    ("homing-underivable.ron", &[
        "22:15: error: no homing order keeps the interlocks: A-, B- cannot move while the others may be anywhere (declare `homing`, e.g. `homing: \"A- B-\"`)",
    ]),
    ("homing-on-charts.ron", &[
        "60:5: error: `homing` is for sequence robots: explicit charts home themselves",
    ]),
    ("guard-unknown-name.ron", &[
        "36:68: error: unknown name `MAX`: not a variable, input or parameter of this chart",
    ]),
    // Each accepted, each broke the machine: B out at the first `B+` (its watchdog
    // faulted every cycle); HOME at each START; an e-stop at each START; a press of
    // `fault` faulted B, an input `A.end2` beside the synthesised `A.end`.
    // `check` took it; `verify` found the interlock broken in the start state (B returns
    // home at a boot, its valve dropped, while A may be out), and `push` refused it.
    ("interlock-at-power-up.ron", &[
        "23:13: error: interlock never[0] `B.moving && !A.home` may hold before HOME, with A at its end, B on its way home: a monostable valve drops at a boot (or `start: Retract` drives), and its actuator returns home at once",
    ]),
    ("start-extend.ron", &[
        "18:104: error: `start: Extend` drives `B` out before the charts run: a sequence starts with every actuator home",
    ]),
    ("home-is-start.ron", &[
        "23:11: error: `home` is the START input `START`: one button cannot both home the machine and start a cycle",
    ]),
    ("estop-is-start.ron", &[
        "15:20: error: `estop` is the START input `START`: every press would stop the machine",
    ]),
    ("input-named-like-an-event.ron", &[
        "14:29: error: input `fault` is named as the sequence's charts name their own events (`fault`, `boot`, `home` and every name with a `.`)",
        "14:54: error: input `A.end2` is named as the sequence's charts name their own events (`fault`, `boot`, `home` and every name with a `.`)",
    ]),
];

#[test]
fn each_broken_file_gives_exactly_its_diagnostics() {
    for (file, expected) in BROKEN {
        assert_eq!(diagnostics(&format!("broken/{file}")), *expected, "{file}");
    }
}

/// A chart type of more states or transitions than a table holds is refused at the first
/// one too many, and nothing compares its states or transitions in pairs (10,000 of each
/// here: 50 million pairs).
#[test]
fn a_chart_type_past_the_capacities_is_refused_at_the_first_one_too_many() {
    let text = fixture("small-charts.ron").text;
    let states: String = (0..10_000).map(|i| format!("(name: \"S{i}\"),")).collect();
    let transitions: String = (0..10_000)
        .map(|i| format!("(from: \"IDLE\", to: \"OUT\", on: \"GO\", when: \"count == {i}\"),"))
        .collect();
    let big = text
        .replacen(
            "(name: \"IDLE\"),",
            &format!("(name: \"IDLE\"),{states}"),
            1,
        )
        .replacen("transitions: [", &format!("transitions: [{transitions}"), 1);
    let src = Source::new("big.ron", big);
    let got = located(&src);
    let state_at = 32
        + (0..95)
            .map(|i| format!("(name: \"S{i}\"),").len())
            .sum::<usize>();
    let transition_at = 27
        + (0..128)
            .map(|i| {
                format!("(from: \"IDLE\", to: \"OUT\", on: \"GO\", when: \"count == {i}\"),").len()
            })
            .sum::<usize>();
    assert_eq!(
        got,
        [
            format!("31:{state_at}: chart type `Mover` has 10003 states: a table holds at most 96 (MAX_STATES)"),
            format!("35:{transition_at}: chart type `Mover` has 10003 transitions: a table holds at most 128 (MAX_TRANSITIONS)"),
        ]
    );
}

/// A chart type no chart is of may be larger than a table: a warning says so.
#[test]
fn a_chart_type_past_the_capacities_that_no_chart_uses_is_a_warning() {
    let text = fixture("small-charts.ron").text;
    let states: String = (0..97).map(|i| format!("(name: \"S{i}\"),")).collect();
    let big = format!("chart_types: [(name: \"Big\", states: [{states}]),");
    let src = Source::new("unused.ron", text.replacen("chart_types: [", &big, 1));
    let ninety_seventh = src.text.find("(name: \"S96\")").expect("S96");
    let (line, col) = src.line_col(ninety_seventh);
    assert_eq!(
        located(&src),
        [format!(
            "{line}:{col}: chart type `Big` has 97 states: a table holds at most 96 (MAX_STATES); \
             no chart is of it"
        )]
    );
}

/// A role of more charts than a table holds is refused at the first one too many, before
/// its charts are elaborated (10,000 of them here).
#[test]
fn a_role_of_more_charts_than_a_table_holds_is_refused_at_the_first_one_too_many() {
    let text = fixture("small-charts.ron").text;
    let chart =
        r#"(name: "a", type: "Mover", params: {"M": 1}, on: {"GO": "START", "BACK": "B/b.DONE"})"#;
    let more: String = (0..10_000)
        .map(|i| format!(", {}", chart.replace("\"a\"", &format!("\"a{i}\""))))
        .collect();
    let src = Source::new(
        "many.ron",
        text.replacen(chart, &format!("{chart}{more}"), 1),
    );
    let got = located(&src);
    let ninth = src.text.find("(name: \"a7\"").expect("the ninth chart");
    let (line, col) = src.line_col(ninth);
    assert_eq!(
        got,
        [format!(
            "{line}:{col}: role `A` has 10001 charts: a table holds at most 8 (MAX_CHARTS)"
        )]
    );
}

/// Asserts that, with `from` in `text` replaced by each of `written`, the diagnostic
/// whose message starts with `message` points at the `zz` the replacement brings.
fn points_at_zz(text: &str, from: &str, written: &[&str], message: &str) {
    assert!(text.contains(from));
    for written in written {
        let src = Source::new("zz.ron", text.replacen(from, written, 1));
        let diags = check(&src).diagnostics;
        let zz = diags
            .iter()
            .find(|d| d.message.starts_with(message))
            .unwrap_or_else(|| panic!("{written}: {diags:?}"));
        let (line, col) = src.line_col(src.text.find("zz").expect("zz"));
        assert_eq!(zz.line_col(&src), (line, col), "{written}");
    }
}

/// An error inside an expression points at its place in the file when the string writes
/// escapes (`\u{63}` or `\x63` for `c`, `\t`, `\n`) or is a raw string.
#[test]
fn an_expression_error_points_into_the_file_through_escapes() {
    let text = fixture("small-charts.ron").text;
    let written = [
        r#"when: "count < M || zz""#,
        r#"when: "\u{63}\u{6f}unt\t< M || zz""#,
        r#"when: "\x63ount\r\n< M || zz""#,
        r##"when: r#"count < M || zz"#"##,
    ];
    let guard = r#"when: "count < M || true""#;
    points_at_zz(&text, guard, &written, "unknown name `zz`");
}

/// An interlock's error too, through escapes and a line continuation (`\` at the end of a
/// line: the next line's leading whitespace is no part of the value).
#[test]
fn an_interlock_error_points_into_the_file_through_escapes_and_continuations() {
    let path = format!(
        "{}/../robot-configs/paint-robot.ron",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(path).expect("paint-robot.ron");
    let written = [
        "never: [\"HC.moving && !VC.home && zz\"",
        "never: [\"HC.moving && \\u{21}VC.home && \\\n          zz\"",
        "never: [\"HC.moving && !VC.home && \\\r\n\t zz\"",
    ];
    let never = r#"never: ["HC.moving && !VC.home""#;
    points_at_zz(&text, never, &written, "`zz` is not an interlock name");
}

#[test]
fn every_broken_file_is_in_the_table() {
    let dir = format!("{}/../tests/fixtures/broken", env!("CARGO_MANIFEST_DIR"));
    let mut on_disk: Vec<String> = std::fs::read_dir(dir)
        .expect("fixtures/broken")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|f| !f.starts_with("automata-")) // tests/automata.rs
        .filter(|f| !f.starts_with("petri-")) // tests/petri.rs
        .collect();
    on_disk.sort();
    let mut listed: Vec<String> = BROKEN.iter().map(|(f, _)| f.to_string()).collect();
    listed.sort();
    assert_eq!(on_disk, listed);
}

#[test]
fn the_small_robots_the_broken_files_derive_from_are_clean() {
    assert_eq!(diagnostics("small-sequence.ron"), Vec::<String>::new());
    assert_eq!(diagnostics("small-charts.ron"), Vec::<String>::new());
}

#[test]
fn every_robot_config_checks_without_a_diagnostic_but_sensorless_steps() {
    let dir = format!("{}/../robot-configs", env!("CARGO_MANIFEST_DIR"));
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).expect("robot-configs") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "ron") {
            let text = std::fs::read_to_string(&path).expect("read");
            let src = Source::new(path.display().to_string(), text);
            let checked = check(&src);
            let (robot, diags) = (checked.robot, checked.diagnostics);
            assert!(robot.is_some());
            let short: Vec<String> = diags
                .iter()
                .filter(|d| !sensorless(d))
                .map(|d| d.short(&src))
                .collect();
            assert_eq!(short, Vec::<String>::new());
            n += 1;
        }
    }
    assert!(n >= 4, "{n} configs");
}

#[test]
fn a_diagnostic_renders_with_file_line_col_the_line_and_a_caret() {
    let src = fixture("broken/step-undeclared.ron");
    let diags = check(&src).diagnostics;
    let text = diags[0].render(&src, false);
    let expected = "  × unknown actuator `C`
    ╭─[broken/step-undeclared.ron:22:22]
 21 │     start: \"START\",
 22 │     sequence: \"A+ B+ C+ B- A-\",
    ·                      ─┬
    ·                       ╰── not declared by any role
 23 │ )
    ╰────
  help: actuators: A, B
";
    assert_eq!(text, expected);
}

/// A file with Windows line ends (CRLF) renders as the same file with LF ones: the same
/// line numbers, no carriage return shown. Found: the line after the span was numbered as
/// the span's, with a stray `^M`.
#[test]
fn a_diagnostic_of_a_crlf_file_renders_as_of_the_lf_file() {
    let render = |src: &Source| {
        let diags = check(src).diagnostics;
        diags
            .iter()
            .map(|d| d.render(src, false))
            .collect::<Vec<_>>()
    };
    for (file, _) in BROKEN {
        let lf = fixture(&format!("broken/{file}"));
        let crlf = Source::new(lf.name.clone(), lf.text.replace('\n', "\r\n"));
        let want = render(&lf);
        assert!(!want.is_empty(), "{file}");
        assert_eq!(render(&crlf), want, "{file}");
    }
}

/// The same for spans at a line's end, across line ends and after them, in text with
/// multi-byte characters: the CRLF file renders each as the LF file does (a span starting
/// at the carriage return was one column off).
#[test]
fn spans_at_line_ends_of_a_crlf_file_render_as_of_the_lf_file() {
    let lf = "(\n    name: \"é€😀\",\n    x: 1,\n)\n";
    let crlf = lf.replace('\n', "\r\n");
    // An offset of the LF text in the CRLF one.
    let at = |o: usize| o + lf[..o].matches('\n').count();
    let render = |text: &str, span: std::ops::Range<usize>| {
        let src = Source::new("crlf.ron", text);
        robot_compiler::Diagnostic::error(span, "here").render(&src, false)
    };
    for (end, _) in lf.match_indices('\n') {
        let next = lf[end + 1..].find('\n').map_or(lf.len(), |i| end + 1 + i);
        let before = lf[..end].char_indices().last().map_or(0, |(i, _)| i);
        for span in [
            end..end,
            end..end + 1,
            before..end + 1,
            end..next,
            end + 1..next,
        ] {
            assert_eq!(
                render(&crlf, at(span.start)..at(span.end)),
                render(lf, span.clone()),
                "{span:?}"
            );
        }
    }
}

#[test]
fn the_complete_example_of_the_format_doc_checks_clean_but_sensorless_steps() {
    let doc = std::fs::read_to_string(format!(
        "{}/../docs/robot-format.md",
        env!("CARGO_MANIFEST_DIR")
    ))
    .expect("docs/robot-format.md");
    let start = doc.find("```ron\n").expect("a ron block") + "```ron\n".len();
    let end = start + doc[start..].find("```").expect("closed");
    let src = Source::new("robot-format.md", &doc[start..end]);
    let checked = check(&src);
    let (robot, diags) = (checked.robot, checked.diagnostics);
    assert!(robot.is_some());
    let short: Vec<String> = diags
        .iter()
        .filter(|d| !sensorless(d))
        .map(|d| d.short(&src))
        .collect();
    assert_eq!(short, Vec::<String>::new());
}

/// The warning every step of a sensorless gripper gets (the paint robot's GR has none).
fn sensorless(d: &robot_compiler::Diagnostic) -> bool {
    !d.is_error() && d.message.contains("has no completion sensor")
}

/// A sequence in which one role moves more often than its table holds states is refused
/// at the first step too many, before any synthesis (a role's events were looked up by a
/// scan per step: 4,000 steps took seconds).
#[test]
fn a_role_that_moves_in_more_steps_than_a_table_holds_states_is_refused_at_the_first_one_too_many()
{
    let text = fixture("small-sequence.ron").text;
    let steps = "A+ B+ B- A- ".repeat(4_000);
    let src = Source::new(
        "long.ron",
        text.replace("\"A+ B+ B- A-\"", &format!("\"{}\"", steps.trim_end())),
    );
    let got = located(&src);
    // Step 97 of A is the 49th repetition's `A+`.
    let at = src.text.find("sequence: \"").expect("the sequence") + "sequence: \"".len();
    let ninety_seventh = |role: char| {
        let (line, col) = src.line_col(at + 48 * 12 + if role == 'A' { 0 } else { 3 });
        format!(
            "{line}:{col}: `{role}+`: role `{role}` moves in more than 96 steps of the sequence"
        )
    };
    assert_eq!(got, [ninety_seventh('A'), ninety_seventh('B')]);
}

/// A robot of more roles than one switch-over moves together is refused at the first one
/// too many, before any synthesis (whose work grows with roles x steps).
#[test]
fn a_robot_of_more_roles_than_a_switch_over_moves_is_refused_at_the_first_one_too_many() {
    let n = 17;
    let role = |i: usize| {
        let start = if i == 0 {
            ", inputs: [(name: \"START\", pin: 4)]"
        } else {
            ""
        };
        format!(
            "(name: \"R{i}\", actuators: [(name: \"R{i}\", kind: DoubleActing(extend: 0, \
             retract: 1, home: 2, end: 3))]{start})"
        )
    };
    let list = |f: &dyn Fn(usize) -> String| (0..n).map(f).collect::<Vec<_>>().join(", ");
    let steps = |sign: char| list(&|i| format!("R{i}{sign}")).replace(',', "");
    let text = format!(
        "Robot(name: \"many\", network: (pan_id: 0x1234, channel: 15), nodes: [{}], \
         assign: [{}], roles: [{}], start: \"START\", sequence: \"{} {}\")",
        list(&|i| format!("(name: \"n{i}\", address: {})", 0x1000 + i)),
        list(&|i| format!("(\"R{i}\", \"n{i}\")")),
        list(&role),
        steps('+'),
        steps('-'),
    );
    let src = Source::new("many.ron", text);
    let (line, col) = src.line_col(src.text.find("(name: \"R16\", act").expect("role 17"));
    assert_eq!(
        located(&src),
        [format!(
            "{line}:{col}: 17 roles: a robot has at most 16 (MAX_ROLES), the nodes one \
             switch-over moves together"
        )]
    );
}

/// The HOME input may be named `home`: it is then the event itself, nothing synthesised
/// beside it (refused as a synthesised event's name while another input would be).
#[test]
fn a_home_input_named_home_is_the_home_input() {
    let base = fixture("small-sequence.ron");
    let text = base
        .text
        .replace(
            "inputs: [(name: \"START\", pin: 4)],",
            "inputs: [(name: \"START\", pin: 4), (name: \"home\", pin: 5)],",
        )
        .replace(
            "    start: \"START\",",
            "    start: \"START\",\n    home: \"home\",",
        );
    assert_eq!(
        located(&Source::new("home.ron", text)),
        Vec::<String>::new()
    );
}
