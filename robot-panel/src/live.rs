//! The machine as it runs: what the medium said of the pins (each actuator's valves and
//! switches, stamped with the medium's clock), the cycle's step and count, and what the
//! nodes answered (status, alarms, security counters). Fed by [`crate::feed`] (pins) and
//! [`crate::poll`] (answers); read by the page through [`crate::view`].

use std::collections::BTreeMap;
use std::time::SystemTime;

use config_schema::alarm::AlarmReport;
use config_schema::wire::msg::{SecurityCounters, Status};
use robot_compiler::compile::Compiled;

use crate::model::Machine;

/// Where an actuator's rod is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Position {
    /// Nothing said yet.
    #[default]
    Unknown,
    Home,
    Moving,
    End,
}

impl Position {
    pub fn text(self) -> &'static str {
        match self {
            Position::Unknown => "unknown",
            Position::Home => "home",
            Position::Moving => "moving",
            Position::End => "end",
        }
    }
}

/// One actuator as the pins say.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LaneLive {
    pub position: Position,
    /// The last command: `Some(true)` extend, `Some(false)` retract.
    pub commanded: Option<bool>,
    /// When it was commanded (medium clock, µs).
    pub since_us: u64,
    /// The last completed travel: (extend, ms from command to the switch).
    pub last: Option<(bool, u64)>,
    /// A motion under way has gone past its plant time (still not there).
    pub late: bool,
}

/// One node as it last answered.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct NodeLive {
    pub status: Option<Status>,
    pub alarms: Option<(AlarmReport, SystemTime)>,
    pub security: Option<(bool, SecurityCounters)>,
    /// It did not answer the last question (and since when, wall clock).
    pub silent: Option<SystemTime>,
}

/// A sorting station as its sensors say.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StationLive {
    /// The ball at the colour sensors: its colour (`unknown`: no row had its levels).
    pub at_sensors: Option<String>,
    /// Balls pushed into the shaft, not landed yet (their colours, first pushed first).
    pub falling: std::collections::VecDeque<String>,
    /// The balls each bin's sensor saw land, by colour, oldest first.
    pub bins: Vec<Vec<String>>,
}

/// Everything the panel knows of the running machine.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Live {
    pub lanes: Vec<LaneLive>,
    /// Pin levels by (node, board pin, output).
    pins: BTreeMap<(u16, u8, bool), bool>,
    /// The step of the cycle under way (an index into the sequence), if one is.
    pub step: Option<usize>,
    next: usize,
    cycle_start_us: Option<u64>,
    /// Cycles completed since the panel started.
    pub cycles: u32,
    /// The last cycles' times, ms, newest last (at most [`KEPT_CYCLES`]).
    pub cycle_ms: Vec<u64>,
    pub nodes: Vec<NodeLive>,
    /// The medium's clock as last heard (µs).
    pub now_us: u64,
    /// The medium's stamp of the last pin change applied (µs): a page, or the latency
    /// bench, tells from it which pin changes a state carries.
    pub pin_us: Option<u64>,
    /// The medium went away (why), or the tool's radio failed on it.
    pub medium_lost: Option<String>,
    /// START runs cycles until STOP: START is pressed again at each idle point.
    pub running: bool,
    /// A command under way.
    pub busy: Option<String>,
    /// How the last command ended, in words.
    pub said: Option<String>,
    pub station: StationLive,
    /// The last events published on the radio, newest last (at most [`KEPT_EVENTS`]):
    /// (medium clock µs, role, event).
    pub events: std::collections::VecDeque<(u64, String, String)>,
    /// Events published since the panel started (each once, however often resent).
    pub event_count: u64,
    /// The last events heard, to tell a resent one: (publisher, epoch, seq, topic).
    heard: std::collections::VecDeque<(u16, u16, u16, u8)>,
}

/// Events kept for the page.
pub const KEPT_EVENTS: usize = 12;

/// Cycle times kept for the page.
pub const KEPT_CYCLES: usize = 8;

impl Live {
    pub fn new(m: &Machine) -> Live {
        Live {
            lanes: vec![LaneLive::default(); m.actuators.len()],
            nodes: vec![NodeLive::default(); m.nodes.len()],
            station: StationLive {
                bins: vec![Vec::new(); m.station.as_ref().map_or(0, |s| s.bins.len())],
                ..StationLive::default()
            },
            ..Live::default()
        }
    }

