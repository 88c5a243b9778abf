//! `verify` performance, printed figures: states explored per second, verify time of the
//! paint robot (lossless and lossy links), and of synthesised robots of 4, 6 and 8
//! double-acting cylinders, one node each, 2 steps each per cycle (`A+ B+ .. B- A-`), and
//! how the state count grows with the number of actuators; homing's proof (from every start
//! position) of the same robots. Best of 3 runs each; the bytes a state takes packed in the
//! visited set, and the peak memory of the largest run (8 actuators homing, once).

use std::time::{Duration, Instant};

use robot_analysis::verify::{self, ExploreOptions, HomingReport, Report};
use robot_compiler::{compile, Compiled, Source};

fn paint_robot() -> Compiled {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../robot-configs/paint-robot.ron"
    );
    let text = std::fs::read_to_string(path).expect("paint-robot.ron");
    compile(&Source::new("paint-robot.ron", text)).expect("compiles")
}

/// `n` cylinders, one node each, cycle `A+ B+ .. N+ N- .. B- A-`.
fn nested(n: usize) -> Compiled {
    let names: Vec<String> = (0..n).map(|i| format!("A{i}")).collect();
    let mut nodes = String::new();
    let mut assign = String::new();
    let mut roles = String::new();
    for (i, a) in names.iter().enumerate() {
        nodes += &format!("(name: \"n{i}\", address: {}),", i + 1);
        assign += &format!("(\"{a}\", \"n{i}\"),");
        let start = if i == 0 {
            "inputs: [(name: \"START\", pin: 4)],"
        } else {
            ""
        };
        roles += &format!(
            "(name: \"{a}\", actuators: [(name: \"{a}\", kind: DoubleActing(extend: 0, \
             retract: 1, home: 2, end: 3))], {start}),"
        );
    }
    let mut seq: Vec<String> = names.iter().map(|a| format!("{a}+")).collect();
    seq.extend(names.iter().rev().map(|a| format!("{a}-")));
    let text = format!(
        "Robot(name: \"nested-{n}\", network: (pan_id: 0x4242, channel: 20), nodes: [{nodes}], \
         assign: [{assign}], roles: [{roles}], start: \"START\", sequence: \"{}\")",
        seq.join(" ")
    );
    compile(&Source::new("nested", text)).expect("compiles")
}

fn best(c: &Compiled, lossy: bool) -> (Report, Duration) {
    let mut best: Option<(Report, Duration)> = None;
    for _ in 0..3 {
        let r = verify::verify(
            c,
            ExploreOptions {
                lossy,
                ..ExploreOptions::default()
            },
        )
        .expect("model");
        assert!(r.ok(), "{}", r.render("bench", 0));
        let t = r.elapsed;
        if best.as_ref().is_none_or(|b| t < b.1) {
            best = Some((r, t));
        }
    }
    best.expect("three runs")
}

fn best_homing(c: &Compiled, lossy: bool) -> (HomingReport, Duration) {
    let model = verify::Model::new(c).expect("model");
    let opts = ExploreOptions {
        lossy,
        ..ExploreOptions::default()
    };
    let mut best: Option<(HomingReport, Duration)> = None;
    for _ in 0..3 {
        let r = verify::explore_homing(&model, opts).expect("homes");
        assert!(r.ok(), "{}", r.render("bench", 0));
        let t = r.report.elapsed;
        if best.as_ref().is_none_or(|b| t < b.1) {
            best = Some((r, t));
        }
    }
    best.expect("three runs")
}

fn homing_line(name: &str, r: &HomingReport, t: Duration) {
    let starts = r.positions << r.held;
    line(&format!("{name} ({starts} starts)"), &r.report, t);
}

fn line(name: &str, r: &Report, t: Duration) {
    println!(
        "{name:<32} {:>9} states {:>10} transitions {:>10.3} ms {:>12.0} states/s {:>6.1} B/state",
        r.states,
        r.transitions,
        t.as_secs_f64() * 1e3,
        r.states as f64 / t.as_secs_f64(),
        r.packed_bytes as f64 / r.states as f64
    );
}

/// The process's peak resident memory so far (Linux: `VmHWM`), in MB.
fn peak_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let kb = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse::<f64>()
        .ok()?;
    Some(kb / 1024.0)
}

fn main() {
    // `cargo bench` passes `--bench`; any other argument is a filter we do not need.
    let t0 = Instant::now();
    let paint = paint_robot();
    let (r, t) = best(&paint, false);
    line("paint-robot", &r, t);
    let (r, t) = best(&paint, true);
    line("paint-robot --lossy", &r, t);
    let mut counts = Vec::new();
    for n in [2, 3, 4, 5, 6, 7, 8] {
        let c = nested(n);
        let (r, t) = best(&c, false);
        line(&format!("{n} actuators, {} steps", 2 * n), &r, t);
        counts.push((n, r.states));
    }
    for n in [4, 6, 8] {
        let c = nested(n);
        let (r, t) = best(&c, true);
        line(&format!("{n} actuators --lossy"), &r, t);
    }
    println!("homing, from every start position:");
    let (r, t) = best_homing(&paint, false);
    homing_line("paint-robot", &r, t);
    let (r, t) = best_homing(&paint, true);
    homing_line("paint-robot --lossy", &r, t);
    for n in [4, 6] {
        let (r, t) = best_homing(&nested(n), false);
        homing_line(&format!("{n} actuators"), &r, t);
    }
    // The largest run, once (6 561 starts, 1.1 M states): the process's peak memory before
    // and after it is what its visited set took.
    let before = peak_mb();
    let eight = nested(8);
    let model = verify::Model::new(&eight).expect("model");
    let r = verify::explore_homing(&model, ExploreOptions::default()).expect("homes");
    assert!(r.ok(), "{}", r.render("bench", 0));
    homing_line("8 actuators, once", &r, r.report.elapsed);
    if let (Some(before), Some(after)) = (before, peak_mb()) {
        println!(
            "  peak memory {before:.0} MB before it, {after:.0} MB after: {:.0} B a state \
             with its transitions and the search's bookkeeping",
            (after - before) * 1024.0 * 1024.0 / r.report.states as f64
        );
    }
    println!("state count growth (lossless):");
    for w in counts.windows(2) {
        println!(
            "  {} -> {} actuators: x{:.2}",
            w[0].0,
            w[1].0,
            w[1].1 as f64 / w[0].1 as f64
        );
    }
    println!("total bench time {:.1} s", t0.elapsed().as_secs_f64());
}
