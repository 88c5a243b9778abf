//! `node-host` as a real process on a minimal medium written here (a relay by destination
//! address; the medium with faults is config-tool's): an unconfigured node announces itself,
//! takes a pushed table, drives its safe outputs, answers status, boots again from its flash
//! file after a kill, turns a plant's input into the chart's output, and survives garbage.
//! Every wait is bounded (10 s) so a broken node fails the test instead of hanging it.

use std::io::{Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use config_schema::wire::mac::{self, Frame, Header, BROADCAST, MAX_PSDU};
use config_schema::wire::medium::{next_message, Link, Peer, MAX_LINK};
use config_schema::wire::msg::{Announce, Command as Cmd, Message, Status};
use config_schema::{Action, Publication, Subscription, Table};
use node_fw::node::CONFIG_PAN;
use node_fw::{ota, switch};
use test_tables::{blob, button, lamp_table, lamp_with, BEACON, BUTTON, LAMP, PAN};

const TOOL: u16 = 0x0100;
const WAIT: Duration = Duration::from_secs(10);

fn emit(msg: &Link<'_>) -> Vec<u8> {
    let mut buf = [0u8; MAX_LINK];
    let n = msg.emit(&mut buf).unwrap();
    buf[..n].to_vec()
}

/// Reads one length-prefixed link message body; `None` when the connection ends.
fn read_body(stream: &mut TcpStream) -> Option<Vec<u8>> {
    let mut len = [0u8; 2];
    stream.read_exact(&mut len).ok()?;
    let mut body = vec![0u8; usize::from(u16::from_le_bytes(len))];
    stream.read_exact(&mut body).ok()?;
    Some(body)
}

/// Waits on a condition variable until `done` holds, at most `WAIT`.
fn wait_for<T>(m: &Mutex<T>, cv: &Condvar, mut done: impl FnMut(&T) -> bool) -> bool {
    let deadline = Instant::now() + WAIT;
    let mut guard = m.lock().unwrap();
    while !done(&guard) {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return false;
        }
        guard = cv.wait_timeout(guard, left).unwrap().0;
    }
    true
}

#[derive(Default)]
struct RelayState {
    clients: Vec<(u64, Peer, TcpStream)>,
    /// Every output pin level a node reported: (node, pin, level).
    pins: Vec<(u16, u8, bool)>,
    next_id: u64,
}

/// A medium without faults: frames go to the node or tool with the destination address (or
/// to all for broadcast), node pins to the plants, plant pins to their node.
struct Relay {
    port: u16,
    state: Arc<(Mutex<RelayState>, Condvar)>,
}

impl Relay {
    fn start() -> Relay {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let state = Arc::new((Mutex::new(RelayState::default()), Condvar::new()));
        let shared = state.clone();
        std::thread::spawn(move || {
            for stream in listener.incoming() {
                let Ok(stream) = stream else { continue };
                let shared = shared.clone();
                std::thread::spawn(move || Relay::serve(stream, &shared));
            }
        });
        Relay { port, state }
    }

    fn serve(mut stream: TcpStream, shared: &(Mutex<RelayState>, Condvar)) {
        let Some(hello) = read_body(&mut stream) else {
            return;
        };
        let Ok(Link::Hello(peer)) = Link::parse(&hello) else {
            return;
        };
        let id = {
            let mut s = shared.0.lock().unwrap();
            let id = s.next_id;
            s.next_id += 1;
            // Routed to from now on, as the medium says with its welcome.
            stream.write_all(&emit(&Link::Welcome)).unwrap();
            s.clients.push((id, peer, stream.try_clone().unwrap()));
            id
        };
        shared.1.notify_all();
        while let Some(body) = read_body(&mut stream) {
            let Ok(msg) = Link::parse(&body) else {
                continue;
            };
            let mut s = shared.0.lock().unwrap();
            let raw = emit(&msg);
            match (&msg, peer) {
                (Link::Frame(psdu), _) => {
                    let Ok(Frame::Data { header, .. }) = Frame::parse(psdu) else {
                        continue;
                    };
                    for (cid, p, out) in &mut s.clients {
                        let addr = match *p {
                            Peer::Node { addr } | Peer::Tool { addr } => addr,
                            _ => continue,
                        };
                        if *cid != id && (header.dst == addr || header.dst == BROADCAST) {
                            let _ = out.write_all(&raw);
                        }
                    }
                }
                (&Link::Pin { addr, pin, level }, Peer::Node { .. }) => {
                    s.pins.push((addr, pin, level));
                    for (_, p, out) in &mut s.clients {
                        if *p == Peer::Plant {
                            let _ = out.write_all(&raw);
                        }
                    }
                }
                (&Link::Pin { addr, .. }, Peer::Plant) => {
                    for (_, p, out) in &mut s.clients {
                        if *p == (Peer::Node { addr }) {
                            let _ = out.write_all(&raw);
                        }
                    }
                }
                _ => {}
            }
            drop(s);
            shared.1.notify_all();
        }
        shared
            .0
            .lock()
            .unwrap()
            .clients
            .retain(|(c, _, _)| *c != id);
        shared.1.notify_all();
    }

