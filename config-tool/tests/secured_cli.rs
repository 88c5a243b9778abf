//! `--keys` on the radio commands, without nodes: which robots need keys, and the exact
//! errors of a missing or exposed key file, an unreadable counter file and a counter file
//! another process holds. The medium named is never reached (port 1): keys come first.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const NO_MEDIUM: &str = "127.0.0.1:1";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Runs the tool at the workspace root, without `CONFIG_TOOL_KEYS` unless `env` sets it.
fn tool(args: &[&str], env: Option<&Path>) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_config-tool"));
    cmd.current_dir(root())
        .args(args)
        .env_remove("CONFIG_TOOL_KEYS");
    if let Some(file) = env {
        cmd.env("CONFIG_TOOL_KEYS", file);
    }
    cmd.output().expect("runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("secured-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A fresh machine secret made by `keys new`.
fn new_key(dir: &Path) -> PathBuf {
    let key = dir.join("machine.key");
    let out = tool(&["keys", "new", "--out", s(&key)], None);
    assert!(out.status.success(), "{}", text(&out.stderr));
    key
}

#[test]
fn check_warns_about_an_unsecured_robot_at_its_setting() {
    let out = tool(&["check", "tests/fixtures/broken/unsecured.ron"], None);
    assert_eq!(out.status.code(), Some(0));
    let err = text(&out.stderr);
    assert!(
        err.contains(
            "frame security is off: anyone in radio range can push a table to these nodes, press START or\n"
        ),
        "{err}"
    );
    assert!(
        err.contains("╭─[tests/fixtures/broken/unsecured.ron:5:15]"),
        "{err}"
    );
    assert!(
        err.contains("help: remove `security: Off` to secure every frame"),
        "{err}"
    );
    assert!(
        err.ends_with("unsecured.ron: 0 error(s), 1 warning(s)\n"),
        "{err}"
    );
    // The secured default says nothing of security.
    let out = tool(&["check", "robot-configs/paint-robot.ron"], None);
    assert!(
        !text(&out.stderr).contains("security"),
        "{}",
        text(&out.stderr)
    );
}

/// `start ROBOT` of a secured robot without keys is refused at once, as `home` and `ack`
/// are. Found: it asked the node for 5 s and said only "did not answer Status".
#[test]
fn start_of_a_secured_robot_without_keys_is_refused_at_once() {
    let robot = "robot-configs/paint-robot.ron";
    let out = tool(&["start", robot, "--medium", NO_MEDIUM], None);
    assert_eq!(out.status.code(), Some(2), "a usage error");
    assert_eq!(text(&out.stderr), SECURED_WITHOUT_KEYS);
}

/// What a command that needs the keys of the secured paint robot says without them.
const SECURED_WITHOUT_KEYS: &str = "error: robot-configs/paint-robot.ron is secured (frame \
    security is on unless the robot says `security: Off`): pass --keys FILE, the machine \
    secret's key file (`config-tool keys new`), or set CONFIG_TOOL_KEYS\n";

#[test]
fn a_secured_robot_is_not_pushed_without_keys_and_an_unsecured_one_takes_none() {
    let robot = "robot-configs/paint-robot.ron";
    let out = tool(&["push", robot, "--medium", NO_MEDIUM], None);
    assert_eq!(out.status.code(), Some(2), "a usage error");
    assert_eq!(text(&out.stderr), SECURED_WITHOUT_KEYS);
    let dir = scratch("push");
    let key = new_key(&dir);
    let unsecured = "tests/fixtures/broken/unsecured.ron";
    let out = tool(
        &["push", unsecured, "--keys", s(&key), "--medium", NO_MEDIUM],
        None,
    );
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(
        text(&out.stderr),
        "error: tests/fixtures/broken/unsecured.ron says `security: Off`: its nodes are pushed \
         and commanded unsecured; drop --keys, or remove the setting to secure them\n"
    );
    // Without keys, or with keys only from the environment (a default, not a demand), the
    // unsecured robot goes as far as the medium.
    let unreachable = format!(
        "error: cannot reach the medium at {NO_MEDIUM}: Connection refused (os error 111)\n"
    );
    for env in [None, Some(key.as_path())] {
        let out = tool(&["push", unsecured, "--medium", NO_MEDIUM], env);
        assert_eq!(
            (out.status.code(), text(&out.stderr)),
            (Some(1), unreachable.clone())
        );
    }
    // The secured one with the environment's keys too.
    let out = tool(&["push", robot, "--medium", NO_MEDIUM], Some(&key));
    assert_eq!(
        (out.status.code(), text(&out.stderr)),
        (Some(1), unreachable)
    );
}

#[test]
fn a_missing_key_file_is_named_with_how_to_make_one_from_the_flag_or_the_environment() {
    let dir = scratch("missing");
    let key = dir.join("machine.key");
    let expected = format!(
        "error: {0}: no such key file (the machine secret is made once, by `config-tool keys \
         new --out {0}`)\n",
        key.display()
    );
    for args in [
        vec!["status", "--node", "0x0011"],
        vec!["start", "--node", "0x0011"],
        vec!["reset", "--node", "0x0011"],
        vec!["scan"],
        vec!["push", "robot-configs/paint-robot.ron"],
    ] {
        let mut with_flag = args.clone();
        with_flag.extend(["--keys", s(&key), "--medium", NO_MEDIUM]);
        let out = tool(&with_flag, None);
        assert_eq!(
            (out.status.code(), text(&out.stderr)),
            (Some(1), expected.clone()),
            "{args:?}"
        );
        let mut from_env = args.clone();
        from_env.extend(["--medium", NO_MEDIUM]);
        let out = tool(&from_env, Some(&key));
        assert_eq!(
            (out.status.code(), text(&out.stderr)),
            (Some(1), expected.clone()),
            "{args:?} with CONFIG_TOOL_KEYS"
        );
    }
    assert!(
        !dir.join("machine.key.counter").exists(),
        "no counter without a key"
    );
}

#[cfg(unix)]
#[test]
fn a_key_file_others_may_read_is_refused() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch("mode");
    let key = new_key(&dir);
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o640)).unwrap();
    let out = tool(
        &[
            "status",
            "--node",
            "0x0011",
            "--keys",
            s(&key),
            "--medium",
            NO_MEDIUM,
        ],
        None,
    );
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        text(&out.stderr),
        format!(
            "error: {0}: mode 0640 lets group or others read or write it; a key file must be \
             readable by its owner only (chmod 600 {0})\n",
            key.display()
        )
    );
}

