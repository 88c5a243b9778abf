//! The machine, in real time, on the medium: a `Peer::Plant` client that watches the nodes'
//! valve outputs and drives their limit switches after each actuator's travel time, with
//! the same plant rules as `sim` and `verify` (`node_fw::cylinder`: valve, sensors, travel).
//! Plants are wired by node address and pin number, so a node never learns which role it
//! plays. It also runs a sorting station's ball feed ([`crate::live_feed`]) or a robot's
//! declared motors and operator inputs ([`crate::live_motor`]).

use std::collections::HashMap;
use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

use config_schema::wire::medium::{Link, Peer};
use node_fw::cylinder::{Command, Cylinder, Outcome as RodOutcome, Position, Rod, Valve, Valves};
use node_fw::sim::Plant;

use medium::Conn;
use robot_compiler::compile::Compiled;
use robot_compiler::ir::Step;

use crate::error::NetError;
use crate::live_feed::{BallFeed, Landing, Running};
use crate::live_motor::{self, Motion, Motors, Operate};

/// One actuator, wired by node address and board pin numbers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Actuator {
    pub name: String,
    pub addr: u16,
    /// Double acting: (extend, retract) solenoid pins. Single acting: (valve, valve).
    pub valves: (u8, u8),
    pub double: bool,
    pub home: Option<u8>,
    pub end: Option<u8>,
    /// Full-stroke times (extend, retract), ms.
    pub travel_ms: (u64, u64),
}

impl Actuator {
    /// Its wiring, for the rules of `node_fw::cylinder` (board pins).
    fn cylinder(&self) -> Cylinder {
        let valve = if self.double {
            Valve::Double {
                extend: self.valves.0,
                retract: self.valves.1,
            }
        } else {
            Valve::Single {
                valve: self.valves.0,
            }
        };
        Cylinder {
            valve,
            home: self.home,
            end: self.end,
        }
    }
}

/// A stroke the plant saw commanded: the step (`VC+`) and when the medium saw the valve
/// output change (its clock, `Medium::now`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Stroke {
    pub at: Duration,
    pub step: Step,
    /// `false`: the valve was commanded but the rod is jammed (an injected fault).
    pub moved: bool,
    /// The table generation the commanding node ran (`Link::Running`; 0: it never said).
    pub generation: u32,
}

impl std::fmt::Display for Stroke {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.step.fmt(f)
    }
}

/// What the plant hears from the medium: a node's output level, or its generation.
enum Heard {
    Output((u64, u16, u8, bool)),
    Running(u16, u32),
}

/// The actuators of a compiled robot, on the nodes its roles are assigned to.
pub fn actuators(c: &Compiled) -> Result<Vec<Actuator>, NetError> {
    let (plants, _) = robot_analysis::sim::plants(c).map_err(|e| NetError::Robot(e.to_string()))?;
    let mut out = Vec::new();
    for p in plants {
        let Some(role) = c.ir.roles.get(p.node()) else {
            continue;
        };
        let opin = |i: u8| role.outputs.get(usize::from(i)).map(|o| o.pin);
        let ipin = |i: Option<u8>| i.and_then(|i| role.inputs.get(usize::from(i)).map(|x| x.pin));
        let travel_ms = p.travel().unwrap_or((0, 0));
        match &p {
            Plant::DoubleActing(d) => {
                let (Some(e), Some(r)) = (opin(d.extend_out), opin(d.retract_out)) else {
                    continue;
                };
                out.push(Actuator {
                    name: d.name.clone(),
                    addr: role.address,
                    valves: (e, r),
                    double: true,
                    home: ipin(d.home_in),
                    end: ipin(d.end_in),
                    travel_ms,
                });
            }
            Plant::SingleActing(s) => {
                let Some(v) = opin(s.out) else { continue };
                out.push(Actuator {
                    name: s.name.clone(),
                    addr: role.address,
                    valves: (v, v),
                    double: false,
                    home: ipin(s.home_in),
                    end: ipin(s.end_in),
                    travel_ms,
                });
            }
            Plant::Button(_) => {}
            // Host-simulation plants: not driven in real time.
            Plant::Motor(_) | Plant::Driven(_) | Plant::Switch(_) => {}
        }
    }
    Ok(out)
}

