//! A sorting station's sensing side (docs/selecting-automata.md, "The station"): the
//! colour sensors' truth table as data, its checks, and its compilation into one
//! classification chart on the sensing role.
//!
//! The chart (default name `part`) waits in `WAIT`; on its input `SAMPLE` it reads the
//! sensors' levels and raises the colour's event `part.COLOUR`, then `part.ball`; all
//! sensors low is no ball (`part.empty`); a combination no row gives faults the node
//! (fault [`UNKNOWN_FAULT`]): a dirty or broken sensor stops the station. The automata
//! read the colour events (`parts: "ROLE/part"`).

use std::collections::BTreeMap;

use serde::Deserialize;

use crate::diag::Diagnostic;
use crate::ir::Ir;
use crate::model::{ActionDecl, ChartInstance, ChartType, Robot, StateDecl, TransitionDecl};
use crate::source::Source;

/// The default name of the classification chart.
pub const DEFAULT_CHART: &str = "part";
/// The fault code of a sensor combination that is no colour.
pub const UNKNOWN_FAULT: u8 = 3;
/// The chart's events besides the colours.
pub const BALL: &str = "ball";
pub const EMPTY: &str = "empty";

/// The station as written (`sorting:` of a robot).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sorting {
    /// The role whose node reads the colour sensors and feeds the balls.
    pub role: String,
    /// The inputs of that role the truth table reads, in column order.
    pub sensors: Vec<String>,
    /// Each colour's sensor levels, one per sensor.
    pub table: Vec<Row>,
    /// The event that makes the chart read the sensors (`EVENT` of the role, e.g.
    /// `feed.sample`).
    pub sample: String,
    /// The classification chart's name (default `part`).
    #[serde(default)]
    pub chart: Option<String>,
    /// For `sim`: the balls in the magazine, front first, as colours.
    #[serde(default)]
    pub feed: Vec<String>,
    /// The pusher (an actuator of the role): its `+` pushes the front ball into the shaft.
    pub pusher: String,
    /// The input of the role that confirms a ball entered the shaft.
    pub entry: String,
    /// The gates, `ROLE/ACTUATOR`, in shaft order: a ball meets gate i (bin i + 1) first;
    /// one that no gate takes falls to the last bin.
    pub gates: Vec<String>,
    /// The bins' sensors, inputs of the role, one per bin (`gates` + 1, in bin order): a
    /// ball landing pulses its bin's. None: the station has no bin sensors.
    #[serde(default)]
    pub bins: Vec<String>,
    /// Plant times for `sim`: pusher at its end -> entry sensor.
    #[serde(default = "default_drop")]
    pub drop_ms: u32,
    /// Entry sensor -> the first gate, and from one gate to the next.
    #[serde(default = "default_fall")]
    pub fall_ms: u32,
    /// Pusher back home -> the next ball lies at the sensors.
    #[serde(default = "default_roll")]
    pub roll_ms: u32,
}

/// One row of the truth table.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Row {
    pub colour: String,
    pub levels: Vec<bool>,
}

fn default_drop() -> u32 {
    30
}
fn default_fall() -> u32 {
    40
}
fn default_roll() -> u32 {
    50
}

impl Sorting {
    /// The classification chart's name.
    pub fn chart_name(&self) -> &str {
        self.chart.as_deref().unwrap_or(DEFAULT_CHART)
    }

    /// The sensor levels of `colour` (its first row).
    pub fn levels(&self, colour: &str) -> Option<&[bool]> {
        self.table
            .iter()
            .find(|r| r.colour == colour)
            .map(|r| r.levels.as_slice())
    }

    /// The events the classification chart raises on its role.
    pub fn events(&self) -> Vec<String> {
        let chart = self.chart_name();
        self.table
            .iter()
            .map(|r| r.colour.as_str())
            .chain([BALL, EMPTY])
            .map(|o| format!("{chart}.{o}"))
            .collect()
    }

