//! `sim --timeline FILE.svg`: a state-timing diagram of a simulated run, like seed 001's:
//! one lane per actuator (home / moving / end, drawn as the rod's stroke over time), one
//! lane per continuous position (a motor and what it moves: position over time), one lane
//! per chart (its state over time, a tick per transition; a control function's chart is its
//! place, the `.seen` charts that mirror another node's function are left out), a radio
//! lane (a tick per publication), and faults, link alarms and injected faults as vertical
//! lines.
//!
//! Every lane is a `<g class="lane KIND" data-name="NAME">` (KIND: `actuator`,
//! `position`, `chart`, `radio`), so tools and tests can find them. A sorting station's
//! run has its own lanes first ([`station`]).

use std::fmt::Write;

use node_fw::sim::{Plant, TraceEntry, What};

use crate::sim::{cycle_limit_ms, SimulationError};
use robot_compiler::compile::Compiled;

pub mod station;

const LEFT: f64 = 150.0;
const WIDTH: f64 = 1100.0;
const ACT_H: f64 = 44.0;
const CHART_H: f64 = 26.0;
const RADIO_H: f64 = 22.0;
const TOP: f64 = 36.0;

/// Runs `cycles` cycles and returns the whole trace.
pub fn run(c: &Compiled, cycles: usize) -> Result<Vec<TraceEntry>, SimulationError> {
    let tables = crate::sim::tables(c)?;
    let (mut world, button) = crate::sim::world(c, &tables)?;
    let limit_ms = cycle_limit_ms(c);
    for _ in 0..cycles {
        world.run_cycle(button, limit_ms)?;
    }
    Ok(world.take_trace())
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A tick spacing of 1, 2 or 5 times a power of ten giving about 10 ticks.
fn tick_step(end_ms: u64) -> u64 {
    let raw = (end_ms / 10).max(1);
    let mut p = 1u64;
    while p * 10 <= raw {
        p *= 10;
    }
    [1, 2, 5, 10]
        .iter()
        .map(|m| m * p)
        .find(|s| *s >= raw)
        .unwrap_or(10 * p)
}

/// The SVG of a trace of the compiled robot.
pub fn svg(c: &Compiled, trace: &[TraceEntry]) -> Result<String, SimulationError> {
    let (plants, _) = crate::sim::plants(c)?;
    let actuators: Vec<(usize, &str)> = plants
        .iter()
        .enumerate()
        .filter(|(_, p)| p.travel().is_some())
        .map(|(i, p)| (i, p.name()))
        .collect();
    // (its name, the motor that moves it, the motor's stroke in µm)
    let positions: Vec<(&str, usize, u64)> = (plants.iter().enumerate())
        .filter_map(|(i, p)| {
            let motor = match p {
                Plant::Motor(_) => i,
                Plant::Driven(d) => d.motor,
                _ => return None,
            };
            match plants.get(motor) {
                Some(Plant::Motor(m)) => Some((p.name(), motor, u64::from(m.stroke_mm) * 1000)),
                _ => None,
            }
        })
        .collect();
    let charts: Vec<(usize, usize)> =
        c.ir.roles
            .iter()
            .enumerate()
            .flat_map(|(r, role)| {
                (0..role.charts.len())
                    .filter(move |&ch| !role.charts[ch].name.ends_with(".seen"))
                    .map(move |ch| (r, ch))
            })
            .collect();
    let end_ms = trace.last().map_or(1, |e| e.t_ms).max(1);
    let mut d = Drawing {
        c,
        trace,
        end_ms,
        o: String::new(),
    };
    let height = TOP
        + ACT_H * (actuators.len() + positions.len()) as f64
        + CHART_H * charts.len() as f64
        + RADIO_H
        + 40.0;
    d.header(height);
    let mut y = TOP;
    for (plant, name) in &actuators {
        d.actuator_lane(*plant, name, y);
        y += ACT_H;
    }
    for &(name, motor, stroke_um) in &positions {
        d.position_lane(name, motor, stroke_um, y);
        y += ACT_H;
    }
    Ok(d.finish(&charts, y))
}

/// An SVG being drawn: the robot, the trace, and the text so far.
struct Drawing<'a> {
    c: &'a Compiled,
    trace: &'a [TraceEntry],
    end_ms: u64,
    o: String,
}

/// Background colours of chart states, by state index.
const PALETTE: [&str; 6] = [
    "#e8f0e0", "#fdf0d8", "#e6eefa", "#f6e4ee", "#e9e4f6", "#e0f3f3",
];

