//! A ball feed of a sorting station (docs/simulation.md, "Ball feed"): a magazine of balls
//! in front of a pusher, sensors that read the front ball, a shaft with an entry sensor
//! and gates that take a ball out into their bin.
//!
//! - At t = 0 the front ball lies at the sensors: its levels are read at power-up (no
//!   edge). The pusher reaching its end pushes it off: the sensors drop at once, the
//!   entry sensor pulses `drop_ms` later ([`ENTRY_PULSE_MS`] long).
//! - The ball then meets gate 1 `fall_ms` after the entry sensor, each next gate (and
//!   last the bottom bin) `fall_ms` after the one before: a gate that is open (its rod at
//!   the end) when the ball meets it takes it into its bin (`i + 1`); a gate in motion
//!   there is traced ([`What::GateMoving`]) and does not take it. A ball no gate takes
//!   falls into bin `gates + 1`.
//! - A ball landing in bin `b` pulses the node's bin sensor `bins[b - 1]` (if the feed
//!   has bin sensors) for [`ENTRY_PULSE_MS`].
//! - The pusher back home lets the next ball roll to the sensors `roll_ms` later.

use super::{Ev, SimError, What, World};
use crate::cylinder::Position;

/// How long the entry sensor sees a ball go by.
pub const ENTRY_PULSE_MS: u64 = 10;

/// A ball feed attached to the sensing node's inputs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Feed {
    /// Node index of the sensing node.
    pub node: usize,
    /// Plant index of the pusher (an actuator).
    pub pusher: usize,
    /// Input indices of the sensors that read the front ball.
    pub sensors: Vec<u8>,
    /// Input index of the shaft's entry sensor.
    pub entry: u8,
    /// The balls, front first: each one's sensor levels (one per sensor).
    pub balls: Vec<Vec<bool>>,
    /// Plant indices of the gates, in shaft order (gate i empties into bin i + 1).
    pub gates: Vec<usize>,
    /// Input indices of the bins' sensors, one per bin (`gates + 1`), or none.
    pub bins: Vec<u8>,
    pub drop_ms: u64,
    pub fall_ms: u64,
    pub roll_ms: u64,
}

/// Where a fed ball is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct FeedState {
    /// The ball at the sensors.
    pub loaded: Option<usize>,
    /// The next ball in the magazine.
    pub next: usize,
}

impl World<'_> {
    /// Attaches a ball feed; returns its index. Its front ball lies at the sensors now.
    pub fn add_feed(&mut self, feed: Feed) -> Result<usize, SimError> {
        let plant = String::from("feed");
        let Some(node) = self.nodes.get(feed.node) else {
            return Err(SimError::NoSuchNode {
                plant,
                node: feed.node,
            });
        };
        let inputs = node.engine.table().inputs.len();
        for &input in feed.sensors.iter().chain([&feed.entry]).chain(&feed.bins) {
            if usize::from(input) >= inputs {
                return Err(SimError::NoSuchInput {
                    plant,
                    node: feed.node,
                    input,
                });
            }
        }
        for &p in feed.gates.iter().chain([&feed.pusher]) {
            if self.plants.get(p).and_then(super::Plant::travel).is_none() {
                return Err(SimError::NoSuchPlant {
                    plant: p,
                    want: "an actuator",
                });
            }
        }
        let loaded = (!feed.balls.is_empty()).then_some(0);
        if let Some(levels) = feed.balls.first() {
            let engine = &mut self.nodes[feed.node].engine;
            for (&input, &level) in feed.sensors.iter().zip(levels) {
                if level {
                    engine.sense(input, true);
                }
            }
        }
        self.feeds.push((
            feed,
            FeedState {
                loaded,
                next: usize::from(loaded.is_some()),
            },
        ));
        Ok(self.feeds.len() - 1)
    }

    /// The pusher of some feed arrived at its end (`end`) or home.
    pub(super) fn feed_arrived(&mut self, plant: usize, end: bool) {
        for f in 0..self.feeds.len() {
            let (feed, state) = &self.feeds[f];
            if feed.pusher != plant {
                continue;
            }
            let (node, drop, roll) = (feed.node, feed.drop_ms, feed.roll_ms);
            match (end, state.loaded) {
                (true, Some(ball)) => {
                    let high: Vec<u8> = (feed.sensors.iter().zip(&feed.balls[ball]))
                        .filter(|(_, l)| **l)
                        .map(|(i, _)| *i)
                        .collect();
                    self.feeds[f].1.loaded = None;
                    self.log(What::Fed { feed: f, ball });
                    for input in high {
                        let ev = Ev::Input {
                            node,
                            input,
                            level: false,
                        };
                        self.schedule(0, ev);
                    }
                    self.schedule(drop, Ev::BallEntry { feed: f, ball });
                }
                (false, None) if state.next < feed.balls.len() => {
                    let ball = state.next;
                    self.feeds[f].1.next += 1;
                    self.schedule(roll, Ev::BallRoll { feed: f, ball });
                }
                _ => {}
            }
        }
    }

    /// A feed's scheduled event.
    pub(super) fn feed_event(&mut self, ev: Ev) {
        match ev {
            Ev::BallRoll { feed, ball } => {
                let (f, _) = &self.feeds[feed];
                let (node, levels) = (f.node, f.sensors.iter().zip(&f.balls[ball]));
                let high: Vec<u8> = levels.filter(|(_, l)| **l).map(|(i, _)| *i).collect();
                self.feeds[feed].1.loaded = Some(ball);
                self.log(What::BallReady { feed, ball });
                for input in high {
                    self.set_input(node, input, true);
                }
            }
            Ev::BallEntry { feed, ball } => {
                let (f, _) = &self.feeds[feed];
                let (node, entry, fall) = (f.node, f.entry, f.fall_ms);
                self.set_input(node, entry, true);
                let low = Ev::Input {
                    node,
                    input: entry,
                    level: false,
                };
                self.schedule(ENTRY_PULSE_MS, low);
                self.schedule(
                    fall,
                    Ev::BallAt {
                        feed,
                        ball,
                        gate: 0,
                    },
                );
            }
            Ev::BallAt { feed, ball, gate } => {
                let (f, _) = &self.feeds[feed];
                let fall = f.fall_ms;
                let Some(&plant) = f.gates.get(gate) else {
                    self.land(feed, ball, gate + 1);
                    return;
                };
                match self.rods[plant].position() {
                    Position::End => self.land(feed, ball, gate + 1),
                    at => {
                        if matches!(at, Position::Extending | Position::Retracting) {
                            self.log(What::GateMoving { feed, ball, plant });
                        }
                        let gate = gate + 1;
                        self.schedule(fall, Ev::BallAt { feed, ball, gate });
                    }
                }
            }
            _ => {}
        }
    }

    /// Ball `ball` of feed `feed` lands in bin `bin` (1-based): traced, and its bin
    /// sensor pulses.
    fn land(&mut self, feed: usize, ball: usize, bin: usize) {
        self.log(What::Binned { feed, ball, bin });
        let (f, _) = &self.feeds[feed];
        let node = f.node;
        if let Some(&input) = bin.checked_sub(1).and_then(|i| f.bins.get(i)) {
            self.set_input(node, input, true);
            let low = Ev::Input {
                node,
                input,
                level: false,
            };
            self.schedule(ENTRY_PULSE_MS, low);
        }
    }
}
