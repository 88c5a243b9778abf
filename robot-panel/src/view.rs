//! The live machine as the page reads it (`state.json`, and each server-sent event):
//! lanes, the cycle, each chart's state, nodes, alarms, and each button with whether the
//! machine allows it and why not.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use config_schema::alarm::Alarm;
use robot_compiler::compile::Compiled;
use robot_net::home;
use serde_json::{json, Value};

use crate::buttons::{self, Button};
use crate::live::Live;
use crate::model::Machine;

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

fn alarm_state(a: &Alarm) -> &'static str {
    match (a.acked, a.persists) {
        (false, true) => "latched, cause persists",
        (false, false) => "latched",
        (true, true) => "acknowledged, cause persists",
        (true, false) => "acknowledged",
    }
}

/// The page's state of the machine.
pub fn state(c: &Compiled, m: &Machine, live: &Live) -> Value {
    let lanes: Vec<Value> = (m.actuators.iter().zip(&live.lanes))
        .map(|(a, l)| {
            json!({
                "name": a.name,
                "position": l.position.text(),
                "commanded": l.commanded.map(|e| if e { "+" } else { "-" }),
                "last_ms": l.last.map(|x| x.1),
                "last_dir": l.last.map(|x| if x.0 { "+" } else { "-" }),
                "late": l.late,
            })
        })
        .collect();
    let mut charts = Vec::new();
    for (ri, r) in c.ir.roles.iter().enumerate() {
        // Chart states only of a node that runs this role's table (another robot's
        // charts are not these).
        let status = live
            .nodes
            .get(ri)
            .and_then(|n| n.status.as_ref())
            .filter(|s| s.role.as_str() == r.name)
            .filter(|s| c.tables.get(ri).is_some_and(|t| home::runs(t, s)));
        for ci in 0..r.charts.len() {
            let state = status.and_then(|s| s.states.get(ci)).copied();
            charts.push(json!(state));
        }
    }
    let nodes: Vec<Value> = (c.ir.roles.iter().enumerate())
        .map(|(i, r)| {
            let n = live.nodes.get(i);
            let s = n.and_then(|n| n.status.as_ref());
            let standing = s
                .zip(c.tables.get(i))
                .map(|(s, t)| home::standing(&r.name, t, s));
            let latched = n
                .and_then(|n| n.alarms.as_ref())
                .map_or(0, |(a, _)| a.alarms.iter().filter(|a| !a.acked).count());
            let security = n.and_then(|n| n.security).map(|(keyed, k)| {
                json!({
                    "keyed": keyed,
                    "not_secured": k.not_secured,
                    "bad_mic": k.bad_mic,
                    "replayed": k.replayed,
                    "unknown_key": k.unknown_key,
                    "wrong_level": k.wrong_level,
                    "malformed": k.malformed,
                    "table_full": k.table_full,
                    "no_counter": k.no_counter,
                    "challenged": k.challenged,
                })
            });
            json!({
                "role": r.name,
                "addr": format!("{:#06x}", r.address),
                "answering": n.is_some_and(|n| n.silent.is_none() && n.status.is_some()),
                "silent_since": n.and_then(|n| n.silent).map(clock),
                "standing": standing.map(|s| s.text()),
                "running_role": s.map(|s| s.role.as_str().to_string()),
                "generation": s.map(|s| s.generation),
                "staged": s.map(|s| s.staged),
                "trial": s.map(|s| s.trial),
                "fault": s.and_then(|s| s.fault).map(|f| format!("{f:#04x}")),
                "sent": s.map(|s| s.counters.sent),
                "retries": s.map(|s| s.counters.retried),
                "dropped": s.map(|s| s.counters.dropped),
                "link_alarms": s.map(|s| s.link_alarms),
                "links_broken": s.map(|s| s.links_broken),
                "alarms_latched": latched,
                "security": security,
            })
        })
        .collect();
    let mut alarms = Vec::new();
    for (n, r) in live.nodes.iter().zip(&c.ir.roles) {
        let Some((report, read_at)) = &n.alarms else {
            continue;
        };
        for a in &report.alarms {
            let age = report.now_ms.wrapping_sub(a.raised_ms);
            let at = read_at
                .checked_sub(Duration::from_millis(u64::from(age)))
                .unwrap_or(UNIX_EPOCH);
            alarms.push(json!({
                "level": a.level.to_string(),
                "time": format!("{} UTC", clock(at)),
                "node": format!("{:#06x}", r.address),
                "role": r.name,
                "source": robot_net::demo::alarm_text(c, &r.name, a.source),
                "state": alarm_state(a),
                "latched": !a.acked,
            }));
        }
    }
    let buttons: serde_json::Map<String, Value> = (Button::ALL.into_iter())
        .map(|b| {
            let allowed = buttons::check(b, c, live);
            (
                b.name().to_string(),
                json!({ "enabled": allowed.is_ok(), "why": allowed.err() }),
            )
        })
        .collect();
    json!({
        "medium": live.medium_lost.as_ref().map_or_else(|| json!("ok"), |w| json!(w)),
        "medium_ok": live.medium_lost.is_none(),
        "lanes": lanes,
        "step": live.step,
        "cycles": live.cycles,
        "cycle_ms": live.cycle_ms,
        "pin_us": live.pin_us,
        "charts": charts,
        "nodes": nodes,
        "alarms": alarms,
        "buttons": buttons,
        "running": live.running,
        "busy": live.busy,
        "said": live.said,
        "event_count": live.event_count,
        "events": (live.events.iter().rev())
            .map(|(at, role, event)| json!({
                "at": format!("{:.3}", *at as f64 / 1e6),
                "role": role,
                "event": event,
            }))
            .collect::<Vec<_>>(),
        "station": m.station.as_ref().map(|s| json!({
            "at_sensors": live.station.at_sensors,
            "falling": live.station.falling.len(),
            "bins": live.station.bins,
            "sensors": (s.sensors.iter().chain([&s.entry]).chain(&s.bins))
                .map(|(_, pin)| live.input(s.addr, *pin))
                .collect::<Vec<_>>(),
        })),
    })
}
