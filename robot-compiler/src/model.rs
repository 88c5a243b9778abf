//! The RON robot description, as serde types. `docs/robot-format.md` documents it.

use std::collections::BTreeMap;

use config_schema::Level;
use serde::Deserialize;

use crate::diag::Diagnostic;
use crate::source::Source;

/// A whole machine: network, nodes, roles and their behaviour.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Robot {
    pub name: String,
    /// Deployment generation written into every blob.
    #[serde(default)]
    pub generation: u32,
    pub network: Network,
    pub nodes: Vec<Node>,
    pub roles: Vec<Role>,
    /// Which node plays which role: `(ROLE, NODE)` pairs. Moving a role to a spare node is
    /// a one-line edit here. A robot with an `application` gets its resources' pairs from
    /// the application's mapping.
    #[serde(default)]
    pub assign: Vec<(String, String)>,
    /// The input (`NAME` or `ROLE/NAME`) whose rising edge starts a cycle.
    #[serde(default)]
    pub start: Option<String>,
    /// The input (`NAME` or `ROLE/NAME`) whose rising edge starts homing, besides the
    /// `config-tool home` command (sequence robots).
    #[serde(default)]
    pub home: Option<String>,
    /// The homing sequence of a sequence robot, as steps `A- B- ...`, run in that order
    /// after a boot, a reset or an activation of a stopped machine; a step whose switch
    /// already reads its target is skipped. Derived from the actuators and the
    /// interlocks when absent (docs/reconfiguration.md).
    #[serde(default)]
    pub homing: Option<String>,
    /// A cycle as steps `A+ B- ...`: the charts are synthesised from it.
    #[serde(default)]
    pub sequence: Option<String>,
    /// Synthesised charts fault when a motion does not complete within this time.
    #[serde(default = "default_timeout")]
    pub motion_timeout_ms: u32,
    /// Explicit chart types, instantiated by the roles' `charts`.
    #[serde(default)]
    pub chart_types: Vec<ChartType>,
    /// Basic FB types in IEC 61499-2 XML (`.fbt`), relative to the robot file: each becomes
    /// a chart type of its `Name`, instantiated like those of `chart_types`
    /// (docs/iec61499-xml.md).
    #[serde(default)]
    pub fb_types: Vec<String>,
    /// An IEC 61499 application (`.sys`): its resources become roles, its devices nodes,
    /// its FB instances charts (docs/iec61499-xml.md, "How to bring a 4diac project").
    #[serde(default)]
    pub application: Option<ApplicationDecl>,
    /// For explicit charts: the actuator sequence one cycle must produce (checked by `sim`).
    #[serde(default)]
    pub expect: Option<String>,
    /// Interlocks `verify` proves: conditions over actuator positions and chart states
    /// that must never hold, e.g. `"HC.moving && !VC.home"`.
    #[serde(default)]
    pub never: Vec<String>,
    /// The charts rely on the radio delivering every publication before the next motion
    /// completes or timer expires (the paper's position-event charts do: each subscriber
    /// counts events that several nodes see). `verify` then explores with that assumption
    /// and says so; `verify --any-delay` drops it (and shows the races it hides).
    #[serde(default)]
    pub assume_prompt_radio: bool,
    /// IEEE 802.15.4 frame security of the machine's radio (docs/security.md): `On` (the
    /// default) unless the robot says `security: Off`, which `check` warns about.
    #[serde(default)]
    pub security: Security,
    /// How long a `push --trial` is watched, seconds: a fault during it, or no `confirm`
    /// by its end, returns every node to the previous generation (docs/reconfiguration.md).
    #[serde(default)]
    pub trial_seconds: Option<u32>,
    /// How many cycles of the machine a `push --trial` is watched (with `trial_seconds`:
    /// whichever ends first).
    #[serde(default)]
    pub trial_cycles: Option<u32>,
    /// The colours (part types) the machine's sensors can tell apart; an automaton without
    /// its own `colours` uses these (docs/selecting-automata.md).
    #[serde(default)]
    pub colours: Vec<String>,
    /// Selecting automata (docs/selecting-automata.md): each picks sequences of colours
    /// out of a stream of parts.
    #[serde(default)]
    pub automata: Vec<AutomatonDecl>,
    /// Control functions (docs/petri-nets.md): state-machine Petri nets placed on roles,
    /// as places and transitions or as their incidence matrix.
    #[serde(default)]
    pub functions: Vec<crate::petri::model::FunctionDecl>,
    /// A sorting station's sensing side (docs/selecting-automata.md, "The station"): the
    /// colour sensors' truth table, compiled into a classification chart, and the feed
    /// `sim` runs.
    #[serde(default)]
    pub sorting: Option<crate::sorting::Sorting>,
    /// Plant models for `sim` beyond the actuators (a motor with a continuous position,
    /// what it moves, maintained contacts, buttons), wired to role pins by name.
    #[serde(default)]
    pub plants: Vec<crate::plants::PlantDecl>,
    /// Alarms the operator acknowledges (docs/robot-format.md, "Alarms and stops"):
    /// raised when a condition over inputs and places becomes true.
    #[serde(default)]
    pub alarms: Vec<crate::alarms::AlarmDeclRon>,
    /// Inputs (`NAME` or `ROLE/NAME`) that restart the machine besides START: refused
    /// while a fault alarm is latched on their node.
    #[serde(default)]
    pub restart: Vec<String>,
    /// What a link alarm does: `Stall` (default: the node keeps retrying) or `Fault`.
    #[serde(default)]
    pub on_link_alarm: crate::alarms::LinkAlarmPolicy,
    /// Chart variables holding a control function's place, for the robot's conditions
    /// naming its places (`F.P`) where the function is a chart: no robot file writes
    /// them, an application brings them (docs/iec61499-xml.md, "Importing it back").
    #[serde(skip)]
    pub places: Vec<PlacesVar>,
}

