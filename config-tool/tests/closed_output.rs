//! A command whose output cannot be written: a reader that went away (`config-tool check
//! r.ron | head -1`) is no failure, the command's status stays its own; a full disk fails
//! it. Issue: every one-shot command panicked there (status 101 and a backtrace).
//! (`monitor` and a push: `monitor_cli.rs`, `e2e_keys.rs`.)

use std::path::Path;
use std::process::{Command, Output, Stdio};

fn config_tool(args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_config-tool"));
    c.current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(args)
        .env_remove("CONFIG_TOOL_KEYS");
    c
}

/// `config-tool ARGS` with its output read.
fn read(args: &[&str]) -> Output {
    config_tool(args).output().expect("runs")
}

/// `config-tool ARGS` with its output a pipe whose reader went away before it ran.
fn unread(args: &[&str]) -> Output {
    let (reader, writer) = std::io::pipe().expect("pipe");
    drop(reader);
    config_tool(args)
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .expect("runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Status and standard error of `out`.
fn ended(out: &Output) -> (Option<i32>, String) {
    (out.status.code(), text(&out.stderr))
}

#[test]
fn a_report_nobody_reads_ends_with_the_status_and_errors_of_one_read() {
    for (args, status) in [
        (&["check", "robot-configs/paint-robot.ron"][..], 0),
        (&["verify", "robot-configs/paint-robot.ron"], 0),
        // A verification that fails: its status says so though nobody reads why.
        (&["verify", "tests/fixtures/verify/order-deadlock.ron"], 1),
        (&["matrix", "robot-configs/waterjet-transport.ron"], 0),
        (
            &["diagram", "robot-configs/paint-robot.ron", "--role", "VC"],
            0,
        ),
        (&["sim", "robot-configs/paint-robot.ron"], 0),
        // Errors too.
        (&["check", "tests/fixtures/no-such-robot.ron"], 1),
    ] {
        let (read, unread) = (read(args), unread(args));
        assert_eq!(read.status.code(), Some(status), "{args:?}");
        assert_eq!(ended(&unread), ended(&read), "{args:?}");
    }
}

#[test]
fn a_command_whose_files_are_written_says_so_though_nobody_reads() {
    let dir = std::env::temp_dir().join(format!("closed-output-{}", std::process::id()));
    let out = dir.to_str().expect("a text path");
    let done = unread(&["compile", "robot-configs/paint-robot.ron", "--out", out]);
    let blobs: Vec<bool> = ["VC", "GR", "HC", "RC"]
        .iter()
        .map(|r| dir.join(format!("{r}.bin")).is_file())
        .collect();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(done.status.code(), Some(0), "{}", text(&done.stderr));
    assert_eq!(blobs, [true; 4]);
}

/// Where the output is a full disk, the report is lost: the command fails and says why,
/// once its work is done.
#[cfg(target_os = "linux")]
#[test]
fn a_report_written_to_a_full_disk_fails_the_command() {
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .expect("/dev/full");
    let out = config_tool(&["verify", "robot-configs/paint-robot.ron"])
        .stdout(full)
        .output()
        .expect("runs");
    assert_eq!(
        ended(&out),
        (
            Some(1),
            "error: cannot write standard output: No space left on device (os error 28)\n"
                .to_string()
        )
    );
}

/// A node whose log nobody reads (a supervisor that dropped its standard error) goes on
/// running: it died of a panic at its first log line, before it joined the medium.
#[test]
fn a_node_whose_log_is_closed_goes_on_running() {
    use config_schema::wire::mac;
    use config_schema::wire::medium::{Link, Peer};
    use std::time::{Duration, Instant};

    let medium = medium::Medium::start(medium::Config::default()).expect("medium");
    let mut monitor = medium::Conn::join(medium.addr(), Peer::Monitor).expect("monitor");
    let (reader, writer) = std::io::pipe().expect("pipe");
    drop(reader);
    let mut node = config_tool(&["node", "--addr", "0x0011"])
        .args(["--medium", &medium.addr().to_string()])
        .stdout(Stdio::null())
        .stderr(writer)
        .spawn()
        .expect("runs");
    // Its first frame (the unconfigured node's announce) comes after its first log lines.
    // A bound, not a pace: a loaded machine starts a debug build slowly.
    let until = Instant::now() + Duration::from_secs(60);
    let heard = monitor.recv(until, |link| match link {
        Link::Frame(psdu) => match mac::Frame::parse(psdu) {
            Ok(mac::Frame::Data { header, .. }) if header.src == 0x0011 => Some(()),
            _ => None,
        },
        _ => None,
    });
    let running = node.try_wait().expect("waits").is_none();
    let _ = node.kill();
    let status = node.wait().expect("waits");
    medium.stop();
    assert_eq!(
        (heard.ok().flatten(), running),
        (Some(()), true),
        "{status}"
    );
}
