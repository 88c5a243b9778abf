//! Sequence synthesis: a cycle `A+ B+ A- B-` -> one chart per actuator.
//!
//! Every actuator starts home. Actuator `a`'s chart has a state per place in the cycle:
//! `STEPk` drives step k and starts the motion watchdog (or the dwell timer of a
//! sensorless actuator); `WAITk` waits for the event that releases step k. Step k+1
//! waits for the completion of step k: the limit switch (`A.end` for `+`, `A.home` for
//! `-`) or the dwell timer. When step k+1 is the same actuator's, the chart goes straight
//! from `STEPk` to `STEPk+1`: nothing is exchanged. Otherwise the chart emits the
//! step-specific event `stepk.done`, which only the next step's chart listens to; it
//! crosses the radio only when that chart is on another node, and only to that node.
//! The owner of step 1 waits in `IDLE` for START, and (if the last step is another
//! actuator's) in `CYCLE_END` for `stepN.done`, so a START during a cycle is ignored.
//! When the START button is on another role than step 1's, a `START` chart on the
//! button's role gates it: `SHUT` -(the machine is idle)-> `IDLE` -(press)-> `CYCLE`
//! (emit `cycle.start`, published to step 1's role) -(the cycle is over)-> `IDLE`. A
//! press during a cycle, or before the machine is homed, costs nothing. The machine is
//! idle, and a cycle over, for the button's role when step 1's chart is back in `IDLE`
//! (after homing or a cycle): it then emits `cycle.done` to the button's role, and enters
//! `IDLE` again (so sends it again) on the boot of a button's role that moves nothing
//! (homing's `button.boot`: a panel's power cut at rest). (The gate
//! once started open, and reopened on the last step's `stepN.done` when that step was the
//! button role's own: a press before HOME then sent `cycle.start`, which started a cycle
//! once homing had ended, unless the last homing step's `home.done` reached step 1's role
//! first on the same link.)
//! A watchdog timeout raises fault 1 through a small per-role `fault` chart, which also
//! publishes `fault` to every other role; receiving a peer's `fault` raises fault 2. So a
//! fault anywhere stops every node at once (outputs safe) until a reset.

mod homing;

pub use homing::{
    home_done_event, homing_events, BOOT_EVENT, HOME_COMMAND_EVENT, HOME_DONE_EVENT,
    HOME_START_EVENT, PEER_BOOT_EVENT,
};

use crate::elab::{AddressError, StartError};
use crate::ir::{ActionIr, ChartIr, InputIr, Ir, RoleIr, StateIr, Step, TimerIr, TransitionIr};
use crate::model::{Actuator, ActuatorKind, Robot, Role};

/// Fault code of a motion that did not complete in time.
pub const FAULT_MOTION_TIMEOUT: u8 = 1;
/// Fault code of a node stopped by another node's fault.
pub const FAULT_PEER: u8 = 2;
/// The node event a role publishes to every other role when its watchdog expires.
pub const FAULT_EVENT: &str = "fault";
/// The node event a peer's `fault` raises.
pub const PEER_FAULT_EVENT: &str = "peer.fault";
/// The event the START chart (button on another role than step 1's) publishes to step 1's
/// role for a press at idle.
pub const CYCLE_START_EVENT: &str = "cycle.start";
/// The event step 1's chart emits (to the button's role) when it is back in `IDLE`, if the
/// button's role needs it to reopen its gate.
pub const CYCLE_DONE_EVENT: &str = "cycle.done";

/// Whether role `q` has an actuator that moves in the sequence.
fn moving_in(robot: &Robot, q: usize, steps: &[Step]) -> bool {
    robot.roles[q]
        .actuators
        .iter()
        .any(|a| steps.iter().any(|s| s.actuator == a.name))
}

/// Whether role `q` has an actuator with a switch (double acting, or single acting with a
/// position sensor) that moves: it has a motion watchdog, so it can detect a fault and
/// publishes `fault`.
fn switched_in(robot: &Robot, q: usize, steps: &[Step]) -> bool {
    robot.roles[q]
        .actuators
        .iter()
        .any(|a| a.kind.has_watchdog() && steps.iter().any(|s| s.actuator == a.name))
}