    /// Node `src` published `topic` (event `seq` of link epoch `epoch`) at `at_us`; a
    /// retransmission or a copy to another subscriber is not a new event.
    pub fn event(&mut self, m: &Machine, at_us: u64, src: u16, epoch: u16, seq: u16, topic: u8) {
        let key = (src, epoch, seq, topic);
        if self.heard.contains(&key) {
            return;
        }
        self.heard.push_back(key);
        if self.heard.len() > 64 {
            self.heard.pop_front();
        }
        let (role, event) = (m.topics.iter())
            .find(|(key, _)| *key == (src, topic))
            .map(|(_, named)| named.clone())
            .unwrap_or_else(|| (format!("{src:#06x}"), format!("topic {topic}")));
        self.event_count += 1;
        self.events.push_back((at_us, role, event));
        if self.events.len() > KEPT_EVENTS {
            self.events.pop_front();
        }
    }

    /// An input pin's level as last heard (low until heard).
    pub fn input(&self, addr: u16, pin: u8) -> bool {
        self.level(addr, Some(pin), false) == Some(true)
    }

    fn level(&self, addr: u16, pin: Option<u8>, output: bool) -> Option<bool> {
        pin.and_then(|p| self.pins.get(&(addr, p, output)).copied())
    }

    /// A pin level the medium saw at `at_us` (its clock): a valve the node drove
    /// (`output`) or a switch the plant set.
    pub fn pin(&mut self, m: &Machine, at_us: u64, addr: u16, pin: u8, level: bool, output: bool) {
        self.now_us = self.now_us.max(at_us);
        self.pin_us = Some(self.pin_us.map_or(at_us, |p| p.max(at_us)));
        let was = self.pins.insert((addr, pin, output), level);
        if !output {
            self.station_pin(m, addr, pin, level, was);
        }
        for i in 0..m.wiring.len() {
            let Some(a) = m.wiring.get(i) else { continue };
            if a.addr != addr {
                continue;
            }
            let valve = output && (pin == a.valves.0 || pin == a.valves.1);
            let switch = !output && (Some(pin) == a.home || Some(pin) == a.end);
            if valve {
                self.valve(m, i, at_us);
            } else if switch {
                self.switch(m, i, at_us);
            }
        }
    }

    /// A station's sensor: the colour sensors say which ball lies there (all low: none;
    /// a ball that goes from there falls), a bin's sensor rising is the first falling ball
    /// landing in it.
    fn station_pin(&mut self, m: &Machine, addr: u16, pin: u8, level: bool, was: Option<bool>) {
        let Some(s) = m.station.as_ref().filter(|s| s.addr == addr) else {
            return;
        };
        if s.sensors.iter().any(|x| x.1 == pin) {
            let levels: Vec<bool> = (s.sensors.iter())
                .map(|x| self.level(addr, Some(x.1), false) == Some(true))
                .collect();
            // The levels change one pin at a time: the ball's colour is the last row they
            // matched while one was high (the ones in between are no colour).
            let row = (s.colours.iter())
                .find(|c| c.1 == levels)
                .map(|c| c.0.clone());
            let st = &mut self.station;
            match (levels.iter().any(|l| *l), row) {
                (false, _) => {
                    if let Some(gone) = st.at_sensors.take() {
                        st.falling.push_back(gone);
                    }
                }
                (true, Some(colour)) => st.at_sensors = Some(colour),
                (true, None) => {
                    st.at_sensors.get_or_insert_with(|| "unknown".to_string());
                }
            }
        } else if let Some(bin) = s.bins.iter().position(|x| x.1 == pin) {
            if level && was != Some(true) {
                let st = &mut self.station;
                let ball = st.falling.pop_front().unwrap_or_else(|| "unknown".into());
                if let Some(b) = st.bins.get_mut(bin) {
                    b.push(ball);
                }
            }
        }
    }

    /// The command of actuator `i` from its valve levels; a new one is a step.
    fn valve(&mut self, m: &Machine, i: usize, at_us: u64) {
        let Some(a) = m.wiring.get(i) else { return };
        let extend = self.level(a.addr, Some(a.valves.0), true).unwrap_or(false);
        let retract = self.level(a.addr, Some(a.valves.1), true).unwrap_or(false);
        let commanded = match (a.double, extend, retract) {
            (false, e, _) => Some(e),
            (true, true, false) => Some(true),
            (true, false, true) => Some(false),
            _ => None,
        };
        let Some(lane) = self.lanes.get_mut(i) else {
            return;
        };
        let Some(dir) = commanded.filter(|d| lane.commanded != Some(*d)) else {
            return;
        };
        lane.commanded = Some(dir);
        lane.since_us = at_us;
        lane.late = false;
        if (a.home.is_none() && a.end.is_none()) || !self.at_target(m, i) {
            if let Some(lane) = self.lanes.get_mut(i) {
                lane.position = Position::Moving;
            }
        }
        self.stepped(
            m,
            &format!("{}{}", a.name, if dir { '+' } else { '-' }),
            at_us,
        );
    }

