//! `sim` of a sorting station (`sorting:` of a robot, docs/selecting-automata.md): the
//! compiled blobs on `node_fw::sim::World` with the robot's actuators and a ball feed
//! ([`node_fw::sim::Feed`]); START pressed once, the station sorts the whole magazine and
//! stops when it is empty. Per ball: its colour, which automata took it, its bin, and
//! every EOS; [`expected`] gives the same from the reference semantics.

use std::fmt::Write;

use node_fw::sim::{Feed, TraceEntry, What};
use robot_compiler::automata::{Automaton, Colour};
use robot_compiler::sorting::Sorting;
use robot_compiler::Compiled;

use crate::sim::{self, SimulationError};

/// Virtual-time bound of a whole feed: this, and [`BALL_LIMIT_MS`] more per ball.
pub const FEED_LIMIT_MS: u64 = 3_600_000;

/// Virtual time a feed is given per ball on top of [`FEED_LIMIT_MS`] (the ball sorter
/// takes about 0.5 s a ball: a feed of 8,000, which `--random` takes, ran out of the hour).
pub const BALL_LIMIT_MS: u64 = 10_000;

/// Why a station could not be simulated.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SortError {
    #[error("the robot declares no sorting station (`sorting:`)")]
    NoStation,
    #[error("the station names `{0}`, which the compiled robot does not drive")]
    Missing(String),
    /// A `--feed` token that is no colour of the table.
    #[error("feed item {index} `{token}` is no colour of the sensor table ({colours})")]
    NoColour {
        index: usize,
        token: String,
        colours: String,
    },
    /// A feed token that abbreviates several colours.
    #[error("feed item {index} `{token}` could be {colours}: write the colour out")]
    Ambiguous {
        index: usize,
        token: String,
        colours: String,
    },
    #[error(transparent)]
    Sim(#[from] SimulationError),
}

/// What happened to one ball.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ball {
    pub colour: String,
    /// The automata that took it (some transition fired), in declaration order.
    pub took: Vec<String>,
    /// Its bin (1-based); `None` if it never landed.
    pub bin: Option<usize>,
    /// The automata whose sequence ended with it (an EOS each).
    pub eos: Vec<String>,
}

/// When an automaton took a ball, or ended a sequence with it (the first of each per
/// ball and automaton, as [`Ball::took`] and [`Ball::eos`] list them).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Selection {
    pub t_ms: u64,
    /// The ball (0-based).
    pub ball: usize,
    pub automaton: String,
    /// An EOS (else: it took the ball).
    pub eos: bool,
}

/// A run of the station.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SortRun {
    pub balls: Vec<Ball>,
    pub duration_ms: u64,
    /// Faults, as text; balls that met a moving gate; pusher strokes while a gate moved.
    pub faults: Vec<String>,
    /// Why the station stopped with balls left in the magazine, if it did (and did not
    /// fault): as text, with the times.
    pub stopped: Option<String>,
    /// Every trace entry, as text.
    pub trace: Vec<String>,
    /// Every trace entry (for `--timeline`).
    pub entries: Vec<TraceEntry>,
    /// Each ball's selections, in time order.
    pub selections: Vec<Selection>,
}

impl SortRun {
    /// Every ball landed in one bin, nothing faulted.
    pub fn ok(&self) -> bool {
        self.faults.is_empty() && self.balls.iter().all(|b| b.bin.is_some())
    }

