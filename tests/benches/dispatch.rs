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
use config_schema::{encode, Publication, Table, Topic};
use criterion::{Criterion, Throughput};
use node_fw::ecc::{Effects, Engine};
use robot_tests::paper_robot::{self, topic, vc, EXT, RET};

/// One stimulus of VC's node.
#[derive(Debug, Clone, Copy)]
enum Stim {
    Input(u8, bool),
    Remote(u8, Topic),
}

use Stim::{Input, Remote};

/// One cycle of sequence (1) as VC's node sees it, starting at rest (home switch high).
const CYCLE: [Stim; 17] = [
    Input(vc::IN_START, true),       // START: S0 -> S1, VC+
    Input(vc::IN_START, false),      // button released: no event
    Input(vc::IN_HOME, false),       // leaves home: no event
    Input(vc::IN_END, true),         // VC1, published; ignored in S1
    Remote(vc::PEER_GR, topic::GR1), // S1 -> S2, VC-
    Input(vc::IN_END, false),        //
    Input(vc::IN_HOME, true),        // VC0, published; ignored in S2
    Remote(vc::PEER_HC, topic::HC1), // S2 -> S3, VC+
    Input(vc::IN_HOME, false),       //
    Input(vc::IN_END, true),         // VC1, published; S3 -> S4, VC-
    Input(vc::IN_END, false),        //
    Input(vc::IN_HOME, true),        // VC0, published; ignored in S4
    Remote(vc::PEER_HC, topic::HC0), // S4 -> S5, VC+
    Input(vc::IN_HOME, false),       //
    Input(vc::IN_END, true),         // VC1, published; ignored in S5
    Remote(vc::PEER_GR, topic::GR0), // S5 -> S6, VC-
    Input(vc::IN_END, false),        //
];

/// The last stimulus of the cycle (kept apart so the array above reads as pairs).
const LAST: Stim = Input(vc::IN_HOME, true); // VC0, published; S6 -> S0

fn cycle() -> impl Iterator<Item = Stim> {
    CYCLE.into_iter().chain([LAST])
}

const EVENTS_PER_CYCLE: u64 = CYCLE.len() as u64 + 1;

/// A sink that folds every effect into a checksum: cheap, and the work cannot be dropped.
#[derive(Default)]
struct Sum(u64);

impl Effects for Sum {
    #[inline]
    fn output(&mut self, output: u8, value: bool) {
        self.0 = self.0.wrapping_mul(31) ^ (u64::from(output) << 1 | u64::from(value));
    }
    #[inline]
    fn publish(&mut self, p: &Publication) {
        self.0 = self.0.wrapping_mul(31) ^ (0x100 | u64::from(p.topic));
    }
    #[inline]
    fn fired(&mut self, chart: u8, transition: u8, from: u8, to: u8) {
        self.0 =
            self.0.wrapping_mul(31) ^ u64::from_le_bytes([chart, transition, from, to, 1, 0, 0, 0]);
    }
    #[inline]
    fn ignored(&mut self, chart: u8, input: u8) {
        self.0 = self.0.wrapping_mul(31) ^ u64::from_le_bytes([chart, input, 2, 0, 0, 0, 0, 0]);
    }
}

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

/// The VC chart written by hand: the same events, states, outputs and publications as
/// `paper_robot::vc_table`, as a `match`.
struct HandVc {
    state: u8,
    inputs: u16,
    outputs: u16,
    pub_vc0: Publication,
    pub_vc1: Publication,
}

impl HandVc {
    fn new(table: &Table) -> HandVc {
        let publication = |e| *table.publication(e).expect("VC publishes VC0 and VC1");
        HandVc {
            state: 0,
            inputs: 1 << vc::IN_HOME,
            outputs: 0,
            pub_vc0: publication(vc::VC0),
            pub_vc1: publication(vc::VC1),
        }
    }

    #[inline]
    fn input(&mut self, input: u8, level: bool, fx: &mut impl Effects) {
        let bit = 1u16 << (input & 15);
        let was = self.inputs & bit != 0;
        if level {
            self.inputs |= bit;
        } else {
            self.inputs &= !bit;
        }
        if was == level || !level {
            return;
        }
        let event = match input {
            vc::IN_START => vc::START,
            vc::IN_HOME => {
                fx.publish(&self.pub_vc0);
                vc::VC0
            }
            vc::IN_END => {
                fx.publish(&self.pub_vc1);
                vc::VC1
            }
            _ => return,
        };
        self.dispatch(event, fx);
    }

    #[inline]
    fn remote(&mut self, peer: u8, topic: Topic, fx: &mut impl Effects) -> bool {
        let event = match (peer, topic) {
            (vc::PEER_GR, topic::GR1) => vc::GR1,
            (vc::PEER_GR, topic::GR0) => vc::GR0,
            (vc::PEER_HC, topic::HC1) => vc::HC1,
            (vc::PEER_HC, topic::HC0) => vc::HC0,
            _ => return false,
        };
        self.dispatch(event, fx);
        true
    }

    #[inline]
    fn dispatch(&mut self, event: u8, fx: &mut impl Effects) {
        // (transition index, next state, valve drive)
        let (transition, next, drive) = match (self.state, event) {
            (0, vc::START) => (0, 1, Some(EXT)),
            (1, vc::GR1) => (1, 2, Some(RET)),
            (2, vc::HC1) => (2, 3, Some(EXT)),
            (3, vc::VC1) => (3, 4, Some(RET)),
            (4, vc::HC0) => (4, 5, Some(EXT)),
            (5, vc::GR0) => (5, 6, Some(RET)),
            (6, vc::VC0) => (6, 0, None),
            _ => {
                fx.ignored(0, event);
                return;
            }
        };
        let from = self.state;
        self.state = next;
        fx.fired(0, transition, from, next);
        if let Some(value) = drive {
            let next = (self.outputs & !(EXT | RET)) | value;
            let changed = self.outputs ^ next;
            self.outputs = next;
            for i in 0..2u8 {
                if changed & (1 << i) != 0 {
                    fx.output(i, next & (1 << i) != 0);
                }
            }
        }
    }
}

/// VC's engine at rest: the home switch read at power-up, then reset (as the simulator
/// does), so no edge is raised.
fn engine(table: &Table) -> Engine<'_> {
    let mut e = Engine::new(table);
    e.input(vc::IN_HOME, true, &mut ());
    e.reset(&mut ());
    e
}

#[inline]
fn run_interpreter(e: &mut Engine<'_>, fx: &mut impl Effects) {
    for s in cycle() {
        match black_box(s) {
            Input(i, level) => e.input(i, level, fx),
            Remote(p, t) => {
                e.remote(p, t, fx);
            }
        }
    }
}

#[inline]
fn run_hand(h: &mut HandVc, fx: &mut impl Effects) {
    for s in cycle() {
        match black_box(s) {
            Input(i, level) => h.input(i, level, fx),
            Remote(p, t) => {
                h.remote(p, t, fx);
            }
        }
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
        "  ratio               {:8.2}x  (target: within 3x) {}",
        i / m,
        if i / m <= 3.0 { "OK" } else { "OVER" }
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
