//! Shared by the end-to-end tests (`e2e.rs`, `e2e_ota.rs`): the test bed with real node
//! processes (`config-tool node`) on a real medium, robots from `robot-configs/`, what a
//! cycle must deliver (from the virtual-time simulator), a hand-driven OTA transfer, and a
//! raw medium client that sends any bytes as a frame.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use config_schema::wire::mac::{self, Frame, Header, MAX_PSDU};
use config_schema::wire::medium::{Link, Peer};
use config_schema::wire::msg::{Command, Message, SecurityReport, Status};
use config_schema::wire::security::{self, ext_addr, AuxRepr, SecurityLevel};
use config_schema::Table;
use node_fw::node::CONFIG_PAN;
use node_fw::ota::{Progress, Sender, TransferStats};
use node_fw::sim::{What, World};
use robot_compiler::{compile, Compiled, Source};
use robot_net::demo::{self, Bed, Cycle, Options};
use robot_net::live_plant;
use robot_net::radio::ToolRadio;

/// Bound of every wait (a cycle, a command, nodes coming up): generous, never a pace.
pub const TIMEOUT: Duration = Duration::from_secs(60);

/// The declared sequence of `paint-robot.ron`: the paper's sequence (1).
pub const SEQUENCE_1: &str = "VC+ GR+ VC- HC+ VC+ VC- RC+ RC- HC- VC+ GR- VC-";

/// `robot-configs/NAME`, compiled for `generation`.
pub fn robot(name: &str, generation: u32) -> Compiled {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("robot-configs")
        .join(name);
    let text = std::fs::read_to_string(&path).expect("robot file");
    let c = compile::compile(&Source::new(name, text))
        .unwrap_or_else(|d| panic!("{name} does not compile: {d:?}"));
    c.with_generation(generation).expect("re-encodes")
}

/// The steps `c` declares, as text.
pub fn expect(c: &Compiled) -> Vec<String> {
    c.ir.expect.iter().map(|s| s.to_string()).collect()
}

/// A role's node address.
pub fn addr_of(c: &Compiled, role: &str) -> u16 {
    role_of(c, role).1
}

/// A role's index and node address.
pub fn role_of(c: &Compiled, role: &str) -> (usize, u16) {
    let i =
        c.ir.roles
            .iter()
            .position(|r| r.name == role)
            .unwrap_or_else(|| panic!("no role {role}"));
    (i, c.ir.roles[i].address)
}

