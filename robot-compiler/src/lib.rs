//! The robot compiler: a RON description of a machine -> checked IR -> one ECC table per
//! role -> blobs. One direction, one elaboration:
//!
//! - [`source`], [`locate`]: file text, line:col, spans of values by path. [`bounds`]:
//!   the range of an integer field for ron's out-of-bounds error.
//! - [`model`]: the RON format as serde types. [`diag`]: miette diagnostics.
//! - [`check`]: independent check passes, and the one elaboration (-> IR) they share.
//!   [`expr`]: guard text -> bytecode. [`interlock`]: `never:` grammar and names.
//! - [`synth`]: sequence -> charts. [`elab`]: explicit charts -> IR. [`ir`]: the IR, with
//!   each actuator's wiring.
//! - [`homing`]: the homing sequence, derived or declared, and the interlocks it keeps.
//! - [`automata`]: selecting automata (RON or the paper's Prolog facts), their checks.
//! - [`petri`]: control functions as state-machine Petri nets (places and transitions or
//!   the paper's matrices), their checks, their charts, their matrix export.
//! - [`sorting`]: a sorting station's colour truth table, compiled to a classification
//!   chart.
//! - [`numbering`]: event ids, routes and imports in the order the packed table reads
//!   them. [`lower`]: IR -> tables. [`compile`](mod@compile): the pipeline. [`dump`], [`diagram`].
//!
//! It knows nothing of the node firmware, the simulator or the radio (see
//! `docs/architecture.md`).

pub mod alarms;
pub mod automata;
pub mod bounds;
pub mod check;
pub mod compile;
pub mod diag;
pub mod diagram;
pub mod dump;
pub mod elab;
pub mod expr;
pub mod homing;
pub mod iec61499;
pub mod interlock;
pub mod ir;
pub mod locate;
pub mod lower;
pub mod model;
pub mod numbering;
pub mod petri;
pub mod plants;
pub mod sorting;
pub mod source;
pub mod synth;
mod unclosed;

pub use compile::{compile, Compiled};
pub use diag::{Diagnostic, Severity};
pub use source::Source;
