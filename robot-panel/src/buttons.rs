//! The operator's buttons and when the machine allows each: one rule per button, read
//! from the machine as last answered. The page greys out a button the rule refuses (its
//! reason as the tooltip); the server refuses the same command with the same reason,
//! and the radio thread checks again on fresh answers before it sends anything.

use config_schema::alarm::AlarmSource;
use robot_compiler::compile::Compiled;
use robot_net::home;
use serde::Serialize;

use crate::live::Live;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum Button {
    /// START: cycles, START pressed again at each idle point, until STOP.
    Start,
    /// STOP at the end of the cycle: START is not pressed again.
    Stop,
    /// RESET every faulted node (or one with broken links).
    Reset,
    /// ACK every node's alarms whose cause is gone.
    Ack,
    /// HOME the machine.
    Home,
    /// CONFIRM the generation on trial on every node.
    Confirm,
}

impl Button {
    pub const ALL: [Button; 6] = [
        Button::Start,
        Button::Stop,
        Button::Reset,
        Button::Ack,
        Button::Home,
        Button::Confirm,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Button::Start => "START",
            Button::Stop => "STOP",
            Button::Reset => "RESET",
            Button::Ack => "ACK",
            Button::Home => "HOME",
            Button::Confirm => "CONFIRM",
        }
    }

    pub fn parse(name: &str) -> Option<Button> {
        Button::ALL.into_iter().find(|b| b.name() == name)
    }
}

/// Whether the machine `live` allows button `b` now; else why not, in words.
pub fn check(b: Button, c: &Compiled, live: &Live) -> Result<(), String> {
    if let Some(why) = &live.medium_lost {
        return Err(format!("no medium: {why}"));
    }
    if let Some(what) = &live.busy {
        return Err(format!("{what} is under way"));
    }
    if b == Button::Stop {
        return match live.running {
            true => Ok(()),
            false => Err("no cycles are running".into()),
        };
    }
    let mut statuses = Vec::new();
    for (n, r) in live.nodes.iter().zip(&c.ir.roles) {
        match (&n.status, n.silent) {
            (Some(s), None) => statuses.push(s.clone()),
            _ => {
                return Err(format!(
                    "node {:#06x} ({}) does not answer",
                    r.address, r.name
                ))
            }
        }
    }
    let nodes = home::nodes(c, &statuses);
    let blocking = || {
        live.nodes.iter().zip(&c.ir.roles).find_map(|(n, r)| {
            let (report, _) = n.alarms.as_ref()?;
            let a = report.blocking()?;
            let text = robot_net::demo::alarm_text(c, &r.name, a.source);
            Some(match a.persists {
                true => format!(
                    "node {:#06x} ({}) has a fault alarm latched: {text} (its cause persists: \
                     {}, then ACK)",
                    r.address,
                    r.name,
                    what_ends(a.source)
                ),
                false => format!(
                    "node {:#06x} ({}) has a fault alarm latched: {text} (ACK first)",
                    r.address, r.name
                ),
            })
        })
    };
    let alarms = || live.nodes.iter().filter_map(|n| n.alarms.as_ref());
    match b {
        Button::Start | Button::Home if live.running => {
            Err("cycles are running: STOP first (it stops at the end of the cycle)".into())
        }
        Button::Start | Button::Home => {
            if c.ir.home.is_none() && b == Button::Home {
                return Err("the robot has no homing".into());
            }
            if c.ir.start.is_none() && b == Button::Start {
                return Err("the robot has no start input".into());
            }
            // A machine only not homed: a latched fault alarm first (ACK comes before
            // HOME, which refuses it), as `config-tool start` says it.
            let not_homed = home::only_not_homed(&nodes);
            if let Some(why) = home::refusal(&nodes, b == Button::Home) {
                return Err(match blocking().filter(|_| not_homed) {
                    Some(alarm) => format!("{alarm}, then HOME"),
                    None => why.replace("run config-tool home", "HOME first"),
                });
            }
            blocking().map_or(Ok(()), Err)
        }
        Button::Reset => {
            let faulted = nodes
                .iter()
                .any(|n| matches!(n.standing, home::Standing::Faulted(_)));
            let broken = statuses.iter().any(|s| s.links_broken != 0);
            match faulted || broken {
                true => Ok(()),
                false => Err("no node is faulted".into()),
            }
        }
        Button::Ack => {
            let open = || {
                alarms()
                    .flat_map(|(r, _)| r.alarms.iter())
                    .filter(|a| !a.acked)
            };
            if open().any(|a| !a.persists) {
                Ok(())
            } else if open().next().is_some() {
                Err("every latched alarm's cause persists (RESET first)".into())
            } else {
                Err("no alarm to acknowledge".into())
            }
        }
        Button::Confirm => match statuses.iter().any(|s| s.trial) {
            true => Ok(()),
            false => Err("nothing on trial".into()),
        },
        Button::Stop => Ok(()),
    }
}

