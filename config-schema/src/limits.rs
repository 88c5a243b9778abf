//! Every capacity of a table, in one place.
//!
//! These bound the decoded [`Table`](crate::Table) (its RAM footprint is fixed at compile time)
//! and the interpreter's work per delivered event. config-tool checks a robot against them
//! before it compiles, and [`validate`](fn@crate::validate) checks every decoded blob again.

/// Node events (ids `0..MAX_EVENTS`): input edges, timer expiries, subscribed remote events,
/// events emitted by charts.
pub const MAX_EVENTS: usize = 64;
/// Integer variables (`i32`) of a node, shared by its charts.
pub const MAX_VARS: usize = 32;
/// Digital inputs (limit switches, buttons, sensors).
pub const MAX_INPUTS: usize = 16;
/// Digital outputs (valve solenoids, lamps). An output mask is a `u16`.
pub const MAX_OUTPUTS: usize = 16;
/// One-shot timers.
pub const MAX_TIMERS: usize = 8;
/// ECC instances per node.
pub const MAX_CHARTS: usize = 8;
/// States over all charts of a node.
pub const MAX_STATES: usize = 96;
/// Transitions over all charts of a node.
pub const MAX_TRANSITIONS: usize = 128;
/// Chart input events per chart.
pub const MAX_CHART_INPUTS: usize = 32;
/// Actions over all states of a node.
pub const MAX_ACTIONS: usize = 160;
/// Guard / expression bytecode operations over the whole node.
pub const MAX_CODE: usize = 192;
/// Operations in one expression.
pub const MAX_EXPR_LEN: usize = 32;
/// Evaluation stack depth of one expression.
pub const MAX_STACK: usize = 8;
/// Event routes (node event -> chart input).
pub const MAX_ROUTES: usize = 96;
/// Peer nodes this node exchanges events with.
pub const MAX_PEERS: usize = 8;
/// Node events published to the radio.
pub const MAX_PUBLICATIONS: usize = 24;
/// Remote events subscribed from the radio.
pub const MAX_SUBSCRIPTIONS: usize = 32;
/// Board pin numbers a table may name: `0..MAX_PINS` (a node keeps its pin levels in a
/// `u64`, one bit a pin).
pub const MAX_PINS: usize = 64;
/// Bytes of the role name.
pub const MAX_ROLE_NAME: usize = 12;
/// Roles of one robot: the nodes the tool's switch-over moves together
/// (`node_fw::switch::Coordinator`).
pub const MAX_ROLES: usize = 16;

/// Event-less transitions fired in one delivery before the node faults.
pub const MAX_CHAIN: usize = 32;
/// Pending events in the interpreter's FIFO before the node faults.
pub const EVENT_QUEUE: usize = 16;

/// Largest transfer a node accepts and stores: the encoded blob (envelope included) and
/// the link key block that may follow it.
pub const MAX_BLOB: usize = 4096;
/// Largest table blob the compiler makes: room is left for the largest key block.
pub const MAX_TABLE_BLOB: usize = MAX_BLOB - crate::link_keys::MAX_LEN;
/// Events processed (queued and delivered) per outside stimulus before the node faults:
/// bounds a cascade of charts that keep emitting to each other.
pub const MAX_CASCADE: usize = 64;

/// IEEE 802.15.4 channels of the 2.4 GHz band (O-QPSK): the only ones a table may name.
pub const CHANNELS: core::ops::RangeInclusive<u8> = 11..=26;
