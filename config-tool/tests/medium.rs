//! The simulated medium with real TCP clients: routing by address, broadcast, monitors,
//! pins between nodes and plants, faults, airtime accounting and the pcap capture.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use config_schema::wire::mac::{self, Frame, Header, BROADCAST, MAX_PSDU};
use config_schema::wire::medium::{next_message, Link, Peer, MAX_LINK};
use config_tool::medium::{Config, Medium};

struct Client {
    stream: TcpStream,
    buf: Vec<u8>,
}

/// What a client received.
#[derive(Debug, PartialEq)]
enum Got {
    Frame(Vec<u8>),
    Pin(u16, u8, bool),
}

impl Client {
    fn join(medium: &Medium, peer: Peer) -> Client {
        let stream = TcpStream::connect(medium.addr()).unwrap();
        let mut c = Client {
            stream,
            buf: Vec::new(),
        };
        c.send(&Link::Hello(peer));
        c
    }
    fn send(&mut self, msg: &Link) {
        let mut buf = [0u8; MAX_LINK];
        let n = msg.emit(&mut buf).unwrap();
        self.stream.write_all(&buf[..n]).unwrap();
    }
    /// The next message, or `None` after `wait`.
    fn recv(&mut self, wait: Duration) -> Option<Got> {
        self.stream.set_read_timeout(Some(wait)).unwrap();
        loop {
            if let Some(body) = next_message(&self.buf) {
                let got = match Link::parse(&self.buf[body.clone()]).unwrap() {
                    Link::Frame(f) => Got::Frame(f.to_vec()),
                    Link::Pin { addr, pin, level } => Got::Pin(addr, pin, level),
                    Link::Hello(_) => panic!("the medium never says hello"),
                };
                self.buf.drain(..body.end);
                return Some(got);
            }
            let mut chunk = [0u8; 512];
            match self.stream.read(&mut chunk) {
                Ok(0) | Err(_) => return None,
                Ok(n) => self.buf.extend_from_slice(&chunk[..n]),
            }
        }
    }
}

const SURE: Duration = Duration::from_secs(5);
const QUIET: Duration = Duration::from_millis(300);

fn frame(src: u16, dst: u16, payload: &[u8]) -> Vec<u8> {
    let header = Header {
        seq: 1,
        pan_id: 0x1234,
        dst,
        src,
        ack_request: false,
        secured: false,
    };
    let mut psdu = [0u8; MAX_PSDU];
    let n = mac::emit_data(&header, payload, &mut psdu).unwrap();
    psdu[..n].to_vec()
}

/// Waits until the medium registered `n` clients (a frame sent before a join is not seen).
fn settle(medium: &Medium, n: u64) {
    assert!(medium.wait_for_clients(n, SURE), "{n} clients did not join");
}

#[test]
fn frames_go_to_their_destination_broadcasts_to_every_radio_monitors_see_all() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    let mut tool = Client::join(&medium, Peer::Tool { addr: 0x100 });
    let mut monitor = Client::join(&medium, Peer::Monitor);
    settle(&medium, 4);
    let to_a = frame(0x100, 0x11, b"hello a");
    tool.send(&Link::Frame(&to_a));
    assert_eq!(a.recv(SURE), Some(Got::Frame(to_a.clone())));
    assert_eq!(monitor.recv(SURE), Some(Got::Frame(to_a)));
    assert_eq!(b.recv(QUIET), None);
    let all = frame(0x11, BROADCAST, b"here I am");
    a.send(&Link::Frame(&all));
    assert_eq!(b.recv(SURE), Some(Got::Frame(all.clone())));
    assert_eq!(tool.recv(SURE), Some(Got::Frame(all.clone())));
    assert_eq!(monitor.recv(SURE), Some(Got::Frame(all)));
    assert_eq!(a.recv(QUIET), None, "not back to the sender");
    let s = medium.stats();
    assert_eq!((s.frames, s.delivered), (2, 3));
    medium.stop();
}

#[test]
fn output_pins_reach_plants_and_plant_inputs_reach_their_node_only() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    let mut plant = Client::join(&medium, Peer::Plant);
    settle(&medium, 3);
    a.send(&Link::Pin {
        addr: 0x11,
        pin: 3,
        level: true,
    });
    assert_eq!(plant.recv(SURE), Some(Got::Pin(0x11, 3, true)));
    plant.send(&Link::Pin {
        addr: 0x12,
        pin: 2,
        level: true,
    });
    assert_eq!(b.recv(SURE), Some(Got::Pin(0x12, 2, true)));
    assert_eq!(a.recv(QUIET), None);
    medium.stop();
}

#[test]
fn total_loss_delivers_nothing_and_counts_it() {
    let medium = Medium::start(Config {
        loss: 1.0,
        ..Config::default()
    })
    .unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    let mut monitor = Client::join(&medium, Peer::Monitor);
    settle(&medium, 3);
    let f = frame(0x11, 0x12, b"lost");
    a.send(&Link::Frame(&f));
    assert_eq!(monitor.recv(SURE), Some(Got::Frame(f)), "it was on the air");
    assert_eq!(b.recv(QUIET), None);
    assert_eq!(medium.stats().lost, 1);
    medium.stop();
}

