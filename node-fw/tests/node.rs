//! The generic node end to end on a lossy radio: unconfigured nodes announce themselves, the
//! tool pushes their tables over the air, events then cross between them exactly once and in
//! order; stale pushes, flash failures and hostile frames change nothing.

mod support;
use support::{Channel, Rng};

use config_schema::link_keys::decode_deployment;
use config_schema::wire::mac::{self, Frame, Header, BROADCAST, MAX_PSDU};
use config_schema::wire::msg::{Announce, Command, Message, Refusal, Status};
use config_schema::{Action, Level, Output, Publication, Subscription, Table, TableId};
use node_fw::epoch::Epochs;
use node_fw::node::{FlashRequest, Io, NodeCore, CONFIG_PAN};
use node_fw::{ota, switch};
use test_tables::{blob, button, toggle};

const TOOL: u16 = 0x0100;
const A: u16 = 0x0001;
const B: u16 = 0x0002;
const PAN: u16 = 0x4242;
const BUTTON_PIN: u8 = 5;
const LAMP_PIN: u8 = 7;

/// A: a button whose press is published to B.
fn table_a(generation: u32) -> Table {
    let mut t = Table::empty("A");
    t.generation = generation;
    t.header.pan_id = PAN;
    let press = button(&mut t, BUTTON_PIN);
    t.start = Some(press);
    t.peers.push(B).unwrap();
    t.publications
        .push(Publication {
            event: press,
            topic: 3,
            subscribers: 0b1,
        })
        .unwrap();
    t
}

/// B: a lamp toggled by every press published by A.
fn table_b(generation: u32) -> Table {
    let mut t = Table::empty("B");
    t.generation = generation;
    t.header.pan_id = PAN;
    let press = t.push_event().unwrap();
    t.outputs.push(Output::safe(LAMP_PIN, false)).unwrap();
    t.peers.push(A).unwrap();
    t.subscriptions
        .push(Subscription {
            publisher: 0,
            topic: 3,
            event: press,
        })
        .unwrap();
    toggle(&mut t, press, &[Action::Drive { mask: 1, value: 1 }]);
    t
}

/// A node's outside: what it transmitted, the pin levels it set, the transfer staged in
/// its flash.
#[derive(Default)]
struct Board {
    out: Vec<Vec<u8>>,
    pins: Vec<(u8, bool)>,
    staged: Option<Vec<u8>>,
    /// The boot counter in its flash (what `FlashRequest::CountBoot` counts).
    boots: u32,
}

/// What the runtime does with the node's flash requests (a slot kept in RAM).
fn serve_flash(node: &mut NodeCore, board: &mut Board, ok: bool, now: u64) {
    match node.flash_request() {
        Some(FlashRequest::Stage(bytes)) => {
            if ok {
                board.staged = Some(bytes.to_vec());
            }
            node.staged(ok, board);
        }
        Some(FlashRequest::Confirm) => node.confirmed(ok, board),
        // This harness keeps one staged copy, no previous table.
        Some(FlashRequest::Rollback) => node.activated(None, now, board),
        Some(FlashRequest::Activate { .. }) => {
            let deployed = board
                .staged
                .take()
                .filter(|_| ok)
                .and_then(|b| decode_deployment(&b).ok());
            node.activated(deployed, now, board);
        }
        Some(FlashRequest::CountBoot) => {
            board.boots += u32::from(ok);
            let _ = node.boot_counted(ok.then_some(board.boots));
        }
        None => {}
    }
}

impl Io for Board {
    fn transmit(&mut self, psdu: &[u8]) {
        self.out.push(psdu.to_vec());
    }
    fn set_pin(&mut self, pin: u8, level: bool) {
        self.pins.push((pin, level));
    }
}

/// Two nodes and the tool on one lossy radio.
struct Net {
    rng: Rng,
    air: Channel<Vec<u8>>,
    nodes: Vec<(NodeCore, Board)>,
    /// Messages the tool received: (src, message bytes).
    tool_inbox: Vec<(u16, Vec<u8>)>,
    flash_ok: bool,
    now: u64,
    seq: u8,
}

impl Net {
    fn new(loss: f64, dup: f64, seed: u64) -> Self {
        Self::on_boards(loss, dup, seed, u64::MAX)
    }

    /// Nodes on boards with pins `board_pins` (bit n: pin n).
    fn on_boards(loss: f64, dup: f64, seed: u64, board_pins: u64) -> Self {
        Net {
            rng: Rng::new(seed),
            air: Channel::new(loss, dup, (1, 8)),
            nodes: vec![
                (NodeCore::new(A, board_pins, None, 1), Board::default()),
                (NodeCore::new(B, board_pins, None, 1), Board::default()),
            ],
            tool_inbox: Vec::new(),
            flash_ok: true,
            now: 0,
            seq: 0,
        }
    }

    fn tool_send(&mut self, dst: u16, msg: &Message) {
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
        self.air.send(&mut self.rng, self.now, psdu[..len].to_vec());
    }

    /// One millisecond: deliver due frames, poll the nodes, put what they sent on the air.
    fn tick(&mut self) {
        for psdu in self.air.due(self.now) {
            let Ok(Frame::Data { header, payload }) = Frame::parse(&psdu) else {
                panic!("the medium only carries good frames here");
            };
            if header.dst == TOOL || header.dst == BROADCAST {
                self.tool_inbox.push((header.src, payload.to_vec()));
            }
            for (node, board) in &mut self.nodes {
                if header.dst == node.addr() || header.dst == BROADCAST {
                    node.receive(&psdu, self.now, board);
                    serve_flash(node, board, self.flash_ok, self.now);
                }
            }
        }
        for (node, board) in &mut self.nodes {
            node.poll(self.now, board);
            for psdu in board.out.drain(..) {
                self.air.send(&mut self.rng, self.now, psdu);
            }
        }
        self.now += 1;
    }

    fn run(&mut self, ms: u64) {
        for _ in 0..ms {
            self.tick();
        }
    }

    /// Pushes `table` to `dst` with the tool's OTA sender, then switches it over (armed,
    /// at its idle point); returns the outcome.
    fn push(&mut self, dst: u16, table: &Table, force: bool) -> ota::Progress {
        self.push_at(dst, table, force, false)
    }