    /// The classification chart as a chart type: one state per row, guards over the
    /// sensors.
    pub fn chart_type(&self) -> ChartType {
        let mut states = vec![
            state("WAIT", vec![]),
            state("CHECK", vec![]),
            state("EMPTY", vec![ActionDecl::Emit(EMPTY.into())]),
            state("UNKNOWN", vec![ActionDecl::Fault(UNKNOWN_FAULT)]),
        ];
        let mut transitions = vec![TransitionDecl {
            from: "WAIT".into(),
            to: "CHECK".into(),
            on: Some("SAMPLE".into()),
            when: None,
        }];
        let back = |from: &str| TransitionDecl {
            from: from.into(),
            to: "WAIT".into(),
            on: None,
            when: None,
        };
        let all_low: Vec<String> = self.sensors.iter().map(|s| format!("!{s}")).collect();
        transitions.push(TransitionDecl {
            from: "CHECK".into(),
            to: "EMPTY".into(),
            on: None,
            when: Some(all_low.join(" && ")),
        });
        let mut outputs = Vec::new();
        for r in &self.table {
            let name = format!("C_{}", r.colour);
            states.push(state(
                &name,
                vec![
                    ActionDecl::Emit(r.colour.clone()),
                    ActionDecl::Emit(BALL.into()),
                ],
            ));
            let guard: Vec<String> = self
                .sensors
                .iter()
                .zip(&r.levels)
                .map(|(s, &l)| if l { s.clone() } else { format!("!{s}") })
                .collect();
            transitions.push(TransitionDecl {
                from: "CHECK".into(),
                to: name.clone(),
                on: None,
                when: Some(guard.join(" && ")),
            });
            transitions.push(back(&name));
            outputs.push(r.colour.clone());
        }
        transitions.push(TransitionDecl {
            from: "CHECK".into(),
            to: "UNKNOWN".into(),
            on: None,
            when: None,
        });
        transitions.push(back("EMPTY"));
        outputs.extend([BALL.to_string(), EMPTY.to_string()]);
        ChartType {
            name: String::from("Classify"),
            params: vec![],
            inputs: vec![String::from("SAMPLE")],
            outputs,
            vars: vec![],
            timers: vec![],
            states,
            transitions,
            idle: None,
            rests: Vec::new(),
            imported: None,
            written: None,
            specializes: None,
        }
    }
}

fn state(name: &str, actions: Vec<ActionDecl>) -> StateDecl {
    StateDecl {
        name: name.into(),
        actions,
    }
}

/// `check`: the table and the station's names, each error at its place.
pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    let Some(s) = &robot.sorting else { return };
    let Some((_, role)) = robot.role(&s.role) else {
        out.push(
            Diagnostic::error(
                src.span("sorting.role"),
                format!("unknown role `{}`", s.role),
            )
            .label("no role has this name"),
        );
        return;
    };
    let is_input = |n: &str| role.inputs.iter().any(|i| i.name == n);
    for (i, n) in s.sensors.iter().enumerate() {
        if !is_input(n) {
            out.push(Diagnostic::error(
                src.span(&format!("sorting.sensors[{i}]")),
                format!("`{n}` is not an input of role `{}`", s.role),
            ));
        }
    }
    if !is_input(&s.entry) {
        out.push(Diagnostic::error(
            src.span("sorting.entry"),
            format!("`{}` is not an input of role `{}`", s.entry, s.role),
        ));
    }
    for (i, n) in s.bins.iter().enumerate() {
        if !is_input(n) {
            out.push(Diagnostic::error(
                src.span(&format!("sorting.bins[{i}]")),
                format!("`{n}` is not an input of role `{}`", s.role),
            ));
        }
    }
    if !s.bins.is_empty() && s.bins.len() != s.gates.len() + 1 {
        out.push(
            Diagnostic::error(
                src.span("sorting.bins"),
                format!(
                    "{} bin sensor(s) for {} bins ({} gates and the bottom bin)",
                    s.bins.len(),
                    s.gates.len() + 1,
                    s.gates.len()
                ),
            )
            .help("name one sensor per bin, in bin order, the bottom bin last"),
        );
    }
    if !role.actuators.iter().any(|a| a.name == s.pusher) {
        out.push(Diagnostic::error(
            src.span("sorting.pusher"),
            format!("`{}` is not an actuator of role `{}`", s.pusher, s.role),
        ));
    }
    for (i, g) in s.gates.iter().enumerate() {
        let ok = g.split_once('/').is_some_and(|(r, a)| {
            robot
                .role(r)
                .is_some_and(|(_, r)| r.actuators.iter().any(|x| x.name == a))
        });
        if !ok {
            out.push(
                Diagnostic::error(
                    src.span(&format!("sorting.gates[{i}]")),
                    format!("`{g}` is not an actuator of a role"),
                )
                .help("write a gate as `ROLE/ACTUATOR`"),
            );
        }
    }
    let chart = s.chart_name();
    if role.charts.iter().any(|c| c.name == chart) {
        out.push(Diagnostic::error(
            src.span("sorting.chart"),
            format!(
                "the classification chart `{chart}` clashes with a chart of role `{}`",
                s.role
            ),
        ));
    }
    check_table(robot, s, src, out);
}

