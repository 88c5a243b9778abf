//! `verify` of the ball-sorting station (`robot-configs/ball-sorter.ron`): every reachable
//! state with every colour sequence of up to N balls, the fall untimed; each ball in
//! exactly one bin, no gate moving while a ball falls past it, the pusher never feeding
//! while a gate moves, each ball's selection as the reference semantics'.

use robot_analysis::verify::{explore, ExploreOptions, Model, Property, Report};
use robot_compiler::Compiled;

mod common;
use common::{build, load};

const SORTER: &str = "../robot-configs/ball-sorter.ron";

fn verify(c: &Compiled, balls: usize) -> Report {
    let model = Model::with_balls(c, balls).expect("model builds");
    explore(&model, ExploreOptions::default())
}

#[test]
fn the_station_passes_for_every_feed_of_up_to_4_balls() {
    let c = build(&load(SORTER));
    let r = verify(&c, 4);
    assert!(r.ok(), "{}", r.render("ball-sorter", 0));
    assert_eq!(
        r.feed.as_deref(),
        Some(
            "ball feed: every sequence of up to 4 balls of black, gray, orange (untimed: the \
             next ball is taken to lie at the sensors once the pusher is home; `sim` times its \
             roll)"
        )
    );
    assert_eq!(
        (r.states, r.transitions, r.idle, r.stopped),
        (5299, 10232, 63, 0)
    );
    // One ball: 3 colours or none at the start, and the end of the feed after it.
    let r = verify(&c, 1);
    assert_eq!((r.states, r.transitions, r.idle), (164, 279, 7));
}

/// An automaton written in a `facts_file` (next to the robot file) verifies as the same
/// automaton written inline: `verify` takes the automata as compile resolved them. It
/// read no file, so such a station did not verify, and `push` refused it.
#[test]
fn an_automaton_from_a_facts_file_verifies_as_written_inline() {
    let src = load(SORTER);
    let start = src
        .text
        .find("facts: r#\"state(s0).")
        .expect("fig. 1's facts inline");
    let end = start + src.text[start..].find("\"#,").expect("their end") + 3;
    let dir = std::env::temp_dir().join(format!("sorter-facts-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let facts = src.text[start..end]
        .trim_start_matches("facts: r#\"")
        .trim_end_matches("\"#,");
    std::fs::write(dir.join("fig1.pl"), facts).unwrap();
    let text = format!(
        "{}facts_file: \"fig1.pl\",{}",
        &src.text[..start],
        &src.text[end..]
    );
    let path = dir.join("ball-sorter.ron");
    let c = build(&robot_compiler::Source::new(
        path.display().to_string(),
        text,
    ));
    std::fs::remove_dir_all(&dir).unwrap();
    let r = verify(&c, 4);
    assert!(r.ok(), "{}", r.render("ball-sorter", 0));
    assert_eq!((r.states, r.transitions), (5299, 10232));
}

/// The station as it was: each gate closed on a 150 ms hold timer started by ENTRY. verify
/// treats timers as untimed, so the timer may expire before the ball has fallen past the
/// gate: gate G2, open for an orange fig. 1 takes, closes while the ball falls toward it.
#[test]
fn gates_held_by_a_timer_race_the_falling_ball() {
    let c = build(&load("fixtures/verify/ball-sorter-hold-timer.ron"));
    let r = verify(&c, 2);
    let v = r.violation.as_ref().expect("a race");
    assert_eq!(v.property, Property::GateFall);
    assert_eq!(
        v.message,
        "gate G2 moves while ball 1 (orange) falls toward it"
    );
    assert_eq!(v.start.as_deref(), Some("ball feed: ball 1 is orange"));
    assert_eq!(v.steps, 13);
    let moves: Vec<&str> = (v.trace.iter())
        .filter(|l| l.as_bytes().get(2).is_some_and(u8::is_ascii_digit))
        .map(String::as_str)
        .collect();
    assert_eq!(
        moves[9..],
        [
            " 10. PUSHER reaches its end switch",
            " 11. ball 1 (orange) passes the entry sensor",
            " 12. radio delivers SENSING -> GATE2",
            " 13. timer gate.hold of GATE2 expires",
        ]
    );
    assert!(
        v.trace.last().is_some_and(
            |l| l.ends_with("balls: no ball at the sensors, ball 1 (orange) falling to gate 1")
        ),
        "{:?}",
        v.trace.last()
    );
}

/// A gate that answers `ready` as it starts to open: the pusher may feed while it moves.
#[test]
fn a_gate_ready_before_it_is_open_is_caught() {
    let text = load(SORTER).text.replacen(
        r#"(name: "OPENING", actions: [Extend("G1")]),
                (name: "OPEN", actions: [Emit("ready")]),"#,
        r#"(name: "OPENING", actions: [Extend("G1"), Emit("ready")]),
                (name: "OPEN"),"#,
        1,
    );
    let c = build(&robot_compiler::Source::new("hasty.ron", text));
    let v = verify(&c, 1).violation.expect("a violation");
    assert_eq!(v.property, Property::PusherGate);
    assert_eq!(v.message, "the pusher feeds while gate G1 moves");
}

/// A gate whose automaton's `Out` does not reach it (the gate never opens): balls the
/// automaton takes land in the wrong bin, against the reference semantics.
#[test]
fn a_gate_that_ignores_its_automaton_sorts_against_the_reference() {
    let text = load(SORTER).text.replacen(
        r#"(from: "WAIT", to: "TAKE", on: "TOOK"),"#,
        r#"(from: "TAKE", to: "WAIT", on: "TOOK"),"#,
        1,
    );
    let c = build(&robot_compiler::Source::new("deaf.ron", text));
    let v = verify(&c, 1).violation.expect("a violation");
    assert_eq!(v.property, Property::Selection);
    assert_eq!(
        v.message,
        "ball 1 (black) landed in bin 2, taken by nd, fig1, EOS none; the reference \
         semantics: bin 1, taken by nd, fig1, EOS none"
    );
}
