//! What the page draws, from the robot file alone: the machine's actuators (one lane
//! each, with its plant times and watchdog), its charts (states and transitions, as the
//! ECC is drawn), the steps of its cycle and its nodes. Sent once as `model.json`.

use robot_compiler::compile::Compiled;
use robot_net::live_plant::{self, Actuator};
use serde::Serialize;

use crate::error::PanelError;

/// The machine, as the page draws it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Machine {
    pub name: String,
    /// The declared cycle, step by step (`VC+`, ...), in sequence order.
    pub sequence: Vec<String>,
    pub actuators: Vec<Lane>,
    pub charts: Vec<Chart>,
    pub nodes: Vec<NodeModel>,
    /// The motion watchdog of every actuator (0: none).
    pub watchdog_ms: u32,
    /// The role whose node takes START (none: no start input).
    pub start_role: Option<String>,
    /// A sorting station's sensors and bins (`sorting:`).
    pub station: Option<Station>,
    /// Each control function (`functions:`): its name and the index of its chart in
    /// `charts` (whose states are its places; the current one holds the token).
    pub functions: Vec<(String, usize)>,
    /// The wiring the live feed reads the pins with (board pins); not sent.
    #[serde(skip)]
    pub wiring: Vec<Actuator>,
    /// Each radio topic: its publisher's address and its number (topics are numbered per
    /// publisher), the publishing role and the event; not sent.
    #[serde(skip)]
    pub topics: Vec<((u16, u8), (String, String))>,
}

/// A sorting station as the page draws it: a light per sensor, the ball at the colour
/// sensors in its colour, each bin with the balls that landed in it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Station {
    pub role: String,
    pub addr: u16,
    /// The colour sensors, in truth-table column order: (name, board pin).
    pub sensors: Vec<(String, u8)>,
    /// Each colour and its sensors' levels.
    pub colours: Vec<(String, Vec<bool>)>,
    pub entry: (String, u8),
    /// The bins' sensors, in bin order (none: the station has none).
    pub bins: Vec<(String, u8)>,
}

impl Station {
    fn of(c: &Compiled) -> Option<Station> {
        let s = c.robot.sorting.as_ref()?;
        let role = c.ir.roles.iter().find(|r| r.name == s.role)?;
        let pin = |n: &String| {
            let i = role.inputs.iter().find(|i| &i.name == n)?;
            Some((n.clone(), i.pin))
        };
        Some(Station {
            role: role.name.clone(),
            addr: role.address,
            sensors: s.sensors.iter().map(pin).collect::<Option<_>>()?,
            colours: (s.table.iter())
                .map(|r| (r.colour.clone(), r.levels.clone()))
                .collect(),
            entry: pin(&s.entry)?,
            bins: s.bins.iter().map(pin).collect::<Option<_>>()?,
        })
    }
}

/// One actuator's lane.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Lane {
    pub name: String,
    pub role: String,
    pub addr: u16,
    /// The plant's full-stroke times, extending and retracting.
    pub out_ms: u64,
    pub back_ms: u64,
    /// Whether limit switches say where it is (otherwise its plant time does).
    pub sensors: bool,
}

/// One chart of one role, as its ECC.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Chart {
    pub role: String,
    pub name: String,
    pub states: Vec<String>,
    /// (from, to, label: the trigger event and guard).
    pub transitions: Vec<(usize, usize, String)>,
    pub initial: usize,
    pub idle: usize,
}

#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct NodeModel {
    pub role: String,
    pub addr: u16,
}

impl Machine {
    /// The page model of the compiled robot `c`.
    pub fn of(c: &Compiled) -> Result<Machine, PanelError> {
        let wiring = live_plant::actuators(c).map_err(|e| PanelError::Robot(e.to_string()))?;
        let role_of = |addr: u16| {
            (c.ir.roles.iter())
                .find(|r| r.address == addr)
                .map_or_else(String::new, |r| r.name.clone())
        };
        let actuators = (wiring.iter())
            .map(|a| Lane {
                name: a.name.clone(),
                role: role_of(a.addr),
                addr: a.addr,
                out_ms: a.travel_ms.0,
                back_ms: a.travel_ms.1,
                sensors: a.home.is_some() || a.end.is_some(),
            })
            .collect();
        let charts: Vec<Chart> = (c.ir.roles.iter())
            .flat_map(|r| {
                r.charts.iter().map(|ch| Chart {
                    role: r.name.clone(),
                    name: ch.name.clone(),
                    states: ch.states.iter().map(|s| s.name.clone()).collect(),
                    transitions: (ch.transitions.iter())
                        .map(|t| {
                            let trigger = t.trigger.and_then(|i| ch.inputs.get(i));
                            let guard = t.guard.as_ref().map(|g| format!("[{}]", g.0));
                            let label = [trigger.cloned(), guard]
                                .into_iter()
                                .flatten()
                                .collect::<Vec<_>>()
                                .join(" ");
                            (t.from, t.to, label)
                        })
                        .collect(),
                    initial: ch.initial,
                    idle: ch.idle,
                })
            })
            .collect();
        let charts_of: Vec<(String, String)> = (charts.iter())
            .map(|ch| (ch.role.clone(), ch.name.clone()))
            .collect();
        Ok(Machine {
            name: c.ir.name.clone(),
            sequence: c.ir.expect.iter().map(|s| s.to_string()).collect(),
            actuators,
            charts,
            nodes: (c.ir.roles.iter())
                .map(|r| NodeModel {
                    role: r.name.clone(),
                    addr: r.address,
                })
                .collect(),
            watchdog_ms: c.robot.motion_timeout_ms,
            start_role: (c.ir.start.as_ref())
                .and_then(|(r, _)| c.ir.roles.get(*r))
                .map(|r| r.name.clone()),
            station: Station::of(c),
            functions: functions(c, &charts_of),
            wiring,
            topics: (robot_compiler::lower::topics(&c.ir).into_iter())
                .filter_map(|(ri, e, topic)| {
                    let r = c.ir.roles.get(ri)?;
                    let event = r.events.get(e).cloned().unwrap_or_default();
                    Some((
                        (r.address, u8::try_from(topic).ok()?),
                        (r.name.clone(), event),
                    ))
                })
                .collect(),
        })
    }
}

