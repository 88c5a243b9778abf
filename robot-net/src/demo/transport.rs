//! The demo of a robot with control functions (`functions:`): push, then the operator's
//! script of fig. 9 ([`super::script`]) on the live plant with the declared motors
//! ([`crate::live_motor`]); each step waits for events (the plant's motions, the nodes'
//! statuses), never for time, and is compared with what `sim` says it does: the motor's
//! motions in order, every function's place, the alarm acknowledged. The fault's step
//! says which node stopped the motor and how long after the contact closed.

use std::io::Write;
use std::sync::mpsc::{Receiver, Sender};
use std::time::{Duration, Instant};

use config_schema::alarm::AlarmSource;
use robot_compiler::Compiled;

use super::bed::{self, Bed};
use super::report::{alarm_text, say};
use super::run::{bring_up, finish_as, push_robot, Verdict};
use super::script::{self, Act, AlarmSeen, Expected, Moved};
use crate::error::NetError;
use crate::live_motor::{self, Motion, Operate};
use crate::live_plant;

/// The demo of `c`: fig. 9 on the bed; says each step and the verdict.
pub fn run(c: &Compiled, options: bed::Options, out: &mut dyn Write) -> Result<Verdict, NetError> {
    let script = script::fig9();
    let expected = script::simulate(c, &script)?;
    let actuators = live_plant::actuators(c)?;
    let addrs = bed::node_addrs(c);
    let mut bed = bring_up(options, &addrs, actuators.clone(), out)?;
    if !push_robot(&mut bed, std::path::Path::new(&c.robot.name), c, out)? {
        finish(bed, Verdict::PushFailed, out)?;
        return Ok(Verdict::PushFailed);
    }
    let motors = live_motor::motors(c)?;
    let (operate, seen) = bed.set_plant_motors(actuators, motors.clone())?;
    let mut live = Live {
        c,
        motors,
        operate,
        seen,
        pending: Vec::new(),
        last_input: None,
        held: false,
    };
    let mut verdict = Verdict::Matched;
    for (i, want) in expected.iter().enumerate() {
        if !live.step(&mut bed, i + 1, want, out)? {
            verdict = Verdict::Mismatch;
            break;
        }
    }
    finish(bed, verdict, out)?;
    Ok(verdict)
}

fn finish(bed: Bed, verdict: Verdict, out: &mut dyn Write) -> Result<(), NetError> {
    finish_as(
        bed,
        verdict,
        "demo: every step as sim",
        "demo: FAILED (steps differ from sim's)",
        out,
    )
}

/// A motion of the motor: with the address of the node that commanded it (0 for an
/// arrival), the medium's time and where the carriage was (µm from home; 0 for an
/// arrival).
type Motioned = (Moved, u16, Duration, u64);

/// What one step did on the bed.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Observed {
    moved: Vec<Moved>,
    /// The fault's step: which node stopped the motor ([`Live::stop_line`]).
    stop: Option<String>,
    functions: Vec<(String, String)>,
    /// [`Act::Ack`]: the alarms of the role of `start` after it.
    alarms: Vec<AlarmSeen>,
}

fn start_role(c: &Compiled) -> String {
    (c.ir.start.as_ref())
        .and_then(|(r, _)| c.ir.roles.get(*r))
        .map_or_else(String::new, |r| r.name.clone())
}

