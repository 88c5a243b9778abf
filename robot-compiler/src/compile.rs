//! The pipeline: source -> checked robot and its IR (`check`) -> tables -> blobs.

use config_schema::{limits::MAX_BLOB, Table};

use crate::check::{self, Checked};
use crate::diag::Diagnostic;
use crate::ir::Ir;
use crate::lower;
use crate::model::Robot;
use crate::source::Source;

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

/// Encodes a table into a blob.
pub fn encode(table: &Table) -> Result<Vec<u8>, String> {
    let mut buf = vec![0u8; MAX_BLOB];
    let n = config_schema::encode(table, &mut buf).map_err(|e| e.to_string())?;
    buf.truncate(n);
    Ok(buf)
}

/// Checks (which elaborates), then lowers and encodes. On error: every diagnostic (errors
/// and warnings).
pub fn compile(src: &Source) -> Result<Compiled, Vec<Diagnostic>> {
    lower_checked(src, check::check(src))
}

/// Lowers and encodes the IR of a robot `check` elaborated. On error (of the check or
/// here): every diagnostic (errors and warnings).
pub fn lower_checked(src: &Source, checked: Checked) -> Result<Compiled, Vec<Diagnostic>> {
    let has_errors = checked.has_errors();
    let Checked {
        robot,
        ir,
        diagnostics: diags,
    } = checked;
    let (Some(robot), Some(ir), false) = (robot, ir, has_errors) else {
        return Err(diags);
    };
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
