//! Interlocks: `never: ["HC.moving && !VC.home"]`, expressions over plant and chart state
//! that must be false in every reachable state.
//!
//! Names: `ACT.home`, `ACT.end`, `ACT.moving`, `ACT.extending`, `ACT.retracting` (an
//! actuator's position), `ROLE.CHART.STATE` (1 while that chart is in that state),
//! `ROLE.fault` (1 while the node is faulted). Operators and precedence are those of
//! guards (`docs/robot-format.md`).

use std::collections::BTreeMap;
use std::ops::Range;

use crate::expr::{self, Ast, ExprError};
use crate::ir::Ir;
use crate::model::Robot;

/// What a name of an interlock reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Atom {
    /// Actuator (plant index) is in one of the positions of the mask (bit 0 home, 1 end,
    /// 2 extending, 3 retracting).
    Position { plant: usize, mask: u8 },
    /// Chart `chart` of role `role` is in state `state`.
    Chart {
        role: usize,
        chart: usize,
        state: usize,
    },
    /// Role `role`'s node is faulted.
    Fault { role: usize },
    /// A name whose value never changes: a position of a declared actuator that no table
    /// drives (it is home for ever).
    Const(bool),
}

/// A parsed interlock with its names resolved.
#[derive(Debug, Clone)]
pub struct Interlock {
    pub text: String,
    pub ast: Ast,
    pub names: BTreeMap<String, Atom>,
}

/// Position masks.
pub const HOME: u8 = 1;
pub const END: u8 = 2;
pub const EXTENDING: u8 = 4;
pub const RETRACTING: u8 = 8;

/// A name of an interlock that reads nothing.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NameError {
    #[error(
        "`{name}`: an actuator has `.home`, `.end`, `.moving`, `.extending`, `.retracting`, \
         not `.{suffix}`"
    )]
    Position { name: String, suffix: String },
    #[error("`{name}`: role {role} has no chart `{chart}` (charts: {})", charts.join(", "))]
    NoChart {
        name: String,
        role: String,
        chart: String,
        charts: Vec<String>,
    },
    #[error(
        "`{name}`: chart {role}.{chart} has no state `{state}` (states: {})",
        states.join(", ")
    )]
    NoState {
        name: String,
        role: String,
        chart: String,
        state: String,
        states: Vec<String>,
    },
    #[error(
        "`{0}` is not an interlock name: write `ACTUATOR.home` / `.end` / `.moving` / \
         `.extending` / `.retracting`, `ROLE.CHART.STATE` or `ROLE.fault`"
    )]
    Unknown(String),
}

/// An interlock that is not an expression, or has a name that reads nothing.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InterlockError {
    #[error(transparent)]
    Syntax(ExprError),
    #[error("{error}")]
    Name {
        error: Box<NameError>,
        /// The name's byte span in the text.
        span: Range<usize>,
    },
}

impl InterlockError {
    /// The byte span of the problem in the interlock's text.
    pub fn span(&self) -> Range<usize> {
        match self {
            InterlockError::Syntax(e) => e.span.clone(),
            InterlockError::Name { span, .. } => span.clone(),
        }
    }
}

/// A bad entry of the robot's `never:` list.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("never[{index}]: {error}")]
pub struct NeverError {
    pub index: usize,
    pub error: InterlockError,
}

/// The position mask of an actuator name's suffix (`home`, `end`, `moving`, ...).
fn position_mask(name: &str, suffix: &str) -> Result<u8, NameError> {
    Ok(match suffix {
        "home" => HOME,
        "end" => END,
        "moving" => EXTENDING | RETRACTING,
        "extending" => EXTENDING,
        "retracting" => RETRACTING,
        other => {
            return Err(NameError::Position {
                name: name.to_string(),
                suffix: other.to_string(),
            })
        }
    })
}

/// Resolves one name of an interlock. `actuators` lists the actuators with a plant, in
/// plant order; `declared` every actuator the robot declares (one without a plant never
/// moves: it is home for ever).
pub fn resolve(
    name: &str,
    ir: &Ir,
    actuators: &[String],
    declared: &[&str],
) -> Result<Atom, NameError> {
    let parts: Vec<&str> = name.split('.').collect();
    if parts.len() == 2 {
        // `ROLE.fault` first: a role and its actuator often share a name.
        if parts[1] == "fault" {
            if let Some(role) = ir.roles.iter().position(|r| r.name == parts[0]) {
                return Ok(Atom::Fault { role });
            }
        }
        if let Some(plant) = actuators.iter().position(|a| a == parts[0]) {
            let mask = position_mask(name, parts[1])?;
            return Ok(Atom::Position { plant, mask });
        }
        if declared.contains(&parts[0]) {
            let mask = position_mask(name, parts[1])?;
            return Ok(Atom::Const(mask & HOME != 0));
        }
    }
    if parts.len() == 3 {
        if let Some(role) = ir.roles.iter().position(|r| r.name == parts[0]) {
            let r = &ir.roles[role];
            let Some(chart) = r.charts.iter().position(|c| c.name == parts[1]) else {
                return Err(NameError::NoChart {
                    name: name.to_string(),
                    role: r.name.clone(),
                    chart: parts[1].to_string(),
                    charts: r.charts.iter().map(|c| c.name.clone()).collect(),
                });
            };
            let c = &r.charts[chart];
            let Some(state) = c.states.iter().position(|s| s.name == parts[2]) else {
                return Err(NameError::NoState {
                    name: name.to_string(),
                    role: r.name.clone(),
                    chart: c.name.clone(),
                    state: parts[2].to_string(),
                    states: c.states.iter().map(|s| s.name.clone()).collect(),
                });
            };
            return Ok(Atom::Chart { role, chart, state });
        }
    }
    Err(NameError::Unknown(name.to_string()))
}

