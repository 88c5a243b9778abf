//! Times: a motion watchdog of 0 ms (`motion_timeout_ms`, an actuator's `timeout_ms`)
//! would fault every motion the moment it is commanded; in synthesised charts (a
//! `sequence`), a stroke (`out_ms`, `back_ms`) the watchdog does not wait for faults every
//! such motion (a warning: the machine stops safely), and a dwell shorter than the stroke it
//! stands for lets the next step start while the actuator still moves (an error).

use crate::diag::Diagnostic;
use crate::model::{Actuator, ActuatorKind, Robot};
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
            } else if robot.sequence.is_some() {
                strokes(
                    robot,
                    a,
                    &format!("roles[{ri}].actuators[{ai}].kind"),
                    src,
                    out,
                );
            }
        }
    }
}

/// Each motion of `a` (at `kind` in the file) against what completes it in synthesised
/// charts: its end switch under the watchdog, or the dwell time.
fn strokes(robot: &Robot, a: &Actuator, kind: &str, src: &Source, out: &mut Vec<Diagnostic>) {
    let (out_ms, back_ms) = a.kind.strokes();
    let dwell_ms = match a.kind {
        ActuatorKind::SingleActing { dwell_ms, .. } => Some(dwell_ms),
        ActuatorKind::DoubleActing { .. } => None,
    };
    let (watchdog, watchdog_field) = match a.kind.timeout_ms() {
        Some(ms) => (ms, "`timeout_ms`"),
        None => (robot.motion_timeout_ms, "`motion_timeout_ms`"),
    };
    for (extend, stroke, field) in [(true, out_ms, "out_ms"), (false, back_ms, "back_ms")] {
        // A stroke the file does not give is `sim`'s guess (200 ms), not the machine's.
        let path = format!("{kind}.{field}");
        if !src.has(&path) {
            continue;
        }
        let motion = format!("{}{}", a.name, if extend { '+' } else { '-' });
        let at = src.span(&path);
        if a.kind.completion_switch(extend).is_some() {
            // A watchdog of 0 ms is refused already.
            if watchdog > 0 && stroke >= watchdog {
                // A warning: the machine stops safely, and `sim` shows how.
                out.push(
                    Diagnostic::warning(
                        at,
                        format!(
                            "`{motion}` takes {stroke} ms (`{field}`) and its watchdog fires \
                             at {watchdog} ms ({watchdog_field}): every `{motion}` would fault"
                        ),
                    )
                    .label(format!("less than {watchdog}"))
                    .help(format!(
                        "give the stroke's real time, or a longer watchdog (`timeout_ms` of \
                         `{}`)",
                        a.name
                    )),
                );
            }
        } else if let Some(dwell) = dwell_ms.filter(|&d| d < stroke) {
            out.push(
                Diagnostic::error(
                    at,
                    format!(
                        "`{motion}` completes after `dwell_ms` ({dwell} ms) but takes {stroke} \
                         ms (`{field}`): the next step would start while `{}` still moves",
                        a.name
                    ),
                )
                .label(format!("at most {dwell}"))
                .help(format!(
                    "make `dwell_ms` at least the longest stroke, or give `{}` a position \
                     sensor",
                    a.name
                )),
            );
        }
    }
}
