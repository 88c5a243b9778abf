//! `alarms` and `ack`: every node's latched alarms in words, and the operator's
//! acknowledgement (docs/running-a-robot.md, "Alarms").

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use config_schema::alarm::{Alarm, AlarmLevel, AlarmReport, AlarmSource};
use robot_compiler::Compiled;
use robot_net::demo;

/// One node's alarms as the tool read them: its role, address, the report and when
/// (wall clock) it came.
pub struct NodeAlarms {
    pub role: String,
    pub addr: u16,
    pub report: AlarmReport,
    pub read_at: SystemTime,
}

/// `latched`, `acknowledged`, and whether the cause persists.
pub fn state_text(a: &Alarm) -> &'static str {
    match (a.acked, a.persists) {
        (false, true) => "latched, cause persists",
        (false, false) => "latched",
        (true, true) => "acknowledged, cause persists",
        (true, false) => "acknowledged",
    }
}

/// When the node raised it, on the wall clock: the report's time less the alarm's age.
pub fn raised_at(n: &NodeAlarms, a: &Alarm) -> SystemTime {
    let age = n.report.now_ms.wrapping_sub(a.raised_ms);
    n.read_at - Duration::from_millis(u64::from(age))
}

/// `HH:MM:SS.mmm` UTC.
pub fn clock(t: SystemTime) -> String {
    let ms = t.duration_since(UNIX_EPOCH).unwrap_or_default().as_millis() as u64;
    let (s, ms) = (ms / 1000, ms % 1000);
    format!(
        "{:02}:{:02}:{:02}.{ms:03}",
        (s / 3600) % 24,
        (s / 60) % 60,
        s % 60
    )
}

/// A node of the robot that did not answer: role, address, how often it was asked, within
/// how long.
pub struct Silent {
    pub role: String,
    pub addr: u16,
    pub asked: u64,
    pub within: Duration,
}

impl Silent {
    /// Its line among the alarms.
    pub fn line(&self) -> String {
        format!(
            "{:#06x} {:<8}  did not answer: its alarms are unknown",
            self.addr, self.role
        )
    }

    /// The error it ends the command with: that it did not answer, then `what`.
    pub fn failure(&self, what: &str) -> String {
        format!(
            "node {:#06x} ({}) did not answer (asked {} times in {} s): {what}",
            self.addr,
            self.role,
            self.asked,
            self.within.as_secs()
        )
    }
}

/// One line per alarm of every node that answered (and a line per node that dropped
/// some; `no alarms` if none), then a line per node that did not answer.
pub fn lines(c: &Compiled, nodes: &[NodeAlarms], silent: &[Silent]) -> Vec<String> {
    let mut out = Vec::new();
    for n in nodes {
        for a in &n.report.alarms {
            out.push(format!(
                "{:<7}  {} UTC  {:#06x} {:<8}  {}  [{}]",
                a.level.to_string(),
                clock(raised_at(n, a)),
                n.addr,
                n.role,
                demo::alarm_text(c, &n.role, a.source),
                state_text(a)
            ));
        }
        if n.report.dropped > 0 {
            out.push(format!(
                "{:#06x} {}: {} alarm(s) dropped (the list was full)",
                n.addr, n.role, n.report.dropped
            ));
        }
    }
    if out.is_empty() && silent.is_empty() {
        out.push(String::from("no alarms"));
    }
    out.extend(silent.iter().map(Silent::line));
    out
}

/// The fault alarm that keeps the machine from restarting, in words, if any.
pub fn blocking_text(c: &Compiled, nodes: &[NodeAlarms]) -> Option<String> {
    nodes.iter().find_map(|n| {
        let a = n.report.blocking()?;
        let why = if a.persists {
            // What ends the cause, then another `ack`.
            match a.source {
                AlarmSource::Chart { .. } => format!(
                    "its cause persists: the node is faulted; config-tool reset --node \
                     {:#06x}, then ack again",
                    n.addr
                ),
                AlarmSource::EStop => {
                    "its cause persists: the emergency stop is pressed; release it, then \
                     ack again"
                        .to_string()
                }
                AlarmSource::Link { .. } => "its cause persists: the link is in alarm; \
                                              ack again once the peer acknowledges"
                    .to_string(),
                AlarmSource::Declared { .. } => {
                    "its cause persists: its condition holds; ack again once it clears".to_string()
                }
            }
        } else {
            "not acknowledged: config-tool ack".to_string()
        };
        Some(format!(
            "node {:#06x} ({}) has a fault alarm latched: {} ({why})",
            n.addr,
            n.role,
            demo::alarm_text(c, &n.role, a.source)
        ))
    })
}

/// What `ack` left latched, one line per alarm, and why.
pub fn stayed(c: &Compiled, nodes: &[NodeAlarms]) -> Vec<String> {
    let mut out = Vec::new();
    for n in nodes {
        for a in n.report.alarms.iter().filter(|a| !a.acked) {
            let why = if a.level == AlarmLevel::Fault && a.persists {
                "its cause persists"
            } else {
                "raised after the acknowledgement"
            };
            out.push(format!(
                "stayed: {:#06x} {}: {} ({why})",
                n.addr,
                n.role,
                demo::alarm_text(c, &n.role, a.source)
            ));
        }
    }
    out
}
