//! Alarms, the emergency stop, restart inputs and the link alarm policy of a robot
//! (docs/robot-format.md, "Alarms and stops"): the structural check, and their place in
//! the IR (the e-stop charts, each role's safety declarations).
//!
//! - A declared alarm sits on `role` (default: the role of the robot's `start`, the
//!   operator's panel) and is raised when its `when` becomes true: a condition with the
//!   guard operators over the role's inputs (`NAME`) and functions' places (`F.P`; a place
//!   of a function on another role is published to it, one radio hop).
//! - `estop: "INPUT"` on a role: its rising edge faults the node (`FAULT_ESTOP`) and
//!   publishes `estop` to every other role, whose `estop` chart faults it
//!   (`FAULT_ESTOP_PEER`): every node within one hop.
//! - `restart: [...]`: inputs besides START whose press is refused while a fault alarm is
//!   latched on their node.

use config_schema::alarm::{AlarmLevel, FAULT_ESTOP, FAULT_ESTOP_PEER, MAX_DECLARED_ALARMS};
use config_schema::Op;
use serde::Deserialize;

use crate::diag::Diagnostic;
use crate::expr::{self, Ast, Operand};
use crate::ir::{ActionIr, ChartIr, InputIr, Ir, RoleIr, StateIr, TransitionIr};
use crate::model::{PlacesVar, Robot};
use crate::petri::{self, Net, Reads};
use crate::source::Source;

/// The event an e-stop role publishes to every other role.
pub const ESTOP_EVENT: &str = "estop";

/// `alarms: [(name, level, when, role)]` of the robot file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AlarmDeclRon {
    pub name: String,
    pub level: LevelRon,
    /// A condition (guard syntax) over the role's inputs and functions' places.
    pub when: String,
    /// The role whose node latches it (default: the role of the robot's `start`).
    #[serde(default)]
    pub role: Option<String>,
}

/// An alarm's level as written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
pub enum LevelRon {
    Info,
    Warning,
    Fault,
}

impl From<LevelRon> for AlarmLevel {
    fn from(l: LevelRon) -> AlarmLevel {
        match l {
            LevelRon::Info => AlarmLevel::Info,
            LevelRon::Warning => AlarmLevel::Warning,
            LevelRon::Fault => AlarmLevel::Fault,
        }
    }
}

/// What a link alarm (a peer silent past its bound) does.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
pub enum LinkAlarmPolicy {
    /// The node keeps retrying; the machine stalls (a warning alarm).
    #[default]
    Stall,
    /// The node faults (a fault alarm).
    Fault,
}

/// One role's safety declarations, with names.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SafetyIr {
    /// The e-stop input.
    pub estop: Option<String>,
    pub link_fault: bool,
    /// Inputs refused while a fault alarm is latched (besides the START input).
    pub restart: Vec<String>,
    /// (name, level, condition text, bytecode).
    pub alarms: Vec<(String, AlarmLevel, String, Vec<Op>)>,
}

/// The role an alarm sits on: its own, or the start input's.
pub fn alarm_role<'a>(robot: &'a Robot, a: &'a AlarmDeclRon) -> Option<&'a str> {
    if let Some(r) = &a.role {
        return Some(r);
    }
    let start = robot.start.as_deref()?;
    match start.split_once('/') {
        Some((role, _)) => Some(role),
        None => robot
            .roles
            .iter()
            .find(|r| r.inputs.iter().any(|i| i.name == start))
            .map(|r| r.name.as_str()),
    }
}

/// The parsed conditions of the alarms on `role` (those that parse).
pub fn conditions(robot: &Robot, role: &str) -> Vec<Ast> {
    robot
        .alarms
        .iter()
        .filter(|a| alarm_role(robot, a) == Some(role))
        .filter_map(|a| expr::parse(&a.when).ok())
        .collect()
}

