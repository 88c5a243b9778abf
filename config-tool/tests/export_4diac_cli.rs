//! `config-tool export-4diac` end to end: the binary writes, for the paper charts'
//! painting robot, each chart type as a `.fbt`, each role's node services type and the
//! `.sys` into the directory `--out` names, prints each file written and one summary
//! line, and the files are what `robot_compiler::iec61499::export` gives (the date
//! aside).

use std::path::PathBuf;
use std::process::Command;

const ROBOT: &str = "robot-configs/paint-robot-paper-charts.ron";

/// `Date="YYYY-MM-DD"` of every `VersionInfo` as `Date="DATE"`.
fn undated(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(i) = rest.find("Date=\"") {
        out.push_str(&rest[..i + 6]);
        rest = &rest[i + 6..];
        let end = rest.find('"').unwrap_or(rest.len());
        out.push_str("DATE");
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

#[test]
fn export_4diac_writes_the_types_and_the_system_and_says_so() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = std::env::temp_dir().join(format!("export-4diac-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["export-4diac", ROBOT, "--out"])
        .arg(&dir)
        .current_dir(&root)
        .output()
        .expect("runs");
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout).to_string(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    );
    assert_eq!(out.status.code(), Some(0), "{stdout}\n{stderr}");
    let names = [
        "Vc.fbt",
        "Gr.fbt",
        "Hc.fbt",
        "Rc.fbt",
        "VC_IO.fbt",
        "GR_IO.fbt",
        "HC_IO.fbt",
        "RC_IO.fbt",
        "paint_robot_paper_charts.sys",
    ];
    let mut want: Vec<String> = names
        .iter()
        .map(|n| dir.join(n).display().to_string())
        .collect();
    want.push(String::from(
        "4 FB types (0 lifted from compiled charts), 4 FB instances",
    ));
    assert_eq!(stdout.lines().collect::<Vec<_>>(), want, "{stderr}");
    let mut written: Vec<String> = std::fs::read_dir(&dir)
        .expect("the directory")
        .map(|e| e.expect("entry").file_name().to_string_lossy().to_string())
        .collect();
    written.sort();
    let mut sorted = names.map(String::from).to_vec();
    sorted.sort();
    assert_eq!(written, sorted);
    let src = robot_compiler::Source::read(&root.join(ROBOT)).expect("reads");
    let c = robot_compiler::compile(&src).expect("compiles");
    let e = robot_compiler::iec61499::export::export(&c, "2026-01-01").expect("exports");
    for (name, text) in &e.files {
        let on_disk = std::fs::read_to_string(dir.join(name)).expect("written");
        assert_eq!(undated(&on_disk), undated(text), "{name}");
    }
    // Each role's node services type names the node events it stands for.
    let gr = std::fs::read_to_string(dir.join("GR_IO.fbt")).expect("written");
    assert!(
        gr.contains("<Event Name=\"gr_T\" Type=\"Event\" Comment=\"gr.T\"/>"),
        "{gr}"
    );
    assert!(gr.contains("Classification=\"ecc-nodes services\""), "{gr}");
    std::fs::remove_dir_all(&dir).expect("removed");
}

/// A chart type 4diac cannot take is refused at its place in the robot file, and nothing
/// is written.
#[test]
fn a_type_that_cannot_be_exported_is_refused_at_its_place() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join(ROBOT)).expect("robot");
    let text = text.replace("\"Vc\"", "\"V-c\"");
    let (code, stderr, at, written) = export_refused("bad", &text, "name: \"V-c\"");
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains(&at), "{at}: {stderr}");
    assert!(
        stderr.contains("cannot export: chart type `V-c`: `V-c` is not an IEC 61131-3 identifier"),
        "{stderr}"
    );
    assert!(!written, "nothing written");
}

