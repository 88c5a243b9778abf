//! The world's trace: everything that happened, in order, on virtual time.

use core::fmt;

use config_schema::{EventId, Topic};

use crate::ecc::Fault;

/// One thing that happened at `t_ms`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TraceEntry {
    /// Virtual time in milliseconds.
    pub t_ms: u64,
    pub what: What,
}

/// What happened. Nodes and plants are indices into the world's lists.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum What {
    /// [`World::press`](super::World::press) was called for a button.
    Press { button: usize },
    /// [`World::start`](super::World::start) sent the START command to a node.
    Start { node: usize },
    /// [`World::home`](super::World::home) sent the HOME command to a node.
    Home { node: usize },
    /// [`World::go`](super::World::go) commanded an actuator's valve directly.
    Go { plant: usize, plus: bool },
    /// An actuator started a motion (`VC+`): from a switch, or reversing mid-travel.
    Step {
        plant: usize,
        actuator: String,
        plus: bool,
    },
    /// An actuator reached the end (`end`) or home.
    Arrived { plant: usize, end: bool },
    /// A motor's run changed (its two outputs): it runs `run` from position `at_um` (µm
    /// from home).
    Motor {
        plant: usize,
        run: super::Run,
        at_um: u64,
    },
    /// [`World::set_switch`](super::World::set_switch) set a maintained contact.
    Switched { plant: usize, level: bool },
    /// Both solenoids of a bistable valve (or both outputs of a motor) were energised by
    /// one engine step: no change (a motor stops).
    Conflict { plant: usize },
    /// A node input changed level.
    Input { node: usize, input: u8, level: bool },
    /// A node drove an output.
    Output {
        node: usize,
        output: u8,
        level: bool,
    },
    /// A node's timer expired.
    TimerExpired { node: usize, timer: u8 },
    /// A chart of a node took a transition (chart-local states).
    Fired {
        node: usize,
        chart: u8,
        transition: u8,
        from: u8,
        to: u8,
    },
    /// A chart input reached a chart whose current state does not expect it: dropped.
    Ignored { node: usize, chart: u8, input: u8 },
    /// A node published an event to the radio.
    Publish {
        node: usize,
        event: EventId,
        topic: Topic,
        subscribers: u8,
    },
    /// A publication was addressed to a peer address no node in the world has.
    NoSuchPeer { node: usize, addr: u16 },
    /// A publication reached a node; `accepted`: the node subscribes to it (from that
    /// publisher), so it raised the subscribed event.
    Deliver {
        from: usize,
        to: usize,
        topic: Topic,
        accepted: bool,
    },
    /// A node faulted (its outputs are already safe).
    Fault { node: usize, fault: Fault },
    /// [`World::reset`](super::World::reset) reset a node.
    Reset { node: usize },
    /// [`World::reboot`](super::World::reboot): a power cut of one node.
    Reboot { node: usize },
    /// A node latched an alarm.
    Alarm {
        node: usize,
        source: config_schema::alarm::AlarmSource,
        level: config_schema::alarm::AlarmLevel,
    },
    /// A START or restart press (input `input`, `None`: the command) was refused: a fault
    /// alarm is latched on the node.
    Refused { node: usize, input: Option<u8> },
    /// [`World::ack`](super::World::ack): the operator acknowledged `acked` alarms.
    Ack { node: usize, acked: usize },
    /// A fault was injected (`jam`, `break_switch`, `stop_node`, `cut_link`), as text.
    Injected { fault: String },
    /// A valve command reached a jammed actuator: it did not move.
    Jammed { plant: usize, plus: bool },
    /// The link from `node` to `peer` gave up after its retries: link alarm at `node`.
    LinkAlarm { node: usize, peer: usize },
    /// Lossy radio: the link from `node` to `peer` overflowed its queue
    /// ([`QUEUE`](crate::link::QUEUE) events unacknowledged): it is broken and sends nothing
    /// more in this epoch.
    LinkBroken { node: usize, peer: usize },
    /// A feed's ball `ball` (0-based) lies at the sensors (the first from t = 0, untraced).
    BallReady { feed: usize, ball: usize },
    /// The pusher pushed ball `ball` into the shaft.
    Fed { feed: usize, ball: usize },
    /// Ball `ball` landed in bin `bin` (1-based).
    Binned {
        feed: usize,
        ball: usize,
        bin: usize,
    },
    /// Ball `ball` met gate plant `plant` while the gate moved.
    GateMoving {
        feed: usize,
        ball: usize,
        plant: usize,
    },
}

impl What {
    /// The step string (`"VC+"`) of a [`What::Step`].
    pub fn step(&self) -> Option<String> {
        match self {
            What::Step { actuator, plus, .. } => {
                Some(format!("{actuator}{}", if *plus { '+' } else { '-' }))
            }
            _ => None,
        }
    }
}

