//! Shared by the tests that run the `config-tool` binary: a run from the workspace root
//! (where `robot-configs/` is), and its output as text.
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::{Command, Output};

use robot_net::demo;

/// `config-tool demo ARGS`, run from the workspace root.
pub fn demo(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .arg("demo")
        .args(args)
        .current_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".."))
        .output()
        .expect("runs")
}

/// The image (`QEMU_ELF`, else the release build's) and QEMU, if both are there; panics
/// if they are not and `REQUIRE_QEMU` is set.
pub fn qemu_image() -> Option<PathBuf> {
    let elf = std::env::var_os("QEMU_ELF").map_or_else(
        || {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("..")
                .join(demo::QEMU_ELF)
        },
        PathBuf::from,
    );
    let missing = match (demo::check_elf(&elf), demo::check_qemu()) {
        (Ok(()), Ok(())) => return Some(elf),
        (Err(e), _) | (_, Err(e)) => e.to_string(),
    };
    assert!(
        std::env::var_os("REQUIRE_QEMU").is_none(),
        "REQUIRE_QEMU is set: {missing}"
    );
    eprintln!("skipped: {missing}");
    None
}

/// Bytes of a process's output as text.
pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// How an interrupted demo ended.
#[derive(Debug, PartialEq, Eq)]
pub struct Interrupted {
    /// Its exit status.
    pub status: Option<i32>,
    /// The end of its standard error.
    pub said: String,
    /// What it left in its temporary directory.
    pub left: Vec<String>,
    /// How many of the node processes it had started still ran once it ended.
    pub nodes_running: usize,
}

impl Interrupted {
    /// How an interrupted demo must end: status 130, saying so, nothing left behind.
    pub fn cleanly() -> Interrupted {
        Interrupted {
            status: Some(130),
            said: "demo: interrupted".into(),
            left: Vec::new(),
            nodes_running: 0,
        }
    }
}

/// `config-tool demo ARGS` (its own temporary directory) sent SIGTERM once the machine
/// moves (its first step said), as a supervisor stops it (Linux: node processes are
/// found in `/proc`).
#[cfg(target_os = "linux")]
pub fn interrupt_demo(args: &[&str]) -> Interrupted {
    use std::io::{BufRead, BufReader, Read};
    use std::process::Stdio;
    use std::time::{Duration, Instant};
    let tmp = std::env::temp_dir().join(format!(
        "interrupted-demo-{}-{}",
        std::process::id(),
        args.len()
    ));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).expect("temp dir");
    let mut child = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .arg("demo")
        .args(args)
        .current_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".."))
        .env("TMPDIR", &tmp)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("runs");
    // Its steps, on standard error.
    let mut steps = BufReader::new(child.stderr.take().expect("stderr"));
    let mut line = String::new();
    while !line.trim_end().ends_with("VC+") {
        line.clear();
        assert!(
            steps.read_line(&mut line).expect("reads") > 0,
            "the demo ended"
        );
    }
    let nodes = children(child.id());
    assert!(!nodes.is_empty(), "node processes");
    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(killed.success());
    let status = child.wait().expect("waits").code();
    let mut err = String::new();
    steps.read_to_string(&mut err).expect("reads");
    // A node ends as its medium closes, or by its parent's death signal: soon, not at once.
    let until = Instant::now() + Duration::from_secs(30);
    let mut nodes_running = nodes.len();
    while nodes_running > 0 && Instant::now() < until {
        nodes_running = nodes.iter().filter(|p| runs(**p)).count();
        std::thread::yield_now();
    }
    let left = std::fs::read_dir(&tmp)
        .expect("temp dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    let _ = std::fs::remove_dir_all(&tmp);
    Interrupted {
        status,
        said: err.lines().last().unwrap_or("").to_string(),
        left,
        nodes_running,
    }
}

/// What became of a node process started by hand once its medium stopped.
#[derive(Debug)]
pub struct MediumGone {
    /// Its exit status, or `None` if it still ran a minute after the medium stopped (it was
    /// killed then).
    pub status: Option<std::process::ExitStatus>,
    /// What it said on standard output.
    pub said: String,
    /// How many processes it had started (QEMU) when it had joined.
    pub started: usize,
    /// How many of them still ran once it ended.
    pub left: usize,
}

/// Runs `config-tool ARGS --medium ADDR` (a node started by hand) on a medium of its own,
/// waits until it joined, stops the medium and waits (at most a minute) for the node to
/// end.
#[cfg(target_os = "linux")]
pub fn node_after_its_medium_stops(args: &[&str]) -> MediumGone {
    use std::io::Read;
    use std::process::Stdio;
    use std::time::Duration;

    let medium = medium::Medium::start(medium::Config::default()).expect("medium");
    let mut node = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(args)
        .arg("--medium")
        .arg(medium.addr().to_string())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("node");
    // Joined: the node said hello (a QEMU node's firmware: QEMU runs).
    let joined = medium.wait_for_clients(1, Duration::from_secs(60));
    let started = children(node.id());
    let pid = node.id();
    let mut stdout = node.stdout.take();
    let (ended, exit) = std::sync::mpsc::channel();
    std::thread::spawn(move || ended.send(node.wait()));
    medium.stop();
    let status = match exit.recv_timeout(Duration::from_secs(60)) {
        Ok(status) => Some(status.expect("wait")),
        Err(_) => {
            // Still running a minute later: ended here (the waiting thread reaps it).
            let _ = Command::new("kill").arg("-9").arg(pid.to_string()).status();
            let _ = exit.recv_timeout(Duration::from_secs(10));
            None
        }
    };
    assert!(joined, "the node never joined its medium");
    let mut said = String::new();
    if let Some(out) = stdout.as_mut() {
        let _ = out.read_to_string(&mut said);
    }
    let left = started.iter().filter(|&&p| runs(p)).count();
    MediumGone {
        status,
        said,
        started: started.len(),
        left,
    }
}

/// The processes whose parent is `pid`.
#[cfg(target_os = "linux")]
fn children(pid: u32) -> Vec<u32> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir("/proc").expect("/proc").flatten() {
        let Ok(p) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        // `pid (comm) state ppid ...`: the fields after the last `)`.
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{p}/stat")) else {
            continue;
        };
        let after = stat.rsplit_once(')').map_or("", |(_, rest)| rest);
        if after.split_whitespace().nth(1) == Some(&pid.to_string()) {
            found.push(p);
        }
    }
    found
}

/// Whether process `pid` runs (not ended, nor a zombie nobody reaped).
#[cfg(target_os = "linux")]
fn runs(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|stat| {
        let after = stat.rsplit_once(')').map_or("", |(_, rest)| rest);
        after.split_whitespace().next() != Some("Z")
    })
}
