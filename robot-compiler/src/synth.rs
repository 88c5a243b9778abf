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
//! button's role gates it: `IDLE` -(press)-> `CYCLE` (emit `cycle.start`, published to
//! step 1's role) -(the cycle is over)-> `IDLE`. A press during a cycle costs nothing. The
//! cycle is over for the button's role when step 1's chart is back in `IDLE`: it then
//! emits `cycle.done` to the button's role, unless the last step is the button role's own
//! (its `stepN.done` reaches step 1's role on the same link before the next
//! `cycle.start`, so that local event reopens the gate for free).
//! A watchdog timeout raises fault 1 through a small per-role `fault` chart, which also
//! publishes `fault` to every other role; receiving a peer's `fault` raises fault 2. So a
//! fault anywhere stops every node at once (outputs safe) until a reset.

use crate::ir::{ActionIr, ChartIr, InputIr, Ir, RoleIr, StateIr, Step, TimerIr, TransitionIr};
use crate::model::{ActuatorKind, Robot};

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

/// Synthesises the charts of a sequence robot. The robot must have passed `check`.
pub fn synthesise(robot: &Robot, steps: &[Step]) -> Result<Ir, String> {
    let n = steps.len();
    if n == 0 {
        return Err(String::from("the sequence has no steps"));
    }
    let (start_role, start_input) = crate::elab::start_input(robot)?.ok_or_else(|| {
        String::from("a sequence robot needs `start`: the input that starts a cycle")
    })?;
    let first_role = robot
        .actuator(&steps[0].actuator)
        .map(|(r, _)| r)
        .ok_or_else(|| format!("unknown actuator `{}`", steps[0].actuator))?;
    let role_of = |k: usize| robot.actuator(&steps[k % n].actuator).map(|(r, _)| r);
    // START on another role than step 1's is gated there (module doc). Its gate reopens
    // on the local `stepN.done` if the last step is that role's, else on `cycle.done`.
    let gated = start_role != first_role;
    let reopen = if role_of(n - 1) == Some(start_role) {
        done_event(n - 1)
    } else {
        String::from(CYCLE_DONE_EVENT)
    };
    let cycle_done = gated && reopen == CYCLE_DONE_EVENT;

    let mut roles = Vec::new();
    for (ri, role) in robot.roles.iter().enumerate() {
        let mut r = RoleIr {
            name: role.name.clone(),
            address: crate::elab::address(robot, &role.name)?,
            ..RoleIr::default()
        };
        // Hardware of the actuators that move.
        let moving: Vec<_> = role
            .actuators
            .iter()
            .filter(|a| steps.iter().any(|s| s.actuator == a.name))
            .collect();
        for a in &moving {
            let first = r.inputs.len();
            r.declare_actuator(a, |_| true, |_| false);
            for i in first..r.inputs.len() {
                let name = r.inputs[i].name.clone();
                r.event(&name);
            }
        }
        if start_role == ri {
            let pin = role
                .inputs
                .iter()
                .find(|i| i.name == start_input)
                .map(|i| i.pin)
                .ok_or_else(|| format!("unknown input `{start_input}`"))?;
            r.event(&start_input);
            r.inputs.push(InputIr {
                name: start_input.clone(),
                pin,
                rise: Some(start_input.clone()),
                fall: None,
                var: None,
            });
        }
        // Per moving actuator: its watchdog and dwell timers, if it has them.
        let mut timers = Vec::new();
        for a in &moving {
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
            timers.push(Timers { watchdog, dwell });
        }
        if ri == first_role {
            if gated {
                r.event(&start_input);
                r.imports.push((
                    robot.roles[start_role].name.clone(),
                    String::from(CYCLE_START_EVENT),
                    start_input.clone(),
                ));
            } else {
                r.start = Some(start_input.clone());
            }
        }
        // One chart per moving actuator.
        for (a, timers) in moving.iter().zip(timers) {
            let motion = Motion::of(robot, &r, a, timers)?;
            let mut chart = actuator_chart(&mut r, &motion, steps, &start_input)?;
            if cycle_done && a.name == steps[0].actuator {
                // Back in IDLE: tell the button's role that a press may start a cycle.
                if let Some(idle) = chart.states.first_mut() {
                    idle.actions
                        .push(ActionIr::Emit(String::from(CYCLE_DONE_EVENT)));
                }
                r.event(CYCLE_DONE_EVENT);
            }
            r.charts.push(chart);
        }
        // Imports of step events from other roles, in step order.
        let routed: Vec<String> = r.routes.iter().map(|(e, _, _)| e.clone()).collect();
        for (k, step) in steps.iter().enumerate() {
            let ev = done_event(k);
            if routed.contains(&ev) && role_of(k) != Some(ri) {
                let from =
                    role_of(k).ok_or_else(|| format!("unknown actuator `{}`", step.actuator))?;
                r.imports
                    .push((robot.roles[from].name.clone(), ev.clone(), ev));
            }
        }
        // The fault chart: a watchdog expiry faults the node and publishes `fault` to
        // every other role; a peer's `fault` faults this node too (stop at once).
        let watchdogs: Vec<String> = r
            .timers
            .iter()
            .filter(|t| t.name.ends_with(".watchdog"))
            .map(|t| t.event.clone())
            .collect();
        let detectors: Vec<usize> = (0..robot.roles.len())
            .filter(|&q| q != ri && moving_in(robot, q, steps) && switched_in(robot, q, steps))
            .collect();
        if !moving.is_empty() && (!watchdogs.is_empty() || !detectors.is_empty()) {
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
                states,
                transitions,
            });
        }
        if gated && ri == start_role {
            start_chart(robot, &mut r, &start_input, &reopen, first_role);
        }
        // Register route events (emitted and imported) in a stable order.
        for (e, _, _) in r.routes.clone() {
            r.event(&e);
        }
        roles.push(r);
    }
    Ok(Ir {
        name: robot.name.clone(),
        generation: robot.generation,
        pan_id: robot.network.pan_id,
        channel: robot.network.channel,
        roles,
        start: Some((start_role, start_input)),
        expect: steps.to_vec(),
    })
}

