//! `sim --fault SPEC`: a fault injected into the simulated machine at a step of a cycle,
//! and what the machine does about it: who detects it and when, what moves afterwards,
//! and every node's outputs at the end.
//!
//! SPEC is `KIND:TARGET@STEP` or `KIND:TARGET@CYCLE.STEP` (cycle 1 by default); the fault
//! is injected just before step STEP (1-based) of that cycle is commanded:
//! - `stuck:ACT`: the actuator is jammed: valve commands move nothing;
//! - `switch:ACT.end` / `switch:ACT.home`: that limit switch stays open;
//! - `stop:ROLE`: the role's node stops (handles nothing, acknowledges nothing);
//! - `link:FROM->TO`: nothing published by FROM reaches TO any more.

use std::fmt::Write;

use node_fw::ecc::Fault;
use node_fw::sim::{Plant, SimError, TraceEntry, What, World};

use crate::sim::{cycle_limit_ms, step_of, steps_text, SimulationError};
use robot_compiler::compile::Compiled;
use robot_compiler::ir::Step;
use robot_compiler::synth::{FAULT_MOTION_TIMEOUT, FAULT_PEER};

/// What is injected.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FaultKind {
    Stuck(String),
    Switch(String),
    Stop(String),
    Link(String, String),
}

/// A parsed `--fault` argument.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FaultSpec {
    pub kind: FaultKind,
    /// 1-based cycle.
    pub cycle: usize,
    /// 1-based step of the cycle, injected just before it is commanded.
    pub step: usize,
}

impl std::fmt::Display for FaultSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} before step {} of cycle {}",
            describe(&self.kind),
            self.step,
            self.cycle
        )
    }
}

/// How to write a fault (the usage hint of [`ParseError`]).
pub const USAGE: &str = "write KIND:TARGET@STEP or KIND:TARGET@CYCLE.STEP, KIND one of stuck (an \
                         actuator), switch (ACT.end or ACT.home), stop (a role), link (FROM->TO)";

/// Why a `--fault` argument does not parse.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ParseError {
    #[error("`{spec}`: no `@STEP`: {}", USAGE)]
    NoStep { spec: String },
    #[error("`{spec}`: no `KIND:`: {}", USAGE)]
    NoKind { spec: String },
    #[error(
        "`{spec}`: `{number}` is not a step or cycle number (1 to {})",
        crate::sim::MAX_CYCLES
    )]
    BadNumber { spec: String, number: String },
    #[error("`{spec}`: a link joins two roles, not `{role}` with itself")]
    SelfLink { spec: String, role: String },
    #[error("`{spec}`: a link is FROM->TO")]
    BadLink { spec: String },
    #[error("`{spec}`: unknown fault kind `{kind}`: {}", USAGE)]
    UnknownKind { spec: String, kind: String },
}

/// Parses `stuck:HC@4`, `switch:HC.end@2.4`, `stop:GR@3`, `link:VC->GR@1`.
pub fn parse(spec: &str) -> Result<FaultSpec, ParseError> {
    let owned = || spec.to_string();
    let (what, at) = spec
        .rsplit_once('@')
        .ok_or_else(|| ParseError::NoStep { spec: owned() })?;
    let (kind, target) = what
        .split_once(':')
        .ok_or_else(|| ParseError::NoKind { spec: owned() })?;
    let number = |s: &str| -> Result<usize, ParseError> {
        s.parse::<usize>()
            .ok()
            .filter(|n| (1..=crate::sim::MAX_CYCLES).contains(n))
            .ok_or_else(|| ParseError::BadNumber {
                spec: owned(),
                number: s.to_string(),
            })
    };
    let (cycle, step) = match at.split_once('.') {
        Some((c, s)) => (number(c)?, number(s)?),
        None => (1, number(at)?),
    };
    let kind = match kind {
        "stuck" => FaultKind::Stuck(target.to_string()),
        "switch" => FaultKind::Switch(target.to_string()),
        "stop" => FaultKind::Stop(target.to_string()),
        "link" => {
            let (f, t) = target
                .split_once("->")
                .ok_or_else(|| ParseError::BadLink { spec: owned() })?;
            if f == t {
                return Err(ParseError::SelfLink {
                    spec: owned(),
                    role: f.to_string(),
                });
            }
            FaultKind::Link(f.to_string(), t.to_string())
        }
        other => {
            return Err(ParseError::UnknownKind {
                spec: owned(),
                kind: other.to_string(),
            })
        }
    };
    Ok(FaultSpec { kind, cycle, step })
}

