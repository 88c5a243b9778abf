//! `sim --timeline FILE.svg` of a sorting station (docs/selecting-automata.md, "The
//! station"): the lanes of the paper's station over the whole feed, then the charts, the
//! radio and the faults as in every robot's timeline.
//!
//! - `lane pusher` (the pusher): `home` / `moving` / `fed` (at its end: the ball is
//!   pushed off), a `fed` tick per ball pushed into the shaft;
//! - `lane gate`, one per gate in shaft order: `closed` / `opening` / `open` /
//!   `closing`, a `met-moving` cross where a ball met it in motion;
//! - `lane sensor`, one per sensor in the ball's path: the colour sensors, the entry
//!   sensor, the bins' sensors; a `high` rect per interval the sensor is on;
//! - `lane ball`, one per ball (`data-colour`, `data-took`, `data-bin`): `at-sensors`
//!   (from when it lies at the sensors until pushed), `falling` (until it lands), a `took`
//!   dot per automaton that took it and an `eos` tick per sequence it ended.
//!
//! Every interval and mark carries `data-from` / `data-to` or `data-t` (ms), so tests
//! read times exactly.

use std::fmt::Write;

use node_fw::sim::{TraceEntry, What};
use robot_compiler::Compiled;

use super::{esc, Drawing, CHART_H, LEFT, RADIO_H, TOP, WIDTH};
use crate::sorter::{SortError, SortRun};

const STATE_H: f64 = 26.0;
const SENSOR_H: f64 = 18.0;
const BALL_H: f64 = 22.0;