/// The actuators of a robot that `sim` and `verify` model, in plant order (role order,
/// then actuator order, only those the tables drive).
pub fn actuator_names(ir: &Ir) -> Vec<String> {
    ir.roles
        .iter()
        .flat_map(|r| r.actuators.iter().map(|w| w.name.clone()))
        .collect()
}

/// Parses and resolves the robot's interlocks: an error for the first bad one.
pub fn interlocks(robot: &Robot, ir: &Ir) -> Result<Vec<Interlock>, NeverError> {
    let names = Scope::of(robot, ir);
    robot
        .never
        .iter()
        .enumerate()
        .map(|(index, text)| {
            names
                .interlock(text)
                .map_err(|error| NeverError { index, error })
        })
        .collect()
}

/// What interlock names can refer to: the actuators with a plant (in plant order) and
/// every declared actuator.
pub struct Scope<'r> {
    ir: &'r Ir,
    actuators: Vec<String>,
    declared: Vec<&'r str>,
}

impl<'r> Scope<'r> {
    pub fn of(robot: &'r Robot, ir: &'r Ir) -> Scope<'r> {
        Scope {
            ir,
            actuators: actuator_names(ir),
            declared: robot
                .roles
                .iter()
                .flat_map(|r| r.actuators.iter().map(|a| a.name.as_str()))
                .collect(),
        }
    }

    /// Parses and resolves one interlock: an error at its first bad name.
    pub fn interlock(&self, text: &str) -> Result<Interlock, InterlockError> {
        let ast = expr::parse(text).map_err(InterlockError::Syntax)?;
        let mut spans = Vec::new();
        name_spans(&ast, &mut spans);
        let mut resolved = BTreeMap::new();
        for (n, span) in spans {
            if resolved.contains_key(n) {
                continue;
            }
            let atom = resolve(n, self.ir, &self.actuators, &self.declared).map_err(|error| {
                InterlockError::Name {
                    error: Box::new(error),
                    span: span.clone(),
                }
            })?;
            resolved.insert(n.to_string(), atom);
        }
        Ok(Interlock {
            text: text.to_string(),
            ast,
            names: resolved,
        })
    }
}

/// Every name of an expression with its span, left to right.
fn name_spans<'a>(ast: &'a Ast, out: &mut Vec<(&'a str, std::ops::Range<usize>)>) {
    match ast {
        Ast::Int(_) => {}
        Ast::Name(n, span) => out.push((n, span.clone())),
        Ast::Not(a) | Ast::Neg(a) | Ast::Wrap { of: a, .. } => name_spans(a, out),
        Ast::Bin(_, a, b) => {
            name_spans(a, out);
            name_spans(b, out);
        }
    }
}

impl Interlock {
    /// Whether the forbidden condition holds, given how to read each atom.
    pub fn holds(&self, read: &dyn Fn(Atom) -> bool) -> bool {
        expr::eval(&self.ast, &|n| {
            self.names.get(n).map(|a| i32::from(read(*a)))
        })
        .is_some_and(|v| v != 0)
    }
}

#[cfg(test)]
mod tests {
    use super::{Robot, Scope};
    use crate::source::Source;

    const PAINT: &str = include_str!("../../robot-configs/paint-robot.ron");

    /// Each bad name of an interlock is an error with its message and its span in the
    /// text; `interlocks` says which entry of `never:` it is.
    #[test]
    fn bad_interlock_names_say_what_they_may_be() {
        let c = crate::compile(&Source::new("paint-robot.ron", PAINT)).expect("compiles");
        let scope = Scope::of(&c.robot, &c.ir);
        let err = |text: &str| {
            let e = scope.interlock(text).expect_err("a bad name");
            (e.to_string(), e.span())
        };
        assert_eq!(
            err("VC.home && HC.up"),
            (
                String::from(
                    "`HC.up`: an actuator has `.home`, `.end`, `.moving`, `.extending`, \
                     `.retracting`, not `.up`"
                ),
                11..16
            )
        );
        assert_eq!(
            err("VC.arm.IDLE"),
            (
                String::from("`VC.arm.IDLE`: role VC has no chart `arm` (charts: VC, fault, home)"),
                0..11
            )
        );
        assert_eq!(
            err("!VC.VC.NOWHERE"),
            (
                String::from(
                    "`VC.VC.NOWHERE`: chart VC.VC has no state `NOWHERE` (states: IDLE, STEP1, \
                     WAIT3, STEP3, WAIT5, STEP5, STEP6, WAIT10, STEP10, WAIT12, STEP12, UNHOMED, HOMING)"
                ),
                1..14
            )
        );
        assert_eq!(
            err("lamp"),
            (
                String::from(
                    "`lamp` is not an interlock name: write `ACTUATOR.home` / `.end` / \
                     `.moving` / `.extending` / `.retracting`, `ROLE.CHART.STATE` or `ROLE.fault`"
                ),
                0..4
            )
        );
        assert_eq!(
            err("VC.home &&"),
            (
                String::from("expected a value, a name or `(`, found the end of the expression"),
                9..10
            )
        );
        let mut robot: Robot = c.robot.clone();
        robot.never.push(String::from("GR.open"));
        assert_eq!(
            super::interlocks(&robot, &c.ir)
                .expect_err("a bad entry")
                .to_string(),
            "never[2]: `GR.open`: an actuator has `.home`, `.end`, `.moving`, `.extending`, \
             `.retracting`, not `.open`"
        );
    }
}