/// A chart variable of a role holding function `function`'s place, by its column in
/// `places`: `F.P` on that role reads `var == column of P`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlacesVar {
    pub role: String,
    pub function: String,
    pub places: Vec<String>,
    /// The role's variable (`CHART.VAR`).
    pub var: String,
}

impl PlacesVar {
    /// The (variable, column) `name` (`F.P`) reads on role `role`, among `vars`.
    pub fn read<'a>(vars: &'a [PlacesVar], role: &str, name: &str) -> Option<(&'a str, usize)> {
        let (f, p) = name.split_once('.')?;
        vars.iter()
            .filter(|v| v.role == role && v.function == f)
            .find_map(|v| Some((v.var.as_str(), v.places.iter().position(|x| x == p)?)))
    }
}

/// The path in the robot file of its application's file name: where what the
/// application brings is reported (its XML errors, its charts' problems, its types).
pub const APPLICATION_FILE: &str = "application.file";

/// An IEC 61499 application brought into the robot: the `.sys` file (relative to the
/// robot file) and what the XML cannot say: which plant events feed FB event inputs and
/// which FB output events drive the plant.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ApplicationDecl {
    pub file: String,
    /// `"FB.EVENT": "EVENT"` (of the FB's role) or `"ROLE/EVENT"`: an event input fed by
    /// an input, a switch or a chart output, as a chart instance's `on`.
    #[serde(default)]
    pub on: BTreeMap<String, String>,
    /// `"FB.EVENT": Extend("VC")`: what an output event of an FB does instead of being
    /// an event (`Extend`, `Retract`, `Out` or `Fault`).
    #[serde(default)]
    pub actions: BTreeMap<String, ActionDecl>,
}