/// A restart input as written (`NAME` or `ROLE/NAME`): (role, input).
fn restart_ref<'a>(robot: &'a Robot, s: &'a str) -> Option<(&'a str, &'a str)> {
    if let Some((r, i)) = s.split_once('/') {
        return Some((r, i));
    }
    let mut found = robot
        .roles
        .iter()
        .filter(|r| r.inputs.iter().any(|i| i.name == s));
    let one = found.next()?;
    found.next().is_none().then_some((one.name.as_str(), s))
}

/// The structural pass: alarm roles, conditions and names; e-stop and restart inputs.
pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    let nets = petri::load(robot, src).nets();
    if robot.alarms.len() > MAX_DECLARED_ALARMS {
        out.push(Diagnostic::error(
            src.span(&format!("alarms[{MAX_DECLARED_ALARMS}]")),
            format!("more than {MAX_DECLARED_ALARMS} alarms"),
        ));
    }
    for (k, a) in robot.alarms.iter().enumerate() {
        let at = |f: &str| src.span(&format!("alarms[{k}].{f}"));
        if robot.alarms[..k].iter().any(|b| b.name == a.name) {
            out.push(Diagnostic::error(
                at("name"),
                format!("alarm `{}` is declared twice", a.name),
            ));
        }
        let Some(role_name) = alarm_role(robot, a) else {
            out.push(
                Diagnostic::error(
                    at("name"),
                    format!(
                        "alarm `{}`: no role (give `role`, or the robot a `start`)",
                        a.name
                    ),
                )
                .label("on which node?"),
            );
            continue;
        };
        let Some((_, role)) = robot.role(role_name) else {
            out.push(
                Diagnostic::error(
                    at("role"),
                    format!("alarm `{}`: no role `{role_name}`", a.name),
                )
                .label("unknown role"),
            );
            continue;
        };
        let when = at("when");
        let ast = match expr::parse(&a.when) {
            Ok(ast) => ast,
            Err(e) => {
                out.push(Diagnostic::error(
                    when,
                    format!("alarm `{}`: {}", a.name, e.message),
                ));
                continue;
            }
        };
        let levels = petri::levels(role);
        let mut names = Vec::new();
        expr::names(&ast, &mut names);
        for name in names {
            if petri::reads(&nets, &levels, &name).is_some()
                || PlacesVar::read(&robot.places, role_name, &name).is_some()
            {
                continue;
            }
            // The name's own place inside the string (after its opening quote).
            let offset = a.when.find(name.as_str()).unwrap_or(0) + 1;
            let start = (when.start + offset).min(when.end);
            let span = start..(start + name.len()).min(when.end);
            out.push(
                Diagnostic::error(
                    span,
                    format!(
                        "alarm `{}`: `{name}` is neither a function's place (`F.P`) nor an input of role `{role_name}`",
                        a.name
                    ),
                )
                .label("unknown place or input"),
            );
        }
    }
    for (i, role) in robot.roles.iter().enumerate() {
        if let Some(e) = &role.estop {
            if !role.inputs.iter().any(|x| x.name == *e) {
                out.push(
                    Diagnostic::error(
                        src.span(&format!("roles[{i}].estop")),
                        format!("e-stop: role `{}` has no input `{e}`", role.name),
                    )
                    .label("not an input of the role"),
                );
            }
        }
    }
    for (k, s) in robot.restart.iter().enumerate() {
        let known = restart_ref(robot, s).is_some_and(|(r, i)| {
            robot
                .role(r)
                .is_some_and(|(_, role)| role.inputs.iter().any(|x| x.name == i))
        });
        if !known {
            out.push(
                Diagnostic::error(
                    src.span(&format!("restart[{k}]")),
                    format!("restart: no input `{s}` (`NAME` or `ROLE/NAME`)"),
                )
                .label("unknown input"),
            );
        }
    }
}

