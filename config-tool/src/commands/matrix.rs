//! `config-tool matrix`: the paper's objects of each control function (M, F, m(0), x, u),
//! as readable tables or CSV (docs/petri-nets.md, "The matrix export").

use std::path::Path;

use robot_compiler::petri::matrix;
use robot_compiler::{check, Source};

use crate::failure::Failure;
use crate::out::{err, out};

/// Prints the matrices of every function of the robot, or of `function` only.
pub fn matrix(robot: &Path, function: Option<&str>, csv: bool) -> Result<(), Failure> {
    let src = Source::read(robot).map_err(Failure::from)?;
    let checked = check::check(&src);
    if checked.has_errors() {
        err!(
            "{}",
            robot_compiler::diag::render_all(&src, &checked.diagnostics, false)
        );
        return Err(Failure::reported());
    }
    let Some(robot) = checked.robot else {
        return Err(Failure::reported());
    };
    let loaded = robot_compiler::petri::load(&robot, &src);
    let nets: Vec<_> = loaded
        .functions
        .iter()
        .map(|l| &l.net)
        .filter(|n| function.is_none_or(|f| n.name == f))
        .collect();
    if nets.is_empty() {
        let names: Vec<&str> = loaded
            .functions
            .iter()
            .map(|l| l.net.name.as_str())
            .collect();
        return Err(Failure::usage(match (function, names.is_empty()) {
            (Some(f), false) => format!(
                "{}: no function `{f}` (functions: {})",
                src.name,
                names.join(", ")
            ),
            (Some(f), true) => format!(
                "{}: no function `{f}`: the robot declares no `functions`",
                src.name
            ),
            (None, _) => format!("{}: the robot declares no `functions`", src.name),
        }));
    }
    let parts: Vec<String> = nets
        .iter()
        .map(|n| if csv { matrix::csv(n) } else { matrix::text(n) })
        .collect();
    out!("{}", parts.join("\n"));
    Ok(())
}
