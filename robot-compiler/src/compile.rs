//! The pipeline: source -> checked robot and its IR (`check`) -> tables -> blobs.

use config_schema::{limits::MAX_TABLE_BLOB, Table};

use crate::check::{self, Checked};
use crate::diag::Diagnostic;
use crate::ir::Ir;
use crate::lower;
use crate::model::Robot;
use crate::source::Source;

/// Why a table could not be made a blob.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    #[error(transparent)]
    Blob(#[from] config_schema::EncodeError),
    /// Longer than a node can store with its link keys.
    #[error("blob of {len} bytes exceeds MAX_TABLE_BLOB ({MAX_TABLE_BLOB})")]
    TooBig { len: usize },
}

/// A compiled robot: its IR, one table and one blob per role (in role order), and the
/// warnings `check` gave.
#[derive(Debug, Clone)]
pub struct Compiled {
    pub robot: Robot,
    pub ir: Ir,
    pub tables: Vec<Table>,
    pub blobs: Vec<Vec<u8>>,
    pub warnings: Vec<Diagnostic>,
    /// The robot's selecting automata as resolved (a `facts_file` read next to the robot
    /// file), in declaration order: what `verify` takes the reference semantics from (it
    /// reads no file: a station whose automaton came from a file did not verify).
    pub automata: Vec<crate::automata::Automaton>,
}

impl Compiled {
    /// The same robot for deployment generation `generation` (re-encoded blobs).
    pub fn with_generation(mut self, generation: u32) -> Result<Compiled, EncodeError> {
        self.ir.generation = generation;
        for (table, blob) in self.tables.iter_mut().zip(self.blobs.iter_mut()) {
            table.generation = generation;
            *blob = encode(table)?;
        }
        Ok(self)
    }
}

/// Encodes a table into a blob (at most `MAX_TABLE_BLOB` bytes).
pub fn encode(table: &Table) -> Result<Vec<u8>, EncodeError> {
    let mut buf = vec![0u8; config_schema::limits::MAX_BLOB];
    let n = config_schema::encode(table, &mut buf)?;
    if n > MAX_TABLE_BLOB {
        return Err(EncodeError::TooBig { len: n });
    }
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
    let fail = |e: &dyn std::fmt::Display| vec![Diagnostic::error(src.span(""), e.to_string())];
    let tables = lower::lower(&ir).map_err(|e| fail(&e))?;
    let blobs = tables
        .iter()
        .map(encode)
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| fail(&e))?;
    let automata = match robot.automata.is_empty() {
        true => Vec::new(),
        false => (crate::automata::load(&robot, src).automata.into_iter())
            .map(|l| l.automaton)
            .collect(),
    };
    Ok(Compiled {
        robot,
        ir,
        tables,
        blobs,
        warnings: diags,
        automata,
    })
}

/// The radio events one cycle of a sequence robot sends: (from role, event, to role), in
/// topic order. Each step event occurs once per cycle, so this is also the count of
/// publications per cycle. A synthesised `fault` (sent only on a fault) and homing's
/// events (sent only when homing) are left out.
pub fn radio_events(ir: &Ir) -> Vec<(String, String, String)> {
    let mut out = Vec::new();
    let homing = crate::synth::homing_events(ir);
    for (ri, e, _) in lower::topics(ir) {
        let from = &ir.roles[ri];
        if from.events[e] == crate::synth::FAULT_EVENT || homing.contains(&from.events[e]) {
            continue; // only on a fault, or when homing
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

/// What homing does, for people: `homing: VC- HC- RC- GR- (derived ...)`; none for a
/// robot without homing (explicit charts).
pub fn homing_line(ir: &Ir) -> Option<String> {
    let role = ir.roles.get(ir.home?)?;
    let steps: Vec<String> = ir.homing.iter().map(ToString::to_string).collect();
    let how = if ir.homing_derived {
        "derived from the actuators and interlocks"
    } else {
        "declared"
    };
    Some(format!(
        "homing: {} ({how}; HOME goes to role {})",
        steps.join(" "),
        role.name
    ))
}

/// One line per role: its worst stimulus (a bound, in instructions: `config_schema::cost`)
/// and the event it is, against the budget.
pub fn stimulus_lines(c: &Compiled) -> Vec<String> {
    let budget = config_schema::cost::STIMULUS_BUDGET;
    c.ir.roles
        .iter()
        .zip(&c.tables)
        .map(|(r, t)| {
            let w = config_schema::cost::worst_stimulus(t);
            let event = r
                .events
                .get(usize::from(w.event))
                .map_or("?", String::as_str);
            format!(
                "{:<12} worst stimulus {:>6} instructions ({:>2}% of {budget}): `{event}`, \
                 {} event(s)",
                r.name,
                w.cost,
                w.cost * 100 / budget,
                w.cascade
            )
        })
        .collect()
}

/// One summary line per role: node address, charts, states, transitions, blob bytes
/// against the data of one `ConfigChunk` (what one secured frame carries), and the frames
/// the blob takes.
pub fn summary(c: &Compiled) -> Vec<String> {
    use config_schema::wire::msg::CHUNK_DATA;
    c.ir.roles
        .iter()
        .zip(&c.tables)
        .zip(&c.blobs)
        .map(|((r, t), b)| {
            let frames = b.len().div_ceil(CHUNK_DATA);
            format!(
                "{:<12} node {:#06x}  charts {}  states {:>3}  transitions {:>3}  stimulus \
                 {:>5}  bytes {:>4} of {CHUNK_DATA}: {}",
                r.name,
                r.address,
                t.charts.len(),
                t.states.len(),
                t.transitions.len(),
                config_schema::cost::worst_stimulus(t).cost,
                b.len(),
                frames_text(frames)
            )
        })
        .collect()
}

/// "one frame", "2 frames".
pub fn frames_text(frames: usize) -> String {
    if frames == 1 {
        "one frame".to_string()
    } else {
        format!("{frames} frames")
    }
}
