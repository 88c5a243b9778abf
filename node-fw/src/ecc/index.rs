//! A table compiled once, when it is installed, into the form the interpreter runs: each
//! event's routes as (chart, input) pairs, each state's transitions in declaration order
//! with their guards lowered ([`Calc`]) and each one's target entry, each state's entry
//! (its actions with their assignments lowered and their publications resolved, then one
//! operation that closes it: the chart is stable, the event-less transition that always
//! follows the entry is fired (fused: taken without a choice), or the event-less
//! transitions are chosen by their guards), each event's publication and the output
//! masks. A stimulus then walks short arrays, an entry one operation after the other, and
//! never decodes or re-validates the table.
//!
//! Derived data only: the table stays the one validated form, and an index built from it
//! gives exactly the order the pools have (the first matching transition in declaration
//! order, the routes in table order, a state's actions in table order). Built without
//! panics from any table: an entry that points outside the pools is left out, as the
//! interpreter over the bare table skipped it (validation refuses such tables anyway),
//! and so is a transition triggered by chart input 255 (no chart has that many inputs).
//!
//! Its size is fixed by the capacities of `config_schema::limits` (9 bytes a transition,
//! 6 an operation, 256 operations, 2 a route, plus per-event and per-state records):
//! `Index::BYTES`.

use config_schema::limits::{
    MAX_ACTIONS, MAX_CHARTS, MAX_EVENTS, MAX_INPUTS, MAX_PUBLICATIONS, MAX_ROUTES, MAX_STATES,
    MAX_TRANSITIONS,
};
use config_schema::{Action, EventId, Publication, Table};

use super::calc::{self, Calc};

/// No entry (a publication, a pool index).
pub(super) const NONE: u8 = u8::MAX;
/// The trigger of an event-less transition.
pub(super) const EVENTLESS: u8 = u8::MAX;
/// What follows the entry of a state whose event-less transitions are chosen by their
/// guards at run time (while the index is built).
pub(super) const CHOOSE: u8 = u8::MAX - 1;

// Every pool index and span end fits a `u8` below `NONE`.
const _: () = assert!(MAX_ROUTES < NONE as usize);
/// The routes' pool: a power of two, so that a route's index masked is in range.
const ROUTES: usize = 128;
const _: () = assert!(MAX_ROUTES <= ROUTES && ROUTES.is_power_of_two());
const _: () = assert!(MAX_TRANSITIONS < CHOOSE as usize);
const _: () = assert!(MAX_ACTIONS < NONE as usize);
/// The operations' pool: every state's actions and close fit, and an index is a `u8`.
const OPS: usize = 256;
const _: () = assert!(MAX_ACTIONS + MAX_STATES <= OPS);

const END: Act = Act {
    code: act::END,
    dst: 0,
    w: [0; 4],
};
const _: () = assert!(MAX_EVENTS <= NONE as usize);
const _: () = assert!(MAX_INPUTS.is_power_of_two() && MAX_EVENTS.is_power_of_two());

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
    /// Its target's entry in `Index::ops` (a target past `MAX_STATES`: the shared
    /// [`act::END`]).
    pub entry: u8,
    /// Its index in `Table::transitions` (for the trace).
    pub index: u8,
    /// Its guard ([`Calc::TRUE`] if it has none).
    pub guard: Calc,
}

const NO_STEP: Step = Step {
    trigger: EVENTLESS,
    to: 0,
    entry: 0,
    index: 0,
    guard: Calc::TRUE,
};

/// An action as the interpreter runs it: `code` up to [`calc::LAST_CODE`] is an assignment
/// `dst := (code, w)` (a lowered expression, [`Calc`]; `dst` = `NONE`: a variable the engine
/// does not have, evaluated for its fault and dropped); above, one of the `act` codes with
/// its operands in `dst` and `w`. Six bytes an action.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
pub(super) struct Act {
    pub code: u8,
    pub dst: u8,
    pub w: [u8; 4],
}

