//! Pins: a GPIO pin past the table's pin range (`limits::MAX_PINS`: a node keeps its pin
//! levels in a `u64`), or used twice on one role (inputs and outputs share the pin numbers
//! of the node).

use std::collections::BTreeMap;

use config_schema::limits::MAX_PINS;

use crate::diag::Diagnostic;
use crate::model::Robot;
use crate::source::Source;

pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    for (ri, role) in robot.roles.iter().enumerate() {
        // (pin, what uses it, path of the pin value)
        let mut uses: Vec<(u8, String, String)> = Vec::new();
        for (ai, a) in role.actuators.iter().enumerate() {
            let p = format!("roles[{ri}].actuators[{ai}].kind");
            for (field, pin, _) in a.kind.pins() {
                uses.push((pin, format!("{}.{field}", a.name), format!("{p}.{field}")));
            }
        }
        for (k, i) in role.inputs.iter().enumerate() {
            uses.push((
                i.pin,
                i.name.clone(),
                format!("roles[{ri}].inputs[{k}].pin"),
            ));
        }
        for (k, o) in role.outputs.iter().enumerate() {
            uses.push((
                o.pin,
                o.name.clone(),
                format!("roles[{ri}].outputs[{k}].pin"),
            ));
        }
        let mut seen: BTreeMap<u8, (String, String)> = BTreeMap::new();
        for (pin, what, path) in uses {
            if usize::from(pin) >= MAX_PINS {
                out.push(
                    Diagnostic::error(
                        src.span(&path),
                        format!(
                            "pin {pin} of `{what}` is out of range: a table names pins 0..={}",
                            MAX_PINS - 1
                        ),
                    )
                    .label(format!("0..={}", MAX_PINS - 1)),
                );
                continue;
            }
            match seen.get(&pin) {
                Some((first, first_path)) => {
                    let (line, col) = src.line_col(src.span(first_path).start);
                    out.push(
                        Diagnostic::error(
                            src.span(&path),
                            format!(
                                "pin {pin} of role `{}` is used twice: by `{first}` and `{what}`",
                                role.name
                            ),
                        )
                        .label(format!("`{first}` uses it at {line}:{col}")),
                    );
                }
                None => {
                    seen.insert(pin, (what, path));
                }
            }
        }
    }
}