fn check_table(robot: &Robot, s: &Sorting, src: &Source, out: &mut Vec<Diagnostic>) {
    let mut seen: BTreeMap<&[bool], &str> = BTreeMap::new();
    for (i, r) in s.table.iter().enumerate() {
        let at = format!("sorting.table[{i}]");
        if !robot.colours.contains(&r.colour) || [BALL, EMPTY].contains(&r.colour.as_str()) {
            out.push(
                Diagnostic::error(
                    src.span(&format!("{at}.colour")),
                    format!(
                        "this sensor combination is no colour: `{}` is not one of the robot's `colours`",
                        r.colour
                    ),
                )
                .help(format!("colours: {}", robot.colours.join(", "))),
            );
        }
        if r.levels.len() != s.sensors.len() {
            out.push(Diagnostic::error(
                src.span(&format!("{at}.levels")),
                format!(
                    "{} levels for {} sensors ({})",
                    r.levels.len(),
                    s.sensors.len(),
                    s.sensors.join(", ")
                ),
            ));
            continue;
        }
        if r.levels.iter().all(|l| !l) {
            out.push(Diagnostic::error(
                src.span(&format!("{at}.levels")),
                format!(
                    "`{}` with every sensor low cannot be told from no ball",
                    r.colour
                ),
            ));
        }
        if let Some(other) = seen.insert(&r.levels, &r.colour) {
            out.push(Diagnostic::error(
                src.span(&format!("{at}.levels")),
                format!(
                    "`{}` has the sensor combination of `{other}`: the sensors cannot tell them apart",
                    r.colour
                ),
            ));
        }
    }
    for (i, f) in s.feed.iter().enumerate() {
        if s.levels(f).is_none() {
            out.push(Diagnostic::error(
                src.span(&format!("sorting.feed[{i}]")),
                format!("no sensor combination gives `{f}`"),
            ));
        }
    }
    let loaded = crate::automata::load(robot, src);
    for l in &loaded.automata {
        let a = &l.automaton;
        for (t, p) in a.transitions.iter().zip(&l.places.transitions) {
            let colour = a.colour_name(t.colour);
            if s.levels(colour).is_none() {
                out.push(p.whole.error(format!(
                        "automaton `{}` selects `{colour}` (transition `{}`), but no sensor combination of `sorting.table` gives it",
                    a.name, t.id
                )));
            }
        }
    }
}

