//! config-tool performance: compile time of the paint robot and of a generated
//! 8-actuator, 64-step sequence; simulated cycles per wall second of the paint robot; the
//! paint robot's blob sizes against one frame's chunk data (`CHUNK_DATA`, 88 bytes; target:
//! one frame each, docs/table-format.md "Size"); `check`
//! diagnostics on 5k vs 20k duplicate node addresses (printed ratio: linear scaling).

use std::hint::black_box;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use robot_analysis::sim;
use robot_compiler::{compile, Source};

fn paint_robot() -> Source {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../robot-configs/paint-robot.ron"
    );
    Source::new(
        "paint-robot.ron",
        std::fs::read_to_string(path).expect("paint-robot.ron"),
    )
}

/// Eight double-acting cylinders A..H, one node each; four rounds of
/// `A+ B+ .. H+ H- .. B- A-`: 64 steps.
fn eight_by_64() -> Source {
    let names = ["A", "B", "C", "D", "E", "F", "G", "H"];
    let mut nodes = String::new();
    let mut assign = String::new();
    let mut roles = String::new();
    for (i, n) in names.iter().enumerate() {
        nodes += &format!("(name: \"n{i}\", address: {}),", i + 1);
        assign += &format!("(\"{n}\", \"n{i}\"),");
        let start = if i == 0 {
            "inputs: [(name: \"START\", pin: 4)],"
        } else {
            ""
        };
        roles += &format!(
            "(name: \"{n}\", actuators: [(name: \"{n}\", kind: DoubleActing(extend: 0, retract: 1, home: 2, end: 3))], {start}),"
        );
    }
    let round: Vec<String> = names
        .iter()
        .map(|n| format!("{n}+"))
        .chain(names.iter().rev().map(|n| format!("{n}-")))
        .collect();
    let sequence = vec![round.join(" "); 4].join(" ");
    Source::new(
        "eight.ron",
        format!(
            "Robot(name: \"eight\", network: (pan_id: 1, channel: 11), nodes: [{nodes}], \
             assign: [{assign}], roles: [{roles}], start: \"START\", sequence: \"{sequence}\")"
        ),
    )
}

fn benches(c: &mut Criterion) {
    let paint = paint_robot();
    let eight = eight_by_64();
    let compiled = compile(&paint).expect("paint robot compiles");
    let eight_compiled = compile(&eight).expect("8 x 64 compiles");
    for (role, blob) in compiled.ir.roles.iter().zip(&compiled.blobs) {
        let chunk = config_schema::wire::msg::CHUNK_DATA;
        println!(
            "paint-robot blob {}: {} B of {chunk}: {}",
            role.name,
            blob.len(),
            robot_compiler::compile::frames_text(blob.len().div_ceil(chunk))
        );
    }
    let largest = eight_compiled.blobs.iter().map(Vec::len).max().unwrap_or(0);
    println!("8 x 64 largest blob: {largest} bytes");

    c.bench_function("compile paint-robot.ron", |b| {
        b.iter(|| compile(black_box(&paint)).expect("compiles"))
    });
    c.bench_function("compile 8 actuators x 64 steps", |b| {
        b.iter(|| compile(black_box(&eight)).expect("compiles"))
    });
    c.bench_function("sim paint-robot 10 cycles", |b| {
        b.iter(|| sim::simulate(black_box(&compiled), 10).expect("sim"))
    });

    // Throughput, measured once more outside criterion for a plain figure.
    let cycles = 2000;
    let t0 = Instant::now();
    let result = sim::simulate(&compiled, cycles).expect("sim");
    let secs = t0.elapsed().as_secs_f64();
    assert!(result.ok());
    println!(
        "sim paint-robot: {cycles} cycles in {secs:.3} s wall = {:.0} simulated cycles / s",
        cycles as f64 / secs
    );
}

/// A one-role robot whose `n` nodes all have address 0x0001: `n - 1` diagnostics.
fn duplicate_addresses(n: usize) -> Source {
    let nodes: String = (0..n)
        .map(|i| format!("(name: \"n{i}\", address: 0x0001),\n"))
        .collect();
    Source::new(
        "dups.ron",
        format!(
            "Robot(name: \"dups\", network: (pan_id: 0x0101, channel: 11), nodes: [\n{nodes}], \
             assign: [(\"A\", \"n0\")], roles: [(name: \"A\", actuators: [(name: \"A\", kind: \
             DoubleActing(extend: 0, retract: 1, home: 2, end: 3))], inputs: [(name: \"START\", \
             pin: 4)])], start: \"START\", sequence: \"A+ A-\")"
        ),
    )
}

/// `check` and its printed output (50 rendered, the rest counted) on 5k and 20k duplicate
/// node addresses: linear scaling gives a ratio of about 4 (quadratic: 16).
fn diagnostics(c: &mut Criterion) {
    let mut group = c.benchmark_group("diagnostics");
    group.sample_size(10);
    let mut secs = Vec::new();
    for n in [5_000, 20_000] {
        let src = duplicate_addresses(n);
        let run = |src: &Source| {
            let diags = robot_compiler::check::check(src).diagnostics;
            let out = robot_compiler::diag::render_all(src, &diags, false);
            (diags.len(), out.len())
        };
        assert_eq!(run(&src).0, n - 1);
        group.bench_function(format!("check + render {n} duplicate addresses"), |b| {
            b.iter(|| run(black_box(&src)))
        });
        let rounds = 5;
        let t0 = Instant::now();
        for _ in 0..rounds {
            black_box(run(&src));
        }
        secs.push(t0.elapsed().as_secs_f64() / f64::from(rounds));
    }
    group.finish();
    println!(
        "diagnostics: 5k duplicate addresses {:.1} ms, 20k {:.1} ms: ratio {:.2} for 4x the \
         input (linear: ~4, quadratic: ~16)",
        secs[0] * 1e3,
        secs[1] * 1e3,
        secs[1] / secs[0]
    );
}

criterion_group!(group, benches, diagnostics);
criterion_main!(group);
