//! A node's alarms through its commands: a declared fault alarm latches, START (the
//! command and the START button) is refused while it is latched, `Ack` is refused while
//! its cause persists and accepted after; then START runs.

use config_schema::alarm::{AlarmDecl, AlarmLevel, AlarmReport, AlarmSource};
use config_schema::wire::mac::{self, Frame, Header, MAX_PSDU};
use config_schema::wire::msg::{Command, Message};
use config_schema::{Input, Op};
use node_fw::node::{Io, NodeCore, CONFIG_PAN};
use test_tables::{lamp_table, load, BUTTON, LAMP};

const NODE: u16 = 0x0001;
const TOOL: u16 = 0x0100;
/// The cause of the declared alarm (a pressure switch, say).
const CAUSE: u8 = 3;

#[derive(Default)]
struct Board {
    sent: Vec<Vec<u8>>,
    lamp: bool,
}

impl Io for Board {
    fn transmit(&mut self, psdu: &[u8]) {
        self.sent.push(psdu.to_vec());
    }
    fn set_pin(&mut self, pin: u8, level: bool) {
        if pin == LAMP {
            self.lamp = level;
        }
    }
}

/// The lamp role whose button is its START, with a fault alarm while input CAUSE is high.
fn node() -> NodeCore {
    let mut t = lamp_table(1);
    t.start = t.inputs[0].rise;
    t.inputs
        .push(Input {
            pin: CAUSE,
            rise: None,
            fall: None,
            var: None,
        })
        .unwrap();
    let when = t.push_expr(&[Op::Input(1)]).unwrap();
    let level = AlarmLevel::Fault;
    t.safety.alarms.push(AlarmDecl { level, when }).unwrap();
    NodeCore::new(NODE, u64::MAX, Some(load(t)), 1)
}

/// Sends command `command` (id `id`) at `now`; the node's answer.
fn command(
    node: &mut NodeCore,
    board: &mut Board,
    id: u16,
    command: Command,
    now: u64,
) -> Message<'static> {
    let header = Header {
        seq: id as u8,
        pan_id: CONFIG_PAN,
        dst: NODE,
        src: TOOL,
        ack_request: false,
        secured: false,
    };
    let mut payload = [0u8; 64];
    let n = Message::Command { id, command }.emit(&mut payload).unwrap();
    let mut psdu = [0u8; MAX_PSDU];
    let len = mac::emit_data(&header, &payload[..n], &mut psdu).unwrap();
    board.sent.clear();
    node.receive(&psdu[..len], now, board);
    let reply = board.sent.pop().expect("an answer");
    let Ok(Frame::Data { payload, .. }) = Frame::parse(&reply) else {
        panic!("not a data frame");
    };
    match Message::parse(payload).unwrap() {
        Message::Alarms(r) => Message::Alarms(r),
        Message::Status(s) => Message::Status(s),
        other => panic!("unexpected {other:?}"),
    }
}

fn alarms(node: &mut NodeCore, board: &mut Board, id: u16, cmd: Command, now: u64) -> AlarmReport {
    match command(node, board, id, cmd, now) {
        Message::Alarms(r) => r,
        other => panic!("not alarms: {other:?}"),
    }
}

/// (raised, acked, persists) of the declared alarm, the only one.
fn latched(r: &AlarmReport) -> Vec<(u32, bool, bool)> {
    r.alarms
        .iter()
        .map(|a| {
            assert_eq!(a.source, AlarmSource::Declared { index: 0 });
            assert_eq!(a.level, AlarmLevel::Fault);
            (a.raised_ms, a.acked, a.persists)
        })
        .collect()
}

#[test]
fn start_is_refused_until_the_fault_alarm_is_acknowledged_and_ack_while_its_cause_persists() {
    let (mut node, mut board) = (node(), Board::default());
    node.poll(0, &mut board);
    let none = alarms(&mut node, &mut board, 1, Command::Alarms, 10);
    assert_eq!((none.now_ms, none.alarms.len(), none.dropped), (10, 0, 0));

    node.input(CAUSE, true, 100, &mut board);
    let r = alarms(&mut node, &mut board, 2, Command::Alarms, 150);
    assert_eq!((r.ack, r.now_ms), (2, 150));
    assert_eq!(latched(&r), [(100, false, true)]);

    // START, by command and by the button: refused, nothing moves.
    let Message::Status(s) = command(&mut node, &mut board, 3, Command::Start, 200) else {
        panic!("START answers with the status");
    };
    assert_eq!((s.ack, s.fault), (3, None));
    node.input(BUTTON, true, 210, &mut board);
    node.input(BUTTON, false, 220, &mut board);
    assert!(!board.lamp, "START was refused");

    // Ack while the cause persists: refused.
    let r = alarms(&mut node, &mut board, 4, Command::Ack, 300);
    assert_eq!(latched(&r), [(100, false, true)]);
    // The cause is gone: still latched, START still refused.
    node.input(CAUSE, false, 400, &mut board);
    command(&mut node, &mut board, 5, Command::Start, 410);
    assert!(!board.lamp, "START was refused");
    let r = alarms(&mut node, &mut board, 6, Command::Alarms, 420);
    assert_eq!(latched(&r), [(100, false, false)]);
    // Acknowledged: START runs.
    let r = alarms(&mut node, &mut board, 7, Command::Ack, 500);
    assert_eq!(latched(&r), [(100, true, false)]);
    command(&mut node, &mut board, 8, Command::Start, 510);
    assert!(board.lamp, "START ran");
    node.input(BUTTON, true, 520, &mut board);
    assert!(!board.lamp, "the button toggles the lamp again");
}

