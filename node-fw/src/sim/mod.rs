//! A deterministic, virtual-time world for the host: one [`Engine`] per node, plant models
//! on their pins, an ideal radio between them, and a trace of everything. Used by the tests,
//! `config-tool sim` and the verifier. Only built with the `std` feature.
//! See `docs/simulation.md`.
//!
//! ```text
//! let nodes = [NodeSpec { addr: 0x11, table: &vc }, NodeSpec { addr: 0x12, table: &gr }];
//! let mut world = World::new(&nodes, plants)?;
//! world.press(start_button)?;
//! world.run_until_idle(60_000)?;
//! assert_eq!(world.steps(), ["VC+", "GR+", ...]);
//! ```
//!
//! Everything happens through one event queue ordered by (virtual time, insertion order):
//! the same tables, plants and calls give the same trace, always. Every run is bounded by a
//! virtual-time limit and by a number of processed events ([`RUN_EVENT_LIMIT`]).

mod feed;
mod lossy;
mod motor;
mod plant;
mod trace;

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::fmt;

use config_schema::limits::MAX_TIMERS;
use config_schema::{Publication, Table, Topic};

use crate::cylinder::{self, Command, Cylinder};
use crate::ecc::{Effects, Engine, Fault};

pub use crate::cylinder::{Outcome as RodOutcome, Position, Rod};
pub use feed::{Feed, ENTRY_PULSE_MS};
pub use motor::{Carriage, Driven, Motor, Run, Switch};
pub use plant::{Button, DoubleActing, Plant, SingleActing};
pub use trace::{cycles, steps, Cycle, TraceEntry, What};

/// Default radio latency, publication to delivery.
pub const DEFAULT_RADIO_DELAY_MS: u64 = 2;
/// Default number of queue events one `run_*` call processes before it gives up with
/// [`SimError::Runaway`] (a zero-delay loop between nodes would otherwise never end).
/// See [`World::set_run_event_limit`].
pub const RUN_EVENT_LIMIT: usize = 1_000_000;

/// A node of the world: its 16-bit short address and the (validated) table it runs.
#[derive(Debug, Clone, Copy)]
pub struct NodeSpec<'t> {
    pub addr: u16,
    pub table: &'t Table,
}

/// Why a world could not be built or a run did not finish.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SimError {
    /// Two nodes have one address.
    DuplicateAddress { addr: u16 },
    /// A plant names a node the world does not have.
    NoSuchNode { plant: String, node: usize },
    /// A plant names an output the node's table does not have.
    NoSuchOutput {
        plant: String,
        node: usize,
        output: u8,
    },
    /// A plant names an input the node's table does not have.
    NoSuchInput {
        plant: String,
        node: usize,
        input: u8,
    },
    /// Two plants (or one plant twice) on one pin.
    PinShared {
        plant: String,
        node: usize,
        pin: u8,
        output: bool,
    },
    /// A plant index that does not exist or is not of the right kind.
    NoSuchPlant { plant: usize, want: &'static str },
    /// A node index that does not exist.
    NoSuchNodeIndex { node: usize },
    /// The run reached its virtual-time limit (`limit_ms`, a time of the clock) with events
    /// still pending: the last it processed at `now_ms`, the next due at `next_ms`.
    NotIdle {
        limit_ms: u64,
        now_ms: u64,
        next_ms: u64,
    },
    /// The run processed its event limit ([`RUN_EVENT_LIMIT`] by default) without
    /// becoming idle.
    Runaway { now_ms: u64, events: usize },
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::DuplicateAddress { addr } => {
                write!(f, "two nodes have the address {addr:#06x}")
            }
            SimError::NoSuchNode { plant, node } => {
                write!(f, "plant {plant}: there is no node #{node}")
            }
            SimError::NoSuchOutput {
                plant,
                node,
                output,
            } => write!(f, "plant {plant}: node #{node} has no output #{output}"),
            SimError::NoSuchInput { plant, node, input } => {
                write!(f, "plant {plant}: node #{node} has no input #{input}")
            }
            SimError::PinShared {
                plant,
                node,
                pin,
                output,
            } => write!(
                f,
                "plant {plant}: {} #{pin} of node #{node} is already wired to a plant",
                if *output { "output" } else { "input" }
            ),
            SimError::NoSuchPlant { plant, want } => write!(f, "plant #{plant} is not {want}"),
            SimError::NoSuchNodeIndex { node } => write!(f, "there is no node #{node}"),
            SimError::NotIdle {
                limit_ms,
                now_ms,
                next_ms,
            } => write!(
                f,
                "not idle by the time limit ({limit_ms} ms): the last event at {now_ms} ms, \
                 the next one due at {next_ms} ms"
            ),
            SimError::Runaway { now_ms, events } => write!(
                f,
                "{events} events processed without becoming idle (at {now_ms} ms)"
            ),
        }
    }
}

impl std::error::Error for SimError {}

/// Something scheduled on the queue.
#[derive(Debug, Clone, Copy)]
enum Ev {
    Input {
        node: usize,
        input: u8,
        level: bool,
    },
    Start {
        node: usize,
    },
    Home {
        node: usize,
    },
    Arrive {
        plant: usize,
        gen: u64,
    },
    Timer {
        node: usize,
        timer: u8,
        gen: u64,
    },
    Deliver {
        from: usize,
        to: usize,
        topic: Topic,
    },
    LinkAlarm {
        node: usize,
        peer: usize,
    },
    /// Lossy radio: a frame of link `from -> to` reaches its end.
    Frame {
        from: usize,
        to: usize,
        frame: lossy::Frame,
    },
    /// Lossy radio: the retransmission timer of link `from -> to`.
    LinkPoll {
        from: usize,
        to: usize,
        gen: u64,
    },
    /// A feed's next ball reaches the sensors.
    BallRoll {
        feed: usize,
        ball: usize,
    },
    /// A fed ball passes the shaft's entry sensor.
    BallEntry {
        feed: usize,
        ball: usize,
    },
    /// A falling ball meets gate `gate` (past the last: the bottom bin).
    BallAt {
        feed: usize,
        ball: usize,
        gate: usize,
    },
}

