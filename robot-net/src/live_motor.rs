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
    /// The plant's time stands still `after_ms` after motor `motor` next sets off (on the
    /// carriages' clock, however late the plant looks): the carriages stay where they
    /// are and none arrives; the nodes, the radio and the operator's inputs go on. Said
    /// by [`Motion::Held`]. The demo holds it where `sim` reads a step's places, half the
    /// stroke after START: a reading slowed by a lossy radio does not race the motion.
    HoldAfter { motor: usize, after_ms: u64 },
    /// The plant's time goes on from where it stood (or an armed hold is dropped).
    Go,
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
    /// The plant's time stands still ([`Operate::HoldAfter`]) from `at` on, motor
    /// `motor`'s carriage `at_um` from home.
    Held {
        motor: usize,
        at_um: u64,
        at: Duration,
    },
}

/// A hold of the plant's time ([`Operate::HoldAfter`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Hold {
    /// At motor `motor`'s next start, `after_ms` later.
    Armed { motor: usize, after_ms: u64 },
    /// From `from` on the medium's clock; `said` once [`Motion::Held`] went out.
    From {
        motor: usize,
        from: Instant,
        said: bool,
    },
}

/// The carriages' clock: the medium's, standing still while the plant is held.
#[derive(Debug, Clone, Copy)]
struct PlantClock {
    /// The medium's start.
    medium: Instant,
    /// The time the plant stood still so far.
    lost: Duration,
    hold: Option<Hold>,
    /// When it last went on after standing still: a change the medium saw while it stood
    /// (and this process heard later) happened where it stood.
    went_on: Instant,
}

impl PlantClock {
    /// The carriages' time at `t` on the medium's clock, in milliseconds.
    fn ms(&self, t: Instant) -> u64 {
        let t = t.max(self.went_on);
        let t = match self.hold {
            Some(Hold::From { from, .. }) => t.min(from),
            _ => t,
        };
        let since = t.saturating_duration_since(self.medium);
        since.saturating_sub(self.lost).as_millis() as u64
    }

    /// When the carriages' clock reads `ms`, on the medium's clock (were it not held).
    fn instant(&self, ms: u64) -> Instant {
        self.medium + self.lost + Duration::from_millis(ms)
    }

    /// When the carriages' clock reads `ms`, if the plant's time gets there before a
    /// hold stops it.
    fn reaches(&self, ms: u64) -> Option<Instant> {
        let t = self.instant(ms);
        match self.hold {
            Some(Hold::From { from, .. }) if t > from => None,
            _ => Some(t),
        }
    }

    /// The plant's time goes on at `now`: the time it stood still is lost.
    fn go(&mut self, now: Instant) {
        if let Some(Hold::From { from, .. }) = self.hold {
            if now > from {
                self.lost += now - from;
                self.went_on = now;
            }
        }
        self.hold = None;
    }
}

