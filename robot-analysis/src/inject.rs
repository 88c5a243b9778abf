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

use node_fw::sim::{Plant, TraceEntry, What, World};

use crate::sim::CYCLE_LIMIT_MS;
use robot_compiler::compile::Compiled;

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

/// Parses `stuck:HC@4`, `switch:HC.end@2.4`, `stop:GR@3`, `link:VC->GR@1`.
pub fn parse(spec: &str) -> Result<FaultSpec, String> {
    let usage = "write KIND:TARGET@STEP or KIND:TARGET@CYCLE.STEP, KIND one of stuck (an \
                 actuator), switch (ACT.end or ACT.home), stop (a role), link (FROM->TO)";
    let (what, at) = spec
        .rsplit_once('@')
        .ok_or_else(|| format!("`{spec}`: no `@STEP`: {usage}"))?;
    let (kind, target) = what
        .split_once(':')
        .ok_or_else(|| format!("`{spec}`: no `KIND:`: {usage}"))?;
    let number = |s: &str| -> Result<usize, String> {
        s.parse::<usize>()
            .ok()
            .filter(|n| *n > 0)
            .ok_or_else(|| format!("`{spec}`: `{s}` is not a step or cycle number (1, 2, ...)"))
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
                .ok_or_else(|| format!("`{spec}`: a link is FROM->TO"))?;
            FaultKind::Link(f.to_string(), t.to_string())
        }
        other => return Err(format!("`{spec}`: unknown fault kind `{other}`: {usage}")),
    };
    Ok(FaultSpec { kind, cycle, step })
}

/// Who noticed the fault first, and how.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Detection {
    pub t_ms: u64,
    pub role: String,
    pub how: String,
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
    pub before_step: Option<String>,
    /// Time step `step` was commanded (or attempted on a jammed actuator).
    pub commanded_ms: Option<u64>,
    /// Steps of the fault's cycle before the injection.
    pub steps_before: Vec<String>,
    /// Steps after the injection, up to the detection (or, undetected, the end of the run).
    pub steps_after: Vec<String>,
    /// The first motion a jam held back, when it has no completion sensor (nothing can
    /// detect it): (time, step).
    pub undetectable: Option<(u64, String)>,
    pub detected: Option<Detection>,
    /// Every node fault and link alarm after the injection: (time, text).
    pub reactions: Vec<(u64, String)>,
    /// Actuator motions started after the detection: (time, step, safe-state release of a
    /// monostable valve on a faulted node).
    pub moves_after: Vec<(u64, String, bool)>,
    /// Per role: fault (if any) and output levels at the end.
    pub outputs: Vec<NodeOutputs>,
    /// The whole trace (for `--timeline`).
    pub trace: Vec<TraceEntry>,
    pub end_ms: u64,
}