/// The action codes above the assignments'.
pub(super) mod act {
    use super::calc::LAST_CODE;
    /// Drive outputs: `w` = mask, levels (little-endian `u16`s).
    pub const DRIVE: u8 = LAST_CODE + 1;
    /// Queue event `dst`; once queued, publish publication `w[0]` (`NONE`: none).
    pub const EMIT: u8 = LAST_CODE + 2;
    /// Publish publication `w[0]` (`NONE`: none, nothing to do).
    pub const PUBLISH: u8 = LAST_CODE + 3;
    /// Start timer `dst` for `w` ms (a little-endian `u32`).
    pub const START_TIMER: u8 = LAST_CODE + 4;
    /// Cancel timer `dst`.
    pub const CANCEL_TIMER: u8 = LAST_CODE + 5;
    /// Fault the node with code `dst`.
    pub const FAULT: u8 = LAST_CODE + 6;
    /// An assignment to a variable the engine does not have: the expression `(dst, w)`
    /// evaluated for its fault, its value dropped.
    pub const DISCARD: u8 = LAST_CODE + 7;
    /// The close of an entry after which the chart is stable (no event-less transition
    /// leaves the state).
    pub const END: u8 = LAST_CODE + 8;
    /// The close of an entry whose first event-less transition always holds (taken
    /// without a choice: no earlier event-less transition is a candidate and its guard
    /// cannot fault): fire it, to chart-local `dst`, `w[0]` its table index, `w[1]` its
    /// target's entry; `w[2]` non-zero: the chart is stable after the firing (the target
    /// has no actions and no event-less transition, or is past `MAX_STATES`).
    pub const FIRE: u8 = LAST_CODE + 9;
    /// The close of an entry whose event-less transitions are chosen by their guards: the
    /// transitions of global state `dst`.
    pub const CHOOSE: u8 = LAST_CODE + 10;
    /// A drive (as [`DRIVE`]) closing an entry as [`END`] does.
    pub const DRIVE_END: u8 = LAST_CODE + 11;
    /// An emit (as [`EMIT`]) closing an entry as [`END`] does.
    pub const EMIT_END: u8 = LAST_CODE + 12;
    /// An emit of event `dst` (publication `w[0]`), then a close as [`FIRE`] after which
    /// the chart is stable: to chart-local `w[1]`, `w[2]` its table index.
    pub const EMIT_FIRE: u8 = LAST_CODE + 13;
}

const _: () = assert!(core::mem::size_of::<Step>() == 9);
const _: () = assert!(core::mem::size_of::<Act>() == 6);

/// A range `start..end` of one of the index's pools, a pool of `N` entries: always
/// `start <= end <= N`. [`Span::new`] is its only constructor and establishes that (a range
/// outside is made empty), so a span is read from its pool without a bounds check
/// ([`span_of`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Span<const N: usize> {
    start: u8,
    end: u8,
}

impl<const N: usize> Span<N> {
    /// The empty span.
    pub(super) const EMPTY: Span<N> = Span { start: 0, end: 0 };

    /// `start..end`, or the empty span if that is not inside a pool of `N` entries.
    fn new(start: usize, end: usize) -> Span<N> {
        if start <= end && end <= N && end <= usize::from(u8::MAX) {
            Span {
                start: start as u8,
                end: end as u8,
            }
        } else {
            Span::EMPTY
        }
    }
}

impl<const N: usize> Span<N> {
    /// `(start, end)`.
    #[inline(always)]
    pub(super) fn bounds(self) -> (u8, u8) {
        (self.start, self.end)
    }
}

impl<const N: usize> Default for Span<N> {
    fn default() -> Self {
        Span::EMPTY
    }
}

type RouteSpan = Span<ROUTES>;
type StepSpan = Span<MAX_TRANSITIONS>;

/// Per event: its routes and its publication.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct EventRec {
    /// Its routes in `Index::routes`, in table order.
    pub routes: RouteSpan,
    /// Its publication's index (`NONE`: not published).
    pub publication: u8,
    /// Four bytes a record, as [`StateRec`].
    pad: u8,
}

