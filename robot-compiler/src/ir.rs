//! The intermediate form: per role, named events, pins, timers and charts, before
//! lowering to a `config_schema::Table`. Both the sequence synthesiser and the explicit
//! chart elaborator produce it; `lower`, `diagram` and the checks read it.

use config_schema::{Level, Op};

use crate::model::ActuatorLevel;

/// The whole robot, elaborated.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ir {
    pub name: String,
    pub generation: u32,
    pub pan_id: u16,
    pub channel: u8,
    pub roles: Vec<RoleIr>,
    /// The role and input whose rising edge starts a cycle.
    pub start: Option<(usize, String)>,
    /// The actuator steps one cycle must produce.
    pub expect: Vec<Step>,
    /// The role whose table raises homing on the HOME command (sequence robots).
    pub home: Option<usize>,
    /// The homing sequence, and whether the synthesiser derived it (not declared).
    pub homing: Vec<Step>,
    pub homing_derived: bool,
}

/// One actuator motion: `VC+` (extend) or `VC-` (retract).
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Step {
    pub actuator: String,
    pub extend: bool,
}

impl std::fmt::Display for Step {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}{}",
            self.actuator,
            if self.extend { '+' } else { '-' }
        )
    }
}

/// One role's table, with names.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RoleIr {
    pub name: String,
    /// Short address of the node playing the role.
    pub address: u16,
    /// Node events, by name; the index is the event id.
    pub events: Vec<String>,
    /// Variables and their initial values.
    pub vars: Vec<(String, i32)>,
    pub inputs: Vec<InputIr>,
    pub outputs: Vec<OutputIr>,
    pub timers: Vec<TimerIr>,
    pub charts: Vec<ChartIr>,
    /// Node event -> (chart, chart input).
    pub routes: Vec<(String, usize, usize)>,
    /// The node event the START command raises.
    pub start: Option<String>,
    /// The node event the HOME command raises.
    pub home: Option<String>,
    /// The node event raised (and published) when the node boots with its table.
    pub boot: Option<String>,
    /// Events of other roles raised here: (publishing role, its event, the local event).
    pub imports: Vec<(String, String, String)>,
    /// The actuators declared here, in declaration order: which outputs and inputs are
    /// their valves and switches.
    pub actuators: Vec<Wiring>,
    /// The e-stop, restart inputs, link alarm policy and declared alarms.
    pub safety: crate::alarms::SafetyIr,
}

/// An index into a role's `outputs` (the table's output index).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct OutputIndex(pub usize);

/// An index into a role's `inputs` (the table's input index).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct InputIndex(pub usize);

impl OutputIndex {
    /// The output's bit in a `Drive` mask or value (none beyond the 16 a table has).
    pub fn bit(self) -> u16 {
        u32::try_from(self.0)
            .ok()
            .and_then(|i| 1u16.checked_shl(i))
            .unwrap_or(0)
    }
}

/// How an actuator's valve is wired.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Valves {
    /// A bistable valve: the extend and the retract solenoid.
    Double {
        extend: OutputIndex,
        retract: OutputIndex,
    },
    /// A monostable valve: energised extends, de-energised retracts.
    Single { valve: OutputIndex },
}

/// One actuator's wiring in its role, recorded when it is declared
/// ([`RoleIr::declare_actuator`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Wiring {
    /// The actuator's name (`VC`).
    pub name: String,
    pub valves: Valves,
    /// The home and end limit switches (or position sensors), if it has them.
    pub home: Option<InputIndex>,
    pub end: Option<InputIndex>,
}