/// Step `n`'s lines (what it did, with every difference from `sim`'s `want`), and whether
/// it did what `sim` does.
fn judge(
    c: &Compiled,
    motor: &str,
    n: usize,
    want: &Expected,
    seen: &Observed,
) -> (Vec<String>, bool) {
    let words = |m: &[Moved]| {
        let w: Vec<String> = m.iter().map(|m| format!("{motor} {m}")).collect();
        if w.is_empty() {
            String::from("nothing moves")
        } else {
            w.join(", ")
        }
    };
    let mut lines = vec![format!("step {n}: {}: {}", want.act, words(&seen.moved))];
    let mut ok = true;
    if seen.moved != want.moved {
        lines.push(format!("  DIFFERENT from sim: {}", words(&want.moved)));
        ok = false;
    }
    lines.extend(seen.stop.clone());
    lines.push(format!(
        "  functions: {}",
        script::functions_text(&seen.functions)
    ));
    if seen.functions != want.functions {
        lines.push(format!(
            "  DIFFERENT from sim: {}",
            script::functions_text(&want.functions)
        ));
        ok = false;
    }
    if want.act == Act::Ack {
        let role = start_role(c);
        // The machine's alarms, compared with sim's; then the radio's (a link in alarm on
        // a lossy radio), which sim has no radio to raise.
        let (radio, machine): (Vec<AlarmSeen>, Vec<AlarmSeen>) =
            seen.alarms.iter().partition(|a| is_radio(a));
        for (kind, a) in
            (machine.iter().map(|a| ("alarm", a))).chain(radio.iter().map(|a| ("radio alarm", a)))
        {
            lines.push(format!(
                "  {kind} on {role}: {} ({:?}){}{}",
                alarm_text(c, &role, a.0),
                a.1,
                if a.2 { ", acknowledged" } else { "" },
                if a.3 { ", persists" } else { "" }
            ));
        }
        if machine != want.alarms {
            lines.push(String::from("  DIFFERENT from sim's alarms"));
            ok = false;
        }
    }
    (lines, ok)
}

/// A link's alarm: the radio's, not the machine's.
fn is_radio(a: &AlarmSeen) -> bool {
    matches!(a.0, AlarmSource::Link { .. })
}

/// The script's side of the bed.
struct Live<'a> {
    c: &'a Compiled,
    motors: live_motor::Motors,
    operate: Sender<Operate>,
    seen: Receiver<Motion>,
    /// Motions taken from the plant, not yet looked at.
    pending: Vec<Motion>,
    /// When the operator last drove an input (the medium's clock).
    last_input: Option<Duration>,
    /// The plant said its time stands still ([`Motion::Held`]).
    held: bool,
}