impl fmt::Display for What {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let lv = |b: bool| u8::from(b);
        match self {
            What::Press { button } => write!(f, "press button #{button}"),
            What::Start { node } => write!(f, "START -> node {node}"),
            What::Home { node } => write!(f, "HOME -> node {node}"),
            What::Go { plant, plus } => {
                write!(f, "go plant #{plant} {}", if *plus { '+' } else { '-' })
            }
            What::Step { .. } => write!(f, "step {}", self.step().unwrap_or_default()),
            What::Arrived { plant, end } => {
                write!(f, "plant #{plant} at {}", if *end { "end" } else { "home" })
            }
            What::Conflict { plant } => write!(f, "plant #{plant}: both solenoids energised"),
            What::Motor { plant, run, at_um } => write!(
                f,
                "plant #{plant} {} at {}.{:03} mm",
                match run {
                    super::Run::Stopped => "stops",
                    super::Run::Clockwise => "runs clockwise",
                    super::Run::CounterClockwise => "runs counter-clockwise",
                },
                at_um / 1000,
                at_um % 1000
            ),
            What::Switched { plant, level } => {
                write!(f, "switch plant #{plant} set to {}", lv(*level))
            }
            What::Input { node, input, level } => {
                write!(f, "node {node} input {input} = {}", lv(*level))
            }
            What::Output {
                node,
                output,
                level,
            } => write!(f, "node {node} output {output} = {}", lv(*level)),
            What::TimerExpired { node, timer } => write!(f, "node {node} timer {timer} expired"),
            What::Fired {
                node,
                chart,
                transition,
                from,
                to,
            } => write!(
                f,
                "node {node} chart {chart}: S{from} -> S{to} (transition {transition})"
            ),
            What::Ignored { node, chart, input } => {
                write!(f, "node {node} chart {chart}: input {input} ignored")
            }
            What::Publish {
                node,
                event,
                topic,
                subscribers,
            } => write!(
                f,
                "node {node} publishes event {event} as topic {topic} to peers {subscribers:#010b}"
            ),
            What::NoSuchPeer { node, addr } => {
                write!(f, "node {node}: no node has peer address {addr:#06x}")
            }
            What::Deliver {
                from,
                to,
                topic,
                accepted,
            } => write!(
                f,
                "topic {topic} node {from} -> node {to}{}",
                if *accepted { "" } else { " (not subscribed)" }
            ),
            What::Fault { node, fault } => write!(f, "node {node} FAULT {fault:?}"),
            What::Reset { node } => write!(f, "node {node} reset"),
            What::Reboot { node } => write!(f, "node {node} rebooted"),
            What::Alarm {
                node,
                source,
                level,
            } => write!(f, "node {node} ALARM {level} {source:?}"),
            What::Refused { node, input: None } => {
                write!(f, "node {node} refused START: a fault alarm is latched")
            }
            What::Refused {
                node,
                input: Some(i),
            } => write!(f, "node {node} refused input {i}: a fault alarm is latched"),
            What::Ack { node, acked } => write!(f, "node {node} ack: {acked} acknowledged"),
            What::Injected { fault } => write!(f, "INJECTED {fault}"),
            What::Jammed { plant, plus } => write!(
                f,
                "plant #{plant} commanded {} but jammed",
                if *plus { '+' } else { '-' }
            ),
            What::LinkAlarm { node, peer } => {
                write!(
                    f,
                    "node {node} LINK ALARM: node {peer} does not acknowledge"
                )
            }
            What::BallReady { feed, ball } => write!(f, "feed {feed}: ball {ball} at the sensors"),
            What::Fed { feed, ball } => write!(f, "feed {feed}: ball {ball} pushed into the shaft"),
            What::Binned { feed, ball, bin } => write!(f, "feed {feed}: ball {ball} in bin {bin}"),
            What::GateMoving { feed, ball, plant } => {
                write!(f, "feed {feed}: ball {ball} met gate plant #{plant} moving")
            }
            What::LinkBroken { node, peer } => {
                write!(
                    f,
                    "node {node} LINK BROKEN: queue to node {peer} overflowed"
                )
            }
        }
    }
}

impl fmt::Display for TraceEntry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:>8} ms  {}", self.t_ms, self.what)
    }
}

/// The step strings (`"VC+"`, `"GR-"`, ...) of a slice of the trace, in order.
pub fn steps(trace: &[TraceEntry]) -> Vec<String> {
    trace.iter().filter_map(|e| e.what.step()).collect()
}

/// One cycle of a trace: from a [`What::Press`] or [`What::Start`] to the next one.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Cycle {
    /// Time of the press / START.
    pub start_ms: u64,
    /// Time of the last entry before the next press / START.
    pub end_ms: u64,
    /// The steps, in order.
    pub steps: Vec<String>,
}

impl Cycle {
    /// `end_ms - start_ms`.
    pub fn duration_ms(&self) -> u64 {
        self.end_ms - self.start_ms
    }
}

/// Splits a trace into cycles at each press / START; entries before the first are dropped.
pub fn cycles(trace: &[TraceEntry]) -> Vec<Cycle> {
    let mut out: Vec<Cycle> = Vec::new();
    for e in trace {
        match &e.what {
            What::Press { .. } | What::Start { .. } => out.push(Cycle {
                start_ms: e.t_ms,
                end_ms: e.t_ms,
                steps: Vec::new(),
            }),
            what => {
                if let Some(c) = out.last_mut() {
                    c.end_ms = e.t_ms;
                    if let Some(s) = what.step() {
                        c.steps.push(s);
                    }
                }
            }
        }
    }
    out
}
