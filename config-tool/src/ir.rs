//! The intermediate form: per role, named events, pins, timers and charts, before
//! lowering to a `config_schema::Table`. Both the sequence synthesiser and the explicit
//! chart elaborator produce it; `lower`, `diagram` and the checks read it.

use config_schema::Op;

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
    /// Events of other roles raised here: (publishing role, its event, the local event).
    pub imports: Vec<(String, String, String)>,
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
    pub safe: bool,
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
    pub initial: usize,
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
    /// Declares an actuator's pins: each valve an output `ACT.FIELD` (safe off), each limit
    /// switch an input `ACT.FIELD` whose rising edge raises the event `ACT.FIELD` if
    /// `rise` says so, and whose falling edge raises `ACT.FIELD.fall` if `fall` says so.
    /// Events are not registered here.
    pub fn declare_actuator(
        &mut self,
        a: &crate::model::Actuator,
        rise: impl Fn(&str) -> bool,
        fall: impl Fn(&str) -> bool,
    ) {
        for (field, pin, used) in a.kind.pins() {
            let name = format!("{}.{field}", a.name);
            match used {
                crate::model::PinUse::Valve => self.outputs.push(OutputIr {
                    name,
                    pin,
                    safe: false,
                }),
                crate::model::PinUse::Switch => {
                    let falling = format!("{name}.fall");
                    self.inputs.push(InputIr {
                        rise: rise(&name).then(|| name.clone()),
                        fall: fall(&falling).then_some(falling),
                        var: None,
                        name,
                        pin,
                    });
                }
            }
        }
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

/// Parses `A+ B- ...` into steps with their byte spans in the text.
pub fn parse_steps(text: &str) -> Vec<(Result<Step, String>, std::ops::Range<usize>)> {
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
                    _ => Err(format!(
                        "`{token}` is not a step: write an actuator name and `+` or `-`, e.g. `VC+`"
                    )),
                };
                out.push((step, s..i));
                start = None;
            }
            _ => {}
        }
    }
    out
}
