//! Passes over the elaborated robot: elaboration itself (names in charts, guards) and the
//! capacity of each role's table against `config_schema::limits`.

use crate::compile;
use crate::diag::Diagnostic;
use crate::model::Robot;
use crate::source::Source;

pub fn build(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    if let Err(mut d) = compile::build(robot, src) {
        out.append(&mut d);
    }
}

pub fn capacity(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    let Ok(ir) = compile::build(robot, src) else {
        return;
    };
    for over in crate::lower::capacity(&ir) {
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
