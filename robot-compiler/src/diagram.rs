//! `diagram`: a role's charts as Graphviz DOT: one cluster per chart, a node per state
//! (its actions listed under the name; a double border marks the initial state, bold the
//! idle one), edges labelled `EVENT [guard]`.

use std::fmt::Write;
use std::io::Write as _;
use std::process::{Command, Stdio};

use crate::dump::level_text;
use crate::ir::Ir;

/// Why a diagram could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum DiagramError {
    #[error("unknown role `{role}` (roles: {})", roles.join(", "))]
    UnknownRole { role: String, roles: Vec<String> },
    /// Graphviz `dot` could not be started.
    #[error(
        "cannot run Graphviz `dot` ({0}): install graphviz, or use `--format dot` and render it elsewhere"
    )]
    NoGraphviz(#[source] std::io::Error),
    #[error("no stdin for dot")]
    NoStdin,
    /// Writing to or waiting for `dot` failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// `dot` failed: its standard error.
    #[error("dot failed: {0}")]
    Failed(String),
    #[error(transparent)]
    NotUtf8(#[from] std::string::FromUtf8Error),
}

fn esc(s: &str) -> String {
    s.replace('\\', "\\\\").replace('"', "\\\"")
}

/// The DOT text of role `role`'s charts.
pub fn dot(ir: &Ir, role: &str) -> Result<String, DiagramError> {
    let r = ir
        .roles
        .iter()
        .find(|r| r.name == role)
        .ok_or_else(|| DiagramError::UnknownRole {
            role: role.to_string(),
            roles: ir.roles.iter().map(|r| r.name.clone()).collect(),
        })?;
    let mut o = String::new();
    let _ = writeln!(o, "digraph \"{}\" {{", esc(&r.name));
    let _ = writeln!(o, "  rankdir=LR;");
    let _ = writeln!(
        o,
        "  node [shape=box, style=rounded, fontname=\"Helvetica\"];"
    );
    let _ = writeln!(o, "  edge [fontname=\"Helvetica\", fontsize=10];");
    if !r.outputs.is_empty() {
        // What the node drives outside the charts: on fault, at start, by homing.
        let mut label = String::from("outputs: fault / start / home\\l");
        for x in &r.outputs {
            label.push_str(&esc(&format!(
                "  {} (pin {}): {} / {} / {}",
                x.name,
                x.pin,
                level_text(x.fault),
                level_text(x.start),
                u8::from(x.home)
            )));
            label.push_str("\\l");
        }
        let _ = writeln!(o, "  outputs [shape=note, label=\"{label}\"];");
    }
    for (ci, c) in r.charts.iter().enumerate() {
        let _ = writeln!(o, "  subgraph cluster_{ci} {{");
        let _ = writeln!(o, "    label=\"{}\";", esc(&c.name));
        for (si, s) in c.states.iter().enumerate() {
            let mut label = esc(&s.name);
            for a in &s.actions {
                label.push_str("\\l  ");
                label.push_str(&esc(&r.action_text(a)));
            }
            if !s.actions.is_empty() {
                label.push_str("\\l");
            }
            // Double border: where the chart starts; bold: where it rests between cycles.
            let extra = match (si == c.initial, si == c.idle) {
                (true, true) => ", peripheries=2, style=bold",
                (true, false) => ", peripheries=2",
                (false, true) => ", style=bold",
                (false, false) => "",
            };
            let _ = writeln!(o, "    c{ci}s{si} [label=\"{label}\"{extra}];");
        }
        for t in &c.transitions {
            let mut label = t
                .trigger
                .and_then(|i| c.inputs.get(i))
                .cloned()
                .unwrap_or_default();
            if let Some((text, _)) = &t.guard {
                if !label.is_empty() {
                    label.push(' ');
                }
                label.push_str(&format!("[{text}]"));
            }
            let _ = writeln!(
                o,
                "    c{ci}s{} -> c{ci}s{} [label=\"{}\"];",
                t.from,
                t.to,
                esc(&label)
            );
        }
        let _ = writeln!(o, "  }}");
    }
    let _ = writeln!(o, "}}");
    Ok(o)
}

/// Renders DOT to SVG through Graphviz `dot`.
pub fn svg(dot: &str) -> Result<String, DiagramError> {
    let mut child = Command::new("dot")
        .arg("-Tsvg")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(DiagramError::NoGraphviz)?;
    child
        .stdin
        .take()
        .ok_or(DiagramError::NoStdin)?
        .write_all(dot.as_bytes())?;
    let out = child.wait_with_output()?;
    if !out.status.success() {
        return Err(DiagramError::Failed(
            String::from_utf8_lossy(&out.stderr).into_owned(),
        ));
    }
    Ok(String::from_utf8(out.stdout)?)
}