/// The live motors while the plant runs.
pub(crate) struct Running {
    plant: Motors,
    carriages: Vec<Carriage>,
    /// Each motor's cw / ccw output levels.
    commanded: Vec<(bool, bool)>,
    /// When each running motor arrives, on the carriages' clock (ms).
    arrival: Vec<Option<u64>>,
    /// Each input's level.
    levels: Vec<bool>,
    /// Button releases due.
    releases: Vec<(Instant, usize)>,
    operate: Receiver<Operate>,
    seen: Sender<Motion>,
    clock: PlantClock,
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
            clock: PlantClock {
                medium,
                lost: Duration::ZERO,
                hold: None,
                went_on: medium,
            },
        }
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

    /// When the next motion, hold or release is due; the plant looks at the operator's
    /// requests at least every [`OPERATOR_POLL`].
    pub(crate) fn wake(&self) -> Instant {
        let hold = match self.clock.hold {
            Some(Hold::From {
                from, said: false, ..
            }) => Some(from),
            _ => None,
        };
        (self.arrival.iter().flatten())
            .filter_map(|&ms| self.clock.reaches(ms))
            .chain(hold)
            .chain(self.releases.iter().map(|r| r.0))
            .chain([Instant::now() + OPERATOR_POLL])
            .min()
            .unwrap_or_else(|| Instant::now() + OPERATOR_POLL)
    }

    fn now(&self) -> Duration {
        self.clock.medium.elapsed()
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
        // The operator's requests first: a hold asked for before this change (before
        // START) is armed for it, however late this process got round to either.
        self.requests(conn)?;
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
            // From when the medium saw the output change, on the carriages' clock.
            let now_ms = (self.clock).ms(self.clock.medium + Duration::from_micros(at_us));
            let change = m.model.change(c, run, now_ms);
            let at_um = c.at_um;
            match self.clock.hold {
                Some(Hold::Armed { motor, after_ms }) if motor == i && run != Run::Stopped => {
                    self.clock.hold = Some(Hold::From {
                        motor,
                        from: self.clock.instant(now_ms.saturating_add(after_ms)),
                        said: false,
                    });
                }
                _ => {}
            }
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
                *a = change.arrive_ms;
            }
        }
        Ok(())
    }

    /// Runs the arrivals, the button releases and the operator's requests that are due.
    pub(crate) fn tick(&mut self, conn: &mut Conn) -> io::Result<()> {
        let now = Instant::now();
        let now_ms = self.clock.ms(now);
        for i in 0..self.plant.motors.len() {
            let due = self.arrival.get(i).copied().flatten();
            if due.is_none_or(|d| d > now_ms) {
                continue;
            }
            if let Some(a) = self.arrival.get_mut(i) {
                *a = None;
            }
            let (Some(m), Some(c)) = (self.plant.motors.get(i), self.carriages.get_mut(i)) else {
                continue;
            };
            if let Some(end) = m.model.arrive(c, now_ms) {
                Self::sensors(conn, if end { &m.end } else { &m.home }, true)?;
                let at = self.now();
                let _ = self.seen.send(Motion::Arrived { motor: i, end, at });
            }
        }
        self.say_held(now);
        let (due, later): (Vec<_>, Vec<_>) = self.releases.drain(..).partition(|r| r.0 <= now);
        self.releases = later;
        for (_, input) in due {
            self.drive(conn, input, false)?;
        }
        self.requests(conn)
    }

    /// What the operator asked for since the plant last looked.
    fn requests(&mut self, conn: &mut Conn) -> io::Result<()> {
        while let Ok(op) = self.operate.try_recv() {
            match op {
                Operate::Set(input, level) => self.drive(conn, input, level)?,
                Operate::HoldAfter { motor, after_ms } => {
                    self.clock.go(Instant::now());
                    self.clock.hold = Some(Hold::Armed { motor, after_ms });
                }
                Operate::Go => self.clock.go(Instant::now()),
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

    /// [`Motion::Held`] once the plant's time stands still.
    fn say_held(&mut self, now: Instant) {
        let Some(Hold::From { motor, from, said }) = &mut self.clock.hold else {
            return;
        };
        if *said || *from > now {
            return;
        }
        *said = true;
        let (motor, from) = (*motor, *from);
        let at_ms = self.clock.ms(from);
        let at_um = (self.plant.motors.get(motor).zip(self.carriages.get(motor)))
            .map_or(0, |(m, c)| m.model.position_um(c, at_ms));
        let at = from.saturating_duration_since(self.clock.medium);
        let _ = self.seen.send(Motion::Held { motor, at_um, at });
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

    /// A plant held half the stroke after its motor sets off stands still there however
    /// late it looks (here 20 s after the medium started): no arrival, the carriage where
    /// it was at the hold, a change while it stands (heard then or later) finds it there;
    /// then it goes on from that place and time. (The demo read the places after START
    /// while the pusher ran on: under load the reading outlasted the 2 s stroke and saw
    /// the next cycle's.)
    #[test]
    fn a_held_plant_stands_still_mid_stroke_and_goes_on_from_there() {
        use config_schema::wire::medium::Peer;
        let medium = medium::Medium::start(medium::Config::default()).expect("medium");
        let mut conn = Conn::join(medium.addr(), Peer::Plant).expect("joins");
        let (operate, operated) = std::sync::mpsc::channel();
        let (seen, motions) = std::sync::mpsc::channel();
        let start = Instant::now() - Duration::from_secs(20);
        let mut plant = Running::new(motors(&waterjet()).expect("wired"), operated, seen, start);
        let (addr, cw) = (plant.plant.motors[0].addr, plant.plant.motors[0].cw);
        operate
            .send(Operate::HoldAfter {
                motor: 0,
                after_ms: 1000,
            })
            .expect("sends");
        // Clockwise at 1 s (heard before the plant looked at the request): 400 mm at
        // 200 mm/s, at its end at 3 s were it not held at 2 s.
        plant
            .output(&mut conn, addr, cw, true, 1_000_000)
            .expect("sent");
        assert_eq!(plant.arrival[0], Some(3000));
        plant.tick(&mut conn).expect("ticks");
        let at = |s: u64| Duration::from_secs(s);
        let run = |run, at_um, t| Motion::Run {
            motor: 0,
            addr,
            run,
            at_um,
            at: t,
        };
        let held = Motion::Held {
            motor: 0,
            at_um: 200_000,
            at: at(2),
        };
        assert_eq!(
            motions.try_iter().collect::<Vec<_>>(),
            [run(Run::Clockwise, 0, at(1)), held]
        );
        assert_eq!(plant.arrival[0], Some(3000), "no arrival while held");
        // Stopped at 9 s (by the fault): where it stood when the hold began.
        plant
            .output(&mut conn, addr, cw, false, 9_000_000)
            .expect("sent");
        assert_eq!(
            motions.try_iter().collect::<Vec<_>>(),
            [run(Run::Stopped, 200_000, at(9))]
        );
        // It goes on at 15 s; clockwise again at 14 s, heard after it went on: from 200 mm
        // and 2 s on the carriages' clock, at its end 1 s after it went on.
        plant.clock.go(start + at(15));
        plant
            .output(&mut conn, addr, cw, true, 14_000_000)
            .expect("sent");
        assert_eq!(
            motions.try_iter().collect::<Vec<_>>(),
            [run(Run::Clockwise, 200_000, at(14))]
        );
        assert_eq!(plant.arrival[0], Some(3000));
        assert_eq!(plant.clock.reaches(3000), Some(start + at(16)));
        plant.tick(&mut conn).expect("ticks");
        let arrived: Vec<_> = (motions.try_iter())
            .map(|m| match m {
                Motion::Arrived { motor, end, .. } => Some((motor, end)),
                _ => None,
            })
            .collect();
        assert_eq!(arrived, [Some((0, true))]);
        medium.stop();
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
