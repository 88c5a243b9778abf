//! The pipeline: source -> checked robot -> IR -> tables -> blobs.

use config_schema::{limits::MAX_BLOB, Table};

use crate::diag::Diagnostic;
use crate::ir::{parse_steps, Ir};
use crate::model::Robot;
use crate::source::Source;
use crate::{check, elab, lower, synth};

/// A compiled robot: its IR, one table and one blob per role (in role order), and the
/// warnings `check` gave.
#[derive(Debug, Clone)]
pub struct Compiled {
    pub robot: Robot,
    pub ir: Ir,
    pub tables: Vec<Table>,
    pub blobs: Vec<Vec<u8>>,
    pub warnings: Vec<Diagnostic>,
}

impl Compiled {
    /// The same robot for deployment generation `generation` (re-encoded blobs).
    pub fn with_generation(mut self, generation: u32) -> Result<Compiled, String> {
        self.ir.generation = generation;
        for (table, blob) in self.tables.iter_mut().zip(self.blobs.iter_mut()) {
            table.generation = generation;
            *blob = encode(table)?;
        }
        Ok(self)
    }
}

/// Elaborates a robot that passed the structural checks: synthesis for a sequence,
/// elaboration of explicit charts otherwise.
pub fn build(robot: &Robot, src: &Source) -> Result<Ir, Vec<Diagnostic>> {
    match &robot.sequence {
        Some(text) => {
            let steps: Vec<_> = parse_steps(text)
                .into_iter()
                .filter_map(|(s, _)| s.ok())
                .collect();
            synth::synthesise(robot, &steps)
                .map_err(|e| vec![Diagnostic::error(src.span("sequence"), e)])
        }
        None => elab::elaborate(robot, src),
    }
}

/// Encodes a table into a blob.
pub fn encode(table: &Table) -> Result<Vec<u8>, String> {
    let mut buf = vec![0u8; MAX_BLOB];
    let n = config_schema::encode(table, &mut buf).map_err(|e| e.to_string())?;
    buf.truncate(n);
    Ok(buf)
}

/// Checks, builds, lowers and encodes. On error: every diagnostic (errors and warnings).
pub fn compile(src: &Source) -> Result<Compiled, Vec<Diagnostic>> {
    let (robot, diags) = check::check(src);
    let Some(robot) = robot else {
        return Err(diags);
    };
    if diags.iter().any(Diagnostic::is_error) {
        return Err(diags);
    }
    let ir = build(&robot, src)?;
    let fail = |m: String| vec![Diagnostic::error(src.span(""), m)];
    let tables = lower::lower(&ir).map_err(|e| fail(e.to_string()))?;
    let blobs = tables
        .iter()
        .map(|t| {
            let blob = encode(t)?;
            if blob.len() > MAX_BLOB {
                return Err(format!(
                    "blob of {} bytes exceeds MAX_BLOB ({MAX_BLOB})",
                    blob.len()
                ));
            }
            Ok(blob)
        })
        .collect::<Result<Vec<_>, String>>()
        .map_err(fail)?;
    Ok(Compiled {
        robot,
        ir,
        tables,
        blobs,
        warnings: diags,
    })
}

/// The radio events one cycle of a sequence robot sends: (from role, event, to role), in
/// topic order. Each step event occurs once per cycle, so this is also the count of
/// publications per cycle. A synthesised `fault` (sent only on a fault) is left out.
pub fn radio_events(ir: &Ir) -> Vec<(String, String, String)> {
    let mut out = Vec::new();
    for (ri, e) in lower::topics(ir) {
        let from = &ir.roles[ri];
        if from.events[e] == crate::synth::FAULT_EVENT {
            continue; // only on a fault
        }
        for to in &ir.roles {
            if to
                .imports
                .iter()
                .any(|(f, x, _)| *f == from.name && *x == from.events[e])
            {
                out.push((from.name.clone(), from.events[e].clone(), to.name.clone()));
            }
        }
    }
    out
}

/// One summary line per role: node address, charts, states, transitions, blob bytes.
pub fn summary(c: &Compiled) -> Vec<String> {
    c.ir.roles
        .iter()
        .zip(&c.tables)
        .zip(&c.blobs)
        .map(|((r, t), b)| {
            format!(
                "{:<12} node {:#06x}  charts {}  states {:>3}  transitions {:>3}  bytes {:>4}",
                r.name,
                r.address,
                t.charts.len(),
                t.states.len(),
                t.transitions.len(),
                b.len()
            )
        })
        .collect()
}