    /// Whether actuator `i`'s switch for its commanded target reads closed already.
    fn at_target(&self, m: &Machine, i: usize) -> bool {
        let (Some(a), Some(lane)) = (m.wiring.get(i), self.lanes.get(i)) else {
            return false;
        };
        let target = match lane.commanded {
            Some(true) => a.end,
            Some(false) => a.home,
            None => return false,
        };
        self.level(a.addr, target, false) == Some(true)
    }

    fn switch(&mut self, m: &Machine, i: usize, at_us: u64) {
        let Some(a) = m.wiring.get(i) else { return };
        let home = self.level(a.addr, a.home, false) == Some(true);
        let end = self.level(a.addr, a.end, false) == Some(true);
        let position = match (home, end) {
            (_, true) => Position::End,
            (true, false) => Position::Home,
            (false, false) => Position::Moving,
        };
        self.arrive(m, i, position, at_us);
    }

    fn arrive(&mut self, m: &Machine, i: usize, position: Position, at_us: u64) {
        let Some(lane) = self.lanes.get_mut(i) else {
            return;
        };
        let was = lane.position;
        lane.position = position;
        let target = match lane.commanded {
            Some(true) => Position::End,
            Some(false) => Position::Home,
            None => return,
        };
        if position != target || was == position {
            return;
        }
        let extend = target == Position::End;
        lane.last = Some((extend, at_us.saturating_sub(lane.since_us) / 1000));
        lane.late = false;
        let name = m.wiring.get(i).map(|a| a.name.as_str());
        let last = m.sequence.len().checked_sub(1);
        let last_step = last.and_then(|l| m.sequence.get(l));
        let this = name.map(|n| format!("{n}{}", if extend { '+' } else { '-' }));
        if self.step.is_some() && self.step == last && this.as_ref() == last_step {
            self.cycles = self.cycles.saturating_add(1);
            if let Some(t0) = self.cycle_start_us {
                self.cycle_ms.push(at_us.saturating_sub(t0) / 1000);
                let extra = self.cycle_ms.len().saturating_sub(KEPT_CYCLES);
                self.cycle_ms.drain(..extra);
            }
            self.step = None;
            self.next = 0;
            self.cycle_start_us = None;
        }
    }

    /// A commanded step: the cycle's next, its first (a new cycle), or outside it
    /// (homing, or a machine out of step).
    fn stepped(&mut self, m: &Machine, step: &str, at_us: u64) {
        let is = |i: usize| m.sequence.get(i).is_some_and(|s| s == step);
        if self.step.is_some() && is(self.next) {
            self.step = Some(self.next);
            self.next += 1;
        } else if is(0) {
            self.step = Some(0);
            self.next = 1;
            self.cycle_start_us = Some(at_us);
        } else {
            self.step = None;
            self.next = 0;
            self.cycle_start_us = None;
        }
    }

    /// Time passing on the medium's clock (`now_us`): actuators without switches arrive
    /// after their plant time; a motion past its plant time is late.
    pub fn tick(&mut self, m: &Machine, now_us: u64) {
        self.now_us = self.now_us.max(now_us);
        for i in 0..self.lanes.len() {
            let (Some(a), Some(lane)) = (m.wiring.get(i), self.lanes.get(i)) else {
                continue;
            };
            let Some(dir) = lane.commanded else { continue };
            if lane.position != Position::Moving {
                continue;
            }
            let travel = if dir { a.travel_ms.0 } else { a.travel_ms.1 };
            let due = lane.since_us.saturating_add(travel.saturating_mul(1000));
            if self.now_us < due {
                continue;
            }
            if a.home.is_none() && a.end.is_none() {
                let to = if dir { Position::End } else { Position::Home };
                self.arrive(m, i, to, due);
            } else if let Some(lane) = self.lanes.get_mut(i) {
                lane.late = true;
            }
        }
    }

