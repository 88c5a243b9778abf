//! Checks: independent passes over the parsed robot, each adding diagnostics. Structural
//! passes run first; then the robot is elaborated, once (synthesis of a sequence or
//! elaboration of explicit charts, into the IR `compile` lowers), and the semantic passes
//! read that IR. Both run only when the passes before them found no error (otherwise they
//! would report the same problem twice). Add a pass by writing
//! `fn(&Robot, &Source, &mut Vec<Diagnostic>)` (structural) or
//! `fn(&Robot, &Ir, &Source, &mut Vec<Diagnostic>)` (semantic) and listing it below.

mod charts;
mod events;
mod homing;
mod interlocks;
mod levels;
mod names;
mod network;
mod pins;
mod sequence;
mod tables;
mod time;
mod timing;

use crate::diag::{self, Diagnostic};
use crate::ir::{parse_steps, Ir};
use crate::model::{self, Robot};
use crate::source::Source;
use crate::{elab, synth};

/// A pass over the description as written.
pub type Pass = fn(&Robot, &Source, &mut Vec<Diagnostic>);

/// A pass over the elaborated robot.
pub type IrPass = fn(&Robot, &Ir, &Source, &mut Vec<Diagnostic>);

/// Passes over the description as written.
pub const STRUCTURE: &[(&str, Pass)] = &[
    ("names", names::check),
    ("network", network::check),
    ("pins", pins::check),
    ("levels", levels::check),
    ("timing", timing::check),
    ("sequence", sequence::check),
    ("homing", homing::check),
    ("charts", charts::check),
    ("automata", crate::automata::check::check),
    ("functions", crate::petri::check::check),
    ("sorting", crate::sorting::check),
    ("plants", crate::plants::check),
    ("alarms", crate::alarms::check),
];

/// Passes over the elaborated robot (run when `STRUCTURE` and the elaboration found no
/// error).
pub const SEMANTIC: &[(&str, IrPass)] = &[
    ("events", events::check),
    ("capacity", tables::check),
    ("time", time::check),
    ("interlocks", interlocks::check),
    ("homing", homing::check_ir),
];

/// A checked robot: what parsed, what elaborated, and every problem found.
#[derive(Debug, Clone)]
pub struct Checked {
    /// The robot, when it parsed.
    pub robot: Option<Robot>,
    /// The elaborated robot, when the structural passes found no error and the
    /// elaboration succeeded (a semantic pass may still have found an error).
    pub ir: Option<Ir>,
    /// Every diagnostic, sorted by position.
    pub diagnostics: Vec<Diagnostic>,
}

impl Checked {
    /// Whether some diagnostic is an error.
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(Diagnostic::is_error)
    }
}

/// Parses, checks and elaborates a robot: every problem found, sorted by position.
pub fn check(src: &Source) -> Checked {
    let mut robot = match model::parse(src) {
        Ok(r) => r,
        Err(d) => {
            return Checked {
                robot: None,
                ir: None,
                diagnostics: vec![d],
            }
        }
    };
    // Imported FB types join the chart types before anything reads them.
    let mut diags = crate::iec61499::import(&mut robot, src);
    // What failed to import is missing from the robot: what the passes would find then (a
    // robot without behaviour, roles on no node) follows from it, and is not said.
    if !diags.iter().any(Diagnostic::is_error) {
        for (_, pass) in STRUCTURE {
            pass(&robot, src, &mut diags);
        }
    }
    let mut ir = None;
    if !diags.iter().any(Diagnostic::is_error) {
        match build_ir(&robot, src) {
            Ok(built) => {
                for (_, pass) in SEMANTIC {
                    pass(&robot, &built, src, &mut diags);
                    if diags.iter().any(Diagnostic::is_error) {
                        break;
                    }
                }
                ir = Some(built);
            }
            Err(mut d) => diags.append(&mut d),
        }
    }
    diag::sort(&mut diags);
    diags.dedup();
    Checked {
        robot: Some(robot),
        ir,
        diagnostics: diags,
    }
}

/// Elaborates a robot that passed the structural checks: synthesis for a sequence,
/// elaboration of explicit charts otherwise; then the charts of the selecting automata
/// placed on a role join it.
fn build_ir(robot: &Robot, src: &Source) -> Result<Ir, Vec<Diagnostic>> {
    let mut ir = build_charts(robot, src)?;
    crate::sorting::place(robot, src, &mut ir)?;
    crate::automata::compile::place(robot, src, &mut ir)?;
    crate::alarms::place(robot, src, &mut ir)?;
    crate::numbering::number(&mut ir);
    Ok(ir)
}

fn build_charts(robot: &Robot, src: &Source) -> Result<Ir, Vec<Diagnostic>> {
    match &robot.sequence {
        Some(text) => {
            let steps: Vec<_> = parse_steps(text)
                .into_iter()
                .filter_map(|(s, _)| s.ok())
                .collect();
            synth::synthesise(robot, &steps).map_err(|e| {
                // An interlock that may hold at power-up is the interlock's problem.
                let at = match &e {
                    synth::SynthError::Homing(crate::homing::DeriveError::AtPowerUp {
                        index,
                        ..
                    }) => format!("never[{index}]"),
                    _ => String::from("sequence"),
                };
                vec![Diagnostic::error(src.span(&at), e.to_string())]
            })
        }
        None => elab::elaborate(robot, src),
    }
}

/// The actuators of the robot's `sequence`, step by step (those of steps that parse).
pub(crate) fn sequence_actuators(robot: &Robot) -> Vec<String> {
    robot
        .sequence
        .as_deref()
        .map(parse_steps)
        .unwrap_or_default()
        .into_iter()
        .filter_map(|(s, _)| s.ok().map(|s| s.actuator))
        .collect()
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

#[cfg(test)]
mod tests {
    use super::check;
    use crate::source::Source;

    const PAINT: &str = include_str!("../../../robot-configs/paint-robot.ron");

    /// `check` elaborates: its IR is the one `compile` lowers (the paint robot has `never:`
    /// interlocks, whose pass reads the same IR).
    #[test]
    fn check_returns_the_ir_compile_lowers() {
        let src = Source::new("paint-robot.ron", PAINT);
        let checked = check(&src);
        assert!(!checked.has_errors());
        let ir = checked.ir.expect("elaborated");
        assert_eq!(ir.roles.len(), 4);
        let compiled = crate::compile(&src).expect("compiles");
        assert_eq!(ir, compiled.ir);
    }

    /// No IR when the structure is broken (the elaboration does not run) or the robot does
    /// not parse.
    #[test]
    fn no_ir_without_a_sound_structure() {
        let broken = PAINT.replace("address: 0x0012", "address: 0x0011");
        let checked = check(&Source::new("twice.ron", broken));
        assert!(checked.has_errors());
        assert!(checked.robot.is_some());
        assert!(checked.ir.is_none());
        let checked = check(&Source::new("syntax.ron", "Robot("));
        assert!(checked.robot.is_none() && checked.ir.is_none());
        assert_eq!(checked.diagnostics.len(), 1);
    }
}