/// Why a sequence could not be synthesised (`check` reports each first).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SynthError {
    #[error("the sequence has no steps")]
    NoSteps,
    #[error(transparent)]
    Start(#[from] StartError),
    #[error("a sequence robot needs `start`: the input that starts a cycle")]
    NoStart,
    #[error(transparent)]
    Address(#[from] AddressError),
    #[error("unknown actuator `{0}`")]
    UnknownActuator(String),
    #[error("unknown input `{0}`")]
    UnknownInput(String),
    #[error("actuator {0} is not declared")]
    Undeclared(String),
    #[error("no timer {actuator}.{kind}")]
    NoTimer {
        actuator: String,
        kind: &'static str,
    },
    #[error("{0}: no timer for its motion")]
    NoMotionTimer(String),
    #[error(transparent)]
    Homing(#[from] crate::homing::DeriveError),
}

/// Synthesises the charts of a sequence robot. The robot must have passed `check`.
pub fn synthesise(robot: &Robot, steps: &[Step]) -> Result<Ir, SynthError> {
    let seq = Sequence::of(robot, steps)?;
    let roles = (0..robot.roles.len())
        .map(|ri| seq.role(ri))
        .collect::<Result<Vec<_>, _>>()?;
    let mut ir = Ir {
        name: robot.name.clone(),
        generation: robot.generation,
        pan_id: robot.network.pan_id,
        channel: robot.network.channel,
        roles,
        start: Some((seq.start_role, seq.start_input.clone())),
        expect: steps.to_vec(),
        home: None,
        homing: Vec::new(),
        homing_derived: false,
    };
    homing::add(&seq, &mut ir)?;
    Ok(ir)
}

/// What every role's synthesis shares: the steps, where START is, and how the START gate
/// (module doc) reopens.
struct Sequence<'a> {
    robot: &'a Robot,
    steps: &'a [Step],
    /// The role and input of the START button.
    start_role: usize,
    start_input: String,
    /// The role of step 1's actuator.
    first_role: usize,
    /// Whether START is on another role than step 1's (gated there; step 1's chart
    /// emits `cycle.done` when back in `IDLE`).
    gated: bool,
}

impl<'a> Sequence<'a> {
    fn of(robot: &'a Robot, steps: &'a [Step]) -> Result<Sequence<'a>, SynthError> {
        let n = steps.len();
        if n == 0 {
            return Err(SynthError::NoSteps);
        }
        let (start_role, start_input) =
            crate::elab::start_input(robot)?.ok_or(SynthError::NoStart)?;
        let first_role = robot
            .actuator(&steps[0].actuator)
            .map(|(r, _)| r)
            .ok_or_else(|| SynthError::UnknownActuator(steps[0].actuator.clone()))?;
        let gated = start_role != first_role;
        Ok(Sequence {
            robot,
            steps,
            start_role,
            start_input,
            first_role,
            gated,
        })
    }

    /// The role of step `k`'s actuator (the cycle wraps around).
    fn role_of(&self, k: usize) -> Option<usize> {
        let n = self.steps.len();
        self.robot
            .actuator(&self.steps[k % n].actuator)
            .map(|(r, _)| r)
    }

    /// Whether role `q` has an actuator that moves in the sequence.
    fn moves_in(&self, q: usize) -> bool {
        moving_in(self.robot, q, self.steps)
    }

    /// Whether an actuator moves in the sequence.
    fn moves(&self, a: &Actuator) -> bool {
        self.steps.iter().any(|s| s.actuator == a.name)
    }

    /// Role `ri`'s IR: the hardware and timers of its moving actuators, the START button,
    /// one chart per moving actuator, the fault chart and the START gate.
    fn role(&self, ri: usize) -> Result<RoleIr, SynthError> {
        let robot = self.robot;
        let role = &robot.roles[ri];
        let mut r = RoleIr {
            name: role.name.clone(),
            address: crate::elab::address(robot, &role.name)?,
            ..RoleIr::default()
        };
        let moving: Vec<&Actuator> = role.actuators.iter().filter(|a| self.moves(a)).collect();
        for a in &moving {
            let first = r.inputs.len();
            r.declare_actuator(a, |_| true, |_| false);
            for i in first..r.inputs.len() {
                let name = r.inputs[i].name.clone();
                r.event(&name);
            }
        }
        // Its lamps and other plain outputs: no chart drives them, the node does on a
        // fault, at start and by homing.
        r.declare_plain_outputs(role);
        if self.start_role == ri {
            self.start_button(&mut r, role)?;
        }
        let timers: Vec<Timers> = moving.iter().map(|a| Timers::add(&mut r, a)).collect();
        if ri == self.first_role {
            self.cycle_start(&mut r);
        }
        for (a, timers) in moving.iter().zip(timers) {
            let motion = Motion::of(robot, &r, a, timers)?;
            let mut chart = actuator_chart(&mut r, &motion, self.steps, &self.start_input)?;
            if self.gated && a.name == self.steps[0].actuator {
                // Back in IDLE: tell the button's role that a press may start a cycle.
                if let Some(idle) = chart.states.first_mut() {
                    idle.actions
                        .push(ActionIr::Emit(String::from(CYCLE_DONE_EVENT)));
                }
                r.event(CYCLE_DONE_EVENT);
            }
            r.charts.push(chart);
        }
        self.step_imports(&mut r, ri)?;
        if !moving.is_empty() {
            self.fault_chart(&mut r, ri);
        }
        if self.gated && ri == self.start_role {
            start_chart(robot, &mut r, &self.start_input, self.first_role);
        }
        plant_inputs(robot, role, &mut r);
        // Register route events (emitted and imported) in a stable order.
        for (e, _, _) in r.routes.clone() {
            r.event(&e);
        }
        Ok(r)
    }

    /// The START button's input, on the button's role.
    fn start_button(&self, r: &mut RoleIr, role: &Role) -> Result<(), SynthError> {
        button(r, role, &self.start_input)
    }

    /// What starts a cycle on step 1's role: START itself, or the gate's `cycle.start`.
    fn cycle_start(&self, r: &mut RoleIr) {
        if self.gated {
            r.event(&self.start_input);
            r.imports.push((
                self.robot.roles[self.start_role].name.clone(),
                String::from(CYCLE_START_EVENT),
                self.start_input.clone(),
            ));
        } else {
            r.start = Some(self.start_input.clone());
        }
    }

    /// Imports of the step events role `ri`'s charts wait for from other roles, in step
    /// order.
    fn step_imports(&self, r: &mut RoleIr, ri: usize) -> Result<(), SynthError> {
        let routed: Vec<String> = r.routes.iter().map(|(e, _, _)| e.clone()).collect();
        for (k, step) in self.steps.iter().enumerate() {
            let ev = done_event(k);
            if routed.contains(&ev) && self.role_of(k) != Some(ri) {
                let from = self
                    .role_of(k)
                    .ok_or_else(|| SynthError::UnknownActuator(step.actuator.clone()))?;
                r.imports
                    .push((self.robot.roles[from].name.clone(), ev.clone(), ev));
            }
        }
        Ok(())
    }

    /// The fault chart of a role with moving actuators: a watchdog expiry faults the node
    /// and publishes `fault` to every other role; a peer's `fault` faults this node too
    /// (stop at once). None if the role has no watchdog and no peer can fault.
    fn fault_chart(&self, r: &mut RoleIr, ri: usize) {
        let robot = self.robot;
        let watchdogs: Vec<String> = r
            .timers
            .iter()
            .filter(|t| t.name.ends_with(".watchdog"))
            .map(|t| t.event.clone())
            .collect();
        let detectors: Vec<usize> = (0..robot.roles.len())
            .filter(|&q| {
                q != ri && moving_in(robot, q, self.steps) && switched_in(robot, q, self.steps)
            })
            .collect();
        if watchdogs.is_empty() && detectors.is_empty() {
            return;
        }
        let c = r.charts.len();
        let mut inputs = Vec::new();
        let mut states = vec![StateIr {
            name: String::from("RUN"),
            actions: vec![],
        }];
        let mut transitions = Vec::new();
        if !watchdogs.is_empty() {
            r.event(FAULT_EVENT);
            for w in watchdogs {
                r.routes.push((w, c, inputs.len()));
            }
            transitions.push(TransitionIr {
                from: 0,
                to: states.len(),
                trigger: Some(inputs.len()),
                guard: None,
            });
            inputs.push(String::from("timeout"));
            states.push(StateIr {
                name: String::from("TIMEOUT"),
                actions: vec![
                    ActionIr::Emit(String::from(FAULT_EVENT)),
                    ActionIr::Fault(FAULT_MOTION_TIMEOUT),
                ],
            });
        }
        if !detectors.is_empty() {
            for q in detectors {
                r.imports.push((
                    robot.roles[q].name.clone(),
                    String::from(FAULT_EVENT),
                    String::from(PEER_FAULT_EVENT),
                ));
            }
            r.routes
                .push((String::from(PEER_FAULT_EVENT), c, inputs.len()));
            transitions.push(TransitionIr {
                from: 0,
                to: states.len(),
                trigger: Some(inputs.len()),
                guard: None,
            });
            inputs.push(String::from("peer"));
            states.push(StateIr {
                name: String::from("PEER_FAULT"),
                actions: vec![ActionIr::Fault(FAULT_PEER)],
            });
        }
        r.charts.push(ChartIr {
            name: String::from("fault"),
            inputs,
            initial: 0,
            idle: 0,
            rests: Vec::new(),
            states,
            transitions,
        });
    }
}

