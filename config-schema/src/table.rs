//! The table one node runs: its events, variables, pins, timers, charts and radio links.
//!
//! Charts, states, transitions and actions live in flat pools. A chart owns the states and
//! transitions up to its `states_end` / `transitions_end` (the previous chart's end, or 0,
//! is its start); a state owns the actions up to its `actions_end`. This keeps the decoded
//! table small and its size fixed, and the blob compact.

use heapless::{String, Vec};
use serde::{Deserialize, Serialize};

use crate::alarm::Safety;
use crate::guard::{Expr, Op};
use crate::limits::*;

/// A node event id (`0..Table::events`).
pub type EventId = u8;
/// A radio topic: robot-wide id of a published event.
pub type Topic = u8;

/// The whole table of one role.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Table {
    /// Deployment generation. Carried by the blob envelope, not the payload.
    #[serde(skip)]
    pub generation: u32,
    pub header: Header,
    /// Number of node events.
    pub events: u8,
    /// The node event raised by the START command, if the role reacts to one.
    pub start: Option<EventId>,
    /// The node event raised by the HOME command, if the role starts homing
    /// (docs/reconfiguration.md).
    pub home: Option<EventId>,
    /// The node event raised (and published) once when the node boots with this table, not
    /// at an activation: a peer that hears it knows this node's actuators may stand
    /// anywhere (docs/reconfiguration.md).
    pub boot: Option<EventId>,
    /// Initial values of the variables.
    pub vars: Vec<i32, MAX_VARS>,
    pub inputs: Vec<Input, MAX_INPUTS>,
    pub outputs: Vec<Output, MAX_OUTPUTS>,
    pub timers: Vec<Timer, MAX_TIMERS>,
    pub charts: Vec<Chart, MAX_CHARTS>,
    pub states: Vec<State, MAX_STATES>,
    pub transitions: Vec<Transition, MAX_TRANSITIONS>,
    pub actions: Vec<Action, MAX_ACTIONS>,
    /// Bytecode pool of every guard and assignment expression.
    pub code: Vec<Op, MAX_CODE>,
    pub routes: Vec<Route, MAX_ROUTES>,
    /// Short addresses of the peers this node publishes to.
    pub peers: Vec<u16, MAX_PEERS>,
    pub publications: Vec<Publication, MAX_PUBLICATIONS>,
    pub subscriptions: Vec<Subscription, MAX_SUBSCRIPTIONS>,
    /// The emergency stop, restart inputs, link alarm policy and declared alarms.
    pub safety: Safety,
}

/// Identity and network facts of the role.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    pub role: String<MAX_ROLE_NAME>,
    pub pan_id: u16,
    pub channel: u8,
}

/// A digital input: its pin, the events raised on its edges, and the variable mirroring it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Input {
    pub pin: u8,
    pub rise: Option<EventId>,
    pub fall: Option<EventId>,
    pub var: Option<u8>,
}

/// What the node drives an output to when it faults or when its charts start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Level {
    /// Off (0).
    Low,
    /// On (1).
    High,
    /// Keep the level the output has: a gripper keeps its part. At boot there is nothing
    /// to keep (the pin comes out of reset off): a held output starts low.
    Hold,
}

impl Level {
    /// The level driven, or `None` for [`Level::Hold`].
    pub fn level(self) -> Option<bool> {
        match self {
            Level::Low => Some(false),
            Level::High => Some(true),
            Level::Hold => None,
        }
    }

    /// `Low` or `High`.
    pub fn of(level: bool) -> Level {
        if level {
            Level::High
        } else {
            Level::Low
        }
    }
}

/// A digital output and the levels the node drives it to outside the charts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Output {
    pub pin: u8,
    /// When the node faults (then it ignores every event until a reset or a new table).
    pub fault: Level,
    /// Before the charts run from their initial states: a new table, a boot, a reset.
    pub start: Level,
    /// Where homing drives it (the machine's idle place); homing drives a level, so it is
    /// never held.
    pub home: bool,
}

