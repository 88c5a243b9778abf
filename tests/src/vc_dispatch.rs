//! The paper robot's VC chart as its node sees one cycle, for the dispatch benchmarks
//! (`benches/dispatch.rs`: wall time; `examples/instructions.rs`: instructions counted by
//! callgrind): the stimuli of one cycle, the table interpreter fed them, and the same
//! chart written by hand as a `match`, doing the same observable work (the same output
//! changes, publications and fired/ignored reports through the same [`Effects`] sink).

use std::hint::black_box;

use config_schema::{Publication, Table, Topic};
use node_fw::ecc::{Effects, Engine};

use crate::paper_robot::{topic, vc, EXT, RET};

/// One stimulus of VC's node.
#[derive(Debug, Clone, Copy)]
pub enum Stim {
    Input(u8, bool),
    Remote(u8, Topic),
}

use Stim::{Input, Remote};

/// One cycle of sequence (1) as VC's node sees it, starting at rest (home switch high).
pub const CYCLE: [Stim; 17] = [
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
pub const LAST: Stim = Input(vc::IN_HOME, true); // VC0, published; S6 -> S0

pub fn cycle() -> impl Iterator<Item = Stim> {
    CYCLE.into_iter().chain([LAST])
}

pub const EVENTS_PER_CYCLE: u64 = CYCLE.len() as u64 + 1;

/// A sink that folds every effect into a checksum: cheap, and the work cannot be dropped.
#[derive(Default)]
pub struct Sum(pub u64);

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

/// The VC chart written by hand: the same events, states, outputs and publications as
/// `paper_robot::vc_table`, as a `match`.
pub struct HandVc {
    state: u8,
    inputs: u16,
    outputs: u16,
    pub_vc0: Publication,
    pub_vc1: Publication,
}

impl HandVc {
    pub fn new(table: &Table) -> HandVc {
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
    pub fn input(&mut self, input: u8, level: bool, fx: &mut impl Effects) {
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
    pub fn remote(&mut self, peer: u8, topic: Topic, fx: &mut impl Effects) -> bool {
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
pub fn engine(table: &Table) -> Engine<'_> {
    let mut e = Engine::new(table);
    e.input(vc::IN_HOME, true, &mut ());
    e.reset(&mut ());
    e
}

#[inline]
pub fn run_interpreter(e: &mut Engine<'_>, fx: &mut impl Effects) {
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
pub fn run_hand(h: &mut HandVc, fx: &mut impl Effects) {
    for s in cycle() {
        match black_box(s) {
            Input(i, level) => h.input(i, level, fx),
            Remote(p, t) => {
                h.remote(p, t, fx);
            }
        }
    }
}
