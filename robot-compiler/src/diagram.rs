//! `diagram`: a role's charts as Graphviz DOT: one cluster per chart, a node per state
//! (its actions listed under the name; a double border marks the initial state, bold the
//! idle one), edges labelled `EVENT [guard]`. The charts of a selecting automaton placed
//! on the role are drawn as its FB network instead (one box per instance with its
//! parameters, set and reset arcs, the colour events and the outputs), and the ECC of the
//! FB type once ([`dot_with_automata`]).

use std::fmt::Write;
use std::io::Write as _;
use std::process::{Command, Stdio};

use crate::automata::{compile, Automaton};
use crate::dump::level_text;
use crate::ir::Ir;
use crate::model::{ActionDecl, ChartType};

/// Why a diagram could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum DiagramError {
    #[error(transparent)]
    UnknownRole(#[from] crate::ir::UnknownRole),
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
    dot_with_automata(ir, &[], role)
}

/// [`dot`], with the automata of the robot (those placed on `role` are drawn as FB
/// networks, see [`crate::automata::compile::placed`]).
pub fn dot_with_automata(
    ir: &Ir,
    automata: &[Automaton],
    role: &str,
) -> Result<String, DiagramError> {
    let r = ir.role(role)?;
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
    let mut networks = Vec::new();
    for a in automata {
        let net = compile::network(a);
        if net
            .instances
            .iter()
            .all(|i| r.charts.iter().any(|c| c.name == i.chart))
        {
            networks.push((a, net));
        }
    }
    let generated = |name: &str| {
        networks
            .iter()
            .any(|(_, n)| n.instances.iter().any(|i| i.chart == name))
    };
    for (k, (a, net)) in networks.iter().enumerate() {
        network_dot(&mut o, k, a, net);
    }
    if !networks.is_empty() {
        if let Ok(t) = compile::fb_type() {
            type_dot(&mut o, &t);
        }
    }
    for (ci, c) in r.charts.iter().enumerate() {
        if generated(&c.name) {
            continue;
        }
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
            let rests = si == c.idle || c.rests.contains(&si);
            let extra = match (si == c.initial, rests) {
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

/// One automaton's FB network: a box per instance (C, T, R, M, EOS), solid set arcs,
/// dashed reset arcs, the colour events into WP, Out and EOS out.
fn network_dot(o: &mut String, k: usize, a: &Automaton, net: &compile::Network) {
    let _ = writeln!(o, "  subgraph cluster_net{k} {{");
    let _ = writeln!(
        o,
        "    label=\"automaton {} (FB network of SelectingTransition)\";",
        esc(&a.name)
    );
    for i in &net.instances {
        let t = a.get(i.transition);
        let arrow = t.map_or(String::new(), |t| {
            format!("{} -> {}", a.state_name(t.from), a.state_name(t.to))
        });
        let colour = esc(t.map_or("?", |t| a.colour_name(t.colour)));
        let eos = if i.is_final { "\\lEOS" } else { "" };
        let _ = writeln!(
            o,
            "    n{k}t{} [shape=box, style=\"\", label=\"{}\\l{}\\lC={colour} T={} R={} M={}{eos}\\l\"];",
            i.transition.0,
            esc(&i.chart),
            esc(&arrow),
            u8::from(i.t),
            u8::from(i.r),
            i.m
        );
    }
    for c in &net.connections {
        let style = match c.arc {
            compile::Arc::Set => "label=\"OutSet -> Set\"",
            compile::Arc::Reset => "label=\"OutReset -> Reset\", style=dashed",
        };
        let _ = writeln!(o, "    n{k}t{} -> n{k}t{} [{style}];", c.from.0, c.to.0);
    }
    let mut colours: Vec<_> = a.transitions.iter().map(|t| t.colour).collect();
    colours.sort();
    colours.dedup();
    for c in colours {
        let _ = writeln!(
            o,
            "    n{k}c{} [shape=plaintext, label=\"part.{}\"];",
            c.0,
            esc(a.colour_name(c))
        );
        for (id, _) in a.iter().filter(|(_, t)| t.colour == c) {
            let _ = writeln!(
                o,
                "    n{k}c{} -> n{k}t{} [label=\"WP\", style=dotted];",
                c.0, id.0
            );
        }
    }
    if net.instances.iter().any(|i| i.is_final) {
        let _ = writeln!(
            o,
            "    n{k}eos [shape=plaintext, label=\"{}\"];",
            esc(&compile::eos_event(a))
        );
        for i in net.instances.iter().filter(|i| i.is_final) {
            let _ = writeln!(
                o,
                "    n{k}t{} -> n{k}eos [label=\"EOS\", style=dotted];",
                i.transition.0
            );
        }
    }
    let _ = writeln!(o, "  }}");
}

/// The ECC of the FB type, once.
fn type_dot(o: &mut String, t: &ChartType) {
    let _ = writeln!(o, "  subgraph cluster_fbtype {{");
    let _ = writeln!(o, "    label=\"ECC of FB type {}\";", esc(&t.name));
    for (si, s) in t.states.iter().enumerate() {
        let mut label = esc(&s.name);
        for a in &s.actions {
            label.push_str("\\l  ");
            label.push_str(&esc(&action_decl_text(a)));
        }
        if !s.actions.is_empty() {
            label.push_str("\\l");
        }
        let extra = if si == 0 { ", peripheries=2" } else { "" };
        let _ = writeln!(o, "    ts{si} [label=\"{label}\"{extra}];");
    }
    let index = |n: &str| t.states.iter().position(|s| s.name == n).unwrap_or(0);
    for tr in &t.transitions {
        let mut label = tr.on.clone().unwrap_or_default();
        if let Some(g) = &tr.when {
            if !label.is_empty() {
                label.push(' ');
            }
            label.push_str(&format!("[{g}]"));
        }
        let _ = writeln!(
            o,
            "    ts{} -> ts{} [label=\"{}\"];",
            index(&tr.from),
            index(&tr.to),
            esc(&label)
        );
    }
    let _ = writeln!(o, "  }}");
}

fn action_decl_text(a: &ActionDecl) -> String {
    match a {
        ActionDecl::Set(v, e) => format!("{v} := {e}"),
        ActionDecl::Emit(e) => format!("emit {e}"),
        other => format!("{other:?}"),
    }
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
