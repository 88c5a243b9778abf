//! `never:` interlocks: syntax, and names that resolve to actuator positions, chart states
//! or node faults of the elaborated robot.

use crate::diag::Diagnostic;
use crate::interlock;
use crate::ir::Ir;
use crate::model::Robot;
use crate::source::Source;

pub fn check(robot: &Robot, ir: &Ir, src: &Source, out: &mut Vec<Diagnostic>) {
    if robot.never.is_empty() {
        return;
    }
    let names = interlock::Scope::of(robot, ir);
    for (i, text) in robot.never.iter().enumerate() {
        if let Err(e) = names.interlock(text) {
            let span = e.span();
            let value = src.span(&format!("never[{i}]"));
            // The value's span starts at its opening quote.
            let start = value.start + 1 + span.start;
            let end = (value.start + 1 + span.end).min(value.end);
            out.push(Diagnostic::error(start..end.max(start), e.to_string()));
        }
    }
}
