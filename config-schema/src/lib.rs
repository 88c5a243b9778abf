//! The table model and formats shared by the node firmware and `config-tool`.
//!
//! `no_std`, no allocation. See `docs/table-format.md`.
//!
//! - [`limits`]: every capacity, in one place.
//! - [`table`]: the table one node runs.
//! - [`guard`]: the expression bytecode of guards and assignments.
//! - [`validate`](mod@validate): semantic checks of a decoded table; [`cost`]: the worst-case work of one
//!   stimulus, which it bounds.
//! - [`blob`]: the versioned, CRC-protected envelope, [`encode`] and [`decode`]; [`pack`]:
//!   the bit-packed payload inside it.
//! - [`alarm`]: alarms a node latches, and the table's safety declarations.
//! - [`text`]: a role name read from bytes (UTF-8 checked).
//! - [`link_keys`]: the link key block that follows a blob in a secured transfer.
#![no_std]
#![forbid(unsafe_code)]

pub mod alarm;
pub mod blob;
pub mod cost;
pub mod guard;
pub mod limits;
pub mod link_keys;
pub mod pack;
pub mod table;
pub mod text;
pub mod validate;
pub mod wire;

pub use blob::{decode, encode, DecodeError, EncodeError, TableId, SCHEMA_VERSION};
pub use guard::{Expr, ExprError, Op};
pub use table::*;
pub use validate::{validate, validate_structure, Invalid, Place};
