//! A table compiled once, when it is installed, into the form the interpreter runs: each
//! event's routes as (chart, input) pairs, each state's transitions in declaration order
//! with their guards lowered ([`Calc`]), each state's actions with their assignments
//! lowered and their publications resolved, each event's publication, the states with
//! event-less transitions, and the output masks. A stimulus then walks short arrays with
//! one bounds check each and never decodes or re-validates the table.
//!
//! Derived data only: the table stays the one validated form, and an index built from it
//! gives exactly the order the pools have (the first matching transition in declaration
//! order, the routes in table order). Built without panics from any table: an entry that
//! points outside the pools is left out, as the interpreter over the bare table skipped it
//! (validation refuses such tables anyway), and so is a transition triggered by chart
//! input 255 (no chart has that many inputs).
//!
//! Its size is fixed by the capacities of `config_schema::limits` (8 bytes a transition,
//! 7 an action, 2 a route, plus per-event and per-state spans): `Index::BYTES`.

use config_schema::limits::{
    MAX_ACTIONS, MAX_CHARTS, MAX_EVENTS, MAX_ROUTES, MAX_STATES, MAX_TRANSITIONS,
};
use config_schema::{Action, EventId, Table};

use super::calc::Calc;

/// No entry (a publication, a pool index).
pub(super) const NONE: u8 = u8::MAX;
/// The trigger of an event-less transition.
pub(super) const EVENTLESS: u8 = u8::MAX;

// Every pool index and span end fits a `u8` below `NONE`, and a state set fits a `u128`.
const _: () = assert!(MAX_ROUTES < NONE as usize);
const _: () = assert!(MAX_TRANSITIONS < NONE as usize);
const _: () = assert!(MAX_ACTIONS < NONE as usize);
const _: () = assert!(MAX_EVENTS <= NONE as usize);
const _: () = assert!(MAX_STATES <= 128);

/// Where a chart's states are in the table's pool.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct Layout {
    /// Its first state in `Table::states` (chart-local state `s` is `first_state + s`).
    pub first_state: u8,
    /// Its number of states.
    pub states: u8,
}

/// Where a route delivers.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct Target {
    pub chart: u8,
    pub input: u8,
}

/// A transition as the interpreter takes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Step {
    /// The chart input that triggers it, or [`EVENTLESS`].
    pub trigger: u8,
    /// Its target, chart-local.
    pub to: u8,
    /// Its index in `Table::transitions` (for the trace).
    pub index: u8,
    /// Its guard ([`Calc::TRUE`] if it has none).
    pub guard: Calc,
}

const NO_STEP: Step = Step {
    trigger: EVENTLESS,
    to: 0,
    index: 0,
    guard: Calc::TRUE,
};

/// An action as the interpreter runs it (multi-byte fields as bytes: 7 bytes an action).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Act {
    /// `var := calc` (`var` below `MAX_VARS`).
    Set { var: u8, calc: Calc },
    /// An assignment to a variable the engine does not have: evaluated (it may fault),
    /// the value dropped.
    Eval { calc: Calc },
    /// Drive the outputs of `mask` to `value` (little-endian `u16`s).
    Drive { mask: [u8; 2], value: [u8; 2] },
    /// Queue `event`; once queued, publish `publication` (`NONE`: it has none).
    Emit { event: EventId, publication: u8 },
    /// Publish `publication` (`NONE`: the event has none, nothing to do).
    Publish { publication: u8 },
    /// Start `timer` for `ms` (a little-endian `u32`).
    StartTimer { timer: u8, ms: [u8; 4] },
    CancelTimer(u8),
    Fault(u8),
}

const _: () = assert!(core::mem::size_of::<Step>() == 8);
const _: () = assert!(core::mem::size_of::<Act>() == 7);

/// A range `start..end` of one of the index's pools.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct Span {
    pub start: u8,
    pub end: u8,
}

