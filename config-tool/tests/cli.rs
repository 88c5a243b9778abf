//! The `config-tool` binary: command names, outputs and exit statuses that scripts rely on.

use std::path::PathBuf;
use std::process::{Command, Output};

fn tool(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("runs")
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn check_accepts_a_good_robot_and_rejects_a_broken_one_with_status_1() {
    let ok = tool(&["check", "robot-configs/paint-robot.ron"]);
    assert!(ok.status.success());
    assert_eq!(
        text(&ok.stdout),
        "homing: VC- HC- RC- GR- (derived from the actuators and interlocks; HOME goes to role \
         VC)\n\
         VC           worst stimulus  13980 instructions (21% of 64000): `VC.watchdog`, 2 event(s)\n\
         GR           worst stimulus  10510 instructions (16% of 64000): `GR.dwell`, 3 event(s)\n\
         HC           worst stimulus  13860 instructions (21% of 64000): `HC.watchdog`, 2 event(s)\n\
         RC           worst stimulus  13840 instructions (21% of 64000): `RC.watchdog`, 2 event(s)\n\
         robot-configs/paint-robot.ron: ok\n"
    );
    // The sensorless gripper's two steps are warned of (a jam goes undetected).
    assert!(
        text(&ok.stderr).ends_with("robot-configs/paint-robot.ron: 0 error(s), 2 warning(s)\n"),
        "{}",
        text(&ok.stderr)
    );

    let bad = tool(&["check", "tests/fixtures/broken/role-twice.ron"]);
    assert_eq!(bad.status.code(), Some(1));
    let err = text(&bad.stderr);
    assert!(err.contains("duplicate assignment of role `A`"), "{err}");
    assert!(err.contains("duplicate use of node `n2`"), "{err}");
    assert!(
        err.contains("[tests/fixtures/broken/role-twice.ron:9:41]"),
        "{err}"
    );
    assert!(
        err.ends_with("tests/fixtures/broken/role-twice.ron: 2 error(s), 0 warning(s)\n"),
        "{err}"
    );
}

/// A guard a node cannot evaluate (11 values on its 8-deep stack) is `check`'s error at the
/// guard. `check` said ok, and `compile` then refused the table at `Robot(`.
#[test]
fn check_refuses_a_guard_too_deep_for_a_node_at_the_guard() {
    let robot = "tests/fixtures/broken/guard-too-deep.ron";
    let dir = scratch("guard-too-deep");
    let dir = dir.to_str().expect("a UTF-8 path");
    for (command, args) in [
        ("check", vec!["check", robot]),
        ("compile", vec!["compile", robot, "--out", dir]),
    ] {
        let out = tool(&args);
        assert_eq!(out.status.code(), Some(1), "{command}");
        assert_eq!(text(&out.stdout), "", "{command}");
        let err = text(&out.stderr);
        assert!(
            err.contains("this expression needs 11 values on the stack at once"),
            "{command}: {err}"
        );
        assert!(
            err.contains("[tests/fixtures/broken/guard-too-deep.ron:36:60]"),
            "{command}: {err}"
        );
        assert!(
            err.ends_with(": 1 error(s), 0 warning(s)\n"),
            "{command}: {err}"
        );
    }
}

/// `push --wait 0` and `rollback --wait 0` are usage errors, as `home --wait 0` is: a
/// push waited 0 ms for the idle point and said the machine was not idle, status 3, naming
/// no node, on a machine at rest.
#[test]
fn push_and_rollback_refuse_a_wait_of_0() {
    for command in ["push", "rollback"] {
        let out = tool(&[command, "robot-configs/paint-robot.ron", "--wait", "0"]);
        assert_eq!(out.status.code(), Some(2), "{command}");
        let err = text(&out.stderr);
        assert!(
            err.contains(
                "invalid value '0' for '--wait <WAIT>': a whole number of seconds from 1 (the \
                 nodes are asked first; --now switches at once)"
            ),
            "{command}: {err}"
        );
    }
}

#[test]
fn check_reports_warnings_but_succeeds() {
    let out = tool(&["check", "tests/fixtures/broken/unreachable-state.ron"]);
    assert!(out.status.success());
    let err = text(&out.stderr);
    assert!(
        err.contains("state `DONE` of chart type `Follower` is unreachable"),
        "{err}"
    );
    assert!(err.ends_with("0 error(s), 1 warning(s)\n"), "{err}");
}

#[test]
fn compile_writes_one_blob_per_role_and_a_summary_line_each() {
    let dir = scratch("compile");
    let out = tool(&[
        "compile",
        "robot-configs/paint-robot.ron",
        "--out",
        dir.to_str().expect("utf-8"),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    let lines: Vec<&str> = stdout.lines().collect();
    for (i, role) in ["VC", "GR", "HC", "RC"].iter().enumerate() {
        let blob = std::fs::read(dir.join(format!("{role}.bin"))).expect("blob written");
        assert!(
            lines[i].starts_with(&format!("{role:<12} node 0x001{}", i + 1)),
            "{}",
            lines[i]
        );
        let frames = match blob.len().div_ceil(88) {
            1 => "one frame".to_string(),
            n => format!("{n} frames"),
        };
        assert!(
            lines[i].ends_with(&format!("bytes {:>4} of 88: {frames}", blob.len())),
            "{}",
            lines[i]
        );
        // Every role fits one frame's chunk (docs/table-format.md, "Size").
        assert!(blob.len() <= 88, "{}", lines[i]);
    }
    assert_eq!(lines[4], "radio publications per cycle: 9");

    let out = tool(&[
        "compile",
        "robot-configs/paint-robot.ron",
        "--out",
        dir.to_str().expect("utf-8"),
        "--generation",
        "7",
    ]);
    assert!(out.status.success());
    let blob = std::fs::read(dir.join("VC.bin")).expect("blob");
    assert_eq!(config_schema::decode(&blob).expect("decodes").generation, 7);
}

#[test]
fn compile_writes_every_blob_or_none() {
    let dir = scratch("compile-none");
    std::fs::create_dir_all(dir.join("RC.bin")).expect("a directory where RC's blob goes");
    let out = tool(&[
        "compile",
        "robot-configs/paint-robot.ron",
        "--out",
        dir.to_str().expect("utf-8"),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let rc = dir.join("RC.bin");
    let want = format!(
        "error: {}: exists and is not a file: nothing written\n",
        rc.display()
    );
    assert!(text(&out.stderr).ends_with(&want), "{}", text(&out.stderr));
    let mut left: Vec<String> = std::fs::read_dir(&dir)
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["RC.bin"], "no other blob written");
}

#[test]
fn dump_prints_a_blob_and_fails_clearly_on_a_bad_one() {
    let dir = scratch("dump");
    let out = tool(&[
        "compile",
        "robot-configs/paint-robot.ron",
        "--out",
        dir.to_str().expect("utf-8"),
    ]);
    assert!(out.status.success());
    let gr = dir.join("GR.bin");
    let dump = tool(&["dump", gr.to_str().expect("utf-8")]);
    assert!(dump.status.success());
    assert!(text(&dump.stdout).contains("role GR  generation 0  pan 0x1234  channel 15\n"));

    let mut bytes = std::fs::read(&gr).expect("blob");
    bytes.truncate(bytes.len() - 1);
    let bad = dir.join("bad.bin");
    std::fs::write(&bad, &bytes).expect("write");
    let out = tool(&["dump", bad.to_str().expect("utf-8")]);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(
        err.contains("not a valid table blob: truncated blob:"),
        "{err}"
    );

    // A file larger than any blob is not read to its end: a device that never ends too.
    let big = dir.join("big.bin");
    std::fs::write(&big, vec![0u8; 4097]).expect("write");
    for (path, what) in [
        (big.to_str().expect("utf-8"), "4097 bytes"),
        ("/dev/zero", "endless"),
    ] {
        let out = tool(&["dump", path]);
        assert_eq!(out.status.code(), Some(1), "{what}");
        let want = format!("error: cannot read {path}: larger than 4096 bytes\n");
        assert_eq!(text(&out.stderr), want, "{what}");
    }
    let out = tool(&["check", "/dev/zero"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        text(&out.stderr).ends_with("cannot read /dev/zero: larger than 8388608 bytes\n"),
        "{}",
        text(&out.stderr)
    );
}

/// A sorting station's `sim` sorts its feed: each ball's colour, the automata that took
/// it, its bin and every EOS; `--feed` replaces the robot's; a bad item names itself.
#[test]
fn sim_of_the_ball_sorter_prints_each_ball_and_its_bin() {
    let out = tool(&[
        "sim",
        "robot-configs/ball-sorter.ron",
        "--feed",
        "G B B O B G",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(
        text(&out.stdout),
        "ball   1: gray     taken by -          bin 3\n\
         ball   2: black    taken by nd, fig1   bin 1\n\
         ball   3: black    taken by nd, fig1   bin 1  EOS fig1\n\
         ball   4: orange   taken by nd, fig1   bin 1  EOS nd\n\
         ball   5: black    taken by nd, fig1   bin 1\n\
         ball   6: gray     taken by fig1       bin 2\n\
         6 ball(s) in 2808 ms: bin 1: 4, bin 2: 1, bin 3: 1; 2 EOS\n\
         ok\n"
    );
    let out = tool(&["verify", "robot-configs/ball-sorter.ron", "--balls", "2"]);
    assert!(out.status.success(), "{}", text(&out.stdout));
    let stdout = text(&out.stdout);
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(
        lines[0],
        "robot-configs/ball-sorter.ron: ball feed: every sequence of up to 2 balls of black, \
         gray, orange (untimed: the next ball is taken to lie at the sensors once the pusher \
         is home; `sim` times its roll)"
    );
    assert!(lines[1].starts_with("robot-configs/ball-sorter.ron: 753 states, 1398 transitions in "));
    assert_eq!(
        lines[3],
        "ok: deadlock freedom, no cycle declared (`expect`) to conform to, 0 interlock(s), no double actuation, no \
         engine fault, a fault stops every node, each ball in exactly one bin, no gate moves \
         while a ball falls past it, the pusher never feeds while a gate moves, selections as \
         the reference semantics"
    );
    let out = tool(&["verify", "robot-configs/ball-sorter.ron", "--balls", "201"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("a number of balls from 1 to 200"));
    // A bad argument: status 2, as an unknown --role (it was 1).
    let out = tool(&["sim", "robot-configs/ball-sorter.ron", "--feed", "B purple"]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(
        text(&out.stderr),
        "error: feed item 2 `purple` is no colour of the sensor table (black, gray, orange)\n"
    );
}

/// `sim --random N --seed S` sorts a seeded random feed: the same seed, the same balls.
#[test]
fn sim_of_the_ball_sorter_takes_a_seeded_random_feed() {
    let run = |seed: &str| {
        let out = tool(&[
            "sim",
            "robot-configs/ball-sorter.ron",
            "--random",
            "20",
            "--seed",
            seed,
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        text(&out.stdout)
    };
    let seven = run("7");
    assert_eq!(seven, run("7"));
    assert_ne!(seven, run("8"));
    let lines: Vec<&str> = seven.lines().collect();
    assert_eq!(lines.len(), 22);
    assert_eq!(
        lines[20],
        "20 ball(s) in 9380 ms: bin 1: 8, bin 2: 9, bin 3: 3; 8 EOS"
    );
    let out = tool(&["sim", "robot-configs/ball-sorter.ron", "--random", "0"]);
    assert_eq!(out.status.code(), Some(2));
    let out = tool(&[
        "sim",
        "robot-configs/ball-sorter.ron",
        "--feed",
        "B",
        "--random",
        "3",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("cannot be used with"),
        "{}",
        text(&out.stderr)
    );
}

/// `sim --timeline` of the station writes its SVG (a lane per gate, sensor and ball)
/// beside the same report; `--fault` is refused, naming what a station's `sim` takes.
#[test]
fn sim_timeline_of_the_ball_sorter_draws_its_lanes() {
    let dir = scratch("sorter-timeline");
    std::fs::create_dir_all(&dir).expect("dir");
    let svg = dir.join("sorter.svg");
    let out = tool(&[
        "sim",
        "robot-configs/ball-sorter.ron",
        "--feed",
        "G B",
        "--timeline",
        svg.to_str().expect("utf-8"),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(
        text(&out.stdout),
        "ball   1: gray     taken by -          bin 3\n\
         ball   2: black    taken by nd, fig1   bin 1\n\
         2 ball(s) in 936 ms: bin 1: 1, bin 2: 0, bin 3: 1; 0 EOS\n\
         ok\n"
    );
    assert_eq!(text(&out.stderr), format!("timeline: {}\n", svg.display()));
    let written = std::fs::read_to_string(&svg).expect("written");
    let doc = roxmltree::Document::parse(&written).expect("parses");
    let lanes = |kind: &str| -> Vec<String> {
        let class = format!("lane {kind}");
        doc.descendants()
            .filter(|n| n.attribute("class") == Some(class.as_str()))
            .map(|n| n.attribute("data-name").unwrap_or("").to_string())
            .collect()
    };
    assert_eq!(lanes("pusher"), ["PUSHER"]);
    assert_eq!(lanes("gate"), ["G1", "G2"]);
    assert_eq!(
        lanes("sensor"),
        ["CAP", "IND", "OPT", "ENTRY", "BIN1", "BIN2", "BIN3"]
    );
    assert_eq!(lanes("ball"), ["ball 1", "ball 2"]);
    let out = tool(&[
        "sim",
        "robot-configs/ball-sorter.ron",
        "--fault",
        "stuck:G1@1",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(
        text(&out.stderr),
        "error: a sorting station's `sim` takes no --fault: it runs its feed (--feed, --random, \
         --trace, --timeline)\n"
    );
}

#[test]
fn sim_refuses_arguments_it_cannot_honour() {
    let sim = |args: &[&str]| {
        let out = tool(&[&["sim", "robot-configs/paint-robot.ron"], args].concat());
        (out.status.code(), text(&out.stderr))
    };
    for cycles in ["0", "10001", "99999999999", "x"] {
        let (code, err) = sim(&["--cycles", cycles]);
        assert_eq!(code, Some(2), "{cycles}");
        assert!(
            err.contains(&format!(
                "invalid value '{cycles}' for '--cycles <CYCLES>': a number of cycles from 1 to 10000"
            )),
            "{err}"
        );
    }
    let (code, err) = sim(&["--fault", "stuck:HC@4294967296.1"]);
    assert_eq!(code, Some(2));
    assert_eq!(
        err,
        "error: `stuck:HC@4294967296.1`: `4294967296` is not a step or cycle number (1 to 10000)\n"
    );
    for args in [&["--feed", "B"][..], &["--random", "3"]] {
        let (code, err) = sim(args);
        assert_eq!(code, Some(2), "{args:?}");
        assert_eq!(
            err,
            "error: --feed and --random are a sorting station's: robot-configs/paint-robot.ron \
             has no `sorting:`\n"
        );
    }
}

#[test]
fn sim_prints_each_cycle_and_fails_on_a_sequence_that_differs() {
    let out = tool(&["sim", "robot-configs/paint-robot.ron", "--cycles", "2"]);
    assert!(out.status.success());
    assert_eq!(
        text(&out.stdout),
        "cycle   1:   3968 ms   9 publications  VC+ GR+ VC- HC+ VC+ VC- RC+ RC- HC- VC+ GR- VC-\n\
         cycle   2:   3968 ms   9 publications  VC+ GR+ VC- HC+ VC+ VC- RC+ RC- HC- VC+ GR- VC-\n\
         ok: 2 cycle(s), each 12 step(s) as declared\n"
    );
    let dir = scratch("sim");
    std::fs::create_dir_all(&dir).expect("dir");
    let robot =
        std::fs::read_to_string(root().join("tests/fixtures/small-charts.ron")).expect("read");
    let wrong = dir.join("wrong.ron");
    std::fs::write(
        &wrong,
        robot.replace("expect: \"A+ B+ B- A-\"", "expect: \"A+ B+ A- B-\""),
    )
    .expect("write");
    let out = tool(&["sim", wrong.to_str().expect("utf-8"), "--cycles", "3"]);
    assert_eq!(out.status.code(), Some(1));
    let stdout = text(&out.stdout);
    assert!(
        stdout.contains("     3  A-        B-        <-- differs\n"),
        "{stdout}"
    );
}

#[test]
fn diagram_prints_dot_and_rejects_an_unknown_role() {
    let out = tool(&["diagram", "robot-configs/paint-robot.ron", "--role", "GR"]);
    assert!(out.status.success());
    let dot = text(&out.stdout);
    assert!(dot.starts_with("digraph \"GR\" {\n"), "{dot}");
    assert!(dot.contains("c0s1 -> c0s2 [label=\"dwell\"];"), "{dot}");
    // An unknown role is a bad argument: status 2, as every other (it was 1), for
    // `diagram` and `push` alike (`push` checks it before anything is sent).
    for args in [
        &["diagram", "robot-configs/paint-robot.ron", "--role", "XX"][..],
        &[
            "push",
            "robot-configs/paint-robot.ron",
            "--role",
            "XX",
            "--medium",
            "127.0.0.1:1",
        ],
    ] {
        let out = tool(args);
        assert_eq!(
            (out.status.code(), text(&out.stderr).as_str()),
            (
                Some(2),
                "error: robot-configs/paint-robot.ron: unknown role `XX` (roles: VC, GR, HC, RC)\n"
            ),
            "{args:?}"
        );
    }
}

/// `push --role VC --node 0x0015` switched VC onto the spare and said `switched: VC's node
/// runs generation 2`, but VC's peers still talk to 0x0011: nothing reached the spare, and
/// with 0x0011 gone the machine could not be homed. A role with peers is refused on
/// another node, before anything is sent (status 2), saying how to move it; at its own
/// address `--node` changes nothing.
#[test]
fn push_refuses_a_role_with_peers_on_another_node_than_the_robot_assigns() {
    let out = tool(&[
        "push",
        "robot-configs/paint-robot.ron",
        "--role",
        "VC",
        "--node",
        "0x0015",
        "--medium",
        "127.0.0.1:1",
    ]);
    assert_eq!(
        (out.status.code(), text(&out.stderr).as_str()),
        (
            Some(2),
            "error: robot-configs/paint-robot.ron: role VC talks with its peers (0x0012, \
             0x0013, 0x0014) at 0x0011, its node in the robot: on 0x0015 it would hear \
             none of them, nor they it; to move VC there, assign it to that node in the \
             robot (`assign`) and push every role\n"
        )
    );
}

#[test]
fn diagram_svg_says_clearly_when_graphviz_is_missing() {
    let out = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args([
            "diagram",
            "robot-configs/paint-robot.ron",
            "--role",
            "GR",
            "--format",
            "svg",
        ])
        .current_dir(root())
        .env("PATH", "")
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(
        err.starts_with("error: cannot run Graphviz `dot` ("),
        "{err}"
    );
    assert!(
        err.ends_with("): install graphviz, or use `--format dot` and render it elsewhere\n"),
        "{err}"
    );
}

/// With Graphviz installed, `--format svg` renders the chart. CI installs Graphviz and sets
/// `REQUIRE_GRAPHVIZ=1`, so there a missing `dot` fails instead of skipping.
#[test]
fn diagram_svg_renders_through_graphviz() {
    let have = Command::new("dot")
        .arg("-V")
        .output()
        .is_ok_and(|o| o.status.success());
    if !have {
        assert!(
            std::env::var_os("REQUIRE_GRAPHVIZ").is_none(),
            "REQUIRE_GRAPHVIZ is set but Graphviz is not installed"
        );
        eprintln!("Graphviz not installed: skipped");
        return;
    }
    // A colour named with a double quote: its label in the automaton's FB network was
    // written unescaped, and Graphviz refused the DOT.
    for (robot, role, shown) in [
        ("robot-configs/paint-robot.ron", "GR", "dwell"),
        (
            "tests/fixtures/sorter-quoted-colour.ron",
            "GATE1",
            "C=bl&quot;ack T=1",
        ),
    ] {
        let out = tool(&["diagram", robot, "--role", role, "--format", "svg"]);
        assert_eq!(out.status.code(), Some(0), "{robot}: {}", text(&out.stderr));
        let svg = text(&out.stdout);
        assert!(svg.contains("<svg"), "{svg}");
        assert!(svg.trim_end().ends_with("</svg>"), "{svg}");
        // The states and the transition labels made it into the picture.
        assert!(svg.contains(shown), "{robot}: {svg}");
    }
}

/// `matrix` prints each control function's M, F, m(0), x and u (`--csv`: as CSV); an
/// unknown function or a robot without functions is a usage error (status 2); `check`
/// says which place changes cross the radio and the delay they imply.
#[test]
fn matrix_prints_the_papers_objects_and_check_names_the_publications() {
    let out = tool(&[
        "matrix",
        "tests/fixtures/petri.ron",
        "--function",
        "Transport",
        "--csv",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let csv = text(&out.stdout);
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 12);
    assert_eq!(
        lines[0],
        "function,object,row,x,u,ReadyToCut,Step1,Step2,Step3"
    );
    assert_eq!(lines[11], "Transport,m(0),,,,1,0,0,0");
    let out = tool(&["matrix", "tests/fixtures/petri.ron"]);
    assert!(out.status.success());
    let all = text(&out.stdout);
    assert!(
        all.starts_with("function Transport on role CELL: 4 places, 5 transitions\n"),
        "{all}"
    );
    assert!(
        all.contains("\nfunction Pusher on role CELL: 3 places, 6 transitions\n"),
        "{all}"
    );
    let out = tool(&["matrix", "tests/fixtures/petri.ron", "--function", "Nope"]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(
        text(&out.stderr),
        "error: tests/fixtures/petri.ron: no function `Nope` (functions: Transport, Pusher)\n"
    );
    let out = tool(&["matrix", "robot-configs/paint-robot.ron"]);
    assert_eq!(out.status.code(), Some(2));
    // A function asked of a robot without any said `(functions: )`.
    let out = tool(&["matrix", "robot-configs/paint-robot.ron", "--function", "F"]);
    assert_eq!(
        (out.status.code(), text(&out.stderr).as_str()),
        (
            Some(2),
            "error: robot-configs/paint-robot.ron: no function `F`: the robot declares no \
             `functions`\n"
        )
    );
    let out = tool(&["matrix", "tests/fixtures/broken/petri-row.ron"]);
    assert_eq!(out.status.code(), Some(1));

    let out = tool(&["check", "tests/fixtures/petri-two-roles.ron"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(
        text(&out.stdout),
        "function Transport (role CELL) publishes Transport.Step1, Transport.Step3 to role PUSHER \
         (events Transport.Step1, Transport.Step3): one radio hop later: 2.47 ms of airtime (at \
         most 8.2 ms on host processes)\nfunction Pusher (role PUSHER) publishes Pusher.Stopped, \
         Pusher.Clockwise, Pusher.CounterClockwise to role CELL (conditions read Pusher.Stopped; \
         events Pusher.Stopped, Pusher.Clockwise): one radio hop later: 2.47 ms of airtime (at \
         most 8.2 ms on host processes)\n\
         CELL         worst stimulus   6150 instructions ( 9% of 64000): `START`, 2 event(s)\n\
         PUSHER       worst stimulus   6210 instructions ( 9% of 64000): `RELEASE`, 2 event(s)\n\
         tests/fixtures/petri-two-roles.ron: ok\n"
    );
}

/// What `compile` prints of each role (`VC node 0x0011 charts 3 states 19 ... bytes 88 of
/// 88: one frame`): role -> (charts, states, transitions, stimulus, bytes, frames).
fn compiled_figures(robot: &str, tag: &str) -> Vec<(String, [String; 6])> {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(tag);
    let out = tool(&["compile", robot, "--out", dir.to_str().expect("utf-8")]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    text(&out.stdout)
        .lines()
        .filter(|l| l.contains(" charts ") && l.contains(" bytes "))
        .map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            let after = |key: &str| {
                let i = w.iter().position(|x| *x == key).expect(key);
                w[i + 1].trim_end_matches(':').to_string()
            };
            let frames = if l.ends_with("one frame") {
                "1".to_string()
            } else {
                l.rsplit(": ")
                    .next()
                    .expect("frames")
                    .split(' ')
                    .next()
                    .expect("n")
                    .to_string()
            };
            (
                w[0].to_string(),
                [
                    after("charts"),
                    after("states"),
                    after("transitions"),
                    after("stimulus"),
                    after("bytes"),
                    frames,
                ],
            )
        })
        .collect()
}

/// The paint robot's figures the docs give are the ones `compile` prints. Found: the docs
/// said VC was 113 bytes in two frames, the others 64 / 78 / 74, while `compile` said 88
/// (one frame), 53, 63 and 59.
#[test]
fn the_docs_give_the_paint_robot_s_figures_as_compile_prints_them() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let doc = std::fs::read_to_string(root.join("docs/config-tool.md")).expect("doc");
    let section = doc
        .split("## Figures (paint robot)")
        .nth(1)
        .expect("the figures section");
    let rows: Vec<(String, [String; 6])> = section
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| role"))
        .take_while(|l| l.matches('|').count() == 8)
        .map(|l| {
            let c: Vec<String> = l
                .split('|')
                .map(|c| c.trim().replace(',', ""))
                .filter(|c| !c.is_empty())
                .collect();
            (
                c[0].clone(),
                [
                    c[1].clone(),
                    c[2].clone(),
                    c[3].clone(),
                    c[4].clone(),
                    c[5].clone(),
                    c[6].clone(),
                ],
            )
        })
        .collect();
    assert_eq!(
        rows,
        compiled_figures("robot-configs/paint-robot.ron", "figures-paint")
    );
    let paper = compiled_figures(
        "robot-configs/paint-robot-paper-charts.ron",
        "figures-paper",
    );
    let bytes: Vec<&str> = paper.iter().map(|(_, f)| f[4].as_str()).collect();
    let said = format!(
        "(`paint-robot-paper-charts.ron`, no watchdog, no homing) are {}\nbytes",
        bytes.join(" / ")
    );
    assert!(section.contains(&said), "{said}");
    let format_doc = std::fs::read_to_string(root.join("docs/robot-format.md")).expect("doc");
    let vc = &compiled_figures("robot-configs/paint-robot.ron", "figures-paint")[0].1;
    let frames = if vc[5] == "1" { "one frame" } else { "frames" };
    let said = format!(
        "paint robot's VC table is {} bytes, {frames} of chunk data",
        vc[4]
    );
    assert!(format_doc.replace('\n', " ").contains(&said), "{said}");
}

/// Arguments the robot cannot use are refused (status 2) instead of ignored: `verify
/// --balls` of a robot without `sorting:`, `--faults` of one without fault contacts, a
/// sorting station's `sim --cycles`, an empty `--feed`, `--balls 0`. Found: all accepted,
/// `--balls 0` saying "each ball in exactly one bin" of no ball.
#[test]
fn arguments_the_robot_cannot_use_are_refused() {
    let paint = "robot-configs/paint-robot.ron";
    let sorter = "robot-configs/ball-sorter.ron";
    let cases: [(&[&str], &str); 7] = [
        (
            &["verify", paint, "--balls", "3"],
            "error: --balls is a sorting station's: robot-configs/paint-robot.ron has no \
             `sorting:`",
        ),
        (
            &["verify", paint, "--faults", "3"],
            "error: --faults is for declared fault contacts: robot-configs/paint-robot.ron \
             declares none (`plants: [Switch(...)]`)",
        ),
        (
            &["verify", sorter, "--balls", "0"],
            "a number of balls from 1 to 200",
        ),
        (
            &["sim", sorter, "--cycles", "3"],
            "error: a sorting station's `sim` takes no --cycles: it runs its feed",
        ),
        (
            &["sim", sorter, "--fault", "stuck:G1@1"],
            "error: a sorting station's `sim` takes no --fault: it runs its feed",
        ),
        (
            &["sim", sorter, "--feed", " "],
            "error: --feed names no ball",
        ),
        (
            &["sim", paint, "--fault", "stuck:HC@4", "--cycles", "7"],
            "error: --fault runs up to the fault's cycle (`@CYCLE.STEP`): it takes no --cycles",
        ),
    ];
    for (args, said) in cases {
        let out = tool(args);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(said), "{args:?}: {err}");
    }
    // Where they apply, they run.
    let out = tool(&[
        "verify",
        "robot-configs/waterjet-transport.ron",
        "--faults",
        "1",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
}

/// A negative probability is refused as one, not read as an unknown flag. Found: `demo
/// --loss -0.1` said "unexpected argument '-0' found". A probability of 1 (every frame
/// lost: `demo --loss 1` waited 60 s, then said the nodes did not answer) is refused too.
#[test]
fn a_negative_probability_is_refused_as_one() {
    // (Every frame duplicated runs: --dup takes 1.)
    for (args, value, range) in [
        (
            &["demo", "robot-configs/paint-robot.ron", "--loss", "-0.1"][..],
            "-0.1",
            "0 to under 1",
        ),
        (&["medium", "--dup", "-0.1"], "-0.1", "0 to 1"),
        (&["medium", "--dup", "1.5"], "1.5", "0 to 1"),
        (
            &["demo", "robot-configs/paint-robot.ron", "--loss", "1"],
            "1",
            "0 to under 1",
        ),
        (&["medium", "--corrupt", "1.0"], "1.0", "0 to under 1"),
    ] {
        let out = tool(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let flag = args[args.len() - 2];
        assert!(
            text(&out.stderr).starts_with(&format!(
                "error: invalid value '{value}' for '{flag} <{}>': `{value}` is not a probability \
                 from {range}",
                flag.trim_start_matches('-').to_uppercase()
            )),
            "{}",
            text(&out.stderr)
        );
    }
}

/// Arguments no run can honour, refused as such (status 2). Found accepted: `verify
/// --max-states 0` (then `INCOMPLETE: stopped after 0 states`), a node address that is
/// config-tool's own (`keys provision --node 0x0100`, `node --addr 0x0100`), a medium delay
/// of 3 years, `demo --then R2 --no-reconfigure` (the --then ignored).
#[test]
fn arguments_no_run_can_honour_are_refused() {
    for (args, said) in [
        (
            &["verify", "robot-configs/paint-robot.ron", "--max-states", "0"][..],
            "error: invalid value '0' for '--max-states <MAX_STATES>': `0` is not a number from 1 up",
        ),
        (
            &["keys", "provision", "--node", "0x0100", "--keys", "k"],
            "error: invalid value '0x0100' for '--node <NODE>': 0x0100 is not a node address (it \
             is config-tool's own)",
        ),
        (
            &["node", "--addr", "0x100", "--medium", "127.0.0.1:9"],
            "error: invalid value '0x100' for '--addr <ADDR>': 0x0100 is not a node address (it \
             is config-tool's own)",
        ),
        (
            &["medium", "--delay-ms", "0..99999999999"],
            "error: invalid value '0..99999999999' for '--delay-ms <DELAY_MS>': 99999999999 ms is \
             longer than a frame may be held (60000 ms at most)",
        ),
        (
            &[
                "demo",
                "robot-configs/paint-robot.ron",
                "--then",
                "robot-configs/paint-robot.ron",
                "--no-reconfigure",
            ],
            "error: the argument '--then <THEN>' cannot be used with '--no-reconfigure'",
        ),
    ] {
        let out = tool(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(text(&out.stderr).starts_with(said), "{}", text(&out.stderr));
    }
}

/// A pcap the medium cannot write is named in the error. Found: `error: medium on ADDR:
/// Is a directory`.
#[test]
fn a_medium_s_pcap_it_cannot_write_is_named() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("pcap-dir");
    std::fs::create_dir_all(&dir).expect("dir");
    let path = dir.to_str().expect("utf-8");
    let out = tool(&["medium", "--listen", "127.0.0.1:0", "--pcap", path]);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(
        err.starts_with("error: medium on 127.0.0.1:0: pcap ")
            && err.contains(&format!("pcap {path}: Is a directory")),
        "{err}"
    );
}

/// `home` of a robot that has no homing says so and nothing else, before it reaches for
/// the medium. Found: it printed an empty `homing:` line first. Nothing to home is no
/// failure (it exited 1, where `scan` calls every node of such a robot homed).
#[test]
fn home_of_a_robot_without_homing_says_so_first() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("home-none");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    let key = dir.join("machine.key");
    let key = key.to_str().expect("utf-8");
    assert!(tool(&["keys", "new", "--out", key]).status.success());
    let out = tool(&[
        "home",
        "robot-configs/waterjet-transport.ron",
        "--keys",
        key,
        "--medium",
        "127.0.0.1:1",
    ]);
    assert_eq!(
        (out.status.code(), text(&out.stdout), text(&out.stderr)),
        (
            Some(0),
            "nothing to home: robot-configs/waterjet-transport.ron has no homing sequence (its \
             nodes start at rest): start it\n"
                .to_string(),
            String::new()
        )
    );
}

/// `home --wait 0` sent HOME and said at once that homing did not end: a wait of no time
/// is refused as a bad argument, before anything is sent, saying what it takes (it said
/// `0 is not in 1..18446744073709551615`).
#[test]
fn home_refuses_a_wait_of_no_time() {
    let out = tool(&[
        "home",
        "robot-configs/paint-robot.ron",
        "--medium",
        "127.0.0.1:9",
        "--wait",
        "0",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains(
            "invalid value '0' for '--wait <WAIT>': a whole number of seconds from 1 (homing \
             takes time)"
        ),
        "{}",
        text(&out.stderr)
    );
}

/// `--now` and `--wait` are the rollback's: `confirm` took them and ignored them.
#[test]
fn confirm_refuses_the_rollbacks_now_and_wait() {
    for extra in [&["--now"][..], &["--wait", "5"]] {
        let mut args = vec!["confirm", "robot-configs/paint-robot.ron"];
        args.extend(extra);
        let out = tool(&args);
        assert_eq!(out.status.code(), Some(2), "{extra:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.starts_with(&format!("error: unexpected argument '{}'", extra[0])),
            "{err}"
        );
    }
}

/// `start ROBOT --node N`: START goes to the robot's start input, so another node is
/// refused before anything is sent (status 2). It said `0x0013: started`, status 0, for
/// a node whose charts take no START (the machine stayed at rest), and for any address
/// at all.
#[test]
fn start_refuses_a_node_other_than_the_robots_start_node() {
    let robot = "robot-configs/paint-robot.ron";
    for node in ["0x0013", "0x0015", "0x0042"] {
        let out = tool(&["start", robot, "--medium", "127.0.0.1:1", "--node", node]);
        assert_eq!(
            (out.status.code(), text(&out.stderr).trim_end()),
            (
                Some(2),
                format!(
                    "error: --node {node}: the robot's START input is on node 0x0011 \
                     (role VC), where START goes (leave out --node)"
                )
                .as_str()
            ),
            "{node}"
        );
    }
}