/// What ends the cause of an alarm from `source`, in the panel's words.
fn what_ends(source: AlarmSource) -> &'static str {
    match source {
        AlarmSource::Chart { .. } => "the node is faulted: RESET it",
        AlarmSource::EStop => "the emergency stop is pressed: release it",
        AlarmSource::Link { .. } => "the link is in alarm: wait for the peer to acknowledge",
        AlarmSource::Declared { .. } => "its condition holds: wait for it to clear",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::tests::paint;
    use crate::model::Machine;
    use config_schema::alarm::{Alarm, AlarmLevel, AlarmReport, AlarmSource};
    use config_schema::wire::msg::{Counters, RuntimeCounters, Status};
    use std::time::SystemTime;

    fn status(c: &Compiled, role: usize, idle: bool, fault: Option<u8>) -> Status {
        let t = &c.tables[role];
        let states = t
            .charts
            .iter()
            .map(|ch| if idle { ch.idle } else { ch.initial })
            .collect::<Vec<u8>>();
        Status {
            ack: 1,
            role: heapless::String::try_from(c.ir.roles[role].name.as_str()).unwrap(),
            generation: 1,
            table: config_schema::TableId::at(t, 1).unwrap(),
            staged: 0,
            previous: 0,
            trial: false,
            states: heapless::Vec::from_slice(&states).unwrap(),
            outputs: 0,
            inputs: 0,
            fault,
            link_alarms: 0,
            links_broken: 0,
            links_restarted: 0,
            epoch: 0,
            counters: Counters::default(),
            runtime: RuntimeCounters::default(),
            cycles: 0,
        }
    }

    fn machine(c: &Compiled, idle: bool) -> Live {
        let mut live = Live::new(&Machine::of(c).unwrap());
        for (i, n) in live.nodes.iter_mut().enumerate() {
            n.status = Some(status(c, i, idle, None));
            n.alarms = Some((
                AlarmReport {
                    ack: 1,
                    now_ms: 0,
                    alarms: heapless::Vec::new(),
                    dropped: 0,
                },
                SystemTime::UNIX_EPOCH,
            ));
        }
        live
    }

    fn allowed(c: &Compiled, live: &Live) -> Vec<&'static str> {
        (Button::ALL.into_iter())
            .filter(|b| check(*b, c, live).is_ok())
            .map(Button::name)
            .collect()
    }

    #[test]
    fn a_machine_not_homed_offers_home_only_and_a_homed_one_start_too() {
        let c = paint();
        let live = machine(&c, false);
        assert_eq!(allowed(&c, &live), ["HOME"]);
        assert_eq!(
            check(Button::Start, &c, &live),
            Err("not homed: HOME first".to_string())
        );
        let mut live = machine(&c, true);
        assert_eq!(allowed(&c, &live), ["START", "HOME"]);
        live.running = true;
        assert_eq!(allowed(&c, &live), ["STOP"]);
    }

    #[test]
    fn a_fault_offers_reset_then_ack_once_its_cause_is_gone() {
        let c = paint();
        let mut live = machine(&c, false);
        live.nodes[2].status = Some(status(&c, 2, false, Some(0x81)));
        let fault = |persists| Alarm {
            source: AlarmSource::Chart {
                chart: 1,
                code: 0x81,
            },
            level: AlarmLevel::Fault,
            raised_ms: 0,
            acked: false,
            persists,
        };
        let report = &mut live.nodes[2].alarms.as_mut().unwrap().0;
        report.alarms.push(fault(true)).unwrap();
        assert_eq!(allowed(&c, &live), ["RESET"]);
        assert_eq!(
            check(Button::Ack, &c, &live),
            Err("every latched alarm's cause persists (RESET first)".to_string())
        );
        // Reset: not faulted any more, the alarm latched until acknowledged.
        live.nodes[2].status = Some(status(&c, 2, false, None));
        live.nodes[2].alarms.as_mut().unwrap().0.alarms[0] = fault(false);
        assert_eq!(allowed(&c, &live), ["ACK"]);
        assert!(check(Button::Home, &c, &live)
            .unwrap_err()
            .starts_with("node 0x0013 (HC) has a fault alarm latched: "));
        // START names the alarm too, then HOME (it said `not homed: HOME first`, and HOME
        // was refused for the alarm).
        let start = check(Button::Start, &c, &live).unwrap_err();
        assert!(
            start.starts_with("node 0x0013 (HC) has a fault alarm latched: ")
                && start.ends_with("(ACK first), then HOME"),
            "{start}"
        );
        // An e-stop alarm whose button is still pressed (the node reset): what ends it.
        live.nodes[2].alarms.as_mut().unwrap().0.alarms[0] = Alarm {
            source: AlarmSource::EStop,
            ..fault(true)
        };
        assert!(check(Button::Home, &c, &live).unwrap_err().ends_with(
            "(its cause persists: the emergency stop is pressed: release it, then ACK)"
        ));
    }

    #[test]
    fn a_silent_node_or_a_lost_medium_offers_nothing() {
        let c = paint();
        let mut live = machine(&c, true);
        live.nodes[1].silent = Some(SystemTime::UNIX_EPOCH);
        assert_eq!(allowed(&c, &live), Vec::<&str>::new());
        assert_eq!(
            check(Button::Start, &c, &live),
            Err("node 0x0012 (GR) does not answer".to_string())
        );
        let mut live = machine(&c, true);
        live.medium_lost = Some("closed".into());
        assert_eq!(
            check(Button::Home, &c, &live),
            Err("no medium: closed".to_string())
        );
    }
}