    /// [`Net::push`], switched over at once (`now`) whatever the node does.
    fn push_at(&mut self, dst: u16, table: &Table, force: bool, now: bool) -> ota::Progress {
        let staged = self.stage(dst, table, force);
        if staged != ota::Progress::Done {
            return staged;
        }
        match self.switch(dst, table.generation, now) {
            switch::Verdict::Switched => ota::Progress::Done,
            _ => {
                let (node, _) = self.nodes.iter().find(|(n, _)| n.addr() == dst).unwrap();
                ota::Progress::Refused(if node.generation() == table.generation {
                    Refusal::Invalid
                } else {
                    Refusal::Flash
                })
            }
        }
    }

    /// The switch-over of `dst` to `generation`, with the tool's coordinator.
    fn switch(&mut self, dst: u16, generation: u32, now: bool) -> switch::Verdict {
        let mut c = switch::Coordinator::new(&[dst], generation, now, 10_000, self.now);
        let mut out = Vec::new();
        let start = self.now;
        while c.verdict() == switch::Verdict::Busy && self.now - start < 20_000 {
            c.poll(self.now, |a, m| out.push((a, m)));
            for (a, m) in out.drain(..) {
                self.tool_send(a, &m);
            }
            self.tick();
            for (src, bytes) in std::mem::take(&mut self.tool_inbox) {
                if let Ok(Message::ConfigReply { generation, reply }) = Message::parse(&bytes) {
                    c.on_reply(src, generation, reply, self.now, |a, m| out.push((a, m)));
                }
            }
        }
        c.verdict()
    }

    /// Stages `table` at `dst` and tries to switch it over at its idle point.
    fn switch_staged(&mut self, dst: u16, table: &Table) -> switch::Verdict {
        assert_eq!(self.stage(dst, table, false), ota::Progress::Done);
        self.switch(dst, table.generation, false)
    }

    /// Stages `table` at `dst` with the tool's OTA sender; returns its outcome.
    fn stage(&mut self, dst: u16, table: &Table, force: bool) -> ota::Progress {
        let bytes = blob(table);
        let mut tx = ota::Sender::new(&bytes, table.generation, force);
        let mut out = Vec::new();
        tx.start(self.now, |m| out.push(m));
        let start = self.now;
        while tx.progress() == ota::Progress::Busy && self.now - start < 20_000 {
            for m in out.drain(..) {
                self.tool_send(dst, &m);
            }
            self.tick();
            for (src, bytes) in std::mem::take(&mut self.tool_inbox) {
                if let (true, Ok(Message::ConfigReply { generation, reply })) =
                    (src == dst, Message::parse(&bytes))
                {
                    tx.on_reply(generation, reply, self.now, |m| out.push(m));
                }
            }
            tx.poll(self.now, |m| out.push(m));
        }
        tx.progress()
    }

    fn press(&mut self) {
        let (node, board) = &mut self.nodes[0];
        node.input(BUTTON_PIN, true, self.now, board);
        self.run(20);
        let (node, board) = &mut self.nodes[0];
        node.input(BUTTON_PIN, false, self.now, board);
        self.run(180);
    }

    fn status(&mut self, dst: u16) -> Status {
        self.ask(dst, Command::Status, |m| match m {
            Message::Status(s) => Some(s),
            _ => None,
        })
    }

    fn announce(&mut self, dst: u16) -> Announce {
        let nonce = 0x0123_4567_89AB_CDEF;
        self.ask(dst, Command::Identify { nonce }, |m| match m {
            Message::Announce(a) if a.nonce == nonce => Some(a),
            _ => None,
        })
    }

    /// Sends `command` to `dst` until an answer `answer` takes comes back from it.
    fn ask<T>(&mut self, dst: u16, command: Command, answer: impl Fn(Message) -> Option<T>) -> T {
        self.tool_inbox.clear();
        for _ in 0..50 {
            self.tool_send(dst, &Message::Command { id: 1, command });
            self.run(30);
            for (src, bytes) in std::mem::take(&mut self.tool_inbox) {
                if let Some(a) = Message::parse(&bytes)
                    .ok()
                    .filter(|_| src == dst)
                    .and_then(&answer)
                {
                    return a;
                }
            }
        }
        panic!("no answer to {command:?} from {dst:#06x}");
    }
}

#[test]
fn unconfigured_nodes_announce_themselves() {
    let mut net = Net::new(0.0, 0.0, 1);
    net.run(10);
    let announced: Vec<u16> = net
        .tool_inbox
        .iter()
        .filter(|(_, b)| matches!(Message::parse(b), Ok(Message::Announce(a)) if a.role.is_empty() && a.generation == 0))
        .map(|(src, _)| *src)
        .collect();
    assert_eq!(announced, vec![A, B]);
}

#[test]
fn pushed_tables_carry_events_exactly_once_in_order_under_loss() {
    for seed in 1..=5 {
        let mut net = Net::new(0.2, 0.1, seed);
        assert_eq!(
            net.push(A, &table_a(1), false),
            ota::Progress::Done,
            "seed {seed}"
        );
        assert_eq!(
            net.push(B, &table_b(1), false),
            ota::Progress::Done,
            "seed {seed}"
        );
        // Activation drove B's lamp to its safe value.
        assert_eq!(net.nodes[1].1.pins, vec![(LAMP_PIN, false)], "seed {seed}");
        net.nodes[1].1.pins.clear();
        for _ in 0..10 {
            net.press();
        }
        net.run(3000);
        let lamp: Vec<bool> = net.nodes[1].1.pins.iter().map(|&(_, l)| l).collect();
        assert_eq!(
            lamp,
            [true, false].repeat(5),
            "seed {seed}: exactly one toggle per press"
        );
        let b = net.status(B);
        assert_eq!(b.role.as_str(), "B");
        assert_eq!(b.generation, 1);
        assert_eq!(b.counters.delivered, 10, "seed {seed}");
        assert_eq!(b.states.as_slice(), &[0]);
        let a = net.status(A);
        assert_eq!(a.link_alarms, 0);
        assert!(
            a.counters.retried > 0,
            "seed {seed}: the loss forced retries"
        );
    }
}

/// The identity a node should report for `table`: the last four bytes of its blob (the
/// CRC the tool compares).
fn blob_crc(table: &Table) -> TableId {
    let mut buf = [0u8; 4096];
    let n = config_schema::encode(table, &mut buf).unwrap();
    TableId(buf[n - 4..n].try_into().unwrap())
}