/// The START chart of the button's role when step 1 is another role's (module doc):
/// `SHUT` -(`cycle.done`)-> `IDLE` -(START)-> `CYCLE` [emit `cycle.start`] -(`cycle.done`)->
/// `IDLE`. It starts shut (after a boot or a reset the machine is not homed) and rests
/// open (a table activated at rest is idle).
fn start_chart(robot: &Robot, r: &mut RoleIr, start_input: &str, first: usize) {
    let c = r.charts.len();
    r.start = Some(start_input.to_string());
    r.event(CYCLE_START_EVENT);
    r.imports.push((
        robot.roles[first].name.clone(),
        String::from(CYCLE_DONE_EVENT),
        String::from(CYCLE_DONE_EVENT),
    ));
    r.routes.push((start_input.to_string(), c, 0));
    r.routes.push((String::from(CYCLE_DONE_EVENT), c, 1));
    r.charts.push(ChartIr {
        name: start_input.to_string(),
        inputs: vec![String::from("press"), String::from("done")],
        initial: 2,
        idle: 0,
        rests: Vec::new(),
        states: vec![
            StateIr {
                name: String::from("IDLE"),
                actions: vec![],
            },
            StateIr {
                name: String::from("CYCLE"),
                actions: vec![ActionIr::Emit(String::from(CYCLE_START_EVENT))],
            },
            StateIr {
                name: String::from("SHUT"),
                actions: vec![],
            },
        ],
        transitions: vec![
            TransitionIr {
                from: 2,
                to: 0,
                trigger: Some(1),
                guard: None,
            },
            TransitionIr {
                from: 0,
                to: 1,
                trigger: Some(0),
                guard: None,
            },
            TransitionIr {
                from: 1,
                to: 0,
                trigger: Some(1),
                guard: None,
            },
        ],
    });
}

