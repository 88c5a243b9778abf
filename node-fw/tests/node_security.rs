//! A node with a management key: the tool's frames on the config PAN are taken only
//! secured at ENC-MIC-64 with that key and with a fresh frame counter; everything the node
//! sends there is secured; each refused frame is counted by its reason.

use config_schema::wire::mac::{self, Frame, Header, BROADCAST, MAX_PAYLOAD, MAX_PSDU};
use config_schema::wire::msg::{Command, Message, SecurityCounters};
use config_schema::wire::security::{self, ext_addr, AuxRepr, KeyId, SecurityLevel};
use node_fw::node::{Io, NodeCore, CONFIG_PAN};
use node_fw::provision::ManagementKey;
use test_tables::{lamp_table, BUTTON, LAMP, PAN};

const TOOL: u16 = 0x0100;
const NODE: u16 = 0x0011;
const KEY: [u8; 16] = [0x5A; 16];
const WRONG: [u8; 16] = [0xA5; 16];

/// The board: what the node sent, the pins it set, and its frame counter.
struct Board {
    out: Vec<Vec<u8>>,
    pins: Vec<(u8, bool)>,
    counter: Option<u32>,
}

impl Io for Board {
    fn transmit(&mut self, psdu: &[u8]) {
        self.out.push(psdu.to_vec());
    }
    fn set_pin(&mut self, pin: u8, level: bool) {
        self.pins.push((pin, level));
    }
    fn next_frame_counter(&mut self) -> Option<u32> {
        let c = self.counter?;
        self.counter = c.checked_add(1);
        Some(c)
    }
}

/// The lamp table with START toggling the lamp: every START that runs drives it; the
/// tool's counter established (its floor 0: the handshake spent the node's counter 0).
fn node() -> (NodeCore, Board) {
    let (mut n, mut b) = booted();
    handshake(&mut n, &mut b, TOOL, 0, 0);
    (n, b)
}

/// A secured frame from `src` with `counter`.
fn from(src: u16, counter: u32, payload: &[u8]) -> Vec<u8> {
    let mut psdu = [0u8; MAX_PSDU];
    let n = security::secure(
        &header(CONFIG_PAN, NODE, src),
        &AuxRepr::new(0, counter),
        &KEY,
        ext_addr(CONFIG_PAN, src),
        payload,
        &mut psdu,
    )
    .unwrap();
    psdu[..n].to_vec()
}

fn message(msg: &Message<'_>) -> Vec<u8> {
    let mut payload = [0u8; MAX_PAYLOAD];
    let n = msg.emit(&mut payload).unwrap();
    payload[..n].to_vec()
}

/// `src`'s first frame (at `counter`) is challenged; the answer (at `counter`) sets its
/// floor. Leaves nothing in `b.out`.
fn handshake(n: &mut NodeCore, b: &mut Board, src: u16, counter: u32, now: u64) {
    let sent = b.out.len();
    n.receive(
        &from(src, counter, &command(0xFFF0, Command::Status)),
        now,
        b,
    );
    assert_eq!(b.out.len(), sent + 1, "challenged");
    let (_, payload) = open(&b.out[sent]).expect("a secured challenge");
    let Ok(Message::Challenge { nonce }) = Message::parse(&payload) else {
        panic!("not a challenge: {payload:?}");
    };
    n.receive(
        &from(src, counter, &message(&Message::ChallengeAnswer { nonce })),
        now,
        b,
    );
    b.out.truncate(sent);
}

/// Just booted: the node knows no sender's counter.
fn booted() -> (NodeCore, Board) {
    let mut t = lamp_table(1);
    t.start = t
        .inputs
        .iter()
        .find(|i| i.pin == BUTTON)
        .and_then(|i| i.rise);
    let node = NodeCore::new(NODE, u64::MAX, Some(t), 1)
        .with_management_key(ManagementKey::from_bytes(KEY));
    let board = Board {
        out: Vec::new(),
        pins: Vec::new(),
        counter: Some(0),
    };
    (node, board)
}

fn header(pan_id: u16, dst: u16, src: u16) -> Header {
    Header {
        seq: 0,
        pan_id,
        dst,
        src,
        ack_request: false,
        secured: false,
    }
}

