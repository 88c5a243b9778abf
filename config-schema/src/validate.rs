//! Semantic validation of a decoded table: every index, count and range is checked, so the
//! interpreter can run a validated table without ever indexing out of bounds.

use core::fmt;

use crate::cost::{worst_stimulus, STIMULUS_BUDGET};
use crate::guard::{self, Expr, ExprError};
use crate::limits::*;
use crate::table::{Action, Chart, Table, Transition};

/// Where in a table a problem is (indices into the table's pools).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Place {
    Header,
    Input(u8),
    Output(u8),
    Timer(u8),
    Chart(u8),
    State(u8),
    Transition(u8),
    Action(u8),
    Route(u8),
    Peer(u8),
    Publication(u8),
    Subscription(u8),
    /// The table's safety declarations (emergency stop, restart inputs).
    Safety,
    /// A declared alarm.
    Alarm(u8),
}

/// A table that decoded but does not make sense.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Invalid {
    /// A count over its capacity limit.
    Capacity {
        what: &'static str,
        count: usize,
        max: usize,
    },
    /// A radio channel outside [`CHANNELS`].
    Channel { channel: u8 },
    /// A node event id at or past `Table::events`.
    Event { at: Place, event: u8 },
    /// A variable that does not exist.
    Var { at: Place, var: u8 },
    /// A timer that does not exist.
    Timer { at: Place, timer: u8 },
    /// An output mask naming outputs that do not exist.
    Output { at: Place, mask: u16 },
    /// A peer that does not exist (or a subscriber mask naming one).
    Peer { at: Place, peer: u8 },
    /// A transition (or initial or idle state) to a state the chart does not have.
    State { at: Place, state: u8 },
    /// A chart input event the chart does not have.
    ChartInput { at: Place, input: u8 },
    /// An event routed to a chart that does not exist.
    Chart { at: Place, chart: u8 },
    /// Pool ranges that go backwards or do not cover their pool.
    Range { at: Place },
    /// A malformed guard or assignment expression.
    Expr { at: Place, error: ExprError },
    /// A pin number at or past [`MAX_PINS`].
    Pin { at: Place, pin: u8 },
    /// A pin, peer, topic or event declared twice.
    Duplicate { at: Place },
    /// A `Publish` action for an event without a publication.
    NotPublished { at: Place, event: u8 },
    /// One stimulus of `event` may cost more than the budget (`crate::cost`).
    Slow { event: u8, cost: u64, budget: u64 },
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Place::Header => write!(f, "header"),
            Place::Input(i) => write!(f, "input #{i}"),
            Place::Output(i) => write!(f, "output #{i}"),
            Place::Timer(i) => write!(f, "timer #{i}"),
            Place::Chart(i) => write!(f, "chart #{i}"),
            Place::State(i) => write!(f, "state #{i}"),
            Place::Transition(i) => write!(f, "transition #{i}"),
            Place::Action(i) => write!(f, "action #{i}"),
            Place::Route(i) => write!(f, "route #{i}"),
            Place::Peer(i) => write!(f, "peer #{i}"),
            Place::Publication(i) => write!(f, "publication #{i}"),
            Place::Subscription(i) => write!(f, "subscription #{i}"),
            Place::Safety => write!(f, "safety"),
            Place::Alarm(i) => write!(f, "alarm #{i}"),
        }
    }
}

impl fmt::Display for ExprError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExprError::Length(n) => write!(f, "expression of {n} operations (1..={MAX_EXPR_LEN})"),
            ExprError::OutOfCode { end, code_len } => {
                write!(
                    f,
                    "expression ends at {end}, past the {code_len} operations of code"
                )
            }
            ExprError::Underflow { at } => write!(f, "operation {at} reads past its operands"),
            ExprError::Overflow { at } => {
                write!(f, "operation {at} overflows the {MAX_STACK}-deep stack")
            }
            ExprError::Result { depth } => write!(f, "expression leaves {depth} values, not 1"),
            ExprError::Var { at, var } => write!(f, "operation {at} reads missing variable {var}"),
            ExprError::Input { at, input } => {
                write!(f, "operation {at} reads missing input {input}")
            }
            ExprError::Wrap { at, bits } => {
                write!(f, "operation {at} wraps to {bits} bits (8 or 16)")
            }
        }
    }
}

impl core::error::Error for ExprError {}