/// A selecting automaton as written: either `states` / `initial` / `transitions`, or the
/// paper's Prolog facts inline (`facts`) or in a file next to the robot (`facts_file`).
/// `crate::automata::load` resolves it into a [`crate::automata::Automaton`].
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AutomatonDecl {
    pub name: String,
    /// The colours it reads (default: the robot's `colours`, else those its transitions
    /// name, in order of appearance).
    #[serde(default)]
    pub colours: Option<Vec<String>>,
    #[serde(default)]
    pub states: Vec<String>,
    /// Initial states: one for a deterministic automaton, any number otherwise.
    #[serde(default)]
    pub initial: Vec<String>,
    #[serde(default)]
    pub transitions: Vec<AutomatonTransitionDecl>,
    /// The paper's facts: `state/1`, `transition/6`, `initial_state/1`.
    #[serde(default)]
    pub facts: Option<String>,
    /// A file of such facts, relative to the robot file.
    #[serde(default)]
    pub facts_file: Option<String>,
    /// Firing order of transitions that conflict (the paper's priority chains): ids, the
    /// first fires first.
    #[serde(default)]
    pub priority: Vec<String>,
    /// Declares the automaton deterministic (`true`: nondeterminism is an error) or
    /// nondeterministic (`false`: it is expected, not reported).
    #[serde(default)]
    pub deterministic: Option<bool>,
    /// The role whose node runs the automaton: its network of generated charts joins that
    /// role's table (docs/selecting-automata.md). None: the automaton is only checked.
    #[serde(default)]
    pub role: Option<String>,
    /// Where a part's colour comes from: the events `PARTS.COLOUR`, one per colour
    /// (`part.black`), of the automaton's role, or of another role as `ROLE/PARTS`.
    /// Default `part`.
    #[serde(default)]
    pub parts: Option<String>,
    /// A chart input of the automaton's role (`CHART.INPUT`) that every transition's
    /// `Out` reaches: "the automaton took this part" (a sorting gate opens on it).
    #[serde(default)]
    pub out: Option<String>,
}

/// One transition of an automaton: `from` -> `to` on a part of `colour`. `max`: how many
/// parts a loop (`from == to`) accepts in a row (required on a loop, not allowed
/// elsewhere).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AutomatonTransitionDecl {
    pub id: String,
    pub from: String,
    pub to: String,
    pub colour: String,
    #[serde(default)]
    pub max: Option<u32>,
    #[serde(default)]
    pub kind: TransitionKind,
}

/// Whether a transition ends a selected sequence (emits EOS).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Deserialize)]
pub enum TransitionKind {
    #[default]
    Ordinary,
    /// The sequence collected so far is selected: end of sequence (EOS).
    Final,
}

/// Whether the tool secures its frames to the robot's nodes (and delivers link keys).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
pub enum Security {
    /// Every frame secured: `push` needs the machine secret (`--keys`).
    #[default]
    On,
    /// Explicitly unsecured: anyone in radio range can push, command and forge events.
    Off,
}

fn default_timeout() -> u32 {
    2000
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Network {
    pub pan_id: u16,
    pub channel: u8,
}

/// A physical node: its name and IEEE 802.15.4 short address.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Node {
    pub name: String,
    pub address: u16,
}

/// A role: the hardware one node drives and the charts it runs.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Role {
    pub name: String,
    #[serde(default)]
    pub actuators: Vec<Actuator>,
    #[serde(default)]
    pub inputs: Vec<InputPin>,
    #[serde(default)]
    pub outputs: Vec<OutputPin>,
    #[serde(default)]
    pub charts: Vec<ChartInstance>,
    /// The emergency-stop input: pressing it faults every node of the machine.
    #[serde(default)]
    pub estop: Option<String>,
    /// Node events its charts may read besides its pins and charts' outputs (of
    /// `iec61499::services::NODE_EVENTS`: the node's boot, the HOME command); no robot
    /// file writes them, an application brings them (a `ROLE_IO` event output marked
    /// `node event boot`).
    #[serde(skip)]
    pub node_events: Vec<String>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Actuator {
    pub name: String,
    pub kind: ActuatorKind,
    /// What its node drives its valve to when it faults (default `Off`).
    #[serde(default)]
    pub fault: ActuatorLevel,
    /// What its node drives its valve to before the charts run: a new table, a boot, a
    /// reset (default `Off`).
    #[serde(default)]
    pub start: ActuatorLevel,
}

