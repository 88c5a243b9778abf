//! The ECC interpreter: IEC 61499 basic-FB execution over a validated [`Table`].
//!
//! Pure and deterministic: no Embassy, no allocation, no clock. Everything a step does to
//! the world (pin changes, publications, timer requests, faults) is reported through
//! [`Effects`], so the MCU runtime, the simulator and the tests share this engine.
//! Semantics: `docs/ecc-semantics.md`.

use config_schema::limits::{MAX_CASCADE, MAX_CHAIN, MAX_CHARTS, MAX_VARS};
use core::borrow::{Borrow, BorrowMut};
use core::ops::{Deref, DerefMut};

use config_schema::{EventId, Publication, Table, Topic};

/// Why a node faulted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Fault {
    /// A chart fired more than `MAX_CHAIN` event-less transitions in one delivery.
    ChainLimit { chart: u8 },
    /// More than `EVENT_QUEUE` events were pending.
    QueueFull { event: EventId },
    /// One stimulus caused more than `MAX_CASCADE` event deliveries.
    Cascade { event: EventId },
    /// A `Fault` action ran.
    Action { chart: u8, code: u8 },
    /// A guard or assignment expression could not be evaluated (only for tables that
    /// skipped validation).
    Expr { chart: u8 },
}

/// What a step does to the world. Every method has a do-nothing default.
pub trait Effects {
    /// Output `output` changed to `value`.
    fn output(&mut self, _output: u8, _value: bool) {}
    /// A node event is to be published to the radio.
    fn publish(&mut self, _publication: &Publication) {}
    /// Start (or restart) timer `timer` to expire in `ms` milliseconds.
    fn start_timer(&mut self, _timer: u8, _ms: u32) {}
    /// Cancel timer `timer`.
    fn cancel_timer(&mut self, _timer: u8) {}
    /// The node faulted; its outputs are already at their fault levels.
    fn fault(&mut self, _fault: Fault) {}
    /// Trace: chart `chart` took `transition` (table index) from state `from` to `to`
    /// (chart-local states).
    fn fired(&mut self, _chart: u8, _transition: u8, _from: u8, _to: u8) {}
    /// Trace: chart input `input` of `chart` fired nothing and was dropped.
    fn ignored(&mut self, _chart: u8, _input: u8) {}
}

/// Discards every effect.
impl Effects for () {}

/// An engine's state without its table: what a runtime that owns and swaps its table keeps
/// between stimuli, and what a verifier hashes. (The event queue is always empty between
/// stimuli, so it is not part of it.)
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct EngineState {
    pub current: [u8; MAX_CHARTS],
    pub vars: [i32; MAX_VARS],
    pub inputs: u16,
    pub outputs: u16,
    pub fault: Option<Fault>,
}

mod calc;
mod fifo;
mod index;

use calc::calc_match;
use calc::Calc;
use fifo::Fifo;
pub use index::Index;
use index::{act, Act, Layout, Span, Step, EVENTLESS, NONE};

/// Whether a delivery goes on or the node faulted (and the stimulus ends).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Flow {
    Go,
    Stop,
    /// The delivery ended with an emit of this event while the FIFO was empty: it is the
    /// next event to deliver once the event's remaining routes are done, so it is queued
    /// only if routes remain (published already).
    Emit(EventId),
}

/// One node's charts running one table, holding its state in `S`: its own
/// ([`EngineState`], the default), or a runtime's borrowed in place (`&mut EngineState`,
/// [`Engine::on`]: nothing copied in or out per stimulus); and the table's [`Index`] in
/// `I`: its own (built with the engine and held inline: no allocator, the default), or
/// the one its runtime keeps beside the table (`&Index`, built once at activation, not
/// per stimulus). Both are type parameters: a call reaches them without a choice.
#[derive(Debug, Clone)]
pub struct Engine<'t, S: BorrowMut<EngineState> = EngineState, I: Borrow<Index> = Index> {
    table: &'t Table,
    index: I,
    state: S,
    queue: Fifo,
}

