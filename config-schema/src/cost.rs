//! The worst-case work of one stimulus (an input edge, a timer expiry, a remote event, a
//! command), computed from the table alone, so that [`validate`](fn@crate::validate) can
//! refuse a table whose stimulus could keep the node deaf for long (docs/ecc-semantics.md).
//!
//! The model follows the interpreter (`node_fw::ecc`): a stimulus is dispatched, then every
//! event its charts emit, up to [`MAX_CASCADE`] events. One
//! dispatch scans every route; each route of the event delivers to its chart, which scans
//! the chart's transitions (evaluating the guards of those that leave its current state on
//! that input: the state with the longest of them, in the worst case), fires one and runs
//! the target state's actions, then (a chart with event-less transitions) up to
//! [`MAX_CHAIN`] more. Each frame a publication sends costs
//! [`weights::FRAME`]. The count of events a cascade processes follows the emit graph: an
//! event reaches the events its charts' states emit; a cycle counts as the whole cascade.
//!
//! Work is counted in instructions of the node's Cortex-M, with the weights below (the
//! interpreter's loops as QEMU counts them on the Cortex-M3 image, and one secured frame
//! with the nRF52840's AES peripheral); the budget keeps one stimulus under 1 ms at
//! 64 MHz. Everything is a bound: a real stimulus takes less.

use crate::limits::{MAX_CASCADE, MAX_CHAIN, MAX_CHARTS, MAX_EVENTS, MAX_STATES};
use crate::table::{Action, EventId, Table};

/// Instructions per unit of work (docs/ecc-semantics.md, "Time per stimulus"). Measured on
/// the QEMU Cortex-M3 image (`-icount shift=0`) with the worst table the budget allows (a
/// transition with a 31-operation guard: 834 instructions; the rest of one stimulus: about
/// 1,130), with a margin; the others are estimates of the same loops.
pub mod weights {
    /// Entering the node with one stimulus (its engine resumed, its effects applied).
    pub const STIMULUS: u64 = 1_200;
    /// An event taken from the queue and dispatched.
    pub const EVENT: u64 = 120;
    /// A route looked at during a dispatch.
    pub const ROUTE: u64 = 10;
    /// A delivery to a chart.
    pub const DELIVER: u64 = 60;
    /// A transition looked at when a chart selects one.
    pub const TRANSITION: u64 = 30;
    /// One operation of a guard or an assignment.
    pub const OP: u64 = 30;
    /// A transition fired.
    pub const FIRE: u64 = 60;
    /// One action run.
    pub const ACTION: u64 = 40;
    /// One output driven.
    pub const PIN: u64 = 40;
    /// One secured event frame put on a link (a publication sends one per subscriber):
    /// CCM* of a short event frame is about seven AES blocks, each a few hundred cycles on
    /// the nRF52840's AES peripheral, plus the header, the encoding and the link's queue
    /// (an estimate: the QEMU image's software AES costs about 36,500, `demo --qemu
    /// --icount`).
    pub const FRAME: u64 = 4_000;
}

/// The most a table's worst stimulus may cost: 1 ms at 64 MHz.
pub const STIMULUS_BUDGET: u64 = 64_000;

/// A table's worst stimulus: what it may cost and which event it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Worst {
    /// Instructions (a bound).
    pub cost: u64,
    /// The node event whose stimulus costs that much.
    pub event: EventId,
    /// The events its cascade may process (at most `MAX_CASCADE`).
    pub cascade: u32,
}

/// The worst stimulus of `t` (every node event taken as a stimulus). `t` must have passed
/// the structural checks of [`validate`](fn@crate::validate) (ranges); anything out of range
/// is counted as nothing.
pub fn worst_stimulus(t: &Table) -> Worst {
    let model = Model::of(t);
    let mut worst = Worst {
        cost: 0,
        event: 0,
        cascade: 0,
    };
    for e in 0..t.events.min(MAX_EVENTS as u8) {
        let (cost, cascade) = model.stimulus(t, e);
        if cost > worst.cost {
            worst = Worst {
                cost,
                event: e,
                cascade,
            };
        }
    }
    worst
}

/// What every dispatch of an event needs, computed once.
struct Model {
    /// Per event: the work of one dispatch (its own publication not included).
    dispatch: [u64; MAX_EVENTS],
    /// Per event: the events its deliveries may emit (bit i: event i).
    reaches: [u64; MAX_EVENTS],
    /// Per event: how many events one dispatch may emit.
    emits: [u64; MAX_EVENTS],
}

impl Model {
    fn of(t: &Table) -> Model {
        let charts: [Option<ChartCost>; MAX_CHARTS] = core::array::from_fn(|c| ChartCost::of(t, c));
        let mut model = Model {
            dispatch: [weights::EVENT + weights::ROUTE * t.routes.len() as u64; MAX_EVENTS],
            reaches: [0; MAX_EVENTS],
            emits: [0; MAX_EVENTS],
        };
        for r in &t.routes {
            let (e, c) = (usize::from(r.event), usize::from(r.chart));
            let (Some(Some(chart)), true) = (charts.get(c), e < MAX_EVENTS) else {
                continue;
            };
            let d = chart.delivery(t, c, r.input);
            model.dispatch[e] += d.cost;
            model.reaches[e] |= d.emit_set;
            model.emits[e] += d.emits;
        }
        model
    }