/// A fresh directory under the system's temp dir, removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> TempDir {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let dir = std::env::temp_dir().join(format!(
            "config-tool-e2e-{tag}-{}-{nanos}",
            std::process::id()
        ));
        std::fs::create_dir_all(&dir).expect("temp dir");
        TempDir(dir)
    }

    /// The flash file the bed gives node `addr`.
    pub fn flash(&self, addr: u16) -> PathBuf {
        self.0.join(format!("node-{addr:04x}.flash"))
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Bed options: nodes are `config-tool node` processes.
pub fn options(medium: medium::Config, flash_dir: Option<&TempDir>) -> Options {
    let node_command: Vec<OsString> = vec![env!("CARGO_BIN_EXE_config-tool").into(), "node".into()];
    Options {
        medium,
        node_command,
        flash_dir: flash_dir.map(|d| d.0.clone()),
        timeout: TIMEOUT,
        secured: true,
    }
}

/// Starts the medium, one unconfigured node process per physical node of `c` (spares
/// too) and the plant of `c`; returns once every node has announced itself unconfigured.
pub fn bring_up(c: &Compiled, options: Options) -> Bed {
    let mut bed = Bed::start(options).expect("bed");
    let addrs = demo::node_addrs(c);
    for a in &addrs {
        bed.start_node(*a).expect("node process");
    }
    bed.set_plant(live_plant::actuators(c).expect("actuators"))
        .expect("plant");
    let found = bed
        .wait_for_nodes(&addrs)
        .expect("every node announces itself");
    assert_eq!(found.keys().copied().collect::<Vec<_>>(), addrs);
    for (addr, a) in &found {
        assert_eq!(
            (a.generation, a.role.as_str(), a.firmware),
            (0, "", node_fw::node::FIRMWARE_VERSION),
            "node {addr:#06x} boots unconfigured"
        );
    }
    bed
}

/// Pushes every role of `c` and checks that every node activated its table.
pub fn push_ok(bed: &mut Bed, c: &Compiled) -> Vec<robot_net::push::Pushed> {
    let outcomes = bed.push(c, false, &mut |_, _, _| {}).expect("push");
    assert_eq!(outcomes.len(), c.ir.roles.len());
    for (o, (r, blob)) in outcomes.iter().zip(c.ir.roles.iter().zip(&c.blobs)) {
        assert_eq!(
            (o.role.as_str(), o.addr, o.progress, o.bytes),
            (r.name.as_str(), r.address, Progress::Done, blob.len()),
            "{}",
            demo::push_line(o)
        );
        assert!(o.stats.bytes as usize >= blob.len(), "every byte was sent");
    }
    outcomes
}

/// Homes the machine of `c` and checks it ended homed; the steps the plant saw.
pub fn home_ok(bed: &mut Bed, c: &Compiled) -> Vec<String> {
    let homing = bed.home(c).expect("home");
    assert_eq!(
        homing.end,
        robot_net::home::HomeEnd::Homed,
        "{}",
        demo::homed_line(&homing)
    );
    homing.steps.iter().map(|s| s.to_string()).collect()
}

/// Pushes every role of `c` to nodes that are not homed (unconfigured, or stopped
/// anywhere), then homes the machine: the actuators are home already, so the plant moves
/// nothing.
pub fn push_and_home(bed: &mut Bed, c: &Compiled) -> Vec<robot_net::push::Pushed> {
    let outcomes = push_ok(bed, c);
    assert_not_homed(bed, c);
    assert_eq!(home_ok(bed, c), Vec::<String>::new(), "from rest");
    outcomes
}

/// Every role's node runs `c`'s table in its initial states (booted, reset or activated
/// on a stopped machine: not homed), no fault, no link alarm.
pub fn assert_not_homed(bed: &mut Bed, c: &Compiled) -> Vec<Status> {
    let statuses = bed.statuses(c).expect("statuses");
    for ((s, r), t) in statuses.iter().zip(&c.ir.roles).zip(&c.tables) {
        assert_eq!(
            (s.role.as_str(), s.generation, s.fault),
            (r.name.as_str(), c.ir.generation, None),
            "node {:#06x}",
            r.address
        );
        assert_eq!(
            s.states.as_slice(),
            initial(t).as_slice(),
            "role {}",
            r.name
        );
    }
    statuses
}

/// Role `role`'s node (rebooted) runs `c`'s table in its initial states, not homed; the
/// other nodes rest homed.
pub fn assert_not_homed_node(bed: &mut Bed, c: &Compiled, role: &str) {
    let statuses = bed.statuses(c).expect("statuses");
    for ((s, r), t) in statuses.iter().zip(&c.ir.roles).zip(&c.tables) {
        let want = if r.name == role { initial(t) } else { idle(t) };
        assert_eq!(
            (s.role.as_str(), s.generation, s.fault, s.states.as_slice()),
            (r.name.as_str(), c.ir.generation, None, want.as_slice()),
            "node {:#06x}",
            r.address
        );
    }
}

/// Every role's node runs `c`'s table, homed and at rest: role, generation, idle states,
/// no fault, no link alarm. Returns the statuses (in role order).
pub fn assert_running(bed: &mut Bed, c: &Compiled) -> Vec<Status> {
    let statuses = bed.statuses(c).expect("statuses");
    for ((s, r), t) in statuses.iter().zip(&c.ir.roles).zip(&c.tables) {
        assert_eq!(
            (s.role.as_str(), s.generation),
            (r.name.as_str(), c.ir.generation),
            "node {:#06x}",
            r.address
        );
        // This very table, not another with the same role and charts.
        assert!(robot_net::home::runs(t, s), "node {:#06x}", r.address);
        assert_eq!(s.states.as_slice(), idle(t).as_slice(), "role {}", r.name);
        assert_eq!(
            (s.fault, s.link_alarms, s.links_broken),
            (None, 0, 0),
            "role {}",
            r.name
        );
    }
    statuses
}

/// The initial state of every chart of `t`.
pub fn initial(t: &Table) -> Vec<u8> {
    t.charts.iter().map(|ch| ch.initial).collect()
}

/// The idle state of every chart of `t` (where it rests homed between cycles).
pub fn idle(t: &Table) -> Vec<u8> {
    t.charts.iter().map(|ch| ch.idle).collect()
}

/// One status of node `addr`.
pub fn status(bed: &mut Bed, addr: u16) -> Status {
    bed.command(addr, Command::Status).expect("status")
}

/// Asks node `addr` for its status until `ok` holds (at most [`TIMEOUT`]).
pub fn wait_until(bed: &mut Bed, addr: u16, mut ok: impl FnMut(&Status) -> bool) -> Status {
    let end = Instant::now() + TIMEOUT;
    loop {
        let s = status(bed, addr);
        if ok(&s) {
            return s;
        }
        assert!(Instant::now() < end, "node {addr:#06x}: {s:?}");
    }
}

/// Runs one cycle and checks it: exactly the declared steps, nothing more, no fault.
pub fn exact_cycle(bed: &mut Bed, c: &Compiled, n: usize) -> Cycle {
    let cycle = bed.run_cycle(c, &mut |_, _| {}).expect("cycle");
    assert!(cycle.ok(), "{}", demo::cycle_line(n, &cycle));
    assert_eq!(cycle.steps, c.ir.expect, "cycle {n}");
    // Every step ran under the robot's generation: no mix.
    assert_eq!(
        cycle.generations,
        vec![c.ir.generation; cycle.steps.len()],
        "cycle {n}: the generation of each step"
    );
    cycle
}

/// Events delivered to each role's node per cycle, cycle by cycle, as the virtual-time
/// simulator (the same tables, a perfect radio) counts them.
pub fn deliveries_per_cycle(c: &Compiled, cycles: usize) -> Vec<Vec<u32>> {
    let specs = robot_analysis::sim::node_specs(c, &c.tables);
    let (plants, button) = robot_analysis::sim::plants(c).expect("plants");
    let mut world = World::new(&specs, plants).expect("world");
    (0..cycles)
        .map(|_| {
            let mark = world.trace().len();
            world.run_cycle(button, 600_000).expect("sim cycle");
            let mut per = vec![0u32; specs.len()];
            for e in &world.trace()[mark..] {
                if let What::Deliver { to, .. } = e.what {
                    per[to] += 1;
                }
            }
            per
        })
        .collect()
}

/// What a hand-driven transfer does with a message the sender wants to send.
pub enum Fate {
    Send,
    /// Lost on the way (not sent).
    Lose,
    /// Stop the transfer here (nothing more is sent).
    Stop,
}

/// One OTA transfer to `addr`, driven by hand like `push::push` drives it, with `fate`
/// deciding about every message (`acked`: bytes the node acknowledged so far). Returns the
/// sender's progress (`Busy` when stopped) and the bytes acknowledged.
pub fn drive(
    radio: &mut ToolRadio,
    addr: u16,
    blob: &[u8],
    generation: u32,
    mut fate: impl FnMut(&Message<'_>, usize) -> Fate,
    mut tamper: impl FnMut(Message<'static>) -> Message<'static>,
) -> (Progress, usize, TransferStats) {
    let blob: &'static [u8] = Box::leak(blob.to_vec().into_boxed_slice());
    let start = Instant::now();
    let now_ms = || start.elapsed().as_millis() as u64;
    let mut sender = Sender::new(blob, generation, false);
    let mut out: Vec<Message<'static>> = Vec::new();
    sender.start(now_ms(), |m| out.push(m));
    let end = start + TIMEOUT;
    loop {
        for m in out.drain(..) {
            match fate(&m, sender.acked()) {
                Fate::Send => radio.send(addr, &tamper(m)).expect("send"),
                Fate::Lose => {}
                Fate::Stop => return (Progress::Busy, sender.acked(), sender.stats()),
            }
        }
        if sender.progress() == Progress::Done {
            // Staged: switch the node over (at its idle point), as `push` does.
            let switched = switch_one(radio, addr, generation);
            let progress = if switched {
                Progress::Done
            } else {
                Progress::GaveUp
            };
            return (progress, sender.acked(), sender.stats());
        }
        if sender.progress() != Progress::Busy {
            return (sender.progress(), sender.acked(), sender.stats());
        }
        assert!(Instant::now() < end, "transfer to {addr:#06x} did not end");
        let until = start + Duration::from_millis(sender.deadline());
        if let Some(r) = radio.recv(until.max(Instant::now())).expect("recv") {
            if let (true, Some(Message::ConfigReply { generation, reply })) =
                (r.src == addr, r.message())
            {
                sender.on_reply(generation, reply, now_ms(), |m| out.push(m));
            }
        }
        sender.poll(now_ms(), |m| out.push(m));
    }
}

/// Switches node `addr` over to its staged `generation`; whether it did.
pub fn switch_one(radio: &mut ToolRadio, addr: u16, generation: u32) -> bool {
    let start = Instant::now();
    let now_ms = || start.elapsed().as_millis() as u64;
    let mut c = node_fw::switch::Coordinator::new(&[addr], generation, false, 30_000, 0);
    let mut out: Vec<(u16, Message<'static>)> = Vec::new();
    while c.verdict() == node_fw::switch::Verdict::Busy {
        c.poll(now_ms(), |a, m| out.push((a, m)));
        for (a, m) in out.drain(..) {
            radio.send(a, &m).expect("send");
        }
        let until = start + Duration::from_millis(c.deadline());
        if let Some(r) = radio.recv(until.max(Instant::now())).expect("recv") {
            if let Some(Message::ConfigReply { generation, reply }) = r.message() {
                c.on_reply(r.src, generation, reply, now_ms(), |a, m| out.push((a, m)));
            }
        }
    }
    c.verdict() == node_fw::switch::Verdict::Switched
}

/// A data frame (FCS included).
fn header(pan_id: u16, dst: u16, src: u16, seq: u8) -> Header {
    Header {
        seq,
        pan_id,
        dst,
        src,
        ack_request: false,
        secured: false,
    }
}

/// A node's secured frame opened with its management key, as an unsecured frame with the
/// plain payload (so it parses as before); `None` if it does not open.
pub fn open_from(secret: &robot_keys::MachineSecret, psdu: &[u8]) -> Option<Vec<u8>> {
    let mut scratch = [0u8; mac::MAX_PAYLOAD];
    let o = security::open_at(
        psdu,
        SecurityLevel::EncMic64,
        |h, _| {
            let key = robot_keys::management_key(secret, h.src);
            Some((*key.expose(), ext_addr(h.pan_id, h.src)))
        },
        &mut scratch,
    )
    .ok()?;
    Some(frame(
        o.header.pan_id,
        o.header.dst,
        o.header.src,
        o.header.seq,
        o.payload,
    ))
}

/// The plain payload of a secured frame from the tool (any tool address) to `node`.
pub fn open_from_tool(
    secret: &robot_keys::MachineSecret,
    node: u16,
    psdu: &[u8],
) -> Option<Vec<u8>> {
    let mut scratch = [0u8; mac::MAX_PAYLOAD];
    let key = robot_keys::management_key(secret, node);
    let o = security::open_at(
        psdu,
        SecurityLevel::EncMic64,
        |h, _| (h.dst == node).then(|| (*key.expose(), ext_addr(h.pan_id, h.src))),
        &mut scratch,
    )
    .ok()?;
    Some(o.payload.to_vec())
}

/// A secured frame from `src` to `dst` on the config PAN, as the tool sends.
pub fn secured_frame(
    secret: &robot_keys::MachineSecret,
    dst: u16,
    src: u16,
    counter: u32,
    payload: &[u8],
) -> Vec<u8> {
    let key = robot_keys::management_key(secret, dst);
    let mut psdu = [0u8; MAX_PSDU];
    let n = security::secure(
        &header(CONFIG_PAN, dst, src, 0),
        &AuxRepr::new(0, counter),
        key.expose(),
        ext_addr(CONFIG_PAN, src),
        payload,
        &mut psdu,
    )
    .expect("fits");
    psdu[..n].to_vec()
}

pub fn frame(pan_id: u16, dst: u16, src: u16, seq: u8, payload: &[u8]) -> Vec<u8> {
    let header = header(pan_id, dst, src, seq);
    let mut psdu = [0u8; MAX_PSDU];
    let n = mac::emit_data(&header, payload, &mut psdu).expect("fits");
    psdu[..n].to_vec()
}

/// A message as a MAC payload.
pub fn payload(msg: &Message<'_>) -> Vec<u8> {
    let mut buf = [0u8; mac::MAX_PAYLOAD];
    let n = msg.emit(&mut buf).expect("fits");
    buf[..n].to_vec()
}

/// A raw client of the medium (on the medium's own connection, [`medium::Conn`]): sends
/// any bytes, as a frame or as a whole connection stream.
pub struct RawClient {
    pub addr: u16,
    conn: medium::Conn,
    next_id: u16,
    /// The machine secret and the next frame counter: `status` is then secured.
    keys: Option<(robot_keys::MachineSecret, u32)>,
}

impl RawClient {
    /// Its `status` secured with the management keys of `secret` (the tool's keys).
    pub fn keyed(mut self, secret: &robot_keys::MachineSecret) -> RawClient {
        self.keys = Some((secret.clone(), 0));
        self
    }

    pub fn join(medium: std::net::SocketAddr, addr: u16) -> RawClient {
        RawClient {
            addr,
            conn: medium::Conn::join(medium, Peer::Tool { addr }).expect("medium"),
            next_id: 0x7000,
            keys: None,
        }
    }

    /// Puts `psdu` on the air, whatever it is.
    pub fn send_psdu(&mut self, psdu: &[u8]) {
        self.conn.send(&Link::Frame(psdu)).expect("write");
    }

    /// Writes raw bytes on the connection (a link message built by hand).
    pub fn send_raw(&mut self, bytes: &[u8]) {
        self.conn.send_raw(bytes).expect("write");
    }

    /// Sends a `Status` command to `addr` and returns the answer. Sent on this connection
    /// after everything sent before it, so the answer counts everything sent before it.
    pub fn status(&mut self, addr: u16) -> Status {
        self.ask(addr, Command::Status, |m, id| match m {
            Message::Status(s) if s.ack == id => Some(s),
            _ => None,
        })
    }

    /// Sends `Command::Security` to `addr` and returns the report (as `status`).
    pub fn security(&mut self, addr: u16) -> SecurityReport {
        self.ask(addr, Command::Security, |m, id| match m {
            Message::Security(r) if r.ack == id => Some(r),
            _ => None,
        })
    }

    /// Sends `command` to `addr` and returns what `pick` takes of its answers.
    fn ask<T>(
        &mut self,
        addr: u16,
        command: Command,
        pick: impl Fn(Message<'_>, u16) -> Option<T>,
    ) -> T {
        self.next_id = self.next_id.wrapping_add(1);
        let id = self.next_id;
        let msg = Message::Command { id, command };
        let psdu = self.psdu_to(addr, id as u8, &payload(&msg));
        self.send_psdu(&psdu);
        let end = Instant::now() + TIMEOUT;
        // Asked again until answered, as the tool does (a challenge may be rate-limited).
        let retry = Duration::from_millis(300);
        let mut again_at = Instant::now() + retry;
        loop {
            let Some(got) = self.next_frame(again_at.min(end)) else {
                assert!(Instant::now() < end, "an answer");
                let again = self.psdu_to(addr, id as u8, &payload(&msg));
                self.send_psdu(&again);
                again_at = Instant::now() + retry;
                continue;
            };
            let got = match &self.keys {
                Some((secret, _)) => match open_from(secret, &got) {
                    Some(plain) => plain,
                    None => continue,
                },
                None => got,
            };
            if let Ok(Frame::Data { header, payload: p }) = Frame::parse(&got) {
                if header.src != addr {
                    continue;
                }
                match Message::parse(p) {
                    // The node does not know this client's counter yet: answer, ask again.
                    Ok(Message::Challenge { nonce }) => {
                        let answer =
                            self.psdu_to(addr, 0, &payload(&Message::ChallengeAnswer { nonce }));
                        self.send_psdu(&answer);
                        let again = self.psdu_to(addr, id as u8, &payload(&msg));
                        self.send_psdu(&again);
                    }
                    Ok(m) => {
                        if let Some(t) = pick(m, id) {
                            return t;
                        }
                    }
                    Err(_) => {}
                }
            }
        }
    }

    /// A frame to `addr` on the config PAN: secured with its key when this client has keys.
    fn psdu_to(&mut self, addr: u16, seq: u8, body: &[u8]) -> Vec<u8> {
        match &mut self.keys {
            Some((secret, counter)) => {
                let key = robot_keys::management_key(secret, addr);
                let mut psdu = [0u8; MAX_PSDU];
                let n = security::secure(
                    &header(CONFIG_PAN, addr, self.addr, seq),
                    &AuxRepr::new(0, *counter),
                    key.expose(),
                    ext_addr(CONFIG_PAN, self.addr),
                    body,
                    &mut psdu,
                )
                .expect("fits");
                *counter += 1;
                psdu[..n].to_vec()
            }
            None => frame(CONFIG_PAN, addr, self.addr, seq, body),
        }
    }

    /// The next frame for this radio before `until`; `None` on timeout or when the medium
    /// closed the connection.
    pub fn next_frame(&mut self, until: Instant) -> Option<Vec<u8>> {
        let frame = |l: Link<'_>| match l {
            Link::Frame(f) => Some(f.to_vec()),
            _ => None,
        };
        self.conn.recv(until, frame).ok().flatten()
    }

    /// Whether the medium closed this connection (waits at most `within`).
    pub fn closed_by_medium(&mut self, within: Duration) -> bool {
        let end = Instant::now() + within;
        self.conn.recv(end, |_| None::<()>).is_err()
    }
}

/// A monitor on the medium: every frame put on the air, in air order.
pub struct Monitor {
    conn: medium::Conn,
}

impl Monitor {
    /// Joins (welcomed: from then on it sees every frame).
    pub fn join(medium: std::net::SocketAddr) -> Monitor {
        Monitor {
            conn: medium::Conn::join(medium, Peer::Monitor).expect("medium"),
        }
    }

    /// Every PSDU on the air until (and including) the first for which `last` holds.
    pub fn psdus_until(&mut self, mut last: impl FnMut(&[u8]) -> bool) -> Vec<Vec<u8>> {
        let end = Instant::now() + TIMEOUT;
        let mut out = Vec::new();
        let mut seen = |l: Link<'_>| {
            let Link::Frame(psdu) = l else { return None };
            out.push(psdu.to_vec());
            last(psdu).then_some(())
        };
        let got = self.conn.recv(end, &mut seen).expect("monitor");
        assert!(got.is_some(), "the monitor saw the frame");
        out
    }

    /// Every data frame's (src, dst, message) until (and including) the first frame for
    /// which `last` holds.
    pub fn until(
        &mut self,
        mut last: impl FnMut(&Header, &[u8]) -> bool,
    ) -> Vec<(Header, Vec<u8>)> {
        let end = Instant::now() + TIMEOUT;
        let mut out = Vec::new();
        let mut seen = |l: Link<'_>| {
            let Link::Frame(psdu) = l else { return None };
            let Ok(Frame::Data { header, payload }) = Frame::parse(psdu) else {
                return None;
            };
            let done = last(&header, payload);
            out.push((header, payload.to_vec()));
            done.then_some(())
        };
        let got = self.conn.recv(end, &mut seen).expect("monitor");
        assert!(got.is_some(), "the monitor saw the marker frame");
        out
    }
}

/// Counters of every role's node, by address.
pub fn counters(
    statuses: &[Status],
    c: &Compiled,
) -> BTreeMap<u16, config_schema::wire::msg::Counters> {
    statuses
        .iter()
        .zip(&c.ir.roles)
        .map(|(s, r)| (r.address, s.counters))
        .collect()
}

/// A second tool on the medium (another address than the bed's), secured with `secret`.
pub fn second_tool(medium: std::net::SocketAddr, secret: &robot_keys::MachineSecret) -> ToolRadio {
    let mut radio = ToolRadio::connect(medium, 0x0101).expect("medium");
    let mut next = 0u32;
    radio.secure(
        secret.clone(),
        Box::new(move || {
            next += 1;
            Ok(next)
        }),
    );
    radio
}

/// Waits until the plant has driven `n` output levels (the cycle is under way).
pub fn wait_for_outputs(medium: std::net::SocketAddr, n: usize) {
    let mut monitor = medium::Conn::join(medium, Peer::Monitor).expect("monitor");
    let mut seen = 0;
    let got = monitor
        .recv(Instant::now() + TIMEOUT, |l: Link<'_>| {
            if l.output_seen().is_some() {
                seen += 1;
            }
            (seen >= n).then_some(())
        })
        .expect("monitor");
    assert!(got.is_some(), "the cycle got under way");
}

/// Every node loses power at once and boots again from its flash.
pub fn power_cut(bed: &mut robot_net::demo::Bed, addrs: &[u16]) {
    for &a in addrs {
        bed.kill_node(a);
    }
    for &a in addrs {
        bed.start_node(a).unwrap();
    }
    bed.wait_for_nodes(addrs).unwrap();
}

/// Push, home, START; once the plant has seen `VC+ GR+ VC- HC+ VC+` (HC+ completed, VC on
/// its way down into the pot) every node process is killed and restarted.
///
/// `options` must keep the nodes' flash (they boot their confirmed table).
pub fn killed_mid_cycle_then_homed(options: Options) {
    let c = robot("paint-robot.ron", 1);
    let addrs: Vec<u16> = c.ir.roles.iter().map(|r| r.address).collect();
    let mut bed = bring_up(&c, options);
    push_and_home(&mut bed, &c);
    assert_running(&mut bed, &c);

    bed.press_start(&c).expect("START");
    let seen: Vec<String> = bed
        .await_strokes(5)
        .expect("five steps")
        .iter()
        .map(|s| s.to_string())
        .collect();
    assert_eq!(seen.join(" "), "VC+ GR+ VC- HC+ VC+");
    power_cut(&mut bed, &addrs);
    // The gripper's monostable valve dropped with the power (a boot cannot hold it): the
    // part is released; the cylinders' valves go off and their rods stay where they are.
    let booted = bed.await_strokes(1).expect("the gripper drops");
    assert_eq!(booted[0].to_string(), "GR-");

    // Booted from flash: generation 1, every chart initial (not homed).
    assert_not_homed(&mut bed, &c);
    let (start_role, _) = c.ir.start.clone().unwrap();
    let before = status(&mut bed, c.ir.roles[start_role].address);
    let after = bed.press_start(&c).expect("START");
    assert_eq!(
        (after.states.as_slice(), after.outputs, after.fault),
        (before.states.as_slice(), before.outputs, None),
        "a START on a machine not homed does nothing"
    );

    // Homing (VC- HC- RC- GR-) from where the power cut left the rods, and nothing else
    // since the boot (no START motion): VC (down, or on its way) and HC (at its end) go
    // home, RC's home switch reads home (skipped), GR- runs its dwell on a valve that is
    // off already (the plant sees no change).
    assert_eq!(
        robot_analysis::sim::steps_text(&c.ir.homing),
        "VC- HC- RC- GR-"
    );
    let homing = home_ok(&mut bed, &c);
    assert_eq!(homing.join(" "), "VC- HC-");
    assert_running(&mut bed, &c);
    let cycle = exact_cycle(&mut bed, &c, 1);
    assert_eq!(robot_analysis::sim::steps_text(&cycle.steps), SEQUENCE_1);
    bed.stop();
}

/// Jams `actuator`'s rod (it stays where it is) once the plant has seen `after` steps, and
/// watches the machine (ready for `run_cycle`).
pub fn jam_after(bed: &mut Bed, c: &Compiled, actuator: &str, after: usize) {
    let actuators = robot_net::live_plant::actuators(c).unwrap();
    let at = actuators.iter().position(|a| a.name == actuator).unwrap();
    bed.set_plant_injected(
        actuators,
        Some(robot_net::live_plant::Injection {
            after,
            actuator: at,
            kind: robot_net::live_plant::Jam::Stuck,
        }),
    )
    .unwrap();
    bed.watch(c).unwrap();
}

/// `robot-configs/NAME` with security off (`security: Off` after its network), written to
/// `dir`: its path, and the robot compiled for generation 1. For command-line tests that
/// run the tool without keys.
pub fn unsecured_robot(dir: &TempDir, name: &str) -> (PathBuf, Compiled) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("robot-configs").join(name)).expect("robot");
    let network = (text.lines())
        .find(|l| l.starts_with("    network: (") && l.ends_with("),"))
        .unwrap_or_else(|| panic!("{name} has a network line"));
    let network = format!("{network}\n");
    let text = text.replacen(&network, &format!("{network}    security: Off,\n"), 1);
    let path = dir.0.join(name);
    std::fs::write(&path, &text).expect("robot file");
    let c = compile::compile(&Source::new(name, text))
        .unwrap_or_else(|d| panic!("{name} does not compile: {d:?}"));
    (path, c.with_generation(1).expect("re-encodes"))
}

