//! The homing charts of a sequence robot (docs/reconfiguration.md).
//!
//! Step 1's chart coordinates: it starts in `UNHOMED` (a boot, a reset, an activation of
//! a stopped machine), where a START does nothing; HOME (the command, or the HOME input)
//! takes it, from `UNHOMED` or from `IDLE`, to `HOMING`, which emits `home.start`; the
//! last homing step's `home.done` takes it to `IDLE`. HOME during a cycle does nothing.
//!
//! Each role with homing steps gets a `home` chart: `WAIT`, then per own step k
//! `HOMINGk` (drive the step's level, start its watchdog or dwell timer) and `HOMEDk`
//! (cancel the watchdog, emit `homek.done`, or `home.done` after the last step). Step k
//! starts on `home.start` (k = 1) or `home{k-1}.done`; a step whose switch already reads
//! its target goes straight to `HOMEDk`. The chart is back in `WAIT` after its last
//! step, so every chart ends homing in its idle state.

use crate::homing;
use crate::ir::{ActionIr, ChartIr, Ir, RoleIr, StateIr, Step, TransitionIr};
use crate::model::Robot;

use super::{Motion, Sequence, SynthError, Timers};

/// The event step 1's chart emits to start the homing steps.
pub const HOME_START_EVENT: &str = "home.start";
/// The event the last homing step emits.
pub const HOME_DONE_EVENT: &str = "home.done";
/// The event a node raises and publishes to step 1's role when it boots with its table.
pub const BOOT_EVENT: &str = "boot";
/// The event another node's boot raises on step 1's role.
pub const PEER_BOOT_EVENT: &str = "peer.boot";
/// The event the boot of the START button's node raises on step 1's role when that
/// button's role moves nothing (a panel): step 1's chart, idle, then reopens the gate.
pub const BUTTON_BOOT_EVENT: &str = "button.boot";
/// The event the HOME command raises when the robot declares no HOME input.
pub const HOME_COMMAND_EVENT: &str = "home";

/// The event that says homing step `k` (0-based) is complete.
pub fn home_done_event(k: usize, n: usize) -> String {
    if k + 1 == n {
        String::from(HOME_DONE_EVENT)
    } else {
        format!("home{}.done", k + 1)
    }
}

/// The event that starts homing step `k`.
fn home_trigger_event(k: usize, n: usize) -> String {
    if k == 0 {
        String::from(HOME_START_EVENT)
    } else {
        home_done_event(k - 1, n)
    }
}

/// The events homing sends (none during a cycle): `home.start`, each step's done event,
/// the HOME input's when it is published to step 1's role, and a node's boot.
pub fn homing_events(ir: &Ir) -> Vec<String> {
    let n = ir.homing.len();
    let mut out = vec![String::from(HOME_START_EVENT), String::from(BOOT_EVENT)];
    out.extend((0..n).map(|k| home_done_event(k, n)));
    if let Some(e) = ir.home.and_then(|r| ir.roles.get(r)?.home.clone()) {
        out.push(e);
    }
    out
}

/// The robot's homing steps: declared, or derived from the actuators and interlocks.
fn plan(robot: &Robot, ir: &Ir) -> Result<(Vec<Step>, bool), SynthError> {
    match &robot.homing {
        Some(text) => Ok((
            crate::ir::parse_steps(text)
                .into_iter()
                .filter_map(|(s, _)| s.ok())
                .collect(),
            false,
        )),
        None => {
            let locks = homing::resolved_interlocks(robot, ir);
            Ok((homing::derive(robot, ir, &locks)?, true))
        }
    }
}