/// Why a fault could not be injected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InjectError {
    #[error("no role `{0}`")]
    NoRole(String),
    #[error("no moving actuator `{0}`")]
    NoMovingActuator(String),
    #[error("no actuator `{0}`")]
    NoActuator(String),
    #[error("`{0}`: a switch is ACT.end or ACT.home")]
    BadSwitch(String),
    #[error("`{0}` has no switches")]
    NoSwitches(String),
    /// The actuator lacks the switch named (`which`: end or home); `has`: the ones it has.
    #[error("`{actuator}` has no {which} switch (its switches: {has})")]
    NoSuchSwitch {
        actuator: String,
        which: &'static str,
        has: String,
    },
    /// The declared cycle is shorter than the step named.
    #[error("the cycle has {steps} steps: there is no step {step}")]
    NoSuchStep { steps: usize, step: usize },
    /// The simulated cycle ended before the step named.
    #[error("the cycle ended after {steps} step(s): there is no step {step}")]
    CycleEnded { steps: usize, step: usize },
    #[error(transparent)]
    Simulation(#[from] SimulationError),
    #[error(transparent)]
    World(#[from] SimError),
}

/// Who noticed the fault first, and how.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Detection {
    pub t_ms: u64,
    pub role: String,
    pub how: String,
    /// The node's fault (`None`: a link alarm).
    pub fault: Option<Fault>,
}

/// A role, its fault (if any) and its output levels by name.
pub type NodeOutputs = (String, Option<String>, Vec<(String, bool)>);

/// What an injected fault led to.
#[derive(Debug, Clone)]
pub struct FaultRun {
    pub spec: FaultSpec,
    /// Text of the injected fault.
    pub fault: String,
    pub injected_ms: u64,
    /// The step the fault was injected before (`HC+`), if the cycle got that far.
    pub before_step: Option<Step>,
    /// Time step `step` was commanded (or attempted on a jammed actuator).
    pub commanded_ms: Option<u64>,
    /// A motion watchdog's detection: the motion it watched (the detecting role's last
    /// step commanded or attempted before it), and when it was commanded.
    pub watched: Option<(u64, Step)>,
    /// Steps of the fault's cycle before the injection.
    pub steps_before: Vec<Step>,
    /// Steps after the injection, up to the detection (or, undetected, the end of the run).
    pub steps_after: Vec<Step>,
    /// The first motion a jam held back, when it has no completion sensor (nothing can
    /// detect it): (time, step).
    pub undetectable: Option<(u64, Step)>,
    pub detected: Option<Detection>,
    /// Every node fault and link alarm after the injection: (time, text).
    pub reactions: Vec<(u64, String)>,
    /// Actuator motions started after the detection: (time, step, safe-state release of a
    /// monostable valve on a faulted node).
    pub moves_after: Vec<(u64, Step, bool)>,
    /// Per role: fault (if any) and output levels at the end.
    pub outputs: Vec<NodeOutputs>,
    /// The whole trace (for `--timeline`).
    pub trace: Vec<TraceEntry>,
    pub end_ms: u64,
}