#[derive(Debug, Clone, Copy)]
struct Queued {
    t: u64,
    seq: u64,
    ev: Ev,
}

impl PartialEq for Queued {
    fn eq(&self, other: &Self) -> bool {
        (self.t, self.seq) == (other.t, other.seq)
    }
}
impl Eq for Queued {}
impl PartialOrd for Queued {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Queued {
    /// Reversed: `BinaryHeap` is a max-heap, the earliest (time, seq) must come out first.
    fn cmp(&self, other: &Self) -> Ordering {
        (other.t, other.seq).cmp(&(self.t, self.seq))
    }
}

struct Node<'t> {
    addr: u16,
    engine: Engine<'t>,
    /// Its latched alarms (as a node keeps them: [`crate::alarms`]).
    alarms: crate::alarms::Alarms,
    /// Generation of each armed timer (0 = not armed).
    timers: [u64; MAX_TIMERS],
}

/// An effect reported by an engine, applied to the world after the engine call returns.
#[derive(Debug, Clone, Copy)]
enum Effect {
    Output(u8, bool),
    Publish(Publication),
    StartTimer(u8, u32),
    CancelTimer(u8),
}

/// The [`Effects`] sink of one engine call: traces at once, applies afterwards.
struct WorldEffects<'a> {
    node: usize,
    now: u64,
    trace: &'a mut Vec<TraceEntry>,
    todo: &'a mut Vec<Effect>,
}

impl WorldEffects<'_> {
    fn log(&mut self, what: What) {
        self.trace.push(TraceEntry {
            t_ms: self.now,
            what,
        });
    }
}

impl Effects for WorldEffects<'_> {
    fn output(&mut self, output: u8, value: bool) {
        let node = self.node;
        self.log(What::Output {
            node,
            output,
            level: value,
        });
        self.todo.push(Effect::Output(output, value));
    }
    fn publish(&mut self, p: &Publication) {
        let node = self.node;
        self.log(What::Publish {
            node,
            event: p.event,
            topic: p.topic,
            subscribers: p.subscribers,
        });
        self.todo.push(Effect::Publish(*p));
    }
    fn start_timer(&mut self, timer: u8, ms: u32) {
        self.todo.push(Effect::StartTimer(timer, ms));
    }
    fn cancel_timer(&mut self, timer: u8) {
        self.todo.push(Effect::CancelTimer(timer));
    }
    fn fault(&mut self, fault: Fault) {
        let node = self.node;
        self.log(What::Fault { node, fault });
    }
    fn fired(&mut self, chart: u8, transition: u8, from: u8, to: u8) {
        let node = self.node;
        self.log(What::Fired {
            node,
            chart,
            transition,
            from,
            to,
        });
    }
    fn ignored(&mut self, chart: u8, input: u8) {
        let node = self.node;
        self.log(What::Ignored { node, chart, input });
    }
}

/// The simulated machine: nodes, plants, radio, virtual clock and trace.
pub struct World<'t> {
    now: u64,
    seq: u64,
    queue: BinaryHeap<Queued>,
    nodes: Vec<Node<'t>>,
    plants: Vec<Plant>,
    /// Rod of each plant (buttons keep `Home`).
    rods: Vec<Rod>,
    /// Carriage of each plant (only a motor's moves).
    carriages: Vec<Carriage>,
    /// Motion generation of each plant: a stale arrival is dropped.
    gens: Vec<u64>,
    timer_gen: u64,
    radio_delay_ms: u64,
    event_limit: usize,
    trace: Vec<TraceEntry>,
    scratch: Vec<Effect>,
    /// Injected faults: jammed plants, broken switches (node, input), stopped nodes, cut
    /// links (from, to), and links already in alarm.
    jammed: Vec<bool>,
    broken: Vec<(usize, u8)>,
    stopped: Vec<bool>,
    cut: Vec<(usize, usize)>,
    alarmed: Vec<(usize, usize)>,
    /// The lossy radio, once [`World::set_loss`] chose it.
    lossy: Option<lossy::Lossy>,
    /// Ball feeds ([`World::add_feed`]) and where their balls are.
    feeds: Vec<(Feed, feed::FeedState)>,
}

/// Time from a publication to the link alarm when the subscriber never acknowledges: the
/// reliable link's [`ALARM_AFTER`](crate::link::ALARM_AFTER) retransmission timeouts with
/// exponential backoff (30 + 60 + 6 x 120 = 810 ms).
pub fn link_alarm_ms() -> u64 {
    use crate::link::{ALARM_AFTER, RTO_MAX_MS, RTO_MS};
    (0..u32::from(ALARM_AFTER))
        .map(|i| (RTO_MS << i.min(8)).min(RTO_MAX_MS))
        .sum()
}

