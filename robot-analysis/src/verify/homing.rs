//! The homing proof: from every place the actuators can rest in when the machine comes up
//! unhomed (each home, at its end or stopped in between; a held valve output high or low),
//! every chart in its initial state, the HOME command given once (any STARTs before it),
//! every interleaving the cycle's exploration has (radio delays, timers, motions) ends with
//! the machine idle: every chart in its idle state, every actuator where the cycle starts,
//! nothing in flight. On the way: no interlock holds, no double actuation, nothing moves
//! before HOME, and the motions are the homing steps in order (a skipped one aside).

use node_fw::cylinder::{Cylinder, Valve};
use node_fw::ecc::Engine;

use super::place::{Place, Rest};
use super::{run, ExploreOptions, Model, Report, Sys};

/// The outcome of a homing exploration.
#[derive(Debug, Clone)]
pub struct HomingReport {
    /// Combinations of actuator positions explored (3 per actuator).
    pub positions: usize,
    /// Held valve outputs (start level `Hold`) explored high and low, per position.
    pub held: usize,
    /// The homing sequence, as declared or derived.
    pub homing: String,
    pub report: Report,
}

impl HomingReport {
    pub fn ok(&self) -> bool {
        self.report.ok()
    }

    /// The text `config-tool verify` prints after the cycle's.
    pub fn render(&self, name: &str, interlocks: usize) -> String {
        let held = match self.held {
            0 => String::new(),
            h => format!(" x {} held valve levels", 1usize << h),
        };
        let mut o = self.report.figures(
            &format!(
                "{name}: homing \"{}\" from {} start positions{held}: ",
                self.homing, self.positions
            ),
            "homed (idle)",
        );
        self.report.verdict(
            &mut o,
            &format!(
                "ok: homing reaches the idle state from every start position, nothing moves \
                 before HOME, homing conformance, {interlocks} interlock(s), no double \
                 actuation, no engine fault, a fault stops every node"
            ),
        );
        o
    }
}

/// Explores homing (module doc); `None` if the robot's tables do not home (explicit
/// charts).
pub fn explore_homing(model: &Model<'_>, opts: ExploreOptions) -> Option<HomingReport> {
    model.home?;
    let roots = roots(model);
    let report = run(model, roots, opts);
    let homing: Vec<String> = model.c.ir.homing.iter().map(|s| s.to_string()).collect();
    Some(HomingReport {
        positions: 3usize.saturating_pow(model.acts.len() as u32),
        held: held_valves(model).len(),
        homing: homing.join(" "),
        report,
    })
}

/// Homing's initial states: every start position of the actuators, with every level of
/// the held valves, each with the positions a counterexample from it names.
pub(super) fn roots<'m>(model: &'m Model<'_>) -> impl Iterator<Item = (Sys, Option<String>)> + 'm {
    let held = held_valves(model);
    let k = model.acts.len();
    // An odometer: the rods' rests (3 each, the first rod fastest), then the held
    // valves' levels (2 each). Made one at a time as the search takes them: it stops at
    // `max_states`, and 3^k of them built at once (14 rods: 4.8 million) ran out of
    // memory before.
    let radix: Vec<u8> = (std::iter::repeat_n(3, k))
        .chain(std::iter::repeat_n(2, held.len()))
        .collect();
    let first = vec![0u8; radix.len()];
    let odometer = std::iter::successors(Some(first), move |digits| {
        let mut next = digits.clone();
        for (d, r) in next.iter_mut().zip(&radix) {
            *d += 1;
            if *d < *r {
                return Some(next);
            }
            *d = 0;
        }
        None
    });
    odometer.map(move |digits| {
        let (rests, levels) = digits.split_at(k);
        let rests: Vec<Rest> = rests.iter().map(|&d| Rest::ALL[usize::from(d)]).collect();
        let mut before = vec![0u16; model.n()];
        for (&high, &(node, output)) in levels.iter().zip(&held) {
            if high != 0 {
                before[node] |= 1 << (output & 15);
            }
        }
        start(model, &rests, &before, &held)
    })
}

/// The valve outputs whose start level is `Hold`, as (node, output).
fn held_valves(model: &Model<'_>) -> Vec<(usize, u8)> {
    let mut held = Vec::new();
    for a in &model.acts {
        let (mask, _) = model.tables[a.node].start_drive();
        for o in valve_outputs(&a.cylinder) {
            if mask & (1 << (o & 15)) == 0 && !held.contains(&(a.node, o)) {
                held.push((a.node, o));
            }
        }
    }
    held
}

fn valve_outputs(c: &Cylinder) -> Vec<u8> {
    match c.valve {
        Valve::Double { extend, retract } => vec![extend, retract],
        Valve::Single { valve } => vec![valve],
    }
}

/// What a valve's output levels `outputs` command: a monostable valve its level, a bistable
/// one the solenoid energised (none or both: nothing).
fn drive(c: &Cylinder, outputs: u16) -> Option<bool> {
    let on = |o: u8| outputs & (1 << (o & 15)) != 0;
    match c.valve {
        Valve::Single { valve } => Some(on(valve)),
        Valve::Double { extend, retract } => match (on(extend), on(retract)) {
            (true, false) => Some(true),
            (false, true) => Some(false),
            _ => None,
        },
    }
}

/// The unhomed machine with its rods at `rests` and held outputs at `before`: engines as a
/// boot (or, held high, a reset) leaves them, each rod where its valve's start levels take
/// it, the switches read there; with its label (`VC end, GR between; GR.valve held high`).
fn start(
    model: &Model<'_>,
    rests: &[Rest],
    before: &[u16],
    held: &[(usize, u8)],
) -> (Sys, Option<String>) {
    // On the model's indexes, built once: not one per start position and node.
    let mut engines: Vec<_> = (model.tables.iter().zip(&model.indexes).zip(before))
        .map(|((t, ix), &b)| Engine::new_indexed(t, ix, b))
        .collect();
    let mut pos = Vec::new();
    let mut names = Vec::new();
    for (a, rest) in model.acts.iter().zip(rests) {
        let e = &mut engines[a.node];
        let place = rest.place(drive(&a.cylinder, e.outputs()));
        let (home, end) = place.sensors();
        for (sensor, level) in [(a.cylinder.home, home), (a.cylinder.end, end)] {
            if let Some(pin) = sensor {
                e.sense(pin, level);
            }
        }
        names.push(match place {
            Place::Rod(p) if p.moving() => format!("{} {} ({})", a.name, rest.name(), place.name()),
            _ => format!("{} {}", a.name, rest.name()),
        });
        pos.push(place);
    }
    let high: Vec<String> = (held.iter())
        .filter(|&&(node, o)| before[node] & (1 << (o & 15)) != 0)
        .map(|&(node, o)| {
            let r = &model.c.ir.roles[node];
            r.outputs
                .get(usize::from(o))
                .map_or_else(|| format!("{}.#{o}", r.name), |x| x.name.clone())
        })
        .collect();
    let mut label = names.join(", ");
    if !high.is_empty() {
        label += &format!("; held high: {}", high.join(", "));
    }
    let n = model.n();
    let s = Sys {
        nodes: engines.iter().map(Engine::snapshot).collect(),
        timers: vec![0; n],
        pos,
        flight: Vec::new(),
        alarms: 0,
        progress: 0,
        homing: Some(false),
        ball: None,
        estop: None,
        regions: model.init.regions.clone(),
        switches: 0,
        sets: 0,
        latched: 0,
        uncleared: false,
    };
    (s, Some(label))
}
