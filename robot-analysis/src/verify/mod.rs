//! `verify`: explicit-state exploration of the whole machine, built from the decoded
//! compiled tables run by the nodes' own interpreter ([`Engine`]), the plant and the
//! network. See `docs/verification.md`.
//!
//! A state is every node's [`EngineState`] and armed timers, every actuator's position
//! (home, end, extending, retracting), every radio link's FIFO of publications in flight
//! (and, with `lossy`, whether it is in alarm), and how far the cycle has got in the
//! declared sequence. Moves: the operator presses START (only when the machine is idle),
//! a moving actuator arrives, an armed timer expires, a link delivers its oldest
//! publication (or, lossy, gives up: link alarm). Breadth-first with a visited set, so a
//! counterexample is a shortest one.
//!
//! The cycle is explored from the machine homed; [`explore_homing`] explores homing from
//! every start position (module `homing`), on the same model and moves.

use std::collections::VecDeque;
use std::fmt::Write;
use std::time::{Duration, Instant};

use config_schema::{Publication, Table, Topic};
use indexmap::IndexSet;
use node_fw::cylinder::{self, Command, Cylinder, Motion, Position as Pos};
use node_fw::ecc::{Effects, Engine, EngineState, Fault, Index};
use rustc_hash::FxBuildHasher;

use robot_compiler::compile::Compiled;
use robot_compiler::interlock::{self, Atom, Interlock};
use robot_compiler::ir::Step;

use crate::sim::SimulationError;

mod estop;
mod feed;
mod homing;
mod motor;
mod packed;
mod place;

pub use feed::{DEFAULT_BALLS, MAX_BALLS};

pub use homing::{explore_homing, HomingReport};
pub(crate) use place::rod_mask;
use place::Place;
pub use place::Rest;

/// Why a compiled robot has no model to explore.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ModelError {
    #[error("{0} roles: verify handles at most 8 nodes")]
    TooManyRoles(usize),
    #[error("no start button")]
    NoStartButton,
    /// More declared switches than a state holds (one bit each).
    #[error("{0} switches: verify handles at most {MAX_SWITCHES}")]
    TooManySwitches(usize),
    /// A `never:` interlock (by index) does not resolve.
    #[error("never[{index}]: {message}")]
    Interlock { index: usize, message: String },
    /// A sorting station the verifier cannot model.
    #[error("the sorting station: {0}")]
    Station(String),
    #[error(transparent)]
    Simulation(#[from] SimulationError),
}

/// Assumptions and bounds of a verification run.
#[derive(Debug, Clone, Copy)]
pub struct ExploreOptions {
    /// A delivery may fail after the link's retries (link alarm).
    pub lossy: bool,
    /// Timing assumption: the radio is faster than any motion or timer, so while a
    /// publication is in flight no actuator arrives and no timer expires. Off: deliveries
    /// take any time.
    pub prompt: bool,
    /// The operator may press START at any time, not only when the machine is idle.
    pub start_anytime: bool,
    /// Give up (inconclusive) beyond this many states.
    pub max_states: usize,
    /// Declared switches (fault contacts): how many times in all one may be set in a run,
    /// each set released at any time after ([`DEFAULT_FAULTS`]).
    pub faults: u8,
}

/// Fault pulses explored by default: two, each at any moment of the cycle and of any length
/// against the radio's delays.
pub const DEFAULT_FAULTS: u8 = 2;

impl Default for ExploreOptions {
    fn default() -> Self {
        ExploreOptions {
            lossy: false,
            prompt: false,
            start_anytime: false,
            max_states: 2_000_000,
            faults: DEFAULT_FAULTS,
        }
    }
}

/// The properties `verify` checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Property {
    /// From every reachable state the machine can get back to idle, or it is faulted (or,
    /// lossy, a link is in alarm).
    Deadlock,
    /// Actuator motions follow the declared sequence (or `expect`).
    Sequence,
    /// A `never:` condition held.
    Interlock,
    /// An actuator commanded one way while moving the other (or both solenoids at once).
    DoubleActuation,
    /// A node faulted for another reason than a declared `Fault` action (event queue,
    /// cascade, chain limit).
    EngineFault,
    /// More publications in flight on one link than [`LINK_BOUND`].
    LinkBound,
    /// A node that publishes `fault` (synthesised fault chart) faulted, and once nothing
    /// more can happen some node that subscribes to it is still running.
    FaultStop,
    /// Homing: an actuator moved before the HOME command (a START while not homed, or a
    /// chart that acted on its own).
    UnhomedStart,
    /// Homing: an actuator motion that is not one of the homing steps left, in order.
    Homing,
    /// A sorting station: a ball that ends in no bin (the station stopped with it in the
    /// shaft or at the sensors, or fed another on top of it).
    Bins,
    /// A sorting station: a gate moved while a ball was falling toward it.
    GateFall,
    /// A sorting station: the pusher fed while a gate moved.
    PusherGate,
    /// A sorting station: a ball's automata, EOSs or bin differ from the reference
    /// semantics on the same feed.
    Selection,
    /// The e-stop: its node did not fault at once, a node is not reached in one hop (or
    /// did not fault on it), or a node it reached commanded a motion.
    EStop,
    /// `on_link_alarm: Fault`: a link went into alarm and its node did not fault.
    LinkFault,
    /// A motor turned clockwise after a fault (a switch set) before the operator cleared
    /// it (the switch released and the alarm acknowledged).
    FaultClear,
}

impl std::fmt::Display for Property {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Property::Deadlock => "deadlock freedom",
            Property::Sequence => "sequence conformance",
            Property::Interlock => "interlock",
            Property::DoubleActuation => "no double actuation",
            Property::EngineFault => "no engine fault",
            Property::LinkBound => "bounded links",
            Property::FaultStop => "a fault stops every node",
            Property::UnhomedStart => "nothing moves before HOME",
            Property::Homing => "homing conformance",
            Property::Bins => "each ball in exactly one bin",
            Property::GateFall => "no gate moves while a ball falls past it",
            Property::PusherGate => "the pusher never feeds while a gate moves",
            Property::Selection => "selections as the reference semantics",
            Property::EStop => "the e-stop stops every node within one hop",
            Property::LinkFault => "a link alarm faults its node",
            Property::FaultClear => {
                "after a fault, no motor turns clockwise until the operator has cleared it"
            }
        })
    }
}

/// Publications in flight on one link beyond which the model is not explored further.
pub const LINK_BOUND: usize = 8;

/// A failed property and its shortest counterexample.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Violation {
    pub property: Property,
    pub message: String,
    /// Moves from the initial state to the violation.
    pub steps: usize,
    /// Numbered steps from the initial state, each with what it did.
    pub trace: Vec<String>,
    /// Homing: the start positions the counterexample starts from (`VC end, GR between`).
    pub start: Option<String>,
}

/// The outcome of a run.
#[derive(Debug, Clone)]
pub struct Report {
    pub states: usize,
    pub transitions: usize,
    /// Bytes of the states as the visited set holds them, packed (a few a node; the
    /// set's own bookkeeping and the parent links, about 70 bytes a state, and 8 bytes a
    /// transition come on top).
    pub packed_bytes: usize,
    /// States where the machine is idle (ready for START).
    pub idle: usize,
    /// States where a node is faulted or, lossy, a link is in alarm.
    pub stopped: usize,
    pub elapsed: Duration,
    pub violation: Option<Violation>,
    /// The exploration hit `max_states`.
    pub incomplete: bool,
    /// When incomplete: variables of the last state explored far from their initial
    /// values (`ROLE.var = value`), the usual cause (a counter never reset).
    pub growing: Vec<String>,
    pub lossy: bool,
    pub prompt: bool,
    /// A sorting station: its feed, as the report names it.
    pub feed: Option<String>,
    /// The e-stop explored (`VC/ESTOP`), if the robot has one.
    pub estop: Option<String>,
    /// Declared plants (motors, switches, buttons), as the report names them.
    pub plants: Option<String>,
    /// Control functions (each a chart: one token in every state, by construction).
    pub functions: usize,
    /// A cycle was declared (`sequence`, `expect`) and its conformance checked.
    pub sequence: bool,
}

impl Report {
    pub fn ok(&self) -> bool {
        self.violation.is_none() && !self.incomplete
    }

    /// The report of an exploration that was not run (`verify --only`): nothing explored,
    /// nothing failed.
    pub fn skipped(opts: ExploreOptions) -> Report {
        Report {
            states: 0,
            transitions: 0,
            packed_bytes: 0,
            idle: 0,
            stopped: 0,
            elapsed: Duration::ZERO,
            violation: None,
            incomplete: false,
            growing: Vec::new(),
            lossy: opts.lossy,
            prompt: opts.prompt,
            feed: None,
            estop: None,
            plants: None,
            functions: 0,
            sequence: false,
        }
    }