fn command(id: u16, command: Command) -> Vec<u8> {
    let mut payload = [0u8; MAX_PAYLOAD];
    let n = Message::Command { id, command }.emit(&mut payload).unwrap();
    payload[..n].to_vec()
}

fn plain(pan: u16, dst: u16, payload: &[u8]) -> Vec<u8> {
    let mut psdu = [0u8; MAX_PSDU];
    let n = mac::emit_data(&header(pan, dst, TOOL), payload, &mut psdu).unwrap();
    psdu[..n].to_vec()
}

fn secured_with(aux: AuxRepr, key: &[u8; 16], payload: &[u8]) -> Vec<u8> {
    let mut psdu = [0u8; MAX_PSDU];
    let n = security::secure(
        &header(CONFIG_PAN, NODE, TOOL),
        &aux,
        key,
        ext_addr(CONFIG_PAN, TOOL),
        payload,
        &mut psdu,
    )
    .unwrap();
    psdu[..n].to_vec()
}

/// What the tool sends: ENC-MIC-64, key index 0, its counter.
fn secured(counter: u32, key: &[u8; 16], payload: &[u8]) -> Vec<u8> {
    secured_with(AuxRepr::new(0, counter), key, payload)
}

/// Times the lamp was switched on: STARTs that ran.
fn starts(board: &Board) -> usize {
    board.pins.iter().filter(|p| **p == (LAMP, true)).count()
}

/// Opens a frame the node sent, as the tool does; `None` if it is not secured with `KEY`.
fn open(psdu: &[u8]) -> Option<(u32, Vec<u8>)> {
    let mut scratch = [0u8; MAX_PAYLOAD];
    let o = security::open_at(
        psdu,
        SecurityLevel::EncMic64,
        |h, _| Some((KEY, ext_addr(h.pan_id, h.src))),
        &mut scratch,
    )
    .ok()?;
    Some((o.aux.frame_counter, o.payload.to_vec()))
}

#[test]
fn a_secured_start_runs_and_the_answer_is_secured() {
    let (mut n, mut b) = node();
    n.receive(&secured(7, &KEY, &command(1, Command::Start)), 0, &mut b);
    assert_eq!(starts(&b), 1);
    assert_eq!(b.out.len(), 1);
    let (counter, payload) = open(&b.out[0]).expect("the status is secured with the key");
    assert_eq!(counter, 1, "after the handshake's challenge");
    assert!(matches!(Message::parse(&payload), Ok(Message::Status(s)) if s.ack == 1));
    // Nothing of the payload is in clear on the air.
    assert!(matches!(Frame::parse(&b.out[0]), Ok(Frame::Data { header, .. }) if header.secured));
    let handshake = SecurityCounters {
        challenged: 1,
        ..SecurityCounters::default()
    };
    assert_eq!(n.security_counters(), handshake);
}

#[test]
fn forged_damaged_and_replayed_starts_start_nothing_and_are_counted_by_reason() {
    let (mut n, mut b) = node();
    // An attacker without the key: unsecured, then secured with another key.
    n.receive(
        &plain(CONFIG_PAN, NODE, &command(1, Command::Start)),
        0,
        &mut b,
    );
    n.receive(&secured(1, &WRONG, &command(2, Command::Start)), 0, &mut b);
    // A real START, captured; one bit flipped in each byte after the MAC header.
    let real = secured(10, &KEY, &command(3, Command::Start));
    for i in 9..real.len() - 2 {
        let mut bad = real.clone();
        bad[i] ^= 0x10;
        // The FCS is recomputed: only the MIC can tell.
        let len = bad.len();
        let fcs = mac::FCS.checksum(&bad[..len - 2]);
        bad[len - 2..].copy_from_slice(&fcs.to_le_bytes());
        n.receive(&bad, 0, &mut b);
    }
    assert_eq!(starts(&b), 0, "nothing started");
    assert!(b.out.is_empty(), "nothing answered");
    let flips = (real.len() - 2 - 9) as u32;
    let c = n.security_counters();
    assert_eq!(c.not_secured, 1);
    // A flipped security control byte makes another level or key id mode; a flipped key
    // index another key; every other flip fails the MIC.
    assert_eq!(
        c.bad_mic + c.wrong_level + c.unknown_key + c.malformed,
        1 + flips
    );
    assert!(c.bad_mic >= 1 + flips - 2, "{c:?}");
    // The real one runs once; its replay, after another command moved the node's
    // memory of commands on, does not.
    n.receive(&real, 0, &mut b);
    n.receive(&secured(11, &KEY, &command(4, Command::Status)), 0, &mut b);
    n.receive(&real, 0, &mut b);
    assert_eq!(starts(&b), 1);
    assert_eq!(n.security_counters().replayed, 1);
    assert_eq!(b.out.len(), 2, "two statuses: for the START and the STATUS");
}