/// The states of an actuator of the station: (home, moving out, at the end, moving back).
type Names = [&'static str; 4];
const PUSHER: Names = ["home", "moving", "fed", "moving"];
const GATE: Names = ["closed", "opening", "open", "closing"];

/// An actuator's states over `trace`: (from ms, state), starting home at 0, a new entry
/// at each change (a step, an arrival).
pub fn actuator_states(trace: &[TraceEntry], plant: usize, names: Names) -> Vec<(u64, &str)> {
    let mut out = vec![(0, names[0])];
    for e in trace {
        let state = match e.what {
            What::Step { plant: p, plus, .. } if p == plant => names[if plus { 1 } else { 3 }],
            What::Arrived { plant: p, end } if p == plant => names[if end { 2 } else { 0 }],
            _ => continue,
        };
        if out.last().is_some_and(|(_, s)| *s == state) {
            continue;
        }
        out.push((e.t_ms, state));
    }
    out
}

/// The intervals (from, to) input `input` of node `node` is high over `trace`, starting
/// at `initial`; one still high at the end ends at `end_ms`.
pub fn high_intervals(
    trace: &[TraceEntry],
    node: usize,
    input: u8,
    initial: bool,
    end_ms: u64,
) -> Vec<(u64, u64)> {
    let mut out = Vec::new();
    let mut since = initial.then_some(0);
    for e in trace {
        match e.what {
            What::Input {
                node: n,
                input: i,
                level,
            } if n == node && i == input => match (since, level) {
                (None, true) => since = Some(e.t_ms),
                (Some(t0), false) => {
                    out.push((t0, e.t_ms));
                    since = None;
                }
                _ => {}
            },
            _ => {}
        }
    }
    if let Some(t0) = since {
        out.push((t0, end_ms));
    }
    out
}

/// Where the station's parts are: plant and input indices, with their names.
struct Layout {
    node: usize,
    pusher: (usize, String),
    gates: Vec<(usize, String)>,
    /// The sensors in the ball's path, and each one's level at power-up.
    sensors: Vec<(u8, String, bool)>,
}

fn layout(c: &Compiled, run: &SortRun) -> Result<Layout, SortError> {
    let s = c.robot.sorting.as_ref().ok_or(SortError::NoStation)?;
    let missing = |n: &str| SortError::Missing(n.to_string());
    let (plants, _) = crate::sim::plants(c)?;
    let plant = |n: &str| {
        (plants.iter())
            .position(|p| p.travel().is_some() && p.name() == n)
            .map(|i| (i, n.to_string()))
            .ok_or_else(|| missing(n))
    };
    let node = (c.ir.roles.iter())
        .position(|r| r.name == s.role)
        .ok_or_else(|| missing(&s.role))?;
    let first = (run.balls.first()).and_then(|b| s.levels(&b.colour));
    let mut sensors = Vec::new();
    let names = (s.sensors.iter().enumerate())
        .map(|(i, n)| (n, first.and_then(|l| l.get(i)).copied().unwrap_or(false)))
        .chain([&s.entry].into_iter().chain(&s.bins).map(|n| (n, false)));
    for (name, initial) in names {
        let input = (c.ir.roles[node].inputs.iter())
            .position(|i| &i.name == name)
            .and_then(|i| u8::try_from(i).ok())
            .ok_or_else(|| missing(name))?;
        sensors.push((input, name.clone(), initial));
    }
    let gates = (s.gates.iter())
        .map(|g| plant(g.split_once('/').map_or(g.as_str(), |(_, a)| a)))
        .collect::<Result<_, _>>()?;
    Ok(Layout {
        node,
        pusher: plant(&s.pusher)?,
        gates,
        sensors,
    })
}

/// The SVG of a station's run.
pub fn svg(c: &Compiled, run: &SortRun) -> Result<String, SortError> {
    let l = layout(c, run)?;
    let charts: Vec<(usize, usize)> = (c.ir.roles.iter().enumerate())
        .flat_map(|(r, role)| {
            (0..role.charts.len())
                .filter(move |&ch| !role.charts[ch].name.ends_with(".seen"))
                .map(move |ch| (r, ch))
        })
        .collect();
    let trace = run.entries.as_slice();
    let end_ms = trace.last().map_or(1, |e| e.t_ms).max(1);
    let mut d = Drawing {
        c,
        trace,
        end_ms,
        o: String::new(),
    };
    let height = TOP
        + STATE_H * (1 + l.gates.len()) as f64
        + SENSOR_H * l.sensors.len() as f64
        + BALL_H * run.balls.len() as f64
        + CHART_H * charts.len() as f64
        + RADIO_H
        + 40.0;
    d.header(height);
    let mut y = TOP;
    let (pusher, name) = &l.pusher;
    let states = actuator_states(trace, *pusher, PUSHER);
    let fed: Vec<(u64, String)> = (trace.iter())
        .filter_map(|e| match e.what {
            What::Fed { ball, .. } => Some((e.t_ms, format!("ball {}", ball + 1))),
            _ => None,
        })
        .collect();
    d.state_lane("pusher", name, name, &states, y);
    d.ticks("fed", &fed, y);
    d.o.push_str("</g>\n");
    y += STATE_H;
    for (i, (gate, name)) in l.gates.iter().enumerate() {
        let states = actuator_states(trace, *gate, GATE);
        let label = format!("gate {} ({name})", i + 1);
        d.state_lane("gate", name, &label, &states, y);
        d.met_moving(*gate, y);
        d.o.push_str("</g>\n");
        y += STATE_H;
    }
    for (input, name, initial) in &l.sensors {
        let high = high_intervals(trace, l.node, *input, *initial, end_ms);
        d.sensor_lane(name, &high, y);
        y += SENSOR_H;
    }
    for i in 0..run.balls.len() {
        d.ball_lane(run, i, y);
        y += BALL_H;
    }
    Ok(d.finish(&charts, y))
}

/// Background colours of the states of [`PUSHER`] and [`GATE`]: home, moving, end.
fn fill(state: &str) -> &'static str {
    match state {
        "home" | "closed" => "#e8f0e0",
        "fed" | "open" => "#e6eefa",
        _ => "#fdf0d8",
    }
}

