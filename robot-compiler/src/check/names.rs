//! Duplicate names: the keys of a map, nodes, roles, actuators (robot-wide: sequences
//! name them), pins of a role, charts of a role, chart types, and the states, variables,
//! inputs, outputs, timers and parameters of a chart type. Role names that are no plain
//! file names.

use std::collections::BTreeMap;

use config_schema::limits::MAX_ROLE_NAME;

use super::duplicate;
use crate::diag::Diagnostic;
use crate::model::Robot;
use crate::source::Source;

fn dups<'a>(
    src: &Source,
    what: &str,
    items: impl Iterator<Item = (&'a str, String)>,
    out: &mut Vec<Diagnostic>,
) {
    let mut seen: BTreeMap<&str, String> = BTreeMap::new();
    for (name, path) in items {
        match seen.get(name) {
            Some(first) => out.push(duplicate(src, what, name, first, &path)),
            None => {
                seen.insert(name, path);
            }
        }
    }
}

/// Whether `name` can name a file in any directory as it is: not empty, letters, digits,
/// `_` and `-` only (no separator, no `..`, no hidden or control character).
pub(crate) fn is_file_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_alphanumeric() || c == '_' || c == '-')
}

pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    for (key, first, second) in src.duplicate_keys() {
        let (line, col) = src.line_col(first.start);
        out.push(
            Diagnostic::error(second, format!("duplicate key `{key}`"))
                .label(format!("first at {line}:{col}")),
        );
    }
    dups(
        src,
        "node name",
        robot
            .nodes
            .iter()
            .enumerate()
            .map(|(i, n)| (n.name.as_str(), format!("nodes[{i}].name"))),
        out,
    );
    dups(
        src,
        "role name",
        robot
            .roles
            .iter()
            .enumerate()
            .map(|(i, r)| (r.name.as_str(), format!("roles[{i}].name"))),
        out,
    );
    for (i, r) in robot.roles.iter().enumerate() {
        if r.name.len() > MAX_ROLE_NAME {
            out.push(Diagnostic::error(
                src.span(&format!("roles[{i}].name")),
                format!(
                    "role name {:?} is {} bytes: at most {MAX_ROLE_NAME} (a node reports it in \
                     its status): shorten it",
                    r.name,
                    r.name.len()
                ),
            ));
        }
        if !is_file_name(&r.name) {
            out.push(Diagnostic::error(
                src.span(&format!("roles[{i}].name")),
                format!(
                    "role name {:?}: letters, digits, `_` and `-` only (it names the role's blob \
                     file, ROLE.bin)",
                    r.name
                ),
            ));
        }
    }
    dups(
        src,
        "actuator name",
        robot.roles.iter().enumerate().flat_map(|(i, r)| {
            r.actuators
                .iter()
                .enumerate()
                .map(move |(a, x)| (x.name.as_str(), format!("roles[{i}].actuators[{a}].name")))
        }),
        out,
    );
    for (i, r) in robot.roles.iter().enumerate() {
        let pins = r
            .actuators
            .iter()
            .enumerate()
            .map(|(a, x)| (x.name.as_str(), format!("roles[{i}].actuators[{a}].name")))
            .chain(
                r.inputs
                    .iter()
                    .enumerate()
                    .map(|(k, x)| (x.name.as_str(), format!("roles[{i}].inputs[{k}].name"))),
            )
            .chain(
                r.outputs
                    .iter()
                    .enumerate()
                    .map(|(k, x)| (x.name.as_str(), format!("roles[{i}].outputs[{k}].name"))),
            );
        // Actuators are checked robot-wide above; here only inputs/outputs against all.
        let mut seen: BTreeMap<&str, String> = BTreeMap::new();
        for (name, path) in pins {
            match seen.get(name) {
                Some(first) if !path.contains(".actuators[") => {
                    out.push(duplicate(src, "pin name", name, first, &path))
                }
                Some(_) => {}
                None => {
                    seen.insert(name, path);
                }
            }
        }
        dups(
            src,
            "chart name",
            r.charts
                .iter()
                .enumerate()
                .map(|(c, x)| (x.name.as_str(), format!("roles[{i}].charts[{c}].name"))),
            out,
        );
    }
    dups(
        src,
        "chart type",
        robot.chart_types.iter().enumerate().map(|(i, t)| {
            // An imported type is where its `fb_types` entry is.
            let at = t.imported.clone();
            (
                t.name.as_str(),
                at.unwrap_or(format!("chart_types[{i}].name")),
            )
        }),
        out,
    );
    for (i, t) in robot.chart_types.iter().enumerate() {
        let p = format!("chart_types[{i}]");
        dups(
            src,
            "state",
            t.states
                .iter()
                .enumerate()
                .map(|(k, s)| (s.name.as_str(), format!("{p}.states[{k}].name"))),
            out,
        );
        dups(
            src,
            "variable",
            t.vars
                .iter()
                .enumerate()
                .map(|(k, s)| (s.name.as_str(), format!("{p}.vars[{k}].name"))),
            out,
        );
        dups(
            src,
            "event",
            t.inputs
                .iter()
                .enumerate()
                .map(|(k, s)| (s.as_str(), format!("{p}.inputs[{k}]")))
                .chain(
                    t.timers
                        .iter()
                        .enumerate()
                        .map(|(k, s)| (s.as_str(), format!("{p}.timers[{k}]"))),
                ),
            out,
        );
        dups(
            src,
            "output event",
            t.outputs
                .iter()
                .enumerate()
                .map(|(k, s)| (s.as_str(), format!("{p}.outputs[{k}]"))),
            out,
        );
        dups(
            src,
            "parameter",
            t.params
                .iter()
                .enumerate()
                .map(|(k, s)| (s.as_str(), format!("{p}.params[{k}]"))),
            out,
        );
    }
}