impl Live<'_> {
    fn input(&self, name: &str) -> Result<usize, NetError> {
        (self.motors.input(name))
            .ok_or_else(|| NetError::Robot(format!("fig. 9 needs a declared input {name}")))
    }

    fn send(&self, op: Operate) -> Result<(), NetError> {
        (self.operate.send(op)).map_err(|_| NetError::Robot("the plant stopped".into()))
    }

    /// Step `n`: the operator's act, then the motor's motions and the functions' places
    /// awaited and compared with `want`; `false` if anything differs.
    fn step(
        &mut self,
        bed: &mut Bed,
        n: usize,
        want: &Expected,
        out: &mut dyn Write,
    ) -> Result<bool, NetError> {
        let (motor, fault) = script::names(self.c)?;
        let mut alarms: Vec<AlarmSeen> = Vec::new();
        // The plant's time goes on from where the last step's places were read.
        self.send(Operate::Go)?;
        let hold = script::under_way(want);
        if hold {
            self.hold_mid_stroke(&motor)?;
        }
        match &want.act {
            Act::Start => {
                bed.press_start(self.c)?;
            }
            Act::Fault(level) => self.send(Operate::Set(self.input(&fault)?, *level))?,
            Act::Press(name) => self.send(Operate::Press(self.input(name)?))?,
            Act::Ack => {
                // The fault cleared reaches the operator's panel one hop later: wait for its
                // alarm report to say the cause is gone, then acknowledge.
                let end = crate::deadline(Instant::now(), bed.timeout());
                while (self.alarms(bed, false)?.iter()).any(|a| a.3 && !is_radio(a))
                    && Instant::now() < end
                {}
                alarms = self.alarms(bed, true)?;
            }
        }
        let moved = self.moved(bed, want.moved.len())?;
        if hold && moved.len() == want.moved.len() {
            self.wait_held(bed);
        }
        let stop = match (&want.act, moved.first()) {
            (Act::Fault(true), Some(&(_, addr, at, at_um))) => {
                Some(self.stop_line(addr, at, at_um, &fault))
            }
            _ => None,
        };
        let seen = Observed {
            moved: moved.iter().map(|m| m.0).collect(),
            stop,
            functions: self.functions(bed, &want.functions)?,
            alarms,
        };
        let (lines, ok) = judge(self.c, &motor, n, want, &seen);
        for line in &lines {
            say(out, line);
        }
        Ok(ok)
    }

    /// The alarms of the role of `start` (after an acknowledgement, with `ack`).
    fn alarms(&self, bed: &mut Bed, ack: bool) -> Result<Vec<AlarmSeen>, NetError> {
        let at = self.c.ir.start.as_ref().map_or(0, |s| s.0);
        let reports = bed.alarms(self.c, ack)?;
        Ok((reports.get(at).iter().flat_map(|r| r.alarms.iter()))
            .map(|a| (a.source, a.level, a.acked, a.persists))
            .collect())
    }

    /// Waits (at most the bed's timeout) for `n` motions of the motor.
    fn moved(&mut self, bed: &Bed, n: usize) -> Result<Vec<Motioned>, NetError> {
        let end = crate::deadline(Instant::now(), bed.timeout());
        let mut got = Vec::new();
        loop {
            for m in self.pending.drain(..) {
                match m {
                    Motion::Run {
                        run,
                        addr,
                        at,
                        at_um,
                        ..
                    } => got.push((Moved::Run(run), addr, at, at_um)),
                    Motion::Arrived { end, at, .. } => got.push((Moved::Arrived(end), 0, at, 0)),
                    Motion::Input { .. } | Motion::Held { .. } => {}
                }
            }
            if got.len() >= n || !self.take_motion(end) {
                return Ok(got);
            }
        }
    }

    /// Takes the plant's next motion into `pending` (noted), waiting until `end`; `false`
    /// once `end` passed without one.
    fn take_motion(&mut self, end: Instant) -> bool {
        let left = end.saturating_duration_since(Instant::now());
        match self.seen.recv_timeout(left) {
            Ok(m) => {
                self.note(&m);
                self.pending.push(m);
                true
            }
            Err(_) => false,
        }
    }

    /// Keeps the time of the operator's last input change (the fault's) and whether the
    /// plant's time stands still.
    fn note(&mut self, m: &Motion) {
        match m {
            Motion::Input { at, .. } => self.last_input = Some(*at),
            Motion::Held { .. } => self.held = true,
            _ => {}
        }
    }

    /// A step that leaves the motor under way has its places read, as `sim` reads them,
    /// half the stroke after it sets off: the plant's time stands still there until the
    /// next step ([`Operate::HoldAfter`]), so a reading slowed by the lossy radio (each
    /// status a round trip, retried) cannot outlast the motion and see the next one's.
    fn hold_mid_stroke(&mut self, motor: &str) -> Result<(), NetError> {
        let i = (self.motors.motor(motor))
            .ok_or_else(|| NetError::Robot(format!("fig. 9 needs a declared motor {motor}")))?;
        let after_ms = (self.motors.motors.get(i)).map_or(0, |m| script::half_stroke_ms(&m.model));
        self.held = false;
        self.send(Operate::HoldAfter { motor: i, after_ms })
    }

    /// Waits (at most the bed's timeout) for the plant to say its time stands still.
    fn wait_held(&mut self, bed: &Bed) {
        let end = crate::deadline(Instant::now(), bed.timeout());
        while !self.held && self.take_motion(end) {}
    }

    /// Which node stopped the motor, how long after the fault contact closed, where.
    fn stop_line(&self, addr: u16, at: Duration, at_um: u64, fault: &str) -> String {
        let c = self.c;
        let role = |a: u16| {
            (c.ir.roles.iter())
                .find(|r| r.address == a)
                .map_or_else(|| String::from("?"), |r| r.name.clone())
        };
        let contact = (self.motors.inputs.iter())
            .find(|i| i.name == fault)
            .map_or(0, |i| i.addr);
        let bound = if addr == contact {
            String::from("the fault contact's own node: same node")
        } else {
            format!(
                "one radio hop from the fault contact's node {contact:#06x} ({})",
                role(contact)
            )
        };
        let after = (self.last_input)
            .map(|t| format!("{:.1} ms", at.saturating_sub(t).as_secs_f64() * 1e3))
            .unwrap_or_else(|| String::from("?"));
        format!(
            "  stopped by node {addr:#06x} ({}), {bound}; {after} after the fault, at {:.1} mm",
            role(addr),
            at_um as f64 / 1e3
        )
    }

    /// The functions' places from the nodes' statuses, asked until they are `want` (a
    /// status arriving is the event) or the bed's timeout passed: the last seen.
    fn functions(
        &self,
        bed: &mut Bed,
        want: &[(String, String)],
    ) -> Result<Vec<(String, String)>, NetError> {
        let end = crate::deadline(Instant::now(), bed.timeout());
        loop {
            let statuses = bed.statuses(self.c)?;
            let states: Vec<Option<Vec<u8>>> = (statuses.iter())
                .zip(&self.c.tables)
                .map(|(s, t)| (s.generation == t.generation).then(|| s.states.to_vec()))
                .collect();
            let got = script::functions(self.c, &states);
            if got == want || Instant::now() >= end {
                return Ok(got);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use config_schema::alarm::AlarmLevel;
    use node_fw::sim::Run;

    fn waterjet() -> Compiled {
        let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../robot-configs/waterjet-transport.ron");
        super::super::load(&path).expect("compiles")
    }

    fn seen(want: &Expected) -> Observed {
        Observed {
            moved: want.moved.clone(),
            stop: None,
            functions: want.functions.clone(),
            alarms: want.alarms.clone(),
        }
    }

    /// A step as sim has it is said and passes; a motion, a place or an alarm that
    /// differs is said beside sim's and fails the step (the demo then exits non-zero).
    #[test]
    fn a_step_that_differs_from_sim_says_how_and_fails() {
        let c = waterjet();
        let want = script::simulate(&c, &script::fig9()).expect("sim");
        let (lines, ok) = judge(&c, "PUSHER", 1, &want[0], &seen(&want[0]));
        assert!(ok);
        assert_eq!(
            lines,
            [
                "step 1: START: PUSHER clockwise",
                "  functions: Operation: Auto, Transport: Step2, Pusher: Clockwise, \
                 FaultDetection: Ok, Belt: Forward"
            ]
        );

        // The motor never stopped and the belt went on: both said, the step fails.
        let mut bad = seen(&want[1]);
        bad.moved.clear();
        if let Some(belt) = bad.functions.iter_mut().find(|f| f.0 == "Belt") {
            belt.1 = "Forward".into();
        }
        let (lines, ok) = judge(&c, "PUSHER", 2, &want[1], &bad);
        assert!(!ok);
        assert_eq!(
            lines,
            [
                "step 2: the fault contact closes: nothing moves",
                "  DIFFERENT from sim: PUSHER stopped",
                "  functions: Operation: Halted, Transport: ReadyToCut, Pusher: Stopped, \
                 FaultDetection: Faulted, Belt: Forward",
                "  DIFFERENT from sim: Operation: Halted, Transport: ReadyToCut, Pusher: \
                 Stopped, FaultDetection: Faulted, Belt: Stopped",
            ]
        );

        // The alarm still persisting after the acknowledgement.
        let mut bad = seen(&want[4]);
        bad.alarms = vec![(
            AlarmSource::Declared { index: 0 },
            AlarmLevel::Fault,
            false,
            true,
        )];
        let (lines, ok) = judge(&c, "PUSHER", 5, &want[4], &bad);
        assert!(!ok);
        assert_eq!(
            lines[2..],
            [
                "  alarm on CABINET: alarm \"pusher fault\" (FaultDetection.Faulted || \
                 FaultDetection.Released) (Fault), persists",
                "  DIFFERENT from sim's alarms",
            ]
        );
        // A link that fell into alarm on the lossy radio (a warning, the link still
        // retrying) is said apart, as the radio's: the sim has no radio, so it is no
        // difference from sim's alarms. Under `on_link_alarm: Fault` the node faults, and
        // that differs in the functions.
        let mut lossy = seen(&want[4]);
        let link = (
            AlarmSource::Link { peer: 0 },
            AlarmLevel::Warning,
            true,
            false,
        );
        lossy.alarms.insert(0, link);
        let (lines, ok) = judge(&c, "PUSHER", 5, &want[4], &lossy);
        assert!(ok, "{lines:?}");
        assert_eq!(
            lines[2..],
            [
                "  alarm on CABINET: alarm \"pusher fault\" (FaultDetection.Faulted || \
                 FaultDetection.Released) (Fault), acknowledged",
                "  radio alarm on CABINET: link alarm: PUSHER (0x0032) does not acknowledge \
                 (Warning), acknowledged",
            ]
        );
        // A motion out of order is a difference too.
        let mut bad = seen(&want[2]);
        bad.moved.swap(0, 2);
        assert_eq!(bad.moved[0], Moved::Run(Run::Stopped));
        assert!(!judge(&c, "PUSHER", 3, &want[2], &bad).1);
    }
}