#[test]
fn other_levels_key_indexes_and_the_nodes_own_frames_are_refused() {
    let (mut n, mut b) = node();
    let start = command(1, Command::Start);
    let mic32 = AuxRepr {
        level: SecurityLevel::EncMic32,
        key_id: KeyId::Index(0),
        frame_counter: 1,
    };
    n.receive(&secured_with(mic32, &KEY, &start), 0, &mut b);
    n.receive(&secured_with(AuxRepr::new(1, 2), &KEY, &start), 0, &mut b);
    // The node's own announcement, reflected back to it.
    let mut psdu = [0u8; MAX_PSDU];
    let len = security::secure(
        &header(CONFIG_PAN, NODE, NODE),
        &AuxRepr::new(0, 3),
        &KEY,
        ext_addr(CONFIG_PAN, NODE),
        &start,
        &mut psdu,
    )
    .unwrap();
    n.receive(&psdu[..len], 0, &mut b);
    // An unsecured command on the robot's PAN is no way around it.
    n.receive(&plain(PAN, NODE, &command(2, Command::Start)), 0, &mut b);
    assert_eq!(starts(&b), 0);
    let c = n.security_counters();
    assert_eq!((c.wrong_level, c.unknown_key, c.not_secured), (1, 2, 1));
}

#[test]
fn without_a_frame_counter_nothing_is_sent_and_it_is_counted() {
    let (mut n, mut b) = node();
    b.counter = None;
    n.receive(&secured(1, &KEY, &command(1, Command::Status)), 0, &mut b);
    assert!(b.out.is_empty());
    assert_eq!(n.security_counters().no_counter, 1);
}

#[test]
fn the_security_command_reports_the_counters_and_counters_increase() {
    let (mut n, mut b) = node();
    n.receive(
        &plain(CONFIG_PAN, NODE, &command(1, Command::Start)),
        0,
        &mut b,
    );
    n.receive(&secured(5, &KEY, &command(2, Command::Security)), 0, &mut b);
    n.receive(&secured(6, &KEY, &command(3, Command::Security)), 0, &mut b);
    let answers: Vec<_> = b.out.iter().map(|p| open(p).expect("secured")).collect();
    assert_eq!(answers.iter().map(|a| a.0).collect::<Vec<_>>(), [1, 2]);
    match Message::parse(&answers[1].1) {
        Ok(Message::Security(r)) => {
            let c = r.counters;
            assert_eq!(
                (r.ack, r.keyed, c.not_secured, c.challenged),
                (3, true, 1, 1)
            );
        }
        other => panic!("not a security report: {other:?}"),
    }
}

#[test]
fn an_unsecured_scan_is_answered_secured_at_most_once_a_second() {
    let (mut n, mut b) = node();
    let nonce = 0xFEDC_BA98_7654_3210;
    let identify = plain(
        CONFIG_PAN,
        BROADCAST,
        &command(9, Command::Identify { nonce }),
    );
    n.receive(&identify, 0, &mut b);
    n.receive(&identify, 10, &mut b);
    n.receive(&identify, 999, &mut b);
    n.receive(&identify, 1000, &mut b);
    assert_eq!(b.out.len(), 2);
    for psdu in &b.out {
        let (_, payload) = open(psdu).expect("the announcement is secured");
        // It carries the ask's nonce back: the scan takes it, and no recorded answer.
        assert!(matches!(Message::parse(&payload), Ok(Message::Announce(a)) if a.nonce == nonce));
    }
    // A scan asking again within the second is not a security refusal.
    assert_eq!(n.security_counters().not_secured, 0);
    assert_eq!(n.counters().dropped, 2);
    // An unsecured Identify to the node itself is not a scan.
    n.receive(
        &plain(
            CONFIG_PAN,
            NODE,
            &command(10, Command::Identify { nonce: 10 }),
        ),
        5000,
        &mut b,
    );
    assert_eq!(b.out.len(), 2);
    assert_eq!(n.security_counters().not_secured, 1);
}

