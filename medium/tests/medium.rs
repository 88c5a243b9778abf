//! The simulated medium with real TCP clients: routing by address, broadcast, monitors,
//! pins between nodes and plants, faults, airtime accounting and the pcap capture.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use config_schema::wire::mac::{self, Frame, Header, BROADCAST, MAX_PSDU};
use config_schema::wire::medium::{Deframer, Link, Peer, MAX_LINK};
use medium::{Config, Medium};

struct Client {
    stream: TcpStream,
    incoming: Box<Deframer<{ 16 * MAX_LINK }>>,
}

/// What a client received.
#[derive(Debug, PartialEq)]
enum Got {
    Frame(Vec<u8>),
    Pin(u16, u8, bool),
    Running(u16, u32),
    Welcome,
    Synced(u32),
}

impl Client {
    /// Joins and waits for the medium's welcome: from then on the client is routed to.
    fn join(medium: &Medium, peer: Peer) -> Client {
        let mut c = Client::hello(medium, peer);
        assert_eq!(
            c.recv(SURE),
            Some(Got::Welcome),
            "the medium welcomes a client"
        );
        c
    }
    /// Connects and says hello, without waiting.
    fn hello(medium: &Medium, peer: Peer) -> Client {
        let stream = TcpStream::connect(medium.addr()).unwrap();
        stream.set_nodelay(true).unwrap();
        let mut c = Client {
            stream,
            incoming: Box::default(),
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
            if let Some(body) = self.incoming.take().unwrap() {
                let got = match Link::parse(body).unwrap() {
                    Link::Frame(f) => Got::Frame(f.to_vec()),
                    Link::Pin { addr, pin, level }
                    | Link::Seen {
                        addr, pin, level, ..
                    } => Got::Pin(addr, pin, level),
                    Link::Running { addr, generation } => Got::Running(addr, generation),
                    Link::Welcome => Got::Welcome,
                    Link::Synced(n) => Got::Synced(n),
                    other => panic!("the medium never says {other:?}"),
                };
                return Some(got);
            }
            match self.stream.read(self.incoming.space()) {
                Ok(0) | Err(_) => return None,
                Ok(n) => self.incoming.filled(n),
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

#[test]
fn frames_go_to_their_destination_broadcasts_to_every_radio_monitors_see_all() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    let mut tool = Client::join(&medium, Peer::Tool { addr: 0x100 });
    let mut monitor = Client::join(&medium, Peer::Monitor);
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
fn a_cut_link_delivers_nothing_from_one_radio_to_the_other_and_everything_else() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    let mut tool = Client::join(&medium, Peer::Tool { addr: 0x100 });
    let mut monitor = Client::join(&medium, Peer::Monitor);
    medium.cut(0x11, 0x12);
    // The air is one channel, in order: what b receives next after a's frames is the
    // tool's frame, so a's never reached it.
    let all = frame(0x11, BROADCAST, b"here I am");
    let direct = frame(0x11, 0x12, b"to b");
    let marker = frame(0x100, 0x12, b"after");
    a.send(&Link::Frame(&all));
    a.send(&Link::Frame(&direct));
    assert_eq!(tool.recv(SURE), Some(Got::Frame(all.clone())));
    tool.send(&Link::Frame(&marker));
    assert_eq!(b.recv(SURE), Some(Got::Frame(marker.clone())));
    assert_eq!(
        monitor.recv(SURE),
        Some(Got::Frame(all)),
        "the air still carries it"
    );
    assert_eq!(monitor.recv(SURE), Some(Got::Frame(direct)));
    assert_eq!(monitor.recv(SURE), Some(Got::Frame(marker)));
    let back = frame(0x12, 0x11, b"to a");
    b.send(&Link::Frame(&back));
    assert_eq!(
        a.recv(SURE),
        Some(Got::Frame(back)),
        "the other direction works"
    );
    assert_eq!(medium.stats().cut, 2);
    medium.stop();
}

#[test]
fn messages_read_during_syncs_come_out_in_the_order_they_came() {
    use medium::Conn;
    use std::time::Instant;
    let medium = Medium::start(Config::default()).unwrap();
    let mut plant = Conn::join(medium.addr(), Peer::Plant).unwrap();
    let mut node = Conn::join(medium.addr(), Peer::Node { addr: 0x11 }).unwrap();
    for pin in [1, 2] {
        node.send(&Link::Pin {
            addr: 0x11,
            pin,
            level: true,
        })
        .unwrap();
        // The node's level is at the plant before the plant's sync is answered.
        node.sync().unwrap();
        plant.sync().unwrap();
    }
    let until = Instant::now() + SURE;
    let mut got = Vec::new();
    while got.len() < 2 {
        let pin = plant.recv(until, |l| l.output_seen().map(|(_, _, pin, _)| pin));
        got.push(pin.unwrap().expect("held"));
    }
    assert_eq!(got, [1, 2]);
    medium.stop();
}

#[test]
fn output_pins_reach_plants_and_plant_inputs_reach_their_node_only() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    let mut plant = Client::join(&medium, Peer::Plant);
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

/// A node that goes away (its process killed: a power cut) drops every output it held
/// high, for plants and monitors, as its de-energized valves do; a low one says nothing.
#[test]
fn a_node_that_goes_away_drops_the_outputs_it_held_high() {
    let medium = Medium::start(Config::default()).unwrap();
    let a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut a = a;
    let mut plant = Client::join(&medium, Peer::Plant);
    let mut monitor = Client::join(&medium, Peer::Monitor);
    for (pin, level) in [(3, true), (5, true), (5, false), (9, true)] {
        a.send(&Link::Pin {
            addr: 0x11,
            pin,
            level,
        });
        for c in [&mut plant, &mut monitor] {
            assert_eq!(c.recv(SURE), Some(Got::Pin(0x11, pin, level)));
        }
    }
    drop(a);
    for c in [&mut plant, &mut monitor] {
        assert_eq!(c.recv(SURE), Some(Got::Pin(0x11, 3, false)));
        assert_eq!(c.recv(SURE), Some(Got::Pin(0x11, 9, false)));
        assert_eq!(c.recv(QUIET), None);
    }
    medium.stop();
}

/// A node's running generation reaches plants and monitors in order with its pins (and a
/// plant that joins later); a node cannot speak for another, a plant not at all.
#[test]
fn a_nodes_running_generation_reaches_plants_and_monitors_before_its_pins() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    let mut plant = Client::join(&medium, Peer::Plant);
    let mut monitor = Client::join(&medium, Peer::Monitor);
    b.send(&Link::Running {
        addr: 0x11,
        generation: 9,
    });
    plant.send(&Link::Running {
        addr: 0x12,
        generation: 9,
    });
    a.send(&Link::Running {
        addr: 0x11,
        generation: 2,
    });
    a.send(&Link::Pin {
        addr: 0x11,
        pin: 0,
        level: true,
    });
    for c in [&mut plant, &mut monitor] {
        assert_eq!(c.recv(SURE), Some(Got::Running(0x11, 2)));
        assert_eq!(c.recv(SURE), Some(Got::Pin(0x11, 0, true)));
    }
    assert_eq!(b.recv(QUIET), None, "nodes are not told");
    // A plant that joins later is told what every connected node runs, after its welcome.
    let mut late = Client::hello(&medium, Peer::Plant);
    assert_eq!(late.recv(SURE), Some(Got::Welcome));
    assert_eq!(late.recv(SURE), Some(Got::Running(0x11, 2)));
    assert_eq!(late.recv(QUIET), None);
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

/// Issue: a plant attached right before START missed the first valve command, because the
/// medium registered it later than it returned. A welcomed client is routed to at once, and
/// a sync orders a client's messages before everything sent after it.
#[test]
fn a_welcomed_client_is_routed_to_at_once_and_sync_orders_its_levels() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut node = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut tool = Client::join(&medium, Peer::Tool { addr: 0x100 });
    for i in 0..100u8 {
        let mut plant = Client::join(&medium, Peer::Plant);
        // The node's output, right after the welcome, reaches the new plant.
        node.send(&Link::Pin {
            addr: 0x11,
            pin: i % 4,
            level: true,
        });
        assert_eq!(
            plant.recv(SURE),
            Some(Got::Pin(0x11, i % 4, true)),
            "round {i}"
        );
        // The plant's level, then its sync: a frame sent after the sync reaches the node
        // after the level.
        plant.send(&Link::Pin {
            addr: 0x11,
            pin: 2,
            level: i.is_multiple_of(2),
        });
        plant.send(&Link::Sync(u32::from(i)));
        assert_eq!(plant.recv(SURE), Some(Got::Synced(u32::from(i))));
        let start = frame(0x100, 0x11, &[i]);
        tool.send(&Link::Frame(&start));
        assert_eq!(
            node.recv(SURE),
            Some(Got::Pin(0x11, 2, i.is_multiple_of(2))),
            "round {i}"
        );
        assert_eq!(node.recv(SURE), Some(Got::Frame(start)), "round {i}");
    }
    medium.stop();
}

/// Resident memory of this process, kB.
fn rss_kb() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap()
}

/// Issue: 10,000 frames/s to a missing address left `status` unanswered for 23 s after
/// the flood; pins without airtime grew the medium to gigabytes. Every queue is bounded,
/// drops are counted, and the medium answers at once after the flood.
#[test]
fn floods_of_frames_and_pins_are_dropped_and_counted_and_the_medium_answers_at_once() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    let mut plant = Client::join(&medium, Peer::Plant);
    let before = rss_kb();
    let flood = |peer: Peer, msg: Vec<u8>| {
        let medium_addr = medium.addr();
        std::thread::spawn(move || {
            let mut c = TcpStream::connect(medium_addr).unwrap();
            let mut hello = [0u8; MAX_LINK];
            let n = Link::Hello(peer).emit(&mut hello).unwrap();
            c.write_all(&hello[..n]).unwrap();
            let batch: Vec<u8> = msg.iter().copied().cycle().take(msg.len() * 500).collect();
            // 100,000 messages as fast as the socket takes them.
            for _ in 0..200 {
                if c.write_all(&batch).is_err() {
                    break;
                }
            }
        })
    };
    let mut buf = [0u8; MAX_LINK];
    let n = Link::Frame(&frame(0x66, 0x7777, &[0xEE; 100]))
        .emit(&mut buf)
        .unwrap();
    let missing = flood(Peer::Node { addr: 0x66 }, buf[..n].to_vec());
    let n = Link::Frame(&frame(0x67, BROADCAST, &[0xBB; 100]))
        .emit(&mut buf)
        .unwrap();
    let broadcast = flood(Peer::Node { addr: 0x67 }, buf[..n].to_vec());
    let n = Link::Pin {
        addr: 0x11,
        pin: 1,
        level: true,
    }
    .emit(&mut buf)
    .unwrap();
    let pins = flood(Peer::Plant, buf[..n].to_vec());
    missing.join().unwrap();
    broadcast.join().unwrap();
    pins.join().unwrap();
    // At once: a frame between two quiet nodes crosses, ahead of nothing but a bounded
    // queue.
    let f = frame(0x11, 0x12, b"status?");
    a.send(&Link::Frame(&f));
    loop {
        match b.recv(SURE) {
            Some(Got::Frame(got)) if got == f => break,
            Some(_) => continue,
            None => panic!("the frame did not cross after the flood"),
        }
    }
    let s = medium.stats();
    assert!(
        s.busy > 0,
        "frames past a sender's transmit queue are dropped: {s:?}"
    );
    assert!(
        s.rate_limited > 0,
        "messages past a client's rate are dropped: {s:?}"
    );
    assert!(
        s.queued <= 3 * 64 * 8,
        "deliveries in flight are bounded: {s:?}"
    );
    let grown = rss_kb().saturating_sub(before);
    assert!(grown < 64 * 1024, "the medium grew by {grown} kB");
    // The plant still gets the node's levels (it was never slow).
    a.send(&Link::Pin {
        addr: 0x11,
        pin: 0,
        level: true,
    });
    loop {
        match plant.recv(SURE) {
            Some(Got::Pin(0x11, 0, true)) => break,
            Some(_) => continue,
            None => panic!("the plant lost its levels"),
        }
    }
    medium.stop();
}

