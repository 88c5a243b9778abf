//! The ECC interpreter: IEC 61499 basic-FB execution over a validated [`Table`].
//!
//! Pure and deterministic: no Embassy, no allocation, no clock. Everything a step does to
//! the world (pin changes, publications, timer requests, faults) is reported through
//! [`Effects`], so the MCU runtime, the simulator and the tests share this engine.
//! Semantics: `docs/ecc-semantics.md`.

use config_schema::limits::{EVENT_QUEUE, MAX_CASCADE, MAX_CHAIN, MAX_CHARTS, MAX_VARS};
use config_schema::{guard, Action, EventId, Expr, Publication, Table, Topic};
use heapless::Deque;

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

mod index;

pub use index::Index;
use index::NONE;

/// The engine's index: its own (built with the engine) or the one its runtime keeps
/// beside the table (built once at activation, not per stimulus). No allocator: an
/// engine that builds its own holds it inline.
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)]
enum IndexRef<'t> {
    Own(Index),
    Kept(&'t Index),
}

impl IndexRef<'_> {
    #[inline(always)]
    fn get(&self) -> &Index {
        match self {
            IndexRef::Own(ix) => ix,
            IndexRef::Kept(ix) => ix,
        }
    }
}

/// One node's charts running one table.
#[derive(Debug, Clone)]
pub struct Engine<'t> {
    table: &'t Table,
    index: IndexRef<'t>,
    current: [u8; MAX_CHARTS],
    vars: [i32; MAX_VARS],
    inputs: u16,
    outputs: u16,
    queue: Deque<EventId, EVENT_QUEUE>,
    fault: Option<Fault>,
}