    /// The text `config-tool verify` prints.
    pub fn render(&self, name: &str, interlocks: usize) -> String {
        let mut o = String::new();
        if let Some(feed) = &self.feed {
            let _ = writeln!(o, "{name}: {feed}");
        }
        if let Some(plants) = &self.plants {
            let _ = writeln!(o, "{name}: {plants}");
        }
        o += &self.figures(&format!("{name}: "), "idle");
        let station = match self.feed {
            Some(_) => {
                ", each ball in exactly one bin, no gate moves while a ball falls past it, \
                 the pusher never feeds while a gate moves, selections as the reference \
                 semantics"
            }
            None => "",
        };
        let estop = match &self.estop {
            Some(e) => format!(
                ", the e-stop ({e}) stops every node within one hop and nothing moves after it"
            ),
            None => String::new(),
        };
        let functions = match self.functions {
            0 => String::new(),
            f => format!(", each of the {f} functions in exactly one place in every state"),
        };
        let plants = match &self.plants {
            Some(_) => ", after a fault no motor turns clockwise until the operator has cleared it",
            None => "",
        };
        let sequence = match self.sequence {
            true => "sequence conformance",
            false => "no cycle declared (`expect`) to conform to",
        };
        self.verdict(
            &mut o,
            &format!(
                "ok: deadlock freedom, {sequence}, {interlocks} interlock(s), no double \
                 actuation, no engine fault, a fault stops every node{station}{estop}\
                 {functions}{plants}"
            ),
        );
        o
    }

    /// The first two lines: size and time, then the idle (`idle` names them) and stopped
    /// states; `head` starts the first.
    fn figures(&self, head: &str, idle: &str) -> String {
        let mut o = String::new();
        let secs = self.elapsed.as_secs_f64();
        let _ = writeln!(
            o,
            "{head}{} states, {} transitions in {:.3} s ({:.0} states/s){}",
            self.states,
            self.transitions,
            secs,
            self.states as f64 / secs.max(1e-9),
            match (self.lossy, self.prompt) {
                (false, false) => "",
                (true, false) => ", lossy links",
                (false, true) => ", prompt radio",
                (true, true) => ", lossy links, prompt radio",
            }
        );
        let _ = writeln!(
            o,
            "  {idle} states {}, stopped (fault / link alarm) states {}",
            self.idle, self.stopped
        );
        o
    }

    /// Incomplete, then `ok` or the failed property with its counterexample.
    fn verdict(&self, o: &mut String, ok: &str) {
        if self.incomplete {
            let _ = writeln!(o, "INCOMPLETE: stopped after {} states", self.states);
            if !self.growing.is_empty() {
                let _ = writeln!(
                    o,
                    "  variables that keep growing (a counter never reset makes the state \
                     space infinite): {}",
                    self.growing.join(", ")
                );
            }
        }
        match &self.violation {
            None if !self.incomplete => {
                let _ = writeln!(o, "{ok}");
            }
            None => {}
            Some(v) => {
                let _ = writeln!(o, "FAILED {}: {}", v.property, v.message);
                match &v.start {
                    Some(start) if start.starts_with("ball feed: ") => {
                        let _ = writeln!(o, "{start}");
                    }
                    Some(start) => {
                        let _ = writeln!(o, "start positions: {start}");
                    }
                    None => {}
                }
                let _ = writeln!(o, "shortest counterexample ({} steps):", v.steps);
                for line in &v.trace {
                    let _ = writeln!(o, "{line}");
                }
            }
        }
    }
}

/// An actuator as the verifier sees it.
#[derive(Debug, Clone)]
struct Act {
    name: String,
    node: usize,
    cylinder: Cylinder,
}

/// The whole machine's state.
#[derive(Debug, Default, PartialEq, Eq, Hash)]
struct Sys {
    nodes: Vec<EngineState>,
    /// Armed timers per node, bit i = timer i.
    timers: Vec<u8>,
    pos: Vec<Place>,
    /// Publications in flight as (link `from * n + to`, topic), sorted by link and oldest
    /// first within a link (a canonical form: one entry per state).
    flight: Vec<(u8, Topic)>,
    /// Links in alarm (lossy), bit `from * n + to`.
    alarms: u64,
    /// Steps of the current cycle done: 0 at rest, [`PRESSED`] after START at rest and
    /// before the first step, the cycle's length once its last step was commanded, one
    /// more if START was pressed again since (`--start-anytime`: the next step may begin
    /// a new cycle); 0 again when the machine is idle after its last step
    /// ([`Model::rested`]). Homing: the homing steps passed.
    progress: u16,
    /// Homing explorations only: whether the HOME command was given (`None`: the cycle).
    homing: Option<bool>,
    /// A sorting station: its balls.
    ball: Option<feed::Balls>,
    /// The e-stop: pressed, and bit i: node i has been reached by it (the e-stop node
    /// when pressed, another when its `estop` was delivered).
    estop: Option<u8>,
    /// Declared motors: where each carriage is.
    regions: Vec<motor::Region>,
    /// Declared switches: bit i set.
    switches: u8,
    /// Declared switches: how many times one was set so far.
    sets: u8,
    /// Bit i: node i has a fault alarm latched, not acknowledged.
    latched: u8,
    /// A switch was set and the operator has not cleared it since.
    uncleared: bool,
}

impl Clone for Sys {
    fn clone(&self) -> Sys {
        let mut s = Sys::default();
        s.clone_from(self);
        s
    }

    /// Field by field, each list into the one `self` has: a search that takes a copy of a
    /// state for each of its moves allocates nothing once its lists are long enough.
    fn clone_from(&mut self, o: &Sys) {
        self.nodes.clone_from(&o.nodes);
        self.timers.clone_from(&o.timers);
        self.pos.clone_from(&o.pos);
        self.flight.clone_from(&o.flight);
        self.alarms = o.alarms;
        self.progress = o.progress;
        self.homing = o.homing;
        self.ball.clone_from(&o.ball);
        self.estop = o.estop;
        self.regions.clone_from(&o.regions);
        self.switches = o.switches;
        self.sets = o.sets;
        self.latched = o.latched;
        self.uncleared = o.uncleared;
    }
}

/// The most declared switches (fault contacts) a state holds: its `switches` has a
/// bit for each.
pub const MAX_SWITCHES: usize = 8;

/// [`Sys::progress`] after START pressed at rest, before the cycle's first step.
const PRESSED: u16 = u16::MAX;

/// One move of the environment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Move {
    Press,
    Home,
    Arrive(u8),
    Expire(u8, u8),
    Deliver(u8, u8),
    Lose(u8, u8),
    /// A sorting station: the pusher arrives home and the next ball (or none) rolls to
    /// the sensors.
    Roll(u8, feed::Front),
    /// A sorting station: the ball in the shaft falls on one step.
    Fall,
    /// The operator presses the emergency stop (and holds it).
    EStop,
    /// A running motor reaches the next region toward its direction.
    Motor(u8),
    /// A declared switch is set or released.
    Switch(u8),
    /// The operator presses (and releases) a declared button.
    Button(u8),
    /// The operator acknowledges the alarms of a node.
    Ack(u8),
}

impl Move {
    /// Whether the machine makes this move (an actuator, a timer, the radio, a motor, a
    /// ball), not the operator (START, HOME, the e-stop, a button, an acknowledgement) or
    /// a fault contact.
    fn by_the_machine(self) -> bool {
        match self {
            Move::Arrive(_)
            | Move::Expire(..)
            | Move::Deliver(..)
            | Move::Lose(..)
            | Move::Roll(..)
            | Move::Fall
            | Move::Motor(_) => true,
            Move::Press
            | Move::Home
            | Move::EStop
            | Move::Switch(_)
            | Move::Button(_)
            | Move::Ack(_) => false,
        }
    }
}

/// What an engine call reported, in order.
#[derive(Debug, Clone)]
enum Effect {
    Output(u8, bool),
    Publish(Publication),
    Start(u8),
    Cancel(u8),
    Fault(Fault),
    Fired(u8, u8, u8),
    Ignored(u8, u8),
}

/// The effects of one engine call, in order.
#[derive(Default)]
struct EffectLog(Vec<Effect>);

impl Effects for EffectLog {
    fn output(&mut self, output: u8, value: bool) {
        self.0.push(Effect::Output(output, value));
    }
    fn publish(&mut self, p: &Publication) {
        self.0.push(Effect::Publish(*p));
    }
    fn start_timer(&mut self, timer: u8, _ms: u32) {
        self.0.push(Effect::Start(timer));
    }
    fn cancel_timer(&mut self, timer: u8) {
        self.0.push(Effect::Cancel(timer));
    }
    fn fault(&mut self, fault: Fault) {
        self.0.push(Effect::Fault(fault));
    }
    fn fired(&mut self, chart: u8, _transition: u8, from: u8, to: u8) {
        self.0.push(Effect::Fired(chart, from, to));
    }
    fn ignored(&mut self, chart: u8, input: u8) {
        self.0.push(Effect::Ignored(chart, input));
    }
}

