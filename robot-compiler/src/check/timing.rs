//! Times: a motion watchdog of 0 ms (`motion_timeout_ms`, an actuator's `timeout_ms`)
//! would fault every motion the moment it is commanded.

use crate::diag::Diagnostic;
use crate::model::Robot;
use crate::source::Source;

pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    let zero = |path: &str, what: &str| {
        Diagnostic::error(
            src.span(path),
            format!("{what} is 0 ms: every motion would fault as soon as it is commanded"),
        )
        .label("more than 0")
        .help("give the longest time a motion may take, e.g. 2000")
    };
    if robot.motion_timeout_ms == 0 {
        out.push(zero("motion_timeout_ms", "`motion_timeout_ms`"));
    }
    for (ri, r) in robot.roles.iter().enumerate() {
        for (ai, a) in r.actuators.iter().enumerate() {
            if a.kind.timeout_ms() == Some(0) {
                out.push(zero(
                    &format!("roles[{ri}].actuators[{ai}].kind.timeout_ms"),
                    &format!("the watchdog `timeout_ms` of `{}`", a.name),
                ));
            }
        }
    }
}