/// The cause comes back after its first alarm was acknowledged: a second alarm latches,
/// and only it persists. The first, whose cause ended before it was acknowledged, said
/// `[acknowledged, cause persists]` again (its source's cause was asked, not its own).
#[test]
fn an_acknowledged_alarm_whose_cause_ended_does_not_persist_when_the_cause_comes_back() {
    let (mut node, mut board) = (node(), Board::default());
    node.poll(0, &mut board);
    node.input(CAUSE, true, 100, &mut board);
    node.input(CAUSE, false, 200, &mut board);
    let r = alarms(&mut node, &mut board, 1, Command::Ack, 300);
    assert_eq!(latched(&r), [(100, true, false)]);
    node.input(CAUSE, true, 400, &mut board);
    let r = alarms(&mut node, &mut board, 2, Command::Alarms, 500);
    assert_eq!(latched(&r), [(100, true, false), (400, false, true)]);
}

/// `on_link_alarm: Fault`: a peer that never acknowledges faults the publisher once its
/// link goes into alarm (code 0x85), with a fault alarm naming the link; without it the
/// node only stalls, with a warning.
#[test]
fn a_link_alarm_faults_the_node_only_under_link_fault() {
    use config_schema::Publication;
    for link_fault in [false, true] {
        let mut t = lamp_table(1);
        t.peers.push(0x0002).unwrap();
        let press = t.inputs[0].rise.unwrap();
        t.publications
            .push(Publication {
                event: press,
                topic: 0,
                subscribers: 1,
            })
            .unwrap();
        t.safety.link_fault = link_fault;
        let mut node = NodeCore::new(NODE, u64::MAX, Some(load(t)), 1);
        let mut board = Board::default();
        node.input(BUTTON, true, 0, &mut board);
        let mut now = 0;
        while node.link_alarms() == 0 && now < 5_000 {
            now = node.deadline().max(now + 1);
            node.poll(now, &mut board);
        }
        assert_eq!(node.link_alarms(), 1, "the silent peer's link is in alarm");
        let fault = node.status(0, Default::default()).fault;
        let r = node.alarm_report(9, now);
        let got: Vec<_> = r.alarms.iter().map(|a| (a.source, a.level)).collect();
        let link = AlarmSource::Link { peer: 0 };
        if link_fault {
            assert_eq!(fault, Some(0x85));
            let chart = AlarmSource::Chart {
                chart: config_schema::alarm::NO_CHART,
                code: 0x85,
            };
            assert_eq!(got, [(chart, AlarmLevel::Fault), (link, AlarmLevel::Fault)]);
        } else {
            assert_eq!(fault, None);
            assert_eq!(got, [(link, AlarmLevel::Warning)]);
        }
    }
}

/// A press refused while a fault alarm is latched still changes what the node senses
/// (the engine senses the level, and returns before the alarms look): a declared warning on
/// the button is raised at the next look, the poll at 250, and not missed by the looks
/// after it (the alarms look at the state only when the core says it changed).
#[test]
fn a_refused_press_raises_the_warning_it_causes_at_the_next_look() {
    let mut node = {
        let mut t = lamp_table(1);
        t.start = t.inputs[0].rise;
        let cause = Input {
            pin: CAUSE,
            rise: None,
            fall: None,
            var: None,
        };
        t.inputs.push(cause).unwrap();
        for (input, level) in [(1, AlarmLevel::Fault), (0, AlarmLevel::Warning)] {
            let when = t.push_expr(&[Op::Input(input)]).unwrap();
            t.safety.alarms.push(AlarmDecl { level, when }).unwrap();
        }
        NodeCore::new(NODE, u64::MAX, Some(load(t)), 1)
    };
    let mut board = Board::default();
    node.poll(0, &mut board);
    node.input(CAUSE, true, 100, &mut board);
    node.input(BUTTON, true, 210, &mut board);
    assert!(!board.lamp, "START was refused");
    node.poll(250, &mut board);
    // Frames and polls that change nothing raise nothing.
    node.poll(260, &mut board);
    let r = alarms(&mut node, &mut board, 1, Command::Alarms, 300);
    let got: Vec<_> = r
        .alarms
        .iter()
        .map(|a| (a.source, a.level, a.raised_ms))
        .collect();
    assert_eq!(
        got,
        [
            (AlarmSource::Declared { index: 0 }, AlarmLevel::Fault, 100),
            (AlarmSource::Declared { index: 1 }, AlarmLevel::Warning, 250),
        ]
    );
}