/// The tool run at the workspace root without keys: (exit status, stdout, stderr).
pub fn run_tool(args: &[&str]) -> (Option<i32>, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(args)
        .env_remove("CONFIG_TOOL_KEYS")
        .output()
        .expect("runs");
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    (out.status.code(), text(&out.stdout), text(&out.stderr))
}

/// A `config-tool plant` process and what it prints, line by line (ended when dropped).
pub struct PlantProcess {
    child: std::process::Child,
    lines: std::sync::mpsc::Receiver<String>,
    errors: std::sync::mpsc::Receiver<String>,
    timeout: Duration,
}

impl PlantProcess {
    /// Types `line` on its standard input, as the operator would.
    pub fn type_line(&mut self, line: &str) {
        use std::io::Write;
        let stdin = self.child.stdin.as_mut().expect("stdin");
        writeln!(stdin, "{line}").expect("the plant reads its standard input");
    }

    /// The next line it says on standard error, waiting at most the bed's timeout.
    pub fn next_error(&self) -> String {
        self.errors
            .recv_timeout(self.timeout)
            .expect("the plant said more on standard error")
    }

    /// The next thing it says after the time column (`PUSHER clockwise`), waiting at most
    /// the bed's timeout.
    pub fn next_said(&self) -> String {
        self.next_timed().1
    }

