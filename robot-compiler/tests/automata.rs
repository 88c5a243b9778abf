//! `check` on selecting automata: one broken robot per kind of problem
//! (tests/fixtures/broken/automata-*), each asserting the exact messages with their
//! line:col (a facts file's own place inside the message); the good robot of every form
//! (facts file, inline facts, RON, a priority) checks clean.

use robot_compiler::automata::{self, from_facts};

use robot_compiler::check::check;
use robot_compiler::Source;

fn fixture(path: &str) -> Source {
    let full = format!("{}/../tests/fixtures/{path}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&full).unwrap_or_else(|e| panic!("{full}: {e}"));
    // Named by its full path so that `facts_file`s next to it are found.
    Source::new(full, text)
}

/// `line:col: severity: message` of every diagnostic of a file, and the help of each.
fn diagnostics(path: &str) -> Vec<String> {
    let src = fixture(path);
    check(&src)
        .diagnostics
        .iter()
        .map(|d| {
            let (line, col) = d.line_col(&src);
            let sev = if d.is_error() { "error" } else { "warning" };
            match &d.help {
                Some(help) => format!("{line}:{col}: {sev}: {} [help: {help}]", d.message),
                None => format!("{line}:{col}: {sev}: {}", d.message),
            }
        })
        .collect()
}

/// (file, every diagnostic as `line:col: severity: message [help: ...]`).
const BROKEN: &[(&str, &[&str])] = &[
    ("automata-bad-facts-file.ron", &[
        "62:36: error: automata-bad-facts-file.pl:4:29: argument 6 of `transition/6` must be `ordinary` or `final`, found `fnal`",
    ]),
    ("automata-bad-facts.ron", &[
        "64:13: error: expected `.` after the fact, found `initial_state`",
    ]),
    ("automata-colour.ron", &[
        "63:33: error: colour `purple` of transition `t1` cannot be produced: it is not one of the robot's colours (black, gray, orange)",
        "65:40: error: colour `white` of automaton `b` is not one of the robot's colours (black, gray, orange): its sensors cannot produce it",
    ]),
    ("automata-conflict.ron", &[
        "64:13: error: conflict in automaton `chain`: `t1` (s1 -> s2) enters and `t2` (s2 -> s3) leaves `s2` on `black`, and `s1` and `s2` can be active together: the firing order matters (`t2` must fire first) [help: declare `priority: [\"t2\", \"t1\"]` (a transition that leaves a state fires before one that enters it)]",
        "71:13: error: conflict in automaton `swap`: `t2` (s2 -> s1) enters and `t1` (s1 -> s2) leaves `s1` on `black`, and `s2` and `s1` can be active together: the firing order matters (`t1` must fire first) [help: no firing order resolves these conflicts: they form a cycle; split the automaton or give the transitions different colours]",
    ]),
    ("automata-determinism.ron", &[
        "62:87: error: automaton `declared` is declared deterministic but it has 2 initial states {s0,s1}",
        "65:13: error: automaton `declared` is declared deterministic but `t1` and `t2` both leave `s0` on `black`",
        "68:16: warning: automaton `undeclared` is nondeterministic: `t1` and `t2` both leave `s0` on `black`; it runs as its on-line determinisation (declare `deterministic: false` to say so)",
    ]),
    ("automata-duplicate.ron", &[
        "62:42: error: duplicate state `s0` of automaton `a` (first declared at 62:30)",
        "64:18: error: duplicate transition id `t1` in automaton `a` (first declared at 63:18)",
        "66:16: error: duplicate automaton `a`",
    ]),
    ("automata-loop-cap.ron", &[
        "63:68: error: transition `t1` (s0 -> s1) of automaton `a` is not a loop: only a loop takes `max`",
        "64:13: error: `max` required on a loop: `t2` (s1 -> s1) of automaton `a` would accept any number of `gray` parts; give the most it accepts in a row",
        "65:69: error: loop `t3` of automaton `a` accepts at most 0 parts: it can never fire (`max` is at least 1)",
        "68:42: error: `max` required on a loop: `t1` (s0 -> s0) of automaton `b` would accept any number of `gray` parts; give the most it accepts in a row",
    ]),
    ("automata-undeclared-state.ron", &[
        "63:69: error: transition `t2` goes to `s9`, which is not a state of automaton `a` (states: s0, s1)",
        "65:47: error: initial state `s1` is not a state of automaton `b` (states: s0)",
    ]),
    ("automata-unreachable.ron", &[
        "62:16: warning: no final transition of automaton `a` can fire: it never selects a sequence (no EOS)",
        "62:42: warning: state `s2` of automaton `a` is unreachable from its initial state(s) {s0}",
        "65:13: warning: transition `t3` (s2 -> s0) of automaton `a` can never fire: `s2` is unreachable",
        "67:16: warning: automaton `b` has no final transition: it never selects a sequence (no EOS)",
        "70:16: error: automaton `c` has no initial state: it never takes a part",
    ]),
];

#[test]
fn each_broken_automaton_gives_exactly_its_diagnostics() {
    for (file, expected) in BROKEN {
        assert_eq!(diagnostics(&format!("broken/{file}")), *expected, "{file}");
    }
}

#[test]
fn every_broken_automaton_file_is_in_the_table() {
    let dir = format!("{}/../tests/fixtures/broken", env!("CARGO_MANIFEST_DIR"));
    let mut on_disk: Vec<String> = std::fs::read_dir(dir)
        .expect("fixtures/broken")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|f| f.starts_with("automata-") && f.ends_with(".ron"))
        .collect();
    on_disk.sort();
    let mut listed: Vec<String> = BROKEN.iter().map(|(f, _)| f.to_string()).collect();
    listed.sort();
    assert_eq!(on_disk, listed);
}