#[test]
fn other_nodes_secured_announcements_are_ignored_not_counted() {
    let (mut n, mut b) = node();
    let mut announce = [0u8; MAX_PAYLOAD];
    let len = Message::Announce(config_schema::wire::msg::Announce {
        firmware: 1,
        generation: 0,
        role: heapless::String::new(),
        table: config_schema::TableId::NONE,
        staged: 0,
        nonce: 0,
    })
    .emit(&mut announce)
    .unwrap();
    let mut psdu = [0u8; MAX_PSDU];
    let other = 0x0012;
    let n_psdu = security::secure(
        &header(CONFIG_PAN, BROADCAST, other),
        &AuxRepr::new(0, 1),
        &WRONG,
        ext_addr(CONFIG_PAN, other),
        &announce[..len],
        &mut psdu,
    )
    .unwrap();
    let dropped = n.counters().dropped;
    n.receive(&psdu[..n_psdu], 0, &mut b);
    assert_eq!(n.counters().dropped, dropped);
    let handshake = SecurityCounters {
        challenged: 1,
        ..SecurityCounters::default()
    };
    assert_eq!(n.security_counters(), handshake);
    assert!(b.out.is_empty());
}

#[test]
fn an_unkeyed_node_is_unchanged() {
    let mut t = lamp_table(1);
    t.start = t.inputs.first().and_then(|i| i.rise);
    let mut n = NodeCore::new(NODE, u64::MAX, Some(t), 1);
    let mut b = Board {
        out: Vec::new(),
        pins: Vec::new(),
        counter: None,
    };
    n.receive(
        &plain(CONFIG_PAN, NODE, &command(1, Command::Start)),
        0,
        &mut b,
    );
    assert_eq!(starts(&b), 1);
    assert!(matches!(Frame::parse(&b.out[0]), Ok(Frame::Data { header, .. }) if !header.secured));
    assert!(!n.keyed());
}

#[test]
fn a_management_sender_past_the_table_is_refused_not_one_forgotten() {
    let (mut n, mut b) = node();
    // The tool and as many others as the table holds but one.
    let others = node_fw::node::MANAGEMENT_SENDERS as u16 - 1;
    for (i, src) in (0x0101..0x0101 + others).enumerate() {
        handshake(&mut n, &mut b, src, 1, 100 * (i as u64 + 1));
    }
    let now = 100 * (u64::from(others) + 1);
    // One more is challenged, but its answer finds the table full.
    let src = 0x0101 + others;
    n.receive(&from(src, 1, &command(1, Command::Status)), now, &mut b);
    let (_, payload) = open(&b.out[0]).unwrap();
    let Ok(Message::Challenge { nonce }) = Message::parse(&payload) else {
        panic!("not a challenge");
    };
    n.receive(
        &from(src, 2, &message(&Message::ChallengeAnswer { nonce })),
        now,
        &mut b,
    );
    assert_eq!(n.security_counters().table_full, 1);
    // And the tool was not forgotten.
    n.receive(
        &secured(1, &KEY, &command(2, Command::Status)),
        now + 100,
        &mut b,
    );
    assert_eq!(b.out.len(), 2);
    assert!(matches!(
        Message::parse(&open(&b.out[1]).unwrap().1),
        Ok(Message::Status(_))
    ));
}

