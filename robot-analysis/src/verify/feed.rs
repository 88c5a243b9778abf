//! A sorting station's ball feed in the verifier's plant (docs/verification.md, "A sorting
//! station"): the magazine, the ball at the sensors, the ball falling down the shaft past
//! the gates into a bin, and the reference semantics the network's selections are checked
//! against, ball by ball.
//!
//! The feed is **every colour sequence of up to `balls` balls** the sensor table can
//! produce: the colour of each ball (or that the magazine is empty) is chosen when it comes
//! to the sensors, so one exploration covers every feed of that length, the robot's own
//! `feed` among them. Untimed, as verify treats timers and motions: the fall from the
//! pusher to the entry sensor, to each gate and to the bottom bin are moves that may come
//! at any time. One assumption: the next ball lies at the sensors when the pusher is back
//! home (it rolls in behind the retracting rod; the feeder's settle time covers its
//! `roll_ms`).

use std::collections::VecDeque;

use node_fw::cylinder::Position as Pos;
use robot_compiler::automata::{Automaton, Colour};
use robot_compiler::ir::ActionIr;
use robot_compiler::Compiled;

use super::place::Place;
use super::{Bad, ModelError, Property};
use crate::automata::Config;

/// The default bound of `verify`'s feed: every colour sequence of up to this many balls.
pub const DEFAULT_BALLS: usize = 4;

/// The largest bound (ball numbers are a byte).
pub const MAX_BALLS: usize = 200;

/// What lies in front of the pusher.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) enum Front {
    /// A ball of this colour (index into the sensor table).
    Ball(u8),
    /// The pusher took it; the next comes when it is back home.
    Gone,
    /// The magazine is empty (for good: the feed ended).
    Empty,
}

/// The feed's part of a state.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(super) struct Balls {
    /// Balls that came to the sensors so far.
    pub count: u8,
    pub front: Front,
    /// The ball in the shaft: (its number from 1, its colour, where it is: 0 dropping to
    /// the entry sensor, 1 + g heading for gate g, 1 + gates for the bottom bin).
    pub shaft: Option<(u8, u8, u8)>,
    /// The automata (bit per gate) whose network took the ball being decided, and those
    /// that ended a sequence with it.
    pub took: u8,
    pub eos: u8,
    /// The reference semantics of each automaton, in gate order, after the balls landed.
    pub refs: Vec<Config>,
}

/// Where an automaton's chart states mark a ball: (node, chart, state) -> (automaton in
/// gate order, emits its `Out`, emits its `EOS`).
type Mark = ((usize, u8, u8), (usize, bool, bool));

/// The station as the verifier drives it.
pub(super) struct FeedModel {
    node: usize,
    /// Actuator indices.
    pusher: usize,
    gates: Vec<usize>,
    sensors: Vec<u8>,
    entry: u8,
    bins: Vec<u8>,
    /// The sensor table: colour names and their levels.
    colours: Vec<(String, Vec<bool>)>,
    /// The automaton of each gate, in gate order.
    automata: Vec<Automaton>,
    marks: Vec<Mark>,
    /// Every colour sequence of up to this many balls.
    pub balls: usize,
}