impl fmt::Display for Invalid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Invalid::Capacity { what, count, max } => {
                write!(f, "{count} {what} exceed the limit of {max}")
            }
            Invalid::Channel { channel } => write!(
                f,
                "channel {channel} is not an IEEE 802.15.4 2.4 GHz channel ({}..={})",
                CHANNELS.start(),
                CHANNELS.end()
            ),
            Invalid::Event { at, event } => write!(f, "{at}: event {event} does not exist"),
            Invalid::Var { at, var } => write!(f, "{at}: variable {var} does not exist"),
            Invalid::Timer { at, timer } => write!(f, "{at}: timer {timer} does not exist"),
            Invalid::Output { at, mask } => {
                write!(f, "{at}: output mask {mask:#06x} names missing outputs")
            }
            Invalid::Peer { at, peer } => write!(f, "{at}: peer {peer} does not exist"),
            Invalid::State { at, state } => {
                write!(f, "{at}: state {state} does not exist in its chart")
            }
            Invalid::ChartInput { at, input } => {
                write!(f, "{at}: chart input {input} does not exist")
            }
            Invalid::Chart { at, chart } => {
                write!(f, "{at}: routed to chart {chart}, which does not exist")
            }
            Invalid::Range { at } => write!(f, "{at}: pool range out of order"),
            Invalid::Expr { at, error } => write!(f, "{at}: {error}"),
            Invalid::Pin { at, pin } => {
                write!(f, "{at}: pin {pin} is out of range (0..={})", MAX_PINS - 1)
            }
            Invalid::Duplicate { at } => write!(f, "{at}: declared twice"),
            Invalid::NotPublished { at, event } => {
                write!(f, "{at}: publishes event {event}, which has no publication")
            }
            Invalid::Slow {
                event,
                cost,
                budget,
            } => write!(
                f,
                "a stimulus of event {event} may cost {cost} instructions, over the budget of \
                 {budget} (1 ms at 64 MHz) by {}",
                cost.saturating_sub(*budget)
            ),
        }
    }
}

impl core::error::Error for Invalid {}

fn capacity(what: &'static str, count: usize, max: usize) -> Result<(), Invalid> {
    if count > max {
        Err(Invalid::Capacity { what, count, max })
    } else {
        Ok(())
    }
}

fn idx(i: usize) -> u8 {
    u8::try_from(i).unwrap_or(u8::MAX)
}

/// Checks every semantic rule of a table. A table that passes can be run by the interpreter
/// without any out-of-range access. The first broken rule is the error, in this order:
/// header, pins, timers, charts and their transitions, states, actions, routes, radio
/// links.
pub fn validate(t: &Table) -> Result<(), Invalid> {
    validate_structure(t)?;
    time(t)
}

/// [`validate`] without the time bound: every index in range, so the interpreter can run
/// the table without a panic (what the interpreter's own tests of its runtime bounds need:
/// a table the time bound refuses still faults, never hangs).
pub fn validate_structure(t: &Table) -> Result<(), Invalid> {
    header(t)?;
    pins(t)?;
    for (i, timer) in t.timers.iter().enumerate() {
        event_ok(t, Place::Timer(idx(i)), timer.event)?;
    }
    charts(t)?;
    states(t)?;
    for (a, action) in t.actions.iter().enumerate() {
        action_ok(t, Place::Action(idx(a)), action)?;
    }
    routes(t)?;
    links(t)?;
    safety(t)
}

/// The emergency stop and the restart inputs name inputs the table has; each declared
/// alarm's condition is a well-formed expression.
fn safety(t: &Table) -> Result<(), Invalid> {
    let s = &t.safety;
    let inputs = t.inputs.len();
    if let Some(i) = s.estop.filter(|&i| usize::from(i) >= inputs) {
        return Err(Invalid::Expr {
            at: Place::Safety,
            error: ExprError::Input { at: 0, input: i },
        });
    }
    let all = 1u32.checked_shl(inputs as u32).map_or(u32::MAX, |b| b - 1);
    if u32::from(s.restart) & !all != 0 {
        return Err(Invalid::Expr {
            at: Place::Safety,
            error: ExprError::Input {
                at: 0,
                input: idx(inputs),
            },
        });
    }
    for (i, a) in s.alarms.iter().enumerate() {
        expr_ok(t, Place::Alarm(idx(i)), a.when)?;
    }
    Ok(())
}

/// The worst stimulus within [`STIMULUS_BUDGET`] (checked last: it reads the pools the
/// checks above found in range).
fn time(t: &Table) -> Result<(), Invalid> {
    let worst = worst_stimulus(t);
    if worst.cost > STIMULUS_BUDGET {
        return Err(Invalid::Slow {
            event: worst.event,
            cost: worst.cost,
            budget: STIMULUS_BUDGET,
        });
    }
    Ok(())
}

/// A node event id below `Table::events`.
fn event_ok(t: &Table, at: Place, event: u8) -> Result<(), Invalid> {
    if event < t.events {
        Ok(())
    } else {
        Err(Invalid::Event { at, event })
    }
}

