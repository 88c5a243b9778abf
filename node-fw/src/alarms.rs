//! The node's latched alarms (docs/running-a-robot.md, "Alarms"): `no_std`, allocation
//! free, shared by [`crate::node::NodeCore`] and the simulator.
//!
//! After every stimulus the node calls [`Alarms::look`] with its table and engine state
//! (and whether it wrote the state since the last look: if not, only the links are
//! compared, the rest cannot have changed; the simulator calls [`Alarms::observe`], which
//! looks at everything): a fault of the node, the emergency stop pressed, a link gone into alarm or a
//! declared condition become true raises an alarm (one per rising cause; a cause that
//! rises again while its alarm is still latched raises nothing new). An alarm stays latched
//! until [`Alarms::ack`]; a fault alarm whose cause persists is not acknowledged. While a
//! fault alarm is latched the machine may not restart ([`Alarms::blocking`]).
//!
//! The list holds [`MAX_ALARMS`]. A new alarm when it is full replaces the oldest
//! acknowledged one, else (a fault alarm) the oldest info or warning one; else it is
//! dropped and counted: the oldest fault alarms are kept.

use config_schema::alarm::{
    Alarm, AlarmLevel, AlarmReport, AlarmSource, MAX_ALARMS, MAX_DECLARED_ALARMS, NO_CHART,
};
use config_schema::{guard, Table};
use heapless::Vec;

use crate::ecc::{EngineState, Fault};
use crate::node::fault_code;

/// What the node's alarms are made of at one moment.
#[derive(Debug, Clone, Copy)]
pub struct Seen<'a> {
    pub table: &'a Table,
    pub state: &'a EngineState,
    /// Bit i: the link to peer i is in alarm.
    pub link_alarms: u8,
}

/// The latched alarms of one node.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Alarms {
    list: Vec<Alarm, MAX_ALARMS>,
    dropped: u16,
    /// Causes as of the last observation: the node faulted, the e-stop pressed, bit i of
    /// `links` peer i in alarm, bit i of `declared` declared alarm i holding.
    faulted: bool,
    estop: bool,
    links: u8,
    declared: u8,
    /// Alarms latched so far (wrapping): what one observation latched.
    raised: u16,
    /// The causes above are those of the running table (false: looked at afresh next).
    looked: bool,
}

impl Alarms {
    /// Looks at the node after a stimulus at `now_ms` (ms since boot) and raises an alarm
    /// for each cause that rose since the last look. Returns how many it latched (the
    /// newest of [`Alarms::list`]).
    pub fn observe(&mut self, seen: Seen<'_>, now_ms: u64) -> usize {
        self.look(seen, now_ms, true)
    }

    /// [`Alarms::observe`] for a caller that knows whether the engine state changed since
    /// the last look (`state_changed`; the node core sets it wherever it writes the state).
    /// The fault, the e-stop and the declared conditions read only the table and the
    /// state, so with the state unchanged only the links are compared, and a look that
    /// finds them as they were returns at once: the same alarms at the same moments as
    /// [`Alarms::observe`], which looks at everything.
    #[inline]
    pub fn look(&mut self, seen: Seen<'_>, now_ms: u64, state_changed: bool) -> usize {
        // Inline: the common look (nothing changed) costs its caller a compare.
        if self.quiet(seen.link_alarms, state_changed) {
            return 0;
        }
        self.look_again(seen, now_ms, state_changed || !self.looked)
    }

    /// Whether [`Alarms::look`] with links `link_alarms` in alarm and `state_changed`
    /// would find nothing to look at (and return 0 at once): a caller asks it before it
    /// puts together what `look` is given.
    #[inline(always)]
    pub fn quiet(&self, link_alarms: u8, state_changed: bool) -> bool {
        !state_changed && self.looked && link_alarms == self.links
    }

    fn look_again(&mut self, seen: Seen<'_>, now_ms: u64, state_changed: bool) -> usize {
        self.looked = true;
        let now = now_ms as u32;
        let list = self.raised;
        if state_changed {
            self.look_at_state(seen, now);
        }
        let mut rose = seen.link_alarms & !self.links;
        if rose != 0 {
            let level = if seen.table.safety.link_fault {
                AlarmLevel::Fault
            } else {
                AlarmLevel::Warning
            };
            // Lowest peer first.
            while rose != 0 {
                let peer = rose.trailing_zeros() as u8;
                self.raise(AlarmSource::Link { peer }, level, now);
                rose &= rose - 1;
            }
        }
        self.links = seen.link_alarms;
        if state_changed {
            self.look_at_declared(seen, now);
        }
        let n = self.raised.wrapping_sub(list);
        usize::from(n)
    }