/// Simulates the robot with the fault of `spec` injected.
pub fn simulate(c: &Compiled, spec: &FaultSpec) -> Result<FaultRun, InjectError> {
    let tables = crate::sim::tables(c)?;
    let (mut world, button) = crate::sim::world(c, &tables)?;
    // Resolve the target now, so a typo fails before anything runs.
    let target = resolve(c, &world, &spec.kind)?;
    let n = c.ir.expect.len();
    if n > 0 && spec.step > n {
        return Err(InjectError::NoSuchStep {
            steps: n,
            step: spec.step,
        });
    }
    let limit_ms = cycle_limit_ms(c);
    let (mark, injected_ms) = run_injected(&mut world, button, spec, &target, limit_ms)?;
    let mut trace = world.take_trace();
    // Name the injected fault by roles and actuators rather than indices.
    let named = describe(&spec.kind);
    for e in trace.iter_mut().skip(mark) {
        if let What::Injected { fault } = &mut e.what {
            *fault = named.clone();
        }
    }
    let fault_text = trace[mark..]
        .iter()
        .find_map(|e| match &e.what {
            What::Injected { fault } => Some(fault.clone()),
            _ => None,
        })
        .unwrap_or_default();
    let inj_index = trace[mark..]
        .iter()
        .position(|e| matches!(e.what, What::Injected { .. }))
        .map_or(mark, |i| mark + i);
    let plants = world.plants();
    let (before_step, commanded_ms) = first_command(plants, &trace[inj_index..]);
    let (reactions, detected) = reactions(c, &trace, inj_index);
    let steps_after = steps_in(
        &trace,
        inj_index..detected.as_ref().map_or(trace.len(), |d| d.0),
    );
    let watched = (detected.as_ref())
        .filter(|(_, d)| {
            matches!(
                d.fault,
                Some(Fault::Action {
                    code: FAULT_MOTION_TIMEOUT,
                    ..
                })
            )
        })
        .and_then(|(i, d)| watched(c, plants, trace.get(..*i)?, &d.role));
    Ok(FaultRun {
        spec: spec.clone(),
        fault: fault_text,
        injected_ms,
        before_step,
        commanded_ms,
        watched,
        steps_before: steps_in(&trace, mark..inj_index),
        steps_after,
        undetectable: undetectable(c, plants, &trace[inj_index..]),
        moves_after: detected
            .as_ref()
            .map_or_else(Vec::new, |(d, _)| moves_after(plants, &trace, *d)),
        detected: detected.map(|d| d.1),
        reactions,
        outputs: outputs(c, &world),
        end_ms: world.now(),
        trace,
    })
}

/// The plant, input, node or link `kind` names.
fn resolve(c: &Compiled, world: &World, kind: &FaultKind) -> Result<Target, InjectError> {
    let role = |name: &str| {
        c.ir.roles
            .iter()
            .position(|r| r.name == *name)
            .ok_or_else(|| InjectError::NoRole(name.to_string()))
    };
    Ok(match kind {
        FaultKind::Stuck(a) => {
            let p = world
                .plant_by_name(a)
                .filter(|p| world.plants()[*p].travel().is_some())
                .ok_or_else(|| InjectError::NoMovingActuator(a.clone()))?;
            Target::Plant(p)
        }
        FaultKind::Switch(s) => {
            let (a, which) = s
                .split_once('.')
                .ok_or_else(|| InjectError::BadSwitch(s.clone()))?;
            let p = world
                .plant_by_name(a)
                .ok_or_else(|| InjectError::NoActuator(a.to_string()))?;
            let Some((node, home, end)) = world.plants()[p].switches() else {
                return Err(InjectError::NoSwitches(a.to_string()));
            };
            let (which, input) = match which {
                "end" => ("end", end),
                "home" => ("home", home),
                _ => return Err(InjectError::BadSwitch(s.clone())),
            };
            let input = input.ok_or_else(|| {
                let has: Vec<&str> = [("home", home), ("end", end)]
                    .into_iter()
                    .filter_map(|(name, pin)| pin.map(|_| name))
                    .collect();
                InjectError::NoSuchSwitch {
                    actuator: a.to_string(),
                    which,
                    has: if has.is_empty() {
                        String::from("none")
                    } else {
                        has.join(", ")
                    },
                }
            })?;
            Target::Input(node, input)
        }
        FaultKind::Stop(r) => Target::Node(role(r)?),
        FaultKind::Link(f, t) => Target::Link(role(f)?, role(t)?),
    })
}

/// Runs the cycles before the fault's, then the fault's cycle with `target` injected
/// just before its step `spec.step`, each cycle within `limit_ms`: the trace index where
/// that cycle starts and the time of the injection.
fn run_injected(
    world: &mut World,
    button: usize,
    spec: &FaultSpec,
    target: &Target,
    limit_ms: u64,
) -> Result<(usize, u64), InjectError> {
    for _ in 1..spec.cycle {
        world.run_cycle(button, limit_ms)?;
    }
    let mark = world.trace().len();
    let steps_so_far = |w: &World| {
        w.trace()[mark..]
            .iter()
            .filter(|e| e.what.step().is_some())
            .count()
    };
    let mut injected_ms = None;
    if spec.step == 1 {
        injected_ms = Some(inject(world, target)?);
    }
    world.press(button)?;
    let deadline = world.now().saturating_add(limit_ms);
    let mut events = 0usize;
    loop {
        if injected_ms.is_none() && steps_so_far(world) + 1 >= spec.step {
            injected_ms = Some(inject(world, target)?);
        }
        match world.step() {
            Some(t) if t <= deadline && events < 1_000_000 => events += 1,
            _ => break,
        }
    }
    let injected_ms = injected_ms.ok_or_else(|| InjectError::CycleEnded {
        steps: steps_so_far(world),
        step: spec.step,
    })?;
    Ok((mark, injected_ms))
}