    /// (cost, events processed) of stimulus `e`: its own publication, then its cascade.
    fn stimulus(&self, t: &Table, e: EventId) -> (u64, u32) {
        let mut memo = [Cascade::default(); MAX_EVENTS];
        let mut state = [Visit::New; MAX_EVENTS];
        let c = self.cascade(usize::from(e), &mut memo, &mut state);
        let own = t.publication(e).map_or(0, |p| {
            weights::FRAME * u64::from(p.subscribers.count_ones())
        });
        (
            weights::STIMULUS.saturating_add(own).saturating_add(c.cost),
            c.events,
        )
    }

    /// The cascade of one dispatch of `e`: the dispatch, then what its deliveries may emit,
    /// each with its own cascade (the dearest of the events it may emit, as many times as
    /// it may emit). A cycle, or more than `MAX_CASCADE` events, is the whole cascade:
    /// `MAX_CASCADE` events, each at most the dearest dispatch of the table. The recursion
    /// is at most `MAX_EVENTS` deep (an event open on the path is a cycle).
    fn cascade(
        &self,
        e: usize,
        memo: &mut [Cascade; MAX_EVENTS],
        state: &mut [Visit; MAX_EVENTS],
    ) -> Cascade {
        let whole = Cascade {
            cost: MAX_CASCADE as u64 * self.dispatch.iter().copied().max().unwrap_or(0),
            events: MAX_CASCADE as u32,
        };
        match state.get(e).copied() {
            None | Some(Visit::Open) => return whole,
            Some(Visit::Done) => return memo[e],
            Some(Visit::New) => {}
        }
        state[e] = Visit::Open;
        let mut dearest = Cascade::default();
        let mut next = self.reaches[e];
        while next != 0 {
            let s = next.trailing_zeros() as usize;
            next &= next - 1;
            let c = self.cascade(s, memo, state);
            dearest.cost = dearest.cost.max(c.cost);
            dearest.events = dearest.events.max(c.events);
        }
        let k = self.emits[e];
        let events = u64::from(dearest.events)
            .saturating_mul(k)
            .saturating_add(1);
        let c = if events > MAX_CASCADE as u64 {
            whole
        } else {
            Cascade {
                cost: self.dispatch[e]
                    .saturating_add(dearest.cost.saturating_mul(k))
                    .min(whole.cost),
                events: events as u32,
            }
        };
        state[e] = Visit::Done;
        memo[e] = c;
        c
    }
}

/// What selecting in a chart costs, and how long its event-less chains can be.
struct ChartCost {
    /// Looking at every transition of the chart (the interpreter scans them all; it
    /// evaluates the guards of those leaving the current state on the input only).
    scan: u64,
    /// Whether it has event-less transitions (a delivery then ends with a select that
    /// finds none).
    eventless: bool,
    /// Per chart-local state: how many event-less transitions can fire in a row from it
    /// (the longest path; `MAX_CHAIN` from a state that reaches a cycle).
    chain: [u64; MAX_STATES],
    /// Per chart-local state: the guard operations of its event-less transitions.
    eventless_ops: [u64; MAX_STATES],
}

/// One delivery of a chart input.
struct Delivery {
    cost: u64,
    emits: u64,
    emit_set: u64,
}

impl ChartCost {
    fn of(t: &Table, c: usize) -> Option<ChartCost> {
        t.charts.get(c)?;
        let transitions = t.transitions.get(t.chart_transitions(c)).unwrap_or(&[]);
        let mut eventless_ops = [0u64; MAX_STATES];
        for tr in transitions.iter().filter(|tr| tr.trigger.is_none()) {
            if let Some(ops) = eventless_ops.get_mut(usize::from(tr.from)) {
                *ops += u64::from(tr.guard.map_or(0, |g| g.len));
            }
        }
        Some(ChartCost {
            scan: weights::TRANSITION * transitions.len() as u64,
            eventless: transitions.iter().any(|tr| tr.trigger.is_none()),
            chain: chains(t, c),
            eventless_ops,
        })
    }

