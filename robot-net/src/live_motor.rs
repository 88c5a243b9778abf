//! The declared plants with a continuous position in real time, on the live plant: the
//! same rules as `node_fw::sim` (docs/simulation.md; `node_fw::sim::Motor`): a motor on
//! two outputs (clockwise toward the end, counter-clockwise home, none or both: stopped)
//! moving a carriage over its stroke at its speed, the sensors at each end of it and of
//! what it moves (a belt, with its sensors on another node); maintained contacts (a fault
//! contact) and push buttons (a pulse) the demo drives as the operator would. Wired by
//! node address and pin; every change is reported, stamped with the medium's clock.

use std::io;
use std::sync::mpsc::{Receiver, Sender};
use std::time::{Duration, Instant};

use config_schema::wire::medium::Link;
use medium::Conn;
use node_fw::sim::{Carriage, Motor, Plant, Run};
use robot_compiler::compile::Compiled;

use crate::error::NetError;

/// A motor, wired by node address and board pins; `model` has its stroke and speed (its
/// indices are not used).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LiveMotor {
    pub name: String,
    pub addr: u16,
    pub cw: u8,
    pub ccw: u8,
    /// The sensors at (home, end): its own and those of what it moves, (address, pin).
    pub home: Vec<(u16, u8)>,
    pub end: Vec<(u16, u8)>,
    pub model: Motor,
}

/// An input the operator (the demo) drives: a maintained contact or a button.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LiveInput {
    pub name: String,
    pub addr: u16,
    pub pin: u8,
    /// A button: a press holds the pin high this long. `None`: a maintained contact.
    pub press_ms: Option<u64>,
}

/// The motors and operator inputs of a robot's declared plants.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Motors {
    pub motors: Vec<LiveMotor>,
    pub inputs: Vec<LiveInput>,
}

impl Motors {
    pub fn motor(&self, name: &str) -> Option<usize> {
        self.motors.iter().position(|m| m.name == name)
    }

    pub fn input(&self, name: &str) -> Option<usize> {
        self.inputs.iter().position(|i| i.name == name)
    }
}

/// The declared motors (with what they move), switches and buttons of `c`, on the nodes
/// its roles are assigned to (the robot's START button is left out: the demo sends the
/// START command).
pub fn motors(c: &Compiled) -> Result<Motors, NetError> {
    let (plants, start) =
        robot_analysis::sim::plants(c).map_err(|e| NetError::Robot(e.to_string()))?;
    let role = |node: usize| {
        (c.ir.roles.get(node)).ok_or_else(|| NetError::Robot(format!("no role for node {node}")))
    };
    let ipin = |node: usize, i: u8| -> Result<(u16, u8), NetError> {
        let r = role(node)?;
        let pin = (r.inputs.get(usize::from(i)))
            .map(|x| x.pin)
            .ok_or_else(|| NetError::Robot(format!("role {} has no input {i}", r.name)))?;
        Ok((r.address, pin))
    };
    let opin = |node: usize, o: u8| -> Result<u8, NetError> {
        let r = role(node)?;
        (r.outputs.get(usize::from(o)))
            .map(|x| x.pin)
            .ok_or_else(|| NetError::Robot(format!("role {} has no output {o}", r.name)))
    };
    let mut out = Motors::default();
    for (p, plant) in plants.iter().enumerate() {
        match plant {
            Plant::Motor(m) => {
                let mut home = Vec::new();
                let mut end = Vec::new();
                // Its own sensors, then those of what it moves (the sim's order).
                let moved = plants.iter().filter_map(|q| match q {
                    Plant::Driven(d) if d.motor == p => Some((d.node, d.home_in, d.end_in)),
                    _ => None,
                });
                for (node, h, e) in [(m.node, m.home_in, m.end_in)].into_iter().chain(moved) {
                    if let Some(h) = h {
                        home.push(ipin(node, h)?);
                    }
                    if let Some(e) = e {
                        end.push(ipin(node, e)?);
                    }
                }
                out.motors.push(LiveMotor {
                    name: m.name.clone(),
                    addr: role(m.node)?.address,
                    cw: opin(m.node, m.cw_out)?,
                    ccw: opin(m.node, m.ccw_out)?,
                    home,
                    end,
                    model: m.clone(),
                });
            }
            Plant::Switch(s) => {
                let (addr, pin) = ipin(s.node, s.input)?;
                out.inputs.push(LiveInput {
                    name: s.name.clone(),
                    addr,
                    pin,
                    press_ms: None,
                });
            }
            Plant::Button(b) if p != start => {
                let (addr, pin) = ipin(b.node, b.input)?;
                out.inputs.push(LiveInput {
                    name: b.name.clone(),
                    addr,
                    pin,
                    press_ms: Some(b.press_ms),
                });
            }
            _ => {}
        }
    }
    Ok(out)
}