/// A fault the plant injects: from the `after`-th step it sees on (0: at once), an
/// actuator is jammed (valve commands move nothing) or one of its limit switches stays open.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Injection {
    pub after: usize,
    /// Index into the plant's actuators.
    pub actuator: usize,
    pub kind: Jam,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Jam {
    /// The rod does not move any more (a motion under way completes).
    Stuck,
    /// The end (`true`) or home switch never closes again.
    SwitchOpen { end: bool },
}

struct State {
    rod: Rod,
    /// When the current motion arrives (a new command replaces it).
    arrival: Option<Instant>,
    stuck: bool,
    /// An open switch: (home, end).
    open: (bool, bool),
}

impl State {
    /// The levels of the actuator's limit switches for where its rod is.
    fn switches(&self) -> (bool, bool) {
        let (home, end) = self.rod.position().sensors();
        (home && !self.open.0, end && !self.open.1)
    }
}

fn send_switches(conn: &mut Conn, a: &Actuator, s: &State) -> io::Result<()> {
    let (home, end) = s.switches();
    for (pin, level) in [(a.home, home), (a.end, end)] {
        if let Some(pin) = pin {
            conn.send(&Link::Pin {
                addr: a.addr,
                pin,
                level,
            })?;
        }
    }
    Ok(())
}

fn rest() -> State {
    State {
        rod: Rod::Home,
        arrival: None,
        stuck: false,
        open: (false, false),
    }
}

/// Connects to the medium as the plant and drives every limit switch to the rest position
/// (rods home). When this returns the medium routes every node output to the plant and
/// has passed the levels on to the nodes, ahead of anything sent after it (a START right
/// after wiring a node new to the plant finds its switches set, and the plant sees the
/// valve it opens).
pub fn attach(medium: SocketAddr, actuators: &[Actuator]) -> io::Result<Conn> {
    let mut conn = Conn::join(medium, Peer::Plant)?;
    for a in actuators {
        send_switches(&mut conn, a, &rest())?;
    }
    conn.sync()?;
    Ok(conn)
}

/// [`attach`], with a sorting station's front ball at its colour sensors: its levels are at
/// the sensing node when this returns.
pub fn attach_fed(medium: SocketAddr, actuators: &[Actuator], feed: &BallFeed) -> io::Result<Conn> {
    let mut conn = Conn::join(medium, Peer::Plant)?;
    for a in actuators {
        send_switches(&mut conn, a, &rest())?;
    }
    let front = feed.balls.first().map_or(&[][..], Vec::as_slice);
    for (i, &pin) in feed.sensors.iter().enumerate() {
        let level = front.get(i).copied().unwrap_or(false);
        conn.send(&Link::Pin {
            addr: feed.addr,
            pin,
            level,
        })?;
    }
    conn.sync()?;
    Ok(conn)
}

/// [`attach`], with the declared motors home (their home sensors closed, the end ones
/// open) and the operator's inputs open: set at the nodes when this returns.
pub fn attach_motors(
    medium: SocketAddr,
    actuators: &[Actuator],
    motors: &Motors,
) -> io::Result<Conn> {
    let mut conn = Conn::join(medium, Peer::Plant)?;
    for a in actuators {
        send_switches(&mut conn, a, &rest())?;
    }
    for (addr, pin, level) in live_motor::rest_levels(motors) {
        conn.send(&Link::Pin { addr, pin, level })?;
    }
    conn.sync()?;
    Ok(conn)
}

/// When the medium at `medium` started, on this process's clock: its clock asked
/// (`Link::Clock`), the answer taken to have left it halfway between the ask and its
/// arrival. The live motors time their carriages on it. `None`: no answer within `within`.
pub fn medium_start(medium: SocketAddr, within: Duration) -> io::Result<Option<Instant>> {
    let mut conn = Conn::join(medium, Peer::Monitor)?;
    let asked = Instant::now();
    conn.send(&Link::Clock)?;
    let now = conn.recv(asked + within, |link| match link {
        Link::Now { at_us } => Some(at_us),
        _ => None,
    })?;
    Ok(now.and_then(|at_us| {
        let here = asked + Instant::now().duration_since(asked) / 2;
        here.checked_sub(Duration::from_micros(at_us))
    }))
}

