//! The painting robot brought from Eclipse 4diac IDE files (`robot-configs/paint-robot-4diac.ron`:
//! four `.fbt` basic FB types and a `.sys` mapping them onto four devices): `check`, `sim` and
//! `verify` say exactly what they say of `paint-robot-paper-charts.ron` (the file's name
//! aside), and `demo` runs sequence (1) on real processes: four unconfigured nodes, the
//! medium, the plant. The demo test waits for the demo process to end; no sleeps, no timing
//! asserted.

use std::process::{Command, Output};

mod cli_support;
use cli_support::{demo, text};

const OURS: &str = "robot-configs/paint-robot-4diac.ron";
const PAPER: &str = "robot-configs/paint-robot-paper-charts.ron";

fn tool(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(args)
        .current_dir(std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".."))
        .output()
        .expect("runs")
}

/// Stdout and stderr of `config-tool ARGS FILE`, the file's name replaced and the
/// exploration's speed (states/s) dropped.
fn said(command: &str, file: &str) -> (Option<i32>, String) {
    let out = tool(&[command, file]);
    let all = format!("{}{}", text(&out.stdout), text(&out.stderr)).replace(file, "ROBOT");
    let all = all
        .lines()
        .map(|l| match l.find(" in ") {
            Some(i) if l.contains("states/s") => l[..i].to_string(),
            _ => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    (out.status.code(), all)
}

#[test]
fn check_sim_and_verify_say_of_the_4diac_robot_what_they_say_of_the_paper_charts() {
    for command in ["check", "sim", "verify"] {
        let ours = said(command, OURS);
        assert_eq!(ours.0, Some(0), "{command}: {}", ours.1);
        assert_eq!(ours, said(command, PAPER), "{command}");
    }
    let (_, sim) = said("sim", OURS);
    assert!(
        sim.contains("cycle   1:   3970 ms  11 publications  VC+ GR+ VC- HC+ VC+ VC- RC+ RC- HC- VC+ GR- VC-"),
        "{sim}"
    );
}

#[test]
fn the_demo_runs_the_4diac_robot_cycle_after_cycle() {
    let out = demo(&[OURS, "--cycles", "2", "--no-reconfigure"]);
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert_eq!(out.status.code(), Some(0), "{stdout}\n{stderr}");
    let cycles: Vec<&str> = stdout
        .lines()
        .map(str::trim_start)
        .filter(|l| l.starts_with("cycle "))
        .collect();
    assert_eq!(cycles.len(), 2, "{stdout}");
    for c in cycles {
        assert!(
            c.contains(": ok ") && c.ends_with("VC+ GR+ VC- HC+ VC+ VC- RC+ RC- HC- VC+ GR- VC-"),
            "{c}\n{stdout}"
        );
    }
    assert_eq!(
        stdout.lines().last(),
        Some("demo: every cycle matched"),
        "{stdout}"
    );
}