/// A pin number below [`MAX_PINS`].
fn pin_ok(at: Place, pin: u8) -> Result<(), Invalid> {
    if usize::from(pin) < MAX_PINS {
        Ok(())
    } else {
        Err(Invalid::Pin { at, pin })
    }
}

/// An expression inside the code pool that checks (stack, variables, inputs).
fn expr_ok(t: &Table, at: Place, e: Expr) -> Result<(), Invalid> {
    let end = usize::from(e.start) + usize::from(e.len);
    if end > t.code.len() {
        return Err(Invalid::Expr {
            at,
            error: ExprError::OutOfCode {
                end,
                code_len: t.code.len(),
            },
        });
    }
    guard::check(t.expr(e), t.vars.len(), t.inputs.len())
        .map_err(|error| Invalid::Expr { at, error })
}

/// The radio channel, the event count and the START event.
fn header(t: &Table) -> Result<(), Invalid> {
    if !CHANNELS.contains(&t.header.channel) {
        return Err(Invalid::Channel {
            channel: t.header.channel,
        });
    }
    capacity("events", usize::from(t.events), MAX_EVENTS)?;
    for e in [t.start, t.home, t.boot].into_iter().flatten() {
        event_ok(t, Place::Header, e)?;
    }
    Ok(())
}

// `pins` keeps the pins taken in a `u64`.
const _: () = assert!(MAX_PINS <= 64);

/// Inputs (pin, events, variable) and outputs: each pin used once.
fn pins(t: &Table) -> Result<(), Invalid> {
    // Bit n: pin n is taken (every pin below `MAX_PINS` = 64 once `pin_ok` passed).
    let mut taken = 0u64;
    let mut take = |at: Place, pin: u8| -> Result<(), Invalid> {
        pin_ok(at, pin)?;
        let bit = 1u64 << (pin & 63);
        if taken & bit != 0 {
            return Err(Invalid::Duplicate { at });
        }
        taken |= bit;
        Ok(())
    };
    for (i, input) in t.inputs.iter().enumerate() {
        let at = Place::Input(idx(i));
        // The pin's range first, its duplicate last (after the events and the variable).
        pin_ok(at, input.pin)?;
        if let Some(e) = input.rise {
            event_ok(t, at, e)?;
        }
        if let Some(e) = input.fall {
            event_ok(t, at, e)?;
        }
        if let Some(v) = input.var {
            if usize::from(v) >= t.vars.len() {
                return Err(Invalid::Var { at, var: v });
            }
        }
        take(at, input.pin)?;
    }
    // A pin is an input or an output, once.
    for (i, output) in t.outputs.iter().enumerate() {
        take(Place::Output(idx(i)), output.pin)?;
    }
    Ok(())
}

/// Charts own consecutive, non-empty runs of states and runs of transitions that cover
/// both pools; each transition stays in its chart.
fn charts(t: &Table) -> Result<(), Invalid> {
    let (mut states_start, mut transitions_start) = (0usize, 0usize);
    for (c, chart) in t.charts.iter().enumerate() {
        let at = Place::Chart(idx(c));
        let (s_end, t_end) = (
            usize::from(chart.states_end),
            usize::from(chart.transitions_end),
        );
        if s_end <= states_start || s_end > t.states.len() || t_end < transitions_start {
            return Err(Invalid::Range { at });
        }
        let Some(transitions) = t.transitions.get(transitions_start..t_end) else {
            return Err(Invalid::Range { at });
        };
        capacity("chart inputs", usize::from(chart.inputs), MAX_CHART_INPUTS)?;
        let n_states = s_end - states_start;
        for state in [chart.initial, chart.idle] {
            if usize::from(state) >= n_states {
                return Err(Invalid::State { at, state });
            }
        }
        // A resting state past the chart's states: the lowest such bit.
        if n_states < 32 && chart.rests >> n_states != 0 {
            let past = chart.rests >> n_states << n_states;
            let state = past.trailing_zeros() as u8;
            return Err(Invalid::State { at, state });
        }
        for (ti, tr) in transitions.iter().enumerate() {
            transition_ok(
                t,
                Place::Transition(idx(transitions_start + ti)),
                tr,
                chart,
                n_states,
            )?;
        }
        states_start = s_end;
        transitions_start = t_end;
    }
    if states_start != t.states.len() {
        return Err(Invalid::Range {
            at: Place::State(idx(states_start)),
        });
    }
    if transitions_start != t.transitions.len() {
        return Err(Invalid::Range {
            at: Place::Transition(idx(transitions_start)),
        });
    }
    Ok(())
}

