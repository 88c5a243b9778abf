//! Homing (docs/reconfiguration.md): as written, `homing` and `home` belong to sequence
//! robots, the steps name actuators of the sequence and the HOME input exists
//! ([`check`]); elaborated, the homing leaves every actuator home and breaks no interlock
//! while the actuators it has not homed yet may be anywhere ([`check_ir`]).

use crate::diag::Diagnostic;
use crate::elab::{home_input, StrMap};
use crate::homing;
use crate::ir::{parse_steps, Ir};
use crate::model::Robot;
use crate::source::Source;

pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    if robot.sequence.is_none() {
        for key in ["homing", "home"] {
            let declared = match key {
                "homing" => robot.homing.is_some(),
                _ => robot.home.is_some(),
            };
            if declared {
                out.push(
                    Diagnostic::error(
                        src.key_span(key),
                        format!("`{key}` is for sequence robots: explicit charts home themselves"),
                    )
                    .help("give the charts their own homing states, or remove it"),
                );
            }
        }
        return;
    }
    if let Err(e) = home_input(robot) {
        out.push(Diagnostic::error(src.span("home"), e.to_string()));
    }
    let Some(text) = &robot.homing else {
        return;
    };
    let base = StrMap::new(src, "homing");
    let parsed = parse_steps(text);
    if parsed.is_empty() {
        out.push(
            Diagnostic::error(src.span("homing"), "`homing` has no steps")
                .help("write the steps that bring every actuator home, e.g. `\"VC- HC-\"`"),
        );
        return;
    }
    let cycle = super::sequence_actuators(robot);
    for (step, span) in parsed {
        let here = base.span(span.clone());
        match step {
            Err(e) => out.push(Diagnostic::error(here, e.to_string())),
            Ok(s) if robot.actuator(&s.actuator).is_none() => out.push(
                Diagnostic::error(here, format!("unknown actuator `{}`", s.actuator))
                    .label("not declared by any role"),
            ),
            Ok(s) if !cycle.contains(&s.actuator) => out.push(
                Diagnostic::error(
                    here,
                    format!("`{s}`: `{}` does not move in the sequence", s.actuator),
                )
                .label("homing drives only the sequence's actuators"),
            ),
            Ok(_) => {}
        }
    }
}

pub fn check_ir(robot: &Robot, ir: &Ir, src: &Source, out: &mut Vec<Diagnostic>) {
    if ir.home.is_none() {
        return;
    }
    // Where to point: the declared step, or (derived) the `sequence`.
    let step_spans: Vec<std::ops::Range<usize>> = match &robot.homing {
        Some(text) => {
            let base = StrMap::new(src, "homing");
            parse_steps(text)
                .into_iter()
                .map(|(_, s)| base.span(s))
                .collect()
        }
        None => Vec::new(),
    };
    let at = |k: usize| {
        step_spans
            .get(k)
            .cloned()
            .unwrap_or_else(|| src.key_span("sequence"))
    };
    let left = homing::not_homed(ir, &ir.homing);
    if !left.is_empty() {
        let add: Vec<String> = left.iter().map(|a| format!("{a}-")).collect();
        out.push(
            Diagnostic::error(
                src.span("homing"),
                format!(
                    "homing leaves {} away from home: the cycle could start from there",
                    left.iter()
                        .map(|a| format!("`{a}`"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )
            .help(format!("end homing with {}", add.join(" "))),
        );
    }
    let locks = homing::resolved_interlocks(robot, ir);
    for (i, witness) in homing::at_power_up(robot, ir, &locks) {
        let lock = robot.never.get(i).map_or("", String::as_str);
        out.push(
            Diagnostic::error(
                src.span(&format!("never[{i}]")),
                homing::DeriveError::AtPowerUp {
                    index: i,
                    text: lock.to_string(),
                    witness,
                }
                .to_string(),
            )
            .help("give the returning actuator a double-acting valve, or an interlock that allows its return"),
        );
    }
    for b in homing::breaches(robot, ir, &locks, &ir.homing) {
        let step = &ir.homing[b.step];
        let lock = robot.never.get(b.interlock).map_or("", String::as_str);
        out.push(
            Diagnostic::error(
                at(b.step),
                format!(
                    "homing step `{step}` breaks interlock never[{}] `{lock}` {}",
                    b.interlock, b.witness
                ),
            )
            .label("the actuators not homed before this step may be anywhere")
            .help("home the actuators the interlock names first"),
        );
    }
}
