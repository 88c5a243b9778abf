//! `config-tool verify` and `sim --fault` / `--timeline` on the command line: outputs and
//! exit statuses.

use std::path::PathBuf;
use std::process::{Command, Output};

fn tool(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(args)
        .current_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".."))
        .output()
        .expect("runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn verify_passes_the_paint_robot_and_says_how_many_states() {
    let out = tool(&["verify", "robot-configs/paint-robot.ron"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    let lines: Vec<&str> = stdout.lines().collect();
    assert!(
        lines[0].starts_with("robot-configs/paint-robot.ron: 451 states, 1111 transitions in "),
        "{stdout}"
    );
    assert_eq!(
        lines[1],
        "  idle states 2, stopped (fault / link alarm) states 388"
    );
    assert_eq!(
        lines[2],
        "ok: deadlock freedom, sequence conformance, 2 interlock(s), no double actuation, no \
         engine fault, a fault stops every node"
    );
    // Then homing, from every start position.
    assert!(
        lines[3].starts_with(
            "robot-configs/paint-robot.ron: homing \"VC- HC- RC- GR-\" from 81 start positions \
             x 2 held valve levels: 1440 states, 3416 transitions in "
        ),
        "{stdout}"
    );
    assert_eq!(
        lines[4],
        "  homed (idle) states 16, stopped (fault / link alarm) states 1008"
    );
    assert_eq!(
        lines[5],
        "ok: homing reaches the idle state from every start position, nothing moves before \
         HOME, homing conformance, 2 interlock(s), no double actuation, no engine fault, a \
         fault stops every node"
    );
    assert_eq!(lines.len(), 6, "{stdout}");
    let lossy = tool(&["verify", "robot-configs/paint-robot.ron", "--lossy"]);
    assert_eq!(lossy.status.code(), Some(0));
    assert!(text(&lossy.stdout).contains(": 1475 states, 4360 transitions in "));
    assert!(text(&lossy.stdout).contains(": 4240 states, 12252 transitions in "));
}

#[test]
fn verify_only_runs_one_of_the_cycle_and_homing() {
    let paint = "robot-configs/paint-robot.ron";
    let cycle = tool(&["verify", paint, "--only", "cycle"]);
    assert_eq!(cycle.status.code(), Some(0), "{}", text(&cycle.stderr));
    let stdout = text(&cycle.stdout);
    assert_eq!(stdout.lines().count(), 3, "{stdout}");
    assert!(
        stdout.starts_with(&format!("{paint}: 451 states, ")),
        "{stdout}"
    );
    let homing = tool(&["verify", paint, "--only", "homing"]);
    assert_eq!(homing.status.code(), Some(0), "{}", text(&homing.stderr));
    let stdout = text(&homing.stdout);
    assert_eq!(stdout.lines().count(), 3, "{stdout}");
    assert!(
        stdout.starts_with(&format!("{paint}: homing \"VC- HC- RC- GR-\" from 81 ")),
        "{stdout}"
    );
    // A robot of explicit charts has no homing: it says so.
    let charts = tool(&[
        "verify",
        "robot-configs/paint-robot-paper-charts.ron",
        "--only",
        "homing",
    ]);
    assert_eq!(charts.status.code(), Some(0));
    assert_eq!(
        text(&charts.stdout),
        "robot-configs/paint-robot-paper-charts.ron: assumes a prompt radio \
         (`assume_prompt_radio`); --any-delay explores without it\n\
         robot-configs/paint-robot-paper-charts.ron: no homing to prove (its charts take no \
         HOME command)\n"
    );
}

/// `--max-states N` stops both searches at N states, homing's start positions included
/// (they were all taken first: 109 states for `--max-states 2`), and says INCOMPLETE.
#[test]
fn verify_stops_at_max_states_even_among_the_start_positions() {
    let out = tool(&[
        "verify",
        "robot-configs/paint-robot.ron",
        "--max-states",
        "2",
    ]);
    let stdout = text(&out.stdout);
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 6, "{stdout}");
    assert!(
        lines[0].starts_with("robot-configs/paint-robot.ron: 2 states, "),
        "{stdout}"
    );
    assert_eq!(lines[2], "INCOMPLETE: stopped after 2 states");
    assert!(
        lines[3].starts_with(
            "robot-configs/paint-robot.ron: homing \"VC- HC- RC- GR-\" from 81 start positions \
             x 2 held valve levels: 2 states, 0 transitions in "
        ),
        "{stdout}"
    );
    assert_eq!(lines[5], "INCOMPLETE: stopped after 2 states");
    assert_ne!(out.status.code(), Some(0));
}

#[test]
fn verify_prints_a_numbered_counterexample_and_exits_1() {
    let out = tool(&["verify", "tests/fixtures/verify/order-deadlock.ron"]);
    assert_eq!(out.status.code(), Some(1));
    let stdout = text(&out.stdout);
    assert!(stdout
        .contains("FAILED deadlock freedom: from here the machine can never get back to idle"));
    assert!(
        stdout.contains("shortest counterexample (4 steps):\n  1. operator presses START (at X)\n")
    );
}

#[test]
fn sim_fault_reports_the_detection_and_exits_0_when_everything_stopped() {
    let out = tool(&[
        "sim",
        "robot-configs/paint-robot.ron",
        "--fault",
        "stuck:HC@4",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(stdout.starts_with(
        "fault: HC jammed at 454 ms (cycle 1, before step 4 HC+)\nsteps until then: VC+ GR+ VC-\n\
         detected at 2706 ms by HC: motion watchdog (fault 1), 2000 ms after HC+ was commanded\n"
    ), "{stdout}");
    // Jammed before an earlier step: the watchdog's time is still its motion's, HC+ (it
    // said `2706 ms after step 1 was commanded`, the step the jam came before).
    let out = tool(&[
        "sim",
        "robot-configs/paint-robot.ron",
        "--fault",
        "stuck:HC@4.1",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(
        stdout.contains(
            "\ndetected at 14610 ms by HC: motion watchdog (fault 1), 2000 ms after HC+ was \
             commanded\n"
        ),
        "{stdout}"
    );
    let bad = tool(&[
        "sim",
        "robot-configs/paint-robot.ron",
        "--fault",
        "stuck:HC",
    ]);
    // Bad arguments, said before anything runs: status 2, as an unknown --role (it was 1).
    assert_eq!(bad.status.code(), Some(2));
    assert!(text(&bad.stderr).starts_with("error: `stuck:HC`: no `@STEP`"));
    for (command, spec, said) in [
        ("sim", "stuck:XX@4", "no moving actuator `XX`"),
        (
            "sim",
            "link:VC->VC@2",
            "`link:VC->VC@2`: a link joins two roles, not `VC` with itself",
        ),
        (
            "sim",
            "stuck:HC@40",
            "the cycle has 12 steps: there is no step 40",
        ),
        ("demo", "stuck:XX@3", "no moving actuator `XX`"),
    ] {
        let bad = tool(&[command, "robot-configs/paint-robot.ron", "--fault", spec]);
        assert_eq!(
            (bad.status.code(), text(&bad.stdout), text(&bad.stderr)),
            (Some(2), String::new(), format!("error: {said}\n")),
            "{command} {spec}"
        );
    }
}

/// A variant of the paint robot, `from` replaced by `to`, written under the test's
/// temporary directory as `name`.
fn paint_variant(name: &str, from: &str, to: &str) -> String {
    let text = std::fs::read_to_string("../robot-configs/paint-robot.ron").expect("robot");
    assert!(text.contains(from), "{from}");
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::write(&path, text.replace(from, to)).expect("written");
    path.to_str().expect("utf-8").to_string()
}

/// `sim` runs as long as the robot's declared times need, past its ten minutes of virtual
/// time per cycle. Found: a 600 s watchdog's fault was reported with its peers still
/// running (their faults came after the bound), status 0; a dwell of 2^32 - 1 ms ended the
/// run with `not idle at the time limit (402 ms)`.
#[test]
fn sim_runs_as_long_as_the_declared_times_need() {
    let slow = paint_variant(
        "watchdog-600s.ron",
        "motion_timeout_ms: 2000",
        "motion_timeout_ms: 600000",
    );
    let out = tool(&["sim", &slow, "--fault", "stuck:HC@4"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    for said in [
        "detected at 600706 ms by HC: motion watchdog (fault 1), 600000 ms after HC+ was \
         commanded\n",
        "  at 600708 ms  VC: a peer's fault (fault 2)\n",
        "  at 600708 ms  GR: a peer's fault (fault 2)\n",
        "  at 600708 ms  RC: a peer's fault (fault 2)\n",
    ] {
        assert!(stdout.contains(said), "{said}\n{stdout}");
    }
    let long = paint_variant("dwell-max.ron", "dwell_ms: 150", "dwell_ms: 4294967295");
    let out = tool(&["sim", &long, "--cycles", "1"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).contains("ok: 1 cycle(s), each 12 step(s) as declared"),
        "{}",
        text(&out.stdout)
    );
}

/// A switch fault names a switch the machine has: one it lacks is said to be missing, and
/// what a motor drives has switches too. Found: `switch:GR.end` said "a switch is ACT.end
/// or ACT.home", `switch:BELT.end` said "`BELT` has no switches" (it declares both).
#[test]
fn sim_fault_on_a_switch_says_which_switch_is_missing() {
    let sim = |robot: &str, fault: &str| {
        let out = tool(&["sim", robot, "--fault", fault]);
        (out.status.code(), text(&out.stdout), text(&out.stderr))
    };
    let paint = "robot-configs/paint-robot.ron";
    let (code, _, err) = sim(paint, "switch:GR.end@2");
    assert_eq!(code, Some(2));
    assert_eq!(err, "error: `GR` has no end switch (its switches: none)\n");
    let (code, _, err) = sim(paint, "switch:VC.top@2");
    assert_eq!(code, Some(2));
    assert_eq!(err, "error: `VC.top`: a switch is ACT.end or ACT.home\n");
    let (code, out, err) = sim("robot-configs/waterjet-transport.ron", "switch:BELT.end@1");
    assert_eq!(code, Some(1), "{err}");
    assert!(
        out.starts_with(
            "fault: switch BELT.end broken (stays open) at 0 ms (cycle 1, before step 1 \
             PUSHER+)\nsteps until then: none\n"
        ),
        "{out}"
    );
}

/// `sim` checks the robot's interlocks (`never:`) after every event it simulates: a
/// sequence that moves HC while VC is out fails, at the moment it happens. Found: `sim`
/// said ok while `verify` found the interlock broken.
#[test]
fn sim_fails_a_cycle_that_breaks_an_interlock() {
    let broken = paint_variant(
        "interlock-broken.ron",
        "sequence: \"VC+ GR+ VC- HC+ VC+ VC- RC+ RC- HC- VC+ GR- VC-\"",
        "sequence: \"VC+ HC+ VC- HC-\"",
    );
    let out = tool(&["sim", &broken, "--cycles", "2"]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stderr));
    assert_eq!(
        text(&out.stdout),
        "cycle   1:   2158 ms   4 publications  VC+ HC+ VC- HC-\n  \
         INTERLOCK at 302 ms: never: \"HC.moving && !VC.home\" holds\n\
         FAILED: 1 of 1 cycle(s) went wrong: an interlock broken\n"
    );
}

/// A robot without a declared sequence (`expect`) says what `sim` did check, not "each 0
/// step(s) as declared".
#[test]
fn sim_without_a_declared_sequence_says_what_it_checked() {
    let out = tool(&[
        "sim",
        "robot-configs/waterjet-transport.ron",
        "--cycles",
        "1",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).ends_with(
            "no expected sequence declared (`expect`): nothing compared\n\
             ok: 1 cycle(s), no fault, no interlock broken\n"
        ),
        "{}",
        text(&out.stdout)
    );
}

#[test]
fn sim_timeline_writes_an_svg() {
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("timeline.svg");
    let _ = std::fs::remove_file(&path);
    let out = tool(&[
        "sim",
        "robot-configs/paint-robot.ron",
        "--cycles",
        "1",
        "--timeline",
        path.to_str().expect("utf-8"),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let svg = std::fs::read_to_string(&path).expect("written");
    let doc = roxmltree::Document::parse(&svg).expect("parses");
    let lanes = doc
        .descendants()
        .filter(|n| n.attribute("class") == Some("lane actuator"))
        .count();
    assert_eq!(lanes, 4);
}

/// `sim --timeline` naming the robot file itself (however written) or a file it imports is
/// refused before anything runs, and the file is left as it was. Found: the robot file was
/// replaced by the SVG, status 0.
#[test]
fn sim_timeline_never_overwrites_the_robot_or_what_it_imports() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("timeline-self");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    let robot = dir.join("paint.ron");
    let original = std::fs::read_to_string("../robot-configs/paint-robot.ron").expect("robot");
    std::fs::write(&robot, &original).expect("copy");
    let robot_arg = robot.to_str().expect("utf-8");
    let same = dir.join(".").join("paint.ron");
    for out in [robot_arg, same.to_str().expect("utf-8")] {
        let run = tool(&["sim", robot_arg, "--cycles", "1", "--timeline", out]);
        assert_eq!(run.status.code(), Some(2));
        assert_eq!(
            text(&run.stderr),
            format!(
                "error: --timeline {out}: that is {robot_arg}, which this command reads: it \
                 would be overwritten\n"
            )
        );
        assert_eq!(std::fs::read_to_string(&robot).expect("robot"), original);
    }
    // A 4diac robot's imported type.
    let fbt = "robot-configs/4diac/paint-robot/Vc.fbt";
    let before = std::fs::read("../".to_string() + fbt).expect("fbt");
    let run = tool(&[
        "sim",
        "robot-configs/paint-robot-4diac.ron",
        "--timeline",
        fbt,
    ]);
    assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
    assert!(text(&run.stderr).contains("it would be overwritten"));
    assert_eq!(std::fs::read("../".to_string() + fbt).expect("fbt"), before);
    // An automaton's facts file.
    let facts = "tests/fixtures/fig1.pl";
    let before = std::fs::read("../".to_string() + facts).expect("facts");
    let run = tool(&["sim", "tests/fixtures/automata.ron", "--timeline", facts]);
    assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
    assert_eq!(
        text(&run.stderr),
        "error: --timeline tests/fixtures/fig1.pl: that is tests/fixtures/fig1.pl, which this \
         command reads: it would be overwritten\n"
    );
    assert_eq!(
        std::fs::read("../".to_string() + facts).expect("facts"),
        before
    );
}

/// `sim --timeline` to a named pipe writes the SVG into it (the check that it is no input
/// opens nothing). Found: the check opened the pipe for reading and waited for ever.
#[cfg(unix)]
#[test]
fn sim_timeline_writes_into_a_named_pipe() {
    use std::io::Read;
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("timeline-fifo");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    let fifo = dir.join("t.svg");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo");
    assert!(made.success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || {
            let mut svg = String::new();
            std::fs::File::open(&fifo)
                .expect("opens")
                .read_to_string(&mut svg)
                .expect("reads");
            svg
        })
    };
    let sim = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args([
            "sim",
            "robot-configs/paint-robot.ron",
            "--cycles",
            "1",
            "--timeline",
        ])
        .arg(&fifo)
        .current_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".."))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("runs");
    let pid = sim.id();
    let (done, ended) = std::sync::mpsc::channel();
    std::thread::spawn(move || done.send(sim.wait_with_output()));
    // A hang is a failure, not a test that never ends.
    let Ok(run) = ended.recv_timeout(std::time::Duration::from_secs(60)) else {
        let _ = Command::new("kill").arg("-9").arg(pid.to_string()).status();
        let _ = std::fs::OpenOptions::new().write(true).open(&fifo);
        panic!("sim --timeline on a named pipe did not end");
    };
    let run = run.expect("waits");
    assert_eq!(run.status.code(), Some(0), "{}", text(&run.stderr));
    assert!(reader.join().expect("reader").starts_with("<svg"));
}

#[test]
fn verify_passes_every_robot_of_robot_configs_as_declared() {
    let mut files: Vec<String> =
        std::fs::read_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../robot-configs"))
            .expect("robot-configs")
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|f| f.ends_with(".ron"))
            .collect();
    files.sort();
    assert_eq!(files.len(), 9, "{files:?}");
    for f in &files {
        let out = tool(&["verify", &format!("robot-configs/{f}")]);
        assert_eq!(out.status.code(), Some(0), "{f}: {}", text(&out.stdout));
        let stdout = text(&out.stdout);
        // The robots that count shared position events say which assumption they rest on.
        let assumes = f.contains("paper-charts")
            || f.contains("4diac")
            || f.contains("counted")
            || f.contains("waterjet");
        assert_eq!(
            stdout.contains("assumes a prompt radio (`assume_prompt_radio`)"),
            assumes,
            "{f}: {stdout}"
        );
        assert_eq!(stdout.contains(", prompt radio"), assumes, "{f}: {stdout}");
    }
}

#[test]
fn any_delay_drops_the_declared_assumption_and_finds_the_race() {
    let out = tool(&[
        "verify",
        "robot-configs/paint-robot-paper-charts.ron",
        "--any-delay",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let stdout = text(&out.stdout);
    assert!(!stdout.contains("assumes a prompt radio"), "{stdout}");
    assert!(
        stdout
            .contains("FAILED deadlock freedom: from here the machine can never get back to idle"),
        "{stdout}"
    );
    let both = tool(&[
        "verify",
        "robot-configs/paint-robot.ron",
        "--any-delay",
        "--prompt",
    ]);
    assert_eq!(
        both.status.code(),
        Some(2),
        "clap refuses the contradiction"
    );
}

#[test]
fn verify_faults_sets_the_fault_pulses_explored_and_refuses_a_count_out_of_range() {
    let out = tool(&[
        "verify",
        "robot-configs/waterjet-transport.ron",
        "--faults",
        "1",
    ]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{stdout}");
    assert!(
        stdout.contains("switch FAULT set once and released, each at any time"),
        "{stdout}"
    );
    assert!(
        stdout.contains("robot-configs/waterjet-transport.ron: 1110 states, 4391 transitions"),
        "{stdout}"
    );
    for bad in ["0", "9", "two"] {
        let out = tool(&[
            "verify",
            "robot-configs/waterjet-transport.ron",
            "--faults",
            bad,
        ]);
        assert_eq!(out.status.code(), Some(2));
        let stderr = text(&out.stderr);
        assert!(
            stderr.contains(&format!(
                "invalid value '{bad}' for '--faults <FAULTS>': a number of fault pulses from 1 to 8"
            )),
            "{stderr}"
        );
    }
}

/// The paint robot exported to IEC 61499 and brought back (its charts from the `.sys` and
/// `.fbt` files, its sequence only what sim compares with): VC still takes the HOME
/// command, but no homing sequence is declared to prove it against. It said `its charts
/// take no HOME command`.
#[test]
fn a_robot_that_takes_home_without_a_declared_homing_says_so() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = std::env::temp_dir().join(format!("verify-imported-home-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let exported = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["export-4diac", "robot-configs/paint-robot.ron", "--out"])
        .arg(dir.join("x"))
        .current_dir(&root)
        .output()
        .expect("runs");
    assert_eq!(
        exported.status.code(),
        Some(0),
        "{}",
        text(&exported.stderr)
    );
    let mut types: Vec<String> = std::fs::read_dir(dir.join("x"))
        .expect("exported")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".fbt"))
        .map(|n| format!("\"x/{n}\""))
        .collect();
    types.sort();
    let robot = std::fs::read_to_string(root.join("robot-configs/paint-robot.ron"))
        .expect("robot")
        .replace("sequence:", "expect:");
    let close = robot.rfind(')').expect("the robot's end");
    let robot = format!(
        "{}    fb_types: [{}],\n    application: (file: \"x/paint_robot.sys\"),\n{}",
        &robot[..close],
        types.join(", "),
        &robot[close..]
    );
    std::fs::write(dir.join("robot.ron"), robot).expect("written");
    let out = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["verify", "robot.ron", "--only", "homing"])
        .current_dir(&dir)
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).ends_with(
            "robot.ron: no homing to prove: role VC takes the HOME command, but the robot \
             declares no homing sequence (`homing:`) to prove it against\n"
        ),
        "{}",
        text(&out.stdout)
    );
    let _ = std::fs::remove_dir_all(&dir);
}
