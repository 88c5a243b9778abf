//! One function per command.

pub mod alarms;
pub mod demo;
pub mod export;
pub mod keys;
pub mod matrix;
pub mod offline;
pub mod operator;
pub mod outputs;
pub mod panel;
pub mod radio;

use std::path::Path;

use crate::failure::Failure;

/// `--role ROLE` names a role of `robot` (compiled as `ir`), or it is a bad argument
/// (status 2) naming the robot's roles.
pub(crate) fn known_role(
    robot: &Path,
    ir: &robot_compiler::ir::Ir,
    role: &str,
) -> Result<(), Failure> {
    ir.role(role)
        .map(|_| ())
        .map_err(|e| Failure::usage(format!("{}: {e}", robot.display())))
}
