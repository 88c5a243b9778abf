//! Output levels outside the charts: homing drives a level, so a plain output's `home`
//! is `Low` or `High`, never `Hold` (fault and start may hold).

use config_schema::Level;

use crate::diag::Diagnostic;
use crate::model::Robot;
use crate::source::Source;

pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    for (ri, r) in robot.roles.iter().enumerate() {
        for (k, o) in r.outputs.iter().enumerate() {
            if o.home == Some(Level::Hold) {
                out.push(
                    Diagnostic::error(
                        src.span(&format!("roles[{ri}].outputs[{k}].home")),
                        format!(
                            "`home` of output `{}` is `Hold`: homing drives an output to a level",
                            o.name
                        ),
                    )
                    .label("`Low` or `High`")
                    .help("`Hold` keeps a level on fault or at start (`fault`, `start`)"),
                );
            }
        }
    }
}