impl Drawing<'_> {
    /// Opens `<g class="lane KIND">` at `y` (the caller closes it) and draws `states`
    /// (from ms, state) as labelled intervals.
    fn state_lane(&mut self, kind: &str, name: &str, label: &str, states: &[(u64, &str)], y: f64) {
        let _ = writeln!(
            self.o,
            r#"<g class="lane {kind}" data-name="{}"><text x="10" y="{:.1}" font-weight="bold">{}</text>"#,
            esc(name),
            y + STATE_H / 2.0 + 4.0,
            esc(label)
        );
        for (i, (t0, s)) in states.iter().enumerate() {
            let t1 = states.get(i + 1).map_or(self.end_ms, |n| n.0);
            let (x0, x1) = (self.x(*t0), self.x(t1));
            let _ = writeln!(
                self.o,
                r##"<rect class="state" data-state="{s}" data-from="{t0}" data-to="{t1}" x="{x0:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="{}" stroke="#999" stroke-width="0.5"><title>{} {s} from {t0} to {t1} ms</title></rect>"##,
                y + 3.0,
                (x1 - x0).max(0.5),
                STATE_H - 6.0,
                fill(s),
                esc(label)
            );
            if x1 - x0 > 6.5 * s.len() as f64 {
                let _ = writeln!(
                    self.o,
                    r#"<text x="{:.1}" y="{:.1}" font-size="10">{s}</text>"#,
                    x0 + 2.0,
                    y + STATE_H / 2.0 + 4.0
                );
            }
        }
    }

    /// Ticks of class `class` at (ms, what) in the lane at `y`.
    fn ticks(&mut self, class: &str, at: &[(u64, String)], y: f64) {
        for (t, what) in at {
            let x = self.x(*t);
            let _ = writeln!(
                self.o,
                r##"<line class="{class}" data-t="{t}" x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{:.1}" stroke="#1f4e9c" stroke-width="2"><title>{} {class} at {t} ms</title></line>"##,
                y + 1.0,
                y + STATE_H - 1.0,
                esc(what)
            );
        }
    }

    /// A red cross in the lane at `y` where a ball met gate plant `gate` moving.
    fn met_moving(&mut self, gate: usize, y: f64) {
        for e in self.trace {
            if let What::GateMoving { ball, plant, .. } = e.what {
                if plant == gate {
                    let _ = writeln!(
                        self.o,
                        r#"<text class="met-moving" data-t="{}" data-ball="{}" x="{:.1}" y="{:.1}" fill="red" font-weight="bold" text-anchor="middle">✕<title>ball {} met the gate moving at {} ms</title></text>"#,
                        e.t_ms,
                        ball + 1,
                        self.x(e.t_ms),
                        y + STATE_H / 2.0 + 4.0,
                        ball + 1,
                        e.t_ms
                    );
                }
            }
        }
    }

    /// A sensor's lane at `y`: a rect per interval it is high.
    fn sensor_lane(&mut self, name: &str, high: &[(u64, u64)], y: f64) {
        let _ = writeln!(
            self.o,
            r##"<g class="lane sensor" data-name="{}"><text x="10" y="{:.1}">{}</text><line x1="{LEFT}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="#bbb"/>"##,
            esc(name),
            y + SENSOR_H / 2.0 + 4.0,
            esc(name),
            y + SENSOR_H - 3.0,
            LEFT + WIDTH,
            y + SENSOR_H - 3.0
        );
        for (t0, t1) in high {
            let (x0, x1) = (self.x(*t0), self.x(*t1));
            let _ = writeln!(
                self.o,
                r##"<rect class="high" data-from="{t0}" data-to="{t1}" x="{x0:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="#2a7a2a"><title>{} on from {t0} to {t1} ms</title></rect>"##,
                y + 3.0,
                (x1 - x0).max(1.0),
                SENSOR_H - 6.0,
                esc(name)
            );
        }
        self.o.push_str("</g>\n");
    }

    /// Ball `i`'s lane at `y`: at the sensors, falling, its selections and its bin.
    fn ball_lane(&mut self, run: &SortRun, i: usize, y: f64) {
        let Some(ball) = run.balls.get(i) else {
            return;
        };
        let at =
            |f: &dyn Fn(&What) -> bool| (self.trace.iter()).find(|e| f(&e.what)).map(|e| e.t_ms);
        // The first ball lies at the sensors from power-up.
        let ready = if i == 0 {
            Some(0)
        } else {
            at(&|w| matches!(w, What::BallReady { ball, .. } if *ball == i))
        };
        let fed = at(&|w| matches!(w, What::Fed { ball, .. } if *ball == i));
        let landed = at(&|w| matches!(w, What::Binned { ball, .. } if *ball == i));
        let bin = ball
            .bin
            .map_or_else(|| String::from("none"), |b| b.to_string());
        let took = ball.took.join(" ");
        let _ = writeln!(
            self.o,
            r#"<g class="lane ball" data-name="ball {}" data-colour="{}" data-took="{}" data-bin="{bin}"><text x="10" y="{:.1}">ball {} {}</text>"#,
            i + 1,
            esc(&ball.colour),
            esc(&took),
            y + BALL_H / 2.0 + 4.0,
            i + 1,
            esc(&ball.colour)
        );
        let end_ms = self.end_ms;
        let spans = [
            ("at-sensors", ready, fed.or(Some(end_ms)), "#fdf0d8"),
            ("falling", fed, landed.or(Some(end_ms)), "#e6eefa"),
        ];
        for (class, t0, t1, colour) in spans {
            let (Some(t0), Some(t1)) = (t0, t1) else {
                continue;
            };
            let (x0, x1) = (self.x(t0), self.x(t1));
            let _ = writeln!(
                self.o,
                r##"<rect class="{class}" data-from="{t0}" data-to="{t1}" x="{x0:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="{colour}" stroke="#999" stroke-width="0.5"><title>ball {} {class} from {t0} to {t1} ms</title></rect>"##,
                y + 3.0,
                (x1 - x0).max(0.5),
                BALL_H - 6.0,
                i + 1
            );
        }
        for s in run.selections.iter().filter(|s| s.ball == i) {
            let (x, t, a) = (self.x(s.t_ms), s.t_ms, esc(&s.automaton));
            if s.eos {
                let _ = writeln!(
                    self.o,
                    r##"<line class="eos" data-automaton="{a}" data-t="{t}" x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{:.1}" stroke="#b00000" stroke-width="2"><title>EOS {a} at {t} ms</title></line><text x="{:.1}" y="{:.1}" font-size="9" fill="#b00000">EOS {a}</text>"##,
                    y + 1.0,
                    y + BALL_H - 1.0,
                    x + 2.0,
                    y + 9.0
                );
            } else {
                let _ = writeln!(
                    self.o,
                    r##"<circle class="took" data-automaton="{a}" data-t="{t}" cx="{x:.1}" cy="{:.1}" r="3" fill="#1f4e9c"><title>{a} took it at {t} ms</title></circle>"##,
                    y + BALL_H - 5.0
                );
            }
        }
        let by = if took.is_empty() { "-" } else { &took };
        // Right of where it landed; left of where it appeared when that is near the end.
        let right = self.x(landed.unwrap_or(end_ms)) + 3.0;
        let (x, anchor) = if right > LEFT + WIDTH - 150.0 {
            (self.x(ready.unwrap_or(0)) - 3.0, "end")
        } else {
            (right, "start")
        };
        let _ = writeln!(
            self.o,
            r#"<text x="{x:.1}" y="{:.1}" font-size="9" text-anchor="{anchor}">bin {bin} (taken by {})</text>"#,
            y + BALL_H / 2.0 + 4.0,
            esc(by)
        );
        self.o.push_str("</g>\n");
    }
}

