//! The demo's report, line by line: pushes, cycles, faults in words.

use std::io::Write;

use config_schema::alarm::{AlarmSource, NO_CHART};
use robot_compiler::compile::Compiled;

use super::bed::{Cycle, FaultReport, Homing, NodeAfter};
use crate::home::HomeEnd;
use crate::push;
use node_fw::ota::Progress;

/// A one-line summary of a push.
pub fn push_line(o: &push::Pushed) -> String {
    let keys = match o.key_bytes {
        0 => String::new(),
        n => format!(" + {n} of keys"),
    };
    format!(
        "  {:<6} {:#06x}  {:>5} bytes{keys}  {:>3} frames  {:>3} retries  {:>6.1} ms  {}",
        o.role,
        o.addr,
        o.bytes,
        o.stats.frames,
        o.stats.retries,
        o.elapsed.as_secs_f64() * 1e3,
        o.verdict()
    )
}

/// A push's last line: the tables staged (all, or how many of how many) and their bytes,
/// and what the transfers took (frames sent, retries; the longest transfer's time).
pub fn push_summary(outcomes: &[push::Pushed]) -> String {
    let (bytes, frames, retries) = outcomes.iter().fold((0, 0, 0), |a, o| {
        let staged = if o.progress == Progress::Done && !o.running {
            o.bytes
        } else {
            0
        };
        (a.0 + staged, a.1 + o.stats.frames, a.2 + o.stats.retries)
    });
    let time = outcomes.iter().map(|o| o.elapsed).max().unwrap_or_default();
    let done = |o: &&push::Pushed| o.progress == Progress::Done;
    let staged = outcomes.iter().filter(done).filter(|o| !o.running).count();
    let running = outcomes.iter().filter(done).filter(|o| o.running).count();
    let already = match running {
        0 => String::new(),
        n => format!(", {n} run theirs already"),
    };
    let what = match outcomes.len() - staged - running {
        0 => format!("pushed {staged} table(s){already}"),
        not => format!(
            "staged {staged} of {} table(s){already} ({not} not: above)",
            outcomes.len()
        ),
    };
    format!(
        "{what}: {bytes} bytes, {frames} frames, {retries} retries, {:.1} ms",
        time.as_secs_f64() * 1e3
    )
}

/// Prints a cycle's verdict.
pub fn cycle_line(n: usize, cy: &Cycle) -> String {
    let verdict = match (&cy.fault, cy.ok()) {
        (Some(_), _) => "FAULTED",
        (None, true) => "ok",
        (None, false) => "MISMATCH",
    };
    let mut s = format!(
        "cycle {n}: {verdict}  {:.2} s  {} frames  {:.1} ms airtime  {}",
        cy.duration.as_secs_f64(),
        cy.frames,
        cy.airtime_us as f64 / 1e3,
        robot_analysis::sim::steps_text(&cy.steps)
    );
    if let Some(f) = &cy.fault {
        s.push('\n');
        s.push_str(&fault_text(f));
    } else if cy.mixed() {
        // Which step ran under which generation: `VC+@1 GR+@1 VC-@2 ...`.
        let steps: Vec<String> = cy
            .steps
            .iter()
            .zip(&cy.generations)
            .map(|(st, g)| format!("{st}@{g}"))
            .collect();
        s.push_str(&format!("\n  MIXED generations: {}", steps.join(" ")));
    } else if !cy.ok() {
        s.push('\n');
        s.push_str(&robot_analysis::sim::diff(&cy.expect, &cy.steps));
        for (role, code) in &cy.faults {
            s.push_str(&format!("  role {role} faulted (code {code:#04x})\n"));
        }
    }
    s
}

