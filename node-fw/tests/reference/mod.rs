//! The reference interpreter: docs/ecc-semantics.md read literally, a plain walk over the
//! table's pools (every route, every transition of the chart, the stack machine for every
//! expression), with no index and no lowering. The engine must report exactly what this
//! reports, for every valid table and stimulus (`ecc_props.rs`).

use std::collections::VecDeque;

use config_schema::limits::{EVENT_QUEUE, MAX_CASCADE, MAX_CHAIN, MAX_VARS};
use config_schema::{guard, Action, EventId, Expr, Table, Topic, Transition};
use node_fw::ecc::{Effects, Fault};

/// One node's charts over `t`, as the semantics say.
pub struct Reference<'t> {
    t: &'t Table,
    pub current: Vec<u8>,
    pub vars: [i32; MAX_VARS],
    pub inputs: u16,
    pub outputs: u16,
    queue: VecDeque<EventId>,
    pub fault: Option<Fault>,
}

impl<'t> Reference<'t> {
    pub fn new(t: &'t Table) -> Self {
        let (mask, value) = t.start_drive();
        let mut r = Reference {
            t,
            current: Vec::new(),
            vars: [0; MAX_VARS],
            inputs: 0,
            outputs: value & mask,
            queue: VecDeque::new(),
            fault: None,
        };
        r.init();
        r
    }

    fn init(&mut self) {
        self.current = self.t.charts.iter().map(|c| c.initial).collect();
        for (slot, v) in self.vars.iter_mut().zip(&self.t.vars) {
            *slot = *v;
        }
        for (i, input) in self.t.inputs.iter().enumerate() {
            if let Some(v) = input.var {
                self.vars[usize::from(v)] = i32::from(self.inputs & (1 << i) != 0);
            }
        }
        self.queue.clear();
        self.fault = None;
    }

    pub fn reset(&mut self, fx: &mut impl Effects) {
        for timer in 0..self.t.timers.len() {
            fx.cancel_timer(timer as u8);
        }
        let (mask, value) = self.t.start_drive();
        self.drive(mask, value, fx);
        self.init();
    }

    pub fn input(&mut self, i: u8, level: bool, fx: &mut impl Effects) {
        let Some(input) = self.t.inputs.get(usize::from(i)) else {
            return;
        };
        let was = self.inputs & (1 << i) != 0;
        if level {
            self.inputs |= 1 << i;
        } else {
            self.inputs &= !(1 << i);
        }
        if let Some(v) = input.var {
            self.vars[usize::from(v)] = i32::from(level);
        }
        if was != level {
            if let Some(e) = if level { input.rise } else { input.fall } {
                self.raise(e, true, fx);
            }
        }
    }

    pub fn timer_expired(&mut self, timer: u8, fx: &mut impl Effects) {
        if let Some(t) = self.t.timers.get(usize::from(timer)) {
            self.raise(t.event, true, fx);
        }
    }

    pub fn remote(&mut self, publisher: u8, topic: Topic, fx: &mut impl Effects) -> bool {
        let sub =
            (self.t.subscriptions.iter()).find(|s| s.publisher == publisher && s.topic == topic);
        match sub {
            Some(s) => {
                self.raise(s.event, false, fx);
                true
            }
            None => false,
        }
    }

    pub fn start(&mut self, fx: &mut impl Effects) -> bool {
        match self.t.start {
            Some(e) => {
                self.raise(e, true, fx);
                true
            }
            None => false,
        }
    }

    pub fn event(&mut self, e: EventId, fx: &mut impl Effects) {
        self.raise(e, false, fx);
    }

    fn raise(&mut self, stimulus: EventId, local: bool, fx: &mut impl Effects) {
        if self.fault.is_some() || stimulus >= self.t.events {
            return;
        }
        if local {
            self.publish(stimulus, fx);
        }
        // The stimulus is taken first; what the charts emit waits behind it.
        let mut next = Some(stimulus);
        let mut processed = 0;
        while let Some(e) = next {
            processed += 1;
            if processed > MAX_CASCADE {
                self.set_fault(Fault::Cascade { event: stimulus }, fx);
                return;
            }
            for r in self.t.routes.iter().filter(|r| r.event == e) {
                self.deliver(r.chart, r.input, fx);
                if self.fault.is_some() {
                    return;
                }
            }
            next = self.queue.pop_front();
        }
    }