impl Output {
    /// An output driven to `level` on fault, at start and by homing (what one `safe`
    /// level meant before fault, start and home levels).
    pub fn safe(pin: u8, level: bool) -> Output {
        Output {
            pin,
            fault: Level::of(level),
            start: Level::of(level),
            home: level,
        }
    }
}

/// A one-shot timer and the node event raised when it expires.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Timer {
    pub event: EventId,
}

/// One ECC instance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Chart {
    /// End (exclusive) of this chart's states in [`Table::states`].
    pub states_end: u8,
    /// End (exclusive) of this chart's transitions in [`Table::transitions`].
    pub transitions_end: u8,
    /// Number of chart input events.
    pub inputs: u8,
    /// Initial state, chart-local: where the chart starts after a boot, a reset or an
    /// activation of a stopped machine (actuators may be anywhere: not homed).
    pub initial: u8,
    /// The chart's idle state, chart-local: where it rests between cycles with every
    /// actuator home. The machine is idle when every chart is in it; a table activated
    /// at the idle point starts its charts there.
    pub idle: u8,
    /// The states besides `idle` where the chart also rests between cycles (a mode the
    /// operator selected, kept from one cycle to the next), one bit each: bit `k` is
    /// chart-local state `k` (so only the chart's first 32 states can be one). The machine
    /// is idle with the chart in any of them; an activation at the idle point still
    /// starts the chart in `idle`.
    pub rests: u32,
}

impl Chart {
    /// Whether the chart rests between cycles in chart-local `state`: its idle state or
    /// one of its other resting states ([`Chart::rests`]).
    pub fn rests_in(&self, state: u8) -> bool {
        state == self.idle || (state < 32 && self.rests & (1 << state) != 0)
    }
}

/// One ECC state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct State {
    /// End (exclusive) of this state's actions in [`Table::actions`]; its start is the
    /// previous state's end (or 0 for the table's first state).
    pub actions_end: u8,
}

/// One ECC transition. States are chart-local indices.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Transition {
    pub from: u8,
    pub to: u8,
    /// The chart input event that triggers it, or `None` for an event-less transition.
    pub trigger: Option<u8>,
    /// The guard; `None` is always true.
    pub guard: Option<Expr>,
}

/// An action run when its state is entered, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Action {
    /// `var := expr`.
    Set { var: u8, expr: Expr },
    /// Drive the outputs of `mask` to the matching bits of `value`, atomically.
    Drive { mask: u16, value: u16 },
    /// Queue a node event (delivered after this chart is stable; published if it has a
    /// publication).
    Emit(EventId),
    /// Publish a node event to the radio without delivering it locally.
    Publish(EventId),
    /// Start (or restart) a timer.
    StartTimer { timer: u8, ms: u32 },
    /// Cancel a timer.
    CancelTimer(u8),
    /// Fault the node with an application code.
    Fault(u8),
}

/// Delivers a node event to a chart input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Route {
    pub event: EventId,
    pub chart: u8,
    pub input: u8,
}

/// A node event sent to the radio under a topic, to the peers of the `subscribers` mask
/// (bit i = `peers[i]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Publication {
    pub event: EventId,
    pub topic: Topic,
    pub subscribers: u8,
}

/// A topic published by peer `publisher`, raised here as a node event.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Subscription {
    pub publisher: u8,
    pub topic: Topic,
    pub event: EventId,
}

impl Table {
    /// An empty table for a role: no events, no charts, nothing to do.
    pub fn empty(role: &str) -> Table {
        let mut name = String::new();
        for c in role.chars() {
            if name.push(c).is_err() {
                break;
            }
        }
        Table {
            generation: 0,
            header: Header {
                role: name,
                pan_id: 0,
                channel: 11,
            },
            events: 0,
            start: None,
            home: None,
            boot: None,
            vars: Vec::new(),
            inputs: Vec::new(),
            outputs: Vec::new(),
            timers: Vec::new(),
            charts: Vec::new(),
            states: Vec::new(),
            transitions: Vec::new(),
            actions: Vec::new(),
            code: Vec::new(),
            routes: Vec::new(),
            peers: Vec::new(),
            publications: Vec::new(),
            subscriptions: Vec::new(),
            safety: Safety::default(),
        }
    }