#[test]
fn a_node_reports_the_identity_of_the_table_it_runs() {
    let mut net = Net::new(0.0, 0.0, 3);
    assert_eq!(net.status(B).table, TableId::NONE);
    assert_eq!(net.push(B, &table_b(4), false), ota::Progress::Done);
    assert_eq!(net.status(B).table, blob_crc(&table_b(4)));
    assert_ne!(blob_crc(&table_b(4)), blob_crc(&table_b(5)));
    // A table that could not be persisted is not run: the identity stays.
    net.flash_ok = false;
    assert_eq!(
        net.push(B, &table_b(5), false),
        ota::Progress::Refused(Refusal::Flash)
    );
    assert_eq!(net.status(B).table, blob_crc(&table_b(4)));
    net.flash_ok = true;
    assert_eq!(net.push(B, &table_b(5), false), ota::Progress::Done);
    assert_eq!(net.status(B).table, blob_crc(&table_b(5)));
    // Its answer to Identify says the same.
    assert_eq!(net.announce(B).table, blob_crc(&table_b(5)));
    assert_eq!(net.announce(A).table, TableId::NONE);
}

#[test]
fn a_stale_push_is_refused_and_a_failed_flash_keeps_the_old_table() {
    let mut net = Net::new(0.0, 0.0, 7);
    assert_eq!(net.push(B, &table_b(4), false), ota::Progress::Done);
    assert_eq!(
        net.push(B, &table_b(4), false),
        ota::Progress::Refused(Refusal::Stale { running: 4 })
    );
    net.flash_ok = false;
    assert_eq!(
        net.push(B, &table_b(5), false),
        ota::Progress::Refused(Refusal::Flash)
    );
    assert_eq!(net.nodes[1].0.generation(), 4);
    net.flash_ok = true;
    assert_eq!(net.push(B, &table_b(5), false), ota::Progress::Done);
    assert_eq!(net.nodes[1].0.generation(), 5);
}

#[test]
fn a_silent_subscriber_raises_the_link_alarm_and_nothing_moves_twice() {
    let mut net = Net::new(0.0, 0.0, 3);
    assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
    assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
    net.nodes[1].1.pins.clear();
    net.air.loss = 1.0; // B's radio dies
    net.press();
    net.run(3000);
    assert!(net.nodes[1].1.pins.is_empty());
    assert_eq!(net.nodes[0].0.link_alarms(), 0b1);
    net.air.loss = 0.0; // back: the press arrives once, late, and the alarm clears
    net.run(1000);
    assert_eq!(net.nodes[1].1.pins, vec![(LAMP_PIN, true)]);
    assert_eq!(net.nodes[0].0.link_alarms(), 0);
}

#[test]
fn hostile_frames_are_dropped_and_counted() {
    let mut net = Net::new(0.0, 0.0, 9);
    assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
    let (node, board) = &mut net.nodes[1];
    let before = node.counters().dropped;
    let mut rng = Rng::new(42);
    let mut sent = 0;
    for len in 0..200usize {
        let bytes: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();
        node.receive(&bytes, 0, board);
        sent += 1;
    }
    // A good frame to B with a payload that is not a message.
    let header = Header {
        seq: 1,
        pan_id: PAN,
        dst: B,
        src: A,
        ack_request: false,
        secured: false,
    };
    let mut psdu = [0u8; MAX_PSDU];
    let n = mac::emit_data(&header, &[0xFF, 0xFF, 0xFF], &mut psdu).unwrap();
    node.receive(&psdu[..n], 0, board);
    sent += 1;
    // An event from a node that is not a peer.
    let n = {
        let mut payload = [0u8; 16];
        let m = Message::Event {
            epoch: 1,
            seq: 0,
            topic: 3,
        }
        .emit(&mut payload)
        .unwrap();
        let h = Header {
            src: 0x0666,
            ..header
        };
        mac::emit_data(&h, &payload[..m], &mut psdu).unwrap()
    };
    node.receive(&psdu[..n], 0, board);
    sent += 1;
    assert_eq!(node.counters().dropped - before, sent);
    assert!(board.pins.iter().all(|&(_, l)| !l), "nothing moved");
    assert_eq!(node.counters().delivered, 0);
}

#[test]
fn a_repeated_command_is_acknowledged_but_runs_once() {
    let mut net = Net::new(0.0, 0.0, 11);
    assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
    assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
    net.nodes[1].1.pins.clear();
    let start = |id| Message::Command {
        id,
        command: Command::Start,
    };
    let mut acks = Vec::new();
    for id in [7, 7, 7, 8] {
        net.tool_send(A, &start(id));
        net.run(200);
        for (src, bytes) in std::mem::take(&mut net.tool_inbox) {
            if let (A, Ok(Message::Status(s))) = (src, Message::parse(&bytes)) {
                acks.push(s.ack);
            }
        }
    }
    assert_eq!(acks, vec![7, 7, 7, 8], "every copy is answered");
    // START raised A's press event twice (ids 7 and 8), not four times.
    assert_eq!(
        net.nodes[1].1.pins,
        vec![(LAMP_PIN, true), (LAMP_PIN, false)]
    );
}

/// Two runs of the tool at once (a panel and a CLI command share the tool's address): one
/// resends its START (id 7, its answer lost) after the other's command (id 8) came in
/// between. The node remembered one id per sender, took the resent START for a new one and
/// ran it twice.
#[test]
fn a_command_resent_after_another_runs_command_runs_once() {
    let mut net = Net::new(0.0, 0.0, 11);
    assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
    assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
    net.nodes[1].1.pins.clear();
    let command = |id, command| Message::Command { id, command };
    // Between them, another run's ACK (id 8) and its polls.
    let mut between: Vec<_> = (100..120).map(|id| command(id, Command::Status)).collect();
    between.push(command(8, Command::Ack));
    let sent = [command(7, Command::Start)]
        .into_iter()
        .chain(between)
        .chain([command(7, Command::Start)]);
    for m in sent {
        net.tool_send(A, &m);
        net.run(200);
    }
    assert_eq!(net.nodes[1].1.pins, vec![(LAMP_PIN, true)], "one START ran");
    // Past `REPEAT_MS`, the same id is a new command (a later run drew it again).
    net.run(u64::from(node_fw::node::REPEAT_MS));
    net.tool_send(A, &command(7, Command::Start));
    net.run(200);
    assert_eq!(
        net.nodes[1].1.pins,
        vec![(LAMP_PIN, true), (LAMP_PIN, false)],
        "a START again"
    );
}

