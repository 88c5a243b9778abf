//! Alarms: what a node latches for the operator, and what its table declares about them
//! (docs/running-a-robot.md, "Alarms").
//!
//! A node keeps at most [`MAX_ALARMS`] alarms, each with its level, its source, the node
//! time it was raised and whether the operator acknowledged it. The table's [`Safety`]
//! says which input is the emergency stop, which inputs restart the machine (refused while
//! a fault alarm is latched), what a link alarm does, and the robot's declared alarms.

use heapless::Vec;
use serde::{Deserialize, Serialize};

use crate::guard::Expr;

/// Alarms a node keeps latched (and sends in one [`crate::wire::msg::Message::Alarms`]).
pub const MAX_ALARMS: usize = 8;
/// Alarms a table may declare.
pub const MAX_DECLARED_ALARMS: usize = 8;

/// How serious an alarm is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum AlarmLevel {
    Info,
    Warning,
    /// The machine may not restart until the operator acknowledged it, which they cannot
    /// while its cause persists.
    Fault,
}

impl core::fmt::Display for AlarmLevel {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            AlarmLevel::Info => "info",
            AlarmLevel::Warning => "warning",
            AlarmLevel::Fault => "fault",
        })
    }
}

/// What raised an alarm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum AlarmSource {
    /// The node faulted: `code` is the status fault code, `chart` the chart whose action
    /// faulted it ([`NO_CHART`]: the interpreter's own bounds). Persists while the node is
    /// faulted (until a reset).
    Chart { chart: u8, code: u8 },
    /// The emergency-stop input was pressed. Persists while it is.
    EStop,
    /// The link to peer `peer` (an index into the table's peers) is in alarm: the peer
    /// stopped acknowledging. Persists while it is.
    Link { peer: u8 },
    /// The table's declared alarm `index` ([`Safety::alarms`]): its condition held.
    /// Persists while it holds.
    Declared { index: u8 },
}

/// Application fault codes (`Action::Fault`, status `0x80 | code`) of the stops: the
/// emergency stop pressed on this node, on another node, a link alarm under
/// `on_link_alarm: Fault`, and a peer that restarted while this node was under way (the
/// last two raised by the node itself, no chart: [`NO_CHART`]).
pub const FAULT_ESTOP: u8 = 3;
pub const FAULT_ESTOP_PEER: u8 = 4;
pub const FAULT_LINK: u8 = 5;
pub const FAULT_PEER_RESTART: u8 = 6;

/// [`AlarmSource::Chart`] of a fault no chart's action raised.
pub const NO_CHART: u8 = u8::MAX;

/// One latched alarm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Alarm {
    pub source: AlarmSource,
    pub level: AlarmLevel,
    /// Node time it was raised: ms since the node booted (modulo 2^32).
    pub raised_ms: u32,
    /// The operator acknowledged it.
    pub acked: bool,
    /// Its cause persists (as of the report).
    pub persists: bool,
}

/// A node's alarms: the answer to `Command::Alarms` and `Command::Ack`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct AlarmReport {
    /// The id of the command this answers.
    pub ack: u16,
    /// The node's time now (ms since boot, modulo 2^32): the tool turns `raised_ms` into
    /// wall time with it.
    pub now_ms: u32,
    /// Oldest first.
    pub alarms: Vec<Alarm, MAX_ALARMS>,
    /// Alarms not kept because the list was full (saturating).
    pub dropped: u16,
}

impl AlarmReport {
    /// A fault alarm not acknowledged, if any: the machine may not restart.
    pub fn blocking(&self) -> Option<&Alarm> {
        self.alarms
            .iter()
            .find(|a| a.level == AlarmLevel::Fault && !a.acked)
    }
}

/// An alarm the robot file declares: raised when `when` becomes true (non-zero),
/// evaluated on the node after every stimulus.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct AlarmDecl {
    pub level: AlarmLevel,
    pub when: Expr,
}

/// The table's safety declarations.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Safety {
    /// The emergency-stop input (an index into the table's inputs), pressed when high.
    pub estop: Option<u8>,
    /// A link alarm faults the node (`on_link_alarm: Fault`) instead of only stalling it.
    pub link_fault: bool,
    /// Bit i: input i restarts the machine (its rising edge is refused while a fault alarm
    /// is latched), besides the START command.
    pub restart: u16,
    pub alarms: Vec<AlarmDecl, MAX_DECLARED_ALARMS>,
}