#[cfg(test)]
mod tests {
    use super::{actuator_states, high_intervals, GATE};
    use node_fw::sim::{TraceEntry, What};

    fn at(t_ms: u64, what: What) -> TraceEntry {
        TraceEntry { t_ms, what }
    }

    fn step(plant: usize, plus: bool) -> What {
        What::Step {
            plant,
            actuator: String::from("G"),
            plus,
        }
    }

    #[test]
    fn a_gate_is_closed_opening_open_closing_and_a_reversal_is_a_change() {
        let trace = [
            at(5, step(1, true)),
            at(6, step(2, true)),
            at(
                85,
                What::Arrived {
                    plant: 1,
                    end: true,
                },
            ),
            at(90, step(1, false)),
            at(100, step(1, true)),
            at(
                120,
                What::Arrived {
                    plant: 1,
                    end: true,
                },
            ),
        ];
        assert_eq!(
            actuator_states(&trace, 1, GATE),
            [
                (0, "closed"),
                (5, "opening"),
                (85, "open"),
                (90, "closing"),
                (100, "opening"),
                (120, "open")
            ]
        );
    }

    #[test]
    fn a_sensor_high_at_power_up_or_at_the_end_is_an_interval_too() {
        let input = |t, input, level| {
            at(
                t,
                What::Input {
                    node: 0,
                    input,
                    level,
                },
            )
        };
        let trace = [input(10, 3, false), input(20, 4, true), input(30, 3, true)];
        assert_eq!(high_intervals(&trace, 0, 3, true, 50), [(0, 10), (30, 50)]);
        assert_eq!(high_intervals(&trace, 0, 4, false, 50), [(20, 50)]);
        assert_eq!(high_intervals(&trace, 1, 3, false, 50), []);
    }
}