    /// The causes read from the table and the engine state before the links: the e-stop,
    /// then the node's fault.
    fn look_at_state(&mut self, seen: Seen<'_>, now: u32) {
        let estop = estop_pressed(seen);
        if estop && !self.estop {
            self.raise(AlarmSource::EStop, AlarmLevel::Fault, now);
        }
        self.estop = estop;
        let faulted = seen.state.fault;
        if let (Some(f), false) = (faulted, self.faulted) {
            // The emergency stop's own fault is its alarm already.
            if !estop {
                let chart = match f {
                    Fault::ChainLimit { chart }
                    | Fault::Action { chart, .. }
                    | Fault::Expr { chart } => chart,
                    Fault::QueueFull { .. } | Fault::Cascade { .. } => NO_CHART,
                };
                let source = AlarmSource::Chart {
                    chart,
                    code: fault_code(f),
                };
                self.raise(source, AlarmLevel::Fault, now);
            }
        }
        self.faulted = faulted.is_some();
    }

    /// The declared conditions, raised after the links as [`Alarms::observe`] always did.
    fn look_at_declared(&mut self, seen: Seen<'_>, now: u32) {
        let mut declared = 0u8;
        for (i, a) in seen
            .table
            .safety
            .alarms
            .iter()
            .enumerate()
            .take(MAX_DECLARED_ALARMS)
        {
            if holds(seen, a.when) {
                declared |= 1 << i;
                if self.declared & (1 << i) == 0 {
                    let source = AlarmSource::Declared { index: i as u8 };
                    self.raise(source, a.level, now);
                }
            }
        }
        self.declared = declared;
    }

    fn raise(&mut self, source: AlarmSource, level: AlarmLevel, now: u32) {
        if self.list.iter().any(|a| a.source == source && !a.acked) {
            return; // still latched: the same alarm
        }
        let alarm = Alarm {
            source,
            level,
            raised_ms: now,
            acked: false,
            persists: true,
        };
        if self.list.is_full() {
            let acked = self.list.iter().position(|a| a.acked);
            let lesser = || {
                (level == AlarmLevel::Fault)
                    .then(|| self.list.iter().position(|a| a.level != AlarmLevel::Fault))
                    .flatten()
            };
            match acked.or_else(lesser) {
                Some(i) => {
                    crate::remove_at(&mut self.list, i);
                }
                None => {
                    self.dropped = self.dropped.saturating_add(1);
                    return;
                }
            }
        }
        if self.list.push(alarm).is_ok() {
            self.raised = self.raised.wrapping_add(1);
        }
    }

    /// Whether the cause of `source` persists.
    pub fn persists(seen: Seen<'_>, source: AlarmSource) -> bool {
        match source {
            AlarmSource::Chart { .. } => seen.state.fault.is_some(),
            AlarmSource::EStop => estop_pressed(seen),
            AlarmSource::Link { peer } => seen.link_alarms & (1u8 << (peer & 7)) != 0,
            AlarmSource::Declared { index } => (seen.table.safety.alarms)
                .get(usize::from(index))
                .is_some_and(|a| holds(seen, a.when)),
        }
    }

    /// Whether the cause of alarm `i` of the list persists: its source's cause persists,
    /// and no later alarm has the same cause (an alarm is raised as its cause begins, so a
    /// later one means this one's cause ended in between; the node's fault is one cause
    /// whatever its code: a reset ends it).
    fn cause_persists(&self, seen: Seen<'_>, i: usize) -> bool {
        let Some(a) = self.list.get(i) else {
            return false;
        };
        let same = |b: &Alarm| match (a.source, b.source) {
            (AlarmSource::Chart { .. }, AlarmSource::Chart { .. }) => true,
            (x, y) => x == y,
        };
        let later = self.list.iter().skip(i + 1).any(same);
        !later && Alarms::persists(seen, a.source)
    }