/// Injects the fault now; returns the time.
fn inject(w: &mut World, target: &Target) -> Result<u64, SimError> {
    match *target {
        Target::Plant(p) => w.jam(p),
        Target::Input(n, i) => w.break_switch(n, i),
        Target::Node(n) => w.stop_node(n),
        Target::Link(f, t) => w.cut_link(f, t),
    }?;
    Ok(w.now())
}

/// A motion of plant `plant` (`HC+`).
fn plant_step(plants: &[Plant], plant: usize, plus: bool) -> Step {
    Step {
        actuator: plants[plant].name().to_string(),
        extend: plus,
    }
}

/// The step the fault precedes: the first step or jammed command of `after`, and its time.
fn first_command(plants: &[Plant], after: &[TraceEntry]) -> (Option<Step>, Option<u64>) {
    after
        .iter()
        .find_map(|e| match &e.what {
            What::Step { .. } => Some((step_of(&e.what), Some(e.t_ms))),
            What::Jammed { plant, plus } => {
                Some((Some(plant_step(plants, *plant, *plus)), Some(e.t_ms)))
            }
            _ => None,
        })
        .unwrap_or((None, None))
}

/// How a motion watchdog's detection is said.
const WATCHDOG: &str = "motion watchdog (fault 1)";

/// The motion of role `role` that a watchdog of it watched, and when it was commanded:
/// its last motion a jam held back in `before`, else its last step (a switch that stayed
/// open: the rod moved, its switch never said so).
fn watched(
    c: &Compiled,
    plants: &[Plant],
    before: &[TraceEntry],
    role: &str,
) -> Option<(u64, Step)> {
    let of_role = |step: Step| {
        let (r, _) = c.robot.actuator(&step.actuator)?;
        (c.robot.roles.get(r)?.name == role).then_some(step)
    };
    let jammed = before.iter().rev().find_map(|e| match &e.what {
        What::Jammed { plant, plus } => Some((e.t_ms, of_role(plant_step(plants, *plant, *plus))?)),
        _ => None,
    });
    jammed.or_else(|| {
        before.iter().rev().find_map(|e| match &e.what {
            What::Step { .. } => Some((e.t_ms, of_role(step_of(&e.what)?)?)),
            _ => None,
        })
    })
}

/// The first reaction to a fault, with its trace index.
type FirstReaction = Option<(usize, Detection)>;

/// Every node fault and link alarm from `from` on, as (time, text), and the first of
/// them.
fn reactions(
    c: &Compiled,
    trace: &[TraceEntry],
    from: usize,
) -> (Vec<(u64, String)>, FirstReaction) {
    let name = |node: usize| c.ir.roles[node].name.clone();
    let mut reactions = Vec::new();
    let mut detected: FirstReaction = None;
    for (i, e) in trace.iter().enumerate().skip(from) {
        let text = match &e.what {
            What::Fault { node, fault } => {
                let how = match fault {
                    Fault::Action {
                        code: FAULT_MOTION_TIMEOUT,
                        ..
                    } => String::from(WATCHDOG),
                    Fault::Action {
                        code: FAULT_PEER, ..
                    } => String::from("a peer's fault (fault 2)"),
                    other => format!("{other:?}"),
                };
                Some((name(*node), how, Some(*fault)))
            }
            What::LinkAlarm { node, peer } => Some((
                name(*node),
                format!("link alarm: {} does not acknowledge", name(*peer)),
                None,
            )),
            _ => None,
        };
        if let Some((role, how, fault)) = text {
            reactions.push((e.t_ms, format!("{role}: {how}")));
            if detected.is_none() {
                detected = Some((
                    i,
                    Detection {
                        t_ms: e.t_ms,
                        role,
                        how,
                        fault,
                    },
                ));
            }
        }
    }
    (reactions, detected)
}

/// The steps of `trace[range]`.
fn steps_in(trace: &[TraceEntry], range: std::ops::Range<usize>) -> Vec<Step> {
    trace
        .get(range)
        .unwrap_or(&[])
        .iter()
        .filter_map(|e| step_of(&e.what))
        .collect()
}

