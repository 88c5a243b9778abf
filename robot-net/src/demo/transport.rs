//! The demo of a robot with control functions (`functions:`): push, then the operator's
//! script of fig. 9 ([`super::script`]) on the live plant with the declared motors
//! ([`crate::live_motor`]); each step waits for events (the plant's motions, the nodes'
//! statuses), never for time, and is compared with what `sim` says it does: the motor's
//! motions in order, every function's place, the alarm acknowledged. The fault's step
//! says which node stopped the motor and how long after the contact closed.

use std::io::Write;
use std::sync::mpsc::{Receiver, Sender};
use std::time::{Duration, Instant};

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
        finish(bed, Verdict::PushFailed, out);
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
    };
    let mut verdict = Verdict::Matched;
    for (i, want) in expected.iter().enumerate() {
        if !live.step(&mut bed, i + 1, want, out)? {
            verdict = Verdict::Mismatch;
            break;
        }
    }
    finish(bed, verdict, out);
    Ok(verdict)
}

fn finish(bed: Bed, verdict: Verdict, out: &mut dyn Write) {
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
        let mut ok = true;
        match &want.act {
            Act::Start => {
                bed.press_start(self.c)?;
            }
            Act::Fault(level) => self.send(Operate::Set(self.input(&fault)?, *level))?,
            Act::Press(name) => self.send(Operate::Press(self.input(name)?))?,
            Act::Ack => {
                // The fault cleared reaches the operator's panel one hop later: wait for its
                // alarm report to say the cause is gone, then acknowledge.
                let end = Instant::now() + bed.timeout();
                while self.alarms(bed, false)?.iter().any(|a| a.3) && Instant::now() < end {}
                alarms = self.alarms(bed, true)?;
            }
        }
        let moved = self.moved(bed, want.moved.len())?;
        let words: Vec<String> = moved.iter().map(|(m, ..)| format!("{motor} {m}")).collect();
        let got: Vec<Moved> = moved.iter().map(|m| m.0).collect();
        say(
            out,
            &format!(
                "step {n}: {}: {}",
                want.act,
                if words.is_empty() {
                    String::from("nothing moves")
                } else {
                    words.join(", ")
                }
            ),
        );
        if got != want.moved {
            let sim: Vec<String> = want.moved.iter().map(|m| format!("{motor} {m}")).collect();
            say(out, &format!("  DIFFERENT from sim: {}", sim.join(", ")));
            ok = false;
        }
        if let (Act::Fault(true), Some(&(_, addr, at, at_um))) = (&want.act, moved.first()) {
            self.say_stop(addr, at, at_um, &fault, out);
        }
        let functions = self.functions(bed, &want.functions)?;
        say(
            out,
            &format!("  functions: {}", script::functions_text(&functions)),
        );
        if functions != want.functions {
            say(
                out,
                &format!(
                    "  DIFFERENT from sim: {}",
                    script::functions_text(&want.functions)
                ),
            );
            ok = false;
        }
        if want.act == Act::Ack {
            let role = self.start_role();
            for a in &alarms {
                say(
                    out,
                    &format!(
                        "  alarm on {role}: {} ({:?}){}{}",
                        alarm_text(self.c, &role, a.0),
                        a.1,
                        if a.2 { ", acknowledged" } else { "" },
                        if a.3 { ", persists" } else { "" }
                    ),
                );
            }
            if alarms != want.alarms {
                say(out, "  DIFFERENT from sim's alarms");
                ok = false;
            }
        }
        Ok(ok)
    }

    fn start_role(&self) -> String {
        let c = self.c;
        (c.ir.start.as_ref())
            .and_then(|(r, _)| c.ir.roles.get(*r))
            .map_or_else(String::new, |r| r.name.clone())
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
        let end = Instant::now() + bed.timeout();
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
                    Motion::Input { .. } => {}
                }
            }
            if got.len() >= n {
                return Ok(got);
            }
            let left = end.saturating_duration_since(Instant::now());
            match self.seen.recv_timeout(left) {
                Ok(m) => {
                    self.note(&m);
                    self.pending.push(m);
                }
                Err(_) => return Ok(got),
            }
        }
    }

    /// Keeps the time of the operator's last input change (the fault's).
    fn note(&mut self, m: &Motion) {
        if let Motion::Input { at, .. } = m {
            self.last_input = Some(*at);
        }
    }

    /// Which node stopped the motor and how long after the fault contact closed.
    fn say_stop(&self, addr: u16, at: Duration, at_um: u64, fault: &str, out: &mut dyn Write) {
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
        say(
            out,
            &format!(
                "  stopped by node {addr:#06x} ({}), {bound}; {after} after the fault, at \
                 {:.1} mm",
                role(addr),
                at_um as f64 / 1e3
            ),
        );
    }

    /// The functions' places from the nodes' statuses, asked until they are `want` (a
    /// status arriving is the event) or the bed's timeout passed: the last seen.
    fn functions(
        &self,
        bed: &mut Bed,
        want: &[(String, String)],
    ) -> Result<Vec<(String, String)>, NetError> {
        let end = Instant::now() + bed.timeout();
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