#[test]
fn a_switch_already_closed_at_activation_raises_no_event() {
    let mut net = Net::new(0.0, 0.0, 13);
    // The plant reports A's button held down while A is still unconfigured.
    let (a, board) = &mut net.nodes[0];
    a.input(BUTTON_PIN, true, 0, board);
    assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
    assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
    net.nodes[1].1.pins.clear();
    // The plant repeats the level it holds: no edge, no event.
    let (a, board) = &mut net.nodes[0];
    a.input(BUTTON_PIN, true, net.now, board);
    net.run(500);
    assert!(net.nodes[1].1.pins.is_empty());
    // Released and pressed again: one event.
    let (a, board) = &mut net.nodes[0];
    a.input(BUTTON_PIN, false, net.now, board);
    net.run(50);
    net.press();
    net.run(500);
    assert_eq!(net.nodes[1].1.pins, vec![(LAMP_PIN, true)]);
}

#[test]
fn a_table_loaded_at_boot_starts_from_the_seeded_pin_levels() {
    let mut a = NodeCore::new(A, u64::MAX, Some(table_a(1)), 1);
    a.seed_pins(1 << BUTTON_PIN);
    let mut board = Board::default();
    a.input(BUTTON_PIN, true, 0, &mut board);
    a.poll(0, &mut board);
    // What the boot sent: its greeting to B, no event.
    let sent = |board: &Board| Net::events_sent_by(&board.out);
    let greeting = match Frame::parse(&board.out[0]) {
        Ok(Frame::Data { header, payload }) => (header.dst, Message::parse(payload).ok()),
        other => panic!("{other:?}"),
    };
    let nonce = node_fw::restart::GREETING;
    assert_eq!(
        greeting,
        (B, Some(Message::Challenge { nonce })),
        "its greeting"
    );
    assert_eq!(board.out.len(), 1, "the greeting alone");
    assert!(sent(&board).is_empty(), "no edge: nothing published");
    a.input(BUTTON_PIN, false, 1, &mut board);
    a.input(BUTTON_PIN, true, 2, &mut board);
    assert_eq!(sent(&board), [(B, 2, 0)], "one edge: one event frame to B");
}

impl Net {
    /// Sends command `command` (id `id`) to `dst` until its status acknowledges it.
    fn command(&mut self, dst: u16, id: u16, command: Command) -> Status {
        self.tool_inbox.clear();
        for _ in 0..50 {
            self.tool_send(dst, &Message::Command { id, command });
            self.run(30);
            for (src, bytes) in std::mem::take(&mut self.tool_inbox) {
                if let (true, Ok(Message::Status(s))) = (src == dst, Message::parse(&bytes)) {
                    if s.ack == id {
                        return s;
                    }
                }
            }
        }
        panic!("no answer from {dst:#06x}");
    }

    /// Every event frame in flight or queued, as (dst, epoch, seq).
    fn events_sent_by(out: &[Vec<u8>]) -> Vec<(u16, u16, u16)> {
        out.iter()
            .filter_map(|psdu| match Frame::parse(psdu) {
                Ok(Frame::Data { header, payload }) => match Message::parse(payload) {
                    Ok(Message::Event { epoch, seq, .. }) => Some((header.dst, epoch, seq)),
                    _ => None,
                },
                _ => None,
            })
            .collect()
    }
}

/// 5,000 presses in one millisecond overflow A's queue to B: the link breaks (no event is
/// skipped); the operator's reset re-establishes it in a new epoch, B accepts it from seq 0,
/// and every later press arrives exactly once, in order; old-epoch frames stay dropped.
#[test]
fn a_flood_breaks_a_link_and_the_operators_reset_re_establishes_it() {
    let mut net = Net::new(0.0, 0.0, 21);
    assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
    assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
    net.nodes[1].1.pins.clear();
    let mut old_frames = Vec::new();
    {
        let (a, board) = &mut net.nodes[0];
        for _ in 0..5_000 {
            a.input(BUTTON_PIN, true, net.now, board);
            a.input(BUTTON_PIN, false, net.now, board);
        }
        old_frames.extend(board.out.iter().cloned());
    }
    let old = Net::events_sent_by(&old_frames);
    assert_eq!(
        old.iter().map(|e| e.2).collect::<Vec<_>>(),
        vec![0, 1, 2, 3],
        "the window went out, nothing after the overflow"
    );
    let old_epoch = old[0].1;
    net.run(3000);
    // B got the queued presses (the window, then the rest of the queue) and nothing more.
    let delivered = net.status(B).counters.delivered;
    assert_eq!(delivered, 16);
    assert_eq!(net.nodes[1].1.pins.len(), 16);
    // Broken for good: another press goes nowhere; status tells it from an alarm.
    net.press();
    net.run(1000);
    assert_eq!(net.status(B).counters.delivered, 16);
    let a = net.status(A);
    assert_eq!(
        (a.links_broken, a.link_alarms, a.links_restarted, a.epoch),
        (0b1, 0, 0, old_epoch)
    );

    // The operator resets A: its link to B starts over in a new epoch, and the answer
    // says so.
    let reset = net.command(A, 40, Command::Reset);
    assert_eq!(
        (reset.links_broken, reset.link_alarms, reset.links_restarted),
        (0, 0, 0b1)
    );
    assert_eq!(reset.epoch, old_epoch.wrapping_add(1));
    net.nodes[1].1.pins.clear();
    let mut sent_after = Vec::new();
    for _ in 0..3 {
        let (a, board) = &mut net.nodes[0];
        a.input(BUTTON_PIN, true, net.now, board);
        sent_after.extend(board.out.iter().cloned());
        net.run(20);
        let (a, board) = &mut net.nodes[0];
        a.input(BUTTON_PIN, false, net.now, board);
        net.run(180);
    }
    let new = Net::events_sent_by(&sent_after);
    assert_eq!(
        new.iter().map(|e| (e.0, e.2)).collect::<Vec<_>>(),
        vec![(B, 0), (B, 1), (B, 2)]
    );
    assert!(new.iter().all(|e| e.1 == old_epoch.wrapping_add(1)));
    assert_eq!(
        net.nodes[1].1.pins,
        vec![(LAMP_PIN, true), (LAMP_PIN, false), (LAMP_PIN, true)],
        "B's lamp: one toggle per press, from where it was"
    );
    // Old-epoch frames (a late copy on the radio) are dropped: nothing moves.
    net.nodes[1].1.pins.clear();
    for psdu in &old_frames {
        let (b, board) = &mut net.nodes[1];
        b.receive(psdu, net.now, board);
    }
    assert!(net.nodes[1].1.pins.is_empty());
    assert_eq!(net.status(B).counters.delivered, 16 + 3);
    // A reset of a quiet machine re-establishes nothing and takes no epoch.
    let again = net.command(A, 41, Command::Reset);
    assert_eq!(
        (again.links_restarted, again.links_broken, again.epoch),
        (0, 0, old_epoch.wrapping_add(1))
    );
}