#[test]
fn corruption_breaks_the_fcs() {
    let medium = Medium::start(Config {
        corrupt: 1.0,
        ..Config::default()
    })
    .unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    settle(&medium, 2);
    let f = frame(0x11, 0x12, b"damaged");
    a.send(&Link::Frame(&f));
    let Some(Got::Frame(got)) = b.recv(SURE) else {
        panic!("nothing arrived")
    };
    assert_ne!(got, f);
    assert_eq!(Frame::parse(&got), Err(mac::FrameError::BadFcs));
    assert_eq!(medium.stats().corrupted, 1);
    medium.stop();
}

#[test]
fn airtime_is_accounted_at_250_kbit_per_second() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    settle(&medium, 2);
    let big = frame(0x11, 0x12, &[0x55; mac::MAX_PAYLOAD]);
    assert_eq!(big.len(), MAX_PSDU);
    for _ in 0..10 {
        a.send(&Link::Frame(&big));
    }
    for _ in 0..10 {
        assert_eq!(b.recv(SURE), Some(Got::Frame(big.clone())));
    }
    let s = medium.stats();
    assert_eq!(s.airtime_us, 10 * 4256);
    assert_eq!(s.bytes, 10 * 127);
    medium.stop();
}

#[test]
fn the_capture_is_a_pcap_of_link_type_195_with_every_frame() {
    let dir = std::env::temp_dir().join(format!("medium-pcap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("air.pcap");
    let medium = Medium::start(Config {
        pcap: Some(path.clone()),
        loss: 1.0,
        ..Config::default()
    })
    .unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut monitor = Client::join(&medium, Peer::Monitor);
    settle(&medium, 2);
    let frames: Vec<Vec<u8>> = (0..3u8).map(|i| frame(0x11, 0x12, &[i; 4])).collect();
    for f in &frames {
        a.send(&Link::Frame(f));
        assert_eq!(monitor.recv(SURE), Some(Got::Frame(f.clone())));
    }
    medium.stop();
    let bytes = std::fs::read(&path).unwrap();
    let mut reader = pcap_file::pcap::PcapReader::new(&bytes[..]).unwrap();
    assert_eq!(u32::from(reader.header().datalink), 195);
    let mut got = Vec::new();
    while let Some(p) = reader.next_packet() {
        got.push(p.unwrap().data.to_vec());
    }
    assert_eq!(got, frames, "lost frames were on the air too");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn only_loopback_is_served_and_garbage_disconnects() {
    let err = Medium::start(Config {
        listen: "0.0.0.0:0".parse().unwrap(),
        ..Config::default()
    })
    .err()
    .unwrap();
    assert_eq!(err.kind(), std::io::ErrorKind::InvalidInput);
    let medium = Medium::start(Config::default()).unwrap();
    let mut rogue = TcpStream::connect(medium.addr()).unwrap();
    rogue.write_all(&[3, 0, 0xFF, 0xFF, 0xFF]).unwrap();
    rogue.set_read_timeout(Some(SURE)).unwrap();
    let mut buf = [0u8; 8];
    assert!(matches!(rogue.read(&mut buf), Ok(0) | Err(_)), "closed");
    // The medium still serves others.
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    settle(&medium, 2);
    let f = frame(0x11, 0x12, b"still here");
    a.send(&Link::Frame(&f));
    assert_eq!(b.recv(SURE), Some(Got::Frame(f)));
    medium.stop();
}

/// Wireshark's decoder agrees: every frame of the capture is IEEE 802.15.4 with a good FCS
/// and the addresses that were sent. Needs `tshark`; CI installs it and sets
/// `REQUIRE_TSHARK=1`, so there a missing tshark fails instead of skipping.
#[test]
fn tshark_decodes_the_capture() {
    let have = std::process::Command::new("tshark")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !have {
        assert!(
            std::env::var_os("REQUIRE_TSHARK").is_none(),
            "REQUIRE_TSHARK is set but tshark is not installed"
        );
        eprintln!("tshark not installed: skipped");
        return;
    }
    let dir = std::env::temp_dir().join(format!("medium-tshark-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("air.pcap");
    let medium = Medium::start(Config {
        pcap: Some(path.clone()),
        ..Config::default()
    })
    .unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    settle(&medium, 2);
    let frames = [
        frame(0x11, 0x12, b"one"),
        frame(0x12, 0x11, b"two"),
        frame(0x11, BROADCAST, b"all"),
    ];
    a.send(&Link::Frame(&frames[0]));
    assert!(b.recv(SURE).is_some());
    b.send(&Link::Frame(&frames[1]));
    assert!(a.recv(SURE).is_some());
    a.send(&Link::Frame(&frames[2]));
    assert!(b.recv(SURE).is_some());
    medium.stop();
    let out = std::process::Command::new("tshark")
        .args(["-r"])
        .arg(&path)
        .args([
            "--disable-protocol",
            "lwm",
            "--disable-protocol",
            "6lowpan",
            "--disable-protocol",
            "zbee_nwk",
            "--disable-protocol",
            "zbee_nwk_gp",
            "-T",
            "fields",
            "-e",
            "wpan.src16",
            "-e",
            "wpan.dst16",
            "-e",
            "wpan.fcs_ok",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(
        rows,
        [
            "0x0011\t0x0012\t1",
            "0x0012\t0x0011\t1",
            "0x0011\t0xffff\t1"
        ]
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
