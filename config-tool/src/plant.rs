//! The machine, in real time, on the medium: a `Peer::Plant` client that watches the nodes'
//! valve outputs and drives their limit switches after each actuator's travel time, with
//! the same rod model as `sim` (`node_fw::sim::Rod`). Plants are wired by node address and
//! pin number, so a node never learns which role it plays.

use std::collections::HashMap;
use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::Arc;
use std::time::{Duration, Instant};

use config_schema::wire::medium::{next_message, Link, Peer, MAX_LINK};
use node_fw::sim::{Plant, Rod, RodOutcome};

use crate::compile::Compiled;

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

/// An actuator starting a motion (`VC+`), seen by the plant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Step {
    pub at: Duration,
    pub actuator: String,
    pub plus: bool,
}

impl std::fmt::Display for Step {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}{}", self.actuator, if self.plus { '+' } else { '-' })
    }
}

/// The actuators of a compiled robot, on the nodes its roles are assigned to.
pub fn actuators(c: &Compiled) -> Result<Vec<Actuator>, String> {
    let (plants, _) = crate::sim::plants(c)?;
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
        }
    }
    Ok(out)
}

struct State {
    rod: Rod,
    /// When the current motion arrives (a new command replaces it).
    arrival: Option<Instant>,
}

fn send(stream: &mut TcpStream, link: &Link) -> io::Result<()> {
    let mut buf = [0u8; MAX_LINK];
    let n = link.emit(&mut buf).map_err(|_| io::Error::other("link"))?;
    stream.write_all(&buf[..n])
}

/// The levels of an actuator's limit switches for where its rod is.
fn send_switches(stream: &mut TcpStream, a: &Actuator, rod: Rod) -> io::Result<()> {
    let (home, end) = match rod {
        Rod::Home => (true, false),
        Rod::End => (false, true),
        Rod::Moving { .. } => (false, false),
    };
    for (pin, level) in [(a.home, home), (a.end, end)] {
        if let Some(pin) = pin {
            send(
                stream,
                &Link::Pin {
                    addr: a.addr,
                    pin,
                    level,
                },
            )?;
        }
    }
    Ok(())
}

/// Connects to the medium as the plant and drives every limit switch to the rest position
/// (rods home): when this returns, the hello and the levels are on their way to the nodes,
/// ahead of anything sent after it (a START right after wiring a node new to the plant
/// finds its switches set).
pub fn attach(medium: SocketAddr, actuators: &[Actuator]) -> io::Result<TcpStream> {
    let mut stream = TcpStream::connect_timeout(&medium, Duration::from_secs(5))?;
    stream.set_nodelay(true)?;
    send(&mut stream, &Link::Hello(Peer::Plant))?;
    for a in actuators {
        send_switches(&mut stream, a, Rod::Home)?;
    }
    Ok(stream)
}

/// Runs the plant until `stop` is set or the medium goes away. Every step is sent to
/// `steps` as it starts.
pub fn run(
    medium: SocketAddr,
    actuators: Vec<Actuator>,
    steps: Sender<Step>,
    stop: Arc<AtomicBool>,
) -> io::Result<()> {
    let stream = attach(medium, &actuators)?;
    run_attached(stream, actuators, steps, stop)
}

/// [`run`] on a connection made by [`attach`].
pub fn run_attached(
    mut stream: TcpStream,
    actuators: Vec<Actuator>,
    steps: Sender<Step>,
    stop: Arc<AtomicBool>,
) -> io::Result<()> {
    let start = Instant::now();
    let ms = |t: Instant| t.duration_since(start).as_millis() as u64;
    let mut states: Vec<State> = actuators
        .iter()
        .map(|_| State {
            rod: Rod::Home,
            arrival: None,
        })
        .collect();
    let mut outputs: HashMap<(u16, u8), bool> = HashMap::new();
    let mut buf = Vec::new();
    let mut next_refresh = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        let now = Instant::now();
        // Arrivals: the far switch closes.
        for (a, s) in actuators.iter().zip(states.iter_mut()) {
            if s.arrival.is_some_and(|due| due <= now) {
                s.arrival = None;
                if let Some(end) = s.rod.arrive() {
                    if let Some(pin) = if end { a.end } else { a.home } {
                        send(
                            &mut stream,
                            &Link::Pin {
                                addr: a.addr,
                                pin,
                                level: true,
                            },
                        )?;
                    }
                }
            }
        }
        // The switches' levels, again and again: a node that (re)starts or gets a new table
        // learns where the rods are (levels, not edges: repeats raise no event).
        if now >= next_refresh {
            next_refresh = now + Duration::from_millis(200);
            for (a, s) in actuators.iter().zip(&states) {
                send_switches(&mut stream, a, s.rod)?;
            }
        }
        let wake = states
            .iter()
            .filter_map(|s| s.arrival)
            .chain([next_refresh])
            .min()
            .unwrap_or(next_refresh);
        stream.set_read_timeout(Some(
            wake.saturating_duration_since(Instant::now())
                .max(Duration::from_millis(1)),
        ))?;
        let mut chunk = [0u8; 1024];
        match stream.read(&mut chunk) {
            Ok(0) => return Ok(()),
            Ok(n) => buf.extend_from_slice(&chunk[..n]),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) => {}
            Err(e) => return Err(e),
        }
        while let Some(body) = next_message(&buf) {
            if let Ok(Link::Pin { addr, pin, level }) = Link::parse(&buf[body.clone()]) {
                let rose = level && !outputs.get(&(addr, pin)).copied().unwrap_or(false);
                let fell = !level && outputs.get(&(addr, pin)).copied().unwrap_or(false);
                outputs.insert((addr, pin), level);
                for (a, s) in actuators.iter().zip(states.iter_mut()) {
                    if a.addr != addr {
                        continue;
                    }
                    // Bistable: the solenoid last energised decides. Monostable: the level.
                    let extend = if a.double {
                        match (pin == a.valves.0 && rose, pin == a.valves.1 && rose) {
                            (true, _) => Some(true),
                            (_, true) => Some(false),
                            _ => None,
                        }
                    } else if pin == a.valves.0 && (rose || fell) {
                        Some(level)
                    } else {
                        None
                    };
                    let Some(extend) = extend else { continue };
                    let now = Instant::now();
                    let outcome = s.rod.command(ms(now), extend, a.travel_ms);
                    let arrive = match outcome {
                        RodOutcome::Nothing => continue,
                        RodOutcome::Left { arrive, .. } | RodOutcome::Reversed { arrive } => arrive,
                    };
                    let _ = steps.send(Step {
                        at: now.duration_since(start),
                        actuator: a.name.clone(),
                        plus: extend,
                    });
                    if let RodOutcome::Left { from_end, .. } = outcome {
                        if let Some(pin) = if from_end { a.end } else { a.home } {
                            send(
                                &mut stream,
                                &Link::Pin {
                                    addr: a.addr,
                                    pin,
                                    level: false,
                                },
                            )?;
                        }
                    }
                    s.arrival = Some(start + Duration::from_millis(arrive));
                }
            }
            buf.drain(..body.end);
        }
    }
    Ok(())
}