/// Declares button `name` of `role` (START, HOME) in its IR `r`, once: an input whose
/// rising edge raises the node event of the same name.
fn button(r: &mut RoleIr, role: &Role, name: &str) -> Result<(), SynthError> {
    let pin = role
        .inputs
        .iter()
        .find(|i| i.name == name)
        .map(|i| i.pin)
        .ok_or_else(|| SynthError::UnknownInput(name.to_string()))?;
    r.event(name);
    if !r.inputs.iter().any(|i| i.name == name) {
        r.inputs.push(InputIr {
            name: name.to_string(),
            pin,
            rise: Some(name.to_string()),
            fall: None,
            var: None,
        });
    }
    Ok(())
}

/// The inputs of `role` that a declared plant drives and the charts do not read (a door
/// button wired and not yet used): declared without an event, so that the node reads the
/// pin and `sim` and `verify` find the plant's input.
fn plant_inputs(robot: &Robot, role: &Role, r: &mut RoleIr) {
    for p in robot.plants.iter().filter(|p| p.role() == role.name) {
        for (_, pin, output) in p.pins() {
            let declared = role.inputs.iter().find(|i| i.name == pin);
            if let (false, Some(i)) = (output, declared) {
                if !r.inputs.iter().any(|x| x.name == i.name) {
                    r.inputs.push(InputIr {
                        name: i.name.clone(),
                        pin: i.pin,
                        rise: None,
                        fall: None,
                        var: None,
                    });
                }
            }
        }
    }
}