/// The composed model of a compiled robot.
pub struct Model<'c> {
    c: &'c Compiled,
    tables: Vec<Table>,
    /// Each table's index, built once (an engine is resumed per move).
    indexes: Vec<Index>,
    acts: Vec<Act>,
    /// (node, input) of START.
    start: (usize, u8),
    /// The node that takes the HOME command, if the tables home.
    home: Option<usize>,
    /// Per node, per peer index: the node with that address.
    peers: Vec<Vec<Option<usize>>>,
    expect: Vec<Step>,
    interlocks: Vec<Interlock>,
    init: Sys,
    feed: Option<feed::FeedModel>,
    estop: Option<estop::EStop>,
    plants: motor::Plants,
}

type Bad = (Property, String);

impl<'c> Model<'c> {
    /// The model of `c`, from its blobs decoded as a node decodes them; a sorting
    /// station's feed is every colour sequence of up to [`DEFAULT_BALLS`] balls.
    pub fn new(c: &'c Compiled) -> Result<Model<'c>, ModelError> {
        Model::with_balls(c, DEFAULT_BALLS)
    }

    /// [`Model::new`], a sorting station fed every colour sequence of up to `balls` balls
    /// (at most [`MAX_BALLS`]).
    pub fn with_balls(c: &'c Compiled, balls: usize) -> Result<Model<'c>, ModelError> {
        let tables = crate::sim::tables(c)?;
        if tables.len() > 8 {
            return Err(ModelError::TooManyRoles(tables.len()));
        }
        let (plants, button) = crate::sim::plants(c)?;
        let acts: Vec<Act> = (plants.iter())
            .filter_map(|p| {
                Some(Act {
                    name: p.name().to_string(),
                    node: p.node(),
                    cylinder: p.cylinder()?,
                })
            })
            .collect();
        let node_fw::sim::Plant::Button(b) = &plants[button] else {
            return Err(ModelError::NoStartButton);
        };
        let start = (b.node, b.input);
        let declared = motor::Plants::new(&plants, button);
        let peers = tables
            .iter()
            .map(|t| {
                t.peers
                    .iter()
                    .map(|a| c.ir.roles.iter().position(|r| r.address == *a))
                    .collect()
            })
            .collect();
        let interlocks =
            interlock::interlocks(&c.robot, &c.ir).map_err(|e| ModelError::Interlock {
                index: e.index,
                message: e.error.to_string(),
            })?;
        let expect = c.ir.expect.clone();
        let n = tables.len();
        // Power-up (`node_fw::cylinder`): each rod rests where its node's safe outputs hold
        // it, the node reads the sensors closed there.
        // The cycle is explored from the machine homed: every chart at its idle point.
        let mut engines: Vec<Engine<'_>> = tables
            .iter()
            .map(|t| {
                let mut e = Engine::new(t);
                e.rest();
                e
            })
            .collect();
        let mut pos = Vec::new();
        for a in &acts {
            let e = &mut engines[a.node];
            let (at, closed) = a.cylinder.power_up(e.outputs());
            if let Some(sensor) = closed {
                e.sense(sensor, true);
            }
            pos.push(Place::Rod(at));
        }
        for m in &declared.motors {
            for &(node, input) in &m.home {
                engines[node].sense(input, true);
            }
        }
        let nodes = engines.iter().map(Engine::snapshot).collect();
        let init = Sys {
            nodes,
            timers: vec![0; n],
            pos,
            flight: Vec::new(),
            alarms: 0,
            progress: 0,
            homing: None,
            ball: None,
            estop: None,
            regions: vec![motor::Region::Home; declared.motors.len()],
            switches: 0,
            sets: 0,
            latched: 0,
            uncleared: false,
        };
        let home = (c.ir.home).filter(|&r| tables.get(r).is_some_and(|t| t.home.is_some()));
        let feed = feed::FeedModel::new(c, &acts, balls)?;
        let estop = estop::EStop::new(c, &tables);
        // The e-stop's own contact is the e-stop's move, not a switch.
        let mut declared = declared;
        if let Some(e) = &estop {
            (declared.switches).retain(|&(_, node, input)| (node, input) != (e.node, e.input));
        }
        // Refused, not explored in part: a ninth was never set, and the report said so
        // nowhere.
        if declared.switches.len() > MAX_SWITCHES {
            return Err(ModelError::TooManySwitches(declared.switches.len()));
        }
        Ok(Model {
            c,
            indexes: tables.iter().map(Index::new).collect(),
            tables,
            acts,
            start,
            home,
            peers,
            expect,
            interlocks,
            init,
            feed,
            estop,
            plants: declared,
        })
    }

    /// A sorting station's feed, as the report names it.
    pub fn feed(&self) -> Option<String> {
        self.feed.as_ref().map(feed::FeedModel::describe)
    }

    /// The initial states: the machine homed; a sorting station's with each ball 1 (or an
    /// empty magazine) at the sensors, read as levels at power-up.
    fn roots(&self) -> Vec<(Sys, Option<String>)> {
        let Some(f) = &self.feed else {
            return vec![(self.init.clone(), None)];
        };
        f.choices(0)
            .map(|front| {
                let mut s = self.init.clone();
                let node = f.node();
                let mut e =
                    Engine::resume_indexed(&self.tables[node], &self.indexes[node], &s.nodes[node]);
                for i in f.levels(front) {
                    e.sense(i, true);
                }
                s.nodes[node] = e.snapshot();
                s.ball = Some(f.start(front));
                (s, Some(f.label(front)))
            })
            .collect()
    }

    /// The declared plants, as the report names them (`None`: none).
    pub fn plants(&self, faults: u8) -> Option<String> {
        self.plants.any().then(|| self.plants.describe(faults))
    }

    /// The e-stop the exploration presses (`VC/ESTOP`), if the robot has one.
    pub fn estop(&self) -> Option<String> {
        self.estop.as_ref().map(|e| e.name(self.c))
    }

    /// The number of `never:` interlocks.
    pub fn interlock_count(&self) -> usize {
        self.interlocks.len()
    }

    fn n(&self) -> usize {
        self.tables.len()
    }

    fn idle(&self, s: &Sys) -> bool {
        if self.plants.any() {
            return self.ready(s);
        }
        s.alarms == 0
            && s.timers.iter().all(|t| *t == 0)
            && s.flight.is_empty()
            && s.pos == self.init.pos
            && s.nodes
                .iter()
                .zip(&self.init.nodes)
                .all(|(a, b)| a.fault.is_none() && a.current == b.current)
    }

    /// With declared plants: idle is ready for START: nothing in flight or armed, every
    /// carriage home, no switch set, no alarm latched, no node faulted, and a START press
    /// here fires a chart (the machine takes a new cycle, in whatever mode it rests in).
    fn ready(&self, s: &Sys) -> bool {
        let quiet = s.alarms == 0
            && s.timers.iter().all(|t| *t == 0)
            && s.flight.is_empty()
            && s.pos == self.init.pos
            && s.regions == self.init.regions
            && s.switches == 0
            && s.latched == 0
            && !s.uncleared
            && s.nodes.iter().all(|e| e.fault.is_none());
        if !quiet {
            return false;
        }
        let (node, input) = self.start;
        let mut e = Engine::resume_indexed(&self.tables[node], &self.indexes[node], &s.nodes[node]);
        let mut fx = EffectLog::default();
        e.input(input, true, &mut fx);
        fx.0.iter().any(|f| matches!(f, Effect::Fired(..)))
    }

    /// Whether a press of `input` on `node` is refused (a restart input, or START, while
    /// a fault alarm is latched there).
    fn refused(&self, s: &Sys, node: usize, input: u8) -> bool {
        let restarts = self.start == (node, input)
            || (input < 16 && self.tables[node].safety.restart & (1 << input) != 0);
        restarts && s.latched & (1 << node) != 0
    }

    /// Whether a cause of a fault alarm on `node` persists (its own fault, a declared
    /// fault alarm's condition).
    fn alarm_cause(&self, s: &Sys, node: usize) -> bool {
        let seen = node_fw::alarms::Seen {
            table: &self.tables[node],
            state: &s.nodes[node],
            link_alarms: 0,
        };
        s.nodes[node].fault.is_some()
            || (self.tables[node].safety.alarms.iter().enumerate()).any(|(i, a)| {
                a.level == config_schema::alarm::AlarmLevel::Fault
                    && node_fw::alarms::Alarms::persists(
                        seen,
                        config_schema::alarm::AlarmSource::Declared { index: i as u8 },
                    )
            })
    }

    /// In a state where nothing more can happen: a role still running although a node
    /// published `fault` to it (its watchdog expired) over a link not in alarm.
    fn unstopped(&self, s: &Sys) -> Option<String> {
        let n = self.n();
        for (f, e) in s.nodes.iter().enumerate() {
            // Only a watchdog fault publishes `fault` (a peer's fault does not echo it).
            let published = matches!(
                e.fault,
                Some(Fault::Action { code, .. }) if code == robot_compiler::synth::FAULT_MOTION_TIMEOUT
            );
            if !published {
                continue;
            }
            let r = &self.c.ir.roles[f];
            // Who must hear it: the roles the robot's description says subscribe to it
            // (from the IR, so a table that lost a subscriber is caught), and every other
            // role that hears any node's fault (it takes part in the machine's stop, so a
            // description that lost one of its subscriptions is caught too).
            // (A fault chart's output is `fault`: the role's event `fault`, or `C.fault` of
            // its chart `C` in a robot imported from IEC 61499.)
            let fault =
                |ev: &str| ev.rsplit('.').next() == Some(robot_compiler::synth::FAULT_EVENT);
            for (to, q) in self.c.ir.roles.iter().enumerate() {
                let listens = (q.imports.iter()).any(|(from, ev, _)| *from == r.name && fault(ev));
                let takes_part = to != f && (q.imports.iter()).any(|(_, ev, _)| fault(ev));
                if (listens || takes_part)
                    && s.nodes[to].fault.is_none()
                    && s.alarms & (1 << (f * n + to)) == 0
                {
                    let why = if listens {
                        ""
                    } else {
                        " (it does not hear that node's fault)"
                    };
                    return Some(format!(
                        "{} faulted but {} is still running{why}",
                        r.name, q.name
                    ));
                }
            }
        }
        None
    }

    fn stopped(&self, s: &Sys) -> bool {
        s.alarms != 0 || s.nodes.iter().any(|e| e.fault.is_some())
    }

    fn moves(&self, s: &Sys, opts: ExploreOptions, out: &mut Vec<Move>) {
        out.clear();
        let lossy = opts.lossy;
        match s.homing {
            // Homing: HOME once, any number of STARTs before it.
            Some(false) => {
                out.push(Move::Press);
                out.push(Move::Home);
            }
            Some(true) => {}
            None if (self.idle(s) || opts.start_anytime)
                && !self.refused(s, self.start.0, self.start.1) =>
            {
                out.push(Move::Press)
            }
            None => {}
        }
        if s.homing.is_none() {
            self.plant_moves(s, opts, out);
        }
        if let Some(e) = &self.estop {
            if s.homing.is_none() && s.estop.is_none() && s.nodes[e.node].fault.is_none() {
                out.push(Move::EStop);
            }
        }
        let radio_busy = s.flight.iter().any(|(l, _)| s.alarms & (1 << l) == 0);
        for (p, pos) in s.pos.iter().enumerate() {
            if opts.prompt && radio_busy {
                break;
            }
            if !pos.moving() {
                continue;
            }
            match (&self.feed, &s.ball) {
                (Some(f), Some(b))
                    if f.is_pusher(p)
                        && *pos == Place::Rod(Pos::Retracting)
                        && b.front == feed::Front::Gone =>
                {
                    out.extend(f.choices(b.count).map(|c| Move::Roll(p as u8, c)));
                }
                _ => out.push(Move::Arrive(p as u8)),
            }
        }
        if s.ball.as_ref().is_some_and(|b| b.shaft.is_some()) && !(opts.prompt && radio_busy) {
            out.push(Move::Fall);
        }
        for (node, t) in s.timers.iter().enumerate() {
            if opts.prompt && radio_busy {
                break;
            }
            for i in 0..8u8 {
                if t & (1 << i) != 0 {
                    out.push(Move::Expire(node as u8, i));
                }
            }
        }
        let n = self.n();
        let mut last = None;
        for &(l, _) in &s.flight {
            if last == Some(l) || s.alarms & (1 << l) != 0 {
                continue;
            }
            last = Some(l);
            let l = usize::from(l);
            let (f, t) = ((l / n) as u8, (l % n) as u8);
            out.push(Move::Deliver(f, t));
            if lossy {
                out.push(Move::Lose(f, t));
            }
        }
    }

    /// The declared plants' moves: a running motor arrives, a switch toggles, the operator
    /// presses a button (not one refused) or acknowledges a node's alarms (once no cause
    /// persists).
    fn plant_moves(&self, s: &Sys, opts: ExploreOptions, out: &mut Vec<Move>) {
        let radio_busy = s.flight.iter().any(|(l, _)| s.alarms & (1 << l) == 0);
        for (i, m) in self.plants.motors.iter().enumerate() {
            let run = m.run(s.nodes[m.node].outputs);
            if !(opts.prompt && radio_busy) && motor::MotorModel::moving(run, s.regions[i]) {
                out.push(Move::Motor(i as u8));
            }
        }
        // A contact is set or released at any time, also with a prompt radio (which is
        // faster than a motion, not than a fault's pulse): at most `opts.faults` sets in a
        // run; a set switch may always be released.
        for i in 0..self.plants.switches.len() {
            let set = s.switches & (1 << i) != 0;
            if set || s.sets < opts.faults {
                out.push(Move::Switch(i as u8));
            }
        }
        for (i, &(_, node, input)) in self.plants.buttons.iter().enumerate() {
            if !self.refused(s, node, input) {
                out.push(Move::Button(i as u8));
            }
        }
        for node in 0..self.n() {
            if s.latched & (1 << node) != 0 && !self.alarm_cause(s, node) {
                out.push(Move::Ack(node as u8));
            }
        }
    }

    /// Applies `m` to `s`; `log` gets readable lines. Returns the first property the move
    /// broke.
    fn apply(&self, s: &mut Sys, m: Move, mut log: Option<&mut Vec<String>>) -> Option<Bad> {
        let mut bad = None;
        let mut inputs: VecDeque<(usize, u8, bool)> = VecDeque::new();
        let n = self.n();
        // The node an `estop` publication is delivered to by this move.
        let mut told = None;
        match m {
            Move::Press => {
                let (node, input) = self.start;
                inputs.push_back((node, input, true));
                inputs.push_back((node, input, false));
                // At rest: a new cycle. After the last step (with START at any time,
                // pressed before the machine came to rest): a new cycle may begin.
                if s.homing.is_none() && !self.expect.is_empty() {
                    if s.progress == 0 {
                        s.progress = PRESSED;
                    } else if usize::from(s.progress) == self.expect.len() {
                        s.progress += 1;
                    }
                }
            }
            Move::Home => {
                s.homing = Some(true);
                if let Some(node) = self.home {
                    self.call(s, node, Call::Home, &mut inputs, &mut bad, &mut log);
                }
            }
            Move::Arrive(p) | Move::Roll(p, _) => {
                let p = usize::from(p);
                let a = &self.acts[p];
                let end = s.pos[p].finish_travel();
                if let (Some(f), Some(b)) = (&self.feed, s.ball.as_mut()) {
                    if let Move::Roll(_, front) = m {
                        f.rolled(b, front, &mut inputs);
                    } else if end == Some(true) && f.is_pusher(p) {
                        bad = f.pushed(b, &mut inputs);
                    }
                }
                if let Some(pin) = end.and_then(|end| a.cylinder.sensor(end)) {
                    inputs.push_back((a.node, pin, true));
                }
            }
            Move::Fall => {
                if let (Some(f), Some(b)) = (&self.feed, s.ball.as_mut()) {
                    bad = f.fall(b, &s.pos, &mut inputs);
                }
            }
            Move::Expire(node, t) => {
                s.timers[usize::from(node)] &= !(1 << t);
                self.call(
                    s,
                    usize::from(node),
                    Call::Timer(t),
                    &mut inputs,
                    &mut bad,
                    &mut log,
                );
            }
            Move::Deliver(f, t) => {
                let l = usize::from(f) * n + usize::from(t);
                let at = s.flight.partition_point(|e| usize::from(e.0) < l);
                let topic = s.flight.remove(at).1;
                let (f, t) = (usize::from(f), usize::from(t));
                let estop = (self.estop.as_ref())
                    .filter(|e| e.node == f && e.topic == Some(topic))
                    .is_some();
                if let (true, Some(reached)) = (estop, s.estop.as_mut()) {
                    *reached |= 1 << t;
                    told = Some(t);
                }
                let from_addr = self.c.ir.roles[f].address;
                if let Some(peer) = self.tables[t].peers.iter().position(|a| *a == from_addr) {
                    self.call(
                        s,
                        t,
                        Call::Remote(peer as u8, topic),
                        &mut inputs,
                        &mut bad,
                        &mut log,
                    );
                }
            }
            Move::Lose(f, t) => {
                let l = usize::from(f) * n + usize::from(t);
                s.alarms |= 1 << l;
                let f = usize::from(f);
                // As the node: its table's `link_fault` faults it on the alarm.
                if self.tables[f].safety.link_fault {
                    let code = config_schema::alarm::FAULT_LINK;
                    self.call(s, f, Call::Fail(code), &mut inputs, &mut bad, &mut log);
                }
                // Checked against the description: a table that lost it is caught.
                if self.c.ir.roles[f].safety.link_fault && s.nodes[f].fault.is_none() {
                    bad = bad.or(Some((
                        Property::LinkFault,
                        format!(
                            "{}'s link to {} is in alarm and {} still runs (the robot says \
                             on_link_alarm: Fault)",
                            self.c.ir.roles[f].name,
                            self.c.ir.roles[usize::from(t)].name,
                            self.c.ir.roles[f].name
                        ),
                    )));
                }
            }
            Move::EStop => {
                if let Some(e) = &self.estop {
                    s.estop = Some(1 << e.node);
                    inputs.push_back((e.node, e.input, true));
                }
            }
            Move::Motor(i) => {
                let i = usize::from(i);
                if let Some(m) = self.plants.motors.get(i) {
                    let run = m.run(s.nodes[m.node].outputs);
                    let mut rise = Vec::new();
                    m.arrive(&mut s.regions[i], run, &mut rise);
                    inputs.extend(rise);
                }
            }
            Move::Switch(i) => {
                if let Some(&(_, node, input)) = self.plants.switches.get(usize::from(i)) {
                    let set = s.switches & (1 << i) == 0;
                    s.switches ^= 1 << i;
                    if set {
                        s.uncleared = true;
                        s.sets = s.sets.saturating_add(1);
                    }
                    inputs.push_back((node, input, set));
                }
            }
            Move::Button(i) => {
                if let Some(&(_, node, input)) = self.plants.buttons.get(usize::from(i)) {
                    inputs.push_back((node, input, true));
                    inputs.push_back((node, input, false));
                }
            }
            Move::Ack(node) => {
                s.latched &= !(1 << node);
                if s.latched == 0 && s.switches == 0 {
                    s.uncleared = false;
                }
            }
        }
        while let Some((node, input, level)) = inputs.pop_front() {
            self.call(
                s,
                node,
                Call::Input(input, level),
                &mut inputs,
                &mut bad,
                &mut log,
            );
        }
        if bad.is_none() {
            bad = self.check_estop(s, m, told);
        }
        self.rested(s);
        if bad.is_none() {
            bad = self.check_state(s);
        }
        if bad.is_none() {
            bad = self.check_cleared(s);
        }
        bad
    }

    /// A whole cycle done and the machine idle: at rest again, as before the cycle (one
    /// state, not one per cycle done; a START pressed before it came to rest was not
    /// taken).
    fn rested(&self, s: &mut Sys) {
        let done = usize::from(s.progress);
        let whole = s.progress != PRESSED && done != 0 && done >= self.expect.len();
        if s.homing.is_none() && !self.expect.is_empty() && whole && self.idle(s) {
            s.progress = 0;
        }
    }

    /// After a move: while a fault is not cleared (the switch set since the operator last
    /// cleared it), no motor runs clockwise (one that ran must have stopped in the same
    /// move that set the switch).
    fn check_cleared(&self, s: &Sys) -> Option<Bad> {
        if !s.uncleared {
            return None;
        }
        let m = (self.plants.motors.iter())
            .find(|m| m.run(s.nodes[m.node].outputs) == node_fw::sim::Run::Clockwise)?;
        Some((
            Property::FaultClear,
            format!(
                "{} runs clockwise after the fault, before the operator cleared it",
                m.name
            ),
        ))
    }

    /// After a move of the e-stop: its node faulted at once with its `estop` in flight to
    /// every other node (a press), the node it reached faulted (a delivery).
    fn check_estop(&self, s: &Sys, m: Move, told: Option<usize>) -> Option<Bad> {
        let e = self.estop.as_ref()?;
        let faulted: Vec<bool> = s.nodes.iter().map(|x| x.fault.is_some()).collect();
        let why = match (m, told) {
            (Move::EStop, _) => e.after_press(self.c, &faulted, &s.flight),
            (_, Some(t)) if !faulted[t] => Some(format!(
                "{} received the e-stop from {} and did not fault",
                self.c.ir.roles[t].name, self.c.ir.roles[e.node].name
            )),
            _ => None,
        };
        why.map(|w| (Property::EStop, w))
    }

    /// A sorting station's properties in `s`.
    fn check_station(&self, s: &Sys) -> Option<Bad> {
        let (f, b) = (self.feed.as_ref()?, s.ball.as_ref()?);
        let names: Vec<&str> = self.acts.iter().map(|a| a.name.as_str()).collect();
        f.check(b, &s.pos, &names, self.idle(s))
    }

    fn check_state(&self, s: &Sys) -> Option<Bad> {
        for (i, e) in s.nodes.iter().enumerate() {
            if let Some(f) = e.fault {
                if !matches!(f, Fault::Action { .. }) {
                    return Some((
                        Property::EngineFault,
                        format!("role {} faulted: {f:?}", self.c.ir.roles[i].name),
                    ));
                }
            }
        }
        for il in &self.interlocks {
            let read = |a: Atom| match a {
                Atom::Position { plant, mask: m } => s.pos[plant].mask() & m != 0,
                Atom::Chart { role, chart, state } => {
                    usize::from(s.nodes[role].current[chart]) == state
                }
                Atom::Fault { role } => s.nodes[role].fault.is_some(),
                Atom::Const(v) => v,
            };
            if il.holds(&read) {
                return Some((Property::Interlock, format!("never: \"{}\" holds", il.text)));
            }
        }
        let over = s
            .flight
            .windows(LINK_BOUND + 1)
            .find(|w| w[0].0 == w[LINK_BOUND].0);
        if let Some(l) = over.map(|w| usize::from(w[0].0)) {
            let n = self.n();
            return Some((
                Property::LinkBound,
                format!(
                    "more than {LINK_BOUND} publications in flight from {} to {}",
                    self.c.ir.roles[l / n].name,
                    self.c.ir.roles[l % n].name
                ),
            ));
        }
        if let Some(bad) = self.check_station(s) {
            return Some(bad);
        }
        let (steps, done) = (self.expect.len(), usize::from(s.progress));
        if s.homing.is_none() && steps != 0 && done != 0 && done < steps && self.idle(s)
            || s.progress == PRESSED && self.idle(s)
        {
            let message = match s.progress {
                PRESSED => format!(
                    "START pressed at rest and the machine is idle again without a step (the \
                     declared sequence has {steps})"
                ),
                _ => format!("the machine is idle after {done} of the {steps} declared steps"),
            };
            return Some((Property::Sequence, message));
        }
        None
    }

    fn call(
        &self,
        s: &mut Sys,
        node: usize,
        what: Call,
        inputs: &mut VecDeque<(usize, u8, bool)>,
        bad: &mut Option<Bad>,
        log: &mut Option<&mut Vec<String>>,
    ) {
        let table = &self.tables[node];
        let role = &self.c.ir.roles[node];
        let before = s.nodes[node].outputs;
        let mut e = Engine::resume_indexed(table, &self.indexes[node], &s.nodes[node]);
        let mut fx = EffectLog::default();
        if let Some(log) = log.as_deref_mut() {
            log.push(format!(
                "   {}: {}",
                role.name,
                self.describe_call(node, what)
            ));
        }
        match what {
            Call::Input(i, level) => e.input(i, level, &mut fx),
            Call::Timer(t) => e.timer_expired(t, &mut fx),
            Call::Remote(p, topic) => {
                e.remote(p, topic, &mut fx);
            }
            Call::Home => {
                e.home(&mut fx);
            }
            Call::Fail(code) => e.fail(code, &mut fx),
        }
        s.nodes[node] = e.snapshot();
        let faulted = s.nodes[node].fault.is_some();
        self.drive_motors(s, node, before, inputs, log);
        let n = self.n();
        let cylinders: Vec<(usize, Cylinder)> = (self.acts.iter().enumerate())
            .filter(|(_, a)| a.node == node)
            .map(|(p, a)| (p, a.cylinder))
            .collect();
        let outputs = fx.0.iter().filter_map(|f| match *f {
            Effect::Output(o, level) => Some((o, level)),
            _ => None,
        });
        let valves = cylinder::commands(&cylinders, outputs);
        for f in &fx.0 {
            if let Some(log) = log.as_deref_mut() {
                if let Some(line) = self.describe_effect(node, f) {
                    log.push(format!("      {line}"));
                }
            }
            match *f {
                Effect::Publish(p) => {
                    for (i, to) in self.peers[node].iter().enumerate().take(8) {
                        if p.subscribers & (1 << i) != 0 {
                            if let Some(to) = to {
                                let l = (node * n + to) as u8;
                                let at = s.flight.partition_point(|e| e.0 <= l);
                                s.flight.insert(at, (l, p.topic));
                            }
                        }
                    }
                }
                Effect::Start(t) => s.timers[node] |= 1 << t,
                Effect::Cancel(t) => s.timers[node] &= !(1 << t),
                Effect::Fired(chart, _, to) => {
                    if let (Some(f), Some(b)) = (&self.feed, s.ball.as_mut()) {
                        f.fired(node, chart, to, b);
                    }
                }
                Effect::Output(..) | Effect::Fault(_) | Effect::Ignored(..) => {}
            }
        }
        for (p, command) in valves {
            let extend = match command {
                Command::Conflict => {
                    if bad.is_none() && !faulted {
                        *bad = Some((
                            Property::DoubleActuation,
                            format!("{}: both solenoids energised at once", self.acts[p].name),
                        ));
                    }
                    continue;
                }
                Command::Drive(extend) => extend,
            };
            self.command(s, p, extend, faulted, inputs, bad, log);
        }
    }

    /// After an engine call on `node` (outputs `before` it): each motor it drives starts
    /// as its outputs now run it (a carriage leaves its end at once), and a fault alarm of
    /// the node latches while its cause holds.
    fn drive_motors(
        &self,
        s: &mut Sys,
        node: usize,
        before: u16,
        inputs: &mut VecDeque<(usize, u8, bool)>,
        log: &mut Option<&mut Vec<String>>,
    ) {
        if self.alarm_cause(s, node) && self.plants.any() {
            s.latched |= 1 << node;
        }
        let now = s.nodes[node].outputs;
        for (i, m) in self.plants.motors.iter().enumerate() {
            if m.node != node {
                continue;
            }
            let (was, run) = (m.run(before), m.run(now));
            if was == run {
                continue;
            }
            if let Some(log) = log.as_deref_mut() {
                log.push(format!("      {}: {run:?}", m.name));
            }
            let mut leave = Vec::new();
            m.start(&mut s.regions[i], run, &mut leave);
            inputs.extend(leave);
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn command(
        &self,
        s: &mut Sys,
        p: usize,
        extend: bool,
        safe: bool,
        inputs: &mut VecDeque<(usize, u8, bool)>,
        bad: &mut Option<Bad>,
        log: &mut Option<&mut Vec<String>>,
    ) {
        let a = &self.acts[p];
        let step = Step {
            actuator: a.name.clone(),
            extend,
        };
        let before = s.pos[p];
        let leaves = match s.pos[p].command(extend) {
            Motion::Nothing => return,
            Motion::Left { from_end } => a.cylinder.sensor(from_end),
            Motion::Reversed => None,
        };
        if let Some(log) = log.as_deref_mut() {
            log.push(format!(
                "      {step}: {} starts {}{}",
                a.name,
                if extend { "extending" } else { "retracting" },
                if safe { " (safe state)" } else { "" }
            ));
        }
        if let Some(pin) = leaves {
            inputs.push_back((a.node, pin, false));
        }
        if safe || bad.is_some() {
            return;
        }
        if s.estop.is_some_and(|reached| reached & (1 << a.node) != 0) {
            *bad = Some((
                Property::EStop,
                format!(
                    "{step} commanded by {} after the e-stop reached it",
                    self.c.ir.roles[a.node].name
                ),
            ));
            return;
        }
        // A monostable valve just follows its level: a sensorless actuator may reverse.
        if a.cylinder.double() && before.moving() {
            *bad = Some((
                Property::DoubleActuation,
                format!(
                    "{step} commanded while {} is still {}",
                    a.name,
                    before.name()
                ),
            ));
            return;
        }
        if let Some(given) = s.homing {
            *bad = self.homing_step(s, &step, given);
            return;
        }
        if self.expect.is_empty() {
            return;
        }
        let k = match usize::from(s.progress) {
            _ if s.progress == PRESSED => 0,
            k if k == self.expect.len() + 1 => 0,
            k => k,
        };
        let Some(expected) = self.expect.get(k) else {
            *bad = Some((
                Property::Sequence,
                format!(
                    "step {} of the cycle is {step}, after the {k} declared steps (START was \
                     not pressed again)",
                    k + 1
                ),
            ));
            return;
        };
        if *expected != step {
            *bad = Some((
                Property::Sequence,
                format!(
                    "step {} of the cycle is {step}, the declared sequence says {expected}",
                    k + 1,
                ),
            ));
            return;
        }
        s.progress = (k + 1) as u16;
    }

    fn event_name(&self, node: usize, e: u8) -> String {
        self.c.ir.roles[node]
            .events
            .get(usize::from(e))
            .cloned()
            .unwrap_or_else(|| format!("event #{e}"))
    }

    fn topic_name(&self, from: usize, topic: Topic) -> String {
        self.tables[from]
            .publications
            .iter()
            .find(|p| p.topic == topic)
            .map_or(format!("topic #{topic}"), |p| {
                self.event_name(from, p.event)
            })
    }

    fn describe_call(&self, node: usize, what: Call) -> String {
        let r = &self.c.ir.roles[node];
        match what {
            Call::Input(i, level) => format!(
                "input {} {}",
                r.inputs
                    .get(usize::from(i))
                    .map_or("?", |x| x.name.as_str()),
                if level { "rises" } else { "falls" }
            ),
            Call::Timer(t) => format!(
                "timer {} expires",
                r.timers
                    .get(usize::from(t))
                    .map_or("?", |x| x.name.as_str())
            ),
            Call::Remote(p, topic) => {
                let from = self.peers[node].get(usize::from(p)).copied().flatten();
                match from {
                    Some(f) => format!(
                        "receives {} from {}",
                        self.topic_name(f, topic),
                        self.c.ir.roles[f].name
                    ),
                    None => format!("receives topic #{topic}"),
                }
            }
            Call::Home => String::from("HOME command"),
            Call::Fail(_) => String::from("link alarm: faults (on_link_alarm: Fault)"),
        }
    }

    /// Homing: the check of a motion `step` (`given`: after the HOME command).
    fn homing_step(&self, s: &mut Sys, step: &Step, given: bool) -> Option<Bad> {
        if !given {
            return Some((
                Property::UnhomedStart,
                format!("{step} before HOME: the machine moved while not homed"),
            ));
        }
        let homing = &self.c.ir.homing;
        let k = usize::from(s.progress).min(homing.len());
        match homing[k..].iter().position(|h| h == step) {
            Some(j) => {
                s.progress = (k + j + 1) as u16;
                None
            }
            None => {
                let left: Vec<String> = homing[k..].iter().map(Step::to_string).collect();
                Some((
                    Property::Homing,
                    format!(
                        "{step} moved, but the homing steps left are \"{}\"",
                        left.join(" ")
                    ),
                ))
            }
        }
    }

    fn describe_effect(&self, node: usize, f: &Effect) -> Option<String> {
        let r = &self.c.ir.roles[node];
        Some(match *f {
            Effect::Output(o, level) => format!(
                "output {} = {}",
                r.outputs
                    .get(usize::from(o))
                    .map_or("?", |x| x.name.as_str()),
                u8::from(level)
            ),
            Effect::Publish(p) => {
                let to: Vec<&str> = self.peers[node]
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| p.subscribers & (1 << i) != 0)
                    .filter_map(|(_, t)| t.map(|t| self.c.ir.roles[t].name.as_str()))
                    .collect();
                format!(
                    "publishes {} to {}",
                    self.event_name(node, p.event),
                    to.join(", ")
                )
            }
            Effect::Start(t) => format!(
                "starts timer {}",
                r.timers
                    .get(usize::from(t))
                    .map_or("?", |x| x.name.as_str())
            ),
            Effect::Cancel(_) => return None,
            Effect::Fault(fault) => format!("FAULT {fault:?}: outputs safe"),
            Effect::Fired(chart, from, to) => {
                let c = r.charts.get(usize::from(chart))?;
                let st = |i: u8| {
                    c.states
                        .get(usize::from(i))
                        .map_or("?", |s| s.name.as_str())
                };
                format!("chart {}: {} -> {}", c.name, st(from), st(to))
            }
            Effect::Ignored(chart, input) => {
                let c = r.charts.get(usize::from(chart))?;
                format!(
                    "chart {} ignores {} (no transition takes it here)",
                    c.name,
                    c.inputs.get(usize::from(input)).map_or("?", |x| x.as_str())
                )
            }
        })
    }

    fn describe_move(&self, s: &Sys, m: Move) -> String {
        let role = |i: u8| self.c.ir.roles[usize::from(i)].name.as_str();
        match m {
            Move::Press => format!("operator presses START (at {})", role(self.start.0 as u8)),
            Move::Home => format!(
                "operator gives the HOME command (at {})",
                self.home.map_or("?", |r| self.c.ir.roles[r].name.as_str())
            ),
            Move::Arrive(p) => {
                let a = &self.acts[usize::from(p)];
                let end = s.pos[usize::from(p)] == Place::Rod(Pos::Extending);
                match (a.cylinder.double(), end) {
                    (true, true) => format!("{} reaches its end switch", a.name),
                    (true, false) => format!("{} reaches its home switch", a.name),
                    (false, true) => format!("{} is fully out (no switch)", a.name),
                    (false, false) => format!("{} is fully back (no switch)", a.name),
                }
            }
            Move::Expire(node, t) => format!(
                "timer {} of {} expires",
                self.c.ir.roles[usize::from(node)]
                    .timers
                    .get(usize::from(t))
                    .map_or("?", |x| x.name.as_str()),
                role(node)
            ),
            Move::Deliver(f, t) => format!("radio delivers {} -> {}", role(f), role(t)),
            Move::Lose(f, t) => format!(
                "radio link {} -> {} gives up after its retries: link alarm at {}",
                role(f),
                role(t),
                role(f)
            ),
            Move::Roll(p, front) => {
                let next = match (&self.feed, &s.ball, front) {
                    (Some(f), Some(b), feed::Front::Ball(c)) => {
                        format!(
                            "ball {} ({}) rolls to the sensors",
                            b.count + 1,
                            f.colour_name(c)
                        )
                    }
                    _ => String::from("the magazine is empty"),
                };
                format!(
                    "{} reaches its home switch; {next}",
                    self.acts[usize::from(p)].name
                )
            }
            Move::Fall => match (&self.feed, &s.ball) {
                (Some(f), Some(b)) => {
                    let names: Vec<&str> = self.acts.iter().map(|a| a.name.as_str()).collect();
                    f.describe_fall(b, &s.pos, &names)
                }
                _ => String::from("the ball falls"),
            },
            Move::EStop => format!(
                "operator presses the e-stop (at {})",
                self.estop
                    .as_ref()
                    .map_or_else(String::new, |e| e.name(self.c))
            ),
            Move::Motor(i) => match self.plants.motors.get(usize::from(i)) {
                Some(m) => {
                    let run = m.run(s.nodes[m.node].outputs);
                    let to = match run {
                        node_fw::sim::Run::Clockwise => "end",
                        _ => "home",
                    };
                    let with = match m.driven.is_empty() {
                        true => String::new(),
                        false => format!(" (with {})", m.driven.join(", ")),
                    };
                    format!("{}{with} reaches its {to} sensor", m.name)
                }
                None => String::from("a motor arrives"),
            },
            Move::Switch(i) => {
                let name = (self.plants.switches.get(usize::from(i))).map_or("?", |w| &w.0);
                match s.switches & (1 << i) == 0 {
                    true => format!("switch {name} is set"),
                    false => format!("switch {name} is released"),
                }
            }
            Move::Button(i) => format!(
                "operator presses {}",
                (self.plants.buttons.get(usize::from(i))).map_or("?", |b| &b.0)
            ),
            Move::Ack(node) => format!("operator acknowledges the alarms of {}", role(node)),
        }
    }

    /// A readable summary of a state: charts, positions, in flight, timers.
    fn describe_state(&self, s: &Sys) -> String {
        let mut parts = Vec::new();
        for (i, e) in s.nodes.iter().enumerate() {
            let r = &self.c.ir.roles[i];
            let charts: Vec<String> = r
                .charts
                .iter()
                .enumerate()
                .map(|(ci, c)| {
                    let st = c
                        .states
                        .get(usize::from(e.current[ci]))
                        .map_or("?", |x| x.name.as_str());
                    format!("{}={st}", c.name)
                })
                .collect();
            let fault = e.fault.map(|f| format!(" FAULT {f:?}")).unwrap_or_default();
            parts.push(format!("{}[{}]{fault}", r.name, charts.join(" ")));
        }
        let pos: Vec<String> = self
            .acts
            .iter()
            .zip(&s.pos)
            .map(|(a, p)| format!("{} {}", a.name, p.name()))
            .collect();
        let n = self.n();
        let mut links: Vec<(usize, Vec<Topic>)> = Vec::new();
        for &(l, t) in &s.flight {
            match links.last_mut() {
                Some((k, q)) if *k == usize::from(l) => q.push(t),
                _ => links.push((usize::from(l), vec![t])),
            }
        }
        let flight: Vec<String> = links
            .iter()
            .map(|(l, q)| {
                let l = *l;
                let names: Vec<String> = q.iter().map(|t| self.topic_name(l / n, *t)).collect();
                format!(
                    "{}->{}: {}",
                    self.c.ir.roles[l / n].name,
                    self.c.ir.roles[l % n].name,
                    names.join(", ")
                )
            })
            .collect();
        let mut balls = match (&self.feed, &s.ball) {
            (Some(f), Some(b)) => format!("; balls: {}", f.describe_state(b)),
            _ => String::new(),
        };
        if self.plants.any() {
            let motors: Vec<String> = (self.plants.motors.iter().zip(&s.regions))
                .map(|(m, r)| format!("{} {}", m.name, r.name()))
                .collect();
            let switches: Vec<&str> = (self.plants.switches.iter().enumerate())
                .filter(|(i, _)| s.switches & (1 << i) != 0)
                .map(|(_, w)| w.0.as_str())
                .collect();
            let latched: Vec<&str> = (0..self.n())
                .filter(|i| s.latched & (1 << i) != 0)
                .map(|i| self.c.ir.roles[i].name.as_str())
                .collect();
            let list = |v: &[&str]| match v.is_empty() {
                true => String::from("none"),
                false => v.join(", "),
            };
            balls += &format!(
                "; motors {}; set: {}; alarms latched: {}",
                motors.join(", "),
                list(&switches),
                list(&latched)
            );
        }
        format!(
            "charts {}; actuators {}; in flight: {}{balls}",
            parts.join(" "),
            pos.join(", "),
            if flight.is_empty() {
                String::from("none")
            } else {
                flight.join("; ")
            }
        )
    }

    /// The numbered, readable trace of `moves` from `root`.
    fn replay(&self, root: &Sys, moves: &[Move]) -> Vec<String> {
        let mut s = root.clone();
        let mut out = Vec::new();
        for (i, m) in moves.iter().enumerate() {
            let mut log = Vec::new();
            let what = self.describe_move(&s, *m);
            self.apply(&mut s, *m, Some(&mut log));
            out.push(format!("{:>3}. {what}", i + 1));
            out.extend(log);
        }
        out.push(format!("     state: {}", self.describe_state(&s)));
        out
    }
}

#[derive(Debug, Clone, Copy)]
enum Call {
    Input(u8, bool),
    Timer(u8),
    Remote(u8, Topic),
    Home,
    /// The node faults with this code (a link alarm under `on_link_alarm: Fault`).
    Fail(u8),
}

/// Explores every reachable state of `c` and checks the properties.
pub fn verify(c: &Compiled, opts: ExploreOptions) -> Result<Report, ModelError> {
    let model = Model::new(c)?;
    Ok(explore(&model, opts))
}

/// [`verify`] on a built model.
pub fn explore(model: &Model<'_>, opts: ExploreOptions) -> Report {
    let mut r = run(model, model.roots(), opts);
    r.feed = model.feed();
    r.estop = model.estop();
    r.plants = model.plants(opts.faults);
    r.functions = model.c.robot.functions.len();
    r.sequence = !model.expect.is_empty();
    r
}

/// Explores every state reachable from `roots` (each with the start positions a
/// counterexample names) and checks the properties.
fn run(
    model: &Model<'_>,
    roots: impl IntoIterator<Item = (Sys, Option<String>)>,
    opts: ExploreOptions,
) -> Report {
    let t0 = Instant::now();
    let mut search = Search::bfs(model, roots, opts);
    let states = search.seen.len();
    // Each state unpacked into one buffer (one that does not unpack, which only a bug in
    // `packed` makes, is neither).
    let mut s = Sys::default();
    let (idle_flags, stopped_flags): (Vec<bool>, Vec<bool>) = (0..states)
        .map(|i| match search.state_into(i, &mut s) {
            true => (model.idle(&s), model.stopped(&s)),
            false => (false, false),
        })
        .unzip();
    if search.violation.is_none() && !search.incomplete {
        search.violation = search.deadlock(model, &idle_flags, &stopped_flags);
    }
    if search.violation.is_none() && !search.incomplete {
        search.violation = search.fault_stop(model);
    }
    let growing = if search.incomplete {
        search.growing(model)
    } else {
        Vec::new()
    };
    Report {
        growing,
        states,
        transitions: search.edges.len(),
        packed_bytes: search.seen.iter().map(|key| key.len()).sum(),
        idle: idle_flags.iter().filter(|b| **b).count(),
        stopped: stopped_flags.iter().filter(|b| **b).count(),
        elapsed: t0.elapsed(),
        violation: search.violation,
        incomplete: search.incomplete,
        lossy: opts.lossy,
        prompt: opts.prompt,
        feed: None,
        estop: None,
        plants: None,
        functions: 0,
        sequence: false,
    }
}

/// The explored state graph.
struct Search {
    /// Every state found, packed ([`packed`]: equal states, equal bytes), in breadth-first
    /// order; the index is the state's number.
    // FxHash: fast and not keyed; the states are our own, no hash flooding to fear.
    seen: IndexSet<Box<[u8]>, FxBuildHasher>,
    /// The initial states are the first `labels.len()`, each with the start positions a
    /// counterexample from it names (none for the cycle's one).
    labels: Vec<Option<String>>,
    /// Parent index and move of each state (the initial states' own entries are unused).
    parent: Vec<(u32, Move)>,
    /// Every transition (from, to).
    edges: Vec<(u32, u32)>,
    /// Bit per state expanded: nothing of the machine itself can happen next (no
    /// arrival, timer, delivery, loss, motor, ball), only what the operator or a fault
    /// contact does.
    settled: Vec<bool>,
    violation: Option<Violation>,
    /// Stopped at `max_states`.
    incomplete: bool,
}

impl Search {
    /// Breadth-first from the initial states, up to the first move that breaks a property
    /// checked on a transition or state.
    fn bfs(
        model: &Model<'_>,
        roots: impl IntoIterator<Item = (Sys, Option<String>)>,
        opts: ExploreOptions,
    ) -> Search {
        let mut g = Search {
            seen: IndexSet::default(),
            labels: Vec::new(),
            parent: Vec::new(),
            edges: Vec::new(),
            settled: Vec::new(),
            violation: None,
            incomplete: false,
        };
        let mut key = Vec::new();
        for (root, label) in roots {
            // The initial states count towards `max_states` too (homing has one per start
            // position and held valve level): past it, the check below stops the search.
            if g.seen.len() >= opts.max_states {
                break;
            }
            let bad = model.check_state(&root);
            if g.insert(&root, &mut key).1 {
                g.labels.push(label);
                g.parent.push((0, Move::Press));
                if let Some((property, message)) = bad {
                    let i = g.labels.len() - 1;
                    g.violation = Some(g.violation(model, property, message, i, &[]));
                    return g;
                }
            }
        }
        // The initial states alone may come to `max_states` (or stopped at it).
        if g.seen.len() >= opts.max_states {
            g.incomplete = true;
            return g;
        }
        let mut moves = Vec::new();
        let mut next = 0usize;
        // The state expanded and its successor, unpacked into and copied into the same
        // lists every time.
        let (mut s, mut t) = (Sys::default(), Sys::default());
        'bfs: while next < g.seen.len() {
            if !g.state_into(next, &mut s) {
                s.clone_from(&model.init);
            }
            model.moves(&s, opts, &mut moves);
            g.settled.push(!moves.iter().any(|m| m.by_the_machine()));
            for &m in &moves {
                t.clone_from(&s);
                if let Some((property, message)) = model.apply(&mut t, m, None) {
                    let (root, mut p) = g.path(next);
                    p.push(m);
                    g.violation = Some(g.violation(model, property, message, root, &p));
                    break 'bfs;
                }
                let (j, new) = g.insert(&t, &mut key);
                if new {
                    g.parent.push((next as u32, m));
                    if g.seen.len() >= opts.max_states {
                        g.incomplete = true;
                        break 'bfs;
                    }
                }
                g.edges.push((next as u32, j as u32));
            }
            next += 1;
        }
        g
    }

    /// Adds state `s` (packed in `key`, a buffer kept between calls) unless it was found
    /// already: its number, and whether it is new.
    fn insert(&mut self, s: &Sys, key: &mut Vec<u8>) -> (usize, bool) {
        packed::pack(s, key);
        match self.seen.get_index_of(key.as_slice()) {
            Some(j) => (j, false),
            None => self.seen.insert_full(key.as_slice().into()),
        }
    }

    /// State number `i`.
    fn state(&self, i: usize) -> Option<Sys> {
        let mut s = Sys::default();
        self.state_into(i, &mut s).then_some(s)
    }

    /// State number `i`, unpacked into `s` (its lists reused); false if there is none.
    fn state_into(&self, i: usize, s: &mut Sys) -> bool {
        (self.seen.get_index(i)).is_some_and(|b| packed::unpack_into(b, s).is_some())
    }

    /// The initial state state `i` was reached from, and the moves from it.
    fn path(&self, mut i: usize) -> (usize, Vec<Move>) {
        let mut moves = Vec::new();
        while i >= self.labels.len() {
            moves.push(self.parent[i].1);
            i = self.parent[i].0 as usize;
        }
        moves.reverse();
        (i, moves)
    }

    /// The counterexample `moves` from initial state `root`.
    fn violation(
        &self,
        model: &Model<'_>,
        property: Property,
        message: String,
        root: usize,
        moves: &[Move],
    ) -> Violation {
        let (init, label) = (self.state(root))
            .zip(self.labels.get(root))
            .map_or((model.init.clone(), None), |(s, l)| (s, l.clone()));
        Violation {
            property,
            message,
            steps: moves.len(),
            trace: model.replay(&init, moves),
            start: label,
        }
    }

    /// Deadlock freedom: a state that is not stopped and cannot get back to idle
    /// (backward reachability of idle over the reverse edges).
    fn deadlock(
        &self,
        model: &Model<'_>,
        idle_flags: &[bool],
        stopped_flags: &[bool],
    ) -> Option<Violation> {
        let states = self.seen.len();
        let edges = &self.edges;
        let mut start = vec![0u32; states + 1];
        for &(_, to) in edges {
            start[to as usize + 1] += 1;
        }
        for i in 0..states {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut rev = vec![0u32; edges.len()];
        for &(from, to) in edges {
            rev[fill[to as usize] as usize] = from;
            fill[to as usize] += 1;
        }
        let mut good = idle_flags.to_vec();
        let mut queue: VecDeque<usize> = (0..states).filter(|&i| good[i]).collect();
        while let Some(i) = queue.pop_front() {
            for &f in &rev[start[i] as usize..start[i + 1] as usize] {
                if !good[f as usize] {
                    good[f as usize] = true;
                    queue.push_back(f as usize);
                }
            }
        }
        let doomed = |i: usize| !good[i] && !stopped_flags[i];
        let first = (0..states).find(|&i| doomed(i))?;
        let homing = self.state(first).is_some_and(|s| s.homing.is_some());
        // Homing starts are often doomed from the start: show where homing gets stuck, the
        // first state after which nothing or only a stop (fault, link alarm) can happen.
        let mut dead_end = vec![true; states];
        for &(f, t) in edges {
            if !stopped_flags[t as usize] {
                dead_end[f as usize] = false;
            }
        }
        let bad = match homing {
            true => (0..states)
                .find(|&i| doomed(i) && dead_end[i])
                .unwrap_or(first),
            false => first,
        };
        let stuck = edges.iter().all(|&(f, _)| f as usize != bad);
        let (root, path) = self.path(bad);
        let message = match (stuck, homing, dead_end[bad]) {
            (true, false, _) => {
                "the machine stops here: nothing can happen any more, and it is not idle"
            }
            (false, false, _) => {
                "from here the machine can never get back to idle (only to faults or other \
                 states that cannot)"
            }
            (true, true, _) => {
                "homing stops here: nothing can happen any more, and the machine is not idle"
            }
            (false, true, true) => {
                "homing is stuck here: only a fault or a link alarm can happen next, and the \
                 machine is not idle"
            }
            (false, true, false) => {
                "from here homing can never reach the idle state (only faults or other states \
                 that cannot)"
            }
        };
        Some(self.violation(model, Property::Deadlock, message.into(), root, &path))
    }

    /// Stop at once: in every state where nothing more of the machine itself can happen
    /// (whatever the operator may still press: START with `--start-anytime`, an e-stop,
    /// a button, which are offered in every state), a fault that was published has
    /// stopped every node that listens for it.
    fn fault_stop(&self, model: &Model<'_>) -> Option<Violation> {
        let (i, message) = (0..self.seen.len()).find_map(|i| {
            (self.settled.get(i) == Some(&true))
                .then(|| model.unstopped(&self.state(i)?))
                .flatten()
                .map(|m| (i, m))
        })?;
        let (root, p) = self.path(i);
        Some(self.violation(model, Property::FaultStop, message, root, &p))
    }

    /// Variables of the last state explored far from their initial values.
    fn growing(&self, model: &Model<'_>) -> Vec<String> {
        let mut growing = Vec::new();
        let Some(last) = self.seen.len().checked_sub(1).and_then(|i| self.state(i)) else {
            return growing;
        };
        for (i, (e, init)) in last.nodes.iter().zip(&model.init.nodes).enumerate() {
            let role = &model.c.ir.roles[i];
            for (v, (name, _)) in role.vars.iter().enumerate() {
                if (i64::from(e.vars[v]) - i64::from(init.vars[v])).abs() > 100 {
                    growing.push(format!("{}.{name} = {}", role.name, e.vars[v]));
                }
            }
        }
        growing
    }
}