/// A transition of `chart` (of `n_states` states): its states, trigger and guard.
fn transition_ok(
    t: &Table,
    at: Place,
    tr: &Transition,
    chart: &Chart,
    n_states: usize,
) -> Result<(), Invalid> {
    for s in [tr.from, tr.to] {
        if usize::from(s) >= n_states {
            return Err(Invalid::State { at, state: s });
        }
    }
    if let Some(input) = tr.trigger {
        if input >= chart.inputs {
            return Err(Invalid::ChartInput { at, input });
        }
    }
    if let Some(g) = tr.guard {
        expr_ok(t, at, g)?;
    }
    Ok(())
}

/// States own consecutive runs of actions that cover the pool.
fn states(t: &Table) -> Result<(), Invalid> {
    let mut actions_start = 0usize;
    for (s, state) in t.states.iter().enumerate() {
        let end = usize::from(state.actions_end);
        if end < actions_start || end > t.actions.len() {
            return Err(Invalid::Range {
                at: Place::State(idx(s)),
            });
        }
        actions_start = end;
    }
    if actions_start != t.actions.len() {
        return Err(Invalid::Range {
            at: Place::Action(idx(actions_start)),
        });
    }
    Ok(())
}

/// One action: the variables, outputs, events and timers it names exist.
fn action_ok(t: &Table, at: Place, action: &Action) -> Result<(), Invalid> {
    let output_mask: u32 = (1u32 << t.outputs.len()) - 1;
    match *action {
        Action::Set { var, expr } => {
            if usize::from(var) >= t.vars.len() {
                return Err(Invalid::Var { at, var });
            }
            expr_ok(t, at, expr)?;
        }
        Action::Drive { mask, value } => {
            if u32::from(mask | value) & !output_mask != 0 {
                return Err(Invalid::Output {
                    at,
                    mask: mask | value,
                });
            }
        }
        Action::Emit(e) => event_ok(t, at, e)?,
        Action::Publish(e) => {
            event_ok(t, at, e)?;
            if t.publication(e).is_none() {
                return Err(Invalid::NotPublished { at, event: e });
            }
        }
        Action::StartTimer { timer, .. } | Action::CancelTimer(timer) => {
            if usize::from(timer) >= t.timers.len() {
                return Err(Invalid::Timer { at, timer });
            }
        }
        Action::Fault(_) => {}
    }
    Ok(())
}

/// Routing: each route from an event to an input of an existing chart.
fn routes(t: &Table) -> Result<(), Invalid> {
    for (r, route) in t.routes.iter().enumerate() {
        let at = Place::Route(idx(r));
        event_ok(t, at, route.event)?;
        let chart = t
            .charts
            .get(usize::from(route.chart))
            .ok_or(Invalid::Chart {
                at,
                chart: route.chart,
            })?;
        if route.input >= chart.inputs {
            return Err(Invalid::ChartInput {
                at,
                input: route.input,
            });
        }
    }
    Ok(())
}

/// Radio links: distinct peers, publications to existing peers (one per event and per
/// topic), subscriptions from existing peers (one per publisher and topic).
fn links(t: &Table) -> Result<(), Invalid> {
    for (p, peer) in t.peers.iter().enumerate() {
        if *peer == 0xFFFF || t.peers.iter().take(p).any(|q| q == peer) {
            return Err(Invalid::Duplicate {
                at: Place::Peer(idx(p)),
            });
        }
    }
    let peer_mask: u32 = (1u32 << t.peers.len()) - 1;
    for (p, publication) in t.publications.iter().enumerate() {
        let at = Place::Publication(idx(p));
        event_ok(t, at, publication.event)?;
        if u32::from(publication.subscribers) & !peer_mask != 0 {
            let stray = u32::from(publication.subscribers) & !peer_mask;
            let peer = idx(stray.trailing_zeros() as usize);
            return Err(Invalid::Peer { at, peer });
        }
        if t.publications
            .iter()
            .take(p)
            .any(|o| o.event == publication.event || o.topic == publication.topic)
        {
            return Err(Invalid::Duplicate { at });
        }
    }
    for (s, sub) in t.subscriptions.iter().enumerate() {
        let at = Place::Subscription(idx(s));
        event_ok(t, at, sub.event)?;
        if usize::from(sub.publisher) >= t.peers.len() {
            return Err(Invalid::Peer {
                at,
                peer: sub.publisher,
            });
        }
        if t.subscriptions
            .iter()
            .take(s)
            .any(|o| o.publisher == sub.publisher && o.topic == sub.topic)
        {
            return Err(Invalid::Duplicate { at });
        }
    }
    Ok(())
}