/// Simulates the robot with the fault of `spec` injected.
pub fn simulate(c: &Compiled, spec: &FaultSpec) -> Result<FaultRun, String> {
    let tables = crate::sim::tables(c)?;
    let (mut world, button) = crate::sim::world(c, &tables)?;
    let role = |name: &str| {
        c.ir.roles
            .iter()
            .position(|r| r.name == *name)
            .ok_or_else(|| format!("no role `{name}`"))
    };
    // Resolve the target now, so a typo fails before anything runs.
    let target = match &spec.kind {
        FaultKind::Stuck(a) => {
            let p = world
                .plant_by_name(a)
                .filter(|p| world.plants()[*p].travel().is_some())
                .ok_or_else(|| format!("no moving actuator `{a}`"))?;
            Target::Plant(p)
        }
        FaultKind::Switch(s) => {
            let (a, which) = s
                .split_once('.')
                .ok_or_else(|| format!("`{s}`: a switch is ACT.end or ACT.home"))?;
            let p = world
                .plant_by_name(a)
                .ok_or_else(|| format!("no actuator `{a}`"))?;
            let Some((node, home, end)) = world.plants()[p].switches() else {
                return Err(format!("`{a}` has no switches"));
            };
            let input = match which {
                "end" => end,
                "home" => home,
                _ => None,
            }
            .ok_or_else(|| format!("`{s}`: a switch is ACT.end or ACT.home"))?;
            Target::Input(node, input)
        }
        FaultKind::Stop(r) => Target::Node(role(r)?),
        FaultKind::Link(f, t) => Target::Link(role(f)?, role(t)?),
    };
    let n = c.ir.expect.len();
    if n > 0 && spec.step > n {
        return Err(format!(
            "the cycle has {n} steps: there is no step {}",
            spec.step
        ));
    }
    for _ in 1..spec.cycle {
        world
            .run_cycle(button, CYCLE_LIMIT_MS)
            .map_err(|e| e.to_string())?;
    }
    let mark = world.trace().len();
    let steps_so_far = |w: &World| {
        w.trace()[mark..]
            .iter()
            .filter(|e| e.what.step().is_some())
            .count()
    };
    let mut injected_ms = None;
    let inject = |w: &mut World, target: &Target| -> Result<u64, String> {
        match *target {
            Target::Plant(p) => w.jam(p),
            Target::Input(n, i) => w.break_switch(n, i),
            Target::Node(n) => w.stop_node(n),
            Target::Link(f, t) => w.cut_link(f, t),
        }
        .map_err(|e| e.to_string())?;
        Ok(w.now())
    };
    if spec.step == 1 {
        injected_ms = Some(inject(&mut world, &target)?);
    }
    world.press(button).map_err(|e| e.to_string())?;
    let deadline = world.now() + CYCLE_LIMIT_MS;
    let mut events = 0usize;
    loop {
        if injected_ms.is_none() && steps_so_far(&world) + 1 >= spec.step {
            injected_ms = Some(inject(&mut world, &target)?);
        }
        match world.step() {
            Some(t) if t <= deadline && events < 1_000_000 => events += 1,
            _ => break,
        }
    }
    let injected_ms = injected_ms.ok_or_else(|| {
        format!(
            "the cycle ended after {} step(s): there is no step {}",
            steps_so_far(&world),
            spec.step
        )
    })?;
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
    let name = |node: usize| c.ir.roles[node].name.clone();
    let plant_name = |p: usize| world.plants()[p].name().to_string();
    // The step the fault precedes: the next step or jammed command after the injection.
    let (before_step, commanded_ms) = trace[inj_index..]
        .iter()
        .find_map(|e| match &e.what {
            What::Step { .. } => Some((e.what.step(), Some(e.t_ms))),
            What::Jammed { plant, plus } => Some((
                Some(format!(
                    "{}{}",
                    plant_name(*plant),
                    if *plus { '+' } else { '-' }
                )),
                Some(e.t_ms),
            )),
            _ => None,
        })
        .unwrap_or((None, None));
    let mut reactions = Vec::new();
    let mut detected: Option<(usize, Detection)> = None;
    for (i, e) in trace.iter().enumerate().skip(inj_index) {
        let text = match &e.what {
            What::Fault { node, fault } => {
                let how = match fault {
                    node_fw::ecc::Fault::Action { code: 1, .. } => {
                        String::from("motion watchdog (fault 1)")
                    }
                    node_fw::ecc::Fault::Action { code: 2, .. } => {
                        String::from("a peer's fault (fault 2)")
                    }
                    other => format!("{other:?}"),
                };
                Some((name(*node), how))
            }
            What::LinkAlarm { node, peer } => Some((
                name(*node),
                format!("link alarm: {} does not acknowledge", name(*peer)),
            )),
            _ => None,
        };
        if let Some((role, how)) = text {
            reactions.push((e.t_ms, format!("{role}: {how}")));
            if detected.is_none() {
                detected = Some((
                    i,
                    Detection {
                        t_ms: e.t_ms,
                        role,
                        how,
                    },
                ));
            }
        }
    }
    let steps = |range: std::ops::Range<usize>| -> Vec<String> {
        trace
            .get(range)
            .unwrap_or(&[])
            .iter()
            .filter_map(|e| e.what.step())
            .collect()
    };
    let steps_before = steps(mark..inj_index);
    let steps_after = steps(inj_index..detected.as_ref().map_or(trace.len(), |d| d.0));
    // The first motion the jam held back, if it has no completion sensor.
    let undetectable = trace[inj_index..].iter().find_map(|e| match &e.what {
        What::Jammed { plant, plus } => {
            let name = plant_name(*plant);
            let sensorless = c.robot.actuator(&name).is_some_and(|(r, i)| {
                c.robot.roles[r].actuators[i]
                    .kind
                    .completion_switch(*plus)
                    .is_none()
            });
            let step = format!("{name}{}", if *plus { '+' } else { '-' });
            Some(sensorless.then_some((e.t_ms, step)))
        }
        _ => None,
    });
    let undetectable = undetectable.flatten();
    let mut moves_after = Vec::new();
    if let Some((d, _)) = &detected {
        for (i, e) in trace.iter().enumerate().skip(*d) {
            if let What::Step { plant, .. } = &e.what {
                let node = world.plants()[*plant].node();
                let single = matches!(world.plants()[*plant], Plant::SingleActing(_));
                let faulted_now = trace[..i]
                    .iter()
                    .rev()
                    .take_while(|x| x.t_ms == e.t_ms)
                    .any(|x| matches!(x.what, What::Fault { node: n, .. } if n == node));
                moves_after.push((
                    e.t_ms,
                    e.what.step().unwrap_or_default(),
                    single && faulted_now,
                ));
            }
        }
    }
    let outputs =
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
            .collect();
    Ok(FaultRun {
        spec: spec.clone(),
        fault: fault_text,
        injected_ms,
        before_step,
        commanded_ms,
        steps_before,
        steps_after,
        undetectable,
        detected: detected.map(|d| d.1),
        reactions,
        moves_after,
        outputs,
        end_ms: world.now(),
        trace,
    })
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
        let _ = writeln!(o, "steps until then: {}", self.steps_before.join(" "));
        if !self.steps_after.is_empty() {
            let _ = writeln!(
                o,
                "steps after the injection{}: {}",
                if self.detected.is_some() {
                    ", before the detection"
                } else {
                    ""
                },
                self.steps_after.join(" ")
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
                    self.commanded_ms
                        .map(|t| format!(
                            ", {} ms after step {} was commanded",
                            d.t_ms - t,
                            self.spec.step
                        ))
                        .unwrap_or_default()
                );
                for (t, r) in &self.reactions {
                    let _ = writeln!(o, "  at {t:>6} ms  {r}");
                }
            }
            None => {
                let _ = writeln!(
                    o,
                    "NOT DETECTED: no node faulted and no link went into alarm; the machine \
                     stopped at {} ms",
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