/// Per global state: the transitions leaving it and where its entry's walk starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct StateRec {
    /// Its transitions in `Index::steps`, in declaration order.
    pub steps: StepSpan,
    /// Its entry in `Index::ops`: its actions in order (the same order as
    /// `Table::actions`), then one closing operation saying what follows the entry
    /// ([`act::END`], [`act::FIRE`], [`act::CHOOSE`]).
    pub entry: u8,
    /// Four bytes a record: a record's address is the pool's plus its index times four,
    /// one addressing mode (three bytes cost a multiply and a base kept aside).
    pad: u8,
}

impl Default for StateRec {
    fn default() -> Self {
        StateRec {
            steps: Span::EMPTY,
            entry: 0,
            pad: 0,
        }
    }
}

/// Per input: the events of its edges and its mirror variable (`NONE`: none, or a
/// variable past `MAX_VARS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct InputRec {
    pub rise: EventId,
    pub fall: EventId,
    pub var: u8,
}

/// The entries of `pool` in `span`, in order. A `Span<N>` is inside a pool of `N` entries,
/// so the walk never stops early; it checks each index as it goes (one compare an entry:
/// cheaper than taking a slice for the one or two entries a span mostly has).
#[inline(always)]
fn span_of<T, const N: usize>(pool: &[T; N], span: Span<N>) -> impl Iterator<Item = &T> {
    (span.start..span.end).map_while(move |i| pool.get(usize::from(i)))
}

