//! Runs the table interpreter over a count of stimuli, for `bench/instructions.sh`, which
//! counts its instructions with callgrind twice (N and 2N) and divides the difference by N:
//! what one more stimulus costs, with start-up, compilation and the table's build taken
//! out.
//!
//! ```text
//! instructions ctu1 N      N pulses into one E_CTU chart (bench/robots/e-ctu.ron, ONE)
//! instructions ctu2 N      N pulses into two E_CTU charts in series (TWO)
//! instructions vc N        N cycles of the paper robot's VC chart, interpreted
//! instructions vc-hand N   the same N cycles through the hand-written `match`
//! ```
//!
//! Prints what the run left (counts, states), so the work cannot be optimised away and a
//! wrong run shows.

use std::hint::black_box;
use std::process::ExitCode;

use config_schema::{Table, Topic};
use node_fw::ecc::Engine;
use robot_compiler::{compile, Compiled, Source};
use robot_tests::paper_robot;
use robot_tests::vc_dispatch::{engine, run_hand, run_interpreter, HandVc, Sum};

fn e_ctu() -> Result<Compiled, String> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../bench/robots/e-ctu.ron");
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    compile::compile(&Source::new(path, text))
        .map_err(|d| format!("e-ctu.ron does not compile: {d:?}"))
}

/// Role `role`'s table, the (publisher, topic) of SRC's PULSE as it subscribes to it, and
/// the index of its variable `var`.
fn counter<'c>(
    c: &'c Compiled,
    role: &str,
    var: &str,
) -> Result<(&'c Table, u8, Topic, usize), String> {
    let i =
        c.ir.roles
            .iter()
            .position(|r| r.name == role)
            .ok_or("no role")?;
    let (r, table) = (&c.ir.roles[i], &c.tables[i]);
    let local = r
        .imports
        .iter()
        .find(|(from, event, _)| from == "SRC" && event == "PULSE")
        .map(|(_, _, local)| local)
        .ok_or("no SRC/PULSE")?;
    let event = r.events.iter().position(|e| e == local).ok_or("no event")?;
    let sub = table
        .subscriptions
        .iter()
        .find(|s| usize::from(s.event) == event)
        .ok_or("no subscription")?;
    let v = r
        .vars
        .iter()
        .position(|(name, _)| name == var)
        .ok_or_else(|| format!("no var {var}: {:?}", r.vars))?;
    Ok((table, sub.publisher, sub.topic, v))
}

fn pulses(c: &Compiled, role: &str, var: &str, n: u64) -> Result<String, String> {
    let (table, publisher, topic, cv) = counter(c, role, var)?;
    let mut e = Engine::new(table);
    let mut fx = Sum::default();
    e.reset(&mut fx);
    for _ in 0..n {
        e.remote(black_box(publisher), black_box(topic), &mut fx);
    }
    Ok(format!("{var} = {:?}, effects {:#x}", e.var(cv), fx.0))
}

fn run(what: &str, n: u64) -> Result<String, String> {
    match what {
        "ctu1" => pulses(&e_ctu()?, "ONE", "c1.CV", n),
        "ctu2" => pulses(&e_ctu()?, "TWO", "c2.CV", n),
        "vc" | "vc-hand" => {
            let table = paper_robot::vc_table().map_err(|e| format!("{e:?}"))?;
            let mut fx = Sum::default();
            if what == "vc" {
                let mut e = engine(&table);
                for _ in 0..n {
                    run_interpreter(&mut e, &mut fx);
                }
            } else {
                let mut h = HandVc::new(&table);
                for _ in 0..n {
                    run_hand(&mut h, &mut fx);
                }
            }
            Ok(format!("effects {:#x}", fx.0))
        }
        _ => Err(format!("unknown run `{what}`: ctu1, ctu2, vc or vc-hand")),
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(what), Some(n)) = (args.first(), args.get(1).and_then(|n| n.parse().ok())) else {
        eprintln!("usage: instructions ctu1|ctu2|vc|vc-hand N");
        return ExitCode::from(2);
    };
    match run(what, n) {
        Ok(left) => {
            println!("{what} {n}: {left}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("instructions: {e}");
            ExitCode::FAILURE
        }
    }
}
