//! A deterministic lossy radio for the protocol tests: loss, duplication, and reordering by
//! a random delay per frame.
#![allow(dead_code)]

use config_schema::{Action, Output, Table, Transition};
use test_tables::{blob as encoded, route};

/// A deterministic xorshift generator.
pub struct Rng(pub u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed | 1)
    }
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    pub fn chance(&mut self, p: f64) -> bool {
        (self.next() % 10_000) as f64 / 10_000.0 < p
    }
    pub fn range(&mut self, lo: u64, hi: u64) -> u64 {
        lo + self.next() % (hi - lo + 1)
    }
}

/// Frames in flight in one direction, each with its arrival time.
pub struct Channel<M> {
    pub loss: f64,
    pub dup: f64,
    pub delay: (u64, u64),
    flight: Vec<(u64, M)>,
    /// Frames handed to the channel.
    pub sent: usize,
}

impl<M: Clone> Channel<M> {
    pub fn new(loss: f64, dup: f64, delay: (u64, u64)) -> Self {
        Channel {
            loss,
            dup,
            delay,
            flight: Vec::new(),
            sent: 0,
        }
    }
    pub fn send(&mut self, rng: &mut Rng, now: u64, msg: M) {
        self.sent += 1;
        let copies = if rng.chance(self.dup) { 2 } else { 1 };
        for _ in 0..copies {
            if !rng.chance(self.loss) {
                let at = now + rng.range(self.delay.0, self.delay.1);
                self.flight.push((at, msg.clone()));
            }
        }
    }
    /// Frames arriving at or before `now`, in arrival order.
    pub fn due(&mut self, now: u64) -> Vec<M> {
        let (mut due, later): (Vec<_>, Vec<_>) =
            self.flight.drain(..).partition(|(t, _)| *t <= now);
        self.flight = later;
        due.sort_by_key(|(t, _)| *t);
        due.into_iter().map(|(_, m)| m).collect()
    }
}
/// A valid table of `generation`: one chart cycling through `states` states (its blob grows
/// with `states`), and its encoded blob.
fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

pub fn blob(generation: u32, states: usize) -> (Table, Vec<u8>) {
    let mut t = Table::empty("VC");
    t.generation = generation;
    let ev = t.push_event().unwrap();
    t.outputs.push(Output::safe(3, false)).unwrap();
    let drive = [Action::Drive { mask: 1, value: 1 }];
    let actions: Vec<&[Action]> = (0..states).map(|_| &drive[..]).collect();
    // A ring visited out of order and variables of large initial values, so that the
    // packed blob still spans several chunks: no field takes its short form.
    let step = (1..states)
        .find(|k| gcd(*k, states) == 1 && *k > 1)
        .unwrap_or(1);
    let transitions: Vec<Transition> = (0..states)
        .map(|s| Transition {
            from: (s * step % states) as u8,
            to: ((s + 1) * step % states) as u8,
            trigger: Some(0),
            guard: None,
        })
        .collect();
    t.push_chart(0, 1, &actions, &transitions).unwrap();
    for v in 0..states.min(config_schema::limits::MAX_VARS) {
        t.vars.push(i32::MIN + v as i32).unwrap();
    }
    route(&mut t, ev, 0, 0);
    let buf = encoded(&t);
    (t, buf)
}