/// What homing is about to run: `homing: VC- HC- RC- GR- (HOME to node 0x0011, VC)`.
pub fn homing_line(c: &Compiled) -> String {
    let node = c.ir.home.and_then(|h| c.ir.roles.get(h)).map_or_else(
        || "the robot has no home role".to_string(),
        |r| format!("HOME to node {:#06x}, {}", r.address, r.name),
    );
    format!(
        "homing: {} ({node}; a step whose switch reads its target already is skipped)",
        robot_analysis::sim::steps_text(&c.ir.homing)
    )
}

/// How homing ended, with the steps the plant saw.
pub fn homed_line(h: &Homing) -> String {
    let moved = if h.steps.is_empty() {
        "the plant moved nothing".to_string()
    } else {
        format!(
            "the plant moved {}",
            robot_analysis::sim::steps_text(&h.steps)
        )
    };
    let end = match &h.end {
        HomeEnd::Homed => format!("homed: every chart idle in {:.2} s", h.took.as_secs_f64()),
        HomeEnd::Refused(why) => format!("homing refused: {why}"),
        HomeEnd::Ignored { role, addr } => {
            format!("homing did not start: node {addr:#06x} ({role}) ignored HOME")
        }
        HomeEnd::Faulted {
            role, addr, code, ..
        } => format!(
            "homing FAULTED: node {addr:#06x} ({role}): {}",
            fault_meaning(*code)
        ),
        HomeEnd::NotDone(waiting) => format!("homing did not end: {}", waiting.join(", ")),
    };
    format!("{end}; {moved}")
}

/// A status fault code in words (`node_fw::node::fault_code`).
pub fn fault_meaning(code: u8) -> String {
    const ACTION: u8 = 0x80;
    match code {
        1 => "the interpreter's chain limit (event-less transitions)".into(),
        2 => "the interpreter's event queue overflowed".into(),
        3 => "the interpreter's cascade limit".into(),
        4 => "a guard or assignment failed to evaluate".into(),
        c if c == ACTION | robot_compiler::synth::FAULT_MOTION_TIMEOUT => {
            "its motion watchdog expired".into()
        }
        c if c == ACTION | robot_compiler::synth::FAULT_PEER => "stopped by a peer's fault".into(),
        c if c == ACTION | config_schema::alarm::FAULT_ESTOP => "its emergency stop".into(),
        c if c == ACTION | config_schema::alarm::FAULT_ESTOP_PEER => {
            "stopped by another node's emergency stop".into()
        }
        c if c == ACTION | config_schema::alarm::FAULT_LINK => {
            "a link alarm (on_link_alarm: Fault)".into()
        }
        c if c == ACTION | config_schema::alarm::FAULT_PEER_RESTART => {
            "a peer restarted (a power cut?) while this node was under way".into()
        }
        c if c & ACTION != 0 => format!("fault action {}", c & !ACTION),
        c => format!("fault {c:#04x}"),
    }
}