/// A table's compiled form, built once by [`Index::new`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Index {
    pub(super) layout: [Layout; MAX_CHARTS],
    /// Per event: its routes, `routes[route_at[e]..route_at[e + 1]]`, in table order.
    route_at: [u8; MAX_EVENTS + 1],
    routes: [Target; MAX_ROUTES],
    /// Per event: its publication's index (`NONE`: not published).
    publication: [u8; MAX_EVENTS],
    /// Per global state: the transitions leaving it, `steps[step_at[s]..step_at[s + 1]]`,
    /// in declaration order.
    step_at: [u8; MAX_STATES + 1],
    steps: [Step; MAX_TRANSITIONS],
    /// Per global state: the actions run on entering it (indices of `Table::actions`).
    acts_of: [Span; MAX_STATES],
    acts: [Act; MAX_ACTIONS],
    /// Bit s: global state s has an event-less transition leaving it.
    eventless: u128,
    /// The table's outputs (bit i: output i exists), the start drive and the fault drive
    /// (mask, levels).
    pub(super) outputs: u16,
    pub(super) start_drive: (u16, u16),
    pub(super) fault_drive: (u16, u16),
}

impl Index {
    /// Bytes of an index (every table's: the pools are sized by the capacities).
    pub const BYTES: usize = core::mem::size_of::<Index>();

    /// The index of `table`.
    pub fn new(table: &Table) -> Index {
        let mut ix = Index {
            layout: [Layout::default(); MAX_CHARTS],
            route_at: [0; MAX_EVENTS + 1],
            routes: [Target::default(); MAX_ROUTES],
            publication: [NONE; MAX_EVENTS],
            step_at: [0; MAX_STATES + 1],
            steps: [NO_STEP; MAX_TRANSITIONS],
            acts_of: [Span::default(); MAX_STATES],
            acts: [Act::Fault(0); MAX_ACTIONS],
            eventless: 0,
            outputs: ((1u32 << table.outputs.len().min(16)) - 1) as u16,
            start_drive: table.start_drive(),
            fault_drive: table.fault_drive(),
        };
        for (c, slot) in ix.layout.iter_mut().enumerate().take(table.charts.len()) {
            let states = table.chart_states(c);
            *slot = Layout {
                first_state: states.start.min(usize::from(NONE)) as u8,
                states: states.len().min(usize::from(NONE)) as u8,
            };
        }
        for (p, publication) in table.publications.iter().enumerate().rev() {
            if let Some(slot) = ix.publication.get_mut(usize::from(publication.event)) {
                *slot = p.min(usize::from(NONE)) as u8;
            }
        }
        ix.build_routes(table);
        ix.build_steps(table);
        ix.build_acts(table);
        ix
    }

    /// The routes, grouped by event (a counting sort: table order within an event).
    fn build_routes(&mut self, table: &Table) {
        let mut count = [0u8; MAX_EVENTS];
        for r in table.routes.iter().take(MAX_ROUTES) {
            if let Some(n) = count.get_mut(usize::from(r.event)) {
                *n += 1;
            }
        }
        let mut at = 0u8;
        for (e, n) in count.iter().enumerate() {
            self.route_at[e] = at;
            at += n;
        }
        self.route_at[MAX_EVENTS] = at;
        let mut next: [u8; MAX_EVENTS] = core::array::from_fn(|e| self.route_at[e]);
        for r in table.routes.iter().take(MAX_ROUTES) {
            if let Some(n) = next.get_mut(usize::from(r.event)) {
                if let Some(slot) = self.routes.get_mut(usize::from(*n)) {
                    *slot = Target {
                        chart: r.chart,
                        input: r.input,
                    };
                }
                *n += 1;
            }
        }
    }