/// The first motion a jam in `after` held back, if it has no completion sensor.
fn undetectable(c: &Compiled, plants: &[Plant], after: &[TraceEntry]) -> Option<(u64, Step)> {
    let held = after.iter().find_map(|e| match &e.what {
        What::Jammed { plant, plus } => {
            let step = plant_step(plants, *plant, *plus);
            let sensorless = c.robot.actuator(&step.actuator).is_some_and(|(r, i)| {
                c.robot.roles[r].actuators[i]
                    .kind
                    .completion_switch(*plus)
                    .is_none()
            });
            Some(sensorless.then_some((e.t_ms, step)))
        }
        _ => None,
    });
    held.flatten()
}

/// Actuator motions from trace index `detected` on: (time, step, safe-state release of a
/// monostable valve on a node that faulted at that instant).
fn moves_after(plants: &[Plant], trace: &[TraceEntry], detected: usize) -> Vec<(u64, Step, bool)> {
    let mut moves = Vec::new();
    for (i, e) in trace.iter().enumerate().skip(detected) {
        if let What::Step { plant, plus, .. } = &e.what {
            let node = plants[*plant].node();
            let single = matches!(plants[*plant], Plant::SingleActing(_));
            let faulted_now = trace[..i]
                .iter()
                .rev()
                .take_while(|x| x.t_ms == e.t_ms)
                .any(|x| matches!(x.what, What::Fault { node: n, .. } if n == node));
            let step = step_of(&e.what).unwrap_or_else(|| plant_step(plants, *plant, *plus));
            moves.push((e.t_ms, step, single && faulted_now));
        }
    }
    moves
}

/// Per role: its fault (if any) and its output levels.
fn outputs(c: &Compiled, world: &World) -> Vec<NodeOutputs> {
    c.ir.roles
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let e = world.engine(i);
            let levels = r
                .outputs
                .iter()
                .enumerate()
                .map(|(o, out)| (out.name.clone(), e.outputs() & (1 << o) != 0))
                .collect();
            (r.name.clone(), e.fault().map(|f| format!("{f:?}")), levels)
        })
        .collect()
}

enum Target {
    Plant(usize),
    Input(usize, u8),
    Node(usize),
    Link(usize, usize),
}

impl FaultRun {
    /// Whether a node noticed the fault and no actuator started a motion afterwards other
    /// than a monostable valve released by its faulted node (its safe state).
    pub fn stopped_safely(&self) -> bool {
        self.detected.is_some() && self.moves_after.iter().all(|m| m.2)
    }

    /// The text `sim --fault` prints.
    pub fn report(&self) -> String {
        let mut o = String::new();
        let _ = writeln!(
            o,
            "fault: {} at {} ms (cycle {}, before step {}{})",
            describe(&self.spec.kind),
            self.injected_ms,
            self.spec.cycle,
            self.spec.step,
            self.before_step
                .as_ref()
                .map(|s| format!(" {s}"))
                .unwrap_or_default()
        );
        let before = match steps_text(&self.steps_before) {
            t if t.is_empty() => String::from("none"),
            t => t,
        };
        let _ = writeln!(o, "steps until then: {before}");
        if !self.steps_after.is_empty() {
            let _ = writeln!(
                o,
                "steps after the injection{}: {}",
                if self.detected.is_some() {
                    ", before the detection"
                } else {
                    ""
                },
                steps_text(&self.steps_after)
            );
        }
        match &self.detected {
            Some(d) => {
                let _ = writeln!(
                    o,
                    "detected at {} ms by {}: {}{}",
                    d.t_ms,
                    d.role,
                    d.how,
                    match (&self.watched, self.commanded_ms) {
                        (Some((t, step)), _) => {
                            format!(", {} {step} was commanded", since(d.t_ms, *t))
                        }
                        (None, Some(t)) => format!(
                            ", {} step {} was commanded",
                            since(d.t_ms, t),
                            self.spec.step
                        ),
                        (None, None) => String::new(),
                    }
                );
                for (t, r) in &self.reactions {
                    let _ = writeln!(o, "  at {t:>6} ms  {r}");
                }
            }
            None => {
                let _ = writeln!(
                    o,
                    "NOT DETECTED: no node faulted and no link went into alarm up to {} ms, \
                     where the run ended",
                    self.end_ms
                );
                if let Some((t, step)) = &self.undetectable {
                    let _ = writeln!(
                        o,
                        "  the jammed motion `{step}` (at {t} ms) has no completion sensor: it \
                         completes after its dwell time whether it moved or not (`check` \
                         warns of such steps)"
                    );
                }
            }
        }
        if self.detected.is_none() {
        } else if self.moves_after.is_empty() {
            let _ = writeln!(o, "after the detection: no actuator moved");
        } else {
            for (t, s, safe) in &self.moves_after {
                let _ = writeln!(
                    o,
                    "after the detection: at {t} ms {s}{}",
                    if *safe {
                        " (safe state: its faulted node released the monostable valve)"
                    } else {
                        "  <-- MOVED AFTER THE FAULT"
                    }
                );
            }
        }
        let _ = writeln!(o, "outputs afterwards:");
        for (role, fault, levels) in &self.outputs {
            let levels: Vec<String> = levels
                .iter()
                .map(|(n, l)| format!("{n}={}", u8::from(*l)))
                .collect();
            let _ = writeln!(
                o,
                "  {role:<8} {:<28} {}",
                fault
                    .as_deref()
                    .map_or(String::from("running"), |f| format!("FAULT {f}")),
                levels.join(" ")
            );
        }
        o
    }
}

