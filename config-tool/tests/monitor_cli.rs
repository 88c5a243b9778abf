//! `config-tool monitor --keys FILE`: secured frames on the medium shown decrypted, the
//! ones that fail marked, an unsecured one shown as such; a key file others may read is
//! refused.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use config_schema::wire::mac::{self, Header, FCS};
use config_schema::wire::medium::{Link, Peer};
use config_schema::wire::msg::{Command as Cmd, Message};
use config_schema::wire::security::{ext_addr, secure, AuxRepr};
use medium::{Config, Conn, Medium};
use robot_keys::{link_key, load_machine_secret, management_key, write_machine_secret};

const SURE: Duration = Duration::from_secs(10);
const TOOL: u16 = 0x0100;
const VC: u16 = 0x0011;
const GR: u16 = 0x0012;

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn header(pan_id: u16, src: u16, dst: u16) -> Header {
    Header {
        seq: 1,
        pan_id,
        dst,
        src,
        ack_request: true,
        secured: false,
    }
}

fn payload(m: &Message) -> Vec<u8> {
    let mut buf = [0u8; 116];
    let n = m.emit(&mut buf).unwrap();
    buf[..n].to_vec()
}

/// `config-tool monitor --medium M ARGS` on `medium`, once it joined (`medium` has one
/// client before it): the process and its lines as they come.
fn monitor(medium: &Medium, args: &[&str]) -> (Child, mpsc::Receiver<String>) {
    let mut monitor = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["monitor", "--medium", &medium.addr().to_string()])
        .args(args)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let out = monitor.stdout.take().unwrap();
    let (tx, lines) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    assert!(medium.wait_for_clients(2, SURE), "the monitor joins");
    (monitor, lines)
}

fn sealed(h: Header, index: u8, counter: u32, key: &[u8; 16], m: &Message) -> Vec<u8> {
    let mut psdu = [0u8; 127];
    let aux = AuxRepr::new(index, counter);
    let src = ext_addr(h.pan_id, h.src);
    let n = secure(&h, &aux, key, src, &payload(m), &mut psdu).unwrap();
    psdu[..n].to_vec()
}

#[test]
fn monitor_with_the_key_file_shows_secured_frames_decrypted_and_marks_the_bad_ones() {
    let dir = scratch("monitor-keys");
    let keys = dir.join("machine.key");
    write_machine_secret(&keys, false).unwrap();
    let secret = load_machine_secret(&keys).unwrap();
    let medium = Medium::start(Config::default()).unwrap();
    let mut radio = Conn::join(medium.addr(), Peer::Tool { addr: TOOL }).unwrap();
    let keys_s = keys.to_str().unwrap();
    let (mut monitor, lines) = monitor(&medium, &["--keys", keys_s, "--generation", "3"]);

    let start = Message::Command {
        id: 3,
        command: Cmd::Start,
    };
    let event = Message::Event {
        epoch: 1,
        seq: 4,
        topic: 2,
    };
    let mgmt = management_key(&secret, VC);
    let link = link_key(&secret, 3, VC, GR);
    let secured_start = sealed(header(0xFFFF, TOOL, VC), 0, 42, mgmt.expose(), &start);
    let mut flipped = secured_start.clone();
    flipped[16] ^= 0x01;
    let n = flipped.len() - 2;
    let fcs = FCS.checksum(&flipped[..n]);
    flipped[n..].copy_from_slice(&fcs.to_le_bytes());
    let secured_event = sealed(header(0xBEEF, VC, GR), 4, 7, link.expose(), &event);
    let unknown = sealed(header(0xBEEF, VC, GR), 9, 8, link.expose(), &event);
    let mut clear = [0u8; 127];
    let n = mac::emit_data(&header(0xFFFF, TOOL, VC), &payload(&start), &mut clear).unwrap();
    for f in [
        &secured_start,
        &flipped,
        &secured_event,
        &unknown,
        &clear[..n].to_vec(),
    ] {
        radio.send(&Link::Frame(f)).unwrap();
    }
    let seen: Vec<String> = (0..5)
        .map(|_| {
            let line = lines.recv_timeout(SURE).expect("the monitor prints a line");
            // The time the frame reached the monitor, then the frame.
            let (_, frame) = line.trim_start().split_once("  ").unwrap();
            frame.to_string()
        })
        .collect();
    let _ = monitor.kill();
    let _ = monitor.wait();
    medium.stop();
    assert_eq!(
        seen,
        [
            "0x0100 -> 0x0011  secured EncMic64 key 0 counter 42: Command { id: 3, command: Start }",
            "0x0100 -> 0x0011  secured EncMic64 key 0 counter 42: BAD MIC, 11 bytes sealed",
            "0x0011 -> 0x0012  secured EncMic64 key 4 counter 7: Event { epoch: 1, seq: 4, topic: 2 }",
            "0x0011 -> 0x0012  secured EncMic64 key 9 counter 8: unknown key, 12 bytes sealed",
            "0x0100 -> 0x0011  unsecured: Command { id: 3, command: Start }",
        ]
    );
}

