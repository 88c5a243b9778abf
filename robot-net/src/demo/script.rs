//! The operator's script of seed 001's fig. 9 for a robot with control functions
//! (`functions:`), and what `sim` says each step does: the same script on the compiled
//! blobs in virtual time (`node_fw::sim`, the robot's declared plants), as
//! `robot-analysis/tests/waterjet.rs` runs it. The demo ([`super::transport`]) runs it on
//! the bed and compares every step with this.

use std::fmt;

use config_schema::alarm::{AlarmLevel, AlarmSource};
use node_fw::sim::{Motor, Plant, Run, TraceEntry, What, World};
use robot_analysis::sim;
use robot_compiler::Compiled;

use crate::error::NetError;

/// What the operator does in one step.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Act {
    /// The START command (the robot's `start`).
    Start,
    /// The fault contact (the first declared switch) closed (`true`) or opened.
    Fault(bool),
    /// A declared button pressed.
    Press(String),
    /// Every alarm acknowledged (`Command::Ack`).
    Ack,
}

impl fmt::Display for Act {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Act::Start => f.write_str("START"),
            Act::Fault(true) => f.write_str("the fault contact closes"),
            Act::Fault(false) => f.write_str("the fault contact opens"),
            Act::Press(b) => write!(f, "{b} pressed"),
            Act::Ack => f.write_str("the alarm acknowledged"),
        }
    }
}

/// Fig. 9: the automatic start (the pusher turns clockwise in step 2), the fault (the
/// pusher stops), the release (pusher and belt home), the fault cleared and its alarm
/// acknowledged, the restart and a full transport cycle.
pub fn fig9() -> Vec<Act> {
    vec![
        Act::Start,
        Act::Fault(true),
        Act::Press("RELEASE".into()),
        Act::Fault(false),
        Act::Ack,
        Act::Press("RESTART".into()),
    ]
}

/// A motion of the motor, as the plant sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Moved {
    Run(Run),
    /// It reached its end (`true`) or home.
    Arrived(bool),
}

impl fmt::Display for Moved {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Moved::Run(Run::Clockwise) => "clockwise",
            Moved::Run(Run::CounterClockwise) => "counter-clockwise",
            Moved::Run(Run::Stopped) => "stopped",
            Moved::Arrived(true) => "at its end",
            Moved::Arrived(false) => "home",
        })
    }
}

/// An alarm as the script compares it: (source, level, acknowledged, its cause persists).
pub type AlarmSeen = (AlarmSource, AlarmLevel, bool, bool);

/// What one step does in `sim`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Expected {
    pub act: Act,
    /// The motor's motions, in order.
    pub moved: Vec<Moved>,
    /// Every control function's place once the step settled: (function, place), in role
    /// and chart order.
    pub functions: Vec<(String, String)>,
    /// [`Act::Ack`]: the alarms of the role of `start` after the acknowledgement.
    pub alarms: Vec<AlarmSeen>,
}

/// The plants the script drives, by index into `plants`: (motor, fault switch).
fn script_plants(plants: &[Plant]) -> Result<(usize, usize), NetError> {
    let motor = (plants.iter())
        .position(|p| matches!(p, Plant::Motor(_)))
        .ok_or_else(|| NetError::Robot("fig. 9 needs a declared Motor plant".into()))?;
    let fault = (plants.iter())
        .position(|p| matches!(p, Plant::Switch(_)))
        .ok_or_else(|| NetError::Robot("fig. 9 needs a declared Switch (the fault)".into()))?;
    Ok((motor, fault))
}

/// The name of the script's motor and fault contact in `c`'s declared plants.
pub fn names(c: &Compiled) -> Result<(String, String), NetError> {
    let (plants, _) = sim::plants(c).map_err(|e| NetError::Robot(e.to_string()))?;
    let (motor, fault) = script_plants(&plants)?;
    let name = |i: usize| {
        plants
            .get(i)
            .map_or_else(String::new, |p| p.name().to_string())
    };
    Ok((name(motor), name(fault)))
}

/// The control functions' places: (function, place) for every chart that is one, in role
/// and chart order, from each role's state indices (`None`: the role did not say).
pub fn functions(c: &Compiled, states: &[Option<Vec<u8>>]) -> Vec<(String, String)> {
    let is_function = |n: &str| c.robot.functions.iter().any(|f| f.name == n);
    let mut out = Vec::new();
    for (role, states) in c.ir.roles.iter().zip(states) {
        for (i, chart) in role.charts.iter().enumerate() {
            if !is_function(&chart.name) {
                continue;
            }
            let place = (states.as_ref())
                .and_then(|s| s.get(i))
                .and_then(|&s| chart.states.get(usize::from(s)))
                .map_or_else(|| String::from("?"), |s| s.name.clone());
            out.push((chart.name.clone(), place));
        }
    }
    out
}