/// The injected fault in words.
fn describe(kind: &FaultKind) -> String {
    match kind {
        FaultKind::Stuck(a) => format!("{a} jammed"),
        FaultKind::Switch(s) => format!("switch {s} broken (stays open)"),
        FaultKind::Stop(r) => format!("node of {r} stopped"),
        FaultKind::Link(f, t) => format!("link {f} -> {t} lost"),
    }
}

/// When `t_ms` came relative to `then_ms`: `N ms after` or `N ms before`.
fn since(t_ms: u64, then_ms: u64) -> String {
    if t_ms >= then_ms {
        format!("{} ms after", t_ms - then_ms)
    } else {
        format!("{} ms before", then_ms - t_ms)
    }
}

#[cfg(test)]
mod tests {
    use super::{parse, FaultKind, ParseError};

    #[test]
    fn a_fault_spec_names_its_cycle_and_step() {
        let s = parse("link:VC->GR@3.2").expect("parses");
        assert_eq!(s.kind, FaultKind::Link("VC".into(), "GR".into()));
        assert_eq!((s.cycle, s.step), (3, 2));
        assert_eq!(s.to_string(), "link VC -> GR lost before step 2 of cycle 3");
    }

    #[test]
    fn a_bad_fault_spec_says_what_is_wrong() {
        assert_eq!(
            parse("link:VC@1"),
            Err(ParseError::BadLink {
                spec: "link:VC@1".into()
            })
        );
        assert_eq!(
            parse("link:VC@1").unwrap_err().to_string(),
            "`link:VC@1`: a link is FROM->TO"
        );
        let err = parse("melt:VC@1").unwrap_err();
        assert_eq!(
            err,
            ParseError::UnknownKind {
                spec: "melt:VC@1".into(),
                kind: "melt".into()
            }
        );
        assert_eq!(
            err.to_string(),
            "`melt:VC@1`: unknown fault kind `melt`: write KIND:TARGET@STEP or \
             KIND:TARGET@CYCLE.STEP, KIND one of stuck (an actuator), switch (ACT.end or \
             ACT.home), stop (a role), link (FROM->TO)"
        );
        assert_eq!(
            parse("stop:GR@x.1").unwrap_err().to_string(),
            "`stop:GR@x.1`: `x` is not a step or cycle number (1 to 10000)"
        );
        assert_eq!(
            parse("link:VC->VC@4").unwrap_err().to_string(),
            "`link:VC->VC@4`: a link joins two roles, not `VC` with itself"
        );
        // A cycle past the simulation's bound is refused, not run to.
        assert_eq!(parse("stuck:HC@10000.1").map(|s| s.cycle), Ok(10_000));
        assert_eq!(
            parse("stuck:HC@4294967296.1").unwrap_err().to_string(),
            "`stuck:HC@4294967296.1`: `4294967296` is not a step or cycle number (1 to 10000)"
        );
        assert_eq!(
            parse("GR@1").unwrap_err(),
            ParseError::NoKind {
                spec: "GR@1".into()
            }
        );
    }
}