/// A power cut of the subscriber on a robot without link keys: B boots its table from
/// flash with a fresh receiver (it waits for seq 0), while A numbered on. B's first event
/// past seq 0 makes it challenge A in clear, naming the epoch it asks for; A numbers its
/// link to B again from 0 in that epoch, with what B did not acknowledge (the press made
/// while B was off). No reset: every press from then on toggles B's lamp exactly once, in
/// order, under loss, duplication and reordering, and A's link ends without an alarm.
#[test]
fn after_the_subscriber_restarts_unsecured_links_are_numbered_again_and_events_flow() {
    for seed in 1..=8 {
        let mut net = Net::new(0.2, 0.1, 40 + seed);
        assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
        assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
        for _ in 0..3 {
            net.press();
        }
        net.run(1000);
        let lamp: Vec<bool> = net.nodes[1].1.pins.iter().map(|&(_, l)| l).collect();
        assert_eq!(
            lamp,
            [false, true, false, true],
            "seed {seed}: activation, three toggles"
        );
        // B's power is cut: frames to B reach nobody. A press meanwhile.
        net.nodes[1] = (NodeCore::new(0x0077, u64::MAX, None, 1), Board::default());
        net.press();
        net.run(100);
        // B boots its table from flash (a boot drives its lamp to the start level).
        net.nodes[1] = (
            NodeCore::new(B, u64::MAX, Some(table_b(1)), 2),
            Board::default(),
        );
        let (b, board) = &mut net.nodes[1];
        b.boot(board);
        net.run(1000);
        for _ in 0..4 {
            net.press();
        }
        net.run(3000);
        let lamp: Vec<bool> = net.nodes[1].1.pins.iter().map(|&(_, l)| l).collect();
        assert_eq!(
            lamp,
            [false, true, false, true, false, true],
            "seed {seed}: the boot's level, then one toggle per press (the one made while B \
             was off first)"
        );
        assert_eq!(net.status(B).counters.delivered, 5, "seed {seed}");
        let a = net.status(A);
        assert_eq!((a.link_alarms, a.links_broken), (0, 0), "seed {seed}");
    }
}

/// A node stays up while its subscriber reboots 300 times on a robot without link keys:
/// each reboot, B's fresh receiver asks A to number its link again, and A takes one more
/// epoch of the 256 its boot count reserves (boot 1: epochs 256 to 511). Then A's power is
/// cut. Its next boot must start above every epoch B took from it, or B drops every event
/// A sends from then on (a stall, before: A's boot 2 started at 512, below the 557 B had
/// taken). A asks its board to count a boot once half its reserved epochs are taken
/// (at 384: count 2, reserving up to 767), so its next boot is count 3, at 768.
#[test]
fn a_node_up_through_hundreds_of_its_peers_reboots_boots_next_above_every_epoch_it_took() {
    let mut net = Net::new(0.0, 0.0, 7);
    net.nodes[0] = (
        NodeCore::new(A, u64::MAX, Some(table_a(1)), Epochs::counted(1)),
        Board {
            boots: 1,
            ..Board::default()
        },
    );
    net.nodes[1] = (
        NodeCore::new(B, u64::MAX, Some(table_b(1)), 1),
        Board::default(),
    );
    for (node, board) in &mut net.nodes {
        node.boot(board);
    }
    net.run(1000);
    net.press();
    for reboot in 0..300u16 {
        // B reboots (its own epochs from the clock), and two presses reach its new life
        // (its lamp back at rest: A's next boot then faults nothing).
        net.nodes[1] = (
            NodeCore::new(B, u64::MAX, Some(table_b(1)), 1000 + reboot),
            Board::default(),
        );
        let (b, board) = &mut net.nodes[1];
        b.boot(board);
        net.run(1000);
        net.press();
        net.press();
        net.run(300);
    }
    // Each life of B toggled its lamp once a press (after the level its boot drives).
    assert_eq!(
        net.nodes[1].1.pins,
        [(LAMP_PIN, false), (LAMP_PIN, true), (LAMP_PIN, false)]
    );
    assert_eq!(
        net.nodes[0].0.epoch(),
        256 + 1 + 300,
        "the boot's table, 300 renumberings"
    );
    assert_eq!(net.nodes[0].1.boots, 2, "counted once, at epoch 384");
    assert_eq!(net.nodes[0].0.epochs().end(), Some(768));
    // A's power is cut; it boots from flash, counting the boot.
    let boots = net.nodes[0].1.boots + 1;
    net.nodes[0] = (
        NodeCore::new(A, u64::MAX, Some(table_a(1)), Epochs::counted(boots)),
        Board {
            boots,
            ..Board::default()
        },
    );
    net.nodes[1].1.pins.clear();
    let (a, board) = &mut net.nodes[0];
    a.boot(board);
    assert_eq!(a.epoch(), 768 + 1);
    net.run(1000);
    for _ in 0..3 {
        net.press();
    }
    net.run(1000);
    assert_eq!(
        net.nodes[1].1.pins,
        [(LAMP_PIN, true), (LAMP_PIN, false), (LAMP_PIN, true)],
        "every press of A's new boot toggles B's lamp"
    );
}

