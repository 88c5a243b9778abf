//! A sorting station's ball feed in real time, on the live plant: the same rules as
//! `node_fw::sim`'s feed (docs/simulation.md, "Ball feed"), driven by the pusher's and
//! gates' rods of [`crate::live_plant`] and sent to the sensing node as pin levels. The
//! front ball's colour sensors read its levels; the pusher at its end pushes it into the
//! shaft (the sensors drop), the entry sensor pulses `drop_ms` later, the ball meets each
//! gate `fall_ms` apart (open: it lands in that bin) and last the bottom bin; landing
//! pulses the bin's sensor and is reported; the pusher back home lets the next ball roll
//! to the sensors `roll_ms` later.

use std::io;
use std::sync::mpsc::Sender;
use std::time::{Duration, Instant};

use config_schema::wire::medium::Link;
use medium::Conn;
use node_fw::cylinder::Position;
use node_fw::sim::ENTRY_PULSE_MS;
use robot_compiler::compile::Compiled;

use crate::error::NetError;
use crate::live_plant::Actuator;

/// A station's feed, wired by node address and pins.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BallFeed {
    pub addr: u16,
    /// Pins of the colour sensors, in table column order.
    pub sensors: Vec<u8>,
    pub entry: u8,
    /// Pins of the bins' sensors (one per bin, or none).
    pub bins: Vec<u8>,
    /// Each ball's sensor levels, front first.
    pub balls: Vec<Vec<bool>>,
    /// Indices into the plant's actuators.
    pub pusher: usize,
    pub gates: Vec<usize>,
    pub drop_ms: u64,
    pub fall_ms: u64,
    pub roll_ms: u64,
}

/// A ball that landed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Landing {
    /// 0-based, in feed order.
    pub ball: usize,
    /// 1-based.
    pub bin: usize,
    /// Gates it met while they moved (not taking it), by actuator name.
    pub met_moving: Vec<String>,
    /// Since the start the plant was given (the medium's clock zero for `plant`).
    pub at: Duration,
}