#[cfg(unix)]
#[test]
fn monitor_refuses_a_key_file_others_may_read() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch("monitor-keys-open");
    let keys = dir.join("machine.key");
    write_machine_secret(&keys, false).unwrap();
    std::fs::set_permissions(&keys, std::fs::Permissions::from_mode(0o644)).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["monitor", "--medium", "127.0.0.1:1", "--keys"])
        .arg(&keys)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&keys.display().to_string()) && err.contains("644"),
        "{err}"
    );
    assert!(out.stdout.is_empty());
}

/// The tool's START to VC, unsecured, as a PSDU.
fn clear_start() -> Vec<u8> {
    let mut clear = [0u8; 127];
    let start = Message::Command {
        id: 3,
        command: Cmd::Start,
    };
    let n = mac::emit_data(&header(0xFFFF, TOOL, VC), &payload(&start), &mut clear).unwrap();
    clear[..n].to_vec()
}

/// Waits (at most [`SURE`]) until `child` (`what`) ends: its exit status and standard
/// error.
fn ended(child: &mut Child, what: &str) -> (std::process::ExitStatus, String) {
    let until = std::time::Instant::now() + SURE;
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        assert!(std::time::Instant::now() < until, "{what} still runs");
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    (status, err)
}

/// Issue: `config-tool monitor ... | head -1` ended with a panic message (printing to a
/// pipe whose reader went away panicked). It ends as a filter does: quietly, status 0.
#[test]
fn monitor_ends_quietly_when_its_reader_goes_away() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut radio = Conn::join(medium.addr(), Peer::Tool { addr: TOOL }).unwrap();
    let mut monitor = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["monitor", "--medium", &medium.addr().to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    assert!(medium.wait_for_clients(2, SURE), "the monitor joins");
    let start = clear_start();
    radio.send(&Link::Frame(&start)).unwrap();
    // `head -1`: one line read, then the pipe closed.
    let mut out = BufReader::new(monitor.stdout.take().unwrap());
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    assert!(line.contains("unsecured: Command"), "{line}");
    drop(out);
    // Its next line finds no reader.
    radio.send(&Link::Frame(&start)).unwrap();
    let (status, err) = ended(&mut monitor, "the monitor");
    medium.stop();
    assert_eq!((status.code(), err.as_str()), (Some(0), ""));
}

/// A pin's level told again (a plant repeats its switches' levels) is no change: the
/// monitor prints a pin's first level and each change, nothing else. Found: every
/// repeat, every 200 ms, as a change.
#[test]
fn monitor_prints_a_pin_only_when_its_level_changes() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut monitor = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["monitor", "--medium", &medium.addr().to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    assert!(medium.wait_for_clients(1, SURE), "the monitor joins");
    let mut plant = Conn::join(medium.addr(), Peer::Plant).unwrap();
    for level in [true, true, true, false, false, true] {
        plant
            .send(&Link::Pin {
                addr: VC,
                pin: 2,
                level,
            })
            .unwrap();
    }
    // Handled by the medium before the frame that marks the end of what to read.
    plant.sync().unwrap();
    let mut radio = Conn::join(medium.addr(), Peer::Tool { addr: TOOL }).unwrap();
    let start = clear_start();
    radio.send(&Link::Frame(&start)).unwrap();
    let (tx, rx) = mpsc::channel();
    let stdout = monitor.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let end = line.contains("unsecured: Command");
            let _ = tx.send(line);
            if end {
                break;
            }
        }
    });
    let mut pins = Vec::new();
    loop {
        let line = rx.recv_timeout(SURE).expect("the monitor's lines");
        if line.contains("unsecured: Command") {
            break;
        }
        let (_, pin) = line
            .trim_start()
            .split_once("  ")
            .expect("time, then the change");
        pins.push(pin.to_string());
    }
    let _ = monitor.kill();
    let _ = monitor.wait();
    medium.stop();
    assert_eq!(
        pins,
        [
            "pin 0x0011.2 = 1 (input)",
            "pin 0x0011.2 = 0 (input)",
            "pin 0x0011.2 = 1 (input)"
        ]
    );
}

