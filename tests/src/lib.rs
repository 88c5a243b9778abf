//! Host-interpreted table tests and end-to-end tests of the robot.
//!
//! - [`paper_robot`]: the paper's four-actuator painting robot as four hand-built tables,
//!   with its plant wiring (used by `tests/paper_robot.rs` and `benches/dispatch.rs`).
//! - [`vc_dispatch`]: one cycle of its VC chart, interpreted and hand-written (the
//!   dispatch benchmarks).

pub mod paper_robot;
pub mod vc_dispatch;
