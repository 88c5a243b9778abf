//! Checks: independent passes over the parsed robot, each adding diagnostics. Structural
//! passes run first; the passes that need the elaborated robot run only when the structure
//! is sound (otherwise they would report the same problem twice). Add a pass by writing
//! `fn(&Robot, &Source, &mut Vec<Diagnostic>)` and listing it below.

mod charts;
mod events;
mod interlocks;
mod names;
mod network;
mod pins;
mod sequence;
mod tables;
mod timing;

use crate::diag::{self, Diagnostic};
use crate::model::{self, Robot};
use crate::source::Source;

/// A check pass.
pub type Pass = fn(&Robot, &Source, &mut Vec<Diagnostic>);

/// Passes over the description as written.
pub const STRUCTURE: &[(&str, Pass)] = &[
    ("names", names::check),
    ("network", network::check),
    ("pins", pins::check),
    ("timing", timing::check),
    ("sequence", sequence::check),
    ("charts", charts::check),
];

/// Passes over the elaborated robot (run when `STRUCTURE` found no error).
pub const SEMANTIC: &[(&str, Pass)] = &[
    ("build", tables::build),
    ("events", events::check),
    ("capacity", tables::capacity),
    ("interlocks", interlocks::check),
];

/// Parses and checks a robot: every problem found, sorted by position. The robot is
/// returned when it parsed.
pub fn check(src: &Source) -> (Option<Robot>, Vec<Diagnostic>) {
    let robot = match model::parse(src) {
        Ok(r) => r,
        Err(d) => return (None, vec![d]),
    };
    let mut diags = Vec::new();
    for (_, pass) in STRUCTURE {
        pass(&robot, src, &mut diags);
    }
    if !diags.iter().any(Diagnostic::is_error) {
        for (_, pass) in SEMANTIC {
            pass(&robot, src, &mut diags);
            if diags.iter().any(Diagnostic::is_error) {
                break;
            }
        }
    }
    diag::sort(&mut diags);
    diags.dedup();
    (Some(robot), diags)
}

/// An error for the second of two things with one name.
pub(crate) fn duplicate(
    src: &Source,
    what: &str,
    name: &str,
    first: &str,
    second: &str,
) -> Diagnostic {
    let (line, col) = src.line_col(src.span(first).start);
    Diagnostic::error(src.span(second), format!("duplicate {what} `{name}`"))
        .label(format!("first declared at {line}:{col}"))
}