/// The START chart of the button's role when step 1 is another role's (module doc):
/// `IDLE` -(START)-> `CYCLE` [emit `cycle.start`] -(`reopen`)-> `IDLE`.
fn start_chart(robot: &Robot, r: &mut RoleIr, start_input: &str, reopen: &str, first: usize) {
    let c = r.charts.len();
    r.start = Some(start_input.to_string());
    r.event(CYCLE_START_EVENT);
    if reopen == CYCLE_DONE_EVENT {
        r.imports.push((
            robot.roles[first].name.clone(),
            String::from(CYCLE_DONE_EVENT),
            String::from(CYCLE_DONE_EVENT),
        ));
    }
    r.routes.push((start_input.to_string(), c, 0));
    r.routes.push((reopen.to_string(), c, 1));
    r.charts.push(ChartIr {
        name: start_input.to_string(),
        inputs: vec![String::from("press"), String::from("done")],
        initial: 0,
        states: vec![
            StateIr {
                name: String::from("IDLE"),
                actions: vec![],
            },
            StateIr {
                name: String::from("CYCLE"),
                actions: vec![ActionIr::Emit(String::from(CYCLE_START_EVENT))],
            },
        ],
        transitions: vec![
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

/// The timers of one actuator's chart (indices into the role's `timers`).
struct Timers {
    watchdog: Option<usize>,
    dwell: Option<usize>,
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
    fn of(
        robot: &Robot,
        r: &RoleIr,
        a: &crate::model::Actuator,
        timers: Timers,
    ) -> Result<Motion, String> {
        let wiring = r
            .actuator(&a.name)
            .ok_or_else(|| format!("actuator {} is not declared", a.name))?;
        let ((mask, plus), (_, minus)) = (wiring.drive(true), wiring.drive(false));
        let dwell_ms = match a.kind {
            ActuatorKind::DoubleActing { .. } => 0,
            ActuatorKind::SingleActing { dwell_ms, .. } => dwell_ms,
        };
        let timer =
            |t: Option<usize>, kind: &str| t.ok_or_else(|| format!("no timer {}.{kind}", a.name));
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
    fn timer(&self, extend: bool) -> Result<(usize, u32), String> {
        match self.is_switched(extend) {
            true => self.watchdog,
            false => self.dwell,
        }
        .ok_or_else(|| format!("{}: no timer for its motion", self.name))
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

fn actuator_chart(
    r: &mut RoleIr,
    motion: &Motion,
    steps: &[Step],
    start_input: &str,
) -> Result<ChartIr, String> {
    let n = steps.len();
    let own: Vec<usize> = (0..n)
        .filter(|&k| steps[k].actuator == motion.name)
        .collect();
    let chart_index = r.charts.len();
    let mut inputs: Vec<String> = Vec::new();
    let mut routes: Vec<(String, String)> = Vec::new(); // (node event, chart input)
    let mut input = |name: &str, event: String| -> usize {
        match inputs.iter().position(|i| i == name) {
            Some(i) => i,
            None => {
                inputs.push(name.to_string());
                routes.push((event, name.to_string()));
                inputs.len() - 1
            }
        }
    };
    let owns_first = own[0] == 0;
    let mut states = vec![StateIr {
        name: if owns_first {
            String::from("IDLE")
        } else {
            format!("WAIT{}", own[0] + 1)
        },
        actions: vec![],
    }];
    let mut transitions = Vec::new();
    let mut wait_state = 0usize;
    let mut prev_move = 0usize;
    let leave = |k: usize| -> Vec<ActionIr> {
        let mut v: Vec<ActionIr> = motion.cancel(steps[k].extend).into_iter().collect();
        v.push(ActionIr::Emit(done_event(k)));
        v
    };
    for (j, &k) in own.iter().enumerate() {
        let step = &steps[k];
        let move_state = states.len();
        let back_to_back = j > 0 && own[j - 1] + 1 == k;
        let (timer, ms) = motion.timer(step.extend)?;
        let mut actions = vec![motion.drive(step.extend)];
        // Straight on from a switched motion to a timed one: its watchdog is still armed.
        if back_to_back && !motion.is_switched(step.extend) {
            actions.extend(motion.cancel(steps[k - 1].extend));
        }
        actions.push(ActionIr::StartTimer { timer, ms });
        states.push(StateIr {
            name: format!("STEP{}", k + 1),
            actions,
        });
        if back_to_back {
            let prev = &steps[k - 1];
            let c = motion.completion(prev.extend);
            let trig = input(c, format!("{}.{c}", motion.name));
            transitions.push(TransitionIr {
                from: prev_move,
                to: move_state,
                trigger: Some(trig),
                guard: None,
            });
        } else {
            let (name, event) = if k == 0 {
                ("start".to_string(), start_input.to_string())
            } else {
                (done_event(k - 1), done_event(k - 1))
            };
            let trig = input(&name, event);
            transitions.push(TransitionIr {
                from: wait_state,
                to: move_state,
                trigger: Some(trig),
                guard: None,
            });
        }
        prev_move = move_state;
        let next_own = own.get(j + 1).copied();
        if next_own == Some(k + 1) {
            continue;
        }
        let c = motion.completion(step.extend);
        let trig = input(c, format!("{}.{c}", motion.name));
        if let Some(k2) = next_own {
            let wait = states.len();
            states.push(StateIr {
                name: format!("WAIT{}", k2 + 1),
                actions: leave(k),
            });
            transitions.push(TransitionIr {
                from: move_state,
                to: wait,
                trigger: Some(trig),
                guard: None,
            });
            wait_state = wait;
        } else if owns_first && k == n - 1 {
            // Last step of the cycle and the first of the next are this actuator's.
            states[0].actions.extend(motion.cancel(step.extend));
            transitions.push(TransitionIr {
                from: move_state,
                to: 0,
                trigger: Some(trig),
                guard: None,
            });
        } else if owns_first {
            let end = states.len();
            states.push(StateIr {
                name: String::from("CYCLE_END"),
                actions: leave(k),
            });
            transitions.push(TransitionIr {
                from: move_state,
                to: end,
                trigger: Some(trig),
                guard: None,
            });
            let last = done_event(n - 1);
            let t = input(&last, last.clone());
            transitions.push(TransitionIr {
                from: end,
                to: 0,
                trigger: Some(t),
                guard: None,
            });
        } else {
            states[0].actions = leave(k);
            transitions.push(TransitionIr {
                from: move_state,
                to: 0,
                trigger: Some(trig),
                guard: None,
            });
        }
    }
    // Emitted events become node events before routes (stable ids).
    for s in &states {
        for act in &s.actions {
            if let ActionIr::Emit(e) = act {
                r.event(e);
            }
        }
    }
    for (event, name) in routes {
        let i = inputs.iter().position(|x| *x == name).unwrap_or(0);
        r.routes.push((event, chart_index, i));
    }
    Ok(ChartIr {
        name: motion.name.clone(),
        inputs,
        initial: 0,
        states,
        transitions,
    })
}