/// Adds homing to the synthesised cycle `ir` (module doc).
pub(super) fn add(seq: &Sequence<'_>, ir: &mut Ir) -> Result<(), SynthError> {
    let robot = seq.robot;
    let (steps, derived) = plan(robot, ir)?;
    let n = steps.len();
    let role_of = |k: usize| -> Result<usize, SynthError> {
        robot
            .actuator(&steps[k].actuator)
            .map(|(r, _)| r)
            .ok_or_else(|| SynthError::UnknownActuator(steps[k].actuator.clone()))
    };
    let owners: Vec<usize> = (0..n).map(role_of).collect::<Result<_, _>>()?;
    let first = seq.first_role;
    let home_event = home_input(robot, ir, first)?;
    let roles_names: Vec<String> = ir.roles.iter().map(|r| r.name.clone()).collect();
    let import = |r: &mut RoleIr, from: usize, event: &str| {
        let entry = (
            roles_names[from].clone(),
            event.to_string(),
            event.to_string(),
        );
        if !r.imports.contains(&entry) {
            r.imports.push(entry);
        }
    };
    // Step 1's chart coordinates (and the role of a button that moves nothing).
    let panel = {
        let r = &mut ir.roles[first];
        r.home = Some(home_event.clone());
        let ci = r
            .charts
            .iter()
            .position(|c| c.name == seq.steps[0].actuator)
            .ok_or_else(|| SynthError::Undeclared(seq.steps[0].actuator.clone()))?;
        let c = &mut r.charts[ci];
        // Another node that boots (a power cut of that node alone) may have left its
        // actuators anywhere: at rest, the machine is no longer homed. (During a cycle or
        // homing its chart waits, from its first state, for an event that has passed: the
        // machine stalls, nothing moves from a wrong place; a reset then leaves it not
        // homed.)
        let booters: Vec<usize> = (0..roles_names.len())
            .filter(|&q| q != first && seq.moves_in(q))
            .collect();
        // States, inputs and transitions in the order that chains them (idle, UNHOMED,
        // HOMING, idle): each transition leaves the state the one before entered, most
        // enter the next state and trigger on the next input, which the packed table
        // says in a bit each.
        let unhomed = c.states.len();
        c.states.push(StateIr {
            name: String::from("UNHOMED"),
            actions: vec![],
        });
        let homing_state = c.states.len();
        c.states.push(StateIr {
            name: String::from("HOMING"),
            actions: vec![ActionIr::Emit(String::from(HOME_START_EVENT))],
        });
        let mut unhome_input = None;
        if !booters.is_empty() {
            let unhome = c.inputs.len();
            unhome_input = Some(unhome);
            c.inputs.push(String::from("unhome"));
            c.transitions.push(TransitionIr {
                from: c.idle,
                to: unhomed,
                trigger: Some(unhome),
                guard: None,
            });
        }
        let (home_in, homed_in) = (c.inputs.len(), c.inputs.len() + 1);
        c.inputs.push(String::from("home"));
        c.inputs.push(String::from("homed"));
        for (from, to, trigger) in [
            (unhomed, homing_state, home_in),
            (homing_state, c.idle, homed_in),
            (c.idle, homing_state, home_in),
        ] {
            c.transitions.push(TransitionIr {
                from,
                to,
                trigger: Some(trigger),
                guard: None,
            });
        }
        // The START button on a role that moves nothing (a panel): that node's power cut
        // leaves no actuator anywhere new, but it comes back with its gate shut. Step 1's
        // chart, idle, answers its boot by entering `IDLE` again, whose `cycle.done` opens
        // the gate (busy or not homed, it lets the boot pass: its next `IDLE` opens it).
        let panel = (seq.gated && !seq.moves_in(seq.start_role)).then(|| {
            let greet = c.inputs.len();
            c.inputs.push(String::from("greet"));
            c.transitions.push(TransitionIr {
                from: c.idle,
                to: c.idle,
                trigger: Some(greet),
                guard: None,
            });
            (seq.start_role, greet)
        });
        c.initial = unhomed;
        if let Some(unhome) = unhome_input {
            r.event(PEER_BOOT_EVENT);
            r.routes.push((String::from(PEER_BOOT_EVENT), ci, unhome));
            for &q in &booters {
                let entry = (
                    roles_names[q].clone(),
                    String::from(BOOT_EVENT),
                    String::from(PEER_BOOT_EVENT),
                );
                r.imports.push(entry);
            }
        }
        if let Some((q, greet)) = panel {
            r.event(BUTTON_BOOT_EVENT);
            r.routes.push((String::from(BUTTON_BOOT_EVENT), ci, greet));
            r.imports.push((
                roles_names[q].clone(),
                String::from(BOOT_EVENT),
                String::from(BUTTON_BOOT_EVENT),
            ));
        }
        r.event(&home_event);
        r.event(HOME_START_EVENT);
        r.event(HOME_DONE_EVENT);
        r.routes.push((home_event.clone(), ci, home_in));
        r.routes.push((String::from(HOME_DONE_EVENT), ci, homed_in));
        if owners.last().is_some_and(|&o| o != first) {
            let last = owners[n - 1];
            import(r, last, HOME_DONE_EVENT);
        }
        panel.map(|(q, _)| q)
    };
    for q in 0..ir.roles.len() {
        if q != first && (seq.moves_in(q) || panel == Some(q)) {
            let r = &mut ir.roles[q];
            r.event(BOOT_EVENT);
            r.boot = Some(String::from(BOOT_EVENT));
        }
    }
    // One `home` chart per role with homing steps.
    for ri in 0..ir.roles.len() {
        let own: Vec<usize> = (0..n).filter(|&k| owners[k] == ri).collect();
        if own.is_empty() {
            continue;
        }
        let chart = home_chart(robot, &mut ir.roles[ri], &steps, &own)?;
        let r = &mut ir.roles[ri];
        let ci = r.charts.len();
        for (event, input) in chart.routes {
            r.event(&event);
            r.routes.push((event, ci, input));
        }
        for s in &chart.chart.states {
            for a in &s.actions {
                if let ActionIr::Emit(e) = a {
                    r.event(e);
                }
            }
        }
        r.charts.push(chart.chart);
        for &k in &own {
            let producer = if k == 0 { first } else { owners[k - 1] };
            if producer != ri {
                import(r, producer, &home_trigger_event(k, n));
            }
        }
    }
    ir.home = Some(first);
    ir.homing = steps;
    ir.homing_derived = derived;
    Ok(())
}

