//! Event dispatch through the paper robot's VC chart: the table interpreter against a
//! hand-written `match` implementation of the same chart, doing the same observable work
//! (the same output changes, publications and fired/ignored reports through the same
//! [`Effects`] sink), fed the same stimuli: one full cycle as VC's node sees it, 17 input
//! edges and remote events, four of which its chart ignores.
//!
//! `cargo bench -p robot-tests --bench dispatch` prints criterion's figures, then ns/event
//! of both and their ratio (median of several interleaved rounds), then the encoded blob
//! size of each of the four robot tables against the one-frame target.

use std::hint::black_box;
use std::time::{Duration, Instant};

use config_schema::limits::MAX_BLOB;
use config_schema::{encode, Publication, Table};
use criterion::{Criterion, Throughput};
use node_fw::ecc::Effects;
use robot_tests::paper_robot;
use robot_tests::vc_dispatch::{engine, run_hand, run_interpreter, HandVc, Sum, EVENTS_PER_CYCLE};

/// A sink that records every effect, to check both implementations do the same work.
#[derive(Default, Debug, PartialEq)]
struct Log(Vec<String>);

impl Effects for Log {
    fn output(&mut self, output: u8, value: bool) {
        self.0.push(format!("out {output}={value}"));
    }
    fn publish(&mut self, p: &Publication) {
        self.0.push(format!("pub {}", p.topic));
    }
    fn start_timer(&mut self, timer: u8, ms: u32) {
        self.0.push(format!("timer {timer} {ms}"));
    }
    fn fired(&mut self, chart: u8, transition: u8, from: u8, to: u8) {
        self.0
            .push(format!("fired {chart} t{transition} {from}->{to}"));
    }
    fn ignored(&mut self, chart: u8, input: u8) {
        self.0.push(format!("ignored {chart} {input}"));
    }
}

/// Both implementations must report exactly the same effects, cycle after cycle.
fn check_equivalent(table: &Table) {
    let (mut e, mut h) = (engine(table), HandVc::new(table));
    for _ in 0..3 {
        let (mut a, mut b) = (Log::default(), Log::default());
        run_interpreter(&mut e, &mut a);
        run_hand(&mut h, &mut b);
        assert_eq!(a, b, "the hand-written VC does not match the table");
        assert_eq!(a.0.iter().filter(|l| l.starts_with("fired")).count(), 7);
        assert_eq!(a.0.iter().filter(|l| l.starts_with("ignored")).count(), 4);
        assert_eq!(e.state(0), Some(0));
    }
}

fn criterion_groups(c: &mut Criterion, table: &Table) {
    let mut g = c.benchmark_group("vc_dispatch_cycle");
    g.throughput(Throughput::Elements(EVENTS_PER_CYCLE));
    g.bench_function("interpreter", |b| {
        let mut e = engine(table);
        let mut fx = Sum::default();
        b.iter(|| run_interpreter(&mut e, &mut fx));
        black_box(fx.0);
    });
    g.bench_function("hand_written", |b| {
        let mut h = HandVc::new(table);
        let mut fx = Sum::default();
        b.iter(|| run_hand(&mut h, &mut fx));
        black_box(fx.0);
    });
    g.finish();
}

/// ns per event of `cycles` cycles.
fn time(cycles: u64, mut run: impl FnMut()) -> f64 {
    let start = Instant::now();
    for _ in 0..cycles {
        run();
    }
    start.elapsed().as_nanos() as f64 / (cycles * EVENTS_PER_CYCLE) as f64
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn ratio_summary(table: &Table, rounds: usize, cycles: u64) {
    let (mut e, mut h) = (engine(table), HandVc::new(table));
    let (mut fa, mut fb) = (Sum::default(), Sum::default());
    let (mut interp, mut hand) = (Vec::new(), Vec::new());
    for _ in 0..rounds {
        interp.push(time(cycles, || run_interpreter(&mut e, &mut fa)));
        hand.push(time(cycles, || run_hand(&mut h, &mut fb)));
    }
    assert_eq!(fa.0, fb.0, "both did the same work");
    let (i, m) = (median(interp), median(hand));
    println!();
    println!(
        "VC chart dispatch, {EVENTS_PER_CYCLE} events per cycle, median of {rounds} rounds \
         x {cycles} cycles:"
    );
    println!("  table interpreter   {i:8.2} ns/event");
    println!("  hand-written match  {m:8.2} ns/event");
    println!(
        "  ratio               {:8.2}x  (target: within 1.5x) {}",
        i / m,
        if i / m <= 1.5 { "OK" } else { "OVER" }
    );
}

fn blob_sizes() {
    /// A 127-byte PSDU minus a data frame's MAC header (PAN id compression, short
    /// addresses: 9 bytes) and FCS (2 bytes).
    const FRAME_PAYLOAD: usize = 116;
    const TARGET: usize = 100;
    let tables = paper_robot::tables().expect("the robot fits the table limits");
    println!();
    println!("Encoded robot tables (envelope included), target ~{TARGET} bytes (one frame: {FRAME_PAYLOAD}):");
    for t in &tables {
        let mut buf = [0u8; MAX_BLOB];
        let len = encode(t, &mut buf).expect("encodes");
        println!(
            "  {:<3} {len:4} bytes  {}",
            t.header.role.as_str(),
            if len <= TARGET {
                "within target".to_string()
            } else if len <= FRAME_PAYLOAD {
                format!("{} over target, fits one frame", len - TARGET)
            } else {
                format!(
                    "{} over target, {} frames",
                    len - TARGET,
                    len.div_ceil(FRAME_PAYLOAD)
                )
            }
        );
    }
}

fn main() {
    let table = paper_robot::vc_table().expect("VC fits the table limits");
    check_equivalent(&table);
    // `cargo bench` passes --bench; `cargo test --benches` runs each benchmark once.
    let benching = std::env::args().any(|a| a == "--bench");
    let mut c = Criterion::default()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3))
        .configure_from_args();
    criterion_groups(&mut c, &table);
    c.final_summary();
    if benching {
        ratio_summary(&table, 9, 200_000);
    } else {
        ratio_summary(&table, 1, 10);
    }
    blob_sizes();
}