/// A node without link keys that boots greets its peers in clear (a `Challenge` whose
/// nonce is `restart::GREETING`), five times, 100 ms apart. B, its lamp on when A's power
/// is cut (its chart neither idle nor initial: under way, as a node in the middle of a
/// cycle), faults `0x86` at the first copy it hears, its lamp at its fault level (off);
/// the other copies change nothing. Reset, at rest, B carries on through A's next restart,
/// and a press toggles its lamp. Before, B stayed on, waiting for what A would never send.
#[test]
fn a_node_under_way_faults_when_a_peer_restarts_and_one_at_rest_carries_on() {
    let restarted = 0x80 | config_schema::alarm::FAULT_PEER_RESTART;
    for seed in 1..=8 {
        let mut net = Net::new(0.2, 0.1, 70 + seed);
        assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
        assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
        net.press();
        net.run(1000);
        assert_eq!(net.status(B).states.as_slice(), [1], "seed {seed}: lamp on");
        for epoch in [5, 6] {
            net.nodes[0] = (
                NodeCore::new(A, u64::MAX, Some(table_a(1)), epoch),
                Board::default(),
            );
            let (a, board) = &mut net.nodes[0];
            a.boot(board);
            net.nodes[1].1.pins.clear();
            net.run(1500);
            let b = net.status(B);
            if epoch == 5 {
                assert_eq!(
                    (b.fault, b.states.as_slice(), b.outputs),
                    (Some(restarted), [1].as_slice(), 0),
                    "seed {seed}"
                );
                assert_eq!(net.nodes[1].1.pins, [(LAMP_PIN, false)], "seed {seed}");
                let reset = net.command(B, 9, Command::Reset);
                assert_eq!(
                    (reset.fault, reset.states.as_slice()),
                    (None, [0].as_slice())
                );
            } else {
                assert_eq!((b.fault, b.states.as_slice()), (None, [0].as_slice()));
                assert!(net.nodes[1].1.pins.is_empty(), "seed {seed}");
            }
        }
        net.nodes[1].1.pins.clear();
        net.press();
        net.run(1000);
        assert_eq!(net.nodes[1].1.pins, [(LAMP_PIN, true)], "seed {seed}");
    }
}

/// A as [`table_a`], its press also toggling a chart of its own (its light on pin 6):
/// after a press A is under way (its chart neither idle nor initial), as a node in the
/// middle of a cycle.
fn table_a_stepping(generation: u32) -> Table {
    let mut t = table_a(generation);
    t.outputs.push(Output::safe(6, false)).unwrap();
    let press = t.inputs[0].rise.unwrap();
    toggle(&mut t, press, &[Action::Drive { mask: 1, value: 1 }]);
    t
}

/// A `Reset` of a node under way (its charts started over, as at a boot) left its peers
/// waiting for ever, with nothing said: the restart rule knew only a boot's greeting. A
/// node reset while under way now greets its peers as a booted one does, and B, under way,
/// faults `0x86` instead of stalling. A node reset at rest (a faulted one, the usual
/// reset) greets nobody: nothing of a cycle was lost, and no late copy can fault a peer
/// that homing sets going right after the resets.
#[test]
fn a_node_reset_under_way_faults_its_peers_under_way_and_one_reset_at_rest_does_not() {
    let restarted = 0x80 | config_schema::alarm::FAULT_PEER_RESTART;
    for seed in 1..=8 {
        let mut net = Net::new(0.2, 0.1, 90 + seed);
        assert_eq!(
            net.push(A, &table_a_stepping(1), false),
            ota::Progress::Done
        );
        assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
        net.press();
        net.run(1000);
        assert_eq!(net.status(B).states.as_slice(), [1], "seed {seed}: lamp on");
        assert_eq!(
            net.status(A).states.as_slice(),
            [1],
            "seed {seed}: A under way"
        );
        let reset = net.command(A, 7, Command::Reset);
        assert_eq!(
            (reset.fault, reset.states.as_slice()),
            (None, [0].as_slice())
        );
        net.run(1500);
        let b = net.status(B);
        assert_eq!(
            (b.fault, b.states.as_slice()),
            (Some(restarted), [1].as_slice()),
            "seed {seed}"
        );
        // B reset, both at rest: a reset of A now changes nothing for B.
        let reset = net.command(B, 8, Command::Reset);
        assert_eq!(
            (reset.fault, reset.states.as_slice()),
            (None, [0].as_slice())
        );
        net.command(A, 9, Command::Reset);
        net.run(1500);
        let b = net.status(B);
        assert_eq!(
            (b.fault, b.states.as_slice()),
            (None, [0].as_slice()),
            "seed {seed}"
        );
        net.nodes[1].1.pins.clear();
        net.press();
        net.run(1000);
        assert_eq!(net.nodes[1].1.pins, [(LAMP_PIN, true)], "seed {seed}");
    }
}

/// A board with pins 0..=5 has B's lamp pin 7 nowhere: B refuses the table, naming the pin
/// and the board's pins, and keeps what it ran; A's button (pin 5) is on the board.
#[test]
fn a_table_naming_a_pin_the_board_lacks_is_refused_with_the_pin() {
    let mut net = Net::on_boards(0.0, 0.0, 23, 0b11_1111);
    assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
    assert_eq!(
        net.push(B, &table_b(1), false),
        ota::Progress::Refused(Refusal::Pin {
            pin: LAMP_PIN,
            board: 0b11_1111
        })
    );
    assert_eq!(net.nodes[1].0.generation(), 0);
    assert!(net.nodes[1].1.pins.is_empty(), "nothing was driven");
    // The same table from flash does not run either.
    let b = NodeCore::new(B, 0b11_1111, Some(table_b(1)), 1);
    assert!(b.table().is_none());
    let b = NodeCore::new(B, u64::MAX, Some(table_b(1)), 1);
    assert_eq!(b.generation(), 1);
}

/// Pin 69 is not pin 5 (69 & 63): a level reported for it leaves pin 5's level alone, so a
/// table with its button on pin 5 still sees the first press as an edge.
#[test]
fn a_pin_past_the_bitmap_does_not_alias_a_real_one() {
    let mut net = Net::new(0.0, 0.0, 25);
    let (a, board) = &mut net.nodes[0];
    a.input(BUTTON_PIN + 64, true, 0, board);
    assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
    assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
    net.nodes[1].1.pins.clear();
    net.press();
    net.run(500);
    assert_eq!(net.nodes[1].1.pins, vec![(LAMP_PIN, true)]);
}

