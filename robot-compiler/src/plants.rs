//! Plant models the robot file declares for `sim` beyond its actuators (a motor with a
//! continuous position, what it moves, maintained contacts, buttons), wired to a role's
//! inputs and outputs by name, and the `check` pass over them. The tables never see them:
//! they only say what `node_fw::sim` attaches to the nodes' pins.

use serde::Deserialize;

use crate::diag::Diagnostic;
use crate::model::Robot;
use crate::source::Source;

/// One plant model, on the pins of one role.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum PlantDecl {
    /// A motor on two outputs (clockwise toward the end, counter-clockwise home) moving a
    /// carriage over `stroke_mm` at `speed_mm_s`, with optional sensors at home and end.
    Motor {
        name: String,
        role: String,
        cw: String,
        ccw: String,
        #[serde(default)]
        home: Option<String>,
        #[serde(default)]
        end: Option<String>,
        stroke_mm: u32,
        speed_mm_s: u32,
    },
    /// What motor `motor` moves with it (always at its position), with its own sensors on
    /// its own role.
    Driven {
        name: String,
        role: String,
        motor: String,
        #[serde(default)]
        home: Option<String>,
        #[serde(default)]
        end: Option<String>,
    },
    /// A maintained contact on an input (a fault contact): it keeps the level it is set to.
    Switch {
        name: String,
        role: String,
        input: String,
    },
    /// A push button on an input (a 50 ms press).
    Button {
        name: String,
        role: String,
        input: String,
    },
}

impl PlantDecl {
    pub fn name(&self) -> &str {
        match self {
            PlantDecl::Motor { name, .. }
            | PlantDecl::Driven { name, .. }
            | PlantDecl::Switch { name, .. }
            | PlantDecl::Button { name, .. } => name,
        }
    }

    pub fn role(&self) -> &str {
        match self {
            PlantDecl::Motor { role, .. }
            | PlantDecl::Driven { role, .. }
            | PlantDecl::Switch { role, .. }
            | PlantDecl::Button { role, .. } => role,
        }
    }

    /// Its pins: (RON field, pin name, an output).
    pub fn pins(&self) -> Vec<(&'static str, &str, bool)> {
        fn opt<'a>(
            f: &'static str,
            p: &'a Option<String>,
        ) -> Option<(&'static str, &'a str, bool)> {
            p.as_deref().map(|p| (f, p, false))
        }
        match self {
            PlantDecl::Motor {
                cw, ccw, home, end, ..
            } => [("cw", cw.as_str(), true), ("ccw", ccw.as_str(), true)]
                .into_iter()
                .chain(opt("home", home))
                .chain(opt("end", end))
                .collect(),
            PlantDecl::Driven { home, end, .. } => opt("home", home)
                .into_iter()
                .chain(opt("end", end))
                .collect(),
            PlantDecl::Switch { input, .. } | PlantDecl::Button { input, .. } => {
                vec![("input", input.as_str(), false)]
            }
        }
    }
}

/// The structural pass: each plant's role exists and has the pins it names (inputs,
/// outputs), names are unique, a driven plant names a motor, a motor moves.
pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    for (k, p) in robot.plants.iter().enumerate() {
        let at = |field: &str| src.span(&format!("plants[{k}].{field}"));
        if robot.plants[..k].iter().any(|q| q.name() == p.name()) {
            out.push(
                Diagnostic::error(
                    at("name"),
                    format!("plant `{}` is declared twice", p.name()),
                )
                .label("second declaration"),
            );
        }
        let Some(role) = robot.roles.iter().find(|r| r.name == p.role()) else {
            out.push(
                Diagnostic::error(
                    at("role"),
                    format!("plant `{}`: no role `{}`", p.name(), p.role()),
                )
                .label("unknown role"),
            );
            continue;
        };
        for (field, pin, output) in p.pins() {
            let known = if output {
                role.outputs.iter().any(|o| o.name == pin)
            } else {
                role.inputs.iter().any(|i| i.name == pin)
            };
            if !known {
                let kind = if output { "output" } else { "input" };
                out.push(
                    Diagnostic::error(
                        at(field),
                        format!(
                            "plant `{}`: role `{}` has no {kind} `{pin}`",
                            p.name(),
                            role.name
                        ),
                    )
                    .label(format!("not an {kind} of the role")),
                );
            }
        }
        match p {
            PlantDecl::Driven { motor, .. }
                if !robot
                    .plants
                    .iter()
                    .any(|q| matches!(q, PlantDecl::Motor { name, .. } if name == motor)) =>
            {
                out.push(
                    Diagnostic::error(
                        at("motor"),
                        format!("plant `{}`: no motor plant `{motor}`", p.name()),
                    )
                    .label("not a motor"),
                );
            }
            PlantDecl::Motor {
                stroke_mm,
                speed_mm_s,
                ..
            } => {
                for (field, v) in [("stroke_mm", stroke_mm), ("speed_mm_s", speed_mm_s)] {
                    if *v == 0 {
                        out.push(
                            Diagnostic::error(
                                at(field),
                                format!("plant `{}`: `{field}` must be at least 1", p.name()),
                            )
                            .label("0"),
                        );
                    }
                }
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::source::Source;

    const ROBOT: &str = r#"Robot(
    name: "m",
    network: (pan_id: 1, channel: 11),
    nodes: [(name: "n1", address: 1)],
    assign: [("R", "n1")],
    roles: [(name: "R", inputs: [(name: "HOME", pin: 0), (name: "F", pin: 1)],
             outputs: [(name: "CW", pin: 8), (name: "CCW", pin: 9)])],
    plants: [
        Motor(name: "M", role: "R", cw: "CW", ccw: "CCWX", home: "HOME", stroke_mm: 0, speed_mm_s: 5),
        Driven(name: "B", role: "R", motor: "N"),
        Switch(name: "F", role: "Q", input: "F"),
        Button(name: "M", role: "R", input: "F"),
    ],
)"#;

    /// Every error names its place in the file.
    #[test]
    fn bad_plants_are_reported_at_their_place() {
        let src = Source::new("m.ron", ROBOT);
        let robot = crate::model::parse(&src).expect("parses");
        let mut out = Vec::new();
        super::check(&robot, &src, &mut out);
        let got: Vec<(String, (usize, usize))> = out
            .iter()
            .map(|d| (d.message.clone(), src.line_col(d.span.start)))
            .collect();
        let want = [
            ("plant `M`: role `R` has no output `CCWX`", (9, 52)),
            ("plant `M`: `stroke_mm` must be at least 1", (9, 85)),
            ("plant `B`: no motor plant `N`", (10, 45)),
            ("plant `F`: no role `Q`", (11, 33)),
            ("plant `M` is declared twice", (12, 22)),
        ];
        let want: Vec<(String, (usize, usize))> =
            want.iter().map(|(m, at)| (m.to_string(), *at)).collect();
        assert_eq!(got, want);
    }
}
