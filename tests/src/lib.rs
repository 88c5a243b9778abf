//! Host-interpreted table tests and end-to-end tests of the robot.
//!
//! - [`paper_robot`]: the paper's four-actuator painting robot as four hand-built tables,
//!   with its plant wiring (used by `tests/paper_robot.rs` and `benches/dispatch.rs`).

pub mod paper_robot;
