//! `verify` of the water-jet cutter's material transport (`waterjet-transport.ron`): the
//! declared plants as the verifier's abstract model (the pusher's carriage home, between,
//! at the end; the belt it drives; the fault contact; the operator's buttons and
//! acknowledgement), explored with the fault at any time.

use robot_analysis::verify::{self, ExploreOptions, Property, Report};
use robot_compiler::Compiled;

mod common;
use common::{build, load};

fn robot() -> Compiled {
    build(&load("../robot-configs/waterjet-transport.ron"))
}

fn run(c: &Compiled, opts: ExploreOptions) -> Report {
    verify::verify(c, opts).expect("model builds")
}

fn prompt() -> ExploreOptions {
    ExploreOptions {
        prompt: true,
        ..ExploreOptions::default()
    }
}

#[test]
fn with_a_prompt_radio_the_transport_is_deadlock_free_and_safe_after_two_fault_pulses() {
    let r = run(&robot(), prompt());
    let text = r.render("waterjet-transport", 0);
    println!("{text}");
    assert!(r.ok(), "{text}");
    assert_eq!(
        (r.states, r.transitions, r.idle, r.stopped),
        (8390, 36003, 4, 0)
    );
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0],
        "waterjet-transport: plants: motor PUSHER moving BELT (home, between, end); switch \
         FAULT set up to 2 times and released, each at any time; RELEASE, RESTART pressed at \
         any time; alarms acknowledged"
    );
    assert_eq!(
        lines[3],
        "ok: deadlock freedom, no cycle declared (`expect`) to conform to, 0 interlock(s), no double actuation, no \
         engine fault, a fault stops every node, each of the 5 functions in exactly one place \
         in every state, after a fault no motor turns clockwise until the operator has \
         cleared it"
    );
    let once = run(
        &robot(),
        ExploreOptions {
            faults: 1,
            ..prompt()
        },
    );
    assert!(once.ok());
    assert_eq!((once.states, once.transitions), (1110, 4391));
    assert!(once
        .render("w", 0)
        .contains("switch FAULT set once and released"));
}

/// The fault detection as it was first declared: `Faulted` only while the contact is set.
const UNLATCHED: &str = r#"places: ["Ok", "Faulted"],
            initial: "Ok",
            transitions: [
                (name: "fault", on: "FAULT", from: "Ok", to: "Faulted"),
                (name: "cleared", on: "FAULT.fall", from: "Faulted", to: "Ok"),
            ],"#;

#[test]
fn an_unlatched_fault_detection_lets_a_pulse_shorter_than_a_delivery_turn_the_pusher_with_a_stale_step1(
) {
    let src = load("../robot-configs/waterjet-transport.ron");
    let (a, b) = (
        src.text
            .find(r#"places: ["Ok", "Faulted", "Released", "Cleared"],"#),
        src.text
            .find(r#"(name: "again", on: "FAULT", from: "Cleared", to: "Faulted"),"#),
    );
    let (a, b) = (a.expect("the latch"), b.expect("its last transition"));
    let end = b + src.text[b..].find("],").expect("the list's end") + 2;
    let text = format!("{}{UNLATCHED}{}", &src.text[..a], &src.text[end..]);
    let text = text.replace(
        "FaultDetection.Faulted || FaultDetection.Released",
        "FaultDetection.Faulted",
    );
    let c = build(&robot_compiler::Source::new("unlatched.ron", text));
    let r = run(&c, prompt());
    let v = r.violation.expect("a counterexample");
    assert_eq!(v.property, Property::FaultClear);
    assert_eq!(
        v.message,
        "PUSHER runs clockwise after the fault, before the operator cleared it"
    );
    assert_eq!(
        moves(&v.trace),
        [
            "1. operator presses START (at CABINET)",
            "2. switch FAULT is set",
            "3. switch FAULT is released",
            "4. radio delivers CABINET -> PUSHER",
        ]
    );
}

#[test]
fn with_any_radio_delay_the_belt_node_lags_the_pusher_by_whole_cycles() {
    let r = run(&robot(), ExploreOptions::default());
    let v = r.violation.expect("a counterexample");
    assert_eq!(v.property, Property::LinkBound);
    assert_eq!(
        v.message,
        "more than 8 publications in flight from PUSHER to BELT"
    );
    let moves = moves(&v.trace);
    assert_eq!(moves.len(), 20);
    assert!(!moves.iter().any(|m| m.contains("-> BELT")), "{moves:?}");
}

/// The transport's text with `from` replaced by `to` (once), compiled.
fn variant(from: &str, to: &str) -> Compiled {
    let src = load("../robot-configs/waterjet-transport.ron");
    assert_eq!(src.text.matches(from).count(), 1, "{from}");
    let text = src.text.replacen(from, to, 1);
    build(&robot_compiler::Source::new("variant.ron", text))
}

/// The numbered move lines of a counterexample.
fn moves(trace: &[String]) -> Vec<&str> {
    (trace.iter())
        .map(|l| l.trim_start())
        .filter(|l| l.starts_with(char::is_numeric))
        .collect()
}

#[test]
fn a_pusher_that_ignores_the_fault_is_caught_running_on() {
    let c = variant(
        r#"(name: "fault", on: "FaultDetection.Faulted", row: [1, -1, 0]),"#,
        "",
    );
    let r = run(&c, prompt());
    let v = r.violation.expect("a counterexample");
    assert_eq!(v.property, Property::FaultClear);
    assert_eq!(
        v.message,
        "PUSHER runs clockwise after the fault, before the operator cleared it"
    );
    assert_eq!(
        moves(&v.trace),
        [
            "1. operator presses START (at CABINET)",
            "2. radio delivers CABINET -> PUSHER",
            "3. switch FAULT is set",
        ]
    );
}

#[test]
fn a_release_that_turns_the_pusher_clockwise_is_caught_before_the_operator_cleared_it() {
    let c = variant(
        r#"row: [-1, 0, 1], when: "!PUSHER_HOME""#,
        r#"row: [-1, 1, 0], when: "!PUSHER_HOME""#,
    );
    let r = run(&c, prompt());
    let v = r.violation.expect("a counterexample");
    assert_eq!(v.property, Property::FaultClear);
    assert_eq!(
        moves(&v.trace),
        [
            "1. operator presses START (at CABINET)",
            "2. radio delivers CABINET -> PUSHER",
            "3. switch FAULT is set",
            "4. radio delivers PUSHER -> CABINET",
            "5. radio delivers PUSHER -> CABINET",
            "6. operator presses RELEASE",
            "7. radio delivers CABINET -> PUSHER",
        ]
    );
    let last = v.trace.last().expect("the state");
    assert!(
        last.contains("PUSHER[Pusher=Clockwise FaultDetection=Released]"),
        "{last}"
    );
}