/// An actuator's valve outside the charts: on fault, or before they run. Homing always
/// drives an actuator home, as a `-` does.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
pub enum ActuatorLevel {
    /// Every solenoid off: a monostable valve drops back (a gripper opens), a bistable
    /// one is no longer driven.
    #[default]
    Off,
    /// Keep driving what it drives: a gripper keeps its part. At boot there is nothing to
    /// keep: every solenoid starts off.
    Hold,
    /// Drive it out, as a `+`.
    Extend,
    /// Drive it home, as a `-`.
    Retract,
}

/// How a node pin of an actuator is used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PinUse {
    /// A valve solenoid (a node output).
    Valve,
    /// A limit switch (a node input).
    Switch,
}

impl ActuatorKind {
    /// Every pin of the actuator: its RON field name (`extend`, `retract`, `home`, `end`,
    /// `valve`), the pin and its use, valves before switches.
    pub fn pins(&self) -> Vec<(&'static str, u8, PinUse)> {
        match *self {
            ActuatorKind::DoubleActing {
                extend,
                retract,
                home,
                end,
                ..
            } => vec![
                ("extend", extend, PinUse::Valve),
                ("retract", retract, PinUse::Valve),
                ("home", home, PinUse::Switch),
                ("end", end, PinUse::Switch),
            ],
            ActuatorKind::SingleActing {
                valve, home, end, ..
            } => [("valve", Some(valve), PinUse::Valve)]
                .into_iter()
                .chain([("home", home, PinUse::Switch), ("end", end, PinUse::Switch)])
                .filter_map(|(f, pin, used)| pin.map(|p| (f, p, used)))
                .collect(),
        }
    }

    /// The limit switch (or position sensor) that says a motion is complete: `end` for a
    /// `+`, `home` for a `-`; `None` if there is none (a sensorless motion completes after
    /// its dwell time, so a jam cannot be detected).
    pub fn completion_switch(&self, extend: bool) -> Option<u8> {
        let (home, end) = match *self {
            ActuatorKind::DoubleActing { home, end, .. } => (Some(home), Some(end)),
            ActuatorKind::SingleActing { home, end, .. } => (home, end),
        };
        if extend {
            end
        } else {
            home
        }
    }

    /// Whether some motion completes on a switch: the actuator has a motion watchdog.
    pub fn has_watchdog(&self) -> bool {
        self.completion_switch(true).is_some() || self.completion_switch(false).is_some()
    }

    /// Whether some motion completes after the dwell time.
    pub fn has_dwell(&self) -> bool {
        self.completion_switch(true).is_none() || self.completion_switch(false).is_none()
    }

    /// Its strokes' times for `sim`: (`out_ms`, `back_ms`).
    pub fn strokes(&self) -> (u32, u32) {
        match *self {
            ActuatorKind::DoubleActing {
                out_ms, back_ms, ..
            }
            | ActuatorKind::SingleActing {
                out_ms, back_ms, ..
            } => (out_ms, back_ms),
        }
    }

    /// This actuator's motion watchdog, if it sets its own.
    pub fn timeout_ms(&self) -> Option<u32> {
        match *self {
            ActuatorKind::DoubleActing { timeout_ms, .. }
            | ActuatorKind::SingleActing { timeout_ms, .. } => timeout_ms,
        }
    }
}

/// Actuator hardware and its plant parameters (for `sim`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum ActuatorKind {
    /// Double-acting cylinder, bistable valve (extend / retract solenoids), home and end
    /// limit switches.
    DoubleActing {
        extend: u8,
        retract: u8,
        home: u8,
        end: u8,
        #[serde(default = "default_travel")]
        out_ms: u32,
        #[serde(default = "default_travel")]
        back_ms: u32,
        /// Watchdog of this actuator's motions in synthesised charts (default: the
        /// robot's `motion_timeout_ms`).
        #[serde(default)]
        timeout_ms: Option<u32>,
    },
    /// Single-acting actuator, monostable valve: a motion is complete after `dwell_ms`, or,
    /// toward an end with a position sensor (`end`: extended / closed, `home`: retracted /
    /// open, both optional), when that sensor closes, under the motion watchdog.
    SingleActing {
        valve: u8,
        dwell_ms: u32,
        #[serde(default = "default_travel")]
        out_ms: u32,
        #[serde(default = "default_travel")]
        back_ms: u32,
        /// Input pin of a position sensor at home (retracted).
        #[serde(default)]
        home: Option<u8>,
        /// Input pin of a position sensor at the end (extended).
        #[serde(default)]
        end: Option<u8>,
        /// Watchdog of the motions a sensor completes (default: the robot's
        /// `motion_timeout_ms`).
        #[serde(default)]
        timeout_ms: Option<u32>,
    },
}