    fn connected(&self, addr: u16) -> bool {
        let (m, cv) = &*self.state;
        wait_for(m, cv, |s| {
            s.clients.iter().any(|(_, p, _)| *p == Peer::Node { addr })
        })
    }

    /// Waits until node `addr` reported at least `n` pin levels; returns them all.
    fn pins(&self, addr: u16, n: usize) -> Vec<(u8, bool)> {
        let (m, cv) = &*self.state;
        let ours = |s: &RelayState| -> Vec<(u8, bool)> {
            s.pins
                .iter()
                .filter(|p| p.0 == addr)
                .map(|&(_, pin, level)| (pin, level))
                .collect()
        };
        wait_for(m, cv, |s| ours(s).len() >= n);
        ours(&m.lock().unwrap())
    }

    fn clear_pins(&self) {
        self.state.0.lock().unwrap().pins.clear();
    }

    /// Writes raw bytes to node `addr`'s connection, as if the medium sent them.
    fn inject(&self, addr: u16, bytes: &[u8]) {
        let mut s = self.state.0.lock().unwrap();
        for (_, p, out) in &mut s.clients {
            if *p == (Peer::Node { addr }) {
                out.write_all(bytes).unwrap();
            }
        }
    }

    /// Closes node `addr`'s connection.
    fn disconnect(&self, addr: u16) {
        let s = self.state.0.lock().unwrap();
        for (_, p, out) in &s.clients {
            if *p == (Peer::Node { addr }) {
                let _ = out.shutdown(Shutdown::Both);
            }
        }
    }
}

/// A client of the relay: the tool (a radio at `TOOL`) or the plant.
struct Client {
    stream: TcpStream,
    inbox: mpsc::Receiver<Vec<u8>>,
    seq: u8,
    cmd_id: u16,
}

impl Client {
    fn connect(relay: &Relay, peer: Peer) -> Client {
        let (m, cv) = &*relay.state;
        let count = |s: &RelayState| s.clients.iter().filter(|c| c.1 == peer).count();
        let n = count(&m.lock().unwrap());
        let mut stream = TcpStream::connect(("127.0.0.1", relay.port)).unwrap();
        stream.set_nodelay(true).unwrap();
        stream.write_all(&emit(&Link::Hello(peer))).unwrap();
        let (tx, inbox) = mpsc::channel();
        let mut reading = stream.try_clone().unwrap();
        std::thread::spawn(move || {
            while let Some(body) = read_body(&mut reading) {
                if tx.send(body).is_err() {
                    break;
                }
            }
        });
        assert!(wait_for(m, cv, |s| count(s) > n), "relay took the client");
        Client {
            stream,
            inbox,
            seq: 0,
            cmd_id: 0,
        }
    }

    fn tool(relay: &Relay) -> Client {
        Client::connect(relay, Peer::Tool { addr: TOOL })
    }

    fn send(&mut self, dst: u16, msg: &Message<'_>) {
        let mut payload = [0u8; mac::MAX_PAYLOAD];
        let n = msg.emit(&mut payload).unwrap();
        let header = Header {
            seq: self.seq,
            pan_id: CONFIG_PAN,
            dst,
            src: TOOL,
            ack_request: false,
            secured: false,
        };
        self.seq = self.seq.wrapping_add(1);
        let mut psdu = [0u8; MAX_PSDU];
        let len = mac::emit_data(&header, &payload[..n], &mut psdu).unwrap();
        self.stream
            .write_all(&emit(&Link::Frame(&psdu[..len])))
            .unwrap();
    }