/// Fig. 1 from a facts file and inline, fig. 2 in RON, a conflict resolved by priority.
#[test]
fn the_good_automata_check_clean_and_resolve_to_the_same_model() {
    assert_eq!(diagnostics("automata.ron"), Vec::<String>::new());
    let src = fixture("automata.ron");
    let robot = check(&src).robot.expect("parses");
    let loaded = automata::load(&robot, &src);
    assert!(loaded.diagnostics.is_empty());
    let names: Vec<&str> = loaded
        .automata
        .iter()
        .map(|l| l.automaton.name.as_str())
        .collect();
    assert_eq!(names, ["fig1", "fig1-inline", "fig2", "chain"]);
    let (file, inline) = (&loaded.automata[0].automaton, &loaded.automata[1].automaton);
    // The robot's colours, in its order; the same automaton either way.
    assert_eq!(file.colours, ["black", "gray", "orange"]);
    assert_eq!(file.transitions, inline.transitions);
    assert_eq!(
        (file.initial, file.deterministic),
        (inline.initial, Some(true))
    );
    // A facts file's places are its own lines; inline facts sit in the robot file.
    let t3 = &loaded.automata[0].places.transitions[2].whole;
    assert_eq!(t3.line_col(&src), "fig1.pl:5:1");
    let t3 = &loaded.automata[1].places.transitions[2].whole;
    assert_eq!(t3.line_col(&src), "65:13");
    let chain = &loaded.automata[3].automaton;
    assert_eq!(
        automata::check::find_conflicts(chain)
            .expect("few sets")
            .len(),
        1
    );
    assert_eq!(
        chain.firing_order().iter().map(|t| t.0).collect::<Vec<_>>(),
        [1, 0, 2]
    );
}

/// A conflict is an error where both states can be active together, and none where they
/// cannot (a deterministic automaton has none).
#[test]
fn conflicts_are_found_only_where_both_states_can_be_active() {
    let chain = from_facts(
        "chain",
        "state(s1). state(s2). state(s3). initial_state(s1). initial_state(s2).
         transition(t1,s1,s2,black,_,ordinary). transition(t2,s2,s3,black,_,ordinary).
         transition(t3,s3,s1,gray,_,final).",
    )
    .expect_err("unresolved conflict");
    assert_eq!(
        chain,
        ["2:10: error: conflict in automaton `chain`: `t1` (s1 -> s2) enters and `t2` (s2 -> s3) leaves `s2` on `black`, and `s1` and `s2` can be active together: the firing order matters (`t2` must fire first)"]
    );
    // Never active together: no conflict.
    let apart = from_facts(
        "apart",
        "state(s1). state(s2). state(s3). initial_state(s1).
         transition(t1,s1,s2,black,_,ordinary). transition(t2,s2,s3,black,_,ordinary).
         transition(t3,s3,s1,gray,_,final).",
    )
    .expect("deterministic");
    assert_eq!(
        automata::check::find_conflicts(&apart.automaton),
        Ok(vec![])
    );
}

/// `from_facts`' errors are at the facts' own line:col.
#[test]
fn from_facts_errors_name_the_place_in_the_facts() {
    assert_eq!(
        from_facts("x", "state(s0).\ntransition(t1,s0,s1,black,_,final).\ninitial_state(s0).")
            .expect_err("s1"),
        ["2:18: error: transition `t1` goes to `s1`, which is not a state of automaton `x` (states: s0)"]
    );
}