fn default_travel() -> u32 {
    200
}

/// A plain digital input (button, sensor). Its rising edge is the event `NAME`, its
/// falling edge `NAME.fall`; guards read its level as `NAME`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputPin {
    pub name: String,
    pub pin: u8,
}

/// A plain digital output (lamp, gate) and its levels outside the charts.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputPin {
    pub name: String,
    pub pin: u8,
    /// The level of `fault`, `start` and `home` where they are not given (default low).
    #[serde(default)]
    pub safe: bool,
    /// When the node faults: `Low`, `High` or `Hold`.
    #[serde(default)]
    pub fault: Option<Level>,
    /// Before the charts run (a new table, a boot, a reset): `Low`, `High` or `Hold`
    /// (low at boot).
    #[serde(default)]
    pub start: Option<Level>,
    /// Where homing drives it: `Low` or `High` (`check` refuses `Hold`).
    #[serde(default)]
    pub home: Option<Level>,
}

impl OutputPin {
    /// Its fault, start and home levels, `safe` where one is not given (a `Hold` home,
    /// which `check` refuses, as `safe`).
    pub fn levels(&self) -> (Level, Level, bool) {
        let safe = Level::of(self.safe);
        let home = self.home.and_then(Level::level).unwrap_or(self.safe);
        (self.fault.unwrap_or(safe), self.start.unwrap_or(safe), home)
    }
}

/// A chart type: an ECC with parameters, input and output events, variables, timers.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChartType {
    pub name: String,
    #[serde(default)]
    pub params: Vec<String>,
    #[serde(default)]
    pub inputs: Vec<String>,
    #[serde(default)]
    pub outputs: Vec<String>,
    #[serde(default)]
    pub vars: Vec<VarDecl>,
    /// Timers; a timer's expiry is a chart input event of the same name.
    #[serde(default)]
    pub timers: Vec<String>,
    pub states: Vec<StateDecl>,
    #[serde(default)]
    pub transitions: Vec<TransitionDecl>,
    /// Where the chart rests between cycles, when not its first state (a lifted chart of
    /// a sequence robot starts not homed and rests at its idle state); no robot file
    /// writes it, the `.fbt` import of a marked type reads it
    /// (`iec61499::services::IDLE`).
    #[serde(skip)]
    pub idle: Option<String>,
    /// Other states where the chart rests between cycles (a mode kept from one cycle to
    /// the next); no robot file writes it, the `.fbt` import of a marked state reads it
    /// (`iec61499::services::REST`).
    #[serde(skip)]
    pub rests: Vec<String>,
    /// For a type the robot file does not write: the place in it that brought the type
    /// (`fb_types[2]`, `application.file`), where its diagnostics point.
    #[serde(skip)]
    pub imported: Option<String>,
    /// For a type read from an IEC 61499 `.fbt` file: where in it each state and
    /// transition was written (its diagnostics name the place).
    #[serde(skip)]
    pub written: Option<Written>,
    /// For a type the application import made of another (an FB instance's own
    /// actions): that one's name (the chart is the same: so are its warnings).
    #[serde(skip)]
    pub specializes: Option<String>,
}

/// Where an imported chart type was written: its file and, per state and per transition
/// of the type (in the type's order), the line and column (1-based) of the element it
/// came from (a state or transition an `IF` or `CASE` became: its state's).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Written {
    pub file: String,
    pub states: Vec<(u32, u32)>,
    pub transitions: Vec<(u32, u32)>,
}

impl ChartType {
    /// The text of every expression of the type: its assignments' (`Set`), then its
    /// transitions' guards.
    pub fn expressions(&self) -> impl Iterator<Item = &String> {
        let sets = (self.states.iter().flat_map(|s| s.actions.iter())).filter_map(|a| match a {
            ActionDecl::Set(_, text) => Some(text),
            _ => None,
        });
        sets.chain(self.transitions.iter().filter_map(|t| t.when.as_ref()))
    }

