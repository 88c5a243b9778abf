//! The secured machine from the command line, as an operator runs it: `keys new`, each
//! host node provisioned (`keys provision --board host --out`) and started with its key
//! file, then `scan`, `push`, `start` and `status` with `--keys`, each its own run of the
//! tool. An unsecured `start` to the keyed node starts nothing and is counted; a second
//! `push --keys` works only because the tool's frame counter persisted in the counter file
//! (a node refuses a counter it saw before).

mod e2e_support;

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, ChildStdout, Command, Output, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Instant;

use config_schema::wire::mac;
use e2e_support::{idle, robot, Monitor, TempDir, SEQUENCE_1, TIMEOUT};
use robot_net::live_plant;

const ROBOT: &str = "robot-configs/paint-robot.ron";

fn tool(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(args)
        .env_remove("CONFIG_TOOL_KEYS")
        .output()
        .expect("runs")
}

/// `push ROBOT --keys KEY --medium MEDIUM --generation GENERATION`, then `more`.
fn push_args<'a>(
    key: &'a str,
    medium: &'a str,
    generation: &'a str,
    more: &[&'a str],
) -> Vec<&'a str> {
    let mut args = vec!["push", ROBOT, "--keys", key, "--medium", medium];
    args.extend(["--generation", generation]);
    args.extend(more);
    args
}

