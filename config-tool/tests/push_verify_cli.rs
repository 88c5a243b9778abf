//! `push` verifies the robot before it contacts a node: a robot that fails `verify` is
//! refused with the report `verify` prints and its exit status, and nothing is sent;
//! `--no-verify` skips the check and says so; a robot that passes gets one line. The medium
//! named is never there (port 1): a push that got past verification ends with "cannot
//! reach the medium", one that did not never tried to reach it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const NO_MEDIUM: &str = "127.0.0.1:1";
const UNREACHABLE: &str =
    "error: cannot reach the medium at 127.0.0.1:1: Connection refused (os error 111)\n";
const DEADLOCK: &str = "tests/fixtures/verify/order-deadlock.ron";

fn tool(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(args)
        .env_remove("CONFIG_TOOL_KEYS")
        .output()
        .expect("runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// A fresh machine secret (`keys new`) in its own directory.
fn new_key(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("push-verify-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let key = dir.join("machine.key");
    let out = tool(&["keys", "new", "--out", key.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    key
}

/// `verify`'s report without its one varying part, the time of the run (first line).
fn untimed(report: &str) -> String {
    report
        .lines()
        .map(|l| match l.split_once(" transitions in ") {
            Some((head, _)) => format!("{head} transitions in (time)"),
            None => l.to_owned(),
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn push(robot: &str, key: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "push",
        robot,
        "--keys",
        key.to_str().unwrap(),
        "--medium",
        NO_MEDIUM,
    ];
    args.extend(extra);
    tool(&args)
}

#[test]
fn push_refuses_a_robot_that_fails_verify_with_its_counterexample_and_sends_nothing() {
    let key = new_key("refused");
    let verified = tool(&["verify", DEADLOCK]);
    assert_eq!(verified.status.code(), Some(1));
    let report = text(&verified.stdout);
    assert!(
        report.contains("shortest counterexample (4 steps):\n  1. operator presses START (at X)\n"),
        "{report}"
    );
    // The whole robot is verified, also for one role.
    for extra in [&[][..], &["--role", "Y"][..]] {
        let out = push(DEADLOCK, &key, extra);
        assert_eq!(out.status.code(), verified.status.code(), "{extra:?}");
        assert_eq!(untimed(&text(&out.stdout)), untimed(&report), "{extra:?}");
        assert_eq!(
            text(&out.stderr),
            "error: tests/fixtures/verify/order-deadlock.ron fails verify (deadlock freedom): \
             nothing was sent (--no-verify pushes it unverified)\n",
            "{extra:?}"
        );
    }
    // The key file was never opened for a radio: no frame counter was reserved.
    assert!(!key.with_extension("key.counter").exists());
}

#[test]
fn push_names_the_property_each_failing_fixture_breaks() {
    let key = new_key("each");
    for (file, property) in [
        ("interlock", "interlock"),
        ("order-deadlock", "deadlock freedom"),
        ("refire", "sequence conformance"),
        ("timed-retract", "no double actuation"),
    ] {
        let robot = format!("tests/fixtures/verify/{file}.ron");
        let out = push(&robot, &key, &[]);
        assert_eq!(out.status.code(), Some(1), "{file}");
        assert_eq!(
            text(&out.stderr),
            format!(
                "error: {robot} fails verify ({property}): nothing was sent (--no-verify \
                 pushes it unverified)\n"
            )
        );
        assert!(
            text(&out.stdout).contains(&format!("FAILED {property}")),
            "{file}: {}",
            text(&out.stdout)
        );
    }
}

#[test]
fn push_no_verify_skips_verification_and_says_so_once() {
    let key = new_key("skipped");
    let out = push(DEADLOCK, &key, &["--no-verify"]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(text(&out.stdout), "");
    assert_eq!(
        text(&out.stderr),
        format!(
            "warning: push --no-verify: tests/fixtures/verify/order-deadlock.ron was not \
             verified\n{UNREACHABLE}"
        )
    );
}

#[test]
fn push_of_a_robot_that_passes_prints_one_verified_line_first() {
    let key = new_key("passed");
    for (robot, line) in [
        (
            "robot-configs/paint-robot.ron",
            "verified: 451 states, 1111 transitions, every property holds\n",
        ),
        (
            "robot-configs/paint-robot-paper-charts.ron",
            "verified: 87 states, 113 transitions, every property holds (assuming a prompt \
             radio)\n",
        ),
    ] {
        let out = push(robot, &key, &[]);
        assert_eq!(
            (out.status.code(), text(&out.stdout), text(&out.stderr)),
            (Some(1), line.to_owned(), UNREACHABLE.to_owned()),
            "{robot}"
        );
    }
}