impl Wiring {
    /// The outputs a motion drives, and their values for a `+` (extend) or a `-`: both
    /// solenoids of a bistable valve at once.
    pub fn drive(&self, extend: bool) -> (u16, u16) {
        match self.valves {
            Valves::Double { extend: e, retract } => {
                let mask = e.bit() | retract.bit();
                (mask, if extend { e.bit() } else { retract.bit() })
            }
            Valves::Single { valve } => (valve.bit(), if extend { valve.bit() } else { 0 }),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InputIr {
    pub name: String,
    pub pin: u8,
    pub rise: Option<String>,
    pub fall: Option<String>,
    pub var: Option<String>,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OutputIr {
    pub name: String,
    pub pin: u8,
    /// When the node faults.
    pub fault: Level,
    /// Before the charts run: a new table, a boot, a reset.
    pub start: Level,
    /// Where homing drives it.
    pub home: bool,
}

/// The level of one valve solenoid of an actuator at `level`: `on_extend` / `on_retract`
/// say whether a `+` / a `-` energises it.
pub fn solenoid(level: ActuatorLevel, on_extend: bool, on_retract: bool) -> Level {
    match level {
        ActuatorLevel::Off => Level::Low,
        ActuatorLevel::Hold => Level::Hold,
        ActuatorLevel::Extend => Level::of(on_extend),
        ActuatorLevel::Retract => Level::of(on_retract),
    }
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TimerIr {
    pub name: String,
    pub event: String,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChartIr {
    pub name: String,
    /// Chart input events, by name.
    pub inputs: Vec<String>,
    /// Where the chart starts (not homed) and where it rests between cycles.
    pub initial: usize,
    pub idle: usize,
    /// Other states where it rests between cycles (a mode kept from one cycle to the
    /// next: `config_schema::Chart::rests`), besides `idle`.
    pub rests: Vec<usize>,
    pub states: Vec<StateIr>,
    pub transitions: Vec<TransitionIr>,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StateIr {
    pub name: String,
    pub actions: Vec<ActionIr>,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TransitionIr {
    pub from: usize,
    pub to: usize,
    /// Chart input index.
    pub trigger: Option<usize>,
    /// Guard text and bytecode.
    pub guard: Option<(String, Vec<Op>)>,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ActionIr {
    /// `var := expr` (text for people, bytecode for the node).
    Set {
        var: usize,
        text: String,
        ops: Vec<Op>,
    },
    /// Drive outputs (`label` says what for people, e.g. `VC+`).
    Drive {
        mask: u16,
        value: u16,
        label: String,
    },
    /// Emit a node event.
    Emit(String),
    StartTimer {
        timer: usize,
        ms: u32,
    },
    CancelTimer(usize),
    Fault(u8),
}

impl RoleIr {
    /// Declares the role's plain outputs (lamps, gates: `Role::outputs`), each with its
    /// fault, start and home levels, after what is declared already.
    pub fn declare_plain_outputs(&mut self, role: &crate::model::Role) {
        for o in &role.outputs {
            let (fault, start, home) = o.levels();
            self.outputs.push(OutputIr {
                name: o.name.clone(),
                pin: o.pin,
                fault,
                start,
                home,
            });
        }
    }

    /// Declares an actuator's pins: each valve an output `ACT.FIELD` (its fault and start
    /// levels from the actuator's, home as after a `-`), each limit
    /// switch an input `ACT.FIELD` whose rising edge raises the event `ACT.FIELD` if
    /// `rise` says so, and whose falling edge raises `ACT.FIELD.fall` if `fall` says so
    /// (in the order of `ActuatorKind::pins`); records their indices in
    /// [`RoleIr::actuators`]. Events are not registered here.
    pub fn declare_actuator(
        &mut self,
        a: &crate::model::Actuator,
        rise: impl Fn(&str) -> bool,
        fall: impl Fn(&str) -> bool,
    ) {
        use crate::model::ActuatorKind;
        let (valves, home, end) = match a.kind {
            ActuatorKind::DoubleActing {
                extend,
                retract,
                home,
                end,
                ..
            } => {
                let extend = self.valve(a, "extend", extend, (true, false));
                let retract = self.valve(a, "retract", retract, (false, true));
                (Valves::Double { extend, retract }, Some(home), Some(end))
            }
            ActuatorKind::SingleActing {
                valve, home, end, ..
            } => {
                let valve = self.valve(a, "valve", valve, (true, false));
                (Valves::Single { valve }, home, end)
            }
        };
        let home = home.map(|pin| self.switch(&a.name, "home", pin, &rise, &fall));
        let end = end.map(|pin| self.switch(&a.name, "end", pin, &rise, &fall));
        self.actuators.push(Wiring {
            name: a.name.clone(),
            valves,
            home,
            end,
        });
    }

    /// A valve solenoid of actuator `a`: the output `ACT.FIELD`; `(on_extend, on_retract)`
    /// say whether a `+` / a `-` energises it.
    fn valve(
        &mut self,
        a: &crate::model::Actuator,
        field: &str,
        pin: u8,
        (on_extend, on_retract): (bool, bool),
    ) -> OutputIndex {
        self.outputs.push(OutputIr {
            name: format!("{}.{field}", a.name),
            pin,
            fault: solenoid(a.fault, on_extend, on_retract),
            start: solenoid(a.start, on_extend, on_retract),
            home: on_retract,
        });
        OutputIndex(self.outputs.len() - 1)
    }

    /// A limit switch of actuator `actuator`: the input `ACT.FIELD` (see
    /// [`RoleIr::declare_actuator`]).
    fn switch(
        &mut self,
        actuator: &str,
        field: &str,
        pin: u8,
        rise: &impl Fn(&str) -> bool,
        fall: &impl Fn(&str) -> bool,
    ) -> InputIndex {
        let name = format!("{actuator}.{field}");
        let falling = format!("{name}.fall");
        self.inputs.push(InputIr {
            rise: rise(&name).then(|| name.clone()),
            fall: fall(&falling).then_some(falling),
            var: None,
            name,
            pin,
        });
        InputIndex(self.inputs.len() - 1)
    }

    /// The wiring of the actuator `name` declared in this role.
    pub fn actuator(&self, name: &str) -> Option<&Wiring> {
        self.actuators.iter().find(|w| w.name == name)
    }

    /// The id of a node event, adding it if new.
    pub fn event(&mut self, name: &str) -> usize {
        match self.events.iter().position(|e| e == name) {
            Some(i) => i,
            None => {
                self.events.push(name.to_string());
                self.events.len() - 1
            }
        }
    }

    pub fn event_id(&self, name: &str) -> Option<usize> {
        self.events.iter().position(|e| e == name)
    }

    /// Human text of an action.
    pub fn action_text(&self, action: &ActionIr) -> String {
        match action {
            ActionIr::Set { var, text, .. } => format!(
                "{} := {text}",
                self.vars.get(*var).map_or("?", |v| v.0.as_str())
            ),
            ActionIr::Drive { label, .. } => format!("drive {label}"),
            ActionIr::Emit(e) => format!("emit {e}"),
            ActionIr::StartTimer { timer, ms } => format!(
                "start {} {ms} ms",
                self.timers.get(*timer).map_or("?", |t| t.name.as_str())
            ),
            ActionIr::CancelTimer(timer) => format!(
                "cancel {}",
                self.timers.get(*timer).map_or("?", |t| t.name.as_str())
            ),
            ActionIr::Fault(code) => format!("fault {code}"),
        }
    }
}

/// A role asked by name (`--role`) that the robot does not have.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown role `{role}` (roles: {})", roles.join(", "))]
pub struct UnknownRole {
    pub role: String,
    /// The robot's roles, in order.
    pub roles: Vec<String>,
}

impl Ir {
    /// Role `name`.
    pub fn role(&self, name: &str) -> Result<&RoleIr, UnknownRole> {
        self.roles
            .iter()
            .find(|r| r.name == name)
            .ok_or_else(|| UnknownRole {
                role: name.to_string(),
                roles: self.roles.iter().map(|r| r.name.clone()).collect(),
            })
    }
}

/// A token of a step list that is not a step.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{token}` is not a step: write an actuator name and `+` or `-`, e.g. `VC+`")]
pub struct NotAStep {
    pub token: String,
}

/// Parses `A+ B- ...` into steps with their byte spans in the text.
pub fn parse_steps(text: &str) -> Vec<(Result<Step, NotAStep>, std::ops::Range<usize>)> {
    let mut out = Vec::new();
    let mut start = None;
    let bytes = text.as_bytes();
    for i in 0..=bytes.len() {
        let blank = i == bytes.len() || bytes[i].is_ascii_whitespace() || bytes[i] == b',';
        match (start, blank) {
            (None, false) => start = Some(i),
            (Some(s), true) => {
                let token = &text[s..i];
                let step = match token.chars().last() {
                    Some(c @ ('+' | '-')) if token.len() > 1 => Ok(Step {
                        actuator: token[..token.len() - 1].to_string(),
                        extend: c == '+',
                    }),
                    _ => Err(NotAStep {
                        token: token.to_string(),
                    }),
                };
                out.push((step, s..i));
                start = None;
            }
            _ => {}
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::{InputIndex, Level, OutputIndex, RoleIr, Valves, Wiring};
    use crate::model::{Actuator, ActuatorKind, ActuatorLevel};

    /// Declaring actuators records the indices of the outputs and inputs they add, after
    /// what the role already has; a `+` / `-` drives both solenoids of a bistable valve.
    #[test]
    fn declaring_an_actuator_records_its_wiring() {
        let mut r = RoleIr::default();
        r.outputs.push(super::OutputIr {
            name: String::from("lamp"),
            pin: 9,
            fault: Level::Low,
            start: Level::Low,
            home: false,
        });
        let double = Actuator {
            name: String::from("VC"),
            kind: ActuatorKind::DoubleActing {
                extend: 0,
                retract: 1,
                home: 2,
                end: 3,
                out_ms: 200,
                back_ms: 200,
                timeout_ms: None,
            },
            fault: ActuatorLevel::Retract,
            start: ActuatorLevel::Off,
        };
        let single = Actuator {
            name: String::from("GR"),
            kind: ActuatorKind::SingleActing {
                valve: 4,
                dwell_ms: 100,
                out_ms: 200,
                back_ms: 200,
                home: None,
                end: Some(5),
                timeout_ms: None,
            },
            fault: ActuatorLevel::Hold,
            start: ActuatorLevel::Extend,
        };
        r.declare_actuator(&double, |_| true, |_| false);
        r.declare_actuator(&single, |_| true, |_| false);
        let vc = Wiring {
            name: String::from("VC"),
            valves: Valves::Double {
                extend: OutputIndex(1),
                retract: OutputIndex(2),
            },
            home: Some(InputIndex(0)),
            end: Some(InputIndex(1)),
        };
        let gr = Wiring {
            name: String::from("GR"),
            valves: Valves::Single {
                valve: OutputIndex(3),
            },
            home: None,
            end: Some(InputIndex(2)),
        };
        assert_eq!(r.actuators, [vc.clone(), gr.clone()]);
        assert_eq!(r.actuator("GR"), Some(&gr));
        let names: Vec<&str> = r.outputs.iter().map(|o| o.name.as_str()).collect();
        assert_eq!(names, ["lamp", "VC.extend", "VC.retract", "GR.valve"]);
        // (fault, start, home) per solenoid: VC retracts on fault, GR holds its part.
        let levels: Vec<_> = (r.outputs.iter().skip(1))
            .map(|o| (o.fault, o.start, o.home))
            .collect();
        assert_eq!(
            levels,
            [
                (Level::Low, Level::Low, false),
                (Level::High, Level::Low, true),
                (Level::Hold, Level::High, false),
            ]
        );
        let names: Vec<&str> = r.inputs.iter().map(|i| i.name.as_str()).collect();
        assert_eq!(names, ["VC.home", "VC.end", "GR.end"]);
        assert_eq!(vc.drive(true), (0b110, 0b010));
        assert_eq!(vc.drive(false), (0b110, 0b100));
        assert_eq!(gr.drive(true), (0b1000, 0b1000));
        assert_eq!(gr.drive(false), (0b1000, 0));
        assert_eq!(OutputIndex(16).bit(), 0);
    }
}