    /// Levels a node's status reports, for pins the medium has not spoken of yet (its
    /// outputs and inputs by table index).
    pub fn levels_from(&mut self, c: &Compiled, m: &Machine, role: usize, s: &Status) {
        let Some(r) = c.ir.roles.get(role) else {
            return;
        };
        let mut fresh = Vec::new();
        for (i, o) in r.outputs.iter().enumerate() {
            if !self.pins.contains_key(&(r.address, o.pin, true)) {
                fresh.push((o.pin, (s.outputs >> i) & 1 == 1, true));
            }
        }
        for (i, input) in r.inputs.iter().enumerate() {
            if !self.pins.contains_key(&(r.address, input.pin, false)) {
                fresh.push((input.pin, (s.inputs >> i) & 1 == 1, false));
            }
        }
        let sensed = fresh.iter().any(|(pin, _, output)| {
            !output
                && (m.station.as_ref())
                    .is_some_and(|s| s.addr == r.address && s.sensors.iter().any(|x| x.1 == *pin))
        });
        for (pin, level, output) in fresh {
            self.pins.insert((r.address, pin, output), level);
        }
        // The ball at a station's sensors before the panel heard a pin (no bin counted).
        if let Some(first) = m
            .station
            .as_ref()
            .and_then(|s| s.sensors.first())
            .filter(|_| sensed)
        {
            let level = self.input(r.address, first.1);
            self.station_pin(m, r.address, first.1, level, Some(level));
        }
        for i in 0..m.wiring.len() {
            let Some(a) = m.wiring.get(i) else { continue };
            let known = self.lanes.get(i).map(|l| l.position) != Some(Position::Unknown);
            if a.addr != r.address || known {
                continue;
            }
            self.init_lane(m, i);
        }
    }