/// The node event the HOME command raises on step 1's role: the HOME input's (declared
/// on that role, or published to it by the role it is on), else `home`.
fn home_input(robot: &Robot, ir: &mut Ir, first: usize) -> Result<String, SynthError> {
    let Some((hr, name)) = crate::elab::home_input(robot)? else {
        return Ok(String::from(HOME_COMMAND_EVENT));
    };
    super::button(&mut ir.roles[hr], &robot.roles[hr], &name)?;
    if hr != first {
        let from = ir.roles[hr].name.clone();
        let r = &mut ir.roles[first];
        r.event(&name);
        r.imports.push((from, name.clone(), name.clone()));
    }
    Ok(name)
}

/// A role's `home` chart and the routes (node event, chart input) it needs.
struct HomeChart {
    chart: ChartIr,
    routes: Vec<(String, usize)>,
}

/// The `home` chart of a role owning homing steps `own` (module doc).
fn home_chart(
    robot: &Robot,
    r: &mut RoleIr,
    steps: &[Step],
    own: &[usize],
) -> Result<HomeChart, SynthError> {
    let n = steps.len();
    let mut inputs: Vec<String> = Vec::new();
    let mut routes: Vec<(String, usize)> = Vec::new();
    let mut input = |event: String| -> usize {
        match inputs.iter().position(|i| *i == event) {
            Some(i) => i,
            None => {
                inputs.push(event.clone());
                routes.push((event, inputs.len() - 1));
                inputs.len() - 1
            }
        }
    };
    let mut states = vec![StateIr {
        name: String::from("WAIT"),
        actions: vec![],
    }];
    let mut transitions = Vec::new();
    let mut go = |from: usize, to: usize, trigger: Option<usize>, guard| {
        transitions.push(TransitionIr {
            from,
            to,
            trigger,
            guard,
        });
    };
    let mut from = 0usize;
    for (j, &k) in own.iter().enumerate() {
        let step = &steps[k];
        let (_, a) = robot
            .actuator(&step.actuator)
            .and_then(|(ri, ai)| Some((ri, robot.roles.get(ri)?.actuators.get(ai)?)))
            .ok_or_else(|| SynthError::UnknownActuator(step.actuator.clone()))?;
        let wiring = r
            .actuator(&a.name)
            .ok_or_else(|| SynthError::Undeclared(a.name.clone()))?
            .clone();
        let timers = Timers {
            watchdog: r
                .timers
                .iter()
                .position(|t| t.name == format!("{}.watchdog", a.name)),
            dwell: r
                .timers
                .iter()
                .position(|t| t.name == format!("{}.dwell", a.name)),
        };
        let motion = Motion::of(robot, r, a, timers)?;
        let (timer, ms) = motion.timer(step.extend)?;
        // Straight on from this chart's previous step: no event to wait for.
        let back_to_back = j > 0 && own[j - 1] + 1 == k;
        let trigger = (!back_to_back).then(|| input(home_trigger_event(k, n)));
        let homing = states.len();
        states.push(StateIr {
            name: format!("HOMING{}", k + 1),
            actions: vec![
                motion.drive(step.extend),
                ActionIr::StartTimer { timer, ms },
            ],
        });
        let homed = states.len();
        let mut done: Vec<ActionIr> = motion.cancel(step.extend).into_iter().collect();
        let next_own = own.get(j + 1).is_some_and(|&next| next == k + 1);
        if !next_own {
            done.push(ActionIr::Emit(home_done_event(k, n)));
        }
        states.push(StateIr {
            name: format!("HOMED{}", k + 1),
            actions: done,
        });
        // Skip a switched motion whose switch already reads its target.
        let target = if step.extend { wiring.end } else { wiring.home };
        if motion.is_switched(step.extend) {
            if let Some(sw) = target {
                let text = format!("{}.{}", a.name, motion.completion(step.extend));
                let op = config_schema::Op::Input(
                    u8::try_from(sw.0).map_err(|_| SynthError::Undeclared(a.name.clone()))?,
                );
                go(from, homed, trigger, Some((text, vec![op])));
            }
        }
        go(from, homing, trigger, None);
        let c = motion.completion(step.extend);
        let complete = input(format!("{}.{c}", a.name));
        go(homing, homed, Some(complete), None);
        from = homed;
    }
    // Back to WAIT after the last own step.
    go(from, 0, None, None);
    Ok(HomeChart {
        chart: ChartIr {
            name: String::from("home"),
            inputs,
            initial: 0,
            idle: 0,
            rests: Vec::new(),
            states,
            transitions,
        },
        routes,
    })
}