#[test]
fn an_unreadable_counter_file_is_refused_and_left_as_it_is() {
    let dir = scratch("counter");
    let key = new_key(&dir);
    let counter = dir.join("machine.key.counter");
    std::fs::write(&counter, b"not a counter").unwrap();
    let out = tool(
        &[
            "start",
            "--node",
            "0x0011",
            "--keys",
            s(&key),
            "--medium",
            NO_MEDIUM,
        ],
        None,
    );
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        text(&out.stderr),
        format!(
            "error: counter file {}: 13 bytes, not a frame counter file (8192 bytes); left \
             unchanged\n",
            counter.display()
        )
    );
    assert_eq!(std::fs::read(&counter).unwrap(), b"not a counter");
    // A directory where the file should be.
    std::fs::remove_file(&counter).unwrap();
    std::fs::create_dir(&counter).unwrap();
    let out = tool(
        &[
            "start",
            "--node",
            "0x0011",
            "--keys",
            s(&key),
            "--medium",
            NO_MEDIUM,
        ],
        None,
    );
    assert_eq!(
        text(&out.stderr),
        format!(
            "error: counter file {}: Is a directory (os error 21)\n",
            counter.display()
        )
    );
}

/// A counter file another process holds locked for over `LOCK_WAIT` (runs share it, each
/// holding it for one frame's counter: one that holds it longer was stopped).
#[cfg(unix)]
#[test]
fn a_counter_file_another_process_holds_for_long_is_refused_until_it_is_released() {
    use rustix::fs::{flock, FlockOperation};
    let dir = scratch("locked");
    let key = new_key(&dir);
    // A first run creates the counter file (the medium is not there: nothing is sent).
    let args = [
        "status",
        "--node",
        "0x0011",
        "--keys",
        s(&key),
        "--medium",
        NO_MEDIUM,
    ];
    let out = tool(&args, None);
    assert!(text(&out.stderr).contains("cannot reach the medium"));
    let counter = dir.join("machine.key.counter");
    let held = std::fs::File::open(&counter).unwrap();
    flock(&held, FlockOperation::NonBlockingLockExclusive).unwrap();
    let out = tool(&args, None);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        text(&out.stderr),
        format!(
            "error: counter file {}: locked by another config-tool process with the same key \
             file for over 2 s (stopped while it held it?)\n",
            counter.display()
        )
    );
    drop(held);
    let out = tool(&args, None);
    assert!(text(&out.stderr).contains("cannot reach the medium"));
}

/// A node that does not answer a command of an unsecured robot's: the hint `pass --keys`
/// was wrong (`--keys` with that robot is refused); without a robot it stays (a keyed
/// node takes only secured frames).
#[test]
fn a_silent_node_of_an_unsecured_robot_gets_no_keys_hint() {
    let m = medium::Medium::start(medium::Config::default()).expect("medium");
    let at = m.addr().to_string();
    let unsecured = "tests/fixtures/broken/unsecured.ron";
    let out = tool(
        &["status", unsecured, "--medium", &at, "--node", "0x0011"],
        None,
    );
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.starts_with("error: node 0x0011 did not answer (asked ") && err.ends_with(" s)\n"),
        "{err}"
    );
    let out = tool(&["status", "--medium", &at, "--node", "0x0011"], None);
    let err = text(&out.stderr);
    assert!(
        err.ends_with("; a node with a management key takes only secured frames: pass --keys\n"),
        "{err}"
    );
}
