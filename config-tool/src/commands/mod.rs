//! One function per command.

pub mod alarms;
pub mod demo;
pub mod export;
pub mod keys;
pub mod matrix;
pub mod offline;
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
    if ir.roles.iter().any(|r| r.name == role) {
        return Ok(());
    }
    let roles: Vec<&str> = ir.roles.iter().map(|r| r.name.as_str()).collect();
    Err(Failure::usage(format!(
        "{}: unknown role `{role}` (roles: {})",
        robot.display(),
        roles.join(", ")
    )))
}