/// A pin change and then a frame, from one node back to back: the monitor printed the
/// frame at its own clock (since the monitor started) and the pin at the medium's (since
/// the medium started), so the frame came out earlier than the pin before it. Both are on
/// the medium's clock now: the frame's time is not before the pin's.
#[test]
fn monitor_stamps_frames_and_pins_with_one_clock() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut node = Conn::join(medium.addr(), Peer::Node { addr: VC }).unwrap();
    let (mut monitor, lines) = monitor(&medium, &[]);
    let event = Message::Event {
        epoch: 1,
        seq: 0,
        topic: 2,
    };
    let mut psdu = [0u8; 127];
    let n = mac::emit_data(&header(0xBEEF, VC, GR), &payload(&event), &mut psdu).unwrap();
    node.send(&Link::Pin {
        addr: VC,
        pin: 3,
        level: true,
    })
    .unwrap();
    node.send(&Link::Frame(&psdu[..n])).unwrap();
    let mut times = Vec::new();
    for what in [
        "pin 0x0011.3 = 1 (output)",
        "0x0011 -> 0x0012  unsecured: Event",
    ] {
        let line = lines.recv_timeout(SURE).expect("the monitor prints a line");
        let (time, rest) = line.trim_start().split_once("  ").unwrap();
        assert!(rest.starts_with(what), "{line}");
        times.push(time.parse::<f64>().unwrap());
    }
    let _ = monitor.kill();
    let _ = monitor.wait();
    medium.stop();
    assert!(
        times[1] >= times[0],
        "frame at {} s, the pin before it at {} s",
        times[1],
        times[0]
    );
}

/// `monitor` and `plant` ended with status 0 and said nothing when the medium went away
/// (its process killed, its machine rebooted): the operator watching took the silence for
/// a quiet machine. Each now says the medium closed the connection, status 1.
#[test]
fn monitor_and_plant_say_so_when_the_medium_goes_away() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    for (args, what) in [
        (
            vec!["monitor"],
            "monitor: the medium at {at} closed the connection",
        ),
        (
            vec!["plant", "robot-configs/paint-robot.ron"],
            "plant on {at}: the medium closed the connection",
        ),
    ] {
        let medium = Medium::start(Config::default()).unwrap();
        let at = medium.addr().to_string();
        let mut child = Command::new(env!("CARGO_BIN_EXE_config-tool"))
            .current_dir(root)
            .args(&args)
            .args(["--medium", &at])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        assert!(medium.wait_for_clients(1, SURE), "{what} joins");
        medium.stop();
        let (status, err) = ended(&mut child, what);
        let want = format!("error: {} (it went away)\n", what.replace("{at}", &at));
        assert_eq!((status.code(), err.as_str()), (Some(1), want.as_str()));
    }
}

/// `--seconds` past what the clock holds (u64::MAX) is no end a run reaches, not a panic
/// (status 101 at once); so is `--wait` of `home` and of a watched push, which panicked
/// after HOME or the switch was sent (their deadline is `robot_net::deadline`, tested
/// there).
#[test]
fn monitor_for_more_seconds_than_the_clock_holds_runs() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut radio = Conn::join(medium.addr(), Peer::Tool { addr: TOOL }).unwrap();
    let (mut monitor, lines) = monitor(&medium, &["--seconds", &u64::MAX.to_string()]);
    radio.send(&Link::Frame(&clear_start())).unwrap();
    let line = lines.recv_timeout(SURE);
    let _ = monitor.kill();
    let _ = monitor.wait();
    medium.stop();
    assert!(
        line.as_deref()
            .is_ok_and(|l| l.contains("unsecured: Command")),
        "{line:?}"
    );
}