    /// [`ChartType::expressions`], to rewrite in place.
    pub fn expressions_mut(&mut self) -> impl Iterator<Item = &mut String> {
        let sets =
            (self.states.iter_mut().flat_map(|s| s.actions.iter_mut())).filter_map(|a| match a {
                ActionDecl::Set(_, text) => Some(text),
                _ => None,
            });
        sets.chain(self.transitions.iter_mut().filter_map(|t| t.when.as_mut()))
    }

    /// `file:line:col` of state `si` in the file the type was read from, if it was.
    pub fn state_written(&self, si: usize) -> Option<String> {
        self.written_at(|w| &w.states, si)
    }

    /// `file:line:col` of transition `k` in the file the type was read from, if it was.
    pub fn transition_written(&self, k: usize) -> Option<String> {
        self.written_at(|w| &w.transitions, k)
    }

    /// `file:line:col` of entry `k` of the places `of` picks, if the type was read from a file.
    fn written_at(&self, of: fn(&Written) -> &[(u32, u32)], k: usize) -> Option<String> {
        let w = self.written.as_ref()?;
        let (line, col) = of(w).get(k)?;
        Some(format!("{}:{line}:{col}", w.file))
    }

    /// Where a diagnostic about `path` of this type (a path in the robot file) points: the
    /// path itself, or for a type the robot file does not write the place that imported it.
    pub fn place<'a>(&'a self, path: &'a str) -> &'a str {
        self.imported.as_deref().unwrap_or(path)
    }
}

/// A chart variable and its initial value (an expression over the parameters).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VarDecl {
    pub name: String,
    #[serde(default = "zero")]
    pub init: String,
}

fn zero() -> String {
    String::from("0")
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateDecl {
    pub name: String,
    #[serde(default)]
    pub actions: Vec<ActionDecl>,
}

/// What a state does when it is entered, in order.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub enum ActionDecl {
    /// `Set("count", "count + 1")`: assign an expression to a variable.
    Set(String, String),
    /// Emit a chart output event.
    Emit(String),
    /// Extend an actuator of the role (valve on / extend solenoid).
    Extend(String),
    /// Retract an actuator of the role.
    Retract(String),
    /// Drive a plain output.
    Out(String, bool),
    /// Start (or restart) a timer, in milliseconds.
    StartTimer(String, u32),
    CancelTimer(String),
    /// Fault the node with an application code.
    Fault(u8),
}

/// An ordered transition: `from` -> `to` on the chart input `on` (none: event-less) when
/// the guard `when` holds.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransitionDecl {
    pub from: String,
    pub to: String,
    #[serde(default)]
    pub on: Option<String>,
    #[serde(default)]
    pub when: Option<String>,
}

/// A chart of a role: an instance of a chart type with parameter values, and the event
/// feeding each of its inputs (`EVENT` of this role or `ROLE/EVENT` of another).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChartInstance {
    pub name: String,
    #[serde(rename = "type")]
    pub type_: String,
    #[serde(default)]
    pub params: BTreeMap<String, i32>,
    #[serde(default)]
    pub on: BTreeMap<String, String>,
    /// Timers of its type that are a timer of the role shared with the role's other
    /// charts (type's timer -> the role's timer event, `VC.watchdog`); a timer not named
    /// is the chart's own, `CHART.TIMER`. No robot file writes them, an application
    /// brings them (the charts whose timer the role's `ROLE_IO` output feeds).
    #[serde(skip)]
    pub timers: BTreeMap<String, String>,
    /// Further sources of an input besides its `on` one, in order (the `on` source
    /// first): an input several events feed, each its own route. No robot file writes
    /// them, an application brings them (the sources an `E_MERGE` chain joins).
    #[serde(skip)]
    pub more: BTreeMap<String, Vec<String>>,
    /// Parameters of its type that read a variable of another chart of its role instead
    /// of a constant (parameter -> the role's variable, `CHART.VAR`; the role's
    /// variables are one pool, so the chart may be declared later). No robot file writes
    /// them, an application brings them (a data connection within a resource, a lifted
    /// chart's input variable `value of FB.VAR`).
    #[serde(skip)]
    pub reads: BTreeMap<String, String>,
    /// Where an application declares the chart (no robot file writes it): a diagnostic
    /// about it names that place ([`crate::diag::Diagnostic::of_chart`]).
    #[serde(skip)]
    pub declared: Option<Declared>,
}

