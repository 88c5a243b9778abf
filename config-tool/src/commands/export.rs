//! `export-4diac`: the robot's chart types as `.fbt` files and the robot as a `.sys`
//! (robot_compiler::iec61499::export).

use std::path::Path;

use robot_compiler::iec61499::export;
use robot_compiler::Diagnostic;

use super::offline::{load_compiled, report};
use super::outputs::MAX_FILE_NAME;
use crate::failure::Failure;
use crate::out::outln;

pub fn export(robot: &Path, out: &Path) -> Result<(), Failure> {
    let (src, compiled) = load_compiled(robot)?;
    // Where the robot file names chart type `ty`.
    let type_at = |ty: &str| {
        (compiled.robot.chart_type(ty))
            .map(|(i, t)| src.span(t.place(&format!("chart_types[{i}].name"))))
    };
    // `problem`, at its place in the robot file if it has one.
    let refused = |at: Option<std::ops::Range<usize>>, problem: String| match at {
        Some(span) => {
            report(&src, &[Diagnostic::error(span, problem)]);
            Failure::reported()
        }
        None => Failure::error(format!("{}: {problem}", robot.display())),
    };
    let exported = export::export(&compiled, &today()).map_err(|e| {
        // At the chart type it names, where the robot file has it.
        let at = match &e {
            export::ExportError::Type { ty, .. } => type_at(ty),
            export::ExportError::Reads { .. } => None,
        };
        refused(at, format!("cannot export: {e}"))
    })?;
    // File names the file system would refuse part-way (too long), or that come twice:
    // refused at the name in the robot file that makes them, before anything is written.
    let mut seen = std::collections::HashSet::new();
    for (name, _) in &exported.files {
        let problem = if name.len() > MAX_FILE_NAME {
            format!(
                "cannot export: the file name `{name}` is {} bytes long: a file system takes \
                 at most {MAX_FILE_NAME}",
                name.len()
            )
        } else if !seen.insert(name.as_str()) {
            format!("cannot export: two files would be named `{name}`")
        } else {
            continue;
        };
        let at = match (name.strip_suffix(".sys"), name.strip_suffix(".fbt")) {
            (Some(_), _) => Some(src.span("name")),
            (_, Some(stem)) => type_at(stem),
            _ => None,
        };
        return Err(refused(at, problem));
    }
    let inputs = super::outputs::robot_files(robot, &compiled.robot);
    let names = exported.files.iter().map(|(name, _)| name.as_str());
    super::outputs::none_an_input("--out", out, names, &inputs)?;
    let files = exported
        .files
        .iter()
        .map(|(name, text)| (name.as_str(), text.as_bytes()));
    for path in super::outputs::write_all(out, files)? {
        outln!("{}", path.display());
    }
    let lifted = exported.instances.iter().filter(|i| i.lifted).count();
    outln!(
        "{} FB types ({lifted} lifted from compiled charts), {} FB instances",
        exported.types.len(),
        exported.instances.len()
    );
    Ok(())
}

/// Today's date (UTC), `YYYY-MM-DD`, for `VersionInfo`.
fn today() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    civil(i64::try_from(secs / 86_400).unwrap_or(0))
}

/// The civil date of day `z` since 1970-01-01 (the proleptic Gregorian calendar).
fn civil(z: i64) -> String {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

#[cfg(test)]
mod tests {
    /// Days since 1970 become their dates (leap years included).
    #[test]
    fn civil_dates() {
        assert_eq!(super::civil(0), "1970-01-01");
        assert_eq!(super::civil(11_016), "2000-02-29");
        assert_eq!(super::civil(20_454), "2026-01-01");
    }
}
