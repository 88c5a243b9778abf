//! Bad input in linear time, printed: `check` of a robot file with N unknown keys in a
//! chart's `on` map (N diagnostics, each located at its key), and the import of `.fbt`
//! files with N event inputs or an `IF` of N `ELSIF`s (refused at the first one past the
//! capacities), per 1,000 and as a ratio to the figure at 1,000: flat when linear.
//!
//!     cargo bench -p robot-compiler --bench bad_input

mod support;

use std::hint::black_box;

use support::time;

use robot_compiler::iec61499::fbt;
use robot_compiler::{check, Source};

/// A robot whose chart's `on` map has `n` keys its chart type lacks.
fn unknown_keys(n: usize) -> String {
    let keys: String = (0..n).map(|i| format!("\"X{i}\": \"I\", ")).collect();
    format!(
        "Robot(name: \"r\", network: (pan_id: 1, channel: 11), \
         nodes: [(name: \"n1\", address: 1)], assign: [(\"A\", \"n1\")], \
         chart_types: [(name: \"T\", inputs: [\"EI\"], states: [(name: \"S\")], transitions: [])], \
         roles: [(name: \"A\", inputs: [(name: \"I\", pin: 0)], \
         charts: [(name: \"t\", type: \"T\", on: {{{keys}\"EI\": \"I\"}})])])"
    )
}

/// A basic FB type with `events` event inputs and an algorithm of `arms` `ELSIF`s.
fn fbt(events: usize, arms: usize) -> String {
    let events: String = (0..events)
        .map(|i| format!("<Event Name=\"E{i}\"/>"))
        .collect();
    let arms = "ELSIF N &gt; 0 THEN N := 1; ".repeat(arms);
    format!(
        "<FBType Name=\"T\"><InterfaceList><EventInputs><Event Name=\"EI\"/>{events}</EventInputs>\
         <InternalVars/></InterfaceList><BasicFB><InternalVars><VarDeclaration Name=\"N\" \
         Type=\"INT\"/></InternalVars><ECC><ECState Name=\"S\"><ECAction Algorithm=\"A\"/>\
         </ECState><ECTransition Source=\"S\" Destination=\"S\" Condition=\"EI\"/></ECC>\
         <Algorithm Name=\"A\"><ST Text=\"IF N &gt; 0 THEN N := 1; {arms}END_IF;\"/></Algorithm>\
         </BasicFB></FBType>"
    )
}

fn main() {
    let runs: [(&str, &dyn Fn(usize) -> f64); 3] = [
        ("check: unknown `on` keys", &|n| {
            let src = Source::new("r.ron", unknown_keys(n));
            time(3, || {
                black_box(check::check(black_box(&src)));
            })
        }),
        (".fbt: event inputs", &|n| {
            let text = fbt(n, 0);
            time(3, || {
                black_box(fbt::import(black_box(&text)).is_err());
            })
        }),
        (".fbt: ELSIF arms", &|n| {
            let text = fbt(0, n);
            time(3, || {
                black_box(fbt::import(black_box(&text)).is_err());
            })
        }),
    ];
    println!("bad input, per 1,000 (and the ratio to the figure at 1,000: flat when linear)");
    for (what, run) in runs {
        let mut at_1000 = None;
        for n in [1_000, 4_000, 16_000] {
            let per_1000 = run(n) * 1e3 * 1_000.0 / n as f64;
            let base = *at_1000.get_or_insert(per_1000);
            println!(
                "  {what:<26} {n:>6}  {per_1000:>7.2} ms per 1,000  ({:.2}x)",
                per_1000 / base
            );
        }
    }
}
