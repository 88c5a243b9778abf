//! The capacity of each role's table against `config_schema::limits`.

use crate::diag::Diagnostic;
use crate::ir::Ir;
use crate::model::Robot;
use crate::source::Source;

pub fn check(_robot: &Robot, ir: &Ir, src: &Source, out: &mut Vec<Diagnostic>) {
    for over in crate::lower::capacity(ir) {
        let role = &ir.roles[over.role].name;
        out.push(
            Diagnostic::error(
                src.span(&format!("roles[{}].name", over.role)),
                format!("the table of role `{role}` is too big: {over}"),
            )
            .label("this role's table")
            .help("move charts to another role, or simplify them"),
        );
    }
}