    /// Input `input` delivered to chart `c`: the select (from whatever state the chart is
    /// in: the one whose transitions on the input have the longest guards), the dearest
    /// transition it can fire, then the event-less chain from where that leads (each step
    /// a select and the dearest event-less target reachable from there), and the events
    /// all of these may emit.
    fn delivery(&self, t: &Table, c: usize, input: u8) -> Delivery {
        let transitions = t.transitions.get(t.chart_transitions(c)).unwrap_or(&[]);
        let n = t.chart_states(c).len().min(MAX_STATES);
        let mut on_input = [0u64; MAX_STATES];
        let mut first = StateCost::default();
        let mut chain = 0u64;
        // States a chain may pass: where the input leads, then event-less targets.
        let mut reached = [false; MAX_STATES];
        let mut todo = [0u8; MAX_STATES];
        let mut top = 0usize;
        for tr in transitions.iter().filter(|tr| tr.trigger == Some(input)) {
            if let Some(ops) = on_input.get_mut(usize::from(tr.from)) {
                *ops += u64::from(tr.guard.map_or(0, |g| g.len));
            }
            let to = state_cost(t, c, tr.to);
            first.fire = first.fire.max(to.fire);
            first.emits = first.emits.max(to.emits);
            first.emit_set |= to.emit_set;
            chain = chain.max(self.chain.get(usize::from(tr.to)).copied().unwrap_or(0));
            let at = usize::from(tr.to);
            if at < n && !reached[at] && top < MAX_STATES {
                reached[at] = true;
                todo[top] = tr.to;
                top += 1;
            }
        }
        let mut then = StateCost::default();
        while top > 0 {
            top -= 1;
            let from = todo[top];
            for tr in transitions
                .iter()
                .filter(|tr| tr.trigger.is_none() && tr.from == from)
            {
                let to = usize::from(tr.to);
                if to >= n || reached[to] {
                    continue;
                }
                reached[to] = true;
                let cost = state_cost(t, c, tr.to);
                then.fire = then.fire.max(cost.fire);
                then.emits = then.emits.max(cost.emits);
                then.emit_set |= cost.emit_set;
                if top < MAX_STATES {
                    todo[top] = tr.to;
                    top += 1;
                }
            }
        }
        let guards = on_input.iter().copied().max().unwrap_or(0);
        let chain_guards = (0..n)
            .filter(|&s| reached[s])
            .map(|s| self.eventless_ops[s])
            .max()
            .unwrap_or(0);
        let select = self.scan + weights::OP * guards;
        let chain_select = self.scan + weights::OP * chain_guards;
        let last = if self.eventless { chain_select } else { 0 };
        Delivery {
            cost: weights::DELIVER
                + select
                + first.fire
                + chain * (chain_select + then.fire)
                + last,
            emits: first.emits + chain * then.emits,
            emit_set: first.emit_set | then.emit_set,
        }
    }
}

/// Entering one state: its actions' work, how many events it emits, and which.
#[derive(Debug, Clone, Copy, Default)]
struct StateCost {
    fire: u64,
    emits: u64,
    emit_set: u64,
}

/// Entering chart-local state `state` of chart `c`.
fn state_cost(t: &Table, c: usize, state: u8) -> StateCost {
    let s = t.chart_states(c).start + usize::from(state);
    let actions = t.actions.get(t.state_actions(s)).unwrap_or(&[]);
    let mut out = StateCost {
        fire: weights::FIRE,
        ..StateCost::default()
    };
    for a in actions {
        out.fire += weights::ACTION + action_cost(t, a);
        if let Action::Emit(e) = a {
            out.emits += 1;
            out.emit_set |= 1u64.checked_shl(u32::from(*e)).unwrap_or(0);
        }
    }
    out
}

/// The work and the events of a cascade.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Cascade {
    cost: u64,
    events: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Visit {
    New,
    Open,
    Done,
}

/// Per chart-local state of chart `c`: how many event-less transitions can fire in a row
/// from it: the longest path of event-less transitions, or `MAX_CHAIN` from a state that
/// reaches a cycle of them (the interpreter faults past `MAX_CHAIN`).
fn chains(t: &Table, c: usize) -> [u64; MAX_STATES] {
    let transitions = t.transitions.get(t.chart_transitions(c)).unwrap_or(&[]);
    let n = t.chart_states(c).len().min(MAX_STATES);
    // Longest paths by relaxation: after n + 1 rounds a state still over n - 1 reaches a
    // cycle (an acyclic path visits each state once).
    let mut longest = [0u64; MAX_STATES];
    for _ in 0..=n {
        let mut changed = false;
        for tr in transitions.iter().filter(|tr| tr.trigger.is_none()) {
            let (from, to) = (usize::from(tr.from), usize::from(tr.to));
            if from >= n || to >= n {
                continue;
            }
            let through = longest[to].saturating_add(1);
            if through > longest[from] {
                longest[from] = through;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    for l in longest.iter_mut() {
        *l = if *l >= n as u64 && *l > 0 {
            MAX_CHAIN as u64
        } else {
            (*l).min(MAX_CHAIN as u64)
        };
    }
    longest
}

/// What one action costs besides [`weights::ACTION`].
fn action_cost(t: &Table, a: &Action) -> u64 {
    let frames = |e: EventId| {
        t.publication(e).map_or(0, |p| {
            weights::FRAME * u64::from(p.subscribers.count_ones())
        })
    };
    match *a {
        Action::Set { expr, .. } => weights::OP * u64::from(expr.len),
        Action::Drive { mask, .. } => weights::PIN * u64::from(mask.count_ones()),
        Action::Emit(e) | Action::Publish(e) => frames(e),
        Action::StartTimer { .. } | Action::CancelTimer(_) | Action::Fault(_) => 0,
    }
}