const GRIP_PIN: u8 = 7;
const WARN_PIN: u8 = 8;
const BEACON_PIN: u8 = 9;

/// B as a gripper: each press published by A steps S0 -> S1 [drive the gripper to
/// `close`] -> S2 [fault 9]. The gripper (a monostable valve) holds on fault and at a new
/// table; a warning lamp lights on fault; a beacon is on from the start and off on fault.
fn gripper(generation: u32, close: bool) -> Table {
    let mut t = table_b(generation);
    t.routes.clear();
    t.charts.clear();
    t.states.clear();
    t.transitions.clear();
    t.actions.clear();
    t.outputs.clear();
    let levels = [
        (GRIP_PIN, Level::Hold, Level::Hold, false),
        (WARN_PIN, Level::High, Level::Low, false),
        (BEACON_PIN, Level::Low, Level::High, true),
    ];
    for (pin, fault, start, home) in levels {
        let o = Output {
            pin,
            fault,
            start,
            home,
        };
        t.outputs.push(o).unwrap();
    }
    let grip = Action::Drive {
        mask: 1,
        value: u16::from(close),
    };
    let step = |from, to| config_schema::Transition {
        from,
        to,
        trigger: Some(0),
        guard: None,
    };
    t.push_chart(
        0,
        1,
        &[&[], &[grip], &[Action::Fault(9)]],
        &[step(0, 1), step(1, 2)],
    )
    .unwrap();
    test_tables::route(&mut t, 0, 0, 0);
    t
}

/// A fault holds the gripper closed (its pin is not touched), drives the warning lamp and
/// the beacon to their fault levels; the operator's reset drives the start levels and the
/// gripper still holds.
#[test]
fn a_fault_holds_the_gripper_closed() {
    let mut net = Net::new(0.0, 0.0, 31);
    assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
    assert_eq!(net.push(B, &gripper(1, true), false), ota::Progress::Done);
    // Activation on an unconfigured node: the held gripper at the level it has (low).
    let activation = [(GRIP_PIN, false), (WARN_PIN, false), (BEACON_PIN, true)];
    assert_eq!(net.nodes[1].1.pins, activation);
    net.nodes[1].1.pins.clear();
    net.press();
    assert_eq!(
        net.nodes[1].1.pins,
        [(GRIP_PIN, true)],
        "the part is gripped"
    );
    net.nodes[1].1.pins.clear();
    net.press();
    assert_eq!(
        net.nodes[1].1.pins,
        [(WARN_PIN, true), (BEACON_PIN, false)],
        "faulted: the gripper keeps its part"
    );
    let status = net.status(B);
    assert_eq!((status.fault, status.outputs), (Some(0x89), 0b011));
    net.nodes[1].1.pins.clear();
    let status = net.command(B, 40, Command::Reset);
    assert_eq!(net.nodes[1].1.pins, [(WARN_PIN, false), (BEACON_PIN, true)]);
    assert_eq!((status.fault, status.outputs), (None, 0b101));
}

/// A new table holds the gripper closed: activation does not touch its pin (the old and
/// new tables' other outputs go to their start levels), and the new engine knows it is
/// closed: its first step opens it.
#[test]
fn activation_keeps_the_gripper_closed_and_drives_the_start_levels() {
    let mut net = Net::new(0.0, 0.0, 33);
    assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
    assert_eq!(net.push(B, &gripper(1, true), false), ota::Progress::Done);
    net.press();
    net.nodes[1].1.pins.clear();
    // Gripping, B is not idle: it switches only when told to at once.
    assert_eq!(
        net.switch_staged(B, &gripper(2, false)),
        switch::Verdict::NotIdle
    );
    assert_eq!(net.nodes[1].0.generation(), 1);
    assert!(net.nodes[1].1.pins.is_empty(), "nothing driven");
    assert_eq!(
        net.push_at(B, &gripper(2, false), false, true),
        ota::Progress::Done
    );
    assert_eq!(
        net.nodes[1].1.pins,
        [
            // The running table's outputs the new one does not hold.
            (WARN_PIN, false),
            (BEACON_PIN, true),
            // The new table's: the gripper at the level it has.
            (GRIP_PIN, true),
            (WARN_PIN, false),
            (BEACON_PIN, true),
        ]
    );
    assert_eq!(
        net.status(B).outputs,
        0b101,
        "the new engine knows it is closed"
    );
    net.nodes[1].1.pins.clear();
    net.press();
    assert_eq!(
        net.nodes[1].1.pins,
        [(GRIP_PIN, false)],
        "released by the new table"
    );
}

/// A table that drives none of the running table's pins (a node released from its role:
/// a table with nothing in it) leaves each of them low, whatever its start level was (the
/// beacon's is high: it stayed lit on a node that played no role any more).
#[test]
fn a_table_without_the_old_outputs_leaves_their_pins_low() {
    let mut net = Net::new(0.0, 0.0, 37);
    assert_eq!(net.push(B, &gripper(1, true), false), ota::Progress::Done);
    net.nodes[1].1.pins.clear();
    let mut released = Table::empty("");
    released.generation = 2;
    released.header.pan_id = gripper(1, true).header.pan_id;
    assert_eq!(net.push(B, &released, false), ota::Progress::Done);
    assert_eq!(
        net.nodes[1].1.pins,
        [(GRIP_PIN, false), (WARN_PIN, false), (BEACON_PIN, false)]
    );
}

/// A boot drives the start levels; a held output starts low (out of reset nothing is
/// held), and the engine agrees.
#[test]
fn a_boot_drives_the_start_levels() {
    let mut b = NodeCore::new(B, u64::MAX, Some(gripper(1, true)), 1);
    let mut board = Board::default();
    b.boot(&mut board);
    assert_eq!(
        board.pins,
        [(GRIP_PIN, false), (WARN_PIN, false), (BEACON_PIN, true)]
    );
    assert_eq!(b.engine_state().map(|s| s.outputs), Some(0b100));
}