    /// The first transition of `chart` in declaration order leaving its current state on
    /// `input` (or event-less; `None`: event-less only) whose guard holds.
    fn select(&self, chart: u8, input: Option<u8>) -> Result<Option<(usize, Transition)>, Fault> {
        let c = usize::from(chart);
        let range = self.t.chart_transitions(c);
        for (i, t) in self.t.transitions[range.clone()].iter().enumerate() {
            if t.from != self.current[c] || !(t.trigger.is_none() || t.trigger == input) {
                continue;
            }
            let holds = match t.guard {
                None => true,
                Some(g) => self.eval(g).ok_or(Fault::Expr { chart })? != 0,
            };
            if holds {
                return Ok(Some((range.start + i, *t)));
            }
        }
        Ok(None)
    }

    fn deliver(&mut self, chart: u8, input: u8, fx: &mut impl Effects) {
        match self.select(chart, Some(input)) {
            Ok(Some((i, t))) => self.fire(chart, i, t, fx),
            Ok(None) => return fx.ignored(chart, input),
            Err(f) => return self.set_fault(f, fx),
        }
        let mut chained = 0;
        while self.fault.is_none() {
            match self.select(chart, None) {
                Ok(Some((i, t))) => {
                    chained += 1;
                    if chained > MAX_CHAIN {
                        return self.set_fault(Fault::ChainLimit { chart }, fx);
                    }
                    self.fire(chart, i, t, fx);
                }
                Ok(None) => return,
                Err(f) => return self.set_fault(f, fx),
            }
        }
    }

    fn fire(&mut self, chart: u8, i: usize, t: Transition, fx: &mut impl Effects) {
        let c = usize::from(chart);
        self.current[c] = t.to;
        fx.fired(chart, i as u8, t.from, t.to);
        let state = self.t.chart_states(c).start + usize::from(t.to);
        for a in &self.t.actions[self.t.state_actions(state)] {
            match *a {
                Action::Set { var, expr } => match self.eval(expr) {
                    Some(v) => self.vars[usize::from(var)] = v,
                    None => self.set_fault(Fault::Expr { chart }, fx),
                },
                Action::Drive { mask, value } => self.drive(mask, value, fx),
                Action::Emit(e) => {
                    if self.queue.len() >= EVENT_QUEUE {
                        self.set_fault(Fault::QueueFull { event: e }, fx);
                    } else {
                        self.queue.push_back(e);
                        self.publish(e, fx);
                    }
                }
                Action::Publish(e) => self.publish(e, fx),
                Action::StartTimer { timer, ms } => fx.start_timer(timer, ms),
                Action::CancelTimer(timer) => fx.cancel_timer(timer),
                Action::Fault(code) => self.set_fault(Fault::Action { chart, code }, fx),
            }
            if self.fault.is_some() {
                return;
            }
        }
    }

    fn eval(&self, e: Expr) -> Option<i32> {
        let inputs = self.inputs;
        guard::eval(
            self.t.expr(e),
            |v| self.vars.get(usize::from(v)).copied(),
            |i| (i < 16).then(|| inputs & (1 << i) != 0),
        )
    }

    fn publish(&self, e: EventId, fx: &mut impl Effects) {
        if let Some(p) = self.t.publication(e) {
            fx.publish(p);
        }
    }

    fn drive(&mut self, mask: u16, value: u16, fx: &mut impl Effects) {
        let next = (self.outputs & !mask) | (value & mask);
        for i in 0..self.t.outputs.len() {
            if (self.outputs ^ next) & (1 << i) != 0 {
                fx.output(i as u8, next & (1 << i) != 0);
            }
        }
        self.outputs = next;
    }

    fn set_fault(&mut self, f: Fault, fx: &mut impl Effects) {
        self.fault = Some(f);
        self.queue.clear();
        let (mask, value) = self.t.fault_drive();
        self.drive(mask, value, fx);
        for timer in 0..self.t.timers.len() {
            fx.cancel_timer(timer as u8);
        }
        fx.fault(f);
    }
}
