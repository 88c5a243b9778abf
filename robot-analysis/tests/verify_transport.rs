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
    println!("{}", r.render("waterjet-transport", 0));
    assert!(r.ok(), "{}", r.render("waterjet-transport", 0));
}

#[test]
fn with_any_radio_delay_a_fault_pulse_shorter_than_a_delivery_lets_a_stale_step1_turn_the_pusher() {
    let r = run(&robot(), ExploreOptions::default());
    let v = r.violation.expect("a counterexample");
    assert_eq!(v.property, Property::FaultClear);
    let moves: Vec<&str> = (v.trace.iter())
        .filter(|l| !l.starts_with(' ') || l.trim_start().starts_with(char::is_numeric))
        .map(|l| l.trim_start())
        .filter(|l| l.starts_with(char::is_numeric))
        .collect();
    assert_eq!(
        moves,
        [
            "1. operator presses START (at CABINET)",
            "2. switch FAULT is set",
            "3. switch FAULT is released",
            "4. radio delivers CABINET -> PUSHER",
        ]
    );
}