/// Issue: a monitor that never reads stopped the medium for every client. It is
/// disconnected past its own bounded outbox; the others never wait for it.
#[test]
fn a_monitor_that_never_reads_is_dropped_and_nobody_waits_for_it() {
    let medium = Medium::start(Config::default()).unwrap();
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    let deaf = Client::join(&medium, Peer::Monitor);
    socket2::SockRef::from(&deaf.stream)
        .set_recv_buffer_size(4096)
        .unwrap();
    let mut plant = Client::join(&medium, Peer::Plant);
    // Plants' levels for the node (and the monitor), far more than a socket and an outbox
    // hold, each plant within its rate.
    let mut senders: Vec<Client> = (0..4).map(|_| Client::join(&medium, Peer::Plant)).collect();
    let mut n = 0u32;
    while medium.stats().slow == 0 {
        for s in &mut senders {
            for _ in 0..40 {
                s.send(&Link::Pin {
                    addr: 0x11,
                    pin: (n % 8) as u8,
                    level: n.is_multiple_of(2),
                });
                n += 1;
            }
        }
        // The node and the plant read; they are never the ones dropped.
        while a.recv(Duration::from_millis(1)).is_some() {}
        while plant.recv(Duration::from_millis(1)).is_some() {}
        assert!(n < 1_000_000, "the deaf monitor was never dropped");
    }
    let f = frame(0x11, 0x12, b"after");
    a.send(&Link::Frame(&f));
    assert_eq!(b.recv(SURE), Some(Got::Frame(f)));
    assert_eq!(medium.stats().slow, 1);
    drop(deaf);
    medium.stop();
}