/// What changes while the charts run: the engine's state (read and written in place
/// through `Deref`) and its event queue, without the table and index.
struct Run<'s> {
    state: &'s mut EngineState,
    queue: &'s mut Fifo,
}

impl Deref for Run<'_> {
    type Target = EngineState;
    #[inline(always)]
    fn deref(&self) -> &EngineState {
        self.state
    }
}

impl DerefMut for Run<'_> {
    #[inline(always)]
    fn deref_mut(&mut self) -> &mut EngineState {
        self.state
    }
}

impl<'t> Engine<'t> {
    /// An engine in its initial state: every chart in its initial state, variables at their
    /// initial values, outputs at their start levels (a held one low: what a boot
    /// drives), inputs low. `table` must be validated (as [`config_schema::decode`] does).
    pub fn new(table: &'t Table) -> Self {
        Engine::new_holding(table, 0)
    }

    /// [`Engine::new`] for a table that replaces a running one: an output whose start
    /// level is `Hold` keeps its bit of `before` (bit i: the level its pin has now, as the
    /// previous table left it).
    pub fn new_holding(table: &'t Table, before: u16) -> Self {
        Engine::start_with(table, Index::new(table), before)
    }

    /// [`Engine::new_holding`] with `index`, the [`Index`] of `table` its runtime keeps.
    pub fn new_indexed(
        table: &'t Table,
        index: &'t Index,
        before: u16,
    ) -> Engine<'t, EngineState, &'t Index> {
        Engine::start_with(table, index, before)
    }

    /// An engine over `table` in a state taken by [`snapshot`](Engine::snapshot) of an
    /// engine running the same table. It builds the table's [`Index`] on every call: for a
    /// test or a one-off; whatever resumes per stimulus keeps the index and calls
    /// [`resume_indexed`](Engine::resume_indexed) (`sim`, `verify` do) or runs on its
    /// state in place ([`Engine::on`]: `NodeCore` does).
    pub fn resume(table: &'t Table, state: &EngineState) -> Self {
        Engine::resume_with(table, Index::new(table), state)
    }

    /// [`resume`](Engine::resume) with `index`, the [`Index`] of `table` its runtime keeps
    /// (built once when the table was activated).
    pub fn resume_indexed(
        table: &'t Table,
        index: &'t Index,
        state: &EngineState,
    ) -> Engine<'t, EngineState, &'t Index> {
        Engine::resume_with(table, index, state)
    }
}

impl<'t, I: Borrow<Index>> Engine<'t, EngineState, I> {
    fn start_with(table: &'t Table, index: I, before: u16) -> Self {
        let (mask, value) = index.borrow().start_drive;
        let mut engine = Engine {
            table,
            index,
            state: EngineState {
                current: [0; MAX_CHARTS],
                vars: [0; MAX_VARS],
                inputs: 0,
                // The outputs at their start levels, a held one at its bit of `before`.
                outputs: (before & !mask) | (value & mask),
                fault: None,
            },
            queue: Fifo::new(),
        };
        engine.parts().1.init(table);
        engine
    }

    fn resume_with(table: &'t Table, index: I, state: &EngineState) -> Self {
        Engine {
            table,
            index,
            state: state.clone(),
            queue: Fifo::new(),
        }
    }
}

impl<'t, 's> Engine<'t, &'s mut EngineState, &'t Index> {
    /// An engine over `table` (with `index`, the [`Index`] its runtime keeps) running on
    /// `state` in place: what [`resume_indexed`](Engine::resume_indexed) then
    /// [`snapshot`](Engine::snapshot) into `state` do, without the two copies. `state`
    /// must be one of an engine running the same table.
    #[inline]
    pub fn on(table: &'t Table, index: &'t Index, state: &'s mut EngineState) -> Self {
        Engine {
            table,
            index,
            state,
            queue: Fifo::new(),
        }
    }
}