    /// One line per ball, then the bins' counts.
    pub fn report(&self) -> String {
        let mut o = String::new();
        for (i, b) in self.balls.iter().enumerate() {
            let took = if b.took.is_empty() {
                String::from("-")
            } else {
                b.took.join(", ")
            };
            let bin = b
                .bin
                .map_or_else(|| String::from("none"), |b| b.to_string());
            let _ = write!(
                o,
                "ball {:>3}: {:<8} taken by {took:<10} bin {bin}",
                i + 1,
                b.colour
            );
            for a in &b.eos {
                let _ = write!(o, "  EOS {a}");
            }
            o.push('\n');
        }
        for f in &self.faults {
            let _ = writeln!(o, "  FAULT {f}");
        }
        if let Some(why) = &self.stopped {
            let _ = writeln!(o, "  STOPPED {why}");
        }
        let bins = self.balls.iter().filter_map(|b| b.bin).max().unwrap_or(0);
        let counts: Vec<String> = (1..=bins.max(1))
            .map(|n| {
                let k = self.balls.iter().filter(|b| b.bin == Some(n)).count();
                format!("bin {n}: {k}")
            })
            .collect();
        let eos: usize = self.balls.iter().map(|b| b.eos.len()).sum();
        let _ = writeln!(
            o,
            "{} ball(s) in {} ms: {}; {eos} EOS",
            self.balls.len(),
            self.duration_ms,
            counts.join(", ")
        );
        let _ = writeln!(o, "{}", if self.ok() { "ok" } else { "FAILED" });
        o
    }
}