impl Drawing<'_> {
    /// The lanes every timeline ends with, from `y`: a lane per chart of `charts` (role,
    /// chart), the radio, the marks and the time axis; the finished SVG.
    fn finish(mut self, charts: &[(usize, usize)], mut y: f64) -> String {
        for &(r, ch) in charts {
            self.chart_lane(r, ch, y);
            y += CHART_H;
        }
        self.radio_lane(y);
        y += RADIO_H;
        self.marks(y);
        self.time_axis(y);
        self.o.push_str("</svg>\n");
        self.o
    }

    /// The x coordinate of time `t`.
    fn x(&self, t: u64) -> f64 {
        LEFT + WIDTH * t as f64 / self.end_ms as f64
    }

    /// The `<svg>` element, the background and the title.
    fn header(&mut self, height: f64) {
        let o = &mut self.o;
        let _ = writeln!(
            o,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{:.0}" height="{height:.0}" font-family="sans-serif" font-size="11">"#,
            LEFT + WIDTH + 20.0
        );
        let _ = writeln!(
            o,
            r#"<rect x="0" y="0" width="{:.0}" height="{height:.0}" fill="white"/>"#,
            LEFT + WIDTH + 20.0
        );
        let _ = writeln!(
            o,
            r#"<text x="10" y="20" font-size="14" font-weight="bold">{} — {} ms</text>"#,
            esc(&self.c.ir.name),
            self.end_ms
        );
    }

    /// An actuator lane at `y`: the stroke over time, its steps and jams.
    fn actuator_lane(&mut self, plant: usize, name: &str, y: f64) {
        let (lo, hi) = (y + ACT_H - 10.0, y + 8.0);
        let (trace, end_ms) = (self.trace, self.end_ms);
        let _ = writeln!(
            self.o,
            r#"<g class="lane actuator" data-name="{}">"#,
            esc(name)
        );
        let _ = writeln!(
            self.o,
            r##"<rect x="{LEFT}" y="{y}" width="{WIDTH}" height="{ACT_H}" fill="#f4f7fb" stroke="#dde"/>"##
        );
        let _ = writeln!(
            self.o,
            r#"<text x="10" y="{:.1}" font-weight="bold">{}</text><text x="{:.1}" y="{:.1}" font-size="9" fill="gray" text-anchor="end">end</text><text x="{:.1}" y="{:.1}" font-size="9" fill="gray" text-anchor="end">home</text>"#,
            y + ACT_H / 2.0 + 4.0,
            esc(name),
            LEFT - 4.0,
            hi + 3.0,
            LEFT - 4.0,
            lo + 3.0
        );
        let mut points = vec![(self.x(0), lo)];
        let mut level = lo;
        for e in trace {
            match &e.what {
                What::Step { plant: p, .. } if *p == plant => {
                    points.push((self.x(e.t_ms), level));
                }
                What::Arrived { plant: p, end } if *p == plant => {
                    level = if *end { hi } else { lo };
                    points.push((self.x(e.t_ms), level));
                }
                What::Jammed { plant: p, .. } if *p == plant => {
                    let _ = writeln!(
                        self.o,
                        r#"<text x="{:.1}" y="{:.1}" fill="red" font-weight="bold" text-anchor="middle">✕ jammed</text>"#,
                        self.x(e.t_ms),
                        y + ACT_H / 2.0 + 4.0
                    );
                }
                _ => {}
            }
        }
        points.push((self.x(end_ms), level));
        let pts: Vec<String> = points
            .iter()
            .map(|(a, b)| format!("{a:.1},{b:.1}"))
            .collect();
        let _ = writeln!(
            self.o,
            r##"<polyline points="{}" fill="none" stroke="#1f4e9c" stroke-width="2"/>"##,
            pts.join(" ")
        );
        for e in trace {
            if let What::Step { plant: p, .. } = &e.what {
                if *p == plant {
                    let _ = writeln!(
                        self.o,
                        r##"<text x="{:.1}" y="{:.1}" font-size="9" fill="#1f4e9c">{}</text>"##,
                        self.x(e.t_ms) + 2.0,
                        y + ACT_H / 2.0 + 3.0,
                        esc(&e.what.step().unwrap_or_default())
                    );
                }
            }
        }
        self.o.push_str("</g>\n");
    }

    /// The lane at `y` of a continuous position (`name`, moved by motor `motor` over
    /// `stroke_um`): the position over time, straight between the motor's changes of run
    /// and its arrivals.
    fn position_lane(&mut self, name: &str, motor: usize, stroke_um: u64, y: f64) {
        let (lo, hi) = (y + ACT_H - 10.0, y + 8.0);
        let (trace, end_ms) = (self.trace, self.end_ms);
        let level = |um: u64| lo - (lo - hi) * um as f64 / stroke_um.max(1) as f64;
        let _ = writeln!(
            self.o,
            r##"<g class="lane position" data-name="{}"><rect x="{LEFT}" y="{y}" width="{WIDTH}" height="{ACT_H}" fill="#f4f7fb" stroke="#dde"/><text x="10" y="{:.1}" font-weight="bold">{} Pos</text><text x="{:.1}" y="{:.1}" font-size="9" fill="gray" text-anchor="end">{} mm</text><text x="{:.1}" y="{:.1}" font-size="9" fill="gray" text-anchor="end">0</text>"##,
            esc(name),
            y + ACT_H / 2.0 + 4.0,
            esc(name),
            LEFT - 4.0,
            hi + 3.0,
            stroke_um / 1000,
            LEFT - 4.0,
            lo + 3.0
        );
        let mut points = vec![(self.x(0), lo)];
        let mut at = lo;
        for e in trace {
            match e.what {
                What::Motor {
                    plant: p, at_um, ..
                } if p == motor => at = level(at_um),
                What::Arrived { plant: p, end } if p == motor => {
                    at = level(if end { stroke_um } else { 0 })
                }
                _ => continue,
            }
            points.push((self.x(e.t_ms), at));
        }
        points.push((self.x(end_ms), at));
        let pts: Vec<String> = points
            .iter()
            .map(|(a, b)| format!("{a:.1},{b:.1}"))
            .collect();
        let _ = writeln!(
            self.o,
            r##"<polyline points="{}" fill="none" stroke="#1f4e9c" stroke-width="2"/>"##,
            pts.join(" ")
        );
        self.o.push_str("</g>\n");
    }

    /// The lane of chart `ch` of role `r` at `y`: state intervals, a tick per transition,
    /// and the time its node faulted shaded.
    fn chart_lane(&mut self, r: usize, ch: usize, y: f64) {
        let (c, trace, end_ms) = (self.c, self.trace, self.end_ms);
        let role = &c.ir.roles[r];
        let chart = &role.charts[ch];
        let label = format!("{}.{}", role.name, chart.name);
        let _ = writeln!(
            self.o,
            r#"<g class="lane chart" data-name="{}">"#,
            esc(&label)
        );
        let _ = writeln!(
            self.o,
            r#"<text x="10" y="{:.1}">{}</text>"#,
            y + CHART_H / 2.0 + 4.0,
            esc(&label)
        );
        // The simulated machine starts homed: every chart at its idle point.
        let mut intervals: Vec<(u64, usize)> = vec![(0, chart.idle)];
        let mut ticks = Vec::new();
        for e in trace {
            match &e.what {
                What::Fired {
                    node, chart: k, to, ..
                } if *node == r && usize::from(*k) == ch => {
                    intervals.push((e.t_ms, usize::from(*to)));
                    ticks.push(e.t_ms);
                }
                What::Reset { node } | What::Reboot { node } if *node == r => {
                    intervals.push((e.t_ms, chart.initial))
                }
                _ => {}
            }
        }
        for (i, (t0, s)) in intervals.iter().enumerate() {
            let t1 = intervals.get(i + 1).map_or(end_ms, |n| n.0);
            let (x0, x1) = (self.x(*t0), self.x(t1));
            let name = chart.states.get(*s).map_or("?", |st| st.name.as_str());
            let _ = writeln!(
                self.o,
                r##"<rect x="{x0:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="{}" stroke="#999" stroke-width="0.5"><title>{} {} from {} ms</title></rect>"##,
                y + 3.0,
                (x1 - x0).max(0.5),
                CHART_H - 6.0,
                PALETTE[*s % PALETTE.len()],
                esc(&label),
                esc(name),
                t0
            );
            if x1 - x0 > 6.5 * name.len() as f64 {
                let _ = writeln!(
                    self.o,
                    r#"<text x="{:.1}" y="{:.1}" font-size="10">{}</text>"#,
                    x0 + 2.0,
                    y + CHART_H / 2.0 + 4.0,
                    esc(name)
                );
            }
        }
        // A faulted node's charts no longer run: shade the rest of the lane.
        let fault = trace.iter().find_map(|e| match &e.what {
            What::Fault { node, .. } if *node == r => Some(e.t_ms),
            _ => None,
        });
        if let Some(t0) = fault {
            let _ = writeln!(
                self.o,
                r##"<rect class="faulted" x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="#ff0000" fill-opacity="0.18"/><text x="{:.1}" y="{:.1}" font-size="9" fill="#b00000">FAULT</text>"##,
                self.x(t0),
                y + 3.0,
                (self.x(end_ms) - self.x(t0)).max(0.5),
                CHART_H - 6.0,
                self.x(t0) + 2.0,
                y + CHART_H / 2.0 + 3.0
            );
        }
        for t in ticks {
            let _ = writeln!(
                self.o,
                r#"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="black"/>"#,
                self.x(t),
                y + CHART_H - 3.0,
                self.x(t),
                y + CHART_H + 1.0
            );
        }
        self.o.push_str("</g>\n");
    }

    /// The radio lane at `y`: a tick per publication.
    fn radio_lane(&mut self, y: f64) {
        let (c, trace) = (self.c, self.trace);
        let _ = writeln!(self.o, r#"<g class="lane radio" data-name="radio">"#);
        let _ = writeln!(
            self.o,
            r#"<text x="10" y="{:.1}" fill="gray">radio</text>"#,
            y + RADIO_H / 2.0 + 4.0
        );
        for e in trace {
            if let What::Publish { node, event, .. } = &e.what {
                let ev = c.ir.roles[*node]
                    .events
                    .get(usize::from(*event))
                    .cloned()
                    .unwrap_or_default();
                let _ = writeln!(
                    self.o,
                    r##"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="#c07000" stroke-width="1.5"><title>{} publishes {} at {} ms</title></line>"##,
                    self.x(e.t_ms),
                    y + 4.0,
                    self.x(e.t_ms),
                    y + RADIO_H - 4.0,
                    esc(&c.ir.roles[*node].name),
                    esc(&ev),
                    e.t_ms
                );
            }
        }
        self.o.push_str("</g>\n");
    }

    /// Faults, link alarms and injections as vertical lines from the top down to `bottom`
    /// (the first of each instant labelled).
    fn marks(&mut self, bottom: f64) {
        let (c, trace) = (self.c, self.trace);
        let mut labelled: Vec<u64> = Vec::new();
        for e in trace {
            let mark = match &e.what {
                What::Fault { node, fault } => Some((
                    "red",
                    match fault {
                        node_fw::ecc::Fault::Action { code, .. } => {
                            format!("FAULT {} (code {code})", c.ir.roles[*node].name)
                        }
                        other => format!("FAULT {} {other:?}", c.ir.roles[*node].name),
                    },
                )),
                What::LinkAlarm { node, peer } => Some((
                    "#b000b0",
                    format!(
                        "LINK ALARM {} -> {}",
                        c.ir.roles[*node].name, c.ir.roles[*peer].name
                    ),
                )),
                What::Injected { fault } => Some(("black", format!("injected: {fault}"))),
                _ => None,
            };
            let Some((color, text)) = mark else {
                continue;
            };
            let x = self.x(e.t_ms);
            if labelled.last().is_none_or(|t| x - self.x(*t) > 140.0) {
                labelled.push(e.t_ms);
                let _ = writeln!(
                    self.o,
                    r#"<text x="{:.1}" y="{:.1}" font-size="9" fill="{color}" text-anchor="end">{}</text>"#,
                    x - 2.0,
                    TOP - 4.0,
                    esc(&text)
                );
            }
            let _ = writeln!(
                self.o,
                r#"<line class="mark" x1="{x:.1}" y1="{TOP}" x2="{x:.1}" y2="{bottom:.1}" stroke="{color}" stroke-dasharray="4,3"><title>{} at {} ms</title></line>"#,
                esc(&text),
                e.t_ms
            );
        }
    }

    /// The time axis at `y`: a tick and label every [`tick_step`] ms.
    fn time_axis(&mut self, y: f64) {
        let end_ms = self.end_ms;
        let step = tick_step(end_ms);
        let _ = writeln!(
            self.o,
            r#"<line x1="{LEFT}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="black"/>"#,
            LEFT + WIDTH
        );
        let mut t = 0;
        while t <= end_ms {
            let x = self.x(t);
            let _ = writeln!(
                self.o,
                r#"<line x1="{x:.1}" y1="{y:.1}" x2="{x:.1}" y2="{:.1}" stroke="black"/><text x="{x:.1}" y="{:.1}" font-size="9" text-anchor="middle">{t}</text>"#,
                y + 4.0,
                y + 15.0
            );
            t += step;
        }
        let _ = writeln!(
            self.o,
            r#"<text x="{:.1}" y="{:.1}" font-size="9" text-anchor="end">ms</text>"#,
            LEFT + WIDTH,
            y + 28.0
        );
    }
}

#[cfg(test)]
mod tests {
    use super::{esc, tick_step};

    #[test]
    fn the_time_axis_has_about_ten_round_ticks() {
        assert_eq!(tick_step(1), 1);
        assert_eq!(tick_step(95), 10);
        assert_eq!(tick_step(1_500), 200);
        assert_eq!(tick_step(13_000), 2_000);
        assert_eq!(tick_step(45_000), 5_000);
    }

    #[test]
    fn names_are_escaped_for_xml() {
        assert_eq!(esc(r#"a<b>&"c""#), "a&lt;b&gt;&amp;&quot;c&quot;");
    }
}