/// The timers of one actuator's chart (indices into the role's `timers`).
struct Timers {
    watchdog: Option<usize>,
    dwell: Option<usize>,
}

impl Timers {
    /// Adds a moving actuator's watchdog and dwell timers to its role, if it has them.
    fn add(r: &mut RoleIr, a: &Actuator) -> Timers {
        let mut timer = |has: bool, kind: &str| {
            has.then(|| {
                let name = format!("{}.{kind}", a.name);
                r.event(&name);
                r.timers.push(TimerIr {
                    name: name.clone(),
                    event: name,
                });
                r.timers.len() - 1
            })
        };
        let watchdog = timer(a.kind.has_watchdog(), "watchdog");
        let dwell = timer(a.kind.has_dwell(), "dwell");
        Timers { watchdog, dwell }
    }
}

/// How an actuator is driven and how its motions complete.
struct Motion {
    name: String,
    /// Its outputs, and their values for `+` and `-`.
    mask: u16,
    plus: u16,
    minus: u16,
    /// The motion watchdog (timer, ms), if some motion completes on a switch.
    watchdog: Option<(usize, u32)>,
    /// The dwell timer (timer, ms), if some motion completes after a time.
    dwell: Option<(usize, u32)>,
    /// Which motions complete on a switch: (`+`, `-`).
    switched: (bool, bool),
}

impl Motion {
    fn of(robot: &Robot, r: &RoleIr, a: &Actuator, timers: Timers) -> Result<Motion, SynthError> {
        let wiring = r
            .actuator(&a.name)
            .ok_or_else(|| SynthError::Undeclared(a.name.clone()))?;
        let ((mask, plus), (_, minus)) = (wiring.drive(true), wiring.drive(false));
        let dwell_ms = match a.kind {
            ActuatorKind::DoubleActing { .. } => 0,
            ActuatorKind::SingleActing { dwell_ms, .. } => dwell_ms,
        };
        let timer = |t: Option<usize>, kind: &'static str| {
            t.ok_or_else(|| SynthError::NoTimer {
                actuator: a.name.clone(),
                kind,
            })
        };
        let timeout_ms = a.kind.timeout_ms().unwrap_or(robot.motion_timeout_ms);
        Ok(Motion {
            name: a.name.clone(),
            mask,
            plus,
            minus,
            watchdog: match a.kind.has_watchdog() {
                true => Some((timer(timers.watchdog, "watchdog")?, timeout_ms)),
                false => None,
            },
            dwell: match a.kind.has_dwell() {
                true => Some((timer(timers.dwell, "dwell")?, dwell_ms)),
                false => None,
            },
            switched: (
                a.kind.completion_switch(true).is_some(),
                a.kind.completion_switch(false).is_some(),
            ),
        })
    }

    /// Drives a `+` (extend) or `-` motion: both solenoids of a bistable valve at once.
    fn drive(&self, extend: bool) -> ActionIr {
        ActionIr::Drive {
            mask: self.mask,
            value: if extend { self.plus } else { self.minus },
            label: format!("{}{}", self.name, if extend { '+' } else { '-' }),
        }
    }

    /// Whether a `+` (or `-`) completes on a switch (under the watchdog).
    fn is_switched(&self, extend: bool) -> bool {
        if extend {
            self.switched.0
        } else {
            self.switched.1
        }
    }

    /// The timer a motion starts: its watchdog (switched) or its dwell timer.
    fn timer(&self, extend: bool) -> Result<(usize, u32), SynthError> {
        match self.is_switched(extend) {
            true => self.watchdog,
            false => self.dwell,
        }
        .ok_or_else(|| SynthError::NoMotionTimer(self.name.clone()))
    }

    /// The watchdog to cancel once a motion is complete (a dwell timer has expired).
    fn cancel(&self, extend: bool) -> Option<ActionIr> {
        self.watchdog
            .filter(|_| self.is_switched(extend))
            .map(|(t, _)| ActionIr::CancelTimer(t))
    }

    /// The chart input that says a motion is complete.
    fn completion(&self, extend: bool) -> &'static str {
        match (self.is_switched(extend), extend) {
            (true, true) => "end",
            (true, false) => "home",
            (false, _) => "dwell",
        }
    }
}