/// A feed of `balls` balls, each of a colour of the truth table (what the sensors tell
/// apart) drawn uniformly from a generator seeded with `seed`: the same seed, the same
/// feed (ChaCha, `rand::rngs::StdRng`, pinned by `Cargo.lock`).
pub fn random_feed(s: &Sorting, balls: usize, seed: u64) -> Vec<String> {
    use rand::{Rng, SeedableRng};
    let colours: Vec<&str> = s.table.iter().map(|r| r.colour.as_str()).collect();
    if colours.is_empty() {
        return Vec::new();
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    (0..balls)
        .map(|_| colours[rng.random_range(0..colours.len())].to_string())
        .collect()
}

/// A feed written `B G O` or `black gray orange`: each item a colour of the table, or
/// the start of exactly one.
pub fn parse_feed(s: &Sorting, text: &str) -> Result<Vec<String>, SortError> {
    let colours: Vec<&str> = s.table.iter().map(|r| r.colour.as_str()).collect();
    let mut out = Vec::new();
    for (index, token) in text.split_whitespace().enumerate() {
        let t = token.to_lowercase();
        if let Some(c) = colours.iter().find(|c| c.to_lowercase() == t) {
            out.push(c.to_string());
            continue;
        }
        let matches: Vec<&str> = (colours.iter().copied())
            .filter(|c| c.to_lowercase().starts_with(&t))
            .collect();
        match matches.as_slice() {
            [c] => out.push(c.to_string()),
            [] => {
                return Err(SortError::NoColour {
                    index: index + 1,
                    token: token.to_string(),
                    colours: colours.join(", "),
                })
            }
            many => {
                return Err(SortError::Ambiguous {
                    index: index + 1,
                    token: token.to_string(),
                    colours: many.join(", "),
                })
            }
        }
    }
    Ok(out)
}

/// The bins the reference semantics gives `feed`: each automaton runs on every ball;
/// a ball goes to the bin of the first automaton (in `gates` order) that takes it, else
/// to the last bin. `automata[i]` selects for bin i + 1.
pub fn expected(automata: &[&Automaton], feed: &[String]) -> Vec<Ball> {
    let mut configs: Vec<_> = automata
        .iter()
        .map(|a| crate::automata::Config::initial(a))
        .collect();
    let mut out = Vec::new();
    for colour in feed {
        let mut ball = Ball {
            colour: colour.clone(),
            took: Vec::new(),
            bin: None,
            eos: Vec::new(),
        };
        for (i, (a, cfg)) in automata.iter().zip(&mut configs).enumerate() {
            let Some(c) = a.colours.iter().position(|n| n == colour) else {
                continue; // a colour it does not read: ignored
            };
            let step = cfg.step(a, Colour(c as u8));
            if step.taken() {
                ball.took.push(a.name.clone());
                ball.bin.get_or_insert(i + 1);
            }
            if step.is_eos() {
                ball.eos.push(a.name.clone());
            }
        }
        ball.bin.get_or_insert(automata.len() + 1);
        out.push(ball);
    }
    out
}

/// Runs the station on `feed` (the robot's `sorting.feed` if `None`).
pub fn simulate(c: &Compiled, feed: Option<&[String]>) -> Result<SortRun, SortError> {
    let s = c.robot.sorting.as_ref().ok_or(SortError::NoStation)?;
    let feed: Vec<String> = feed.map_or_else(|| s.feed.clone(), <[String]>::to_vec);
    let tables = sim::tables(c)?;
    let (mut world, button) = sim::world(c, &tables)?;
    let missing = |n: &str| SortError::Missing(n.to_string());
    let node = (c.ir.roles.iter())
        .position(|r| r.name == s.role)
        .ok_or_else(|| missing(&s.role))?;
    let input = |n: &str| {
        (c.ir.roles[node].inputs.iter())
            .position(|i| i.name == n)
            .map(|i| i as u8)
            .ok_or_else(|| missing(n))
    };
    let plant = |n: &str| world.plant_by_name(n).ok_or_else(|| missing(n));
    let sensors = s
        .sensors
        .iter()
        .map(|n| input(n))
        .collect::<Result<_, _>>()?;
    let gates = (s.gates.iter())
        .map(|g| plant(g.split_once('/').map_or(g.as_str(), |(_, a)| a)))
        .collect::<Result<Vec<_>, _>>()?;
    let balls = (feed.iter())
        .map(|f| s.levels(f).map(<[bool]>::to_vec).ok_or_else(|| missing(f)))
        .collect::<Result<_, _>>()?;
    let pusher = plant(&s.pusher)?;
    let bins = (s.bins.iter())
        .map(|n| input(n))
        .collect::<Result<_, _>>()?;
    let gate_plants = gates.clone();
    let f = Feed {
        node,
        pusher,
        sensors,
        entry: input(&s.entry)?,
        balls,
        gates,
        bins,
        drop_ms: u64::from(s.drop_ms),
        fall_ms: u64::from(s.fall_ms),
        roll_ms: u64::from(s.roll_ms),
    };
    world
        .add_feed(f)
        .map_err(|e| SortError::Sim(SimulationError::World(e)))?;
    world
        .press(button)
        .map_err(|e| SortError::Sim(SimulationError::World(e)))?;
    let end = world
        .run_until_idle(
            FEED_LIMIT_MS.saturating_add(BALL_LIMIT_MS.saturating_mul(feed.len() as u64)),
        )
        .map_err(|e| SortError::Sim(SimulationError::World(e)))?;
    let mut run = SortRun {
        balls: (feed.iter())
            .map(|colour| Ball {
                colour: colour.clone(),
                took: Vec::new(),
                bin: None,
                eos: Vec::new(),
            })
            .collect(),
        duration_ms: end,
        faults: Vec::new(),
        stopped: None,
        trace: world.trace().iter().map(ToString::to_string).collect(),
        entries: world.trace().to_vec(),
        selections: Vec::new(),
    };
    let mut moving: Vec<usize> = Vec::new();
    let mut fed = 0;
    for e in world.trace() {
        match &e.what {
            What::Step { plant: p, .. } if gate_plants.contains(p) && !moving.contains(p) => {
                moving.push(*p);
            }
            What::Step { plant: p, .. } if gate_plants.contains(p) => {}
            What::Arrived { plant: p, .. } => moving.retain(|m| m != p),
            What::Step {
                plant: p,
                plus: true,
                ..
            } if *p == pusher => {
                for g in &moving {
                    run.faults.push(format!(
                        "at {} ms: the pusher fed while gate {} moved",
                        e.t_ms,
                        world.plants()[*g].name()
                    ));
                }
            }
            What::Fed { .. } => fed += 1,
            What::Binned { ball, bin, .. } => {
                if let Some(b) = run.balls.get_mut(*ball) {
                    b.bin = Some(*bin);
                }
            }
            What::GateMoving { ball, plant, .. } => run.faults.push(format!(
                "at {} ms: ball {} met gate {} moving",
                e.t_ms,
                ball + 1,
                world.plants()[*plant].name()
            )),
            What::Fault { node, fault } => run.faults.push(format!(
                "at {} ms: role {} faulted: {fault:?}",
                e.t_ms, c.ir.roles[*node].name
            )),
            What::Fired {
                node, chart, to, ..
            } => {
                let Some(b) = run.balls.get_mut(fed) else {
                    continue;
                };
                for (automaton, eos) in entered(c, *node, *chart, *to, b) {
                    run.selections.push(Selection {
                        t_ms: e.t_ms,
                        ball: fed,
                        automaton,
                        eos,
                    });
                }
            }
            _ => {}
        }
    }
    if run.faults.is_empty() && fed < feed.len() {
        let chart = (c.ir.roles[node].charts.iter()).position(|ch| ch.name == s.chart_name());
        run.stopped = Some(stopped(
            world.trace(),
            node,
            chart,
            fed,
            feed.len(),
            s.roll_ms,
        ));
    }
    Ok(run)
}

/// Why the station stopped at ball `next` (0-based, never pushed) of `balls`: the ball
/// reached the sensors after the station last read them (its classification chart,
/// `chart`, fired on `node`), which the station took for an empty magazine.
fn stopped(
    trace: &[TraceEntry],
    node: usize,
    chart: Option<usize>,
    next: usize,
    balls: usize,
    roll_ms: u32,
) -> String {
    let left = format!("with {} ball(s) in the magazine", balls - next);
    let ready = trace.iter().find_map(|e| match e.what {
        What::BallReady { ball, .. } if ball == next => Some(e.t_ms),
        _ => None,
    });
    let read = ready.and_then(|ready| {
        (trace.iter().rev())
            .filter(|e| e.t_ms < ready)
            .find_map(|e| match e.what {
                What::Fired {
                    node: n, chart: ch, ..
                } if n == node && chart == Some(usize::from(ch)) => Some(e.t_ms),
                _ => None,
            })
    });
    match (ready, read) {
        (Some(ready), Some(read)) => format!(
            "{left}: ball {} reached the sensors at {ready} ms (roll_ms {roll_ms} after the \
             pusher came home), after the station read them at {read} ms: the next ball must \
             lie at the sensors before the station samples them",
            next + 1
        ),
        _ => left,
    }
}

/// A chart of node `node` entered state `to` while ball `b` was being decided: an
/// automaton's instance that emits its `Out` took it, one that emits `NAME.EOS` ended a
/// sequence. Returns what it newly recorded: (automaton, an EOS).
fn entered(c: &Compiled, node: usize, chart: u8, to: u8, b: &mut Ball) -> Vec<(String, bool)> {
    let mut new = Vec::new();
    let Some(role) = c.ir.roles.get(node) else {
        return new;
    };
    let Some(ch) = role.charts.get(usize::from(chart)) else {
        return new;
    };
    let Some(state) = ch.states.get(usize::from(to)) else {
        return new;
    };
    let emits = |e: &str| {
        state
            .actions
            .iter()
            .any(|a| matches!(a, robot_compiler::ir::ActionIr::Emit(x) if x == e))
    };
    for a in &c.robot.automata {
        if a.role.as_deref() != Some(role.name.as_str())
            || !ch.name.starts_with(&format!("{}.", a.name))
        {
            continue;
        }
        if emits(&format!("{}.Out", ch.name)) && !b.took.contains(&a.name) {
            b.took.push(a.name.clone());
            new.push((a.name.clone(), false));
        }
        if emits(&format!("{}.EOS", a.name)) && !b.eos.contains(&a.name) {
            b.eos.push(a.name.clone());
            new.push((a.name.clone(), true));
        }
    }
    new
}