/// A table's compiled form, built once by [`Index::new`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Index {
    pub(super) layout: [Layout; MAX_CHARTS],
    events: [EventRec; MAX_EVENTS],
    /// The routes, grouped by event (at most `MAX_ROUTES`, in a pool of `ROUTES`).
    routes: [Target; ROUTES],
    states: [StateRec; MAX_STATES],
    steps: [Step; MAX_TRANSITIONS],
    /// The states' entries, one after the other (each its actions and its close): at most
    /// `MAX_ACTIONS + MAX_STATES` operations (then one shared [`act::END`], the entry of
    /// a state the table does not have), 256: an operation's index is a `u8`.
    ops: [Act; OPS],
    inputs: [InputRec; MAX_INPUTS],
    input_count: u8,
    /// The table's publications (what `Effects::publish` reports), node events and timers.
    publications: [Publication; MAX_PUBLICATIONS],
    pub(super) event_count: u8,
    pub(super) timer_count: u8,
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
            events: [EventRec {
                routes: Span::EMPTY,
                publication: NONE,
                pad: 0,
            }; MAX_EVENTS],
            routes: [Target::default(); ROUTES],
            states: [StateRec::default(); MAX_STATES],
            steps: [NO_STEP; MAX_TRANSITIONS],
            ops: [END; OPS],
            inputs: [InputRec {
                rise: NONE,
                fall: NONE,
                var: NONE,
            }; MAX_INPUTS],
            input_count: table.inputs.len().min(MAX_INPUTS) as u8,
            publications: [Publication {
                event: 0,
                topic: 0,
                subscribers: 0,
            }; MAX_PUBLICATIONS],
            // At most `MAX_EVENTS` (a table that skipped validation may say more: the
            // events past it have no record, so they raise nothing).
            event_count: table.events.min(MAX_EVENTS as u8),
            timer_count: table.timers.len().min(usize::from(NONE)) as u8,
            outputs: ((1u32 << table.outputs.len().min(16)) - 1) as u16,
            start_drive: table.start_drive(),
            fault_drive: table.fault_drive(),
        };
        // Each chart's states after the previous chart's, inside the pool: a chart whose
        // range overlaps an earlier one's or passes `MAX_STATES` (only in a table that
        // skipped validation) has no state, and ignores its inputs. So every global state
        // is of one chart at most, and a walk of entries is of its own chart's states.
        let mut free = 0;
        for (c, slot) in ix.layout.iter_mut().enumerate().take(table.charts.len()) {
            let states = table.chart_states(c);
            if free <= states.start && states.start <= states.end && states.end <= MAX_STATES {
                *slot = Layout {
                    first_state: states.start as u8,
                    states: states.len() as u8,
                };
                free = states.end;
            }
        }
        for (slot, p) in ix.publications.iter_mut().zip(table.publications.iter()) {
            *slot = *p;
        }
        for (p, publication) in table.publications.iter().enumerate().rev() {
            if let Some(slot) = ix.events.get_mut(usize::from(publication.event)) {
                slot.publication = p.min(usize::from(NONE)) as u8;
            }
        }
        for (rec, input) in ix.inputs.iter_mut().zip(table.inputs.iter()) {
            *rec = InputRec {
                rise: input.rise.unwrap_or(NONE),
                fall: input.fall.unwrap_or(NONE),
                var: input
                    .var
                    .filter(|&v| usize::from(v) < config_schema::limits::MAX_VARS)
                    .unwrap_or(NONE),
            };
        }
        ix.build_routes(table);
        let (next, targets) = ix.build_steps(table);
        ix.build_ops(table, &next, &targets);
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
        for (rec, n) in self.events.iter_mut().zip(count) {
            rec.routes = Span::new(usize::from(at), usize::from(at) + usize::from(n));
            at += n;
        }
        let mut next: [u8; MAX_EVENTS] = core::array::from_fn(|e| self.events[e].routes.start);
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
    fn build_steps(&mut self, table: &Table) -> ([u8; MAX_STATES], [u8; MAX_TRANSITIONS]) {
        let mut next = [NONE; MAX_STATES];
        let mut targets = [NONE; MAX_TRANSITIONS];
        let mut n = 0usize;
        for (s, next) in next.iter_mut().enumerate() {
            let start = n as u8;
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
                    // A target outside the chart (only in a table that skipped
                    // validation) has no entry: its transition stops the chart there.
                    let target = first + usize::from(t.to);
                    if let Some(slot) = targets.get_mut(n) {
                        *slot = if t.to < layout.states && target < MAX_STATES {
                            target as u8
                        } else {
                            NONE
                        };
                    }
                    *slot = Step {
                        trigger,
                        to: t.to,
                        entry: 0,
                        index: (range.start + i) as u8,
                        guard: Calc::lower(table, t.guard),
                    };
                    n += 1;
                }
            }
            let steps = Span::new(usize::from(start), n);
            let first_eventless =
                span_of(&self.steps, steps).position(|step| step.trigger == EVENTLESS);
            self.states[s].steps = steps;
            *next = match first_eventless {
                None => NONE,
                Some(i) => {
                    let at = usize::from(start) + i;
                    match self.steps.get(at) {
                        Some(step) if step.guard.always_holds() => at as u8,
                        _ => CHOOSE,
                    }
                }
            };
        }
        (next, targets)
    }

    /// Each state's entry: its actions, lowered one for one, then its close, from `next`
    /// (per state: `NONE`, no event-less transition leaves it; a step index, its first
    /// event-less transition, which always holds; [`CHOOSE`], chosen by their guards).
    fn build_ops(
        &mut self,
        table: &Table,
        next: &[u8; MAX_STATES],
        targets: &[u8; MAX_TRANSITIONS],
    ) {
        // A range past the actions (only in a table that skipped validation) is none.
        let actions = |s: usize| table.actions.get(table.state_actions(s)).unwrap_or(&[]);
        // A state with no actions and no event-less transition has no entry of its own:
        // it shares one `END`, after the entries (with at most `MAX_ACTIONS` actions over
        // the states, in a validated table, and `MAX_STATES` states, the entries and that
        // `END` fit in the pool).
        let shared: [bool; MAX_STATES] =
            core::array::from_fn(|s| actions(s).is_empty() && next[s] == NONE);
        // Whether the fused step of state `s` leaves the chart stable: its target has no
        // entry of its own (or is past `MAX_STATES`).
        let stops = |s: usize| {
            let at = usize::from(next[s]);
            let target = targets.get(at).map_or(NONE, |t| *t);
            shared.get(usize::from(target)).copied().unwrap_or(true)
        };
        // Whether state `s`'s last action and its close are one operation (a drive or an
        // emit, then `END`; an emit, then a fused step that leaves the chart stable).
        let fused = |s: usize| match actions(s).last() {
            Some(Action::Drive { .. }) => next[s] == NONE,
            Some(Action::Emit(_)) => {
                next[s] == NONE
                    || (next[s] != CHOOSE && usize::from(next[s]) < MAX_TRANSITIONS && stops(s))
            }
            _ => false,
        };
        // The entries laid out first (a close names its target's entry).
        let mut pc = 0usize;
        for (s, rec) in self.states.iter_mut().enumerate() {
            if !shared[s] {
                rec.entry = pc.min(OPS - 1) as u8;
                pc += actions(s).len() + 1 - usize::from(fused(s));
            }
        }
        let end = pc.min(OPS - 1) as u8;
        for (rec, shared) in self.states.iter_mut().zip(shared) {
            if shared {
                rec.entry = end;
            }
        }
        let mut pc = 0usize;
        let push = |ops: &mut [Act; OPS], pc: &mut usize, op: Act| {
            if let Some(slot) = ops.get_mut(*pc) {
                *slot = op;
            }
            *pc += 1;
        };
        for s in 0..MAX_STATES {
            if shared[s] {
                continue;
            }
            let close = match next[s] {
                NONE => END,
                CHOOSE => Act {
                    code: act::CHOOSE,
                    dst: s as u8,
                    w: [0; 4],
                },
                at => match self.steps.get(usize::from(at)) {
                    Some(step) => {
                        // Its target's entry, or stop after the firing.
                        let target = targets.get(usize::from(at)).map_or(NONE, |t| *t);
                        let (entry, stop) = match self.states.get(usize::from(target)) {
                            Some(rec) if !stops(s) => (rec.entry, 0),
                            _ => (end, 1),
                        };
                        Act {
                            code: act::FIRE,
                            dst: step.to,
                            w: [step.index, entry, stop, 0],
                        }
                    }
                    None => END,
                },
            };
            let n = actions(s).len();
            for (i, action) in actions(s).iter().enumerate() {
                let mut op = self.lower_action(table, action);
                if i + 1 == n && fused(s) {
                    op = match (op.code, close.code) {
                        (act::DRIVE, _) => Act {
                            code: act::DRIVE_END,
                            ..op
                        },
                        (_, act::END) => Act {
                            code: act::EMIT_END,
                            ..op
                        },
                        _ => Act {
                            code: act::EMIT_FIRE,
                            dst: op.dst,
                            w: [op.w[0], close.dst, close.w[0], 0],
                        },
                    };
                }
                push(&mut self.ops, &mut pc, op);
            }
            if !fused(s) {
                push(&mut self.ops, &mut pc, close);
            }
        }
        // Each transition to its target's entry.
        for (step, target) in self.steps.iter_mut().zip(targets) {
            step.entry = match self.states.get(usize::from(*target)) {
                Some(rec) => rec.entry,
                None => end,
            };
        }
    }

    /// `action`, lowered.
    fn lower_action(&self, table: &Table, action: &Action) -> Act {
        let publication = |e: EventId| {
            (self.events)
                .get(usize::from(e))
                .map_or(NONE, |rec| rec.publication)
        };
        let of = |code, dst, w| Act { code, dst, w };
        match *action {
            Action::Set { var, expr } => {
                let calc = Calc::lower(table, Some(expr));
                if usize::from(var) < config_schema::limits::MAX_VARS {
                    of(calc.code, var, calc.w)
                } else {
                    of(act::DISCARD, calc.code, calc.w)
                }
            }
            Action::Drive { mask, value } => {
                let ([m0, m1], [v0, v1]) = (mask.to_le_bytes(), value.to_le_bytes());
                of(act::DRIVE, 0, [m0, m1, v0, v1])
            }
            Action::Emit(event) => of(act::EMIT, event, [publication(event), 0, 0, 0]),
            Action::Publish(event) => of(act::PUBLISH, 0, [publication(event), 0, 0, 0]),
            Action::StartTimer { timer, ms } => of(act::START_TIMER, timer, ms.to_le_bytes()),
            Action::CancelTimer(timer) => of(act::CANCEL_TIMER, timer, [0; 4]),
            Action::Fault(code) => of(act::FAULT, code, [0; 4]),
        }
    }

    /// The record of `event` (`None` past `MAX_EVENTS`).
    #[inline(always)]
    pub(super) fn event(&self, event: EventId) -> Option<&EventRec> {
        self.events.get(usize::from(event))
    }

    /// The record of `event`, an event below `event_count` (masked: `MAX_EVENTS` is a power
    /// of two, so the index is in range without a check; `event_count` is at most
    /// `MAX_EVENTS`).
    #[inline(always)]
    pub(super) fn event_below_count(&self, event: EventId) -> &EventRec {
        &self.events[usize::from(event) & (MAX_EVENTS - 1)]
    }

    /// The record of global state `state` (`None` past `MAX_STATES`).
    #[inline(always)]
    pub(super) fn state(&self, state: usize) -> Option<&StateRec> {
        self.states.get(state)
    }

    /// Route `at` (masked: inside the pool; a span's routes are below its end).
    #[inline(always)]
    pub(super) fn route(&self, at: u8) -> &Target {
        &self.routes[usize::from(at) & (ROUTES - 1)]
    }

    /// The transitions of a span, in order.
    #[inline(always)]
    pub(super) fn steps(&self, span: StepSpan) -> impl Iterator<Item = &Step> {
        span_of(&self.steps, span)
    }

    /// The operation at `pc` (a `u8`: always inside the pool).
    #[inline(always)]
    pub(super) fn op(&self, pc: u8) -> &Act {
        &self.ops[usize::from(pc)]
    }

    /// The record of input `input` (`None` past the table's inputs).
    #[inline(always)]
    pub(super) fn input(&self, input: u8) -> Option<&InputRec> {
        // `input_count` is at most `MAX_INPUTS`, a power of two: the mask keeps the index
        // in range without a second check.
        (input < self.input_count).then(|| &self.inputs[usize::from(input) & (MAX_INPUTS - 1)])
    }

    /// Publication `p` of the table (`None` for `NONE`).
    #[inline(always)]
    pub(super) fn publication_at(&self, p: u8) -> Option<&Publication> {
        self.publications.get(usize::from(p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The index's RAM is its pools at the capacities of `limits.rs`, nothing per table:
    /// what docs/ecc-semantics.md and docs/boards.md count.
    #[test]
    fn the_index_is_its_pools_at_the_capacities() {
        let pools = 2 * MAX_CHARTS
            + 4 * MAX_EVENTS
            + 2 * ROUTES
            + 4 * MAX_STATES
            + 9 * MAX_TRANSITIONS
            + 6 * 256
            + 3 * MAX_INPUTS
            + 3 * MAX_PUBLICATIONS;
        // The input, event and timer counts, the output mask and the two drives (u16s).
        let rest = 3 + 2 + 2 * 4;
        assert_eq!(Index::BYTES, (pools + rest).next_multiple_of(2));
        assert_eq!(Index::BYTES, 3734);
    }

    /// A span is always inside its pool: any other range is made empty.
    #[test]
    fn a_span_outside_its_pool_is_empty() {
        assert_eq!(Span::<4>::new(1, 3), Span { start: 1, end: 3 });
        assert_eq!(Span::<4>::new(0, 4), Span { start: 0, end: 4 });
        assert_eq!(Span::<4>::new(2, 5), Span::EMPTY);
        assert_eq!(Span::<4>::new(3, 2), Span::EMPTY);
        assert_eq!(Span::<300>::new(0, 256), Span::EMPTY);
        let pool = [10, 11, 12, 13];
        let got: Vec<_> = span_of(&pool, Span::new(1, 3)).copied().collect();
        assert_eq!(got, [11, 12]);
    }
}
