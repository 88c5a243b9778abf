//! Time per stimulus: each role's table within `config_schema::cost::STIMULUS_BUDGET`
//! (validation refuses the rest; here the refusal names the role and the event).

use config_schema::Invalid;

use crate::diag::Diagnostic;
use crate::ir::Ir;
use crate::lower::{self, LowerError, RoleError};
use crate::model::Robot;
use crate::source::Source;

pub fn check(_robot: &Robot, ir: &Ir, src: &Source, out: &mut Vec<Diagnostic>) {
    let lowered = lower::lower(ir);
    if let Ok(tables) = &lowered {
        endless(ir, tables, src, out);
    }
    let Err(LowerError::Internal {
        role,
        error:
            RoleError::Invalid(Invalid::Slow {
                event,
                cost,
                budget,
            }),
    }) = lowered
    else {
        return;
    };
    let Some(ri) = ir.roles.iter().position(|r| r.name == role) else {
        return;
    };
    let name = ir.roles[ri]
        .events
        .get(usize::from(event))
        .map_or("?", String::as_str);
    out.push(
        Diagnostic::error(
            src.span(&format!("roles[{ri}].name")),
            format!(
                "one stimulus of role `{role}` (event `{name}`) may cost {cost} instructions, \
                 over the budget of {budget} (1 ms at 64 MHz) by {}",
                cost.saturating_sub(budget)
            ),
        )
        .label("this role's table")
        .help(
            "shorten the guards of its charts, send fewer publications per event, break \
             event-less chains or cascades of emitted events, or move charts to another role",
        ),
    );
}

/// A role whose dearest stimulus may set off a cascade as long as a node takes
/// (`MAX_CASCADE`): its charts emit events in a cycle (two control functions that enter a
/// place on each other's entries, back and forth). The bound counts every emit that may
/// happen, so the cycle may stop on its states; `verify` says whether it does (a node
/// that runs it faults: `Cascade`). `check` took such a robot without a word.
fn endless(ir: &Ir, tables: &[config_schema::Table], src: &Source, out: &mut Vec<Diagnostic>) {
    use config_schema::limits::MAX_CASCADE;
    for (ri, (r, t)) in ir.roles.iter().zip(tables).enumerate() {
        let worst = config_schema::cost::worst_stimulus(t);
        if worst.cascade < MAX_CASCADE as u32 {
            continue;
        }
        let name = r
            .events
            .get(usize::from(worst.event))
            .map_or("?", String::as_str);
        out.push(
            Diagnostic::warning(
                src.span(&format!("roles[{ri}].name")),
                format!(
                    "event `{name}` of role `{}` may set off a cascade of {MAX_CASCADE} events \
                     its charts emit, or more (a cycle: charts that react to each other's \
                     events): a node that runs that long faults (`Cascade`); `verify` says \
                     whether it can",
                    r.name
                ),
            )
            .label("this role's charts"),
        );
    }
}