fn ok(args: &[&str]) -> String {
    let out = tool(args);
    assert!(
        out.status.success(),
        "{args:?}: {}{}",
        text(&out.stdout),
        text(&out.stderr)
    );
    text(&out.stdout)
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The reservations in the tool's counter file, in log order (first sector only: a run
/// writes one, far fewer than the 256 a sector holds here).
fn reservations(counter: &Path) -> Vec<u32> {
    let bytes = std::fs::read(counter).expect("counter file");
    assert_eq!(bytes.len(), 8192);
    let word = |r: &[u8], i: usize| u32::from_le_bytes(r[i..i + 4].try_into().unwrap());
    bytes[..4096]
        .chunks(16)
        .take_while(|r| r.iter().any(|b| *b != 0xFF))
        .map(|r| {
            assert_eq!(word(r, 0), 0xFC0C_0017, "a whole record");
            assert_eq!(word(r, 8), !word(r, 4));
            word(r, 4)
        })
        .collect()
}

/// `push` of `generation` on trial, watched for 600 s, running: the process and its
/// standard output's lines.
fn watched_push(
    key: &str,
    medium: &str,
    generation: &str,
) -> (Child, std::io::Lines<BufReader<ChildStdout>>) {
    let mut watching = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(push_args(
            key,
            medium,
            generation,
            &["--trial", "--watch", "600"],
        ))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .env_remove("CONFIG_TOOL_KEYS")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("push");
    let lines = BufReader::new(watching.stdout.take().expect("stdout")).lines();
    (watching, lines)
}

/// `lines` past the watched push's "watching the trial" line.
fn until_watching(
    mut lines: std::io::Lines<BufReader<ChildStdout>>,
) -> std::io::Lines<BufReader<ChildStdout>> {
    while !(lines.next().expect("push said more").expect("a line"))
        .starts_with("watching the trial")
    {}
    lines
}

/// How a watched push ended: its status, standard error, and what it printed after `lines`
/// were read so far.
fn watch_end(
    watching: Child,
    lines: std::io::Lines<BufReader<ChildStdout>>,
) -> (Option<i32>, String, Vec<String>) {
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    let done = watching.wait_with_output().expect("ends");
    (done.status.code(), text(&done.stderr), rest)
}

/// `status --keys` of `node`, as lines.
fn status(key: &str, medium: &str, node: &str) -> Vec<String> {
    ok(&["status", "--keys", key, "--medium", medium, "--node", node])
        .lines()
        .map(str::to_string)
        .collect()
}

/// The security line's drop counters, up to the challenges (normal after a node's boot:
/// one per sender, or a few while the answer is on its way).
fn drops(security_line: &str) -> &str {
    let (drops, rest) = security_line
        .split_once("  challenged after boot ")
        .unwrap_or_else(|| panic!("{security_line}"));
    assert!(
        rest.ends_with("  not sent (no frame counter) 0"),
        "{security_line}"
    );
    drops
}

#[test]
fn keys_new_provision_push_start_status_with_keys_then_unsecured_start_is_dropped_and_counted() {
    let dir = TempDir::new("keys-cli");
    let key = dir.0.join("machine.key");
    let key_s = s(&key).to_string();
    ok(&["keys", "new", "--out", &key_s]);
    let c = robot("paint-robot.ron", 1);
    let addrs = robot_net::demo::node_addrs(&c);

    let medium = medium::Medium::start(medium::Config::default()).expect("medium");
    let m = medium.addr().to_string();
    let mut monitor = Monitor::join(medium.addr());
    let mut nodes = Vec::new();
    for a in &addrs {
        let node_key = dir.0.join(format!("node-{a:04x}.key"));
        let addr = format!("{a:#06x}");
        ok(&[
            "keys",
            "provision",
            "--keys",
            &key_s,
            "--node",
            &addr,
            "--board",
            "host",
            "--out",
            s(&node_key),
        ]);
        let child = Command::new(env!("CARGO_BIN_EXE_config-tool"))
            .args([
                "node",
                "--addr",
                &addr,
                "--medium",
                &m,
                "--key",
                s(&node_key),
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("node process");
        nodes.push(Killed(child));
    }
    let actuators = live_plant::actuators(&c).expect("actuators");
    let conn = live_plant::attach(medium.addr(), &actuators).expect("plant");
    let (steps_tx, steps) = mpsc::channel();
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let plant =
        std::thread::spawn(move || live_plant::run_attached(conn, actuators, None, steps_tx, flag));

    // Every node is up once it announced itself (unconfigured, every second).
    let mut heard = std::collections::BTreeSet::new();
    monitor.psdus_until(|psdu| {
        if let Ok(mac::Frame::Data { header, .. }) = mac::Frame::parse(psdu) {
            if addrs.contains(&header.src) {
                heard.insert(header.src);
            }
        }
        heard.len() == addrs.len()
    });

    let counter = dir.0.join("machine.key.counter");
    let pushed = ok(&["push", ROBOT, "--keys", &key_s, "--medium", &m]);
    let lines: Vec<&str> = pushed.lines().collect();
    assert_eq!(lines.len(), c.ir.roles.len() + 3, "{pushed}");
    assert_eq!(
        lines[0],
        "verified: 451 states, 1111 transitions, every property holds"
    );
    for line in &lines[1..=c.ir.roles.len()] {
        assert!(line.ends_with("activated"), "{pushed}");
    }
    assert!(
        lines[c.ir.roles.len() + 1].starts_with("pushed 4 table(s): 263 bytes"),
        "{pushed}"
    );
    assert_eq!(
        lines[c.ir.roles.len() + 2],
        "switched: every node runs the new generation"
    );
    // One reservation for the whole run: the counter file, not a write per frame.
    assert_eq!(reservations(&counter), [1024]);

    // The nodes booted their first table not homed: `status` and `scan` with the robot
    // say so, and `start` with the robot refuses (nothing sent, the plant does not move).
    let st = ok(&[
        "status", ROBOT, "--keys", &key_s, "--medium", &m, "--node", "0x0011",
    ]);
    assert_eq!(
        st.lines().last(),
        Some("  homing: not homed (config-tool home)"),
        "{st}"
    );
    let found = ok(&["scan", ROBOT, "--keys", &key_s, "--medium", &m]);
    assert!(
        found.contains("0x0011  firmware 1  generation 1  VC  not homed (config-tool home)\n")
            && found.contains("0x0012  firmware 1  generation 1  GR  homed\n")
            && found.contains("0x0015  firmware 1  generation 0  (unconfigured)\n"),
        "{found}"
    );
    let refused = tool(&["start", ROBOT, "--keys", &key_s, "--medium", &m]);
    assert_eq!(
        (refused.status.code(), text(&refused.stderr).as_str()),
        (
            Some(6),
            "error: not homed: run config-tool home; START was not sent\n"
        )
    );
    // Homing from rest: every rod's switch reads home, the gripper's valve is off: the
    // plant moves nothing.
    let homed = ok(&["home", ROBOT, "--keys", &key_s, "--medium", &m]);
    let lines: Vec<&str> = homed.lines().collect();
    assert_eq!(lines.len(), 2, "{homed}");
    assert_eq!(
        lines[0],
        "homing: VC- HC- RC- GR- (HOME to node 0x0011, VC; a step whose switch reads its \
         target already is skipped)"
    );
    assert!(
        lines[1].starts_with("homed: every chart idle in "),
        "{homed}"
    );
    assert!(steps.try_recv().is_err(), "homing from rest moves nothing");
    let st = ok(&[
        "status", ROBOT, "--keys", &key_s, "--medium", &m, "--node", "0x0011",
    ]);
    assert_eq!(st.lines().last(), Some("  homing: homed"), "{st}");

    assert_eq!(
        ok(&["start", ROBOT, "--keys", &key_s, "--medium", &m]),
        "0x0011: started\n"
    );
    let cycle: Vec<String> = (0..12)
        .map(|_| {
            steps
                .recv_timeout(TIMEOUT)
                .expect("a step of the cycle")
                .to_string()
        })
        .collect();
    assert_eq!(cycle.join(" "), SEQUENCE_1);

    // VC back at rest (its last step's switch may still be on its way).
    let vc = &c.tables[e2e_support::role_of(&c, "VC").0];
    let rest = format!(
        "  states {}",
        idle(vc)
            .iter()
            .map(|s| format!("S{s}"))
            .collect::<Vec<_>>()
            .join(" ")
    );
    let end = Instant::now() + TIMEOUT;
    let before = loop {
        let st = status(&key_s, &m, "0x0011");
        if st[1].starts_with(&format!("{rest}  ")) || Instant::now() > end {
            break st;
        }
    };
    assert_eq!(before.len(), 6, "{before:?}");
    assert_eq!(before[0], "0x0011  role VC  generation 1");
    assert!(before[1].ends_with("fault none"), "{before:?}");
    assert_eq!(
        drops(&before[5]),
        "  security on  dropped: not secured 0  bad MIC 0  replayed 0  unknown key 0  \
         wrong level 0  malformed 0  replay table full 0"
    );

    // Without keys: the node drops every try, answers none, starts nothing.
    let out = tool(&["start", "--medium", &m, "--node", "0x0011"]);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    let asked: u32 = err
        .strip_prefix("error: node 0x0011 did not answer (asked ")
        .and_then(|r| r.split_once(" times in 5 s)"))
        .and_then(|(n, rest)| {
            (rest == "; a node with a management key takes only secured frames: pass --keys\n")
                .then(|| n.parse().ok())
                .flatten()
        })
        .unwrap_or_else(|| panic!("{err}"));
    assert!(asked >= 1);
    let after = status(&key_s, &m, "0x0011");
    assert_eq!(
        after[1], before[1],
        "states, outputs, inputs and fault unchanged"
    );
    assert_eq!(
        drops(&after[5]),
        format!(
            "  security on  dropped: not secured {asked}  bad MIC 0  replayed 0  unknown key 0  \
             wrong level 0  malformed 0  replay table full 0"
        )
    );
    assert!(steps.try_recv().is_err(), "nothing moved");

    // A second push: a new run, its counters above every earlier run's (the node would
    // drop them as replayed otherwise, and the push would fail).
    let runs = reservations(&counter);
    let again = ok(&push_args(&key_s, &m, "2", &[]));
    assert_eq!(
        again.lines().filter(|l| l.ends_with("activated")).count(),
        4,
        "{again}"
    );
    let now = reservations(&counter);
    assert_eq!(now.len(), runs.len() + 1);
    assert!(
        now.windows(2).all(|w| w[1] == w[0] + 1024),
        "one reservation per run, each above the last: {now:?}"
    );
    let last = status(&key_s, &m, "0x0011");
    assert_eq!(last[0], "0x0011  role VC  generation 2");
    assert_eq!(
        drops(&last[5]),
        format!(
            "  security on  dropped: not secured {asked}  bad MIC 0  replayed 0  unknown key 0  \
             wrong level 0  malformed 0  replay table full 0"
        )
    );

    // A secured scan reads the nodes' secured answers; without keys it reads none.
    let found = ok(&["scan", "--keys", &key_s, "--medium", &m]);
    for r in &c.ir.roles {
        let line = format!("{:#06x}  firmware 1  generation 2  {}", r.address, r.name);
        assert!(found.contains(&line), "{found}");
    }
    assert!(found.ends_with("5 node(s)\n"), "the spare too: {found}");
    // No node answering is an error (status 1, as the docs have it): a script that scans
    // before it pushes stops there.
    let unkeyed = tool(&["scan", "--medium", &m]);
    assert_eq!(
        (
            unkeyed.status.code(),
            text(&unkeyed.stdout).as_str(),
            text(&unkeyed.stderr).as_str()
        ),
        (
            Some(1),
            "0 node(s)\n",
            "error: no node answered: a node with a management key answers only secured frames \
             (pass --keys)\n"
        )
    );

    // Generation 3 on trial; rolled back to 2; on trial again and confirmed.
    let push_trial = |generation: &str| ok(&push_args(&key_s, &m, generation, &["--trial"]));
    let trial = push_trial("3");
    assert!(
        trial.ends_with(
            "switched on trial: `config-tool confirm` keeps it; a power cut or \
             `config-tool rollback` returns to the previous generation\n"
        ),
        "{trial}"
    );
    assert_eq!(
        status(&key_s, &m, "0x0011")[0],
        "0x0011  role VC  generation 3  on trial"
    );
    let back = ok(&["rollback", ROBOT, "--keys", &key_s, "--medium", &m]);
    let expect: Vec<String> =
        c.ir.roles
            .iter()
            .map(|r| {
                format!(
                    "  {:<6} {:#06x}  generation 2  rolled back",
                    r.name, r.address
                )
            })
            .collect();
    assert_eq!(back.lines().collect::<Vec<_>>(), expect, "{back}");
    assert_eq!(
        status(&key_s, &m, "0x0011")[0],
        "0x0011  role VC  generation 2"
    );
    // A push whose output nobody reads (`push ... | head -1`) still pushes: it prints
    // nothing more and ends with its own status (it ended with a panic at its first line).
    let (reader, writer) = std::io::pipe().expect("pipe");
    drop(reader);
    let unread = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(push_args(&key_s, &m, "4", &["--trial"]))
        .env_remove("CONFIG_TOOL_KEYS")
        .stdout(writer)
        .output()
        .expect("runs");
    assert_eq!(
        (unread.status.code(), text(&unread.stderr).as_str()),
        (Some(0), "")
    );
    let kept = ok(&["confirm", ROBOT, "--keys", &key_s, "--medium", &m]);
    assert!(
        kept.lines().all(|l| l.ends_with("generation 4  confirmed")),
        "{kept}"
    );
    assert_eq!(
        status(&key_s, &m, "0x0011")[0],
        "0x0011  role VC  generation 4"
    );
    assert_eq!(
        ok(&["confirm", ROBOT, "--keys", &key_s, "--medium", &m]),
        "nothing on trial: every node's generation is confirmed\n"
    );
    // A watched trial nobody confirms goes back by itself.
    let watched = tool(&push_args(&key_s, &m, "5", &["--trial", "--watch", "1"]));
    assert_eq!(watched.status.code(), Some(3), "{}", text(&watched.stdout));
    assert!(
        text(&watched.stdout).ends_with(
            "watching the trial for 1 s (rolled back to generation 4 unless confirmed: type \
             `confirm` here, or run `config-tool confirm`)\n"
        ),
        "{}",
        text(&watched.stdout)
    );
    assert_eq!(
        text(&watched.stderr),
        "error: the trial was not confirmed within 1 s: every node back to generation 4\n"
    );
    assert_eq!(
        status(&key_s, &m, "0x0011")[0],
        "0x0011  role VC  generation 4"
    );
    // A watched trial confirmed where it is watched: `confirm` typed on the push's
    // standard input.
    let (mut watching, mut lines) = watched_push(&key_s, &m, "6");
    let watching_line = loop {
        let line = lines.next().expect("push said more").expect("a line");
        if line.starts_with("watching the trial") {
            break line;
        }
    };
    assert_eq!(
        watching_line,
        "watching the trial for 600 s (rolled back to generation 4 unless confirmed: type \
         `confirm` here, or run `config-tool confirm`)"
    );
    writeln!(watching.stdin.as_mut().expect("stdin"), "confirm").expect("typed");
    assert_eq!(
        watch_end(watching, lines),
        (
            Some(0),
            String::new(),
            vec!["confirmed: the trial generation stays".to_string()]
        )
    );
    assert_eq!(
        status(&key_s, &m, "0x0011")[0],
        "0x0011  role VC  generation 6"
    );
    // ... or by `confirm` from another terminal while the watch runs: the two runs share
    // the key file's counter, each frame numbered above every earlier one of either (the
    // nodes take no counter at or below the last one they took). Before, the second run
    // was refused ("in use by another config-tool process") until the watch ended, and
    // the trial rolled back.
    let (watching, lines) = watched_push(&key_s, &m, "7");
    let lines = until_watching(lines);
    let before = reservations(&counter);
    let kept = ok(&["confirm", ROBOT, "--keys", &key_s, "--medium", &m]);
    assert!(
        kept.lines().all(|l| l.ends_with("generation 7  confirmed")),
        "{kept}"
    );
    assert_eq!(
        watch_end(watching, lines),
        (
            Some(0),
            String::new(),
            vec!["confirmed: the trial generation stays".to_string()]
        )
    );
    let after = reservations(&counter);
    assert!(
        after.len() > before.len() && after.windows(2).all(|w| w[0] < w[1]),
        "the confirm and the watch each reserved above the other: {before:?} then {after:?}"
    );
    assert_eq!(
        status(&key_s, &m, "0x0011")[0],
        "0x0011  role VC  generation 7"
    );
    // A `rollback` from another terminal ends a watched trial too: the watch said the
    // node had lost power.
    let (watching, lines) = watched_push(&key_s, &m, "8");
    let lines = until_watching(lines);
    ok(&["rollback", ROBOT, "--keys", &key_s, "--medium", &m]);
    let (code, said, rest) = watch_end(watching, lines);
    assert_eq!((code, rest), (Some(3), vec![]), "{said}");
    assert!(
        said.starts_with("error: node 0x00")
            && said.contains(
                " runs generation 7 again during the trial (a power cut, or a rollback from \
                 another terminal): "
            ),
        "{said}"
    );
    assert_eq!(
        status(&key_s, &m, "0x0011")[0],
        "0x0011  role VC  generation 7"
    );

    stop.store(true, Ordering::Relaxed);
    drop(nodes);
    medium.stop();
    let _ = plant.join();
}

/// A node started from the command line with its key and a flash file.
fn start_node(dir: &Path, key: &str, medium: &str, addr: u16) -> Killed {
    let a = format!("{addr:#06x}");
    let node_key = dir.join(format!("node-{addr:04x}.key"));
    if !node_key.exists() {
        ok(&[
            "keys",
            "provision",
            "--keys",
            key,
            "--node",
            &a,
            "--board",
            "host",
            "--out",
            s(&node_key),
        ]);
    }
    let flash = dir.join(format!("node-{addr:04x}.flash"));
    let child = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args([
            "node",
            "--addr",
            &a,
            "--medium",
            medium,
            "--key",
            s(&node_key),
        ])
        .arg("--flash")
        .arg(&flash)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("node process");
    Killed(child)
}

/// A machine secret, the paint robot's role nodes started with their keys and flash on a
/// medium of their own, each heard on the air.
struct Keyed {
    dir: TempDir,
    key_s: String,
    c: robot_compiler::Compiled,
    medium: medium::Medium,
    /// The medium's address, as the tool takes it.
    m: String,
    /// Each role's node, by address.
    nodes: Vec<(u16, Killed)>,
}

fn keyed(tag: &str) -> Keyed {
    let dir = TempDir::new(tag);
    let key_s = s(&dir.0.join("machine.key")).to_string();
    ok(&["keys", "new", "--out", &key_s]);
    let c = robot("paint-robot.ron", 1);
    let roles: Vec<u16> = c.ir.roles.iter().map(|r| r.address).collect();
    let medium = medium::Medium::start(medium::Config::default()).expect("medium");
    let m = medium.addr().to_string();
    let mut monitor = Monitor::join(medium.addr());
    let nodes: Vec<(u16, Killed)> = roles
        .iter()
        .map(|&a| (a, start_node(&dir.0, &key_s, &m, a)))
        .collect();
    let mut heard = std::collections::BTreeSet::new();
    monitor.psdus_until(|psdu| {
        if let Ok(mac::Frame::Data { header, .. }) = mac::Frame::parse(psdu) {
            if roles.contains(&header.src) {
                heard.insert(header.src);
            }
        }
        heard.len() == roles.len()
    });
    Keyed {
        dir,
        key_s,
        c,
        medium,
        m,
        nodes,
    }
}

/// `rollback`'s lines: every node of `c` back to `generation`, node `on_it` on it already.
fn rolled_back(c: &robot_compiler::Compiled, on_it: u16, generation: u32) -> Vec<String> {
    (c.ir.roles.iter())
        .map(|r| {
            let what = if r.address == on_it {
                "on it already"
            } else {
                "rolled back"
            };
            format!(
                "  {:<6} {:#06x}  generation {generation}  {what}",
                r.name, r.address
            )
        })
        .collect()
}

/// A node that a power cut took off a trial (it booted its confirmed generation) keeps
/// `confirm` from confirming the others: the machine would run two generations. `confirm`
/// names it and fails, nothing confirmed; `rollback` then brings every node back to one.
/// Found: `confirm` confirmed the three still on trial, said nothing of the fourth, and
/// succeeded.
#[test]
fn confirm_refuses_a_trial_a_power_cut_split() {
    let Keyed {
        dir,
        key_s,
        c,
        medium,
        m,
        mut nodes,
    } = keyed("keys-trial-cut");
    let push = |generation: &str, trial: bool| {
        let more: &[&str] = if trial { &["--trial"] } else { &[] };
        ok(&push_args(&key_s, &m, generation, more))
    };
    push("1", false);
    push("2", true);
    // A power cut at RC's node: it boots generation 1, the others stay on trial on 2.
    let rc = e2e_support::role_of(&c, "RC").1;
    let at = nodes.iter().position(|n| n.0 == rc).expect("RC");
    drop(nodes.remove(at));
    // `scan` with the robot names the node that does not answer.
    let found = ok(&["scan", ROBOT, "--keys", &key_s, "--medium", &m]);
    let name = &c
        .robot
        .nodes
        .iter()
        .find(|n| n.address == rc)
        .expect("node")
        .name;
    assert!(
        found.contains(&format!("{rc:#06x}  RC  did not answer (node {name})\n")),
        "{found}"
    );
    nodes.push((rc, start_node(&dir.0, &key_s, &m, rc)));
    let rc_s = format!("{rc:#06x}");
    let end = Instant::now() + TIMEOUT;
    loop {
        let out = tool(&["status", "--keys", &key_s, "--medium", &m, "--node", &rc_s]);
        let first = text(&out.stdout).lines().next().map(str::to_string);
        if first.as_deref() == Some(&format!("{rc_s}  role RC  generation 1")) {
            break;
        }
        assert!(Instant::now() < end, "RC did not come back: {first:?}");
    }
    // `scan` shows who is on trial, and that the trial is split (it showed neither).
    let found = ok(&["scan", ROBOT, "--keys", &key_s, "--medium", &m]);
    for r in &c.ir.roles {
        let want = if r.address == rc {
            format!("\n{rc:#06x}  firmware 1  generation 1  RC  ")
        } else {
            format!(
                "\n{:#06x}  firmware 1  generation 2 on trial  {}  ",
                r.address, r.name
            )
        };
        assert!(format!("\n{found}").contains(&want), "{want}{found}");
    }
    assert!(
        found.contains(&format!(
            "not every node runs generation 2 on trial: {rc:#06x} (RC) runs generation 1 (a \
             power cut returns a node to its previous generation): `config-tool rollback` \
             returns the others to theirs\n"
        )),
        "{found}"
    );
    let out = tool(&["confirm", ROBOT, "--keys", &key_s, "--medium", &m]);
    assert_eq!(out.status.code(), Some(3), "{}", text(&out.stderr));
    let lines: Vec<String> =
        c.ir.roles
            .iter()
            .map(|r| {
                let what = if r.address == rc {
                    "generation 1  NOT on trial"
                } else {
                    "generation 2  on trial"
                };
                format!("  {:<6} {:#06x}  {what}", r.name, r.address)
            })
            .collect();
    assert_eq!(text(&out.stdout).lines().collect::<Vec<_>>(), lines);
    assert_eq!(
        text(&out.stderr),
        "error: not every node runs generation 2 on trial (a power cut returns a node to its \
         previous generation): nothing confirmed; `config-tool rollback` returns the others to \
         theirs\n"
    );
    for r in &c.ir.roles {
        let a = format!("{:#06x}", r.address);
        let first = status(&key_s, &m, &a).remove(0);
        let want = if r.address == rc {
            format!("{a}  role RC  generation 1")
        } else {
            format!("{a}  role {}  generation 2  on trial", r.name)
        };
        assert_eq!(first, want);
    }
    let back = ok(&["rollback", ROBOT, "--keys", &key_s, "--medium", &m]);
    assert_eq!(back.lines().collect::<Vec<_>>(), rolled_back(&c, rc, 1));
    for r in &c.ir.roles {
        let a = format!("{:#06x}", r.address);
        assert_eq!(
            status(&key_s, &m, &a).remove(0),
            format!("{a}  role {}  generation 1", r.name)
        );
    }
    drop(nodes);
    medium.stop();
}

/// Secured nodes answer an unsecured broadcast `Identify` once a second, to whoever asks
/// first; another tool asking all the time (or a lossy medium) kept `scan` from hearing
/// them, and it listed healthy nodes as `did not answer`. With the robot, `scan` asks each
/// of its nodes that did not announce itself directly, secured: every node is listed.
#[test]
fn a_secured_scan_finds_every_node_while_another_tool_asks_all_the_time() {
    // (The directory and the nodes held to the end: `..` would drop them here.)
    let Keyed {
        dir: _dir,
        key_s,
        c,
        medium,
        m,
        nodes: _nodes,
    } = keyed("keys-scan-flood");
    ok(&["push", ROBOT, "--keys", &key_s, "--medium", &m]);
    // Another tool asks every node to identify itself every 2 ms.
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let mut other = e2e_support::RawClient::join(medium.addr(), 0x0200);
    let asking = std::thread::spawn(move || {
        let identify = config_schema::wire::msg::Message::Command {
            id: 1,
            command: config_schema::wire::msg::Command::Identify { nonce: 1 },
        };
        let payload = e2e_support::payload(&identify);
        let mut seq = 0u8;
        while !flag.load(Ordering::Relaxed) {
            let frame = e2e_support::frame(
                node_fw::node::CONFIG_PAN,
                mac::BROADCAST,
                0x0200,
                seq,
                &payload,
            );
            other.send_psdu(&frame);
            seq = seq.wrapping_add(1);
            let until = Instant::now() + std::time::Duration::from_millis(2);
            while other.next_frame(until).is_some() {}
        }
    });
    let found = ok(&["scan", ROBOT, "--keys", &key_s, "--medium", &m]);
    stop.store(true, Ordering::Relaxed);
    asking.join().expect("the other tool");
    for r in &c.ir.roles {
        let want = format!(
            "\n{:#06x}  firmware 1  generation 1  {}  ",
            r.address, r.name
        );
        assert!(format!("\n{found}").contains(&want), "{want}{found}");
    }
    // The spare, not started, is the only one that did not answer.
    let silent: Vec<&str> = found
        .lines()
        .filter(|l| l.contains("did not answer"))
        .collect();
    assert_eq!(
        silent,
        ["0x0015  (no role)  did not answer (node spare)"],
        "{found}"
    );
    medium.stop();
}

/// A switch-over that did not finish (RC's node lost between staging and switching, as a
/// `push --now` with a node gone half way leaves it): VC, GR and HC run generation 2, RC
/// runs 1 with 2 staged. `home` and `start` sent their commands to a machine whose nodes
/// share no link keys (homing then timed out, naming a link in alarm); now they refuse
/// it, naming RC's generation. Found: the advice `push again to finish it` failed for
/// good (every node that had switched refused a generation not newer than its own), and
/// `rollback` found `no common previous generation` (RC's previous is 0, though it runs
/// the generation the others return to). Now the push finishes the switch-over, and so
/// does a rollback, the other way.
#[test]
fn a_switch_over_that_did_not_finish_is_refused_by_home_then_finished_by_push_or_rollback() {
    let Keyed {
        dir,
        key_s,
        c,
        medium,
        m,
        nodes,
    } = keyed("keys-split-switch");
    let secret = robot_keys::load_machine_secret(Path::new(&key_s)).expect("secret");
    let rc = e2e_support::role_of(&c, "RC").1;
    let push = |generation: &str, extra: &[&str]| tool(&push_args(&key_s, &m, generation, extra));
    let split = |generation: u32| {
        let g = generation.to_string();
        let out = push(&g, &["--stage-only"]);
        assert!(out.status.success(), "{}", text(&out.stdout));
        let mut radio = e2e_support::second_tool(medium.addr(), &secret);
        for r in c.ir.roles.iter().filter(|r| r.address != rc) {
            assert!(e2e_support::switch_one(&mut radio, r.address, generation));
        }
    };
    let out = push("1", &[]);
    assert!(out.status.success(), "{}", text(&out.stdout));
    split(2);
    for (command, what) in [("home", "HOME"), ("start", "START")] {
        let refused = format!(
            "error: the nodes run different generations: 0x0014 (RC) runs generation 1: push \
             again to finish the switch-over, or roll back; {what} was not sent\n"
        );
        let out = tool(&[command, ROBOT, "--keys", &key_s, "--medium", &m]);
        assert_eq!(
            (out.status.code(), text(&out.stderr)),
            (Some(6), refused),
            "{command}: {}",
            text(&out.stdout)
        );
    }
    // Rolled back: the three that switched return to 1, RC is on it.
    let back = ok(&["rollback", ROBOT, "--keys", &key_s, "--medium", &m]);
    assert_eq!(back.lines().collect::<Vec<_>>(), rolled_back(&c, rc, 1));
    // Split again. Pushed again on trial: the three run generation 3 confirmed, not on
    // trial, and refuse it (taken as running it, the machine would end half on trial).
    split(3);
    let out = push("3", &["--trial"]);
    assert_eq!(out.status.code(), Some(3), "{}", text(&out.stdout));
    assert_eq!(
        text(&out.stderr),
        "error: not every node staged its table: nothing switched; a node runs generation \
         3: push with --generation 4\n"
    );
    // Pushed again as it was: RC switches, the others run it already.
    let out = push("3", &[]);
    let said = text(&out.stdout);
    assert_eq!(
        (out.status.code(), text(&out.stderr).as_str()),
        (Some(0), ""),
        "{said}"
    );
    for r in &c.ir.roles {
        let line = said
            .lines()
            .find(|l| l.starts_with(&format!("  {:<6} {:#06x}", r.name, r.address)))
            .unwrap_or_default();
        let want = if r.address == rc {
            "activated"
        } else {
            "runs this table already"
        };
        assert!(line.ends_with(want), "{said}");
    }
    assert_eq!(
        said.lines().last(),
        Some("switched: every node runs the new generation")
    );
    for r in &c.ir.roles {
        let a = format!("{:#06x}", r.address);
        assert_eq!(
            status(&key_s, &m, &a).remove(0),
            format!("{a}  role {}  generation 3", r.name)
        );
    }
    drop((nodes, dir));
    medium.stop();
}

/// `push --role` at another generation than the robot's other nodes run: each generation
/// of a secured robot has link keys of its own, so the role's node would share none with
/// its peers (it was pushed, switched, and the machine could not run until every role was
/// pushed again). Refused before anything is sent, saying what to push; at the machine's
/// generation the role alone goes through (`--force` over the node that runs it).
#[test]
fn a_role_pushed_alone_at_another_generation_of_a_secured_robot_is_refused() {
    let Keyed {
        dir,
        key_s,
        medium,
        m,
        nodes,
        ..
    } = keyed("keys-push-role");
    let push = |generation: &str, extra: &[&str]| {
        tool(
            &[
                push_args(&key_s, &m, generation, &["--now"]),
                extra.to_vec(),
            ]
            .concat(),
        )
    };
    let out = push("1", &[]);
    assert!(out.status.success(), "{}", text(&out.stdout));
    let out = push("2", &["--role", "RC"]);
    assert_eq!(
        (out.status.code(), text(&out.stderr)),
        (
            Some(6),
            "error: the robot's other nodes run generation 1, and each generation of a secured \
             robot has link keys of its own: RC alone at generation 2 would share none with \
             its peers; push every role at generation 2, or RC at generation 1 (--generation \
             1, with --force over a node that runs it); nothing was sent\n"
                .to_string()
        ),
        "{}",
        text(&out.stdout)
    );
    assert_eq!(
        status(&key_s, &m, "0x0014")[0],
        "0x0014  role RC  generation 1"
    );
    // At the machine's generation, RC alone is pushed again.
    let out = push("1", &["--role", "RC", "--force"]);
    assert_eq!(
        (out.status.code(), text(&out.stderr).as_str()),
        (Some(0), ""),
        "{}",
        text(&out.stdout)
    );
    drop((nodes, dir));
    medium.stop();
}

/// A robot that says `security: Off` pushed to keyed nodes: its tables go in clear and
/// every keyed node drops them. It said only `FAILED: the node stopped answering (is it
/// running, in range?)` of each node; now the error says why.
#[test]
fn an_unsecured_robot_pushed_to_keyed_nodes_says_they_take_only_secured_frames() {
    let Keyed {
        dir,
        medium,
        m,
        nodes,
        ..
    } = keyed("keys-push-off");
    let (off, _) = e2e_support::unsecured_robot(&dir, "paint-robot.ron");
    let out = tool(&["push", s(&off), "--medium", &m]);
    let said = text(&out.stdout);
    assert_eq!(out.status.code(), Some(3), "{said}");
    assert_eq!(
        said.lines()
            .filter(|l| l.ends_with("FAILED: the node stopped answering (is it running, in range?)"))
            .count(),
        4,
        "{said}"
    );
    assert_eq!(
        text(&out.stderr),
        "error: not every node staged its table: nothing switched; the robot says `security: \
         Off`, so its tables went in clear: a node with a management key takes only secured \
         frames (push a robot with security on, with --keys)\n"
    );
    drop(nodes);
    medium.stop();
}

/// A rollback of a faulted machine (generation 2 pushed over 1, then HOME with no plant to
/// move the rods: every node faults) is refused at once, status 3, the faulted nodes named
/// with the ways out, as `push` does: a faulted machine never comes to rest. It waited
/// out `--wait` and said every node stayed "on the trial generation" (there was no trial).
#[test]
fn a_rollback_of_a_faulted_machine_is_refused_at_once_naming_the_faulted_nodes() {
    let Keyed {
        dir: _dir,
        key_s,
        c,
        medium: _medium,
        m,
        nodes: _nodes,
    } = keyed("keys-rollback-faulted");
    ok(&push_args(&key_s, &m, "1", &[]));
    ok(&push_args(&key_s, &m, "2", &["--now"]));
    let home = tool(&["home", ROBOT, "--keys", &key_s, "--medium", &m]);
    assert_eq!(home.status.code(), Some(5), "{}", text(&home.stderr));
    let back = tool(&[
        "rollback", ROBOT, "--keys", &key_s, "--medium", &m, "--wait", "600",
    ]);
    assert_eq!(back.status.code(), Some(3), "{}", text(&back.stderr));
    assert_eq!(text(&back.stdout), "");
    let err = text(&back.stderr);
    let each: Vec<String> = (c.ir.roles.iter())
        .map(|r| format!("config-tool reset --node {:#06x}", r.address))
        .collect();
    assert!(err.starts_with("error: nodes 0x0011 (VC, 0x"), "{err}");
    assert!(
        err.ends_with(&format!(
            " are faulted: a faulted machine does not reach its idle point, so nothing rolled \
             back: rollback --now to return at once, or reset each ({}), acknowledge the \
             alarms (config-tool ack), home, and roll back again\n",
            each.join("; ")
        )),
        "{err}"
    );
}

/// An alarm's wall time is the tool's clock when its node answered, less the alarm's age:
/// the same in every read, whoever else answers. With one node silent, every other
/// node's alarm moved 5 s later (the answers were stamped when the last ask gave up).
#[test]
fn alarm_times_do_not_move_when_a_node_is_silent() {
    let Keyed {
        dir: _dir,
        key_s,
        c: _c,
        medium: _medium,
        m,
        mut nodes,
    } = keyed("keys-alarm-times");
    ok(&push_args(&key_s, &m, "1", &[]));
    // HOME with no plant to move the rods: every node faults and latches an alarm.
    let home = tool(&["home", ROBOT, "--keys", &key_s, "--medium", &m]);
    assert_eq!(home.status.code(), Some(5), "{}", text(&home.stderr));
    // Each alarm line's time (`HH:MM:SS.mmm`, in ms) and node.
    let times = |out: &str| -> Vec<(String, u64)> {
        out.lines()
            .filter(|l| l.contains(" UTC  0x"))
            .map(|l| {
                let clock = l.split_whitespace().nth(1).unwrap();
                let (hms, ms) = clock.split_once('.').unwrap();
                let secs: Vec<u64> = hms.split(':').map(|x| x.parse().unwrap()).collect();
                let at =
                    ((secs[0] * 60 + secs[1]) * 60 + secs[2]) * 1000 + ms.parse::<u64>().unwrap();
                (l.split_whitespace().nth(3).unwrap().to_string(), at)
            })
            .collect()
    };
    let alarms = || text(&tool(&["alarms", ROBOT, "--keys", &key_s, "--medium", &m]).stdout);
    let before = times(&alarms());
    assert_eq!(before.len(), 4, "{before:?}");
    // HC's node off: the others' alarms are read again.
    let hc = nodes.iter().position(|(a, _)| *a == 0x0013).unwrap();
    drop(nodes.remove(hc));
    let after = times(&alarms());
    assert_eq!(after.len(), 3, "{after:?}");
    for (node, at) in &after {
        let (_, was) = before.iter().find(|(n, _)| n == node).unwrap();
        // The same alarm, read twice: its time moves by the radio's delays only (ms),
        // not by the 5 s the tool waits for a silent node.
        assert!(at.abs_diff(*was) < 1000, "{node}: {was} ms, then {at} ms");
    }
}