impl<'t, S: BorrowMut<EngineState>, I: Borrow<Index>> Engine<'t, S, I> {
    /// The engine's state.
    #[inline(always)]
    fn st(&self) -> &EngineState {
        self.state.borrow()
    }

    /// The state to [`resume`](Engine::resume) from later.
    pub fn snapshot(&self) -> EngineState {
        self.st().clone()
    }

    /// The table this engine runs.
    pub fn table(&self) -> &'t Table {
        self.table
    }

    /// The chart-local current state of `chart`.
    pub fn state(&self, chart: usize) -> Option<u8> {
        (chart < self.table.charts.len())
            .then(|| self.st().current.get(chart).copied())
            .flatten()
    }

    /// The value of variable `var`.
    pub fn var(&self, var: usize) -> Option<i32> {
        (var < self.table.vars.len())
            .then(|| self.st().vars.get(var).copied())
            .flatten()
    }

    /// The output levels, bit i = output i.
    pub fn outputs(&self) -> u16 {
        self.st().outputs
    }

    /// The input levels, bit i = input i.
    pub fn inputs(&self) -> u16 {
        self.st().inputs
    }

    /// The fault the node is in, if any.
    pub fn fault(&self) -> Option<Fault> {
        self.st().fault
    }

    /// Back to the initial state: clears a fault, cancels every timer, charts and variables
    /// to their initial values, outputs to their start levels (a held one keeps its level).
    pub fn reset(&mut self, fx: &mut impl Effects) {
        for timer in 0..self.table.timers.len() {
            fx.cancel_timer(timer as u8);
        }
        let table = self.table;
        let (ix, mut run) = self.parts();
        let (mask, value) = ix.start_drive;
        run.drive(ix, mask, value, fx);
        run.init(table);
    }

    /// The index and the interpreter's run, borrowed apart.
    #[inline(always)]
    fn parts(&mut self) -> (&Index, Run<'_>) {
        let ix = self.index.borrow();
        let run = Run {
            state: self.state.borrow_mut(),
            queue: &mut self.queue,
        };
        (ix, run)
    }

    /// Faults the node from outside the charts (a link alarm under `on_link_alarm:
    /// Fault`): as a `Fault(code)` action of no chart ([`config_schema::alarm::NO_CHART`]).
    /// A faulted node stays in its fault.
    pub fn fail(&mut self, code: u8, fx: &mut impl Effects) {
        if self.st().fault.is_none() {
            let chart = config_schema::alarm::NO_CHART;
            let fault = Fault::Action { chart, code };
            let (ix, mut run) = self.parts();
            run.set_fault(ix, fault, fx);
        }
    }

    /// Input `input` is at `level` when the engine starts (a switch that was already
    /// closed): sets the level and its mirror variable without raising any event.
    pub fn sense(&mut self, input: u8, level: bool) {
        let (ix, mut run) = self.parts();
        if let Some(rec) = ix.input(input) {
            run.level(input, rec.var, level);
        }
    }

    /// Input `input` is now at `level`: updates its mirror variable and, on an edge, raises
    /// its rise or fall event (published if it has a publication).
    #[inline]
    pub fn input(&mut self, input: u8, level: bool, fx: &mut impl Effects) {
        let table = self.table;
        let (ix, mut run) = self.parts();
        let Some(rec) = ix.input(input) else {
            return;
        };
        let was = run.level(input, rec.var, level);
        let event = if level { rec.rise } else { rec.fall };
        if was != level && event != NONE {
            run.raise(ix, table, event, true, fx);
        }
    }

    /// Timer `timer` expired: raises its event (published if it has a publication).
    pub fn timer_expired(&mut self, timer: u8, fx: &mut impl Effects) {
        if let Some(t) = self.table.timers.get(usize::from(timer)) {
            self.raise(t.event, true, fx);
        }
    }

    /// Peer `publisher` (index into the table's peers) published `topic`: raises the
    /// subscribed event, if this node subscribes to it. Returns whether it did.
    pub fn remote(&mut self, publisher: u8, topic: Topic, fx: &mut impl Effects) -> bool {
        match self.table.subscribed(publisher, topic) {
            Some(event) => {
                self.raise(event, false, fx);
                true
            }
            None => false,
        }
    }

    /// The START command: raises the table's start event, if it has one, as if the START
    /// button wired to this node was pressed (so it is published like the button's edge).
    /// Returns whether it did.
    pub fn start(&mut self, fx: &mut impl Effects) -> bool {
        self.raise_own(self.table.start, fx)
    }

    /// Raises the table's HOME event (the HOME command), if it has one; false if not.
    pub fn home(&mut self, fx: &mut impl Effects) -> bool {
        self.raise_own(self.table.home, fx)
    }

    /// Raises the table's boot event (once, when the node boots with the table), if it has
    /// one; false if not.
    pub fn boot(&mut self, fx: &mut impl Effects) -> bool {
        self.raise_own(self.table.boot, fx)
    }

    /// Puts every chart in its idle state, running no action: a table activated at the
    /// idle point of the one it replaces starts where that one rested (every actuator
    /// home), not in its initial (not homed) state.
    pub fn rest(&mut self) {
        let table = self.table;
        let state = self.state.borrow_mut();
        for (slot, chart) in state.current.iter_mut().zip(table.charts.iter()) {
            *slot = chart.idle;
        }
    }

    /// Raises one of the table's own events (START, HOME, boot) as if locally originated
    /// (published); false if the table has none.
    fn raise_own(&mut self, event: Option<EventId>, fx: &mut impl Effects) -> bool {
        match event {
            Some(event) => {
                self.raise(event, true, fx);
                true
            }
            None => false,
        }
    }

    /// Delivers a node event from outside (no publication), running every chart to a
    /// stable state.
    pub fn event(&mut self, event: EventId, fx: &mut impl Effects) {
        self.raise(event, false, fx);
    }

    #[inline]
    fn raise(&mut self, event: EventId, local: bool, fx: &mut impl Effects) {
        let table = self.table;
        let (ix, mut run) = self.parts();
        run.raise(ix, table, event, local, fx);
    }
}