/// Declares input `name` of the robot role in `r` if the elaboration left it out, with
/// a rising event `rise` if asked (an existing input gets it).
fn declare_input(robot: &Robot, r: &mut RoleIr, name: &str, rise: bool) -> Result<usize, String> {
    let pin = robot
        .role(&r.name)
        .and_then(|(_, role)| role.inputs.iter().find(|i| i.name == name))
        .map(|i| i.pin)
        .ok_or_else(|| format!("role `{}` has no input `{name}`", r.name))?;
    let i = match r.inputs.iter().position(|i| i.name == name) {
        Some(i) => i,
        None => {
            r.inputs.push(InputIr {
                name: name.to_string(),
                pin,
                rise: None,
                fall: None,
                var: None,
            });
            r.inputs.len() - 1
        }
    };
    if rise && r.inputs[i].rise.is_none() {
        r.event(name);
        r.inputs[i].rise = Some(name.to_string());
    }
    Ok(i)
}

/// A chart `estop`: `RUN` -(its input 0, routed from `event`)-> `STOP` running `actions`.
fn stop_chart(r: &mut RoleIr, event: &str, actions: Vec<ActionIr>) {
    let c = r.charts.len();
    r.routes.push((event.to_string(), c, 0));
    r.charts.push(ChartIr {
        name: String::from(ESTOP_EVENT),
        inputs: vec![event.to_string()],
        initial: 0,
        idle: 0,
        rests: Vec::new(),
        states: vec![
            StateIr {
                name: String::from("RUN"),
                actions: vec![],
            },
            StateIr {
                name: String::from("STOP"),
                actions,
            },
        ],
        transitions: vec![TransitionIr {
            from: 0,
            to: 1,
            trigger: Some(0),
            guard: None,
        }],
    });
}

/// Adds the e-stop charts and every role's safety declarations to the IR.
pub fn place(robot: &Robot, src: &Source, ir: &mut Ir) -> Result<(), Vec<Diagnostic>> {
    let fail = |path: String, e: String| vec![Diagnostic::error(src.span(&path), e)];
    let nets = petri::load(robot, src).nets();
    let stops: Vec<(usize, String)> = robot
        .roles
        .iter()
        .enumerate()
        .filter_map(|(i, r)| r.estop.clone().map(|e| (i, e)))
        .collect();
    for r in ir.roles.iter_mut() {
        let Some((mi, _)) = robot.role(&r.name) else {
            continue;
        };
        r.safety.link_fault = robot.on_link_alarm == LinkAlarmPolicy::Fault;
        for (si, input) in &stops {
            if *si == mi {
                declare_input(robot, r, input, true)
                    .map_err(|e| fail(format!("roles[{si}].estop"), e))?;
                r.event(ESTOP_EVENT);
                let actions = vec![
                    ActionIr::Emit(String::from(ESTOP_EVENT)),
                    ActionIr::Fault(FAULT_ESTOP),
                ];
                stop_chart(r, input, actions);
                r.safety.estop = Some(input.clone());
            } else {
                let from = robot.roles[*si].name.clone();
                let local = format!("{from}/{ESTOP_EVENT}");
                r.imports
                    .push((from, String::from(ESTOP_EVENT), local.clone()));
                r.event(&local);
                stop_chart(r, &local, vec![ActionIr::Fault(FAULT_ESTOP_PEER)]);
            }
        }
        for (k, s) in robot.restart.iter().enumerate() {
            if let Some((_, input)) = restart_ref(robot, s).filter(|(role, _)| *role == r.name) {
                declare_input(robot, r, input, false)
                    .map_err(|e| fail(format!("restart[{k}]"), e))?;
                r.safety.restart.push(input.to_string());
            }
        }
        let levels = robot
            .role(&r.name)
            .map(|(_, role)| petri::levels(role))
            .unwrap_or_default();
        for (k, a) in robot.alarms.iter().enumerate() {
            if alarm_role(robot, a) != Some(r.name.as_str()) {
                continue;
            }
            let at = format!("alarms[{k}].when");
            let ast = expr::parse(&a.when).map_err(|e| fail(at.clone(), e.message))?;
            // Inputs the condition reads must be in the table.
            let mut names = Vec::new();
            expr::names(&ast, &mut names);
            for n in &names {
                if let Some(Reads::Input(i)) = petri::reads(&nets, &levels, n) {
                    if !i.contains('.') {
                        declare_input(robot, r, i, false).map_err(|e| fail(at.clone(), e))?;
                    }
                }
            }
            let ast = chart_places(&ast, &robot.places, &r.name);
            let ops = condition(&nets, &levels, &ast, r).map_err(|e| fail(at.clone(), e))?;
            r.safety
                .alarms
                .push((a.name.clone(), a.level.into(), a.when.clone(), ops));
        }
    }
    Ok(())
}