    /// The next line it says: its time column (seconds) and what follows it.
    pub fn next_timed(&self) -> (f64, String) {
        let line = self
            .lines
            .recv_timeout(self.timeout)
            .expect("the plant said more");
        let line = line.trim_start();
        line.split_once("  ")
            .map_or((f64::NAN, String::new()), |(t, l)| {
                (t.trim().parse().unwrap_or(f64::NAN), l.to_string())
            })
    }
}

impl Drop for PlantProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Robot `c` (the file `robot-configs/NAME`) on a bed of its nodes, pushed, with no plant
/// of the bed's: `config-tool plant` runs it as a process of its own, returned once it
/// says it is on the medium.
pub fn pushed_with_plant_process(c: &Compiled, name: &str) -> (Bed, PlantProcess) {
    pushed_with_plant(c, name, true)
}

/// As [`pushed_with_plant_process`], the nodes given a management key if `secured` (a
/// bed without one leaves the tool's commands to `run_tool` of a robot file with
/// `security: Off`: [`unsecured_robot`]).
pub fn pushed_with_plant(c: &Compiled, name: &str, secured: bool) -> (Bed, PlantProcess) {
    use std::io::{BufRead, BufReader};
    let mut opts = options(medium::Config::default(), None);
    opts.secured = secured;
    let timeout = opts.timeout;
    let mut bed = Bed::start(opts).expect("bed");
    let addrs = demo::node_addrs(c);
    for a in &addrs {
        bed.start_node(*a).expect("node");
    }
    bed.wait_for_nodes(&addrs).expect("nodes");
    let pushed = bed.push(c, false, &mut |_, _, _| {}).expect("push");
    assert!(pushed.iter().all(|p| p.switched()), "{pushed:?}");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .arg("plant")
        .arg(Path::new("robot-configs").join(name))
        .arg("--medium")
        .arg(bed.medium().addr().to_string())
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("plant");
    let lines_of = |from: Box<dyn std::io::Read + Send>| {
        let (tx, lines) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for l in BufReader::new(from).lines().map_while(Result::ok) {
                let _ = tx.send(l);
            }
        });
        lines
    };
    let lines = lines_of(Box::new(child.stdout.take().expect("stdout")));
    let errors = lines_of(Box::new(child.stderr.take().expect("stderr")));
    let plant = PlantProcess {
        child,
        lines,
        errors,
        timeout,
    };
    while !(plant.lines.recv_timeout(timeout))
        .expect("the plant said more")
        .starts_with("plant on ")
    {}
    (bed, plant)
}