/// Issue: 5,000 connections that never said hello held 5,007 threads. Connections that
/// do not say hello are closed after `HELLO_TIMEOUT`, and only a few wait at once.
#[test]
fn silent_connections_are_capped_and_closed() {
    use medium::limits;
    let medium = Medium::start(Config::default()).unwrap();
    let threads = || -> u64 {
        let status = std::fs::read_to_string("/proc/self/status").unwrap();
        status
            .lines()
            .find_map(|l| l.strip_prefix("Threads:"))
            .and_then(|v| v.trim().parse().ok())
            .unwrap()
    };
    let before = threads();
    let silent: Vec<TcpStream> = (0..500)
        .map(|_| TcpStream::connect(medium.addr()).unwrap())
        .collect();
    // Each is closed by the medium: at once past the cap, or after the hello timeout.
    for mut s in silent {
        s.set_read_timeout(Some(limits::HELLO_TIMEOUT * 3)).unwrap();
        let mut byte = [0u8; 1];
        assert!(matches!(s.read(&mut byte), Ok(0)), "closed by the medium");
    }
    let s = medium.stats();
    assert_eq!(s.refused + s.silent, 500, "{s:?}");
    assert!(threads() <= before + 2 * limits::MAX_GREETING as u64 + 4);
    // And the medium serves as before.
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    let f = frame(0x11, 0x12, b"still serving");
    a.send(&Link::Frame(&f));
    assert_eq!(b.recv(SURE), Some(Got::Frame(f)));
    medium.stop();
}