/// `Operation: Auto, Transport: Step2, ...`.
pub fn functions_text(f: &[(String, String)]) -> String {
    (f.iter())
        .map(|(n, p)| format!("{n}: {p}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn moved(trace: &[TraceEntry], motor: usize) -> Vec<Moved> {
    (trace.iter())
        .filter_map(|e| match e.what {
            What::Motor { plant, run, .. } if plant == motor => Some(Moved::Run(run)),
            What::Arrived { plant, end } if plant == motor => Some(Moved::Arrived(end)),
            _ => None,
        })
        .collect()
}

/// Where START's step ends and its places are read: half the stroke of `motor` (it is
/// under way), in milliseconds.
pub(crate) fn half_stroke_ms(motor: &Motor) -> u64 {
    u64::from(motor.stroke_mm) * 1000 / u64::from(motor.speed_mm_s.max(1)) / 2
}

/// Whether `step` leaves the motor under way (its last motion sets it off): its places
/// are read while it moves.
pub(crate) fn under_way(step: &Expected) -> bool {
    matches!(
        step.moved.last(),
        Some(Moved::Run(Run::Clockwise | Run::CounterClockwise))
    )
}

/// `script` on `c` in `sim`: what each step does.
pub fn simulate(c: &Compiled, script: &[Act]) -> Result<Vec<Expected>, NetError> {
    let err = |e: &dyn fmt::Display| NetError::Robot(format!("sim: {e}"));
    let tables = sim::tables(c).map_err(|e| err(&e))?;
    let (mut world, start) = sim::world(c, &tables).map_err(|e| err(&e))?;
    let (motor, fault) = script_plants(world.plants())?;
    let cabinet = c.ir.start.as_ref().map_or(0, |s| s.0);
    let half_ms = match world.plants().get(motor) {
        Some(Plant::Motor(m)) => half_stroke_ms(m),
        _ => 0,
    };
    let settle = |world: &mut World| world.run_until_idle(60_000).map(|_| ());
    let mut out = Vec::new();
    for act in script {
        let mark = world.trace().len();
        let mut alarms = Vec::new();
        match act {
            Act::Start => {
                world.press(start).map_err(|e| err(&e))?;
                world.run_for(half_ms).map_err(|e| err(&e))?;
            }
            Act::Fault(level) => {
                world.set_switch(fault, *level).map_err(|e| err(&e))?;
                settle(&mut world).map_err(|e| err(&e))?;
            }
            Act::Press(name) => {
                let b = (world.plant_by_name(name))
                    .ok_or_else(|| NetError::Robot(format!("fig. 9 needs a button {name}")))?;
                world.press(b).map_err(|e| err(&e))?;
                settle(&mut world).map_err(|e| err(&e))?;
            }
            Act::Ack => {
                world.ack(cabinet).map_err(|e| err(&e))?;
                let report = world.alarms(cabinet);
                alarms = (report.iter().flat_map(|r| r.alarms.iter()))
                    .map(|a| (a.source, a.level, a.acked, a.persists))
                    .collect();
            }
        }
        let states: Vec<Option<Vec<u8>>> = (0..world.node_count())
            .map(|n| Some(world.states(n)))
            .collect();
        out.push(Expected {
            act: act.clone(),
            moved: moved(&world.trace()[mark..], motor),
            functions: functions(c, &states),
            alarms,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn waterjet() -> Compiled {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../robot-configs/waterjet-transport.ron");
        crate::demo::load(&path).expect("compiles")
    }

    /// What the demo compares the bed with: fig. 9 in `sim`, step by step.
    #[test]
    fn fig_9_in_sim_step_by_step() {
        let c = waterjet();
        let got = simulate(&c, &fig9()).expect("simulates");
        let lines: Vec<String> = (got.iter())
            .map(|e| {
                let moved: Vec<String> = e.moved.iter().map(|m| m.to_string()).collect();
                format!(
                    "{}: [{}] {}",
                    e.act,
                    moved.join(" "),
                    functions_text(&e.functions)
                )
            })
            .collect();
        assert_eq!(
            lines,
            [
                "START: [clockwise] Operation: Auto, Transport: Step2, Pusher: Clockwise, \
                 FaultDetection: Ok, Belt: Forward",
                "the fault contact closes: [stopped] Operation: Halted, Transport: ReadyToCut, \
                 Pusher: Stopped, FaultDetection: Faulted, Belt: Stopped",
                "RELEASE pressed: [counter-clockwise home stopped] Operation: Releasing, \
                 Transport: ReadyToCut, Pusher: Stopped, FaultDetection: Released, Belt: Stopped",
                "the fault contact opens: [] Operation: Releasing, Transport: ReadyToCut, \
                 Pusher: Stopped, FaultDetection: Ok, Belt: Stopped",
                "the alarm acknowledged: [] Operation: Releasing, Transport: ReadyToCut, \
                 Pusher: Stopped, FaultDetection: Ok, Belt: Stopped",
                "RESTART pressed: [clockwise at its end stopped counter-clockwise home stopped] \
                 Operation: Auto, Transport: ReadyToCut, Pusher: Stopped, FaultDetection: Ok, \
                 Belt: Stopped",
            ],
            "{}",
            lines.join("\n")
        );
        assert_eq!(
            got[4].alarms,
            [(
                AlarmSource::Declared { index: 0 },
                AlarmLevel::Fault,
                true,
                false
            )]
        );
        assert_eq!(names(&c).expect("names"), ("PUSHER".into(), "FAULT".into()));
    }
}