/// The paint robot (`security: Off`, its watchdog ten minutes) on a bed of host nodes,
/// pushed, homed and started, under way for as long as the test needs: HC's end switch
/// never closes, so the cycle waits after `VC+ GR+ VC- HC+` (no node faulted, VC, GR and
/// HC not at their idle points, RC at its own). Returns once the plant saw those four.
pub fn under_way_for_good(dir: &TempDir) -> (Bed, Compiled) {
    let (file, _) = unsecured_robot(dir, "paint-robot.ron");
    let slow = std::fs::read_to_string(&file).expect("robot").replacen(
        "motion_timeout_ms: 2000",
        "motion_timeout_ms: 600000",
        1,
    );
    std::fs::write(&file, &slow).expect("robot");
    let paint = compile::compile(&Source::new("slow", slow))
        .expect("compiles")
        .with_generation(1)
        .expect("encodes");
    let mut opts = options(medium::Config::default(), None);
    opts.secured = false;
    let mut bed = bring_up(&paint, opts);
    push_and_home(&mut bed, &paint);
    let actuators = live_plant::actuators(&paint).expect("actuators");
    let hc = actuators.iter().position(|a| a.name == "HC").expect("HC");
    bed.set_plant_injected(
        actuators,
        Some(live_plant::Injection {
            after: 3,
            actuator: hc,
            kind: live_plant::Jam::SwitchOpen { end: true },
        }),
    )
    .expect("plant");
    bed.press_start(&paint).expect("START");
    bed.await_strokes(4).expect("VC+ GR+ VC- HC+");
    (bed, paint)
}