    /// A lane's first position, from the levels as they are (no step, no travel).
    fn init_lane(&mut self, m: &Machine, i: usize) {
        let Some(a) = m.wiring.get(i) else { return };
        let extend = self.level(a.addr, Some(a.valves.0), true) == Some(true);
        let retract = self.level(a.addr, Some(a.valves.1), true) == Some(true);
        let home = self.level(a.addr, a.home, false) == Some(true);
        let end = self.level(a.addr, a.end, false) == Some(true);
        let position = match (a.home.is_some() || a.end.is_some(), home, end) {
            (true, _, true) => Position::End,
            (true, true, false) => Position::Home,
            (true, false, false) => Position::Moving,
            (false, ..) if extend => Position::End,
            (false, ..) => Position::Home,
        };
        if let Some(lane) = self.lanes.get_mut(i) {
            lane.position = position;
            lane.commanded = match (a.double, extend, retract) {
                (false, e, _) => Some(e),
                (true, true, false) => Some(true),
                (true, false, true) => Some(false),
                _ => None,
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::tests::paint;

    /// Drives step `step` (`VC+`) of the paint robot's wiring at `t_ms`, arriving
    /// `travel_ms` later (a switch, or by the plant time for the gripper); the steps the
    /// panel names as the valve changes and at arrival.
    fn stroke(l: &mut Live, m: &Machine, step: &str, t_ms: u64) -> u64 {
        let (name, sign) = step.split_at(step.len() - 1);
        let extend = sign == "+";
        let a = m.wiring.iter().find(|a| a.name == name).unwrap().clone();
        let us = t_ms * 1000;
        if a.double {
            let (on, off) = if extend {
                a.valves
            } else {
                (a.valves.1, a.valves.0)
            };
            l.pin(m, us, a.addr, off, false, true);
            l.pin(m, us, a.addr, on, true, true);
        } else {
            l.pin(m, us, a.addr, a.valves.0, extend, true);
        }
        let travel = if extend { a.travel_ms.0 } else { a.travel_ms.1 };
        let at = us + travel * 1000 + 3000;
        let (from, to) = if extend {
            (a.home, a.end)
        } else {
            (a.end, a.home)
        };
        if let (Some(from), Some(to)) = (from, to) {
            l.pin(m, us + 1000, a.addr, from, false, false);
            assert_eq!(
                l.lanes[m.wiring.iter().position(|w| w.name == name).unwrap()].position,
                Position::Moving
            );
            l.pin(m, at, a.addr, to, true, false);
        } else {
            l.tick(m, at);
        }
        at / 1000
    }

    #[test]
    fn a_cycle_of_pin_changes_walks_the_steps_in_order_and_is_counted_with_its_time() {
        let c = paint();
        let m = Machine::of(&c).unwrap();
        let mut l = Live::new(&m);
        let mut t = 100;
        let mut seen = Vec::new();
        for cycle in 0..2 {
            for (i, step) in m.sequence.clone().iter().enumerate() {
                let done = stroke(&mut l, &m, step, t);
                seen.push(l.step);
                if i + 1 < m.sequence.len() {
                    assert_eq!(l.step, Some(i), "{step} of cycle {cycle}");
                }
                t = done + 2;
            }
            assert_eq!((l.step, l.cycles), (None, cycle + 1));
        }
        assert_eq!(l.cycle_ms.len(), 2);
        // Each stroke: its plant time and 3 ms to the switch, 2 ms to the next command.
        let plant: u64 = (m.sequence.iter())
            .map(|s| {
                let a = m.wiring.iter().find(|a| s.starts_with(&a.name)).unwrap();
                if s.ends_with('+') {
                    a.travel_ms.0
                } else {
                    a.travel_ms.1
                }
            })
            .sum();
        let strokes = m.sequence.len() as u64;
        assert_eq!(l.cycle_ms[0], plant + strokes * 5 - 2);
        let vc = &l.lanes[0];
        assert_eq!((vc.position, vc.last), (Position::Home, Some((false, 253))));
        // The gripper has no switches: it arrived by its plant time.
        assert_eq!(l.lanes[1].position, Position::Home);
    }

    #[test]
    fn a_step_out_of_sequence_is_no_step_of_the_cycle() {
        let c = paint();
        let m = Machine::of(&c).unwrap();
        let mut l = Live::new(&m);
        stroke(&mut l, &m, "HC-", 0);
        assert_eq!(l.step, None);
        stroke(&mut l, &m, "VC+", 900);
        assert_eq!(l.step, Some(0));
        stroke(&mut l, &m, "RC+", 1500);
        assert_eq!((l.step, l.cycles), (None, 0));
    }

    #[test]
    fn a_sorters_balls_are_seen_at_the_sensors_and_in_their_bins() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../robot-configs/ball-sorter.ron"
        );
        let text = std::fs::read_to_string(path).unwrap();
        let c = robot_compiler::compile::compile(&robot_compiler::Source::new("b", text)).unwrap();
        let m = Machine::of(&c).unwrap();
        let s = m.station.clone().unwrap();
        let mut l = Live::new(&m);
        let sense = |l: &mut Live, levels: [bool; 3], t: u64| {
            for (x, lv) in s.sensors.iter().zip(levels) {
                l.pin(&m, t, s.addr, x.1, lv, false);
            }
        };
        let land = |l: &mut Live, bin: usize, t: u64| {
            l.pin(&m, t, s.addr, s.bins[bin].1, true, false);
            l.pin(&m, t + 5, s.addr, s.bins[bin].1, false, false);
        };
        sense(&mut l, [true, true, true], 0);
        assert_eq!(l.station.at_sensors.as_deref(), Some("gray"));
        sense(&mut l, [false, false, false], 10);
        assert_eq!(l.station.at_sensors, None);
        sense(&mut l, [true, false, false], 20);
        assert_eq!(l.station.at_sensors.as_deref(), Some("black"));
        land(&mut l, 1, 30);
        sense(&mut l, [false, false, false], 40);
        land(&mut l, 0, 50);
        sense(&mut l, [false, true, false], 60);
        assert_eq!(l.station.at_sensors.as_deref(), Some("unknown"));
        sense(&mut l, [true, false, true], 70);
        assert_eq!(l.station.at_sensors.as_deref(), Some("orange"));
        assert_eq!(l.station.bins, [vec!["black"], vec!["gray"], vec![]]);
    }

    #[test]
    fn an_event_is_counted_once_however_often_it_is_resent() {
        let c = paint();
        let m = Machine::of(&c).unwrap();
        let mut l = Live::new(&m);
        let ((src, topic), _) = (m.topics.iter()).find(|(_, (r, _))| r == "GR").unwrap();
        assert_eq!(*src, 0x0012);
        let topic = *topic;
        l.event(&m, 10, 0x0012, 1, 5, topic);
        l.event(&m, 20, 0x0012, 1, 5, topic);
        l.event(&m, 30, 0x0012, 1, 6, topic);
        assert_eq!(l.event_count, 2);
        let (at, role, _) = l.events.back().unwrap();
        assert_eq!((*at, role.as_str()), (30, "GR"));
        l.event(&m, 40, 0x0099, 0, 0, 250);
        assert_eq!(
            l.events.back().map(|e| (&e.1[..], &e.2[..])),
            Some(("0x0099", "topic 250"))
        );
    }

    #[test]
    fn a_motion_past_its_plant_time_is_late() {
        let c = paint();
        let m = Machine::of(&c).unwrap();
        let mut l = Live::new(&m);
        let hc = m.wiring.iter().position(|a| a.name == "HC").unwrap();
        let a = m.wiring[hc].clone();
        l.pin(&m, 0, a.addr, a.home.unwrap(), true, false);
        l.pin(&m, 1000, a.addr, a.valves.0, true, true);
        assert_eq!(l.lanes[hc].position, Position::Moving);
        assert_eq!(l.pin_us, Some(1000));
        l.tick(&m, 800_000);
        assert!(!l.lanes[hc].late);
        l.tick(&m, 801_001);
        assert!(l.lanes[hc].late);
    }
}