/// The outputs at their start levels, a held one at its bit of `before`.
fn start_outputs(table: &Table, before: u16) -> u16 {
    let (mask, value) = table.start_drive();
    (before & !mask) | (value & mask)
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
        let mut engine = Engine {
            table,
            index: IndexRef::Own(Index::new(table)),
            current: [0; MAX_CHARTS],
            vars: [0; MAX_VARS],
            inputs: 0,
            outputs: start_outputs(table, before),
            queue: Deque::new(),
            fault: None,
        };
        engine.init();
        engine
    }

    fn init(&mut self) {
        for (slot, chart) in self.current.iter_mut().zip(self.table.charts.iter()) {
            *slot = chart.initial;
        }
        for (slot, value) in self.vars.iter_mut().zip(self.table.vars.iter()) {
            *slot = *value;
        }
        // Inputs keep their levels and mirrors: the switches did not move.
        for (i, input) in self.table.inputs.iter().enumerate().take(16) {
            if let Some(var) = input.var.and_then(|v| self.vars.get_mut(usize::from(v))) {
                *var = i32::from(self.inputs & (1 << i) != 0);
            }
        }
        self.queue.clear();
        self.fault = None;
    }

    /// The state to [`resume`](Engine::resume) from later.
    pub fn snapshot(&self) -> EngineState {
        EngineState {
            current: self.current,
            vars: self.vars,
            inputs: self.inputs,
            outputs: self.outputs,
            fault: self.fault,
        }
    }

    /// An engine over `table` in a state taken by [`snapshot`](Engine::snapshot) of an
    /// engine running the same table. It builds the table's [`Index`] on every call: for a
    /// test or a one-off; whatever resumes per stimulus keeps the index and calls
    /// [`resume_indexed`](Engine::resume_indexed) (`NodeCore`, `sim`, `verify` do).
    pub fn resume(table: &'t Table, state: &EngineState) -> Self {
        Engine::resume_with(table, IndexRef::Own(Index::new(table)), state)
    }

    /// [`resume`](Engine::resume) with `index`, the [`Index`] of `table` its runtime keeps
    /// (built once when the table was activated).
    pub fn resume_indexed(table: &'t Table, index: &'t Index, state: &EngineState) -> Self {
        Engine::resume_with(table, IndexRef::Kept(index), state)
    }

    fn resume_with(table: &'t Table, index: IndexRef<'t>, state: &EngineState) -> Self {
        Engine {
            table,
            index,
            current: state.current,
            vars: state.vars,
            inputs: state.inputs,
            outputs: state.outputs,
            queue: Deque::new(),
            fault: state.fault,
        }
    }

    /// The table this engine runs.
    pub fn table(&self) -> &'t Table {
        self.table
    }

    /// The chart-local current state of `chart`.
    pub fn state(&self, chart: usize) -> Option<u8> {
        (chart < self.table.charts.len()).then(|| self.current[chart])
    }

    /// The value of variable `var`.
    pub fn var(&self, var: usize) -> Option<i32> {
        (var < self.table.vars.len()).then(|| self.vars[var])
    }

    /// The output levels, bit i = output i.
    pub fn outputs(&self) -> u16 {
        self.outputs
    }

    /// The input levels, bit i = input i.
    pub fn inputs(&self) -> u16 {
        self.inputs
    }

    /// The fault the node is in, if any.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }

    /// Back to the initial state: clears a fault, cancels every timer, charts and variables
    /// to their initial values, outputs to their start levels (a held one keeps its level).
    pub fn reset(&mut self, fx: &mut impl Effects) {
        for timer in 0..self.table.timers.len() {
            fx.cancel_timer(timer as u8);
        }
        let (mask, value) = self.table.start_drive();
        self.drive(mask, value, fx);
        self.init();
    }

    /// Faults the node from outside the charts (a link alarm under `on_link_alarm:
    /// Fault`): as a `Fault(code)` action of no chart ([`config_schema::alarm::NO_CHART`]).
    /// A faulted node stays in its fault.
    pub fn fail(&mut self, code: u8, fx: &mut impl Effects) {
        if self.fault.is_none() {
            let chart = config_schema::alarm::NO_CHART;
            self.set_fault(Fault::Action { chart, code }, fx);
        }
    }

    /// Input `input` is at `level` when the engine starts (a switch that was already
    /// closed): sets the level and its mirror variable without raising any event.
    pub fn sense(&mut self, input: u8, level: bool) {
        let Some(binding) = self.table.inputs.get(usize::from(input)) else {
            return;
        };
        let bit = 1u16 << (input & 15);
        if level {
            self.inputs |= bit;
        } else {
            self.inputs &= !bit;
        }
        if let Some(var) = binding.var.and_then(|v| self.vars.get_mut(usize::from(v))) {
            *var = i32::from(level);
        }
    }

    /// Input `input` is now at `level`: updates its mirror variable and, on an edge, raises
    /// its rise or fall event (published if it has a publication).
    pub fn input(&mut self, input: u8, level: bool, fx: &mut impl Effects) {
        let Some(binding) = self.table.inputs.get(usize::from(input)) else {
            return;
        };
        let bit = 1u16 << (input & 15);
        let was = self.inputs & bit != 0;
        if level {
            self.inputs |= bit;
        } else {
            self.inputs &= !bit;
        }
        if let Some(var) = binding.var.and_then(|v| self.vars.get_mut(usize::from(v))) {
            *var = i32::from(level);
        }
        if was != level {
            if let Some(event) = if level { binding.rise } else { binding.fall } {
                self.raise(event, true, fx);
            }
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
        let sub = self
            .table
            .subscriptions
            .iter()
            .find(|s| s.publisher == publisher && s.topic == topic);
        match sub {
            Some(s) => {
                self.raise(s.event, false, fx);
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
        for (slot, chart) in self.current.iter_mut().zip(self.table.charts.iter()) {
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

    fn raise(&mut self, event: EventId, local: bool, fx: &mut impl Effects) {
        if self.fault.is_some() || usize::from(event) >= usize::from(self.table.events) {
            return;
        }
        if local {
            self.publish(event, fx);
        }
        // The queue is empty between stimuli: the stimulus goes straight to its routes, and
        // only events emitted by actions wait in the FIFO.
        self.dispatch(event, fx);
        let mut processed = 1usize;
        while self.fault.is_none() {
            let Some(next) = self.queue.pop_front() else {
                return;
            };
            processed += 1;
            if processed > MAX_CASCADE {
                self.set_fault(Fault::Cascade { event }, fx);
                return;
            }
            self.dispatch(next, fx);
        }
    }

    /// Publishes `event` if it has a publication.
    #[inline]
    fn publish(&self, event: EventId, fx: &mut impl Effects) {
        let p = self.index.get().publication(event);
        if p != NONE {
            if let Some(p) = self.table.publications.get(usize::from(p)) {
                fx.publish(p);
            }
        }
    }

    /// Delivers `event` to all its routes, in order, each chart running to a stable state.
    fn dispatch(&mut self, event: EventId, fx: &mut impl Effects) {
        let table = self.table;
        let mut r = self.index.get().first_route(event);
        while r != NONE {
            let Some(route) = table.routes.get(usize::from(r)) else {
                return;
            };
            self.deliver(route.chart, route.input, fx);
            if self.fault.is_some() {
                return;
            }
            r = self.index.get().next_route(r);
        }
    }

    /// The global index (into `Table::states`) of `chart`'s current state.
    #[inline]
    fn current_state(&self, chart: u8) -> Option<usize> {
        let c = usize::from(chart);
        let current = *self.current.get(c)?;
        let layout = self.index.get().layout.get(c)?;
        (current < layout.states).then(|| usize::from(layout.first_state) + usize::from(current))
    }

    /// Delivers chart input `input` to `chart` and runs its event-less transitions until it
    /// is stable.
    #[inline]
    fn deliver(&mut self, chart: u8, input: u8, fx: &mut impl Effects) {
        match self.select(chart, Some(input)) {
            Ok(Some(t)) => self.fire(chart, t, fx),
            Ok(None) => {
                fx.ignored(chart, input);
                return;
            }
            Err(fault) => {
                self.set_fault(fault, fx);
                return;
            }
        }
        let mut steps = 0usize;
        while self.fault.is_none() {
            // Only a state with event-less transitions leaving it can move on its own.
            if !self
                .current_state(chart)
                .is_some_and(|s| self.index.get().eventless(s))
            {
                return;
            }
            let t = match self.select(chart, None) {
                Ok(Some(t)) => t,
                Ok(None) => return,
                Err(fault) => {
                    self.set_fault(fault, fx);
                    return;
                }
            };
            steps += 1;
            if steps > MAX_CHAIN {
                self.set_fault(Fault::ChainLimit { chart }, fx);
                return;
            }
            self.fire(chart, t, fx);
        }
    }

    /// The first transition of `chart`, in declaration order, leaving the current state
    /// whose trigger matches (`None`: event-less only) and whose guard holds. A guard that
    /// cannot be evaluated (only in a table that skipped validation) is a fault.
    #[inline]
    fn select(&self, chart: u8, input: Option<u8>) -> Result<Option<usize>, Fault> {
        let table = self.table;
        let Some(state) = self.current_state(chart) else {
            return Ok(None);
        };
        let ix = self.index.get();
        let mut t = ix.first_from(state);
        while t != NONE {
            let Some(tr) = table.transitions.get(usize::from(t)) else {
                return Ok(None);
            };
            if tr.trigger.is_none() || (input.is_some() && tr.trigger == input) {
                let holds = match tr.guard {
                    None => true,
                    Some(g) => self.eval(g).ok_or(Fault::Expr { chart })? != 0,
                };
                if holds {
                    return Ok(Some(usize::from(t)));
                }
            }
            t = ix.next_from(t);
        }
        Ok(None)
    }

    #[inline]
    fn eval(&self, expr: Expr) -> Option<i32> {
        let inputs = self.inputs;
        guard::eval(
            self.table.expr(expr),
            |v| self.vars.get(usize::from(v)).copied(),
            |i| (i < 16).then(|| inputs & (1 << i) != 0),
        )
    }

    #[inline]
    fn fire(&mut self, chart: u8, transition: usize, fx: &mut impl Effects) {
        let table = self.table;
        let Some(t) = table.transitions.get(transition) else {
            return;
        };
        let Some(current) = self.current.get_mut(usize::from(chart)) else {
            return;
        };
        *current = t.to;
        fx.fired(chart, transition as u8, t.from, t.to);
        let first_state = (self.index.get().layout.get(usize::from(chart)))
            .map_or(0, |l| usize::from(l.first_state));
        let state = first_state + usize::from(t.to);
        let actions = table.actions.get(table.state_actions(state)).unwrap_or(&[]);
        for action in actions {
            self.act(chart, *action, fx);
            if self.fault.is_some() {
                return;
            }
        }
    }

    #[inline]
    fn act(&mut self, chart: u8, action: Action, fx: &mut impl Effects) {
        match action {
            Action::Set { var, expr } => match self.eval(expr) {
                Some(value) => {
                    if let Some(slot) = self.vars.get_mut(usize::from(var)) {
                        *slot = value;
                    }
                }
                None => self.set_fault(Fault::Expr { chart }, fx),
            },
            Action::Drive { mask, value } => self.drive(mask, value, fx),
            Action::Emit(event) => self.emit(event, fx),
            Action::Publish(event) => self.publish(event, fx),
            Action::StartTimer { timer, ms } => fx.start_timer(timer, ms),
            Action::CancelTimer(timer) => fx.cancel_timer(timer),
            Action::Fault(code) => self.set_fault(Fault::Action { chart, code }, fx),
        }
    }

    /// A locally originated event: queued and, once queued, published if it has a
    /// publication. An event that does not fit faults the node and is not published.
    fn emit(&mut self, event: EventId, fx: &mut impl Effects) {
        if self.queue.push_back(event).is_err() {
            self.set_fault(Fault::QueueFull { event }, fx);
            return;
        }
        self.publish(event, fx);
    }

    fn drive(&mut self, mask: u16, value: u16, fx: &mut impl Effects) {
        let next = (self.outputs & !mask) | (value & mask);
        // The table's outputs (at most 16): bits 0..n.
        let n = self.table.outputs.len().min(16) as u32;
        let valid = ((1u32 << n) - 1) as u16;
        let mut changed = (self.outputs ^ next) & valid;
        self.outputs = next;
        // Each changed output, lowest first.
        while changed != 0 {
            let i = changed.trailing_zeros();
            changed &= changed - 1;
            fx.output(i as u8, next & (1 << i) != 0);
        }
    }

    fn set_fault(&mut self, fault: Fault, fx: &mut impl Effects) {
        self.fault = Some(fault);
        self.queue.clear();
        let (mask, value) = self.table.fault_drive();
        self.drive(mask, value, fx);
        for timer in 0..self.table.timers.len() {
            fx.cancel_timer(timer as u8);
        }
        fx.fault(fault);
    }
}