/// A fault in words: who detected it, how, when, and what every node then did.
pub fn fault_text(f: &FaultReport) -> String {
    let links: Vec<String> = f
        .links
        .iter()
        .map(|(peer, broken)| match broken {
            true => format!("link to {peer} broken (nothing more is sent on it until a reset)"),
            false => format!("link alarm: {peer} does not acknowledge"),
        })
        .collect();
    let how = match f.code {
        Some(code) => fault_meaning(code),
        None if !links.is_empty() => links.join("; "),
        None => "a fault (its status did not answer)".to_string(),
    };
    let mut s = format!(
        "FAULT at {:.3} s: node {:#06x} ({}) detected it: {how}",
        f.at.as_secs_f64(),
        f.addr,
        f.role
    );
    if let Some(quiet) = f.stalled {
        s.push_str(&format!(
            "\n  no node published a fault: its status showed it after {:.3} s without a step",
            quiet.as_secs_f64()
        ));
    }
    let watchdog = f.code.is_some() || f.links.is_empty();
    if let Some((step, at, _)) = f.step.as_ref().filter(|_| !watchdog) {
        s.push_str(&format!(
            "\n  last step: {step}, commanded at {:.3} s",
            at.as_secs_f64()
        ));
    }
    if let Some((step, at, jammed)) = f.step.as_ref().filter(|_| watchdog) {
        let what = if *jammed {
            "the plant saw the command and the rod did not move"
        } else {
            "it did not complete"
        };
        s.push_str(&format!(
            "\n  watchdog of step {step}, commanded at {:.3} s ({:.3} s before the detection): \
             {what}",
            at.as_secs_f64(),
            f.at.saturating_sub(*at).as_secs_f64()
        ));
    }
    for (role, addr, node) in &f.nodes {
        let state = match node {
            Some(NodeAfter {
                fault: Some(c),
                outputs,
            }) => format!(
                "faulted ({}, code {c:#04x}), outputs {outputs:#06x}",
                fault_meaning(*c)
            ),
            Some(NodeAfter {
                fault: None,
                outputs,
            }) => format!("NOT faulted, outputs {outputs:#06x}"),
            None => "did not answer (stopped, or out of range)".to_string(),
        };
        s.push_str(&format!("\n  node {addr:#06x} ({role}): {state}"));
        let changes: Vec<String> = f
            .outputs
            .iter()
            .filter(|o| o.1 == *addr)
            .map(|(at, _, pin, level)| {
                format!(
                    "pin {pin} -> {} at {:.3} s",
                    u8::from(*level),
                    at.as_secs_f64()
                )
            })
            .collect();
        if !changes.is_empty() {
            s.push_str(&format!("; {}", changes.join(", ")));
        }
    }
    s
}