    /// Next (src, payload) received within `timeout`.
    fn recv(&mut self, timeout: Duration) -> Option<(u16, Vec<u8>)> {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let body = self.inbox.recv_timeout(left).ok()?;
            if let Ok(Link::Frame(psdu)) = Link::parse(&body) {
                if let Ok(Frame::Data { header, payload }) = Frame::parse(psdu) {
                    return Some((header.src, payload.to_vec()));
                }
            }
        }
    }

    /// The first announcement from `addr`.
    fn announce(&mut self, addr: u16) -> Announce {
        let deadline = Instant::now() + WAIT;
        while Instant::now() < deadline {
            if let Some((src, bytes)) = self.recv(Duration::from_millis(100)) {
                if let (true, Ok(Message::Announce(a))) = (src == addr, Message::parse(&bytes)) {
                    return a;
                }
            }
        }
        panic!("no announcement from {addr:#06x}");
    }

    fn status(&mut self, addr: u16) -> Status {
        let deadline = Instant::now() + WAIT;
        while Instant::now() < deadline {
            self.cmd_id = self.cmd_id.wrapping_add(1);
            let id = self.cmd_id;
            self.send(
                addr,
                &Message::Command {
                    id,
                    command: Cmd::Status,
                },
            );
            let asked = Instant::now();
            while asked.elapsed() < Duration::from_millis(500) {
                if let Some((src, bytes)) = self.recv(Duration::from_millis(50)) {
                    if let (true, Ok(Message::Status(s))) = (src == addr, Message::parse(&bytes)) {
                        return s;
                    }
                }
            }
        }
        panic!("no status from {addr:#06x}");
    }

    /// Pushes `table` to `addr` with the OTA sender on wall-clock time.
    /// Stages `table` at `addr`, then switches it over (at its idle point).
    fn push(&mut self, addr: u16, table: &Table) -> ota::Progress {
        self.push_at(addr, table, false)
    }

    /// [`Client::push`]; `now`: switched at once, idle or not (a lit lamp, a fault).
    fn push_at(&mut self, addr: u16, table: &Table, at_once: bool) -> ota::Progress {
        let staged = self.stage(addr, table);
        if staged != ota::Progress::Done {
            return staged;
        }
        let t0 = Instant::now();
        let now = || t0.elapsed().as_millis() as u64;
        let mut c = switch::Coordinator::new(&[addr], table.generation, at_once, 10_000, now());
        let mut out = Vec::new();
        while c.verdict() == switch::Verdict::Busy && t0.elapsed() < WAIT {
            c.poll(now(), |a, m| out.push((a, m)));
            for (a, m) in out.drain(..) {
                self.send(a, &m);
            }
            if let Some((src, bytes)) = self.recv(Duration::from_millis(5)) {
                if let Ok(Message::ConfigReply { generation, reply }) = Message::parse(&bytes) {
                    c.on_reply(src, generation, reply, now(), |a, m| out.push((a, m)));
                }
            }
        }
        match c.verdict() {
            switch::Verdict::Switched => ota::Progress::Done,
            _ => ota::Progress::GaveUp,
        }
    }

    /// Stages `table` at `addr` with the tool's OTA sender.
    fn stage(&mut self, addr: u16, table: &Table) -> ota::Progress {
        let bytes = blob(table);
        let mut tx = ota::Sender::new(&bytes, table.generation, false);
        let t0 = Instant::now();
        let now = || t0.elapsed().as_millis() as u64;
        let mut out = Vec::new();
        tx.start(now(), |m| out.push(m));
        while tx.progress() == ota::Progress::Busy && t0.elapsed() < WAIT {
            for m in out.drain(..) {
                self.send(addr, &m);
            }
            if let Some((src, bytes)) = self.recv(Duration::from_millis(5)) {
                if let (true, Ok(Message::ConfigReply { generation, reply })) =
                    (src == addr, Message::parse(&bytes))
                {
                    // Anything else (announcements of other nodes) is not for the push.
                    tx.on_reply(generation, reply, now(), |m| out.push(m));
                }
            }
            tx.poll(now(), |m| out.push(m));
        }
        let st = tx.stats();
        eprintln!(
            "push of {} bytes to {addr:#06x}: {:?} in {} ms, {} frames, {} retries",
            bytes.len(),
            tx.progress(),
            t0.elapsed().as_millis(),
            st.frames,
            st.retries
        );
        tx.progress()
    }

    /// As the plant: input `pin` of node `addr` is now at `level`.
    fn drive(&mut self, addr: u16, pin: u8, level: bool) {
        self.stream
            .write_all(&emit(&Link::Pin { addr, pin, level }))
            .unwrap();
    }
}