/// Runs the plant until `stop` is set or the medium goes away. Every step is sent to
/// `steps` as it starts, stamped with the medium's clock.
pub fn run(
    medium: SocketAddr,
    actuators: Vec<Actuator>,
    steps: Sender<Stroke>,
    stop: Arc<AtomicBool>,
) -> io::Result<()> {
    let conn = attach(medium, &actuators)?;
    run_attached(conn, actuators, None, steps, stop)
}

/// [`run`] on a connection made by [`attach`], with an optional injected fault.
pub fn run_attached(
    conn: Conn,
    actuators: Vec<Actuator>,
    injection: Option<Injection>,
    steps: Sender<Stroke>,
    stop: Arc<AtomicBool>,
) -> io::Result<()> {
    run_with(conn, actuators, injection, None, None, steps, stop)
}

/// [`run_attached`] with a sorting station's ball feed ([`crate::live_feed`]), on a
/// connection made by [`attach_fed`]; every ball that lands is sent to `landed`, stamped
/// from `start` (the medium's clock zero, [`medium_start`], stamps them as the steps are).
pub fn run_fed(
    conn: Conn,
    actuators: Vec<Actuator>,
    (feed, start): (BallFeed, Instant),
    landed: Sender<Landing>,
    steps: Sender<Stroke>,
    stop: Arc<AtomicBool>,
) -> io::Result<()> {
    let feed = Running::new(feed, landed, start);
    run_with(conn, actuators, None, Some(feed), None, steps, stop)
}

/// [`run_attached`] with the declared motors and operator inputs ([`crate::live_motor`]),
/// on a connection made by [`attach_motors`]: the operator's requests come from
/// `operate`, every motion and input change goes to `seen`, stamped with the clock of the
/// medium started at `medium_start`.
pub fn run_motors(
    conn: Conn,
    actuators: Vec<Actuator>,
    plant: (Motors, Receiver<Operate>, Sender<Motion>, Instant),
    steps: Sender<Stroke>,
    stop: Arc<AtomicBool>,
) -> io::Result<()> {
    let (motors, operate, seen, medium_start) = plant;
    let motors = live_motor::Running::new(motors, operate, seen, medium_start);
    run_with(conn, actuators, None, None, Some(motors), steps, stop)
}