/// A table that declares no levels (one safe level each, as before): activation drives
/// every old output to it, then every new one, and a fault drives every output to it.
#[test]
fn safe_levels_drive_every_output_as_before() {
    let mut net = Net::new(0.0, 0.0, 35);
    assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
    net.nodes[1].1.pins.clear();
    let mut next = table_b(2);
    next.outputs.push(Output::safe(BEACON_PIN, true)).unwrap();
    assert_eq!(net.push(B, &next, false), ota::Progress::Done);
    assert_eq!(
        net.nodes[1].1.pins,
        [(LAMP_PIN, false), (LAMP_PIN, false), (BEACON_PIN, true)]
    );
    let mut b = NodeCore::new(B, u64::MAX, Some(next), 1);
    let mut board = Board::default();
    b.boot(&mut board);
    assert_eq!(board.pins, [(LAMP_PIN, false), (BEACON_PIN, true)]);
}

/// B with homing: its chart starts `UNHOMED` (S1) and rests in `IDLE` (S0); HOME takes it
/// from `UNHOMED` to `IDLE`; a press (from A) takes it from `IDLE` to `BUSY` (S2), where
/// it stays.
fn homing_b(generation: u32) -> Table {
    let mut t = table_b(generation);
    t.routes.clear();
    t.charts.clear();
    t.states.clear();
    t.transitions.clear();
    t.actions.clear();
    let home = t.push_event().unwrap();
    t.home = Some(home);
    let on = |from, to, trigger| config_schema::Transition {
        from,
        to,
        trigger: Some(trigger),
        guard: None,
    };
    t.push_chart(1, 2, &[&[], &[], &[]], &[on(1, 0, 1), on(0, 2, 0)])
        .unwrap();
    t.charts[0].idle = 0;
    test_tables::route(&mut t, 0, 0, 0);
    test_tables::route(&mut t, home, 0, 1);
    t
}

/// A first table, or one activated on a node that is not at its idle point, starts in its
/// initial (not homed) state; the HOME command raises the table's home event; a table
/// activated at the idle point starts in its idle state.
#[test]
fn a_table_starts_homed_only_when_activated_at_the_idle_point() {
    let mut net = Net::new(0.0, 0.0, 35);
    assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
    assert_eq!(net.push(B, &homing_b(1), false), ota::Progress::Done);
    assert_eq!(net.status(B).states, [1], "a first table: not homed");
    // A press while not homed does nothing.
    net.press();
    assert_eq!(net.status(B).states, [1]);
    // Not homed is at rest: a switch-over need not wait, and the next table is not homed
    // either.
    assert_eq!(
        net.switch_staged(B, &homing_b(10)),
        switch::Verdict::Switched
    );
    assert_eq!(net.status(B).states, [1], "switched at rest, not homed");
    assert_eq!(net.command(B, 50, Command::Home).states, [0], "homed");
    // At the idle point: the next table starts idle.
    assert_eq!(
        net.switch_staged(B, &homing_b(12)),
        switch::Verdict::Switched
    );
    assert_eq!(
        net.status(B).states,
        [0],
        "switched at the idle point: homed"
    );
    // Busy: only an explicit switch-over at once, which starts not homed.
    net.press();
    assert_eq!(net.status(B).states, [2]);
    assert_eq!(
        net.push_at(B, &homing_b(13), false, true),
        ota::Progress::Done
    );
    assert_eq!(
        net.status(B).states,
        [1],
        "switched away from the idle point"
    );
    // A reset, too, leaves the chart not homed.
    assert_eq!(net.command(B, 51, Command::Home).states, [0]);
    assert_eq!(net.command(B, 52, Command::Reset).states, [1]);
}

/// A counts a cycle for each START at its idle point (the button or the command) once it is
/// back at it (here: its published press acknowledged by B).
#[test]
fn the_status_counts_the_cycles_a_start_began_and_that_ended() {
    let mut net = Net::new(0.2, 0.0, 37);
    assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
    assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
    assert_eq!(net.status(A).cycles, 0);
    net.press();
    net.run(2_000);
    net.press();
    net.run(2_000);
    assert_eq!(net.status(A).cycles, 2);
    net.command(A, 60, Command::Start);
    net.run(2_000);
    assert_eq!(net.status(A).cycles, 3);
    assert_eq!(net.status(B).cycles, 0, "B has no START");
}

/// A node that boots with a table raises (and publishes) its boot event once, at its first
/// poll; one that gets its table by a push does not.
#[test]
fn a_node_booting_with_a_table_publishes_its_boot_event_once() {
    let mut net = Net::new(0.0, 0.0, 39);
    assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
    let mut a = table_a(1);
    a.boot = a.start;
    assert_eq!(net.push(A, &a, false), ota::Progress::Done);
    net.run(500);
    assert!(
        !net.nodes[1].1.pins.contains(&(LAMP_PIN, true)),
        "a push is not a boot"
    );
    // A's power cut: it boots its table.
    net.nodes[0].0 = NodeCore::new(A, u64::MAX, Some(a), 2);
    net.run(2_000);
    assert_eq!(
        net.nodes[1]
            .1
            .pins
            .iter()
            .filter(|p| **p == (LAMP_PIN, true))
            .count(),
        1,
        "B heard A's boot once"
    );
}

/// A node quiet for 2^32 ms (49.7 days) and less than 30 s took a new command whose
/// (sender, id) it remembered from before the quiet time for a repeat: it kept the last
/// command's time as `now as u32` ms, whose wrapping difference was under `REPEAT_MS`.
#[test]
fn a_command_49_7_days_later_with_a_remembered_id_is_run() {
    let mut net = Net::new(0.0, 0.0, 11);
    assert_eq!(net.push(A, &table_a(1), false), ota::Progress::Done);
    assert_eq!(net.push(B, &table_b(1), false), ota::Progress::Done);
    net.nodes[1].1.pins.clear();
    let start = Message::Command {
        id: 1024,
        command: Command::Start,
    };
    net.tool_send(A, &start);
    net.run(200);
    assert_eq!(net.nodes[1].1.pins, vec![(LAMP_PIN, true)]);
    // 2^32 ms + 10 s later (the nodes idle meanwhile; the time skipped, not stepped).
    net.now += 1 << 32;
    net.run(10_000);
    net.tool_send(A, &start);
    net.run(2_000);
    assert_eq!(
        net.nodes[1].1.pins,
        vec![(LAMP_PIN, true), (LAMP_PIN, false)],
        "a START 49.7 days later ran"
    );
}