/// Issue: `MAX_GREETING` connections that never said hello, made again as the medium
/// closed them, kept every newcomer out (each refused at once). A newcomer now takes the
/// place of the oldest connection still waiting for its hello, which is closed.
#[test]
fn silent_connections_do_not_keep_a_newcomer_out() {
    use medium::limits;
    let medium = Medium::start(Config::default()).unwrap();
    let silent: Vec<TcpStream> = (0..limits::MAX_GREETING)
        .map(|_| TcpStream::connect(medium.addr()).unwrap())
        .collect();
    // The medium accepts in order: the newcomers come after every silent one.
    let mut a = Client::join(&medium, Peer::Node { addr: 0x11 });
    let mut b = Client::join(&medium, Peer::Node { addr: 0x12 });
    let f = frame(0x11, 0x12, b"let in");
    a.send(&Link::Frame(&f));
    assert_eq!(b.recv(SURE), Some(Got::Frame(f)));
    // The two oldest silent connections made room: closed by the medium, counted silent.
    for mut s in silent.into_iter().take(2) {
        s.set_read_timeout(Some(SURE)).unwrap();
        let mut byte = [0u8; 1];
        assert!(matches!(s.read(&mut byte), Ok(0)), "closed by the medium");
    }
    // None refused; the two closed for the newcomers counted silent (and any that the
    // hello timeout closed since, on a slow machine).
    let s = medium.stats();
    assert!((s.refused, s.clients) == (0, 2) && s.silent >= 2, "{s:?}");
    medium.stop();
}

/// A client writing to a medium that went away is told so: the error says the medium
/// closed the connection, as a read's does. It said `Broken pipe (os error 32)`, which
/// `alarms --watch` printed as if its own output had broken. Both name the medium (they
/// named no address: a push cut off said only "the medium closed the connection").
#[test]
fn writing_to_a_medium_that_went_away_says_so() {
    let medium = Medium::start(Config::default()).unwrap();
    let said = format!("the medium at {} closed the connection", medium.addr());
    let mut conn = medium::Conn::join(medium.addr(), Peer::Tool { addr: 0x100 }).unwrap();
    medium.stop();
    // The read sees the end first; writes then fail (the first may still be buffered).
    let read = conn.recv(std::time::Instant::now() + SURE, |_| Some(()));
    assert_eq!(read.map_err(|e| e.to_string()), Err(said.clone()));
    let frame = frame(0x100, 0x11, b"anyone?");
    let failed = (0..100)
        .find_map(|_| conn.send(&Link::Frame(&frame)).err())
        .expect("a write fails");
    assert_eq!(failed.to_string(), said);
}
