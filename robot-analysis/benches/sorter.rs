//! The ball-sorting station (`robot-configs/ball-sorter.ron`), printed figures: charts and
//! blob bytes per automaton transition, events per ball, sorting throughput in simulation
//! (balls per second of wall time), and `verify`'s states and time for feeds of up to 4, 8
//! and 12 balls (every colour sequence of that length). Best of 3 runs where timed.
//!
//!     cargo bench -p robot-analysis --bench sorter
//!
//! `SORTER_BALLS=4,8` limits the verify feeds.

use std::time::{Duration, Instant};

use robot_analysis::sorter;
use robot_analysis::verify::{explore, ExploreOptions, Model};
use robot_compiler::{compile, Compiled, Source};

const SORTER: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../robot-configs/ball-sorter.ron"
);

fn station(text: &str) -> Compiled {
    compile(&Source::new("ball-sorter.ron", text)).expect("compiles")
}

fn best<T>(runs: usize, mut f: impl FnMut() -> T) -> (Duration, T) {
    let mut best = Duration::MAX;
    let mut out = None;
    for _ in 0..runs {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed());
        out = Some(r);
    }
    (best, out.expect("runs > 0"))
}

/// Charts and blob bytes each automaton's network adds to its gate's table, per
/// transition: the station against the same station whose gate role runs no automaton.
fn per_transition(text: &str, c: &Compiled) {
    println!("charts and blob bytes per automaton transition:");
    for a in &c.robot.automata {
        let Some(role) = a.role.as_deref() else {
            continue;
        };
        let r =
            c.ir.roles
                .iter()
                .position(|x| x.name == role)
                .expect("role");
        let decl = format!(
            "role: \"{role}\",\n            parts: \"SENSING/part\",\n            out: \"gate.TOOK\","
        );
        assert!(text.contains(&decl), "{decl}");
        let bare = station(&text.replacen(&decl, "", 1));
        let n = a_transitions(c, &a.name);
        let charts = c.ir.roles[r].charts.len() - bare.ir.roles[r].charts.len();
        let bytes = c.blobs[r].len() - bare.blobs[r].len();
        println!(
            "  {:<5} on {role}: {n} transitions, {charts} charts, {bytes} blob bytes \
             ({} bytes per transition; the gate's table {} bytes)",
            a.name,
            bytes / n.max(1),
            c.blobs[r].len()
        );
    }
}

/// The transitions of automaton `name`: its charts on its role.
fn a_transitions(c: &Compiled, name: &str) -> usize {
    (c.ir.roles.iter())
        .flat_map(|r| &r.charts)
        .filter(|ch| ch.name.starts_with(&format!("{name}.")))
        .count()
}

/// A feed of `n` balls, the robot's own repeated.
fn feed(c: &Compiled, n: usize) -> Vec<String> {
    let f = &c.robot.sorting.as_ref().expect("station").feed;
    f.iter().cycle().take(n).cloned().collect()
}

fn events_and_throughput(c: &Compiled) {
    let balls = feed(c, 13);
    let run = sorter::simulate(c, Some(&balls)).expect("runs");
    assert!(run.ok(), "{}", run.report());
    // Counted from the world's trace, by kind.
    let (mut fired, mut published, mut delivered, mut inputs) = (0usize, 0, 0, 0);
    for line in &run.trace {
        if line.contains(" -> S") && line.contains("(transition ") {
            fired += 1;
        } else if line.contains(" publishes event ") {
            published += 1;
        } else if line.contains("topic ") && line.contains(" -> node ") {
            delivered += 1;
        } else if line.contains(" input ") && line.contains(" = ") {
            inputs += 1;
        }
    }
    let k = balls.len() as f64;
    println!(
        "events per ball (the robot's 13-ball feed, {} ms virtual): {:.1} chart transitions \
         fired, {:.1} publications, {:.1} radio deliveries, {:.1} input edges",
        run.duration_ms,
        fired as f64 / k,
        published as f64 / k,
        delivered as f64 / k,
        inputs as f64 / k
    );
    for n in [13usize, 130] {
        let balls = feed(c, n);
        let (t, run) = best(3, || sorter::simulate(c, Some(&balls)).expect("runs"));
        assert!(run.ok());
        println!(
            "sim throughput, {n} balls: {:.1} ms wall, {:.0} balls/s of wall time \
             ({:.0} x real time)",
            t.as_secs_f64() * 1e3,
            n as f64 / t.as_secs_f64(),
            run.duration_ms as f64 / 1e3 / t.as_secs_f64()
        );
    }
}

fn verify_feeds(c: &Compiled) {
    let lengths: Vec<usize> = std::env::var("SORTER_BALLS")
        .ok()
        .map(|v| v.split(',').filter_map(|x| x.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![4, 8, 12]);
    println!("verify, every colour sequence of up to N balls:");
    for n in lengths {
        let model = Model::with_balls(c, n).expect("model");
        let runs = if n <= 8 { 3 } else { 1 };
        let (t, r) = best(runs, || explore(&model, ExploreOptions::default()));
        assert!(r.ok(), "{}", r.render("ball-sorter", 0));
        println!(
            "  N = {n:>2}: {:>8} states, {:>8} transitions, {:.3} s ({:.0} states/s)",
            r.states,
            r.transitions,
            t.as_secs_f64(),
            r.states as f64 / t.as_secs_f64()
        );
    }
}

fn main() {
    let text = std::fs::read_to_string(SORTER).expect("ball-sorter.ron");
    let c = station(&text);
    per_transition(&text, &c);
    events_and_throughput(&c);
    verify_feeds(&c);
}
