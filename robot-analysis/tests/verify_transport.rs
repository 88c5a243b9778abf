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
fn with_a_prompt_radio_the_transport_is_deadlock_free_and_safe_after_a_fault() {
    let r = run(&robot(), prompt());
    let text = r.render("waterjet-transport", 0);
    println!("{text}");
    assert!(r.ok(), "{text}");
    assert_eq!(
        (r.states, r.transitions, r.idle, r.stopped),
        (321, 1086, 2, 0)
    );
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0],
        "waterjet-transport: plants: motor PUSHER moving BELT (home, between, end); switch \
         FAULT set and released at any time; RELEASE, RESTART pressed at any time; alarms \
         acknowledged"
    );
    assert_eq!(
        lines[3],
        "ok: deadlock freedom, sequence conformance, 0 interlock(s), no double actuation, no \
         engine fault, a fault stops every node, each of the 5 functions in exactly one place \
         in every state, after a fault no motor turns clockwise until the operator has \
         cleared it"
    );
}

#[test]
fn with_any_radio_delay_a_fault_pulse_shorter_than_a_delivery_lets_a_stale_step1_turn_the_pusher() {
    let r = run(&robot(), ExploreOptions::default());
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
            "3. radio delivers PUSHER -> CABINET",
            "4. radio delivers PUSHER -> BELT",
            "5. radio delivers BELT -> CABINET",
            "6. switch FAULT is set",
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
            "3. radio delivers PUSHER -> CABINET",
            "4. radio delivers PUSHER -> BELT",
            "5. radio delivers BELT -> CABINET",
            "6. switch FAULT is set",
            "7. radio delivers PUSHER -> CABINET",
            "8. operator presses RELEASE",
            "9. radio delivers CABINET -> PUSHER",
        ]
    );
    let last = v.trace.last().expect("the state");
    assert!(
        last.contains("PUSHER[FaultDetection=Faulted Pusher=Clockwise]"),
        "{last}"
    );
}