    /// The transitions, grouped by the global state they leave (charts in order, then
    /// declaration order).
    fn build_steps(&mut self, table: &Table) {
        let mut n = 0usize;
        for s in 0..MAX_STATES {
            self.step_at[s] = n as u8;
            for (c, layout) in self.layout.iter().enumerate().take(table.charts.len()) {
                let first = usize::from(layout.first_state);
                if s < first || s - first >= usize::from(layout.states) {
                    continue;
                }
                let local = (s - first) as u8;
                let range = table.chart_transitions(c);
                let Some(ts) = table.transitions.get(range.clone()) else {
                    continue;
                };
                for (i, t) in ts.iter().enumerate() {
                    let trigger = t.trigger.unwrap_or(EVENTLESS);
                    if t.from != local || t.trigger == Some(EVENTLESS) {
                        continue;
                    }
                    let Some(slot) = self.steps.get_mut(n) else {
                        continue;
                    };
                    *slot = Step {
                        trigger,
                        to: t.to,
                        index: (range.start + i) as u8,
                        guard: Calc::lower(table, t.guard),
                    };
                    n += 1;
                    if trigger == EVENTLESS {
                        self.eventless |= 1u128 << s;
                    }
                }
            }
        }
        self.step_at[MAX_STATES] = n as u8;
    }

    /// The actions, lowered one for one, and each state's span of them.
    fn build_acts(&mut self, table: &Table) {
        for (slot, action) in self.acts.iter_mut().zip(table.actions.iter()) {
            let publication = |e: EventId| {
                (self.publication)
                    .get(usize::from(e))
                    .copied()
                    .unwrap_or(NONE)
            };
            *slot = match *action {
                Action::Set { var, expr } => {
                    let calc = Calc::lower(table, Some(expr));
                    if usize::from(var) < config_schema::limits::MAX_VARS {
                        Act::Set { var, calc }
                    } else {
                        Act::Eval { calc }
                    }
                }
                Action::Drive { mask, value } => Act::Drive {
                    mask: mask.to_le_bytes(),
                    value: value.to_le_bytes(),
                },
                Action::Emit(event) => Act::Emit {
                    event,
                    publication: publication(event),
                },
                Action::Publish(event) => Act::Publish {
                    publication: publication(event),
                },
                Action::StartTimer { timer, ms } => Act::StartTimer {
                    timer,
                    ms: ms.to_le_bytes(),
                },
                Action::CancelTimer(timer) => Act::CancelTimer(timer),
                Action::Fault(code) => Act::Fault(code),
            };
        }
        for (s, span) in self.acts_of.iter_mut().enumerate() {
            let range = table.state_actions(s);
            if range.end <= table.actions.len() {
                *span = Span {
                    start: range.start as u8,
                    end: range.end as u8,
                };
            }
        }
    }

    /// The routes of `event`, in table order.
    #[inline(always)]
    pub(super) fn routes(&self, event: EventId) -> &[Target] {
        let e = usize::from(event);
        match (self.route_at.get(e), self.route_at.get(e + 1)) {
            (Some(&start), Some(&end)) => (self.routes)
                .get(usize::from(start)..usize::from(end))
                .unwrap_or(&[]),
            _ => &[],
        }
    }

    /// The transitions leaving global state `state`, in declaration order.
    #[inline(always)]
    pub(super) fn steps(&self, state: usize) -> &[Step] {
        match (self.step_at.get(state), self.step_at.get(state + 1)) {
            (Some(&start), Some(&end)) => (self.steps)
                .get(usize::from(start)..usize::from(end))
                .unwrap_or(&[]),
            _ => &[],
        }
    }

    /// The actions run on entering global state `state`, in order.
    #[inline(always)]
    pub(super) fn acts(&self, state: usize) -> &[Act] {
        match self.acts_of.get(state) {
            Some(span) => (self.acts)
                .get(usize::from(span.start)..usize::from(span.end))
                .unwrap_or(&[]),
            None => &[],
        }
    }

    /// The index of `event`'s publication (`NONE`: not published).
    #[inline(always)]
    pub(super) fn publication(&self, event: EventId) -> u8 {
        self.publication
            .get(usize::from(event))
            .copied()
            .unwrap_or(NONE)
    }

    /// Whether global state `state` has an event-less transition leaving it.
    #[inline(always)]
    pub(super) fn eventless(&self, state: usize) -> bool {
        state < 128 && self.eventless & (1u128 << state) != 0
    }
}