/// A `node-host` process, killed when dropped; its stderr collected.
struct Node {
    child: Child,
    log: Arc<Mutex<String>>,
}

impl Node {
    fn spawn(addr: u16, relay: &Relay, flash: Option<&PathBuf>) -> Node {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_node-host"));
        cmd.arg("--addr")
            .arg(format!("{addr:#06x}"))
            .arg("--medium")
            .arg(format!("127.0.0.1:{}", relay.port))
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        if let Some(f) = flash {
            cmd.arg("--flash").arg(f);
        }
        let mut child = cmd.spawn().unwrap();
        let mut stderr = child.stderr.take().unwrap();
        let log = Arc::new(Mutex::new(String::new()));
        let sink = log.clone();
        std::thread::spawn(move || {
            let mut buf = [0u8; 512];
            while let Ok(n) = stderr.read(&mut buf) {
                if n == 0 {
                    break;
                }
                sink.lock()
                    .unwrap()
                    .push_str(&String::from_utf8_lossy(&buf[..n]));
            }
        });
        assert!(relay.connected(addr), "node {addr:#06x} connected");
        Node { child, log }
    }

    fn kill(mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }

    fn exit(&mut self) -> Option<ExitStatus> {
        let deadline = Instant::now() + WAIT;
        while Instant::now() < deadline {
            if let Some(status) = self.child.try_wait().unwrap() {
                return Some(status);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    }

    fn log(&self) -> String {
        self.log.lock().unwrap().clone()
    }

    /// The log once it says `what`, or as it is after `WAIT` (the stderr reader is a thread
    /// of its own: a line the node wrote may not be read yet).
    fn log_saying(&self, what: &str) -> String {
        let deadline = Instant::now() + WAIT;
        loop {
            let log = self.log();
            if log.contains(what) || Instant::now() >= deadline {
                return log;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

impl Drop for Node {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn flash_file(name: &str) -> PathBuf {
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("{name}-{}.flash", std::process::id()));
    let _ = std::fs::remove_file(&path);
    path
}

#[test]
fn a_pushed_table_runs_survives_a_restart_and_answers_the_plant() {
    const ADDR: u16 = 0x0003;
    let relay = Relay::start();
    let flash = flash_file("restart");
    let node = Node::spawn(ADDR, &relay, Some(&flash));
    let mut tool = Client::tool(&relay);
    let mut plant = Client::connect(&relay, Peer::Plant);

    let a = tool.announce(ADDR);
    assert_eq!((a.role.as_str(), a.generation), ("", 0), "unconfigured");
    assert_eq!(tool.push(ADDR, &lamp_table(3)), ota::Progress::Done);
    // Activation drove both outputs to their safe levels, and nothing else.
    assert_eq!(relay.pins(ADDR, 2), vec![(LAMP, false), (BEACON, true)]);
    let s = tool.status(ADDR);
    assert_eq!(s.role.as_str(), "lamp");
    assert_eq!(s.generation, 3);
    assert_eq!(s.states.as_slice(), &[0]);
    assert_eq!(s.fault, None);

    // The plant presses the button: the chart turns the lamp on.
    relay.clear_pins();
    plant.drive(ADDR, BUTTON, true);
    assert_eq!(relay.pins(ADDR, 1), vec![(LAMP, true)]);
    plant.drive(ADDR, BUTTON, false);
    plant.drive(ADDR, BUTTON, true);
    assert_eq!(relay.pins(ADDR, 2), vec![(LAMP, true), (LAMP, false)]);
    assert_eq!(tool.status(ADDR).states.as_slice(), &[0]);
    let log = node.log_saying("activated role lamp generation 3");
    assert!(log.contains("activated role lamp generation 3"), "{log}");

    // Killed and restarted on the same flash file: it boots with the table, no push.
    node.kill();
    relay.clear_pins();
    let node = Node::spawn(ADDR, &relay, Some(&flash));
    assert_eq!(relay.pins(ADDR, 2), vec![(LAMP, false), (BEACON, true)]);
    let s = tool.status(ADDR);
    assert_eq!((s.role.as_str(), s.generation), ("lamp", 3));
    assert_eq!(s.counters.delivered, 0);
    let log = node.log_saying("boot: role lamp generation 3");
    assert!(log.contains("boot: role lamp generation 3"), "{log}");
    let log = node.log_saying("(boot 2)");
    assert!(log.contains("(boot 2)"), "{log}");
    // The restarted node still answers the plant.
    relay.clear_pins();
    plant.drive(ADDR, BUTTON, false);
    plant.drive(ADDR, BUTTON, true);
    assert_eq!(relay.pins(ADDR, 1), vec![(LAMP, true)]);
    // A newer table replaces it (at once: the lamp is lit, the node not idle); an older
    // one is refused.
    assert_eq!(
        tool.push_at(ADDR, &lamp_table(4), true),
        ota::Progress::Done
    );
    assert_eq!(
        tool.push(ADDR, &lamp_table(2)),
        ota::Progress::Refused(config_schema::wire::msg::Refusal::Stale { running: 4 })
    );
    assert_eq!(tool.status(ADDR).generation, 4);
    drop(node);
    let _ = std::fs::remove_file(&flash);
}

#[test]
fn garbage_and_hostile_frames_do_not_crash_the_node() {
    const ADDR: u16 = 0x0007;
    let relay = Relay::start();
    let mut node = Node::spawn(ADDR, &relay, None);
    let mut tool = Client::tool(&relay);
    tool.announce(ADDR);
    assert_eq!(tool.push(ADDR, &lamp_table(1)), ota::Progress::Done);
    let before = tool.status(ADDR);

    // Messages that are not link messages, or make no sense from the medium.
    relay.inject(ADDR, &[3, 0, 0xFF, 0xFF, 0xFF]);
    relay.inject(ADDR, &[0, 0]);
    relay.inject(ADDR, &emit(&Link::Hello(Peer::Plant)));
    relay.inject(
        ADDR,
        &emit(&Link::Pin {
            addr: ADDR + 1,
            pin: BUTTON,
            level: true,
        }),
    );
    // An oversized frame (dropped before the node sees it).
    let mut big = vec![0u8; 600];
    let n = postcard_frame(&[0xAA; 200], &mut big);
    relay.inject(ADDR, &big[..n]);

    // Frames the node sees and drops: random bytes, truncated, bad FCS.
    let mut hostile = 0u32;
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    for len in 0..=MAX_PSDU {
        let bytes: Vec<u8> = (0..len)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                x as u8
            })
            .collect();
        relay.inject(ADDR, &emit(&Link::Frame(&bytes)));
        hostile += 1;
    }
    let mut payload = [0u8; 16];
    let m = Message::Command {
        id: 1,
        command: Cmd::Start,
    }
    .emit(&mut payload)
    .unwrap();
    let header = Header {
        seq: 9,
        pan_id: CONFIG_PAN,
        dst: ADDR,
        src: TOOL,
        ack_request: false,
        secured: false,
    };
    let mut psdu = [0u8; MAX_PSDU];
    let len = mac::emit_data(&header, &payload[..m], &mut psdu).unwrap();
    relay.inject(ADDR, &emit(&Link::Frame(&psdu[..len - 3])));
    let mut bad = psdu[..len].to_vec();
    bad[len - 1] ^= 0x55;
    relay.inject(ADDR, &emit(&Link::Frame(&bad)));
    hostile += 2;

    let after = tool.status(ADDR);
    assert_eq!(after.counters.dropped - before.counters.dropped, hostile);
    assert_eq!((after.role.as_str(), after.generation), ("lamp", 1));
    assert_eq!(after.counters.delivered, 0);
    assert_eq!(node.child.try_wait().unwrap(), None, "still running");

    // Losing the medium ends the node cleanly, with its counts in the log.
    relay.disconnect(ADDR);
    let status = node.exit().expect("node-host exits when the medium goes");
    assert!(status.success(), "{status:?}");
    let log = node.log_saying("1 oversized frames, 4 garbage messages");
    assert!(
        log.contains("1 oversized frames, 4 garbage messages"),
        "{log}"
    );
}

/// A `Link::Frame` longer than a PSDU (`Link::emit` refuses it: MAX_LINK), by hand.
fn postcard_frame(psdu: &[u8], buf: &mut [u8]) -> usize {
    // postcard: variant index 1 (Frame), varint length, bytes.
    let mut body = vec![1u8];
    let mut n = psdu.len();
    loop {
        let byte = (n & 0x7F) as u8;
        n >>= 7;
        if n == 0 {
            body.push(byte);
            break;
        }
        body.push(byte | 0x80);
    }
    body.extend_from_slice(psdu);
    buf[..2].copy_from_slice(&(body.len() as u16).to_le_bytes());
    buf[2..2 + body.len()].copy_from_slice(&body);
    assert!(next_message(&buf[..2 + body.len()]).is_some());
    2 + body.len()
}

#[test]
fn bad_arguments_and_a_foreign_flash_file_get_clear_errors() {
    let bin = env!("CARGO_BIN_EXE_node-host");
    let run = |args: &[&str]| {
        let out = Command::new(bin).args(args).output().unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (code, err) = run(&["--addr", "zz", "--medium", "127.0.0.1:9"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("`zz` is not a 16-bit address"), "{err}");
    let (code, err) = run(&["--addr", "0xFFFF", "--medium", "127.0.0.1:9"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("reserved"), "{err}");
    let (code, err) = run(&["--addr", "3"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("--medium"), "{err}");
    let (code, err) = run(&["--addr", "3", "--medium", "nowhere"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("--medium"), "{err}");

    // Nobody listens: exit 1 with the address.
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let medium = format!("127.0.0.1:{port}");
    let (code, err) = run(&["--addr", "3", "--medium", &medium]);
    assert_eq!(code, Some(1));
    assert!(
        err.contains(&format!("cannot connect to the medium at {medium}")),
        "{err}"
    );

    // A file that is not a flash file is refused and left as it was.
    let path = flash_file("foreign");
    std::fs::write(&path, b"my notes").unwrap();
    let (code, err) = run(&[
        "--addr",
        "3",
        "--medium",
        &medium,
        "--flash",
        path.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(1));
    assert!(err.contains("not a node flash file"), "{err}");
    assert_eq!(std::fs::read(&path).unwrap(), b"my notes");
    let _ = std::fs::remove_file(&path);
}

/// "button": a press is published to the lamp node (peer 0).
fn button_table(lamp: u16) -> Table {
    let mut t = Table::empty("button");
    t.generation = 1;
    t.header.pan_id = PAN;
    let press = button(&mut t, BUTTON);
    t.peers.push(lamp).unwrap();
    t.publications
        .push(Publication {
            event: press,
            topic: 3,
            subscribers: 0b1,
        })
        .unwrap();
    t
}

/// "lamp" again, toggled by the button node's publication instead of a local input.
fn remote_lamp_table(button: u16) -> Table {
    let mut t = lamp_table(1);
    t.inputs.clear();
    t.peers.push(button).unwrap();
    t.subscriptions
        .push(Subscription {
            publisher: 0,
            topic: 3,
            event: 0,
        })
        .unwrap();
    t
}

#[test]
fn two_nodes_in_process_carry_events_and_return_when_the_medium_goes() {
    const A: u16 = 0x0011;
    const B: u16 = 0x0012;
    let relay = Relay::start();
    let (done_tx, done) = mpsc::channel();
    for addr in [A, B] {
        let args = node_fw::host::Args {
            addr,
            medium: format!("127.0.0.1:{}", relay.port).parse().unwrap(),
            flash: None,
            key: None,
        };
        let done_tx = done_tx.clone();
        std::thread::spawn(move || {
            let result = node_fw::host::run(args).map_err(|e| e.to_string());
            let _ = done_tx.send((addr, result));
        });
        assert!(relay.connected(addr));
    }
    let mut tool = Client::tool(&relay);
    let mut plant = Client::connect(&relay, Peer::Plant);
    assert_eq!(tool.push(A, &button_table(B)), ota::Progress::Done);
    assert_eq!(tool.push(B, &remote_lamp_table(A)), ota::Progress::Done);
    assert_eq!(relay.pins(B, 2), vec![(LAMP, false), (BEACON, true)]);
    relay.clear_pins();
    // Three presses on A: B's lamp on, off, on; each exactly once.
    for _ in 0..3 {
        plant.drive(A, BUTTON, true);
        plant.drive(A, BUTTON, false);
    }
    assert_eq!(
        relay.pins(B, 3),
        vec![(LAMP, true), (LAMP, false), (LAMP, true)]
    );
    let b = tool.status(B);
    assert_eq!(b.counters.delivered, 3);
    assert_eq!(tool.status(A).link_alarms, 0);

    // The medium goes away: both runs return Ok.
    relay.disconnect(A);
    relay.disconnect(B);
    let mut stopped = Vec::new();
    for _ in 0..2 {
        stopped.push(done.recv_timeout(WAIT).expect("run returns"));
    }
    stopped.sort();
    assert_eq!(stopped, vec![(A, Ok(())), (B, Ok(()))]);
}

#[test]
fn a_fault_is_logged_reported_and_cleared_by_a_new_table() {
    const ADDR: u16 = 0x0021;
    let relay = Relay::start();
    let node = Node::spawn(ADDR, &relay, None);
    let mut tool = Client::tool(&relay);
    let mut plant = Client::connect(&relay, Peer::Plant);
    // A lamp whose "on" state faults with application code 5.
    let t = lamp_with(1, &[Action::Drive { mask: 1, value: 1 }, Action::Fault(5)]);
    assert_eq!(tool.push(ADDR, &t), ota::Progress::Done);
    assert_eq!(relay.pins(ADDR, 2), vec![(LAMP, false), (BEACON, true)]);
    relay.clear_pins();
    plant.drive(ADDR, BUTTON, true);
    // The lamp went on, then the fault drove every output to its safe level.
    assert_eq!(relay.pins(ADDR, 2), vec![(LAMP, true), (LAMP, false)]);
    assert_eq!(tool.status(ADDR).fault, Some(0x85));
    let log = node.log_saying("fault 0x85");
    assert!(log.contains("fault 0x85"), "{log}");
    // A new table, switched to at once (a faulted node is not idle), clears it.
    assert_eq!(
        tool.push_at(ADDR, &lamp_table(2), true),
        ota::Progress::Done
    );
    assert_eq!(tool.status(ADDR).fault, None);
    let log = node.log_saying("fault cleared");
    assert!(log.contains("fault cleared"), "{log}");
}

/// A "medium" that talks but never welcomes (another service on that port, sending a
/// message a second) is given up on within the welcome timeout, as a silent one is. Each
/// message restarted the wait: the node waited for ever, saying nothing.
#[test]
fn a_medium_that_talks_but_never_welcomes_is_given_up_on() {
    use node_fw::host::medium::{Connection, WELCOME_TIMEOUT};
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let at = listener.local_addr().unwrap();
    let server = std::thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        // Every 100 ms a message, never `Welcome`, until the node hangs up.
        while s.write_all(&emit(&Link::Synced(7))).is_ok() {
            std::thread::sleep(Duration::from_millis(100));
        }
    });
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let stream = TcpStream::connect(at).unwrap();
        let _ = tx.send(
            Connection::start(0x0011, stream)
                .map(drop)
                .map_err(|e| e.to_string()),
        );
    });
    // Bounded: a node that never gives up fails here instead of hanging the suite.
    let ended = rx
        .recv_timeout(WELCOME_TIMEOUT * 6)
        .expect("the node gave up on the medium");
    assert_eq!(
        ended,
        Err(String::from("the medium did not welcome this node"))
    );
    server.join().unwrap();
}

/// A node run on a thread of a process (as the tool's tests and an embedding run it), not
/// a process of its own: stopped (its medium closed its connection), it left its flash
/// file locked until the process ended, its boot counter's handle (which shares the flash
/// file's lock) leaked with the closure that counts boots; the same file run again in the
/// same process was refused, "in use by another node process".
#[test]
fn a_node_run_on_a_thread_frees_its_flash_file_when_it_stops() {
    let relay = Relay::start();
    let flash = flash_file("on-a-thread");
    // Another address each time: the relay forgets a closed connection on its own time.
    for addr in [0x0031, 0x0032] {
        let args = node_fw::host::Args {
            addr,
            medium: std::net::SocketAddr::from(([127, 0, 0, 1], relay.port)),
            flash: Some(flash.clone()),
            key: None,
        };
        let node = std::thread::spawn(move || node_fw::host::run(args).map_err(|e| e.to_string()));
        assert!(relay.connected(addr), "node {addr:#06x} on the relay");
        relay.disconnect(addr);
        assert_eq!(node.join().expect("no panic"), Ok(()), "node {addr:#06x}");
    }
    assert!(node_fw::host::flash::HostFlash::open(&flash).is_ok());
    let _ = std::fs::remove_file(&flash);
}