/// The event that says step `k` (0-based) is complete: `step{k+1}.done`.
pub fn done_event(k: usize) -> String {
    format!("step{}.done", k + 1)
}

/// Actuator `motion`'s chart (module doc): `IDLE` or `WAITk` first, then per own step k
/// `STEPk`, and after the last own step of a run either `WAITk'` (this actuator's next
/// step k'), `CYCLE_END` or straight back to the first state.
fn actuator_chart(
    r: &mut RoleIr,
    motion: &Motion,
    steps: &[Step],
    start_input: &str,
) -> Result<ChartIr, SynthError> {
    let own: Vec<usize> = (0..steps.len())
        .filter(|&k| steps[k].actuator == motion.name)
        .collect();
    let owns_first = own[0] == 0;
    let first = if owns_first {
        String::from("IDLE")
    } else {
        format!("WAIT{}", own[0] + 1)
    };
    let mut b = ChartBuilder {
        motion,
        steps,
        inputs: Vec::new(),
        routes: Vec::new(),
        states: vec![StateIr {
            name: first,
            actions: vec![],
        }],
        transitions: Vec::new(),
    };
    let (mut wait_state, mut prev_move) = (0usize, 0usize);
    for (j, &k) in own.iter().enumerate() {
        let back_to_back = j > 0 && own[j - 1] + 1 == k;
        let from = if back_to_back { prev_move } else { wait_state };
        let move_state = b.enter(k, back_to_back, from, start_input)?;
        prev_move = move_state;
        match own.get(j + 1).copied() {
            Some(next) if next == k + 1 => {}
            next => {
                if let Some(wait) = b.complete(k, move_state, next, owns_first) {
                    wait_state = wait;
                }
            }
        }
    }
    Ok(b.finish(r))
}

/// One actuator's chart as it is built: its inputs (each with the node event routed to
/// it), states and transitions.
struct ChartBuilder<'a> {
    motion: &'a Motion,
    steps: &'a [Step],
    inputs: Vec<String>,
    /// (node event, chart input), in the order the inputs were added.
    routes: Vec<(String, String)>,
    states: Vec<StateIr>,
    transitions: Vec<TransitionIr>,
}