/// A condition with each place of a function that is a chart (`F.P`, brought by an
/// application: [`PlacesVar`]) read through the chart's variable: `VAR == column`.
fn chart_places(ast: &Ast, vars: &[PlacesVar], role: &str) -> Ast {
    use crate::expr::BinOp;
    ast.map_names(&|n, span| {
        let (var, column) = PlacesVar::read(vars, role, n)?;
        Some(Ast::Bin(
            BinOp::Eq,
            Box::new(Ast::Name(var.to_string(), span.clone())),
            Box::new(Ast::Int(column as i32)),
        ))
    })
}

/// The bytecode of an alarm's condition on role `r`: places read through the role's
/// `F.state` variables (set by the function's chart on its own role, by its `.seen`
/// chart on another).
fn condition(nets: &[Net], levels: &[String], ast: &Ast, r: &RoleIr) -> Result<Vec<Op>, String> {
    let ast = petri::compile::rewrite(ast, nets, levels, (usize::MAX, 0), &|_, _| None);
    let resolve = |name: &str| {
        if let Some(v) = r.vars.iter().position(|(v, _)| v == name) {
            return u8::try_from(v).ok().map(Operand::Var);
        }
        let i = r.inputs.iter().position(|i| i.name == name)?;
        u8::try_from(i).ok().map(Operand::Input)
    };
    expr::bytecode(&ast, &resolve).map_err(|e| e.message)
}

#[cfg(test)]
mod tests {
    use crate::source::Source;

    const ROBOT: &str = r#"Robot(
    name: "m",
    network: (pan_id: 1, channel: 11),
    nodes: [(name: "n1", address: 1)],
    assign: [("R", "n1")],
    roles: [(name: "R", inputs: [(name: "GO", pin: 0), (name: "F", pin: 1)], estop: "STOPX")],
    start: "GO",
    restart: ["AGAIN"],
    alarms: [
        (name: "a", level: Fault, when: "F && Pusher.Gone"),
        (name: "b", level: Warning, when: "F", role: "Q"),
        (name: "a", level: Info, when: "F &&"),
    ],
)"#;

    /// Every error names its place in the file: the unknown name inside the condition.
    #[test]
    fn bad_alarms_are_reported_at_their_place() {
        let src = Source::new("m.ron", ROBOT);
        let robot = crate::model::parse(&src).expect("parses");
        let mut out = Vec::new();
        super::check(&robot, &src, &mut out);
        let mut got: Vec<(String, (usize, usize))> = out
            .iter()
            .map(|d| (d.message.clone(), src.line_col(d.span.start)))
            .collect();
        got.sort_by_key(|g| g.1);
        let want = [
            ("e-stop: role `R` has no input `STOPX`", (6, 85)),
            ("restart: no input `AGAIN` (`NAME` or `ROLE/NAME`)", (8, 15)),
            (
                "alarm `a`: `Pusher.Gone` is neither a function's place (`F.P`) nor an input of role `R`",
                (10, 47),
            ),
            ("alarm `b`: no role `Q`", (11, 54)),
            ("alarm `a` is declared twice", (12, 16)),
        ];
        let want: Vec<(String, (usize, usize))> =
            want.iter().map(|(m, p)| (m.to_string(), *p)).collect();
        assert_eq!(got[..5], want[..], "{got:#?}");
        assert_eq!(got.len(), 6, "{got:#?}");
        assert!(got[5].0.starts_with("alarm `a`: "), "{got:#?}");
        assert_eq!(got[5].1, (12, 40));
    }
}