/// After a reboot the node knows no counter: a START captured before is not run but
/// challenged; the real tool's answer sets the floor above every captured frame, so the
/// replay stays refused, and the tool's next START runs.
#[test]
fn after_a_reboot_a_replayed_start_is_challenged_and_never_runs() {
    let (mut n, mut b) = node();
    let captured = secured(5, &KEY, &command(1, Command::Start));
    n.receive(&captured, 0, &mut b);
    assert_eq!(starts(&b), 1);
    // Reboot: a fresh core (its frame counter goes on: the board's persists).
    let counter = b.counter;
    let (mut n, mut b) = booted();
    b.counter = counter;
    n.receive(&captured, 0, &mut b);
    assert_eq!(starts(&b), 0);
    assert_eq!(n.security_counters().challenged, 1);
    let (_, payload) = open(&b.out[0]).unwrap();
    let Ok(Message::Challenge { nonce }) = Message::parse(&payload) else {
        panic!("not a challenge");
    };
    // A wrong nonce (an old answer replayed) is no answer: challenged again (rate-limited).
    let old = secured(
        6,
        &KEY,
        &message(&Message::ChallengeAnswer { nonce: nonce - 1 }),
    );
    n.receive(&old, 10, &mut b);
    assert_eq!(n.security_counters().challenged, 2);
    // The tool answers with its current counter; the replay is then below the floor.
    n.receive(
        &secured(7, &KEY, &message(&Message::ChallengeAnswer { nonce })),
        20,
        &mut b,
    );
    n.receive(&captured, 30, &mut b);
    assert_eq!((starts(&b), n.security_counters().replayed), (0, 1));
    n.receive(&secured(8, &KEY, &command(2, Command::Start)), 40, &mut b);
    assert_eq!(starts(&b), 1);
}

/// An answer held back from the node (captured, its copy to the node jammed) and sent
/// long after the challenge sets no floor: else the START the node refused while it had
/// none (the operator's, who gave up) could be replayed after it and run, minutes later.
#[test]
fn an_answer_held_back_and_sent_long_after_its_challenge_sets_no_floor() {
    let (mut n, mut b) = booted();
    let start = secured(5, &KEY, &command(1, Command::Start));
    n.receive(&start, 0, &mut b);
    let (_, payload) = open(&b.out[0]).unwrap();
    let Ok(Message::Challenge { nonce }) = Message::parse(&payload) else {
        panic!("not a challenge");
    };
    let answer = secured(4, &KEY, &message(&Message::ChallengeAnswer { nonce }));
    let later = 60_000;
    n.receive(&answer, later, &mut b);
    n.receive(&start, later + 1, &mut b);
    assert_eq!(starts(&b), 0);
    // (The answer and the START challenged, as frames of a sender without a floor.)
    assert_eq!(n.security_counters().challenged, 3);
    // Within its time, the same answer sets the floor (below the START: it runs).
    let (mut n, mut b) = booted();
    n.receive(&start, 0, &mut b);
    n.receive(&answer, node_fw::peer_security::ANSWER_WITHIN_MS, &mut b);
    n.receive(&start, node_fw::peer_security::ANSWER_WITHIN_MS + 1, &mut b);
    assert_eq!(starts(&b), 1);
}

proptest::proptest! {
    /// Random bytes, and a real secured START with any bytes flipped, cut or added (its
    /// FCS made good again or not): the node never starts and never answers.
    #[test]
    fn mutated_secured_starts_never_run(
        flips in proptest::collection::vec((0usize..64, 1u8..=255), 1..4),
        cut in proptest::option::of(0usize..64),
        extra in proptest::collection::vec(proptest::num::u8::ANY, 0..3),
        noise in proptest::collection::vec(proptest::num::u8::ANY, 0..127),
        fix_fcs in proptest::bool::ANY,
    ) {
        let (mut n, mut b) = node();
        let real = secured(3, &KEY, &command(1, Command::Start));
        let mut bad = real.clone();
        for (at, x) in &flips {
            let i = at % bad.len();
            bad[i] ^= x;
        }
        if let Some(c) = cut {
            bad.truncate(c % bad.len());
        }
        bad.extend_from_slice(&extra);
        if fix_fcs && bad.len() >= 2 {
            // Only the MIC can tell then.
            let body = bad.len() - 2;
            let fcs = mac::FCS.checksum(&bad[..body]).to_le_bytes();
            bad[body..].copy_from_slice(&fcs);
        }
        if bad != real {
            n.receive(&bad, 0, &mut b);
        }
        n.receive(&noise, 0, &mut b);
        proptest::prop_assert_eq!(starts(&b), 0);
        proptest::prop_assert!(b.out.is_empty());
    }
}
