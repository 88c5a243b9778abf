//! The behaviour's shape: a sequence or explicit charts (not both, not neither), the start
//! input, and the sequence itself: undeclared actuators, a `+` on an actuator that is
//! already out (or `-` on one at home), actuators out at the end of the cycle, actuators
//! that never move, steps without a completion sensor (a jam goes undetected: warning).
//! Also the `expect` sequence of explicit robots.

use config_schema::limits::MAX_STATES;

use crate::diag::Diagnostic;
use crate::elab::{start_input, StrMap};
use crate::ir::parse_steps;
use crate::model::{ActuatorKind, ActuatorLevel, Robot};
use crate::source::Source;

pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    let has_charts =
        robot.roles.iter().any(|r| !r.charts.is_empty()) || !robot.functions.is_empty();
    // An automaton placed on a role brings its own charts.
    let placed = robot.automata.iter().any(|a| a.role.is_some());
    match (&robot.sequence, has_charts || placed) {
        (Some(_), true) => out.push(Diagnostic::error(
            src.key_span("sequence"),
            "a robot has either a `sequence` or explicit `charts` (or `functions`), not both",
        )),
        (None, false) => out.push(
            Diagnostic::error(src.span(""), "the robot has no behaviour")
                .help("add a `sequence`, give the roles `charts` or declare `functions`"),
        ),
        _ => {}
    }
    match start_input(robot) {
        Err(e) => out.push(Diagnostic::error(src.span("start"), e.to_string())),
        Ok(None) if robot.sequence.is_some() => out.push(
            Diagnostic::error(src.key_span("sequence"), "a sequence needs a `start` input")
                .help("add `start: \"START\"` naming the button that starts a cycle"),
        ),
        Ok(_) => {}
    }
    if let Some(text) = &robot.sequence {
        steps(robot, src, "sequence", text, true, out);
        buttons(robot, src, out);
        start_levels(robot, src, out);
    }
    if let Some(text) = &robot.expect {
        steps(robot, src, "expect", text, false, out);
    }
}

fn steps(
    robot: &Robot,
    src: &Source,
    path: &str,
    text: &str,
    synth: bool,
    out: &mut Vec<Diagnostic>,
) {
    let base = StrMap::new(src, path);
    let mut out_now: Vec<(String, std::ops::Range<usize>)> = Vec::new();
    // Steps per role: each is a state of its actuator's chart at least, so a role with
    // more steps than a table holds states is refused here, before any synthesis.
    let mut per_role = vec![0usize; robot.roles.len()];
    let parsed = parse_steps(text);
    if parsed.is_empty() {
        out.push(Diagnostic::error(
            src.span(path),
            format!("`{path}` has no steps"),
        ));
        return;
    }
    for (step, span) in &parsed {
        let here = base.span(span.clone());
        let step = match step {
            Ok(s) => s,
            Err(e) => {
                out.push(Diagnostic::error(here, e.to_string()));
                continue;
            }
        };
        let Some((ri, ai)) = robot.actuator(&step.actuator) else {
            let names: Vec<&str> = robot
                .roles
                .iter()
                .flat_map(|r| r.actuators.iter().map(|a| a.name.as_str()))
                .collect();
            out.push(
                Diagnostic::error(here, format!("unknown actuator `{}`", step.actuator))
                    .label("not declared by any role")
                    .help(format!("actuators: {}", names.join(", "))),
            );
            continue;
        };
        if synth {
            if let Some(n) = per_role.get_mut(ri) {
                *n += 1;
                if *n == MAX_STATES + 1 {
                    out.push(
                        Diagnostic::error(
                            here.clone(),
                            format!(
                                "`{step}`: role `{}` moves in more than {MAX_STATES} steps \
                                 of the sequence",
                                robot.roles[ri].name
                            ),
                        )
                        .label("one step too many")
                        .help(format!(
                            "each step is a state of its actuator's chart, and a role's \
                             table holds at most {MAX_STATES} states (MAX_STATES)"
                        )),
                    );
                }
            }
            let kind = &robot.roles[ri].actuators[ai].kind;
            if let (None, ActuatorKind::SingleActing { dwell_ms, .. }) =
                (kind.completion_switch(step.extend), kind)
            {
                let sensor = if step.extend { "end" } else { "home" };
                out.push(
                    Diagnostic::warning(
                        here.clone(),
                        format!(
                            "step `{step}` has no completion sensor: a jam of `{}` goes \
                             undetected",
                            step.actuator
                        ),
                    )
                    .label(format!(
                        "completes after dwell_ms ({dwell_ms} ms), unsupervised"
                    ))
                    .help(format!(
                        "if `{}` has a position sensor, declare it (`{sensor}: PIN`) to get a \
                         motion watchdog",
                        step.actuator
                    )),
                );
            }
        }
        let at = out_now.iter().position(|(a, _)| *a == step.actuator);
        match (step.extend, at) {
            (true, Some(i)) => {
                let (line, col) = src.line_col(out_now[i].1.start);
                out.push(
                    Diagnostic::error(
                        here,
                        format!("`{step}`: `{}` is already out", step.actuator),
                    )
                    .label(format!("extended at {line}:{col} and not retracted since")),
                );
            }
            (false, None) => out.push(
                Diagnostic::error(
                    here,
                    format!("`{step}`: `{}` is already home", step.actuator),
                )
                .label("every actuator starts home (retracted)"),
            ),
            (true, None) => out_now.push((step.actuator.clone(), here)),
            (false, Some(i)) => {
                out_now.remove(i);
            }
        }
    }
    for (a, span) in out_now {
        out.push(
            Diagnostic::error(
                span,
                format!("`{a}` is still out at the end of the cycle: the cycle cannot repeat"),
            )
            .label("extended here, never retracted")
            .help(format!("add `{a}-` to the cycle")),
        );
    }
    if synth {
        for (ri, r) in robot.roles.iter().enumerate() {
            for (ai, a) in r.actuators.iter().enumerate() {
                if !parsed
                    .iter()
                    .any(|(s, _)| s.as_ref().is_ok_and(|s| s.actuator == a.name))
                {
                    out.push(Diagnostic::warning(
                        src.span(&format!("roles[{ri}].actuators[{ai}].name")),
                        format!("actuator `{}` never moves in the sequence", a.name),
                    ));
                }
            }
        }
    }
}