/// The feed of `c`'s station for `feed` (colours), with the plant's `actuators`.
pub fn ball_feed(
    c: &Compiled,
    actuators: &[Actuator],
    feed: &[String],
) -> Result<BallFeed, NetError> {
    let s =
        (c.robot.sorting.as_ref()).ok_or_else(|| NetError::Robot("no sorting station".into()))?;
    let missing = |n: &str| NetError::Robot(format!("the station names `{n}`, which is not there"));
    let role = (c.ir.roles.iter())
        .find(|r| r.name == s.role)
        .ok_or_else(|| missing(&s.role))?;
    let pin = |n: &str| {
        (role.inputs.iter())
            .find(|i| i.name == n)
            .map(|i| i.pin)
            .ok_or_else(|| missing(n))
    };
    let act = |n: &str| {
        let n = n.split_once('/').map_or(n, |(_, a)| a);
        (actuators.iter())
            .position(|a| a.name == n)
            .ok_or_else(|| missing(n))
    };
    Ok(BallFeed {
        addr: role.address,
        sensors: s.sensors.iter().map(|n| pin(n)).collect::<Result<_, _>>()?,
        entry: pin(&s.entry)?,
        bins: s.bins.iter().map(|n| pin(n)).collect::<Result<_, _>>()?,
        balls: (feed.iter())
            .map(|f| s.levels(f).map(<[bool]>::to_vec).ok_or_else(|| missing(f)))
            .collect::<Result<_, _>>()?,
        pusher: act(&s.pusher)?,
        gates: s.gates.iter().map(|g| act(g)).collect::<Result<_, _>>()?,
        drop_ms: u64::from(s.drop_ms),
        fall_ms: u64::from(s.fall_ms),
        roll_ms: u64::from(s.roll_ms),
    })
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ev {
    /// A pin level.
    Pin(u8, bool),
    /// Ball `ball` passes the entry sensor.
    Entry(usize),
    /// Ball `ball` meets gate `gate` (past the last: the bottom bin).
    At(usize, usize),
    /// Ball `ball` lies at the sensors.
    Roll(usize),
}

/// The feed while the plant runs.
pub(crate) struct Running {
    feed: BallFeed,
    /// The ball at the sensors.
    loaded: Option<usize>,
    next: usize,
    due: Vec<(Instant, Ev)>,
    met: Vec<Vec<String>>,
    landed: Sender<Landing>,
    start: Instant,
}

impl Running {
    pub(crate) fn new(feed: BallFeed, landed: Sender<Landing>, start: Instant) -> Running {
        let loaded = (!feed.balls.is_empty()).then_some(0);
        let met = vec![Vec::new(); feed.balls.len()];
        Running {
            next: usize::from(loaded.is_some()),
            loaded,
            feed,
            due: Vec::new(),
            met,
            landed,
            start,
        }
    }

    fn front(&self) -> Vec<(u8, bool)> {
        let levels = self.loaded.and_then(|b| self.feed.balls.get(b));
        (self.feed.sensors.iter())
            .enumerate()
            .map(|(i, &p)| (p, levels.and_then(|l| l.get(i)).copied().unwrap_or(false)))
            .collect()
    }

    /// The colour sensors' levels for the ball at the sensors (sent at attach and on
    /// each refresh: levels, repeats raise nothing).
    pub(crate) fn send_levels(&self, conn: &mut Conn) -> io::Result<()> {
        for (pin, level) in self.front() {
            conn.send(&Link::Pin {
                addr: self.feed.addr,
                pin,
                level,
            })?;
        }
        Ok(())
    }

    /// When the next feed event is due.
    pub(crate) fn wake(&self) -> Option<Instant> {
        self.due.iter().map(|d| d.0).min()
    }

    fn after(&mut self, now: Instant, ms: u64, ev: Ev) {
        self.due.push((now + Duration::from_millis(ms), ev));
    }

    /// Actuator `actuator` arrived at its end (`end`) or home.
    pub(crate) fn arrived(
        &mut self,
        conn: &mut Conn,
        actuator: usize,
        end: bool,
    ) -> io::Result<()> {
        if actuator != self.feed.pusher {
            return Ok(());
        }
        let now = Instant::now();
        match (end, self.loaded) {
            (true, Some(ball)) => {
                let high: Vec<u8> = (self.front().into_iter())
                    .filter(|(_, l)| *l)
                    .map(|(p, _)| p)
                    .collect();
                self.loaded = None;
                for pin in high {
                    self.pin(conn, pin, false)?;
                }
                self.after(now, self.feed.drop_ms, Ev::Entry(ball));
            }
            (false, None) if self.next < self.feed.balls.len() => {
                let ball = self.next;
                self.next += 1;
                self.after(now, self.feed.roll_ms, Ev::Roll(ball));
            }
            _ => {}
        }
        Ok(())
    }

    fn pin(&self, conn: &mut Conn, pin: u8, level: bool) -> io::Result<()> {
        conn.send(&Link::Pin {
            addr: self.feed.addr,
            pin,
            level,
        })
    }

    /// Runs the events that are due; `position` gives an actuator's rod position.
    pub(crate) fn tick(
        &mut self,
        conn: &mut Conn,
        names: &[String],
        position: &dyn Fn(usize) -> Position,
    ) -> io::Result<()> {
        loop {
            let now = Instant::now();
            let Some(i) = (0..self.due.len())
                .filter(|&i| self.due[i].0 <= now)
                .min_by_key(|&i| self.due[i].0)
            else {
                return Ok(());
            };
            let (_, ev) = self.due.remove(i);
            match ev {
                Ev::Pin(pin, level) => self.pin(conn, pin, level)?,
                Ev::Entry(ball) => {
                    self.pin(conn, self.feed.entry, true)?;
                    self.after(now, ENTRY_PULSE_MS, Ev::Pin(self.feed.entry, false));
                    self.after(now, self.feed.fall_ms, Ev::At(ball, 0));
                }
                Ev::At(ball, gate) => match self.feed.gates.get(gate).copied() {
                    Some(a) if position(a) == Position::End => {
                        self.land(conn, now, ball, gate + 1)?
                    }
                    Some(a) => {
                        if matches!(position(a), Position::Extending | Position::Retracting) {
                            if let (Some(m), Some(n)) = (self.met.get_mut(ball), names.get(a)) {
                                m.push(n.clone());
                            }
                        }
                        self.after(now, self.feed.fall_ms, Ev::At(ball, gate + 1));
                    }
                    None => self.land(conn, now, ball, gate + 1)?,
                },
                Ev::Roll(ball) => {
                    self.loaded = Some(ball);
                    self.send_levels(conn)?;
                }
            }
        }
    }

    fn land(&mut self, conn: &mut Conn, now: Instant, ball: usize, bin: usize) -> io::Result<()> {
        if let Some(&pin) = bin.checked_sub(1).and_then(|i| self.feed.bins.get(i)) {
            self.pin(conn, pin, true)?;
            self.after(now, ENTRY_PULSE_MS, Ev::Pin(pin, false));
        }
        let met_moving = self
            .met
            .get_mut(ball)
            .map(std::mem::take)
            .unwrap_or_default();
        let _ = self.landed.send(Landing {
            ball,
            bin,
            met_moving,
            at: now.duration_since(self.start),
        });
        Ok(())
    }
}