impl FeedModel {
    /// The feed of `c`'s station (`None`: not a station), feeds of up to `balls` balls.
    pub(super) fn new(
        c: &Compiled,
        acts: &[super::Act],
        balls: usize,
    ) -> Result<Option<FeedModel>, ModelError> {
        let Some(s) = &c.robot.sorting else {
            return Ok(None);
        };
        let missing = |n: &str| ModelError::Station(format!("`{n}` is not in the compiled robot"));
        let node = (c.ir.roles.iter())
            .position(|r| r.name == s.role)
            .ok_or_else(|| missing(&s.role))?;
        let role = &c.ir.roles[node];
        let input = |n: &str| {
            (role.inputs.iter())
                .position(|i| i.name == n)
                .map(|i| i as u8)
                .ok_or_else(|| missing(n))
        };
        let act = |n: &str| {
            let n = n.split_once('/').map_or(n, |(_, a)| a);
            acts.iter()
                .position(|a| a.name == n)
                .ok_or_else(|| missing(n))
        };
        let mut automata = Vec::new();
        let mut marks = Vec::new();
        for (g, gate) in s.gates.iter().enumerate() {
            let role_name = gate.split_once('/').map_or(gate.as_str(), |(r, _)| r);
            let decl = (c.robot.automata.iter())
                .find(|a| a.role.as_deref() == Some(role_name))
                .ok_or_else(|| {
                    ModelError::Station(format!("gate `{gate}`: no automaton runs on its role"))
                })?;
            let a = (c.automata.iter())
                .find(|a| a.name == decl.name)
                .cloned()
                .ok_or_else(|| {
                    ModelError::Station(format!("automaton `{}` did not resolve", decl.name))
                })?;
            let gnode = (c.ir.roles.iter())
                .position(|r| r.name == role_name)
                .ok_or_else(|| missing(role_name))?;
            for (ci, ch) in c.ir.roles[gnode].charts.iter().enumerate() {
                if !ch.name.starts_with(&format!("{}.", a.name)) {
                    continue;
                }
                let (out, eos) = (format!("{}.Out", ch.name), format!("{}.EOS", a.name));
                for (si, st) in ch.states.iter().enumerate() {
                    let emits = |e: &str| {
                        (st.actions.iter()).any(|x| matches!(x, ActionIr::Emit(n) if n == e))
                    };
                    let (took, ended) = (emits(&out), emits(&eos));
                    if took || ended {
                        marks.push(((gnode, ci as u8, si as u8), (g, took, ended)));
                    }
                }
            }
            automata.push(a);
        }
        Ok(Some(FeedModel {
            node,
            pusher: act(&s.pusher)?,
            gates: (s.gates.iter()).map(|g| act(g)).collect::<Result<_, _>>()?,
            sensors: (s.sensors.iter())
                .map(|n| input(n))
                .collect::<Result<_, _>>()?,
            entry: input(&s.entry)?,
            bins: (s.bins.iter())
                .map(|n| input(n))
                .collect::<Result<_, _>>()?,
            colours: (s.table.iter())
                .map(|r| (r.colour.clone(), r.levels.clone()))
                .collect(),
            automata,
            marks,
            balls: balls.min(MAX_BALLS),
        }))
    }

    /// The sensing node.
    pub(super) fn node(&self) -> usize {
        self.node
    }