    /// The first input or output pin (in table order, inputs first) that `board` lacks
    /// (bit n: the board has pin n; pins past 63 are on no board), if any.
    pub fn missing_pin(&self, board: u64) -> Option<u8> {
        let on_board = |pin: u8| {
            1u64.checked_shl(u32::from(pin))
                .is_some_and(|b| board & b != 0)
        };
        let inputs = self.inputs.iter().map(|i| i.pin);
        let outputs = self.outputs.iter().map(|o| o.pin);
        inputs.chain(outputs).find(|&pin| !on_board(pin))
    }

    /// The outputs a fault drives (mask, bit i = output i: those not held) and their
    /// levels.
    pub fn fault_drive(&self) -> (u16, u16) {
        drive_of(self.outputs.iter().map(|o| o.fault))
    }

    /// The outputs a start (new table, boot, reset) drives (those not held) and their
    /// levels.
    pub fn start_drive(&self) -> (u16, u16) {
        drive_of(self.outputs.iter().map(|o| o.start))
    }

    /// The levels homing drives the outputs to, bit i = output i.
    pub fn home_levels(&self) -> u16 {
        drive_of(self.outputs.iter().map(|o| Level::of(o.home))).1
    }

    /// The half-open range of chart `chart`'s states in [`Table::states`].
    pub fn chart_states(&self, chart: usize) -> core::ops::Range<usize> {
        let end = self
            .charts
            .get(chart)
            .map_or(0, |c| usize::from(c.states_end));
        let start = match chart.checked_sub(1) {
            Some(prev) => self
                .charts
                .get(prev)
                .map_or(0, |c| usize::from(c.states_end)),
            None => 0,
        };
        start..end.max(start)
    }

    /// The half-open range of chart `chart`'s transitions in [`Table::transitions`].
    pub fn chart_transitions(&self, chart: usize) -> core::ops::Range<usize> {
        let end = self
            .charts
            .get(chart)
            .map_or(0, |c| usize::from(c.transitions_end));
        let start = match chart.checked_sub(1) {
            Some(prev) => self
                .charts
                .get(prev)
                .map_or(0, |c| usize::from(c.transitions_end)),
            None => 0,
        };
        start..end.max(start)
    }

    /// The half-open range of global state `state`'s actions in [`Table::actions`].
    pub fn state_actions(&self, state: usize) -> core::ops::Range<usize> {
        let end = self
            .states
            .get(state)
            .map_or(0, |s| usize::from(s.actions_end));
        let start = match state.checked_sub(1) {
            Some(prev) => self
                .states
                .get(prev)
                .map_or(0, |s| usize::from(s.actions_end)),
            None => 0,
        };
        start..end.max(start)
    }

    /// The operations of an expression (empty if the reference is out of range).
    pub fn expr(&self, expr: Expr) -> &[Op] {
        let start = usize::from(expr.start);
        self.code
            .get(start..start + usize::from(expr.len))
            .unwrap_or(&[])
    }

    /// The publication of a node event, if it is published.
    pub fn publication(&self, event: EventId) -> Option<&Publication> {
        self.publications.iter().find(|p| p.event == event)
    }

    /// The node event that peer `publisher` (index into the peers) publishing `topic`
    /// raises here, if this node subscribes to it.
    #[inline]
    pub fn subscribed(&self, publisher: u8, topic: Topic) -> Option<EventId> {
        (self.subscriptions.iter())
            .find(|s| s.publisher == publisher && s.topic == topic)
            .map(|s| s.event)
    }
}

/// (mask of the outputs a level drives, their levels) over the first 16 outputs.
fn drive_of(levels: impl Iterator<Item = Level>) -> (u16, u16) {
    levels
        .take(16)
        .enumerate()
        .fold((0, 0), |(mask, value), (i, l)| match l.level() {
            Some(high) => (mask | 1 << i, value | u16::from(high) << i),
            None => (mask, value),
        })
}

