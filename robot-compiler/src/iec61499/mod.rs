//! IEC 61499-2 XML in: basic FB types (`.fbt`) become chart types of the robot
//! (docs/iec61499-xml.md). [`fbt`] reads one file, [`st`] translates its Structured Text.
//! Out: [`export`] writes a compiled robot as `.fbt` types and a `.sys`; [`services`] is
//! the naming of the node's services both directions share.

pub mod export;
pub mod fbt;
pub mod services;
pub mod st;

use std::io;
use std::path::Path;

use crate::diag::Diagnostic;
use crate::model::Robot;
use crate::source::Source;

/// Imports the robot's `fb_types` (files next to the robot file, `src.name`) into its
/// `chart_types`; every problem is an error at its `fb_types` entry naming the file's
/// line:col. A type with an error is not imported.
pub fn import(robot: &mut Robot, src: &Source) -> Vec<Diagnostic> {
    let dir = Path::new(&src.name)
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    import_with(robot, src, &|name: &str| std::fs::read(dir.join(name)))
}

/// [`import`], with `read` giving the bytes of a file as the robot names it.
pub fn import_with(
    robot: &mut Robot,
    src: &Source,
    read: &dyn Fn(&str) -> io::Result<Vec<u8>>,
) -> Vec<Diagnostic> {
    let mut diags = Vec::new();
    for (i, file) in robot.fb_types.clone().iter().enumerate() {
        let at = src.span(&format!("fb_types[{i}]"));
        let bytes = match read(file) {
            Ok(b) => b,
            Err(e) => {
                diags.push(Diagnostic::error(at, format!("cannot read `{file}`: {e}")));
                continue;
            }
        };
        let Ok(text) = String::from_utf8(bytes) else {
            diags.push(Diagnostic::error(at, format!("`{file}` is not UTF-8 text")));
            continue;
        };
        match fbt::import(&text) {
            Ok(t) => robot.chart_types.push(t),
            Err(e) => {
                diags.push(Diagnostic::error(at, format!("{file}:{e}")).label("imported here"))
            }
        }
    }
    diags
}