/// The events a sequence's synthesised charts name themselves without a `.` (every other
/// one has one: `A.end`, `step1.done`, `cycle.start`, ...).
const SYNTHESISED: [&str; 3] = [
    crate::synth::FAULT_EVENT,
    crate::synth::BOOT_EVENT,
    crate::synth::HOME_COMMAND_EVENT,
];

/// A sequence robot's inputs are events of its synthesised charts: none may be named as
/// their own events (an input `fault` faulted a peer at each press), and the START, HOME
/// and e-stop buttons are three buttons (HOME on START homed at each press, an e-stop on
/// START stopped the machine at each).
fn buttons(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    // The HOME input is `home` itself (its own event, none synthesised beside it).
    let home = crate::elab::home_input(robot).ok().flatten();
    for (ri, r) in robot.roles.iter().enumerate() {
        for (k, i) in r.inputs.iter().enumerate() {
            if home.as_ref() == Some(&(ri, i.name.clone()))
                && i.name == crate::synth::HOME_COMMAND_EVENT
            {
                continue;
            }
            if i.name.contains('.') || SYNTHESISED.contains(&i.name.as_str()) {
                out.push(
                    Diagnostic::error(
                        src.span(&format!("roles[{ri}].inputs[{k}].name")),
                        format!(
                            "input `{}` is named as the sequence's charts name their own \
                             events (`fault`, `boot`, `home` and every name with a `.`)",
                            i.name
                        ),
                    )
                    .help("rename the input"),
                );
            }
        }
    }
    let Ok(Some(start)) = start_input(robot) else {
        return;
    };
    if let Some(home) = home {
        if home == start {
            out.push(Diagnostic::error(
                src.span("home"),
                format!(
                    "`home` is the START input `{}`: one button cannot both home the machine \
                     and start a cycle",
                    start.1
                ),
            ));
        }
    }
    if let Some(r) = robot.roles.get(start.0) {
        if r.estop.as_deref() == Some(start.1.as_str()) {
            out.push(Diagnostic::error(
                src.span(&format!("roles[{}].estop", start.0)),
                format!(
                    "`estop` is the START input `{}`: every press would stop the machine",
                    start.1
                ),
            ));
        }
    }
}

/// A sequence starts with every actuator home: one the sequence moves may not be driven
/// out before the charts run (`start: Extend`: the first `+` then commanded nothing and
/// its watchdog faulted the machine, every cycle).
fn start_levels(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    let moved = super::sequence_actuators(robot);
    for (ri, r) in robot.roles.iter().enumerate() {
        for (ai, a) in r.actuators.iter().enumerate() {
            if a.start == ActuatorLevel::Extend && moved.contains(&a.name) {
                out.push(
                    Diagnostic::error(
                        src.span(&format!("roles[{ri}].actuators[{ai}].start")),
                        format!(
                            "`start: Extend` drives `{}` out before the charts run: a sequence \
                             starts with every actuator home",
                            a.name
                        ),
                    )
                    .help("`Off`, `Hold` or `Retract`"),
                );
            }
        }
    }
}