/// Writes a line and flushes (the demo prints as things happen).
pub fn say(out: &mut dyn Write, line: &str) {
    let _ = writeln!(out, "{line}");
    let _ = out.flush();
}
/// The source of an alarm in words, with the robot's names.
pub fn alarm_text(c: &Compiled, role: &str, source: AlarmSource) -> String {
    let ri = c.ir.roles.iter().position(|r| r.name == role);
    match source {
        AlarmSource::Chart { chart, code } => {
            let name = (chart != NO_CHART)
                .then(|| ri.and_then(|r| c.ir.roles[r].charts.get(usize::from(chart))))
                .flatten()
                .map_or_else(String::new, |ch| format!("chart `{}`: ", ch.name));
            format!("{name}{} (code {code:#04x})", fault_meaning(code))
        }
        AlarmSource::EStop => {
            let input = ri
                .and_then(|r| c.ir.roles[r].safety.estop.clone())
                .unwrap_or_default();
            format!("emergency stop `{input}` pressed")
        }
        AlarmSource::Link { peer } => {
            let addr = ri.and_then(|r| c.tables[r].peers.get(usize::from(peer)).copied());
            let who = addr.map_or_else(
                || format!("peer #{peer}"),
                |a| match c.ir.roles.iter().find(|r| r.address == a) {
                    Some(r) => format!("{} ({a:#06x})", r.name),
                    None => format!("{a:#06x}"),
                },
            );
            format!("link alarm: {who} does not acknowledge")
        }
        AlarmSource::Declared { index } => {
            let decl = ri.and_then(|r| c.ir.roles[r].safety.alarms.get(usize::from(index)));
            match decl {
                Some((name, _, when, _)) => format!("alarm \"{name}\" ({when})"),
                None => format!("declared alarm #{index}"),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use config_schema::wire::msg::Refusal;
    use node_fw::ota::TransferStats;

    use super::*;

    #[test]
    fn homing_says_how_it_ended_and_what_the_plant_moved() {
        let step = |a: &str| robot_compiler::ir::Step {
            actuator: a.into(),
            extend: false,
        };
        let mut h = Homing {
            end: HomeEnd::Homed,
            steps: vec![],
            took: Duration::from_millis(420),
        };
        assert_eq!(
            homed_line(&h),
            "homed: every chart idle in 0.42 s; the plant moved nothing"
        );
        h.steps = vec![step("VC"), step("HC")];
        h.end = HomeEnd::Faulted {
            role: "HC".into(),
            addr: 0x0013,
            code: 0x81,
            others: vec![0x0011],
        };
        assert_eq!(
            homed_line(&h),
            "homing FAULTED: node 0x0013 (HC): its motion watchdog expired; the plant moved \
             VC- HC-"
        );
    }

    /// A cycle whose steps ran under two generations is not ok, and says which ran where.
    #[test]
    fn a_cycle_of_mixed_generations_is_shown_step_by_step() {
        let step = |a: &str, extend| robot_compiler::ir::Step {
            actuator: a.to_string(),
            extend,
        };
        let steps = vec![step("A", true), step("B", true), step("A", false)];
        let mut cy = Cycle {
            steps: steps.clone(),
            generations: vec![1, 1, 1],
            expect: steps,
            duration: Duration::from_millis(1500),
            frames: 7,
            airtime_us: 4000,
            faults: Vec::new(),
            fault: None,
        };
        assert!(cy.ok());
        cy.generations[2] = 2;
        assert!(!cy.ok());
        assert_eq!(
            cycle_line(3, &cy),
            "cycle 3: MISMATCH  1.50 s  7 frames  4.0 ms airtime  A+ B+ A-\n  \
             MIXED generations: A+@1 B+@1 A-@2"
        );
    }

    /// A push that every node refused said `pushed 4 table(s)`: the summary counts the
    /// tables staged, and says how many were not.
    #[test]
    fn the_push_summary_counts_the_tables_staged() {
        let o = |progress| push::Pushed {
            role: "VC".into(),
            addr: 0x0011,
            switch: None,
            progress,
            stats: TransferStats {
                frames: 2,
                retries: 1,
                bytes: 88,
            },
            bytes: 88,
            key_bytes: 0,
            elapsed: Duration::from_micros(12_500),
            running: false,
            not_idle: false,
        };
        let stale = Progress::Refused(Refusal::Stale { running: 1 });
        assert_eq!(
            push_summary(&[o(Progress::Done), o(Progress::Done)]),
            "pushed 2 table(s): 176 bytes, 4 frames, 2 retries, 12.5 ms"
        );
        assert_eq!(
            push_summary(&[o(Progress::Done), o(stale), o(Progress::GaveUp)]),
            "staged 1 of 3 table(s) (2 not: above): 88 bytes, 6 frames, 3 retries, 12.5 ms"
        );
        // The bytes are the tables staged' (a refused table's were counted too).
        assert_eq!(
            push_summary(&[o(stale), o(stale)]),
            "staged 0 of 2 table(s) (2 not: above): 0 bytes, 4 frames, 2 retries, 12.5 ms"
        );
    }

    #[test]
    fn push_prints_the_nodes_refusal_reason() {
        let o = push::Pushed {
            role: "VC".into(),
            addr: 0x0011,
            switch: None,
            progress: Progress::Refused(Refusal::Pin {
                pin: 20,
                board: 0xFFFF,
            }),
            stats: TransferStats {
                frames: 5,
                retries: 0,
                bytes: 274,
            },
            bytes: 274,
            key_bytes: 0,
            elapsed: Duration::from_micros(46_100),
            running: false,
            not_idle: false,
        };
        assert_eq!(
            push_line(&o),
            "  VC     0x0011    274 bytes    5 frames    0 retries    46.1 ms  \
             refused: the table uses pin 20, which the board lacks (its pins: 0-15)"
        );
        let done = push::Pushed {
            progress: Progress::Done,
            switch: Some(node_fw::switch::NodeState::Switched),
            key_bytes: 81,
            ..o
        };
        assert_eq!(done.verdict(), "activated");
        assert_eq!(
            push_line(&done),
            "  VC     0x0011    274 bytes + 81 of keys    5 frames    0 retries    46.1 ms  \
             activated"
        );
    }
}