/// Joins the classification chart to the sensing role's IR.
pub fn place(robot: &Robot, src: &Source, ir: &mut Ir) -> Result<(), Vec<Diagnostic>> {
    let Some(s) = &robot.sorting else {
        return Ok(());
    };
    let (Some((_, role)), Some(r)) = (
        robot.role(&s.role),
        ir.roles.iter_mut().find(|r| r.name == s.role),
    ) else {
        return Ok(()); // `check` reported it
    };
    let t = s.chart_type();
    let c = ChartInstance {
        name: s.chart_name().to_string(),
        type_: t.name.clone(),
        params: BTreeMap::new(),
        on: BTreeMap::new(),
        timers: BTreeMap::new(),
        more: BTreeMap::new(),
        reads: BTreeMap::new(),
        declared: None,
    };
    let chart = crate::elab::instantiate(
        src,
        "sorting",
        role,
        &c,
        &t,
        &BTreeMap::new(),
        &BTreeMap::new(),
        r,
        "sorting",
    )?;
    let ci = r.charts.len();
    r.charts.push(chart);
    let (sr, e) = crate::elab::split_source(&s.sample, &s.role);
    if sr != s.role {
        return Err(vec![Diagnostic::error(
            src.span("sorting.sample"),
            format!("`{}` is not an event of role `{}`", s.sample, s.role),
        )]);
    }
    r.event(e);
    r.routes.push((e.to_string(), ci, 0));
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::Source;

    const SORTER: &str = include_str!("../../robot-configs/ball-sorter.ron");

    /// Every error of `text` as `line:col message`.
    fn errors(text: &str) -> Vec<String> {
        let src = Source::new("ball-sorter.ron", text);
        match crate::compile(&src) {
            Ok(_) => Vec::new(),
            Err(d) => d
                .iter()
                .filter(|d| d.is_error())
                .map(|d| {
                    let (l, c) = src.line_col(d.span.start);
                    format!("{l}:{c} {}", d.message)
                })
                .collect(),
        }
    }

    fn edit(from: &str, to: &str) -> String {
        assert!(SORTER.contains(from), "{from}");
        SORTER.replacen(from, to, 1)
    }

    #[test]
    fn the_station_compiles_its_table_into_a_classification_chart() {
        let src = Source::new("ball-sorter.ron", SORTER);
        let c = crate::compile(&src).expect("compiles");
        let sensing = &c.ir.roles[0];
        let names: Vec<&str> = sensing.charts.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["feed", "bins", "part"]);
        let states: Vec<&str> = sensing.charts[2]
            .states
            .iter()
            .map(|s| s.name.as_str())
            .collect();
        assert_eq!(
            states,
            ["WAIT", "CHECK", "EMPTY", "UNKNOWN", "C_black", "C_gray", "C_orange"]
        );
        // Each gate: its automaton's charts after the gate's own.
        assert_eq!(c.ir.roles[1].charts.len(), 1 + 5);
        assert_eq!(c.ir.roles[2].charts.len(), 1 + 4);
    }

    #[test]
    fn a_combination_that_is_no_colour_is_an_error_at_its_row() {
        let text = edit(r#"(colour: "gray", levels"#, r#"(colour: "grey", levels"#);
        assert_eq!(
            errors(&text),
            [
                "114:22 this sensor combination is no colour: `grey` is not one of the robot's `colours`",
                "123:16 no sensor combination gives `gray`",
                "123:61 no sensor combination gives `gray`",
                "124:26 no sensor combination gives `gray`",
                "124:53 no sensor combination gives `gray`",
                "142:17 automaton `nd` selects `gray` (transition `t5`), but no sensor combination of `sorting.table` gives it",
                "155:17 automaton `fig1` selects `gray` (transition `t3`), but no sensor combination of `sorting.table` gives it",
            ]
        );
    }

    #[test]
    fn combinations_the_sensors_cannot_tell_apart_are_errors() {
        let text = edit("[true, true, true]", "[true, false, false]");
        assert_eq!(
            errors(&text)[0],
            "114:38 `gray` has the sensor combination of `black`: the sensors cannot tell them apart"
        );
        let text = edit("[true, true, true]", "[false, false, false]");
        assert_eq!(
            errors(&text)[0],
            "114:38 `gray` with every sensor low cannot be told from no ball"
        );
        let text = edit("[true, true, true]", "[true, true]");
        assert_eq!(
            errors(&text)[0],
            "114:38 2 levels for 3 sensors (CAP, IND, OPT)"
        );
    }

    #[test]
    fn the_stations_names_are_checked_at_their_place() {
        let text = edit(
            r#"sensors: ["CAP", "IND", "OPT"]"#,
            r#"sensors: ["CAP", "IND", "OPTO"]"#,
        );
        assert_eq!(
            errors(&text),
            ["110:33 `OPTO` is not an input of role `SENSING`"]
        );
        let text = edit(r#"gates: ["GATE1/G1", "#, r#"gates: ["GATE1/G3", "#);
        assert_eq!(
            errors(&text),
            ["120:17 `GATE1/G3` is not an actuator of a role"]
        );
        let text = edit(r#"out: "gate.TOOK","#, r#"out: "gate.TAKEN","#);
        assert_eq!(
            errors(&text),
            ["146:18 automaton `nd`: `gate.TAKEN` is not an input of a chart of role `GATE1`"]
        );
    }

    #[test]
    fn the_bin_sensors_are_inputs_of_the_role_one_per_bin() {
        let text = edit(
            r#"bins: ["BIN1", "BIN2", "BIN3"]"#,
            r#"bins: ["BIN1", "BIN4", "BIN3"]"#,
        );
        assert_eq!(
            errors(&text),
            ["121:24 `BIN4` is not an input of role `SENSING`"]
        );
        let text = edit(
            r#"bins: ["BIN1", "BIN2", "BIN3"]"#,
            r#"bins: ["BIN1", "BIN2"]"#,
        );
        assert_eq!(
            errors(&text),
            ["121:15 2 bin sensor(s) for 3 bins (2 gates and the bottom bin)"]
        );
    }
}