/// Each control function and its chart's index among `charts` (role, chart name): the
/// chart of the function's own name (not the `.seen` mirrors on other roles).
fn functions(c: &Compiled, charts: &[(String, String)]) -> Vec<(String, usize)> {
    (c.robot.functions.iter())
        .filter_map(|f| {
            let i = charts.iter().position(|(_, name)| *name == f.name)?;
            Some((f.name.clone(), i))
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn paint() -> Compiled {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../robot-configs/paint-robot.ron"
        );
        let text = std::fs::read_to_string(path).unwrap();
        robot_compiler::compile::compile(&robot_compiler::Source::new("paint-robot.ron", text))
            .unwrap()
    }

    #[test]
    fn the_paint_robot_has_four_lanes_its_sequence_and_every_chart() {
        let c = paint();
        let m = Machine::of(&c).unwrap();
        let lanes: Vec<(&str, &str, u64, u64, bool)> = (m.actuators.iter())
            .map(|l| (&l.name[..], &l.role[..], l.out_ms, l.back_ms, l.sensors))
            .collect();
        assert_eq!(
            lanes,
            [
                ("VC", "VC", 300, 250, true),
                ("GR", "GR", 100, 100, false),
                ("HC", "HC", 800, 800, true),
                ("RC", "RC", 200, 200, true),
            ]
        );
        assert_eq!(
            m.sequence.join(" "),
            "VC+ GR+ VC- HC+ VC+ VC- RC+ RC- HC- VC+ GR- VC-"
        );
        let charts: usize = c.ir.roles.iter().map(|r| r.charts.len()).sum();
        assert_eq!(m.charts.len(), charts);
        assert_eq!((m.watchdog_ms, m.start_role.as_deref()), (2000, Some("VC")));
        assert!(m.charts.iter().all(|ch| ch.states.len() > ch.idle));
    }

    fn robot(name: &str) -> Compiled {
        let path = format!("{}/../robot-configs/{name}", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(path).unwrap();
        robot_compiler::compile::compile(&robot_compiler::Source::new(name, text)).unwrap()
    }

    #[test]
    fn the_sorters_station_has_its_sensors_colours_and_bins() {
        let m = Machine::of(&robot("ball-sorter.ron")).unwrap();
        let s = m.station.unwrap();
        let names = |v: &[(String, u8)]| v.iter().map(|x| x.0.clone()).collect::<Vec<_>>();
        assert_eq!(names(&s.sensors), ["CAP", "IND", "OPT"]);
        assert_eq!(names(&s.bins), ["BIN1", "BIN2", "BIN3"]);
        assert_eq!(s.entry.0, "ENTRY");
        assert_eq!(
            s.colours,
            [
                ("black".to_string(), vec![true, false, false]),
                ("gray".to_string(), vec![true, true, true]),
                ("orange".to_string(), vec![true, false, true]),
            ]
        );
    }

    #[test]
    fn the_sorter_and_the_transport_give_a_page_with_every_chart() {
        for name in ["ball-sorter.ron", "waterjet-transport.ron"] {
            let c = robot(name);
            let m = Machine::of(&c).unwrap();
            let charts: usize = c.ir.roles.iter().map(|r| r.charts.len()).sum();
            assert_eq!(m.charts.len(), charts, "{name}");
            let lanes: Vec<&str> = m.actuators.iter().map(|a| &a.name[..]).collect();
            let want: &[&str] = match name {
                "ball-sorter.ron" => &["PUSHER", "G1", "G2"],
                _ => &[],
            };
            assert_eq!(lanes, want, "{name}");
            assert_eq!(m.station.is_some(), name == "ball-sorter.ron");
            // In the robot's declaration order: each on its own role's chart.
            let mut functions: Vec<String> = (m.functions.iter())
                .map(|(f, i)| format!("{f} {}/{}", m.charts[*i].role, m.charts[*i].name))
                .collect();
            let declared: Vec<&str> = c.robot.functions.iter().map(|f| &f.name[..]).collect();
            let order: Vec<&str> = m.functions.iter().map(|f| &f.0[..]).collect();
            assert_eq!(order, declared, "{name}");
            functions.sort();
            let want: &[&str] = match name {
                "ball-sorter.ron" => &[],
                _ => &[
                    "Belt BELT/Belt",
                    "FaultDetection PUSHER/FaultDetection",
                    "Operation CABINET/Operation",
                    "Pusher PUSHER/Pusher",
                    "Transport CABINET/Transport",
                ],
            };
            assert_eq!(functions, want, "{name}");
        }
    }
}
