//! config-tool: RON robot descriptions -> checked, compiled, simulated table blobs.
//!
//! - [`source`], [`locate`]: file text, line:col, spans of values by path. [`bounds`]:
//!   the range of an integer field for ron's out-of-bounds error.
//! - [`model`]: the RON format as serde types. [`diag`]: miette diagnostics.
//! - [`check`]: independent check passes, and the one elaboration (-> IR) they share.
//!   [`expr`]: guard text -> bytecode. [`interlock`]: `never:` grammar and names.
//! - [`synth`]: sequence -> charts. [`elab`]: explicit charts -> IR. [`ir`]: the IR, with
//!   each actuator's wiring.
//! - [`lower`]: IR -> tables. [`compile`]: the pipeline. [`dump`], [`diagram`].
//! - The front end above uses nothing of the rest: [`sim`], [`faults`], [`timeline`],
//!   [`verify`], the radio side ([`medium`], [`radio`], [`plant`], [`push`], [`watch`],
//!   [`demo`], [`netcmd`]).

pub mod bounds;
pub mod check;
pub mod compile;
pub mod demo;
pub mod diag;
pub mod diagram;
pub mod dump;
pub mod elab;
pub mod expr;
pub mod faults;
pub mod interlock;
pub mod ir;
pub mod locate;
pub mod lower;
pub mod medium;
pub mod model;
pub mod netcmd;
pub mod plant;
pub mod push;
pub mod radio;
pub mod sim;
pub mod source;
pub mod synth;
pub mod timeline;
pub mod verify;
pub mod watch;

pub use compile::{compile, Compiled};
pub use diag::{Diagnostic, Severity};
pub use source::Source;