/// The levels at rest (every carriage home, every input open): (address, pin, level).
pub(crate) fn rest_levels(plant: &Motors) -> Vec<(u16, u8, bool)> {
    let sensors = plant.motors.iter().flat_map(|m| {
        (m.home.iter().map(|&(a, p)| (a, p, true))).chain(m.end.iter().map(|&(a, p)| (a, p, false)))
    });
    sensors
        .chain(plant.inputs.iter().map(|i| (i.addr, i.pin, false)))
        .collect()
}

/// What the operator does to an input ([`Motors::inputs`] index).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Operate {
    /// A maintained contact to this level.
    Set(usize, bool),
    /// A button pressed (high now, low its press time later).
    Press(usize),
}

/// What the live motors did, stamped with the medium's clock.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Motion {
    /// Motor `motor` runs `run` from `at_um` on, as its node `addr` commanded.
    Run {
        motor: usize,
        addr: u16,
        run: Run,
        at_um: u64,
        at: Duration,
    },
    /// Motor `motor`'s carriage reached its end (`end`) or home.
    Arrived {
        motor: usize,
        end: bool,
        at: Duration,
    },
    /// The operator drove input `input` to `level`.
    Input {
        input: usize,
        level: bool,
        at: Duration,
    },
}

/// The live motors while the plant runs.
pub(crate) struct Running {
    plant: Motors,
    carriages: Vec<Carriage>,
    /// Each motor's cw / ccw output levels.
    commanded: Vec<(bool, bool)>,
    /// When each running motor arrives.
    arrival: Vec<Option<Instant>>,
    /// Each input's level.
    levels: Vec<bool>,
    /// Button releases due.
    releases: Vec<(Instant, usize)>,
    operate: Receiver<Operate>,
    seen: Sender<Motion>,
    /// The medium's start (its clock).
    medium: Instant,
}

/// How long the plant waits at most for the next message before it looks at what the
/// operator asked for.
pub(crate) const OPERATOR_POLL: Duration = Duration::from_millis(2);

impl Running {
    pub(crate) fn new(
        plant: Motors,
        operate: Receiver<Operate>,
        seen: Sender<Motion>,
        medium: Instant,
    ) -> Running {
        let n = plant.motors.len();
        Running {
            carriages: vec![Carriage::default(); n],
            commanded: vec![(false, false); n],
            arrival: vec![None; n],
            levels: vec![false; plant.inputs.len()],
            releases: Vec::new(),
            plant,
            operate,
            seen,
            medium,
        }
    }

    /// Milliseconds on the medium's clock (the carriages' time).
    fn ms(&self, t: Instant) -> u64 {
        t.saturating_duration_since(self.medium).as_millis() as u64
    }

    /// The levels of every sensor and input for where the carriages stand (sent at attach
    /// and on each refresh: levels, repeats raise nothing).
    pub(crate) fn send_levels(&self, conn: &mut Conn) -> io::Result<()> {
        let motors = self.plant.motors.iter().zip(&self.carriages);
        for ((m, c), arrival) in motors.zip(&self.arrival) {
            // On its way: both ends open; else where it stands (it stops where it is, and
            // an arrival leaves it at that end).
            let at = if arrival.is_some() {
                None
            } else {
                m.model.at_end(c.at_um)
            };
            let (home, end) = (at == Some(false), at == Some(true));
            for (&(addr, pin), level) in
                (m.home.iter().map(|s| (s, home))).chain(m.end.iter().map(|s| (s, end)))
            {
                conn.send(&Link::Pin { addr, pin, level })?;
            }
        }
        for (i, level) in self.plant.inputs.iter().zip(&self.levels) {
            conn.send(&Link::Pin {
                addr: i.addr,
                pin: i.pin,
                level: *level,
            })?;
        }
        Ok(())
    }

    /// When the next motion or release is due; the plant looks at the operator's
    /// requests at least every [`OPERATOR_POLL`].
    pub(crate) fn wake(&self) -> Instant {
        (self.arrival.iter().flatten().copied())
            .chain(self.releases.iter().map(|r| r.0))
            .chain([Instant::now() + OPERATOR_POLL])
            .min()
            .unwrap_or_else(|| Instant::now() + OPERATOR_POLL)
    }

    fn now(&self) -> Duration {
        self.medium.elapsed()
    }

    fn sensors(conn: &mut Conn, sensors: &[(u16, u8)], level: bool) -> io::Result<()> {
        for &(addr, pin) in sensors {
            conn.send(&Link::Pin { addr, pin, level })?;
        }
        Ok(())
    }