    /// What may come to the sensors after `count` balls: each colour while the bound
    /// allows, and the end of the feed.
    pub(super) fn choices(&self, count: u8) -> impl Iterator<Item = Front> + '_ {
        let more = usize::from(count) < self.balls;
        (0..self.colours.len())
            .filter(move |_| more)
            .map(|c| Front::Ball(c as u8))
            .chain([Front::Empty])
    }

    /// The feed state of a magazine whose front is `front`, before any ball.
    pub(super) fn start(&self, front: Front) -> Balls {
        Balls {
            count: u8::from(matches!(front, Front::Ball(_))),
            front,
            shaft: None,
            took: 0,
            eos: 0,
            refs: self.automata.iter().map(Config::initial).collect(),
        }
    }

    /// The inputs that rise when a ball of `front` lies at the sensors.
    pub(super) fn levels(&self, front: Front) -> Vec<u8> {
        match front {
            Front::Ball(c) => (self.sensors.iter())
                .zip(self.colours.get(usize::from(c)).map_or(&[][..], |r| &r.1))
                .filter(|(_, l)| **l)
                .map(|(i, _)| *i)
                .collect(),
            _ => Vec::new(),
        }
    }

    pub(super) fn colour_name(&self, c: u8) -> &str {
        self.colours
            .get(usize::from(c))
            .map_or("?", |r| r.0.as_str())
    }

    /// `ball feed: ...` (a counterexample's start).
    pub(super) fn label(&self, front: Front) -> String {
        match front {
            Front::Ball(c) => format!("ball feed: ball 1 is {}", self.colour_name(c)),
            _ => String::from("ball feed: the magazine is empty"),
        }
    }

    /// The feed in one line, for the report.
    pub(super) fn describe(&self) -> String {
        let names: Vec<&str> = self.colours.iter().map(|r| r.0.as_str()).collect();
        format!(
            "ball feed: every sequence of up to {} balls of {} (untimed: the next ball is \
             taken to lie at the sensors once the pusher is home; `sim` times its roll)",
            self.balls,
            names.join(", ")
        )
    }

    pub(super) fn is_pusher(&self, act: usize) -> bool {
        act == self.pusher
    }

    /// A chart of `node` entered `state`: the automaton it belongs to took the ball or
    /// ended a sequence.
    pub(super) fn fired(&self, node: usize, chart: u8, state: u8, b: &mut Balls) {
        for &(at, (g, took, eos)) in &self.marks {
            if at == (node, chart, state) {
                if took {
                    b.took |= 1 << g;
                }
                if eos {
                    b.eos |= 1 << g;
                }
            }
        }
    }

    /// The pusher reached its end: the ball at the sensors goes into the shaft (the
    /// sensors drop).
    pub(super) fn pushed(
        &self,
        b: &mut Balls,
        inputs: &mut VecDeque<(usize, u8, bool)>,
    ) -> Option<Bad> {
        let Front::Ball(c) = b.front else {
            return None;
        };
        if let Some((k, kc, _)) = b.shaft {
            return Some((
                Property::Bins,
                format!(
                    "ball {} ({}) was pushed into the shaft while ball {k} ({}) still falls",
                    b.count,
                    self.colour_name(c),
                    self.colour_name(kc)
                ),
            ));
        }
        for i in self.levels(b.front) {
            inputs.push_back((self.node, i, false));
        }
        b.front = Front::Gone;
        b.shaft = Some((b.count, c, 0));
        None
    }

    /// The pusher is back home: the next ball (`front`) lies at the sensors.
    pub(super) fn rolled(
        &self,
        b: &mut Balls,
        front: Front,
        inputs: &mut VecDeque<(usize, u8, bool)>,
    ) {
        if matches!(front, Front::Ball(_)) {
            b.count = b.count.saturating_add(1);
        }
        b.front = front;
        for i in self.levels(front) {
            inputs.push_back((self.node, i, true));
        }
    }

    /// The ball in the shaft falls on one step: to the entry sensor, to the next gate, or
    /// into a bin.
    pub(super) fn fall(
        &self,
        b: &mut Balls,
        pos: &[Place],
        inputs: &mut VecDeque<(usize, u8, bool)>,
    ) -> Option<Bad> {
        let (k, c, stage) = b.shaft?;
        if stage == 0 {
            inputs.push_back((self.node, self.entry, true));
            inputs.push_back((self.node, self.entry, false));
            b.shaft = Some((k, c, 1));
            return None;
        }
        let g = usize::from(stage - 1);
        match self.gates.get(g).map(|&a| pos[a]) {
            Some(Place::Rod(Pos::End)) => self.land(b, g + 1, inputs),
            Some(_) => {
                b.shaft = Some((k, c, stage + 1));
                None
            }
            None => self.land(b, g + 1, inputs),
        }
    }

    /// The ball lands in `bin` (1-based): its sensor pulses; the network's selection is
    /// checked against the reference semantics.
    fn land(
        &self,
        b: &mut Balls,
        bin: usize,
        inputs: &mut VecDeque<(usize, u8, bool)>,
    ) -> Option<Bad> {
        let (k, c, _) = b.shaft.take()?;
        if let Some(&i) = self.bins.get(bin - 1) {
            inputs.push_back((self.node, i, true));
            inputs.push_back((self.node, i, false));
        }
        let (mut took, mut eos) = (0u8, 0u8);
        let colour = self.colour_name(c);
        for (g, (a, cfg)) in self.automata.iter().zip(&mut b.refs).enumerate() {
            let Some(ac) = a.colours.iter().position(|n| n == colour) else {
                continue;
            };
            let step = cfg.step(a, Colour(ac as u8));
            if step.taken() {
                took |= 1 << g;
            }
            if step.is_eos() {
                eos |= 1 << g;
            }
        }
        let want_bin = (0..self.gates.len())
            .find(|g| took & (1 << g) != 0)
            .map_or(self.gates.len() + 1, |g| g + 1);
        let (got_took, got_eos) = (b.took, b.eos);
        b.took = 0;
        b.eos = 0;
        if (got_took, got_eos, bin) == (took, eos, want_bin) {
            return None;
        }
        Some((
            Property::Selection,
            format!(
                "ball {k} ({colour}) landed in bin {bin}, taken by {}, EOS {}; the reference \
                 semantics: bin {want_bin}, taken by {}, EOS {}",
                self.names(got_took),
                self.names(got_eos),
                self.names(took),
                self.names(eos)
            ),
        ))
    }

    fn names(&self, mask: u8) -> String {
        let n: Vec<&str> = (self.automata.iter().enumerate())
            .filter(|(g, _)| mask & (1 << g) != 0)
            .map(|(_, a)| a.name.as_str())
            .collect();
        if n.is_empty() {
            String::from("none")
        } else {
            n.join(", ")
        }
    }

    /// The station's properties in state `s` (`idle`: the machine is idle there).
    pub(super) fn check(
        &self,
        b: &Balls,
        pos: &[Place],
        names: &[&str],
        idle: bool,
    ) -> Option<Bad> {
        let moving = |a: usize| pos.get(a).is_some_and(|p| p.moving());
        if let Some((k, c, stage)) = b.shaft {
            let below = self.gates.iter().skip(usize::from(stage.saturating_sub(1)));
            if let Some(&g) = below.into_iter().find(|&&g| moving(g)) {
                return Some((
                    Property::GateFall,
                    format!(
                        "gate {} moves while ball {k} ({}) falls toward it",
                        names[g],
                        self.colour_name(c)
                    ),
                ));
            }
        }
        if pos.get(self.pusher) == Some(&Place::Rod(Pos::Extending)) {
            if let Some(&g) = self.gates.iter().find(|&&g| moving(g)) {
                return Some((
                    Property::PusherGate,
                    format!("the pusher feeds while gate {} moves", names[g]),
                ));
            }
        }
        if idle {
            if let Some((k, c, _)) = b.shaft {
                return Some((
                    Property::Bins,
                    format!(
                        "the station stopped with ball {k} ({}) in the shaft, in no bin",
                        self.colour_name(c)
                    ),
                ));
            }
            if let (Front::Ball(c), true) = (b.front, b.count > 1) {
                return Some((
                    Property::Bins,
                    format!(
                        "the station stopped with ball {} ({}) at the sensors, in no bin",
                        b.count,
                        self.colour_name(c)
                    ),
                ));
            }
        }
        None
    }

    /// What the next fall does, before it (`names`: the actuators').
    pub(super) fn describe_fall(&self, b: &Balls, pos: &[Place], names: &[&str]) -> String {
        let Some((k, c, stage)) = b.shaft else {
            return String::from("no ball falls");
        };
        let ball = format!("ball {k} ({})", self.colour_name(c));
        let g = usize::from(stage.saturating_sub(1));
        match (stage, self.gates.get(g)) {
            (0, _) => format!("{ball} passes the entry sensor"),
            (_, Some(&a)) if pos.get(a) == Some(&Place::Rod(Pos::End)) => {
                format!(
                    "{ball} meets gate {}, open: it lands in bin {}",
                    names[a],
                    g + 1
                )
            }
            (_, Some(&a)) => format!("{ball} falls past gate {}", names[a]),
            (_, None) => format!("{ball} lands in the bottom bin {}", g + 1),
        }
    }

    /// A readable summary of the feed's state.
    pub(super) fn describe_state(&self, b: &Balls) -> String {
        let front = match b.front {
            Front::Ball(c) => format!("ball {} ({}) at the sensors", b.count, self.colour_name(c)),
            Front::Gone => String::from("no ball at the sensors"),
            Front::Empty => String::from("magazine empty"),
        };
        let shaft = match b.shaft {
            None => String::from("shaft empty"),
            Some((k, c, 0)) => format!(
                "ball {k} ({}) dropping to the entry sensor",
                self.colour_name(c)
            ),
            Some((k, c, s)) if usize::from(s) <= self.gates.len() => {
                format!("ball {k} ({}) falling to gate {s}", self.colour_name(c))
            }
            Some((k, c, _)) => format!(
                "ball {k} ({}) falling to the bottom bin",
                self.colour_name(c)
            ),
        };
        format!("{front}, {shaft}")
    }
}