impl ChartBuilder<'_> {
    /// The chart input `name` (raised by node event `event`), added if new.
    fn input(&mut self, name: &str, event: String) -> usize {
        match self.inputs.iter().position(|i| i == name) {
            Some(i) => i,
            None => {
                self.inputs.push(name.to_string());
                self.routes.push((event, name.to_string()));
                self.inputs.len() - 1
            }
        }
    }

    /// The input that says step `k`'s motion is complete (`end`, `home` or `dwell`).
    fn completion(&mut self, k: usize) -> usize {
        let c = self.motion.completion(self.steps[k].extend);
        self.input(c, format!("{}.{c}", self.motion.name))
    }

    fn state(&mut self, name: String, actions: Vec<ActionIr>) -> usize {
        self.states.push(StateIr { name, actions });
        self.states.len() - 1
    }

    fn go(&mut self, from: usize, to: usize, trigger: usize) {
        self.transitions.push(TransitionIr {
            from,
            to,
            trigger: Some(trigger),
            guard: None,
        });
    }

    /// The actions of leaving step `k` for another actuator's step: cancel the watchdog,
    /// emit `stepk.done`.
    fn leave(&self, k: usize) -> Vec<ActionIr> {
        let mut v: Vec<ActionIr> = self
            .motion
            .cancel(self.steps[k].extend)
            .into_iter()
            .collect();
        v.push(ActionIr::Emit(done_event(k)));
        v
    }

    /// Adds `STEPk` (drive, start its timer) and the transition into it from `from`: on
    /// the previous motion's completion (`back_to_back`: step k-1 is this actuator's
    /// too), on START (step 1) or on `stepk-1.done`. Returns `STEPk`.
    fn enter(
        &mut self,
        k: usize,
        back_to_back: bool,
        from: usize,
        start_input: &str,
    ) -> Result<usize, SynthError> {
        let (motion, step) = (self.motion, &self.steps[k]);
        let (timer, ms) = motion.timer(step.extend)?;
        let mut actions = vec![motion.drive(step.extend)];
        // Straight on from a switched motion to a timed one: its watchdog is still armed.
        if back_to_back && !motion.is_switched(step.extend) {
            actions.extend(motion.cancel(self.steps[k - 1].extend));
        }
        actions.push(ActionIr::StartTimer { timer, ms });
        let move_state = self.state(format!("STEP{}", k + 1), actions);
        let trigger = if back_to_back {
            self.completion(k - 1)
        } else if k == 0 {
            self.input("start", start_input.to_string())
        } else {
            self.input(&done_event(k - 1), done_event(k - 1))
        };
        self.go(from, move_state, trigger);
        Ok(move_state)
    }

    /// Leaves `STEPk` (`move_state`) on its motion's completion: to `WAITnext` if this
    /// actuator has a later step `next` (returned), else back to the first state,
    /// through `CYCLE_END` when this chart starts the cycle and another actuator ends it.
    fn complete(
        &mut self,
        k: usize,
        move_state: usize,
        next: Option<usize>,
        owns_first: bool,
    ) -> Option<usize> {
        let n = self.steps.len();
        let trigger = self.completion(k);
        match next {
            Some(next) => {
                let actions = self.leave(k);
                let wait = self.state(format!("WAIT{}", next + 1), actions);
                self.go(move_state, wait, trigger);
                return Some(wait);
            }
            None if owns_first && k == n - 1 => {
                // Last step of the cycle and the first of the next are this actuator's.
                let cancel = self.motion.cancel(self.steps[k].extend);
                self.states[0].actions.extend(cancel);
                self.go(move_state, 0, trigger);
            }
            None if owns_first => {
                let actions = self.leave(k);
                let end = self.state(String::from("CYCLE_END"), actions);
                self.go(move_state, end, trigger);
                let last = done_event(n - 1);
                let t = self.input(&last, last.clone());
                self.go(end, 0, t);
            }
            None => {
                self.states[0].actions = self.leave(k);
                self.go(move_state, 0, trigger);
            }
        }
        None
    }

    /// The chart, as the role's next; its emitted events and routes are registered in
    /// the role (emitted events first: stable ids).
    fn finish(self, r: &mut RoleIr) -> ChartIr {
        let chart_index = r.charts.len();
        for s in &self.states {
            for act in &s.actions {
                if let ActionIr::Emit(e) = act {
                    r.event(e);
                }
            }
        }
        for (event, name) in self.routes {
            let i = self.inputs.iter().position(|x| *x == name).unwrap_or(0);
            r.routes.push((event, chart_index, i));
        }
        ChartIr {
            name: self.motion.name.clone(),
            inputs: self.inputs,
            initial: 0,
            idle: 0,
            rests: Vec::new(),
            states: self.states,
            transitions: self.transitions,
        }
    }
}