impl<'t> World<'t> {
    /// A world at t = 0: one engine per node in its initial state, every actuator at home
    /// with its home switch high (set at power-up, before the charts start: no edge, no
    /// event), a single-acting actuator out if its output starts high, buttons released.
    pub fn new(nodes: &[NodeSpec<'t>], plants: Vec<Plant>) -> Result<World<'t>, SimError> {
        for (i, n) in nodes.iter().enumerate() {
            if nodes[..i].iter().any(|m| m.addr == n.addr) {
                return Err(SimError::DuplicateAddress { addr: n.addr });
            }
        }
        let mut used: Vec<(usize, u8, bool)> = Vec::new();
        for p in &plants {
            let node = p.node();
            let plant = p.name().to_string();
            let Some(spec) = nodes.get(node) else {
                return Err(SimError::NoSuchNode { plant, node });
            };
            for output in p.outputs() {
                if usize::from(output) >= spec.table.outputs.len() {
                    return Err(SimError::NoSuchOutput {
                        plant,
                        node,
                        output,
                    });
                }
                if used.contains(&(node, output, true)) {
                    return Err(SimError::PinShared {
                        plant,
                        node,
                        pin: output,
                        output: true,
                    });
                }
                used.push((node, output, true));
            }
            for input in p.inputs() {
                if usize::from(input) >= spec.table.inputs.len() {
                    return Err(SimError::NoSuchInput { plant, node, input });
                }
                if used.contains(&(node, input, false)) {
                    return Err(SimError::PinShared {
                        plant,
                        node,
                        pin: input,
                        output: false,
                    });
                }
                used.push((node, input, false));
            }
        }
        for p in &plants {
            if let Plant::Driven(d) = p {
                if !matches!(plants.get(d.motor), Some(Plant::Motor(_))) {
                    return Err(SimError::NoSuchPlant {
                        plant: d.motor,
                        want: "a motor",
                    });
                }
            }
        }
        let plants_len = plants.len();
        let mut world = World {
            now: 0,
            seq: 0,
            queue: BinaryHeap::new(),
            nodes: nodes
                .iter()
                .map(|n| Node {
                    addr: n.addr,
                    // The machine starts homed: every chart at its idle point.
                    engine: {
                        let mut e = Engine::new(n.table);
                        e.rest();
                        e
                    },
                    timers: [0; MAX_TIMERS],
                    alarms: crate::alarms::Alarms::default(),
                })
                .collect(),
            rods: vec![Rod::Home; plants.len()],
            carriages: vec![Carriage::default(); plants.len()],
            gens: vec![0; plants.len()],
            plants,
            timer_gen: 0,
            radio_delay_ms: DEFAULT_RADIO_DELAY_MS,
            event_limit: RUN_EVENT_LIMIT,
            trace: Vec::new(),
            scratch: Vec::new(),
            jammed: vec![false; plants_len],
            broken: Vec::new(),
            stopped: vec![false; nodes.len()],
            cut: Vec::new(),
            alarmed: Vec::new(),
            lossy: None,
            feeds: Vec::new(),
        };
        // Power-up: each rod rests where its node's safe outputs hold it, and the node reads
        // the sensors closed there as levels before its charts start.
        for (p, plant) in world.plants.iter().enumerate() {
            if let Some(cylinder) = plant.cylinder() {
                let engine = &mut world.nodes[plant.node()].engine;
                let (at, closed) = cylinder.power_up(engine.outputs());
                if at == Position::End {
                    world.rods[p] = Rod::End;
                }
                if let Some(sensor) = closed {
                    engine.sense(sensor, true);
                }
            }
            // A motor and what it moves start at home, their home sensors closed.
            let home = match plant {
                Plant::Motor(m) => m.home_in,
                Plant::Driven(d) => d.home_in,
                _ => None,
            };
            if let Some(sensor) = home {
                world.nodes[plant.node()].engine.sense(sensor, true);
            }
        }
        Ok(world)
    }

    /// Sets the radio latency (publication to delivery) for later publications.
    pub fn set_radio_delay(&mut self, ms: u64) {
        self.radio_delay_ms = ms;
    }

    /// Makes the radio lossy: from now on every publication travels over the node's
    /// reliable link ([`crate::link`]: window, queue, retransmissions, alarm, broken on
    /// overflow), and each frame (event or acknowledgement) is lost with probability
    /// `loss`, drawn from a generator seeded with `seed`. Each surviving frame takes the
    /// radio delay. Call it before anything is published (every link starts a new epoch).
    pub fn set_loss(&mut self, loss: f64, seed: u64) {
        self.lossy = Some(lossy::Lossy::new(self.nodes.len(), loss, seed));
    }

    /// Frames the lossy radio carried and lost so far ((0, 0) on the ideal radio).
    pub fn frames(&self) -> (u64, u64) {
        self.lossy.as_ref().map_or((0, 0), |l| (l.sent, l.lost))
    }

    /// Sets how many queue events one `run_*` call may process ([`RUN_EVENT_LIMIT`] by
    /// default).
    pub fn set_run_event_limit(&mut self, events: usize) {
        self.event_limit = events;
    }

    /// Virtual time now, in milliseconds.
    pub fn now(&self) -> u64 {
        self.now
    }

    /// The number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The engine of node `node` (panics if there is no such node).
    pub fn engine(&self, node: usize) -> &Engine<'t> {
        &self.nodes[node].engine
    }

    /// The address of node `node` (panics if there is no such node).
    pub fn addr(&self, node: usize) -> u16 {
        self.nodes[node].addr
    }

    /// The node with address `addr`.
    pub fn node_by_addr(&self, addr: u16) -> Option<usize> {
        self.nodes.iter().position(|n| n.addr == addr)
    }

    /// Current chart-local state of every chart of node `node`.
    pub fn states(&self, node: usize) -> Vec<u8> {
        let engine = &self.nodes[node].engine;
        (0..engine.table().charts.len())
            .filter_map(|c| engine.state(c))
            .collect()
    }

    /// The plants, in the order given to [`World::new`].
    pub fn plants(&self) -> &[Plant] {
        &self.plants
    }

    /// The index of the plant named `name`.
    pub fn plant_by_name(&self, name: &str) -> Option<usize> {
        self.plants.iter().position(|p| p.name() == name)
    }

    /// Where an actuator's rod is (`None` for a button or no such plant).
    pub fn position(&self, plant: usize) -> Option<Position> {
        self.plants.get(plant)?.travel()?;
        Some(self.rods[plant].position())
    }

    /// Where a motor's carriage (or what it moves) is now, µm from home (`None` for
    /// another plant).
    pub fn carriage_um(&self, plant: usize) -> Option<u64> {
        let motor = match self.plants.get(plant)? {
            Plant::Motor(_) => plant,
            Plant::Driven(d) => d.motor,
            _ => return None,
        };
        let Some(Plant::Motor(m)) = self.plants.get(motor) else {
            return None;
        };
        Some(m.position_um(&self.carriages[motor], self.now))
    }

    /// How a motor runs now (`None` for another plant).
    pub fn run(&self, plant: usize) -> Option<Run> {
        match self.plants.get(plant)? {
            Plant::Motor(_) => Some(self.carriages[plant].run),
            _ => None,
        }
    }

    /// Sets a maintained contact ([`Switch`]) to `level` now; setting the level it has
    /// does nothing. Takes effect when the world runs.
    pub fn set_switch(&mut self, plant: usize, level: bool) -> Result<(), SimError> {
        let Some(Plant::Switch(s)) = self.plants.get(plant) else {
            return Err(SimError::NoSuchPlant {
                plant,
                want: "a switch",
            });
        };
        let (node, input) = (s.node, s.input);
        self.log(What::Switched { plant, level });
        self.schedule(0, Ev::Input { node, input, level });
        Ok(())
    }

    /// Everything that happened so far.
    pub fn trace(&self) -> &[TraceEntry] {
        &self.trace
    }

    /// Takes the trace, leaving it empty (long runs: keep memory flat).
    pub fn take_trace(&mut self) -> Vec<TraceEntry> {
        std::mem::take(&mut self.trace)
    }

    /// The step strings of the whole trace.
    pub fn steps(&self) -> Vec<String> {
        steps(&self.trace)
    }

    /// The trace split into cycles at each press / START.
    pub fn cycles(&self) -> Vec<Cycle> {
        cycles(&self.trace)
    }

    /// Whether nothing is scheduled (no motion, timer, delivery or button release pending).
    pub fn is_idle(&mut self) -> bool {
        self.peek().is_none()
    }

    /// Presses button `button` (plant index) now: its input goes high at once and low
    /// `press_ms` later. Takes effect when the world runs.
    pub fn press(&mut self, button: usize) -> Result<(), SimError> {
        let Some(Plant::Button(b)) = self.plants.get(button) else {
            return Err(SimError::NoSuchPlant {
                plant: button,
                want: "a button",
            });
        };
        let (node, input, press_ms) = (b.node, b.input, b.press_ms);
        self.log(What::Press { button });
        self.schedule(
            0,
            Ev::Input {
                node,
                input,
                level: true,
            },
        );
        self.schedule(
            press_ms,
            Ev::Input {
                node,
                input,
                level: false,
            },
        );
        Ok(())
    }

    /// Sends the START command to node `node` now (raises its table's start event).
    pub fn start(&mut self, node: usize) -> Result<(), SimError> {
        if node >= self.nodes.len() {
            return Err(SimError::NoSuchNodeIndex { node });
        }
        self.log(What::Start { node });
        self.schedule(0, Ev::Start { node });
        Ok(())
    }

    /// Sends the HOME command to node `node` now (raises its table's home event).
    pub fn home(&mut self, node: usize) -> Result<(), SimError> {
        if node >= self.nodes.len() {
            return Err(SimError::NoSuchNodeIndex { node });
        }
        self.log(What::Home { node });
        self.schedule(0, Ev::Home { node });
        Ok(())
    }

    /// Commands actuator `plant`'s valve directly, bypassing its node (a GO_1 / GO_0 of
    /// `Bistabilni_C`): `plus` extends. Applied at once.
    pub fn go(&mut self, plant: usize, plus: bool) -> Result<(), SimError> {
        if self.plants.get(plant).and_then(Plant::travel).is_none() {
            return Err(SimError::NoSuchPlant {
                plant,
                want: "an actuator",
            });
        }
        self.log(What::Go { plant, plus });
        self.command(plant, plus);
        Ok(())
    }

    /// A frame from node `from` carrying `topic` reaches node `to` now, whoever published
    /// it: a stray, duplicated or forged frame. It goes through the same subscription check
    /// as a real delivery (traced as [`What::Deliver`]).
    pub fn inject(&mut self, from: usize, to: usize, topic: Topic) -> Result<(), SimError> {
        for node in [from, to] {
            if node >= self.nodes.len() {
                return Err(SimError::NoSuchNodeIndex { node });
            }
        }
        self.schedule(0, Ev::Deliver { from, to, topic });
        Ok(())
    }

    /// Injects a jammed actuator: from now on valve commands to plant `plant` move nothing
    /// (a motion under way still completes).
    pub fn jam(&mut self, plant: usize) -> Result<(), SimError> {
        if self.plants.get(plant).and_then(Plant::travel).is_none() {
            return Err(SimError::NoSuchPlant {
                plant,
                want: "an actuator",
            });
        }
        self.jammed[plant] = true;
        let fault = format!("{} jammed", self.plants[plant].name());
        self.log(What::Injected { fault });
        Ok(())
    }

    /// Injects a broken switch: input `input` of node `node` stays low from now on.
    pub fn break_switch(&mut self, node: usize, input: u8) -> Result<(), SimError> {
        if node >= self.nodes.len() {
            return Err(SimError::NoSuchNodeIndex { node });
        }
        self.broken.push((node, input));
        self.log(What::Injected {
            fault: format!("node {node} input {input} broken (stays low)"),
        });
        Ok(())
    }

    /// Injects a stopped node: it handles nothing more (its outputs keep their levels, its
    /// timers never fire) and acknowledges nothing, so its publishers' links go into alarm.
    pub fn stop_node(&mut self, node: usize) -> Result<(), SimError> {
        if node >= self.nodes.len() {
            return Err(SimError::NoSuchNodeIndex { node });
        }
        self.stopped[node] = true;
        self.log(What::Injected {
            fault: format!("node {node} stopped"),
        });
        Ok(())
    }

    /// Injects a lost link: nothing published by `from` reaches `to` any more; `from`'s link
    /// goes into alarm [`link_alarm_ms`] after the first undelivered publication.
    pub fn cut_link(&mut self, from: usize, to: usize) -> Result<(), SimError> {
        for node in [from, to] {
            if node >= self.nodes.len() {
                return Err(SimError::NoSuchNodeIndex { node });
            }
        }
        self.cut.push((from, to));
        self.log(What::Injected {
            fault: format!("link node {from} -> node {to} lost"),
        });
        Ok(())
    }

    /// Resets node `node` (the reset command): charts to initial states, timers cancelled,
    /// outputs safe, fault cleared. Applied at once.
    pub fn reset(&mut self, node: usize) -> Result<(), SimError> {
        if node >= self.nodes.len() {
            return Err(SimError::NoSuchNodeIndex { node });
        }
        self.log(What::Reset { node });
        self.call(node, |e, fx| e.reset(fx));
        Ok(())
    }

    /// A power cut of node `node` alone: charts back in their initial states, timers
    /// cancelled, outputs at their start levels (as a reset: a held output keeps its level
    /// here, where a real boot drops it), then its table's boot event raised and published;
    /// every peer of it under way faults (`FAULT_PEER_RESTART`), as its greeting makes a
    /// node do.
    pub fn reboot(&mut self, node: usize) -> Result<(), SimError> {
        if node >= self.nodes.len() {
            return Err(SimError::NoSuchNodeIndex { node });
        }
        self.log(What::Reboot { node });
        self.call(node, |e, fx| {
            e.reset(fx);
            e.boot(fx);
        });
        // Its greeting: each peer under way faults (`crate::restart`).
        let addr = self.nodes[node].addr;
        for peer in 0..self.nodes.len() {
            let e = &self.nodes[peer].engine;
            let states = self.states(peer);
            if peer != node
                && e.table().peers.contains(&addr)
                && e.fault().is_none()
                && crate::restart::under_way(e.table(), &states)
            {
                let code = config_schema::alarm::FAULT_PEER_RESTART;
                self.call(peer, |e, fx| e.fail(code, fx));
            }
        }
        Ok(())
    }

    /// Processes the next scheduled event (advancing the clock to it). Returns its time, or
    /// `None` when idle.
    pub fn step(&mut self) -> Option<u64> {
        let q = self.peek()?;
        self.queue.pop();
        self.now = q.t;
        self.process(q.ev);
        Some(q.t)
    }

    /// Runs until nothing is scheduled, for at most `limit_ms` of virtual time from now.
    /// Returns the time of the last event processed (the clock stays there).
    pub fn run_until_idle(&mut self, limit_ms: u64) -> Result<u64, SimError> {
        self.run_until_idle_watched(limit_ms, &mut |_| {})
    }

    /// [`World::run_until_idle`], showing the world to `after` after every event it
    /// processes.
    pub fn run_until_idle_watched(
        &mut self,
        limit_ms: u64,
        after: &mut dyn FnMut(&World<'t>),
    ) -> Result<u64, SimError> {
        let deadline = self.now.saturating_add(limit_ms);
        for _ in 0..self.event_limit {
            match self.peek() {
                None => return Ok(self.now),
                Some(q) if q.t > deadline => {
                    return Err(SimError::NotIdle {
                        limit_ms: deadline,
                        now_ms: self.now,
                        next_ms: q.t,
                    })
                }
                Some(_) => {
                    self.step();
                    after(self);
                }
            }
        }
        Err(SimError::Runaway {
            now_ms: self.now,
            events: self.event_limit,
        })
    }

    /// Runs every event up to `now + ms`, then sets the clock to `now + ms`.
    pub fn run_for(&mut self, ms: u64) -> Result<(), SimError> {
        let deadline = self.now.saturating_add(ms);
        for _ in 0..self.event_limit {
            match self.peek() {
                Some(q) if q.t <= deadline => {
                    self.step();
                }
                _ => {
                    self.now = deadline;
                    return Ok(());
                }
            }
        }
        Err(SimError::Runaway {
            now_ms: self.now,
            events: self.event_limit,
        })
    }

    /// Presses `button`, runs until idle (at most `limit_ms`), and returns the cycle it ran.
    pub fn run_cycle(&mut self, button: usize, limit_ms: u64) -> Result<Cycle, SimError> {
        self.run_cycle_watched(button, limit_ms, &mut |_| {})
    }

    /// [`World::run_cycle`], showing the world to `after` after every event it processes.
    pub fn run_cycle_watched(
        &mut self,
        button: usize,
        limit_ms: u64,
        after: &mut dyn FnMut(&World<'t>),
    ) -> Result<Cycle, SimError> {
        let mark = self.trace.len();
        self.press(button)?;
        self.run_until_idle_watched(limit_ms, after)?;
        let mut cycles = cycles(&self.trace[mark..]);
        Ok(cycles.pop().unwrap_or(Cycle {
            start_ms: self.now,
            end_ms: self.now,
            steps: Vec::new(),
        }))
    }

    fn log(&mut self, what: What) {
        self.trace.push(TraceEntry {
            t_ms: self.now,
            what,
        });
    }

    fn schedule(&mut self, delay_ms: u64, ev: Ev) {
        self.seq += 1;
        self.queue.push(Queued {
            t: self.now.saturating_add(delay_ms),
            seq: self.seq,
            ev,
        });
    }

    fn live(&self, ev: &Ev) -> bool {
        match *ev {
            Ev::Arrive { plant, gen } => self.gens[plant] == gen,
            Ev::Timer { node, timer, gen } => self.nodes[node].timers[usize::from(timer)] == gen,
            Ev::LinkPoll { from, to, gen } => {
                self.lossy.as_ref().and_then(|l| l.poll_gen(from, to)) == Some(gen)
            }
            _ => true,
        }
    }

    /// The next live event, dropping stale ones (cancelled timers, superseded arrivals).
    fn peek(&mut self) -> Option<Queued> {
        while let Some(q) = self.queue.peek().copied() {
            if self.live(&q.ev) {
                return Some(q);
            }
            self.queue.pop();
        }
        None
    }

    fn process(&mut self, ev: Ev) {
        match ev {
            Ev::Input { node, input, level } => self.set_input(node, input, level),
            Ev::Start { node } if self.blocked(node) => {
                self.log(What::Refused { node, input: None });
            }
            Ev::Start { node } => self.call(node, |e, fx| {
                e.start(fx);
            }),
            Ev::Home { node } => self.call(node, |e, fx| {
                e.home(fx);
            }),
            Ev::Arrive { plant, .. } if matches!(self.plants[plant], Plant::Motor(_)) => {
                self.motor_arrive(plant);
            }
            Ev::Arrive { plant, .. } => {
                if let Some(end) = self.rods[plant].arrive() {
                    self.log(What::Arrived { plant, end });
                    let node = self.plants[plant].node();
                    if let Some(pin) = self.plants[plant].cylinder().and_then(|c| c.sensor(end)) {
                        self.set_input(node, pin, true);
                    }
                    self.feed_arrived(plant, end);
                }
            }
            Ev::BallRoll { .. } | Ev::BallEntry { .. } | Ev::BallAt { .. } => self.feed_event(ev),
            Ev::Timer { node, timer, .. } => {
                self.nodes[node].timers[usize::from(timer)] = 0;
                self.log(What::TimerExpired { node, timer });
                self.call(node, |e, fx| e.timer_expired(timer, fx));
            }
            Ev::Deliver { from, to, .. } if self.stopped[to] || self.cut.contains(&(from, to)) => {
                if !self.alarmed.contains(&(from, to)) {
                    self.alarmed.push((from, to));
                    let wait = link_alarm_ms().saturating_sub(self.radio_delay_ms);
                    self.schedule(
                        wait,
                        Ev::LinkAlarm {
                            node: from,
                            peer: to,
                        },
                    );
                }
            }
            Ev::LinkAlarm { node, peer } => {
                if !self.stopped[node] {
                    self.log(What::LinkAlarm { node, peer });
                }
            }
            Ev::Deliver { from, to, topic } => self.deliver(from, to, topic),
            Ev::Frame { from, to, frame } => self.frame(from, to, frame),
            Ev::LinkPoll { from, to, .. } => {
                if self.stopped[from] {
                    return;
                }
                let now = self.now;
                let mut out = Vec::new();
                let mut alarm = None;
                if let Some(link) = self.lossy.as_mut().and_then(|l| l.link(from, to)) {
                    link.poll_at = None;
                    link.tx.poll(now, |m| out.extend(lossy::Frame::of(&m)));
                    let alarmed = lossy::alarmed(link.tx.state());
                    if alarmed && !link.alarm_traced {
                        alarm = Some(What::LinkAlarm {
                            node: from,
                            peer: to,
                        });
                    }
                    link.alarm_traced = alarmed;
                }
                if let Some(what) = alarm {
                    self.log(what);
                }
                self.send_frames(from, to, out);
            }
        }
    }

    /// Topic `topic` published by `from` reaches `to`'s engine (if it subscribes to it).
    fn deliver(&mut self, from: usize, to: usize, topic: Topic) {
        let from_addr = self.nodes[from].addr;
        let engine = &self.nodes[to].engine;
        let peer = engine.table().peers.iter().position(|a| *a == from_addr);
        let accepted = peer.is_some_and(|p| {
            engine
                .table()
                .subscriptions
                .iter()
                .any(|s| usize::from(s.publisher) == p && s.topic == topic)
        });
        self.log(What::Deliver {
            from,
            to,
            topic,
            accepted,
        });
        if let (true, Some(p)) = (accepted, peer) {
            self.call(to, |e, fx| {
                e.remote(p as u8, topic, fx);
            });
        }
    }

    /// Lossy radio: a publication joins the link `from -> to`.
    fn link_push(&mut self, from: usize, to: usize, topic: Topic) {
        let now = self.now;
        let mut out = Vec::new();
        let mut broken = None;
        if let Some(link) = self.lossy.as_mut().and_then(|l| l.link(from, to)) {
            let pushed = link
                .tx
                .push(topic, now, |m| out.extend(lossy::Frame::of(&m)));
            if pushed.is_err() && !link.broken_traced {
                link.broken_traced = true;
                broken = Some(What::LinkBroken {
                    node: from,
                    peer: to,
                });
            }
        }
        if let Some(what) = broken {
            self.log(what);
        }
        self.send_frames(from, to, out);
    }

    /// Lossy radio: puts frames of link `from -> to` on the air (each may be lost), then
    /// (re)schedules the link's retransmission timer.
    fn send_frames(&mut self, from: usize, to: usize, frames: Vec<lossy::Frame>) {
        let delay = self.radio_delay_ms;
        for frame in frames {
            let lost = self.lossy.as_mut().is_none_or(|l| l.lose());
            if !lost {
                self.schedule(delay, Ev::Frame { from, to, frame });
            }
        }
        let now = self.now;
        let mut poll = None;
        if let Some(link) = self.lossy.as_mut().and_then(|l| l.link(from, to)) {
            let deadline = link.tx.deadline();
            if deadline != link.poll_at {
                link.poll_at = deadline;
                link.poll_gen += 1;
                poll = deadline.map(|d| (d.saturating_sub(now), link.poll_gen));
            }
        }
        if let Some((wait, gen)) = poll {
            self.schedule(wait, Ev::LinkPoll { from, to, gen });
        }
    }

    /// Lossy radio: a frame of link `from -> to` arrives (an event at `to`, an
    /// acknowledgement at `from`).
    fn frame(&mut self, from: usize, to: usize, frame: lossy::Frame) {
        let now = self.now;
        match frame {
            lossy::Frame::Event { epoch, seq, topic } => {
                if self.stopped[to] || self.cut.contains(&(from, to)) {
                    return;
                }
                let Some(got) = self
                    .lossy
                    .as_mut()
                    .and_then(|l| l.link(from, to))
                    .map(|link| link.rx.on_event(epoch, seq, topic))
                else {
                    return;
                };
                for topic in got.deliver {
                    self.deliver(from, to, topic);
                }
                if let Some(ack) = got.ack.as_ref().and_then(lossy::Frame::of) {
                    let lost = self.lossy.as_mut().is_none_or(|l| l.lose());
                    if !lost {
                        self.schedule(
                            self.radio_delay_ms,
                            Ev::Frame {
                                from,
                                to,
                                frame: ack,
                            },
                        );
                    }
                }
            }
            lossy::Frame::Ack { epoch, next } => {
                if self.stopped[from] {
                    return;
                }
                let mut out = Vec::new();
                if let Some(link) = self.lossy.as_mut().and_then(|l| l.link(from, to)) {
                    link.tx
                        .on_ack(epoch, next, now, |m| out.extend(lossy::Frame::of(&m)));
                    if !lossy::alarmed(link.tx.state()) {
                        link.alarm_traced = false;
                    }
                }
                self.send_frames(from, to, out);
            }
        }
    }

    fn set_input(&mut self, node: usize, input: u8, level: bool) {
        if level && self.broken.contains(&(node, input)) {
            return;
        }
        self.log(What::Input { node, input, level });
        let engine = &self.nodes[node].engine;
        let table = engine.table();
        let rise = table.inputs.get(usize::from(input)).and_then(|i| i.rise);
        let restarts = level
            && !self.stopped[node]
            && ((rise.is_some() && rise == table.start)
                || (input < 16 && table.safety.restart & (1 << input) != 0));
        if restarts && self.blocked(node) {
            self.log(What::Refused {
                node,
                input: Some(input),
            });
            self.nodes[node].engine.sense(input, level);
            return;
        }
        self.call(node, |e, fx| e.input(input, level, fx));
    }

    /// Whether a fault alarm is latched on node `node` (a START is refused).
    fn blocked(&self, node: usize) -> bool {
        self.nodes[node].alarms.blocking().is_some()
    }

    /// Node `node`'s alarms now (`ack` 0).
    pub fn alarms(&self, node: usize) -> Option<config_schema::alarm::AlarmReport> {
        let n = self.nodes.get(node)?;
        let state = n.engine.snapshot();
        let seen = crate::alarms::Seen {
            table: n.engine.table(),
            state: &state,
            link_alarms: 0,
        };
        Some(n.alarms.report(0, Some(seen), self.now))
    }

    /// The operator acknowledges node `node`'s alarms (a fault alarm whose cause persists
    /// stays). Applied at once; returns how many were acknowledged.
    pub fn ack(&mut self, node: usize) -> Result<usize, SimError> {
        let n = self
            .nodes
            .get_mut(node)
            .ok_or(SimError::NoSuchNodeIndex { node })?;
        let state = n.engine.snapshot();
        let seen = crate::alarms::Seen {
            table: n.engine.table(),
            state: &state,
            link_alarms: 0,
        };
        let acked = n.alarms.ack(seen);
        self.log(What::Ack { node, acked });
        Ok(acked)
    }

    /// Runs one engine call with a tracing sink, then applies its effects.
    fn call(&mut self, node: usize, f: impl FnOnce(&mut Engine<'t>, &mut WorldEffects<'_>)) {
        if self.stopped[node] {
            return;
        }
        let mut todo = std::mem::take(&mut self.scratch);
        {
            let mut fx = WorldEffects {
                node,
                now: self.now,
                trace: &mut self.trace,
                todo: &mut todo,
            };
            f(&mut self.nodes[node].engine, &mut fx);
        }
        self.apply(node, &todo);
        todo.clear();
        self.scratch = todo;
        self.look(node);
    }

    /// The node's alarms look at it after an engine call.
    fn look(&mut self, node: usize) {
        let n = &mut self.nodes[node];
        let state = n.engine.snapshot();
        let seen = crate::alarms::Seen {
            table: n.engine.table(),
            state: &state,
            link_alarms: 0,
        };
        let latched = n.alarms.observe(seen, self.now);
        let raised: Vec<_> = (n.alarms.list().iter().rev())
            .take(latched)
            .map(|a| (a.source, a.level))
            .collect();
        for (source, level) in raised.into_iter().rev() {
            self.log(What::Alarm {
                node,
                source,
                level,
            });
        }
    }

    fn apply(&mut self, node: usize, effects: &[Effect]) {
        // The valves see the outputs once the engine step is over.
        let cylinders: Vec<(usize, Cylinder)> = (self.plants.iter().enumerate())
            .filter(|(_, plant)| plant.node() == node)
            .filter_map(|(p, plant)| Some((p, plant.cylinder()?)))
            .collect();
        let outputs = effects.iter().filter_map(|e| match *e {
            Effect::Output(output, level) => Some((output, level)),
            _ => None,
        });
        let valves = cylinder::commands(&cylinders, outputs);
        for effect in effects {
            match *effect {
                Effect::Output(..) => {}
                Effect::Publish(p) => self.publish(node, &p),
                Effect::StartTimer(timer, ms) => {
                    if let Some(slot) = self.nodes[node].timers.get_mut(usize::from(timer)) {
                        self.timer_gen += 1;
                        *slot = self.timer_gen;
                        let gen = self.timer_gen;
                        self.schedule(u64::from(ms), Ev::Timer { node, timer, gen });
                    }
                }
                Effect::CancelTimer(timer) => {
                    if let Some(slot) = self.nodes[node].timers.get_mut(usize::from(timer)) {
                        *slot = 0;
                    }
                }
            }
        }
        for (plant, command) in valves {
            match command {
                Command::Conflict => self.log(What::Conflict { plant }),
                Command::Drive(extend) => self.command(plant, extend),
            }
        }
        self.drive_motors(node, effects);
    }

    /// The motors of node `node` whose outputs the step `effects` drove: each runs as its
    /// two outputs now say (both high: a conflict, it stops).
    fn drive_motors(&mut self, node: usize, effects: &[Effect]) {
        let outputs = self.nodes[node].engine.outputs();
        let level = |o: u8| outputs & (1u16 << (o & 15)) != 0;
        let mut changes = Vec::new();
        for (p, plant) in self.plants.iter().enumerate() {
            let Plant::Motor(m) = plant else { continue };
            let touched = effects
                .iter()
                .any(|e| matches!(*e, Effect::Output(o, _) if o == m.cw_out || o == m.ccw_out));
            if m.node != node || !touched {
                continue;
            }
            let (cw, ccw) = (level(m.cw_out), level(m.ccw_out));
            changes.push((p, cw && ccw, Run::of(cw, ccw)));
        }
        for (plant, conflict, run) in changes {
            if conflict {
                self.log(What::Conflict { plant });
            }
            if self.carriages[plant].run != run {
                self.motor_run(plant, run);
            }
        }
    }

    /// Motor `plant` runs `run` from now on.
    fn motor_run(&mut self, plant: usize, run: Run) {
        let Some(Plant::Motor(m)) = self.plants.get(plant) else {
            return;
        };
        let change = m.change(&mut self.carriages[plant], run, self.now);
        let at_um = self.carriages[plant].at_um;
        let name = m.name.clone();
        self.log(What::Motor { plant, run, at_um });
        self.gens[plant] += 1;
        let Some(arrive) = change.arrive_ms else {
            return;
        };
        self.log(What::Step {
            plant,
            actuator: name,
            plus: run == Run::Clockwise,
        });
        if let Some(end) = change.left {
            for (node, input) in self.carriage_sensors(plant, end) {
                self.schedule(
                    0,
                    Ev::Input {
                        node,
                        input,
                        level: false,
                    },
                );
            }
        }
        let gen = self.gens[plant];
        self.schedule(arrive - self.now, Ev::Arrive { plant, gen });
    }

    /// Motor `plant`'s carriage reaches the end it runs to: the sensors there close (its
    /// own and those of what it moves).
    fn motor_arrive(&mut self, plant: usize) {
        let Some(Plant::Motor(m)) = self.plants.get(plant) else {
            return;
        };
        let Some(end) = m.arrive(&mut self.carriages[plant], self.now) else {
            return;
        };
        self.log(What::Arrived { plant, end });
        for (node, input) in self.carriage_sensors(plant, end) {
            self.set_input(node, input, true);
        }
    }

    /// The sensors (node, input) at one end (`end`, else home) of motor `motor`'s stroke:
    /// its own, then those of the plants it moves.
    fn carriage_sensors(&self, motor: usize, end: bool) -> Vec<(usize, u8)> {
        let pick = |home: Option<u8>, far: Option<u8>| if end { far } else { home };
        self.plants
            .iter()
            .enumerate()
            .filter_map(|(p, plant)| match plant {
                Plant::Motor(m) if p == motor => Some((m.node, pick(m.home_in, m.end_in)?)),
                Plant::Driven(d) if d.motor == motor => Some((d.node, pick(d.home_in, d.end_in)?)),
                _ => None,
            })
            .collect()
    }

    fn publish(&mut self, node: usize, p: &Publication) {
        let table = self.nodes[node].engine.table();
        for (i, addr) in table.peers.iter().enumerate().take(8) {
            if p.subscribers & (1 << i) == 0 {
                continue;
            }
            match self.node_by_addr(*addr) {
                Some(to) if self.lossy.is_some() => self.link_push(node, to, p.topic),
                Some(to) => self.schedule(
                    self.radio_delay_ms,
                    Ev::Deliver {
                        from: node,
                        to,
                        topic: p.topic,
                    },
                ),
                None => self.log(What::NoSuchPeer { node, addr: *addr }),
            }
        }
    }

    /// A valve command to an actuator (`extend` or retract).
    fn command(&mut self, plant: usize, extend: bool) {
        let Some(travel) = self.plants[plant].travel() else {
            return;
        };
        if self.jammed[plant] {
            if self.rods[plant].position() != Position::from_command(extend) {
                self.log(What::Jammed {
                    plant,
                    plus: extend,
                });
            }
            return;
        }
        let outcome = self.rods[plant].command(self.now, extend, travel);
        let arrive = match outcome {
            RodOutcome::Nothing => return,
            RodOutcome::Left { arrive, .. } | RodOutcome::Reversed { arrive } => arrive,
        };
        self.log(What::Step {
            plant,
            actuator: self.plants[plant].name().to_string(),
            plus: extend,
        });
        // Leaving a switch drops it at once (before a zero-time arrival raises the other).
        if let (RodOutcome::Left { from_end, .. }, Some(cylinder)) =
            (outcome, self.plants[plant].cylinder())
        {
            let node = self.plants[plant].node();
            if let Some(input) = cylinder.sensor(from_end) {
                self.schedule(
                    0,
                    Ev::Input {
                        node,
                        input,
                        level: false,
                    },
                );
            }
        }
        self.gens[plant] += 1;
        let gen = self.gens[plant];
        self.schedule(arrive - self.now, Ev::Arrive { plant, gen });
    }
}