/// A pool of the table is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Full(pub &'static str);

impl core::fmt::Display for Full {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "table capacity exceeded: {}", self.0)
    }
}

impl core::error::Error for Full {}

fn push<T, const N: usize>(v: &mut Vec<T, N>, x: T, what: &'static str) -> Result<(), Full> {
    v.push(x).map_err(|_| Full(what))
}

fn end(len: usize, what: &'static str) -> Result<u8, Full> {
    u8::try_from(len).map_err(|_| Full(what))
}

/// Building a table chart by chart (config-tool and tests). The result still has to pass
/// [`validate`](fn@crate::validate); these only keep the pools' layout right.
impl Table {
    /// Appends an expression to the code pool.
    pub fn push_expr(&mut self, ops: &[Op]) -> Result<Expr, Full> {
        let start = end(self.code.len(), "code")?;
        let len = u8::try_from(ops.len()).map_err(|_| Full("expression length"))?;
        self.code.extend_from_slice(ops).map_err(|_| Full("code"))?;
        Ok(Expr { start, len })
    }

    /// Appends a chart. `states[i]` are the actions of chart-local state `i`; transitions
    /// use chart-local states and chart inputs `0..inputs`. Its idle state is its initial
    /// one (set `idle` of the chart for one that starts elsewhere). Returns the chart's
    /// index.
    pub fn push_chart(
        &mut self,
        initial: u8,
        inputs: u8,
        states: &[&[Action]],
        transitions: &[Transition],
    ) -> Result<u8, Full> {
        let index = end(self.charts.len(), "charts")?;
        let saved = (
            self.states.len(),
            self.actions.len(),
            self.transitions.len(),
        );
        let result = (|| {
            for actions in states {
                for a in *actions {
                    push(&mut self.actions, *a, "actions")?;
                }
                let actions_end = end(self.actions.len(), "actions")?;
                push(&mut self.states, State { actions_end }, "states")?;
            }
            for t in transitions {
                push(&mut self.transitions, *t, "transitions")?;
            }
            let chart = Chart {
                states_end: end(self.states.len(), "states")?,
                transitions_end: end(self.transitions.len(), "transitions")?,
                inputs,
                initial,
                idle: initial,
                rests: 0,
            };
            push(&mut self.charts, chart, "charts")
        })();
        if result.is_err() {
            self.states.truncate(saved.0);
            self.actions.truncate(saved.1);
            self.transitions.truncate(saved.2);
        }
        result.map(|()| index)
    }

    /// Adds a node event and returns its id.
    pub fn push_event(&mut self) -> Result<EventId, Full> {
        let id = self.events;
        if usize::from(id) >= MAX_EVENTS {
            return Err(Full("events"));
        }
        self.events += 1;
        Ok(id)
    }
}

#[cfg(test)]
mod tests {
    use super::{Level, Output, Table};

    /// Fault and start drive every output that is not held, to its level; homing drives
    /// every output.
    #[test]
    fn the_drive_masks_leave_held_outputs_alone() {
        let mut t = Table::empty("r");
        let outputs = [
            Output {
                pin: 0,
                fault: Level::Hold,
                start: Level::Low,
                home: false,
            },
            Output {
                pin: 1,
                fault: Level::High,
                start: Level::Hold,
                home: true,
            },
            Output {
                pin: 2,
                fault: Level::Low,
                start: Level::High,
                home: true,
            },
            Output::safe(3, true),
        ];
        for o in outputs {
            t.outputs.push(o).unwrap();
        }
        assert_eq!(t.fault_drive(), (0b1110, 0b1010));
        assert_eq!(t.start_drive(), (0b1101, 0b1100));
        assert_eq!(t.home_levels(), 0b1110);
        assert_eq!(Level::Hold.level(), None);
        assert_eq!(Level::of(true).level(), Some(true));
    }
}