/// An export into the directory of the robot's own imported types (`Vc.fbt`, ...) would
/// overwrite them with what the export made of them (the user's comments gone, a marker
/// added): refused before anything is written, status 2, naming the file; so is a
/// compile whose blob would land on the robot file.
#[test]
fn an_export_or_compile_that_would_overwrite_one_of_its_inputs_is_refused() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = std::env::temp_dir().join(format!("export-4diac-inputs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let types = dir.join("4diac/paint-robot");
    std::fs::create_dir_all(&types).expect("dir");
    std::fs::copy(
        root.join("robot-configs/paint-robot-4diac.ron"),
        dir.join("robot.ron"),
    )
    .expect("robot");
    for entry in std::fs::read_dir(root.join("robot-configs/4diac/paint-robot")).expect("dir") {
        let from = entry.expect("entry").path();
        std::fs::copy(&from, types.join(from.file_name().expect("name"))).expect("copied");
    }
    let before = std::fs::read(types.join("Vc.fbt")).expect("Vc.fbt");
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_config-tool"))
            .args(args)
            .current_dir(&dir)
            .output()
            .expect("runs");
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).to_string(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    assert_eq!(
        run(&["export-4diac", "robot.ron", "--out", "4diac/paint-robot"]),
        (
            Some(2),
            String::new(),
            "error: --out 4diac/paint-robot/Vc.fbt: that is 4diac/paint-robot/Vc.fbt, which \
             this command reads: it would be overwritten\n"
                .to_string()
        )
    );
    assert_eq!(std::fs::read(types.join("Vc.fbt")).expect("Vc.fbt"), before);
    assert!(!types.join("VC_IO.fbt").exists(), "nothing written");
    std::fs::copy(dir.join("robot.ron"), dir.join("VC.bin")).expect("robot");
    let (code, _, err) = run(&["compile", "VC.bin", "--out", "."]);
    assert_eq!(
        (code, err.as_str()),
        (
            Some(2),
            "error: --out ./VC.bin: that is VC.bin, which this command reads: it would be \
             overwritten\n"
        )
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `export-4diac` of `text` (written as `r.ron` in a directory of its own, `tag`): its
/// status, its standard error, the place of `what` in `text` as `r.ron:LINE:COL]`, and
/// whether the output directory was made.
fn export_refused(tag: &str, text: &str, what: &str) -> (Option<i32>, String, String, bool) {
    // At its value when `what` is a field (`name: "X"`).
    let skip = what.find('"').unwrap_or(0);
    let dir = std::env::temp_dir().join(format!("export-4diac-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    let robot = dir.join("r.ron");
    std::fs::write(&robot, text).expect("writes");
    let out = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["export-4diac"])
        .arg(&robot)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .expect("runs");
    let at = text.find(what).expect("what") + skip;
    let line = text[..at].matches('\n').count() + 1;
    let col = at - text[..at].rfind('\n').map_or(0, |i| i + 1) + 1;
    let written = dir.join("out").exists();
    let _ = std::fs::remove_dir_all(&dir);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).to_string(),
        format!("r.ron:{line}:{col}]"),
        written,
    )
}

/// A robot name too long for a file name: refused at the name, nothing written (the
/// `.fbt` files were, then the `.sys` failed with the file system's error and no place).
#[test]
fn a_robot_name_too_long_for_a_file_name_is_refused_at_it_and_nothing_is_written() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join(ROBOT)).expect("robot");
    let long = "A".repeat(252);
    let text = text.replacen(
        "name: \"paint-robot-paper-charts\"",
        &format!("name: \"{long}\""),
        1,
    );
    let (code, stderr, at, written) = export_refused("long", &text, &format!("\"{long}\""));
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains(&at), "{at}: {stderr}");
    // The message as miette wraps it: compared without its spaces and the frame's bars.
    let bare = |t: &str| -> String {
        t.chars()
            .filter(|c| !c.is_whitespace() && *c != '│')
            .collect()
    };
    let message = format!(
        "cannot export: the file name `{long}.sys` is 256 bytes long: a file system takes at most 255"
    );
    assert!(bare(&stderr).contains(&bare(&message)), "{stderr}");
    assert!(!written, "nothing written");
}

/// A chart type named as a role's service type (`VC_IO`): refused at the chart type.
#[test]
fn a_chart_type_named_as_a_roles_service_type_is_refused_at_it() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join(ROBOT)).expect("robot");
    let text = text.replace("\"Vc\"", "\"VC_IO\"");
    let (code, stderr, at, written) = export_refused("clash", &text, "name: \"VC_IO\"");
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains(&at), "{at}: {stderr}");
    assert!(
        stderr.contains("cannot export: two files would be named `VC_IO.fbt`"),
        "{stderr}"
    );
    assert!(!written, "nothing written");
}