fn run_with(
    mut conn: Conn,
    actuators: Vec<Actuator>,
    injection: Option<Injection>,
    mut feed: Option<Running>,
    mut motors: Option<live_motor::Running>,
    steps: Sender<Stroke>,
    stop: Arc<AtomicBool>,
) -> io::Result<()> {
    // A motion ends on a timed wait: let it end on time, not up to 50 us late.
    medium::precise_timers();
    let names: Vec<String> = actuators.iter().map(|a| a.name.clone()).collect();
    // Motions are timed on the medium's clock, from its stamp of the valve change (`at_us`),
    // in microseconds: not from when this process got round to the change, nor rounded to
    // a millisecond. Where the medium's zero is on this process's clock is estimated from
    // below, as the earliest any stamped message could have been sent: the least of
    // (received - stamp) over every one heard (a stamp is never after its receipt; the
    // least is off by the shortest relay, tens of microseconds).
    let mut medium_zero: Option<Instant> = None;
    let mut states: Vec<State> = actuators.iter().map(|_| rest()).collect();
    let mut outputs: HashMap<(u16, u8), bool> = HashMap::new();
    // The generation each node says it runs.
    let mut running: HashMap<u16, u32> = HashMap::new();
    let mut next_refresh = Instant::now();
    let mut seen_steps = 0usize;
    let inject = |states: &mut [State], seen: usize| {
        let Some(i) = injection.filter(|i| i.after == seen) else {
            return;
        };
        if let Some(s) = states.get_mut(i.actuator) {
            match i.kind {
                Jam::Stuck => s.stuck = true,
                Jam::SwitchOpen { end: true } => s.open.1 = true,
                Jam::SwitchOpen { end: false } => s.open.0 = true,
            }
        }
    };
    inject(&mut states, 0);
    while !stop.load(Ordering::Relaxed) {
        let now = Instant::now();
        // Arrivals: the far switch closes.
        for (i, (a, s)) in actuators.iter().zip(states.iter_mut()).enumerate() {
            if s.arrival.is_some_and(|due| due <= now) {
                s.arrival = None;
                if s.rod.arrive().is_some() {
                    send_switches(&mut conn, a, s)?;
                    if let Some(f) = feed.as_mut() {
                        f.arrived(&mut conn, i, s.rod.position() == Position::End)?;
                    }
                }
            }
        }
        if let Some(m) = motors.as_mut() {
            m.tick(&mut conn)?;
        }
        if let Some(f) = feed.as_mut() {
            f.tick(&mut conn, &names, &|a| {
                states.get(a).map_or(Position::Home, |s| s.rod.position())
            })?;
        }
        // The switches' levels, again and again: a node that (re)starts or gets a new table
        // learns where the rods are (levels, not edges: repeats raise no event).
        if now >= next_refresh {
            next_refresh = now + Duration::from_millis(200);
            for (a, s) in actuators.iter().zip(&states) {
                send_switches(&mut conn, a, s)?;
            }
            if let Some(f) = &feed {
                f.send_levels(&mut conn)?;
            }
            if let Some(m) = &motors {
                m.send_levels(&mut conn)?;
            }
        }
        let wake = states
            .iter()
            .filter_map(|s| s.arrival)
            .chain(feed.as_ref().and_then(Running::wake))
            .chain(motors.as_ref().map(live_motor::Running::wake))
            .chain([next_refresh])
            .min()
            .unwrap_or(next_refresh);
        let heard = conn.recv(wake, |l| match l {
            Link::Running { addr, generation } => Some(Heard::Running(addr, generation)),
            _ => l.output_seen().map(Heard::Output),
        });
        let seen = match heard {
            Ok(Some(Heard::Output(seen))) => seen,
            Ok(Some(Heard::Running(addr, generation))) => {
                running.insert(addr, generation);
                continue;
            }
            Ok(None) => continue,
            Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => return Ok(()),
            Err(e) => return Err(e),
        };
        let (at_us, addr, pin, level) = seen;
        let heard_at = Instant::now();
        if let Some(zero) = heard_at.checked_sub(Duration::from_micros(at_us)) {
            medium_zero = Some(medium_zero.map_or(zero, |z| z.min(zero)));
        }
        if let Some(m) = motors.as_mut() {
            m.output(&mut conn, addr, pin, level, at_us)?;
        }
        let generation = running.get(&addr).copied().unwrap_or(0);
        let was = outputs.insert((addr, pin), level).unwrap_or(false);
        let (rose, fell) = (level && !was, !level && was);
        for (a, s) in actuators.iter().zip(states.iter_mut()) {
            if a.addr != addr {
                continue;
            }
            // Each change the medium saw is a step of its own (no conflict in real time).
            let mut step = Valves::default();
            if rose || fell {
                a.cylinder().output(&mut step, pin, level);
            }
            let Some(Command::Drive(extend)) = step.command() else {
                continue;
            };
            if s.stuck {
                if s.rod.position() != Position::from_command(extend) {
                    let _ = steps.send(Stroke {
                        at: Duration::from_micros(at_us),
                        step: Step {
                            actuator: a.name.clone(),
                            extend,
                        },
                        moved: false,
                        generation,
                    });
                }
                continue;
            }
            let us = (a.travel_ms.0 * 1000, a.travel_ms.1 * 1000);
            let outcome = s.rod.command(at_us, extend, us);
            let arrive = match outcome {
                RodOutcome::Nothing => continue,
                RodOutcome::Left { arrive, .. } | RodOutcome::Reversed { arrive } => arrive,
            };
            let _ = steps.send(Stroke {
                at: Duration::from_micros(at_us),
                step: Step {
                    actuator: a.name.clone(),
                    extend,
                },
                moved: true,
                generation,
            });
            seen_steps += 1;
            if let RodOutcome::Left { .. } = outcome {
                send_switches(&mut conn, a, s)?;
            }
            s.arrival = Some(match medium_zero {
                Some(zero) => zero + Duration::from_micros(arrive),
                None => heard_at + Duration::from_micros(arrive.saturating_sub(at_us)),
            });
        }
        inject(&mut states, seen_steps);
    }
    Ok(())
}
