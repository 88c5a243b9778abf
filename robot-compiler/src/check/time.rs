//! Time per stimulus: each role's table within `config_schema::cost::STIMULUS_BUDGET`
//! (validation refuses the rest; here the refusal names the role and the event).

use config_schema::Invalid;

use crate::diag::Diagnostic;
use crate::ir::Ir;
use crate::lower::{self, LowerError, RoleError};
use crate::model::Robot;
use crate::source::Source;

pub fn check(_robot: &Robot, ir: &Ir, src: &Source, out: &mut Vec<Diagnostic>) {
    let Err(LowerError::Internal {
        role,
        error:
            RoleError::Invalid(Invalid::Slow {
                event,
                cost,
                budget,
            }),
    }) = lower::lower(ir)
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