    /// A node drove output `pin` to `level` (the medium saw it at `at_us`).
    pub(crate) fn output(
        &mut self,
        conn: &mut Conn,
        addr: u16,
        pin: u8,
        level: bool,
        at_us: u64,
    ) -> io::Result<()> {
        for i in 0..self.plant.motors.len() {
            let (Some(m), Some(cmd)) = (self.plant.motors.get(i), self.commanded.get_mut(i)) else {
                continue;
            };
            if m.addr != addr || (pin != m.cw && pin != m.ccw) {
                continue;
            }
            if pin == m.cw {
                cmd.0 = level;
            } else {
                cmd.1 = level;
            }
            let run = Run::of(cmd.0, cmd.1);
            let Some(c) = self.carriages.get_mut(i) else {
                continue;
            };
            if c.run == run {
                continue;
            }
            // From when the medium saw the output change (its clock is the carriages').
            let change = m.model.change(c, run, at_us / 1000);
            let at_um = c.at_um;
            let _ = self.seen.send(Motion::Run {
                motor: i,
                addr,
                run,
                at_um,
                at: Duration::from_micros(at_us),
            });
            match change.left {
                Some(true) => Self::sensors(conn, &m.end, false)?,
                Some(false) => Self::sensors(conn, &m.home, false)?,
                None => {}
            }
            if let Some(a) = self.arrival.get_mut(i) {
                *a = change
                    .arrive_ms
                    .map(|ms| self.medium + Duration::from_millis(ms));
            }
        }
        Ok(())
    }

    /// Runs the arrivals, the button releases and the operator's requests that are due.
    pub(crate) fn tick(&mut self, conn: &mut Conn) -> io::Result<()> {
        let now = Instant::now();
        for i in 0..self.plant.motors.len() {
            let due = self.arrival.get(i).copied().flatten();
            if due.is_none_or(|d| d > now) {
                continue;
            }
            if let Some(a) = self.arrival.get_mut(i) {
                *a = None;
            }
            let now_ms = self.ms(now);
            let (Some(m), Some(c)) = (self.plant.motors.get(i), self.carriages.get_mut(i)) else {
                continue;
            };
            if let Some(end) = m.model.arrive(c, now_ms) {
                Self::sensors(conn, if end { &m.end } else { &m.home }, true)?;
                let at = self.now();
                let _ = self.seen.send(Motion::Arrived { motor: i, end, at });
            }
        }
        let (due, later): (Vec<_>, Vec<_>) = self.releases.drain(..).partition(|r| r.0 <= now);
        self.releases = later;
        for (_, input) in due {
            self.drive(conn, input, false)?;
        }
        while let Ok(op) = self.operate.try_recv() {
            match op {
                Operate::Set(input, level) => self.drive(conn, input, level)?,
                Operate::Press(input) => {
                    let hold = (self.plant.inputs.get(input)).and_then(|i| i.press_ms);
                    self.drive(conn, input, true)?;
                    self.releases.push((
                        Instant::now() + Duration::from_millis(hold.unwrap_or(0)),
                        input,
                    ));
                }
            }
        }
        Ok(())
    }

    fn drive(&mut self, conn: &mut Conn, input: usize, level: bool) -> io::Result<()> {
        let (Some(i), Some(l)) = (self.plant.inputs.get(input), self.levels.get_mut(input)) else {
            return Ok(());
        };
        *l = level;
        conn.send(&Link::Pin {
            addr: i.addr,
            pin: i.pin,
            level,
        })?;
        let at = self.now();
        let _ = self.seen.send(Motion::Input { input, level, at });
        Ok(())
    }
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

    /// The water-jet transport's plants, by address and pin: the pusher's motor on the
    /// drive with its end sensors and the belt's on the belt node, the fault contact on
    /// the drive, the operator's buttons on the cabinet (START is the command).
    #[test]
    fn the_transports_plants_are_wired_by_address_and_pin() {
        let m = motors(&waterjet()).expect("wired");
        let got: Vec<_> = (m.motors.iter())
            .map(|m| {
                (
                    m.name.as_str(),
                    m.addr,
                    m.cw,
                    m.ccw,
                    m.home.clone(),
                    m.end.clone(),
                )
            })
            .collect();
        assert_eq!(
            got,
            [(
                "PUSHER",
                0x0032,
                8,
                9,
                vec![(0x0032, 0), (0x0033, 0)],
                vec![(0x0032, 1), (0x0033, 1)]
            )]
        );
        let inputs: Vec<_> = (m.inputs.iter())
            .map(|i| (i.name.as_str(), i.addr, i.pin, i.press_ms))
            .collect();
        assert_eq!(
            inputs,
            [
                ("FAULT", 0x0032, 2, None),
                ("RELEASE", 0x0031, 1, Some(50)),
                ("RESTART", 0x0031, 2, Some(50)),
            ]
        );
    }
}