/// Where an application declares a chart, each place as `FILE:LINE:COL`: its `FB` element
/// and the connection into each of its inputs; and the inputs the robot file's
/// `application.on` feeds, each with its key there (`vc.START`).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Declared {
    pub fb: String,
    pub on: BTreeMap<String, String>,
    pub ron_on: BTreeMap<String, String>,
}

impl ChartInstance {
    /// Every (input, source) connection: per input of `on` (in its order), its `on`
    /// source, then its further ones ([`ChartInstance::more`]).
    pub fn sources(&self) -> Vec<(&str, &str)> {
        let mut out = Vec::new();
        for (key, source) in &self.on {
            out.push((key.as_str(), source.as_str()));
            for s in self.more.get(key).into_iter().flatten() {
                out.push((key.as_str(), s.as_str()));
            }
        }
        out
    }
}

/// Parses a RON robot; a syntax or shape error becomes a diagnostic at ron's position.
pub fn parse(src: &Source) -> Result<Robot, Diagnostic> {
    let options =
        ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME);
    options.from_str(&src.text).map_err(|e| {
        let start = src.offset(e.span.start.line, e.span.start.col);
        let end = src.offset(e.span.end.line, e.span.end.col).max(start);
        if e.code == ron::Error::IntegerOutOfBounds {
            if let Some((field, range)) = crate::bounds::integer_field(&src.text, start) {
                return Diagnostic::error(
                    start..end,
                    format!("Integer is out of bounds: `{field}` takes {range}"),
                )
                .label(range);
            }
        }
        // Nothing but white space and comments from ron's position on, and a bracket
        // still open: the file ends too early (ron says what it expected next).
        let (code_end, open) = crate::unclosed::unclosed(&src.text);
        if let (Some((at, bracket)), true) = (open, start >= code_end) {
            let (line, col) = src.line_col(at);
            let end = src.text.len();
            return Diagnostic::error(
                code_end..end,
                format!(
                    "Unexpected end of RON: the file ends before the `{}` opened at \
                     {line}:{col} is closed (is it cut short?)",
                    char::from(bracket)
                ),
            )
            .label("the file ends here");
        }
        Diagnostic::error(start..end, e.code.to_string()).label("here")
    })
}

impl Robot {
    /// The files compiling this robot reads besides the robot file at `path`: its
    /// `fb_types`, its `application`, its automata's `facts_file`s, each relative to the
    /// robot file as the loaders read them.
    pub fn imports(&self, path: &std::path::Path) -> Vec<std::path::PathBuf> {
        let dir = path.parent().unwrap_or(std::path::Path::new(""));
        let files = self.fb_types.iter().map(String::as_str);
        let files = files.chain(self.application.iter().map(|a| a.file.as_str()));
        let files = files.chain(self.automata.iter().filter_map(|a| a.facts_file.as_deref()));
        files.map(|f| dir.join(f)).collect()
    }

    pub fn role(&self, name: &str) -> Option<(usize, &Role)> {
        self.roles.iter().enumerate().find(|(_, r)| r.name == name)
    }

    pub fn chart_type(&self, name: &str) -> Option<(usize, &ChartType)> {
        self.chart_types
            .iter()
            .enumerate()
            .find(|(_, t)| t.name == name)
    }

    /// The role and actuator index of an actuator name.
    pub fn actuator(&self, name: &str) -> Option<(usize, usize)> {
        self.roles.iter().enumerate().find_map(|(r, role)| {
            role.actuators
                .iter()
                .position(|a| a.name == name)
                .map(|a| (r, a))
        })
    }
}
