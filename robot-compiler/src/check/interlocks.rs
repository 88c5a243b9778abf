//! `never:` interlocks: syntax, and names that resolve to actuator positions, chart states
//! or node faults of the elaborated robot.

use crate::diag::Diagnostic;
use crate::elab::StrMap;
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
            let path = format!("never[{i}]");
            let at = StrMap::new(src, &path).span(e.span());
            let value = src.span(&path);
            let end = at.end.min(value.end).max(at.start);
            out.push(Diagnostic::error(at.start..end, e.to_string()));
        }
    }
}
