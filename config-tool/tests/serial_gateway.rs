//! `--serial`: the radio commands reach nodes through a gateway on a serial port. The
//! gateway's serial end is played by a pseudo-terminal whose other side (a small Python
//! relay) joins a second medium, the "air", where a real node runs: the tool's frames go
//! medium -> serial bridge -> pty -> air -> node, and the answers come back the same way.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use config_schema::wire::medium::{Link, Peer};
use medium::{Config, Medium};

/// Opens a pty in raw mode, prints its slave's path, and relays bytes between the master and
/// a TCP connection to the air (joined as a monitor: it hears every frame and may send).
const RELAY: &str = r#"
import os, pty, select, socket, sys, tty
port = int(sys.argv[1])
master, slave = pty.openpty()
tty.setraw(slave)
print(os.ttyname(slave), flush=True)
air = socket.create_connection(("127.0.0.1", port))
air.sendall(bytes([2, 0, 0, 3]))  # Link::Hello(Peer::Monitor): length 2, postcard 00 03
while True:
    r, _, _ = select.select([master, air], [], [])
    if master in r:
        data = os.read(master, 4096)
        if not data:
            break
        air.sendall(data)
    if air in r:
        data = air.recv(4096)
        if not data:
            break
        os.write(master, data)
"#;

struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn scan_and_status_reach_a_node_through_the_serial_gateway() {
    // The relay's hello, by hand, is the real one.
    let mut hello = [0u8; 8];
    let n = Link::Hello(Peer::Monitor).emit(&mut hello).unwrap();
    assert_eq!(&hello[..n], &[2, 0, 0, 3]);
    let air = Medium::start(Config::default()).unwrap();
    let _node = Killed(
        Command::new(env!("CARGO_BIN_EXE_config-tool"))
            .args(["node", "--addr", "0x0021", "--medium"])
            .arg(air.addr().to_string())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let mut relay = Killed(
        Command::new("python3")
            .args(["-c", RELAY, &air.addr().port().to_string()])
            .stdout(Stdio::piped())
            .spawn()
            .expect("python3 runs"),
    );
    let mut line = String::new();
    BufReader::new(relay.0.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let pty = line.trim().to_string();
    assert!(pty.starts_with("/dev/"), "{pty}");
    assert!(
        air.wait_for_clients(2, Duration::from_secs(10)),
        "node and relay"
    );

    // The node announces itself every second while unconfigured: scan finds it.
    let end = Instant::now() + Duration::from_secs(20);
    let found = loop {
        let out = Command::new(env!("CARGO_BIN_EXE_config-tool"))
            .args(["scan", "--serial", &pty])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        if text.contains("0x0021") || Instant::now() > end {
            break text;
        }
    };
    assert!(
        found.contains("0x0021  firmware 1  generation 0  (unconfigured)"),
        "{found}"
    );
    let out = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["status", "--serial", &pty, "--node", "0x0021"])
        .output()
        .unwrap();
    let status = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{status}");
    assert!(
        status.starts_with("0x0021  role (unconfigured)  generation 0"),
        "{status}"
    );
    // The frames really crossed the air medium.
    assert!(air.stats().frames >= 4, "{:?}", air.stats());
    air.stop();
}

#[test]
fn the_plant_refuses_a_serial_port() {
    let out = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args([
            "plant",
            concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../robot-configs/paint-robot.ron"
            ),
            "--serial",
            "/dev/null",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "error: the plant is the simulated machine: it needs a medium, not --serial\n"
    );
}

/// A serial port named by a link (`/dev/serial/by-id/...`, the stable name of a board) is a
/// terminal all the same: `stty` sets it, and refuses a baud it does not know (status 1).
/// Only paths starting with `/dev/tty` were set: such a port stayed in the line mode a
/// terminal starts in, the bad baud was taken, and the gateway heard nothing.
#[test]
fn a_serial_port_named_by_a_link_is_set_up_as_a_terminal() {
    // A pty held open while the test runs (until its standard input closes).
    let (_holder, path) = device(
        "import os, pty, sys\nm, s = pty.openpty()\nprint(os.ttyname(s), flush=True)\n\
         sys.stdin.read()\n",
    );
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("by-id-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("usb-SEGGER_J-Link-if00");
    std::os::unix::fs::symlink(&path, &link).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["gateway", "--serial"])
        .arg(&link)
        .args(["--baud", "12345", "--listen", "127.0.0.1:0"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    // (stty says why first, in its own words.)
    let err = String::from_utf8_lossy(&out.stderr);
    let want = format!(
        "error: stty -F {} 12345 raw: exit status: 1\n",
        link.display()
    );
    assert!(err.ends_with(&want), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A gateway that goes away under a command (unplugged: the serial line ends as the tool's
/// first frame goes out) is said to have gone, and the command fails as on a medium that
/// went away. It waited 5 s and blamed the node ("did not answer ... pass --keys").
#[test]
fn a_gateway_that_goes_away_is_said_to_have_gone() {
    // A pty whose other side closes as the first byte reaches it.
    let (_device, pty) = device(
        "import os, pty, sys, tty\nm, s = pty.openpty()\ntty.setraw(s)\n\
         print(os.ttyname(s), flush=True)\nos.read(m, 1)\nos.close(m)\n",
    );
    let out = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["status", "--node", "0x0021", "--serial", &pty])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.starts_with(&format!("error: {}: the ", pty)), "{err}");
    assert!(!err.contains("did not answer"), "{err}");
}

/// A serial device played by `script` (Python): it prints its pty's path first, which is
/// returned with the process (killed when dropped).
fn device(script: &str) -> (Killed, String) {
    let mut process = Killed(
        Command::new("python3")
            .args(["-c", script])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("python3"),
    );
    let mut path = String::new();
    BufReader::new(process.0.stdout.as_mut().unwrap())
        .read_line(&mut path)
        .unwrap();
    (process, path.trim().to_string())
}

/// A serial port that is no terminal (`/dev/null`, a regular file) is refused, status 1:
/// the gateway said it was listening and ended at once, status 0.
#[test]
fn a_serial_port_that_is_no_terminal_is_refused() {
    let out = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args([
            "gateway",
            "--serial",
            "/dev/null",
            "--listen",
            "127.0.0.1:0",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(String::from_utf8_lossy(&out.stdout), "");
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "error: /dev/null: not a serial port (not a terminal)\n"
    );
}