    /// The operator acknowledges: every latched alarm is acknowledged but a fault alarm
    /// whose cause persists. Returns how many were.
    pub fn ack(&mut self, seen: Seen<'_>) -> usize {
        let mut n = 0;
        for i in 0..self.list.len() {
            let Some(a) = self.list.get(i) else { continue };
            if a.acked || a.level == AlarmLevel::Fault && self.cause_persists(seen, i) {
                continue;
            }
            if let Some(a) = self.list.get_mut(i) {
                a.acked = true;
                n += 1;
            }
        }
        n
    }

    /// The oldest fault alarm not acknowledged: while there is one, the machine may not
    /// restart.
    pub fn blocking(&self) -> Option<&Alarm> {
        self.list
            .iter()
            .find(|a| a.level == AlarmLevel::Fault && !a.acked)
    }

    /// The alarms, oldest first (`persists` as of the last report).
    pub fn list(&self) -> &[Alarm] {
        &self.list
    }

    /// Alarms dropped because the list was full.
    pub fn dropped(&self) -> u16 {
        self.dropped
    }

    /// The report of command `ack` at `now_ms`, each alarm's `persists` as of `seen`.
    pub fn report(&self, ack: u16, seen: Option<Seen<'_>>, now_ms: u64) -> AlarmReport {
        let mut alarms = self.list.clone();
        for (i, a) in alarms.iter_mut().enumerate() {
            a.persists = seen.is_some_and(|s| self.cause_persists(s, i));
        }
        AlarmReport {
            ack,
            now_ms: now_ms as u32,
            alarms,
            dropped: self.dropped,
        }
    }

    /// A new table: its causes are looked at afresh (the latched alarms stay).
    pub fn new_table(&mut self) {
        self.faulted = false;
        self.estop = false;
        self.links = 0;
        self.declared = 0;
        self.looked = false;
    }
}

/// What the alarms read of a running table's engine state, found once per table (kept
/// beside it: [`Reads`] are taken at every stimulus): the emergency stop's input bit, and
/// whether the table declares alarms.
#[derive(Debug, Clone, Copy, Default)]
pub struct Watch {
    /// The emergency stop's input bit (none: 0).
    estop: u16,
    declared: bool,
}

impl Watch {
    /// What the alarms read of the state of `table`.
    pub fn of(table: &Table) -> Watch {
        Watch {
            estop: estop_bit(table),
            declared: !table.safety.alarms.is_empty(),
        }
    }
}

/// What the alarms read from an engine state, kept before a stimulus that runs the engine
/// on the state in place (nothing copied): the fault and the emergency stop's input (the
/// other inputs are read by declared conditions only). A table that declares alarms has
/// their conditions read its inputs and variables too: for it every such stimulus counts
/// as a change ([`Alarms::look`] then looks at everything, as [`Alarms::observe`] does:
/// the same alarms at the same moments).
#[derive(Debug, Clone, Copy)]
pub struct Reads {
    fault: Option<Fault>,
    /// The inputs masked with the emergency stop's input bit.
    inputs: u16,
}

impl Reads {
    /// What the alarms read of `state` now (running the table `watch` is of).
    #[inline]
    pub fn of(watch: Watch, state: &EngineState) -> Reads {
        Reads {
            fault: state.fault,
            inputs: state.inputs & watch.estop,
        }
    }

    /// Whether the alarms may read something else in `now`: the fault or the emergency
    /// stop's input changed, or the table declares alarms (their conditions taken as
    /// changed).
    #[inline]
    pub fn changed(&self, watch: Watch, now: &EngineState) -> bool {
        watch.declared || self.fault != now.fault || self.inputs != now.inputs & watch.estop
    }
}

/// The table's emergency-stop input as a bit of the engine's inputs (none, or past them:
/// 0).
fn estop_bit(table: &Table) -> u16 {
    (table.safety.estop)
        .and_then(|i| 1u16.checked_shl(u32::from(i)))
        .unwrap_or(0)
}

/// Whether the table's emergency-stop input is high.
fn estop_pressed(seen: Seen<'_>) -> bool {
    estop_bit(seen.table) & seen.state.inputs != 0
}

/// Whether a declared condition holds (an expression that does not evaluate: no).
fn holds(seen: Seen<'_>, when: config_schema::Expr) -> bool {
    let (vars, inputs) = (&seen.state.vars, seen.state.inputs);
    let value = guard::eval(
        seen.table.expr(when),
        |v| vars.get(usize::from(v)).copied(),
        |i| (i < 16).then(|| inputs & (1 << i) != 0),
    );
    value.is_some_and(|v| v != 0)
}

#[cfg(test)]
mod tests;
