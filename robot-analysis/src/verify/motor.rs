//! The declared plants of a control-function robot in the verifier (docs/verification.md,
//! "Motors, switches, buttons"): a motor's carriage as three regions (at the home sensor,
//! between, at the end sensor); a running motor leaves an end at once and reaches the next
//! region toward its direction as a move that may come at any time (as a cylinder's motion
//! completes); what it drives (the belt) is where it is, with its own sensors; a switch
//! (the fault contact) is set or released at any time; the operator's other buttons are
//! pressed at any time; a fault alarm latched on a node is acknowledged once its cause is
//! gone.

use node_fw::sim::Plant;
use node_fw::sim::Run;

/// Where a carriage is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) enum Region {
    Home,
    Between,
    End,
}

impl Region {
    pub(super) fn name(self) -> &'static str {
        match self {
            Region::Home => "home",
            Region::Between => "between",
            Region::End => "end",
        }
    }
}

/// A motor and the sensors that read its carriage: (node, input) of home and end, its own
/// and those of what it drives.
#[derive(Debug, Clone)]
pub(super) struct MotorModel {
    pub name: String,
    pub node: usize,
    pub cw: u8,
    pub ccw: u8,
    pub home: Vec<(usize, u8)>,
    pub end: Vec<(usize, u8)>,
    /// The names of what it drives.
    pub driven: Vec<String>,
}

impl MotorModel {
    /// How its outputs run it.
    pub(super) fn run(&self, outputs: u16) -> Run {
        let on = |o: u8| outputs & (1 << (o & 15)) != 0;
        Run::of(on(self.cw), on(self.ccw))
    }

    /// The motor now runs `run` from `at`: leaving an end drops its sensors at once.
    pub(super) fn start(&self, at: &mut Region, run: Run, inputs: &mut Vec<(usize, u8, bool)>) {
        let leaves = match (run, *at) {
            (Run::Clockwise, Region::Home) => &self.home,
            (Run::CounterClockwise, Region::End) => &self.end,
            _ => return,
        };
        *at = Region::Between;
        inputs.extend(leaves.iter().map(|&(n, i)| (n, i, false)));
    }

    /// Whether running `run` from `at` it reaches an end next.
    pub(super) fn moving(run: Run, at: Region) -> bool {
        at == Region::Between && run != Run::Stopped
    }

    /// It reaches the end it runs toward: its sensors rise.
    pub(super) fn arrive(&self, at: &mut Region, run: Run, inputs: &mut Vec<(usize, u8, bool)>) {
        let (to, sensors) = match run {
            Run::Clockwise => (Region::End, &self.end),
            Run::CounterClockwise => (Region::Home, &self.home),
            Run::Stopped => return,
        };
        *at = to;
        inputs.extend(sensors.iter().map(|&(n, i)| (n, i, true)));
    }
}

/// The declared plants the verifier drives.
#[derive(Debug, Clone, Default)]
pub(super) struct Plants {
    pub motors: Vec<MotorModel>,
    /// Maintained contacts: (name, node, input).
    pub switches: Vec<(String, usize, u8)>,
    /// The operator's buttons other than START: (name, node, input).
    pub buttons: Vec<(String, usize, u8)>,
}

impl Plants {
    /// From the simulator's plants (`start`: the START button's index).
    pub(super) fn new(plants: &[Plant], start: usize) -> Plants {
        let mut out = Plants::default();
        for (i, p) in plants.iter().enumerate() {
            match p {
                Plant::Motor(m) => out.motors.push(MotorModel {
                    name: m.name.clone(),
                    node: m.node,
                    cw: m.cw_out,
                    ccw: m.ccw_out,
                    home: m.home_in.map(|h| (m.node, h)).into_iter().collect(),
                    end: m.end_in.map(|e| (m.node, e)).into_iter().collect(),
                    driven: Vec::new(),
                }),
                Plant::Switch(s) => out.switches.push((s.name.clone(), s.node, s.input)),
                Plant::Button(b) if i != start => {
                    out.buttons.push((b.name.clone(), b.node, b.input));
                }
                _ => {}
            }
        }
        for p in plants {
            let Plant::Driven(d) = p else { continue };
            let motor = (plants
                .iter()
                .take(d.motor)
                .filter(|q| matches!(q, Plant::Motor(_))))
            .count();
            if let Some(m) = out.motors.get_mut(motor) {
                m.home.extend(d.home_in.map(|h| (d.node, h)));
                m.end.extend(d.end_in.map(|e| (d.node, e)));
                m.driven.push(d.name.clone());
            }
        }
        out
    }

    /// The plants in one line, for the report.
    pub(super) fn describe(&self, faults: u8) -> String {
        let mut parts: Vec<String> = (self.motors.iter())
            .map(|m| {
                let with = match m.driven.is_empty() {
                    true => String::new(),
                    false => format!(" moving {}", m.driven.join(", ")),
                };
                format!("motor {}{with} (home, between, end)", m.name)
            })
            .collect();
        let names = |v: &[(String, usize, u8)]| {
            v.iter()
                .map(|x| x.0.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        };
        if !self.switches.is_empty() {
            let times = match faults {
                1 => "once".to_string(),
                n => format!("up to {n} times"),
            };
            parts.push(format!(
                "switch {} set {times} and released, each at any time",
                names(&self.switches)
            ));
        }
        if !self.buttons.is_empty() {
            parts.push(format!("{} pressed at any time", names(&self.buttons)));
        }
        format!("plants: {}; alarms acknowledged", parts.join("; "))
    }

    /// Whether there is anything to drive.
    pub(super) fn any(&self) -> bool {
        !self.motors.is_empty() || !self.switches.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pusher() -> MotorModel {
        MotorModel {
            name: "PUSHER".into(),
            node: 1,
            cw: 8,
            ccw: 9,
            home: vec![(1, 0), (2, 0)],
            end: vec![(1, 1), (2, 1)],
            driven: vec!["BELT".into()],
        }
    }

    #[test]
    fn a_running_motor_leaves_its_end_at_once_and_arrives_at_the_other_with_what_it_drives() {
        let m = pusher();
        let mut at = Region::Home;
        let mut inputs = Vec::new();
        let run = m.run(1 << 8);
        assert_eq!(run, Run::Clockwise);
        m.start(&mut at, run, &mut inputs);
        assert_eq!(
            (at, &inputs[..]),
            (Region::Between, &[(1, 0, false), (2, 0, false)][..])
        );
        assert!(MotorModel::moving(run, at));
        inputs.clear();
        m.arrive(&mut at, run, &mut inputs);
        assert_eq!(
            (at, &inputs[..]),
            (Region::End, &[(1, 1, true), (2, 1, true)][..])
        );
        // Stalled at the end, still commanded: nothing more.
        assert!(!MotorModel::moving(run, at));
        inputs.clear();
        m.start(&mut at, run, &mut inputs);
        assert_eq!((at, inputs.len()), (Region::End, 0));
        // Stopped between: stays.
        let mut mid = Region::Between;
        assert!(!MotorModel::moving(m.run(0), mid));
        m.start(&mut mid, m.run(0), &mut inputs);
        assert_eq!(mid, Region::Between);
        assert_eq!(m.run((1 << 8) | (1 << 9)), Run::Stopped);
    }
}