impl Run<'_> {
    fn init(&mut self, table: &Table) {
        let s = &mut *self.state;
        for (slot, chart) in s.current.iter_mut().zip(table.charts.iter()) {
            *slot = chart.initial;
        }
        for (slot, value) in s.vars.iter_mut().zip(table.vars.iter()) {
            *slot = *value;
        }
        // Inputs keep their levels and mirrors: the switches did not move.
        for (i, input) in table.inputs.iter().enumerate().take(16) {
            if let Some(var) = input.var.and_then(|v| s.vars.get_mut(usize::from(v))) {
                *var = i32::from(s.inputs & (1 << i) != 0);
            }
        }
        self.queue.clear();
        s.fault = None;
    }

    /// Sets input `input`'s level and its mirror variable `var`; returns the level it had.
    #[inline]
    fn level(&mut self, input: u8, var: u8, level: bool) -> bool {
        let bit = 1u16 << (input & 15);
        let was = self.inputs & bit != 0;
        if level {
            self.inputs |= bit;
        } else {
            self.inputs &= !bit;
        }
        if var != NONE {
            self.vars[usize::from(var) & (MAX_VARS - 1)] = i32::from(level);
        }
        was
    }

    /// One stimulus, run to completion: `event` (published first if `local`), then every
    /// event the charts emit, oldest first.
    fn raise(
        &mut self,
        ix: &Index,
        table: &Table,
        event: EventId,
        local: bool,
        fx: &mut impl Effects,
    ) {
        if self.fault.is_some() || event >= ix.event_count {
            return;
        }
        let rec = ix.event_below_count(event);
        if local {
            publish(ix, rec.publication, fx);
        }
        // The queue is empty between stimuli: the stimulus goes straight to its routes, and
        // only events emitted by actions wait in the FIFO.
        let mut routes = rec.routes;
        // Deliveries so far, this one included (the first cannot be one too many).
        let mut processed = 1usize;
        loop {
            // Delivers `next` to all its routes, in order, each chart running to a stable
            // state.
            let (mut at, end) = routes.bounds();
            // An event the last route's delivery emitted last into the empty FIFO: the
            // next one the FIFO would give.
            let mut emitted = None;
            while at < end {
                let route = ix.route(at);
                at += 1;
                match self.deliver(ix, table, route.chart, route.input, fx) {
                    Flow::Go => {}
                    Flow::Stop => return,
                    Flow::Emit(e) if at < end => {
                        if self.enqueue(ix, e, fx) == Flow::Stop {
                            return;
                        }
                    }
                    Flow::Emit(e) => emitted = Some(e),
                }
            }
            let next = match emitted {
                Some(e) => e,
                None => match self.queue.pop() {
                    Some(e) => e,
                    None => return,
                },
            };
            routes = ix.event(next).map_or(Span::EMPTY, |rec| rec.routes);
            processed += 1;
            if processed > MAX_CASCADE {
                self.set_fault(ix, Fault::Cascade { event }, fx);
                return;
            }
        }
    }

    /// Delivers chart input `input` to `chart` and runs its event-less transitions until it
    /// is stable. [`Flow::Stop`]: the node faulted.
    #[inline(always)]
    fn deliver(
        &mut self,
        ix: &Index,
        table: &Table,
        chart: u8,
        input: u8,
        fx: &mut impl Effects,
    ) -> Flow {
        let c = usize::from(chart);
        // A chart outside the table, or in a state outside its chart, has no state: it
        // ignores its input (only a table that skipped validation gets here).
        let (Some(layout), Some(&current)) = (ix.layout.get(c), self.current.get(c)) else {
            fx.ignored(chart, input);
            return Flow::Go;
        };
        let Layout {
            first_state,
            states,
        } = *layout;
        let state = ix
            .state(usize::from(first_state) + usize::from(current))
            .filter(|_| current < states);
        // The input first: the first of the state's transitions it triggers (or an
        // event-less one) whose guard holds.
        let step = match state.map(|rec| self.select(ix.steps(rec.steps), input, table)) {
            Some(Ok(Some(step))) => step,
            Some(Err(())) => return self.fail_expr(ix, chart, fx),
            None | Some(Ok(None)) => {
                fx.ignored(chart, input);
                return Flow::Go;
            }
        };
        // Then event-less transitions only, `chained` of them so far.
        let mut chained = 0usize;
        let (mut from, mut to, mut index, mut entry) = (current, step.to, step.index, step.entry);
        loop {
            // Fire: the target becomes current, then its entry runs: its actions in order,
            // then its close (what follows the entry, fused when the index was built).
            if let Some(slot) = self.current.get_mut(c) {
                *slot = to;
            }
            fx.fired(chart, index, from, to);
            let mut pc = entry;
            // The entry's walk: one jump an operation.
            loop {
                let Act { code, dst, w } = *ix.op(pc);
                pc = pc.wrapping_add(1);
                let value = calc_match!(code, &w, &self.vars, self.inputs, table, {
                    // Code 0 (a missing guard) is no assignment's: the index builds none
                    // (taken as `END` here, so that the walk's jump has no arm of its own
                    // for it).
                    0 | act::END => return Flow::Go,
                    act::FIRE => {
                        chained += 1;
                        if chained > MAX_CHAIN {
                            self.set_fault(ix, Fault::ChainLimit { chart }, fx);
                            return Flow::Stop;
                        }
                        // Fired here, and its target's entry walked on.
                        let [index, next, stop, _] = w;
                        from = to;
                        to = dst;
                        if let Some(slot) = self.current.get_mut(c) {
                            *slot = to;
                        }
                        fx.fired(chart, index, from, to);
                        if stop != 0 {
                            return Flow::Go;
                        }
                        pc = next;
                        continue;
                    }
                    act::CHOOSE => {
                        chained += 1;
                        let steps = ix.state(usize::from(dst)).map_or(Span::EMPTY, |r| r.steps);
                        let step = match self.select(ix.steps(steps), EVENTLESS, table) {
                            Ok(Some(step)) => step,
                            Ok(None) => return Flow::Go,
                            Err(()) => return self.fail_expr(ix, chart, fx),
                        };
                        if chained > MAX_CHAIN {
                            self.set_fault(ix, Fault::ChainLimit { chart }, fx);
                            return Flow::Stop;
                        }
                        from = to;
                        (to, index, entry) = (step.to, step.index, step.entry);
                        break;
                    }
                    act::DRIVE => {
                        self.drive_op(ix, w, fx);
                        continue;
                    }
                    act::DRIVE_END => {
                        self.drive_op(ix, w, fx);
                        return Flow::Go;
                    }
                    act::EMIT => {
                        if self.emit(ix, dst, w[0], fx) == Flow::Stop {
                            return Flow::Stop;
                        }
                        continue;
                    }
                    act::EMIT_END => return self.emit_last(ix, dst, w[0], fx),
                    act::EMIT_FIRE => {
                        let flow = self.emit_last(ix, dst, w[0], fx);
                        if flow == Flow::Stop {
                            return Flow::Stop;
                        }
                        // Then the close, as `FIRE` with a stable target.
                        chained += 1;
                        if chained > MAX_CHAIN {
                            self.set_fault(ix, Fault::ChainLimit { chart }, fx);
                            return Flow::Stop;
                        }
                        from = to;
                        to = w[1];
                        if let Some(slot) = self.current.get_mut(c) {
                            *slot = to;
                        }
                        fx.fired(chart, w[2], from, to);
                        return flow;
                    }
                    act::PUBLISH => {
                        publish(ix, w[0], fx);
                        continue;
                    }
                    act::START_TIMER => {
                        fx.start_timer(dst, u32::from_le_bytes(w));
                        continue;
                    }
                    act::CANCEL_TIMER => {
                        fx.cancel_timer(dst);
                        continue;
                    }
                    act::DISCARD => {
                        if Calc::run(dst, &w, &self.vars, self.inputs, table).is_none() {
                            return self.fail_expr(ix, chart, fx);
                        }
                        continue;
                    }
                    act::FAULT => {
                        self.set_fault(ix, Fault::Action { chart, code: dst }, fx);
                        return Flow::Stop;
                    }
                });
                // `dst := expression`: the index builds no other codes than the actions'
                // and the operations' (up to `calc::LAST_CODE`), and `dst` below
                // `MAX_VARS` (an assignment to any other variable is a `DISCARD`).
                match value {
                    Some(value) => self.vars[usize::from(dst) & (MAX_VARS - 1)] = value,
                    None => return self.fail_expr(ix, chart, fx),
                }
            }
        }
    }

    /// The first of `steps` (a state's transitions, in declaration order) whose trigger is
    /// `want` or which is event-less, and whose guard holds. A guard that cannot be
    /// evaluated (only in a table that skipped validation) is an error.
    #[inline(always)]
    fn select<'i>(
        &self,
        steps: impl Iterator<Item = &'i Step>,
        want: u8,
        table: &Table,
    ) -> Result<Option<&'i Step>, ()> {
        for step in steps {
            if step.trigger == want || step.trigger == EVENTLESS {
                if step.guard.is_true() {
                    return Ok(Some(step));
                }
                if step.guard.eval(&self.vars, self.inputs, table).ok_or(())? != 0 {
                    return Ok(Some(step));
                }
            }
        }
        Ok(None)
    }

    /// A drive action: `w` = mask, levels (little-endian `u16`s).
    #[inline(always)]
    fn drive_op(&mut self, ix: &Index, w: [u8; 4], fx: &mut impl Effects) {
        let [m0, m1, v0, v1] = w;
        let (mask, value) = (u16::from_le_bytes([m0, m1]), u16::from_le_bytes([v0, v1]));
        self.drive(ix, mask, value, fx);
    }

    /// An emit action: event `event` queued and, once queued, published (publication
    /// `p`); an event that does not fit faults the node ([`Flow::Stop`]) and is not
    /// published.
    #[inline(always)]
    fn emit(&mut self, ix: &Index, event: EventId, p: u8, fx: &mut impl Effects) -> Flow {
        if self.enqueue(ix, event, fx) == Flow::Stop {
            return Flow::Stop;
        }
        publish(ix, p, fx);
        Flow::Go
    }

    /// Queues `event` for delivery; a full FIFO faults the node.
    #[inline(always)]
    fn enqueue(&mut self, ix: &Index, event: EventId, fx: &mut impl Effects) -> Flow {
        if self.queue.push(event).is_err() {
            self.set_fault(ix, Fault::QueueFull { event }, fx);
            return Flow::Stop;
        }
        Flow::Go
    }

    /// An emit that ends the delivery: as [`Run::emit`], but into an empty FIFO it is
    /// only published and handed back ([`Flow::Emit`]) to be delivered next without the
    /// FIFO's round trip (the same order: nothing else is pending, nothing else is
    /// queued before the delivery ends).
    #[inline(always)]
    fn emit_last(&mut self, ix: &Index, event: EventId, p: u8, fx: &mut impl Effects) -> Flow {
        if self.queue.is_empty() {
            publish(ix, p, fx);
            return Flow::Emit(event);
        }
        self.emit(ix, event, p, fx)
    }

    /// Faults the node on an expression of `chart` that cannot be evaluated.
    #[cold]
    #[inline(never)]
    fn fail_expr(&mut self, ix: &Index, chart: u8, fx: &mut impl Effects) -> Flow {
        self.set_fault(ix, Fault::Expr { chart }, fx);
        Flow::Stop
    }

    fn drive(&mut self, ix: &Index, mask: u16, value: u16, fx: &mut impl Effects) {
        let next = (self.outputs & !mask) | (value & mask);
        // The table's outputs (at most 16): bits 0..n.
        let changed = (self.outputs ^ next) & ix.outputs;
        self.outputs = next;
        if changed != 0 {
            report_outputs(changed, next, fx);
        }
    }

    #[cold]
    #[inline(never)]
    fn set_fault(&mut self, ix: &Index, fault: Fault, fx: &mut impl Effects) {
        self.fault = Some(fault);
        self.queue.clear();
        let (mask, value) = ix.fault_drive;
        self.drive(ix, mask, value, fx);
        for timer in 0..ix.timer_count {
            fx.cancel_timer(timer);
        }
        fx.fault(fault);
    }
}

/// Reports each output of `changed` (bit i: output i), lowest first, at its level in
/// `levels`. Out of line: inlined, the output loop and what a runtime reads to set a pin
/// sat in the one function the whole cascade is inlined into, and cost registers (and
/// spills) to every delivery, one that drives nothing too (one more E_CTU: 161 -> 152
/// instructions; a firing that drives pays the call, about 1 a VC stimulus).
#[inline(never)]
fn report_outputs(mut changed: u16, levels: u16, fx: &mut impl Effects) {
    while changed != 0 {
        let i = changed.trailing_zeros();
        changed &= changed - 1;
        fx.output(i as u8, levels & (1 << i) != 0);
    }
}

/// Reports publication `p` of the table (`NONE`: the event has none).
#[inline(always)]
fn publish(ix: &Index, p: u8, fx: &mut impl Effects) {
    if p != NONE {
        if let Some(p) = ix.publication_at(p) {
            fx.publish(p);
        }
    }
}
