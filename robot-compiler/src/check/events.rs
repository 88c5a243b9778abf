//! Event flow of explicit charts: a connection to a chart output that no state emits
//! (error: subscribed, nobody publishes), a chart output that is emitted but connected to
//! nothing (warning: published, nobody uses), a chart input connected to nothing (warning).

use crate::diag::Diagnostic;
use crate::elab::split_source;
use crate::ir::Ir;
use crate::model::{ActionDecl, ChartType, Robot};
use crate::source::Source;

fn emits(t: &ChartType, output: &str) -> bool {
    t.states
        .iter()
        .flat_map(|s| s.actions.iter())
        .any(|a| matches!(a, ActionDecl::Emit(o) if o == output))
}

pub fn check(robot: &Robot, _ir: &Ir, src: &Source, out: &mut Vec<Diagnostic>) {
    // Every (role, event) some connection listens to.
    let mut listened: Vec<(String, String)> = Vec::new();
    for (ri, role) in robot.roles.iter().enumerate() {
        for (ci, c) in role.charts.iter().enumerate() {
            for (key, source) in c.sources() {
                let (r, e) = split_source(source, &role.name);
                listened.push((r.to_string(), e.to_string()));
                let Some((_, rr)) = robot.role(r) else {
                    continue;
                };
                let Some((chart, output)) = e.split_once('.') else {
                    continue;
                };
                let Some(inst) = rr.charts.iter().find(|x| x.name == chart) else {
                    continue;
                };
                let Some((_, t)) = robot.chart_type(&inst.type_) else {
                    continue;
                };
                if t.outputs.iter().any(|o| o == output) && !emits(t, output) {
                    out.push(
                        Diagnostic::error(
                            src.span(&format!("roles[{ri}].charts[{ci}].on.{key}")),
                            format!(
                                "`{source}` is subscribed here but nobody publishes it: no state of chart `{chart}` emits `{output}`"
                            ),
                        )
                        .label("never raised")
                        .of_chart(src, c, Some(key)),
                    );
                }
            }
        }
    }
    // A sorting station's classification chart listens to its `sample`.
    if let Some(s) = &robot.sorting {
        listened.push((s.role.clone(), s.sample.clone()));
    }
    if let Ok(Some((r, name))) = crate::elab::start_input(robot) {
        listened.push((robot.roles[r].name.clone(), name));
    }
    for (ri, role) in robot.roles.iter().enumerate() {
        for (ci, c) in role.charts.iter().enumerate() {
            let Some((_, t)) = robot.chart_type(&c.type_) else {
                continue;
            };
            let here = src.span(&format!("roles[{ri}].charts[{ci}].name"));
            for o in &t.outputs {
                let event = format!("{}.{o}", c.name);
                if emits(t, o) && !listened.contains(&(role.name.clone(), event.clone())) {
                    out.push(
                        Diagnostic::warning(
                            here.clone(),
                            format!("chart `{}` publishes `{o}` but nobody uses it", c.name),
                        )
                        .help(format!(
                            "connect `{}/{event}` to a chart input, or stop emitting it",
                            role.name
                        ))
                        .of_chart(src, c, None),
                    );
                }
            }
            // An automaton's `out` wires a chart input to its transitions' Outs.
            let took = |i: &str| {
                robot.automata.iter().any(|a| {
                    a.role.as_deref() == Some(role.name.as_str())
                        && a.out.as_deref() == Some(format!("{}.{i}", c.name).as_str())
                })
            };
            for i in &t.inputs {
                if !c.on.contains_key(i) && !took(i) {
                    out.push(
                        Diagnostic::warning(
                            here.clone(),
                            format!("input `{i}` of chart `{}` is connected to no event", c.name),
                        )
                        .of_chart(src, c, None),
                    );
                }
            }
        }
    }
}
