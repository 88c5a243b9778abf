//! Events between nodes whose tables came with link keys: secured at ENC-MIC-64 under the
//! sender's key for that peer; a receiver takes only those, fresh, and challenges a peer it
//! knows no counter of (after its boot). Forged, damaged, replayed, unsecured frames and
//! frames under another generation's or another node's key move nothing and are counted.

use config_schema::wire::mac::{self, Frame, Header, MAX_PAYLOAD, MAX_PSDU};
use config_schema::wire::msg::{Message, SecurityCounters};
use config_schema::wire::security::{self, ext_addr, link_key_index, AuxRepr};
use config_schema::{Action, Output, Publication, Subscription, Table};
use node_fw::node::{Io, NodeCore, CONFIG_PAN};
use test_tables::{button, link_keys, pair_key, toggle};

const A: u16 = 0x0001;
const B: u16 = 0x0002;
const C: u16 = 0x0003;
const PAN: u16 = 0x4242;
const BUTTON_PIN: u8 = 5;
const LAMP_PIN: u8 = 7;
const GENERATION: u32 = 1;

/// A: a button whose press is published to B.
fn table_a() -> Table {
    let mut t = Table::empty("A");
    t.generation = GENERATION;
    t.header.pan_id = PAN;
    let press = button(&mut t, BUTTON_PIN);
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

/// B: a lamp toggled by every press published by A (or by C, its other peer).
fn table_b() -> Table {
    let mut t = Table::empty("B");
    t.generation = GENERATION;
    t.header.pan_id = PAN;
    let press = t.push_event().unwrap();
    t.outputs.push(Output::safe(LAMP_PIN, false)).unwrap();
    t.peers.push(A).unwrap();
    t.peers.push(C).unwrap();
    for publisher in 0..2 {
        t.subscriptions
            .push(Subscription {
                publisher,
                topic: 3,
                event: press,
            })
            .unwrap();
    }
    toggle(&mut t, press, &[Action::Drive { mask: 1, value: 1 }]);
    t
}

/// A node's outside: what it sent, its lamp, its frame counter (persisted ahead: a reboot
/// keeps counting from where it was).
#[derive(Default)]
struct Board {
    out: Vec<Vec<u8>>,
    lamp: Vec<bool>,
    counter: u32,
}

impl Io for Board {
    fn transmit(&mut self, psdu: &[u8]) {
        self.out.push(psdu.to_vec());
    }
    fn set_pin(&mut self, pin: u8, level: bool) {
        if pin == LAMP_PIN {
            self.lamp.push(level);
        }
    }
    fn next_frame_counter(&mut self) -> Option<u32> {
        self.counter += 1;
        Some(self.counter)
    }
}

fn node_a() -> NodeCore {
    NodeCore::new(A, u64::MAX, Some(table_a()), 1).with_link_keys(link_keys(A, &[B], GENERATION))
}

fn node_b() -> NodeCore {
    NodeCore::new(B, u64::MAX, Some(table_b()), 1).with_link_keys(link_keys(B, &[A, C], GENERATION))
}

/// A and B on a perfect radio; every frame on the air is recorded.
struct Net {
    a: (NodeCore, Board),
    b: (NodeCore, Board),
    now: u64,
    /// (src, dst, message kind) of every frame, opened with the pair's key.
    trace: Vec<(u16, u16, &'static str)>,
    air: Vec<Vec<u8>>,
}

fn kind(m: &Message) -> &'static str {
    match m {
        Message::Event { .. } => "Event",
        Message::EventAck { .. } => "EventAck",
        Message::Challenge { .. } => "Challenge",
        Message::ChallengeAnswer { .. } => "ChallengeAnswer",
        _ => "other",
    }
}

/// Opens a frame on the robot's PAN with the pair's key (as the receiver would).
fn open(psdu: &[u8]) -> (Header, AuxRepr, Vec<u8>) {
    let mut scratch = [0u8; MAX_PAYLOAD];
    let o = security::open(
        psdu,
        |h, _| Some((pair_key(h.src, h.dst), ext_addr(h.pan_id, h.src))),
        &mut scratch,
    )
    .expect("every frame between the nodes is secured under the pair's key");
    (o.header, o.aux, o.payload.to_vec())
}

impl Net {
    fn new() -> Net {
        Net {
            a: (node_a(), Board::default()),
            b: (node_b(), Board::default()),
            now: 0,
            trace: Vec::new(),
            air: Vec::new(),
        }
    }

    /// Delivers every frame sent until none is left, advancing 1 ms per round and
    /// polling the nodes (retransmissions), for `ms` milliseconds.
    fn run(&mut self, ms: u64) {
        self.run_each(ms, |net, f| net.deliver(&f));
    }

    /// [`Net::run`], each frame sent handed to `each` (which delivers it, holds it or
    /// drops it) instead of delivered.
    fn run_each(&mut self, ms: u64, mut each: impl FnMut(&mut Net, Vec<u8>)) {
        let end = self.now + ms;
        while self.now < end {
            self.now += 1;
            self.a.0.poll(self.now, &mut self.a.1);
            self.b.0.poll(self.now, &mut self.b.1);
            let mut frames = std::mem::take(&mut self.a.1.out);
            frames.append(&mut self.b.1.out);
            for f in frames {
                each(self, f);
            }
        }
    }

    fn deliver(&mut self, psdu: &[u8]) {
        let (h, aux, payload) = open(psdu);
        assert_eq!(
            (aux.key_id.index(), h.pan_id),
            (Some(link_key_index(GENERATION)), PAN)
        );
        let m = Message::parse(&payload).unwrap();
        self.trace.push((h.src, h.dst, kind(&m)));
        self.air.push(psdu.to_vec());
        match h.dst {
            A => self.a.0.receive(psdu, self.now, &mut self.a.1),
            B => self.b.0.receive(psdu, self.now, &mut self.b.1),
            _ => {}
        }
    }

    fn press(&mut self) {
        self.a.0.input(BUTTON_PIN, true, self.now, &mut self.a.1);
        self.a.0.input(BUTTON_PIN, false, self.now, &mut self.a.1);
    }

    /// A's first press, through both handshakes: the lamp is on, and both know the
    /// other's counter.
    fn established() -> Net {
        let mut net = Net::new();
        net.press();
        net.run(400);
        assert_eq!(net.b.1.lamp, [true]);
        net.trace.clear();
        net.air.clear();
        net
    }

    /// [`Net::established`], then B reboots and A's button is pressed: A has an event
    /// for B, whose fresh side of the link knows no counter of A.
    fn b_rebooted_and_pressed() -> Net {
        let mut net = Net::established();
        net.b.0 = node_b();
        net.b.1.lamp.clear();
        net.press();
        net
    }

    /// The lamp toggled once for the press of [`Net::b_rebooted_and_pressed`], and once
    /// more for the next.
    fn delivered_once(&mut self) {
        assert_eq!(self.b.1.lamp, [true], "delivered once: {:?}", self.trace);
        self.press();
        self.run(400);
        assert_eq!(self.b.1.lamp, [true, false]);
    }

    /// Injects a frame at B (an attacker on the air).
    fn inject(&mut self, psdu: &[u8]) {
        self.b.0.receive(psdu, self.now, &mut self.b.1);
        self.run(200);
    }
}

/// A frame from `src` to B secured with `key` under `key_index` at `counter`.
fn forged(src: u16, key: [u8; 16], key_index: u8, counter: u32, msg: &Message) -> Vec<u8> {
    let mut payload = [0u8; MAX_PAYLOAD];
    let n = msg.emit(&mut payload).unwrap();
    let header = Header {
        seq: 0,
        pan_id: PAN,
        dst: B,
        src,
        ack_request: false,
        secured: false,
    };
    let mut psdu = [0u8; MAX_PSDU];
    let len = security::secure(
        &header,
        &AuxRepr::new(key_index, counter),
        &key,
        ext_addr(PAN, src),
        &payload[..n],
        &mut psdu,
    )
    .unwrap();
    psdu[..len].to_vec()
}

fn event(seq: u16) -> Message<'static> {
    Message::Event {
        epoch: 2,
        seq,
        topic: 3,
    }
}

#[test]
fn nodes_with_keys_greet_their_peers_at_once_and_a_press_is_then_one_event_and_its_ack() {
    let mut net = Net::new();
    net.run(10);
    // Each node challenges every peer it knows no counter of (B's other peer, C, is not
    // on the air); each answers.
    assert_eq!(
        net.trace,
        [
            (A, B, "Challenge"),
            (B, A, "Challenge"),
            (B, C, "Challenge"),
            (A, B, "ChallengeAnswer"),
            (B, A, "ChallengeAnswer"),
        ]
    );
    net.trace.clear();
    net.press();
    net.run(1_000);
    // (B greets the absent C again every 100 ms, 5 times in all, then stops.)
    assert_eq!(
        net.trace.iter().filter(|t| t.1 == C).count(),
        4,
        "{:?}",
        net.trace
    );
    net.trace.retain(|t| t.1 != C);
    assert_eq!(net.trace, [(A, B, "Event"), (B, A, "EventAck")]);
    assert_eq!(net.b.1.lamp, [true], "delivered exactly once");
    let challenged = |n: &NodeCore| n.security_counters().challenged;
    assert_eq!((challenged(&net.a.0), challenged(&net.b.0)), (0, 0));
}

#[test]
fn an_event_before_the_greetings_is_challenged_and_delivered_once_on_its_resend() {
    let mut net = Net::new();
    net.press();
    net.run(400);
    assert_eq!(net.b.1.lamp, [true], "delivered exactly once");
    net.trace.retain(|t| t.1 != C);
    assert_eq!(
        net.trace,
        [
            // B knows no counter of A yet: A's first event is not taken (besides the
            // greetings both send).
            (A, B, "Event"),
            (A, B, "Challenge"),
            (B, A, "Challenge"),
            (A, B, "ChallengeAnswer"),
            // B's challenge told A that B has no side of the link: A numbers it again
            // and resends at once; B, knowing A's counter now, takes it.
            (A, B, "Event"),
            (B, A, "ChallengeAnswer"),
            (B, A, "EventAck"),
        ]
    );
    assert_eq!(net.b.0.security_counters().challenged, 1);
}

#[test]
fn forged_damaged_replayed_unsecured_and_misaddressed_events_move_nothing() {
    let mut net = Net::established();
    let idx = link_key_index(GENERATION);
    // A captured event of A's, replayed.
    net.press();
    let captured = net.a.1.out[0].clone();
    net.run(200);
    assert_eq!(net.b.1.lamp, [true, false]);
    let mut expected = SecurityCounters {
        challenged: 1,
        ..Default::default()
    };
    let counted = |net: &Net| net.b.0.security_counters();
    assert_eq!(counted(&net), expected);

    net.inject(&captured);
    expected.replayed += 1;
    assert_eq!(counted(&net), expected, "a replay");

    let mut flipped = captured.clone();
    let body = flipped.len() - 6;
    flipped[body] ^= 0x01;
    // The FCS no longer matches: refused by the frame layer before any key.
    let fcs = mac::FCS.checksum(&flipped[..flipped.len() - 2]);
    let n = flipped.len();
    flipped[n - 2..].copy_from_slice(&fcs.to_le_bytes());
    net.inject(&flipped);
    expected.bad_mic += 1;
    assert_eq!(counted(&net), expected, "one bit flipped (with a good FCS)");

    net.inject(&forged(A, [0xEE; 16], idx, 1_000, &event(9)));
    expected.bad_mic += 1;
    assert_eq!(counted(&net), expected, "a forgery with a guessed key");

    // C is a peer of B too (a stolen node, say): its key to B does not make A's frames.
    net.inject(&forged(A, pair_key(C, B), idx, 1_001, &event(9)));
    expected.bad_mic += 1;
    assert_eq!(counted(&net), expected, "C posing as A");

    net.inject(&forged(
        A,
        pair_key(A, B),
        link_key_index(GENERATION + 1),
        1_002,
        &event(9),
    ));
    expected.unknown_key += 1;
    assert_eq!(counted(&net), expected, "another generation's key index");

    let mut payload = [0u8; MAX_PAYLOAD];
    let n = event(9).emit(&mut payload).unwrap();
    let header = Header {
        seq: 0,
        pan_id: PAN,
        dst: B,
        src: A,
        ack_request: false,
        secured: false,
    };
    let mut psdu = [0u8; MAX_PSDU];
    let len = mac::emit_data(&header, &payload[..n], &mut psdu).unwrap();
    net.inject(&psdu[..len]);
    expected.not_secured += 1;
    assert_eq!(counted(&net), expected, "unsecured");

    // B's own frame reflected back to it.
    net.inject(&forged(B, pair_key(B, A), idx, 1_003, &event(9)));
    expected.unknown_key += 1;
    assert_eq!(counted(&net), expected, "reflected");

    assert_eq!(net.b.1.lamp, [true, false], "nothing moved");
    // And the real A still gets through.
    net.press();
    net.run(200);
    assert_eq!(net.b.1.lamp, [true, false, true]);
}

#[test]
fn after_the_receiver_reboots_a_replayed_event_is_challenged_and_never_delivered() {
    let mut net = Net::established();
    net.press();
    let captured = net.a.1.out[0].clone();
    net.run(200);
    assert_eq!(net.b.1.lamp, [true, false]);
    // B loses power; it boots from its flash with the same table and keys, knowing no
    // counter of A. The replayed event is authentic but not fresh for all B knows.
    net.b.0 = node_b();
    net.b.1.lamp.clear();
    net.b.0.receive(&captured, net.now, &mut net.b.1);
    assert_eq!(net.b.0.security_counters().challenged, 1);
    let challenge = net.b.1.out.pop().expect("B challenges A");
    assert_eq!(
        kind(&Message::parse(&open(&challenge).2).unwrap()),
        "Challenge"
    );
    // The attacker replays it again, and does not pass the challenge on to A.
    net.b.0.receive(&captured, net.now + 100, &mut net.b.1);
    assert!(net.b.1.lamp.is_empty(), "nothing delivered");
    assert_eq!(net.b.0.security_counters().challenged, 2);
}

#[test]
fn after_the_sender_reboots_its_new_events_pass_and_its_old_frames_do_not() {
    let mut net = Net::established();
    net.press();
    let captured = net.a.1.out[0].clone();
    net.run(200);
    // A reboots (a new link epoch); its counter continues from flash.
    net.a.0 = NodeCore::new(A, u64::MAX, Some(table_a()), 7).with_link_keys(link_keys(
        A,
        &[B],
        GENERATION,
    ));
    net.press();
    net.run(400);
    assert_eq!(net.b.1.lamp, [true, false, true]);
    let before = net.b.0.security_counters().replayed;
    net.inject(&captured);
    assert_eq!(net.b.0.security_counters().replayed, before + 1);
    assert_eq!(net.b.1.lamp, [true, false, true]);
}

#[test]
fn without_link_keys_the_node_refuses_secured_events_and_sends_in_clear() {
    let mut a = NodeCore::new(A, u64::MAX, Some(table_a()), 1);
    let mut board = Board::default();
    assert!(!a.links_secured());
    a.input(BUTTON_PIN, true, 0, &mut board);
    let Ok(Frame::Data { header, .. }) = Frame::parse(&board.out[0]) else {
        panic!("a data frame");
    };
    assert!(!header.secured);
    // Keys for another table's peers are not taken.
    let b = NodeCore::new(B, u64::MAX, Some(table_b()), 1).with_link_keys(link_keys(B, &[A], 1));
    assert!(!b.links_secured());
    let b = NodeCore::new(B, u64::MAX, Some(table_b()), 1).with_link_keys(link_keys(B, &[A, C], 2));
    assert!(!b.links_secured(), "keys of another generation");
}

/// A subscriber that rebooted lost its side of every link: its publisher numbered on and
/// the fresh receiver, waiting for seq 0, dropped every event (the machine stalled). The
/// rebooted node's greeting tells the publisher, which numbers its link to it again from 0
/// in a new epoch: the next press is delivered, once.
#[test]
fn after_the_subscriber_reboots_the_publisher_numbers_its_link_again_and_events_flow() {
    let mut net = Net::established();
    net.press();
    net.run(200);
    assert_eq!(net.b.1.lamp, [true, false]);
    net.b.0 = node_b();
    net.b.1.lamp.clear();
    net.run(300);
    net.press();
    net.run(400);
    assert_eq!(net.b.1.lamp, [true], "delivered, once");
    net.press();
    net.run(400);
    assert_eq!(net.b.1.lamp, [true, false]);
    assert_eq!(net.a.0.link_alarms(), 0);
}

/// Both nodes boot at once (a machine's power cut), A with an event for B queued: B's
/// greeting (a `Challenge`) reaches A twice (the radio duplicated it) before A knows B's
/// counter. A numbers its link to B again once, not for the copy: B delivers the event
/// once.
#[test]
fn a_duplicated_greeting_numbers_the_link_again_once() {
    let mut net = Net::new();
    net.press();
    net.a.0.poll(1, &mut net.a.1);
    net.b.0.poll(1, &mut net.b.1);
    let from_b = std::mem::take(&mut net.b.1.out);
    let greeting = from_b
        .iter()
        .find(|f| {
            let (h, _, payload) = open(f);
            h.dst == A && kind(&Message::parse(&payload).unwrap()) == "Challenge"
        })
        .expect("B greets A")
        .clone();
    for f in &from_b {
        net.deliver(f);
    }
    // A numbers again and sends; B takes A's answer and the event.
    net.run(1);
    assert_eq!(net.b.1.lamp, [true]);
    // The copy, a moment later, before B's answer to A's greeting reached A.
    net.deliver(&greeting);
    net.run(400);
    assert_eq!(net.b.1.lamp, [true], "delivered once");
    net.press();
    net.run(400);
    assert_eq!(net.b.1.lamp, [true, false]);
}

/// B reboots while A has an event for it. B's greeting is answered, but the answer comes
/// late: B's retry of the greeting is on its way by then. B takes the answer and the
/// event A numbered again for the greeting; its acknowledgement is lost, and the retry
/// reaches A after it. A numbered its link to B again for the retry too, resent the
/// event in the newer epoch, and B took it again: delivered twice. A retry of a greeting
/// A answered is the same restart of B: the link is numbered again once, the event
/// delivered once.
#[test]
fn a_greetings_retry_after_a_late_answer_numbers_the_link_again_once() {
    let mut net = Net::b_rebooted_and_pressed();
    let (mut answer, mut retry) = (None, None);
    let mut greetings = 0;
    net.run_each(1000, |net, f| {
        let (h, _, payload) = open(&f);
        match (h.src, h.dst, Message::parse(&payload).unwrap()) {
            // A's first answer to B, held until B retried its greeting.
            (A, B, Message::ChallengeAnswer { .. }) if greetings < 2 => {
                answer.get_or_insert(f);
            }
            (B, A, Message::Challenge { .. }) if greetings == 1 => {
                greetings += 1;
                retry = Some(f);
                if let Some(late) = answer.take() {
                    net.deliver(&late);
                }
            }
            (B, A, Message::Challenge { .. }) => {
                greetings += 1;
                net.deliver(&f);
            }
            // B's acknowledgement lost; the retry arrives in its place.
            (B, A, Message::EventAck { .. }) if retry.is_some() => {
                if let Some(late) = retry.take() {
                    net.deliver(&late);
                }
            }
            _ => net.deliver(&f),
        }
    });
    assert!(greetings >= 2, "{:?}", net.trace);
    net.delivered_once();
}

/// B reboots while A has an event for it, and A's answers to B's greeting are late: B
/// repeats the greeting's nonce for `REPEAT_MS`, then challenges A's resent event with a
/// fresh one. That challenge is on its way when A's (held) answer reaches B: B takes the
/// event A numbered again for the greeting, its acknowledgement is lost, and the fresh
/// challenge reaches A after it. A numbered its link to B again for it (a newer nonce),
/// resent the event in the newer epoch, and B took it again: delivered twice. None of the
/// events of A's epoch was acknowledged when the challenge came: B's receiver, fresh or
/// not, takes its seq 0 as it is; the link is not numbered again, the event delivered
/// once.
#[test]
fn a_fresh_challenge_that_comes_after_the_event_it_asked_for_numbers_nothing_again() {
    let mut net = Net::b_rebooted_and_pressed();
    let (mut greeting, mut answer, mut fresh) = (None, None, None);
    let mut released = false;
    net.run_each(3000, |net, f| {
        let (h, _, payload) = open(&f);
        match (h.src, h.dst, Message::parse(&payload).unwrap()) {
            // The greeting reaches A; the first challenge with another nonce, and its
            // repeats, are held.
            (B, A, Message::Challenge { nonce }) if !released => {
                match *greeting.get_or_insert(nonce) == nonce {
                    true => net.deliver(&f),
                    false => {
                        fresh.get_or_insert(f);
                    }
                }
            }
            // A's answers held, the last one released once B challenged afresh.
            (A, B, Message::ChallengeAnswer { .. }) if fresh.is_none() => answer = Some(f),
            // B's acknowledgement lost; the fresh challenge reaches A in its place.
            (B, A, Message::EventAck { .. }) if !released => {
                released = true;
                net.deliver(&fresh.take().expect("B challenged afresh"));
            }
            _ => net.deliver(&f),
        }
        if let Some(late) = answer.take_if(|_| fresh.is_some()) {
            net.deliver(&late);
        }
    });
    assert!(released, "{:?}", net.trace);
    net.delivered_once();
}

/// A reboots while B is up: B answers A's greeting and takes A's press (its lamp on
/// again), its answer and its acknowledgement held in the air; then B reboots too. The
/// net, the old B's answer and its acknowledgement.
fn old_b_held_its_answer_and_ack_then_rebooted() -> (Net, Vec<u8>, Vec<u8>) {
    let mut net = Net::established();
    net.press();
    net.run(400);
    net.a.0 = rebooted_a();
    let mut held: Vec<Vec<u8>> = Vec::new();
    let mut hold = |net: &mut Net, f: Vec<u8>| {
        let (h, _, payload) = open(&f);
        match (h.src, Message::parse(&payload).unwrap()) {
            (B, Message::ChallengeAnswer { .. } | Message::EventAck { .. }) => held.push(f),
            _ => net.deliver(&f),
        }
    };
    net.run_each(20, &mut hold);
    net.press();
    net.run_each(20, &mut hold);
    assert_eq!(
        net.b.1.lamp,
        [true, false, true],
        "the old B took the press"
    );
    let first = |k: &str| {
        let of_kind = |f: &&Vec<u8>| kind(&Message::parse(&open(f).2).unwrap()) == k;
        held.iter().find(of_kind).expect("held").clone()
    };
    let (answer, ack) = (first("ChallengeAnswer"), first("EventAck"));
    net.b.0 = node_b();
    net.b.1.lamp.clear();
    (net, answer, ack)
}

/// After [`old_b_held_its_answer_and_ack_then_rebooted`], the new B's greeting reaches
/// A, which knows no floor of B (A's link is still at seq 0: not numbered again); A's
/// resent event and the new B's answers are lost. Then the old B's answer comes and set
/// A's floor below the new B's greeting, and the old B's acknowledgement passed and
/// moved A's link to seq 1: the new B's fresh receiver waited for a seq 0 that never
/// came, and every later press was lost. A floor an answer sets is at least the counter
/// of every frame of the peer come before it: the old frames are replays.
#[test]
fn an_old_lifes_late_answer_and_ack_move_no_link_of_the_new_one() {
    let (mut net, answer, ack) = old_b_held_its_answer_and_ack_then_rebooted();
    net.run_each(30, |net, f| {
        let (h, _, payload) = open(&f);
        match (h.src, h.dst, Message::parse(&payload).unwrap()) {
            (A, B, Message::Event { .. }) | (B, A, Message::ChallengeAnswer { .. }) => {}
            _ => net.deliver(&f),
        }
    });
    net.deliver(&answer);
    net.deliver(&ack);
    net.run(1_000);
    let before = net.b.1.lamp.clone();
    net.press();
    net.run(3_000);
    assert_eq!(
        net.b.1.lamp.len(),
        before.len() + 1,
        "the new B takes the next press: {:?}",
        net.trace
    );
    assert_eq!(net.a.0.link_alarms(), 0);
}

/// As above, but the new B greets A twice before it knows A's floor, and the retry is
/// late. The new B takes A's resent press; the old B's answer and acknowledgement come
/// (they moved A's link to seq 1); A's next press, seq 1, is taken by the new B, its
/// acknowledgement lost; then the late retry passed A's replay check, A's link (past seq
/// 0) was numbered again and the press delivered twice.
#[test]
fn an_old_lifes_late_ack_then_a_late_retry_deliver_a_press_once() {
    let (mut net, answer, ack) = old_b_held_its_answer_and_ack_then_rebooted();
    // The new B's greeting reaches A; A's frames to B wait until B's retry went out
    // (held: late); the new B's answers and acknowledgements are lost.
    let (mut first, mut late, mut to_b) = (true, None::<Vec<u8>>, Vec::<Vec<u8>>::new());
    net.run_each(150, |net, f| {
        let (h, _, payload) = open(&f);
        match (h.src, h.dst, Message::parse(&payload).unwrap()) {
            (B, A, Message::Challenge { .. }) if first => {
                first = false;
                net.deliver(&f);
            }
            (B, A, Message::Challenge { .. }) => {
                if late.is_none() {
                    late = Some(f);
                    for g in std::mem::take(&mut to_b) {
                        net.deliver(&g);
                    }
                }
            }
            (B, A, Message::ChallengeAnswer { .. } | Message::EventAck { .. }) => {}
            // A's greeting retries lost (the new B, under way, would fault at one).
            (A, B, Message::Challenge { .. }) => {}
            (A, B, _) if late.is_none() => to_b.push(f),
            _ => net.deliver(&f),
        }
    });
    assert_eq!(net.b.1.lamp, [true], "the new B took A's resent press");
    net.deliver(&answer);
    net.deliver(&ack);
    net.press();
    net.run_each(50, |net, f| {
        let (h, _, payload) = open(&f);
        if !(h.src == B && matches!(Message::parse(&payload), Ok(Message::EventAck { .. }))) {
            net.deliver(&f);
        }
    });
    assert_eq!(net.b.1.lamp, [true, false]);
    net.deliver(&late.expect("B retried its greeting"));
    net.run(1_000);
    assert_eq!(
        net.b.1.lamp,
        [true, false],
        "delivered once: {:?}",
        net.trace
    );
}

/// A's power is cut while B's lamp is on (B's chart neither idle nor initial: under way).
/// A boots and greets B: a challenge whose nonce is its frame's counter with bit 31 set
/// (`restart::GREETING`). B faults `0x86` at once, its lamp at its fault level (off),
/// instead of waiting for what A's charts will not send; the greeting is answered all the
/// same. At rest, B carries on through A's boot.
#[test]
fn a_peers_boot_greeting_faults_a_node_under_way_and_not_one_at_rest() {
    let mut net = Net::established();
    // (Greetings within a second of the boot's are copies of it: `restart::Heard`.)
    net.run(1000);
    net.air.clear();
    net.trace.clear();
    net.a.0 = rebooted_a();
    net.run(300);
    let greeting = greeted_b_under_way(&net);
    assert_eq!(greeting.1, greeting.0 | node_fw::restart::GREETING);
    assert_eq!(net.b.1.lamp, [true, false]);

    // At rest (the lamp off again: its initial state), B carries on.
    let mut net = Net::established();
    net.press();
    net.run(1000);
    net.a.0 = rebooted_a();
    net.run(300);
    net.press();
    net.run(400);
    assert_eq!(net.b.1.lamp, [true, false, true], "{:?}", net.trace);
    let b = net.b.0.status(0, Default::default());
    assert_eq!((b.fault, b.states.as_slice()), (None, [1].as_slice()));
}

/// A `Reset` of A while under way (its press toggled a chart of its own on: in the middle
/// of a cycle) starts A's charts over as a boot does, but a secured node greets only when
/// it boots: B, under way, waited for ever. A reset under way now greets B with a
/// challenge whose nonce is `restart::RESET_GREETING` (bits 31 and 30, no counter): B
/// faults `0x86` and answers, and numbers nothing again (A kept its receivers: B's epoch
/// stays).
#[test]
fn a_node_reset_under_way_greets_its_peers_and_nothing_is_numbered_again() {
    use config_schema::wire::msg::Command;
    use node_fw::restart::RESET_GREETING;
    let mut net = Net::new();
    let mut stepping = table_a();
    stepping.outputs.push(Output::safe(6, false)).unwrap();
    let press = stepping.inputs[0].rise.unwrap();
    toggle(&mut stepping, press, &[Action::Drive { mask: 1, value: 1 }]);
    net.a.0 = NodeCore::new(A, u64::MAX, Some(stepping), 1).with_link_keys(link_keys(
        A,
        &[B],
        GENERATION,
    ));
    // The boots' greetings first (A under way would fault at B's).
    net.run(1500);
    net.press();
    net.run(400);
    assert_eq!(net.b.1.lamp, [true]);
    assert!(net.a.0.under_way() && net.b.0.under_way());
    let epoch = net.b.0.epoch();
    net.air.clear();
    net.trace.clear();
    let mut payload = [0u8; MAX_PAYLOAD];
    let n = Message::Command {
        id: 1,
        command: Command::Reset,
    }
    .emit(&mut payload)
    .unwrap();
    let header = Header {
        seq: 1,
        pan_id: node_fw::node::CONFIG_PAN,
        dst: A,
        src: 0x0100,
        ack_request: false,
        secured: false,
    };
    let mut psdu = [0u8; MAX_PSDU];
    let len = mac::emit_data(&header, &payload[..n], &mut psdu).unwrap();
    net.a.0.receive(&psdu[..len], net.now, &mut net.a.1);
    net.a.1.out.retain(|f| open_to_tool(f));
    net.run(600);
    let greeting = greeted_b_under_way(&net);
    assert_eq!(greeting.1, RESET_GREETING);
    assert!(greeting.0 > 0);
    assert_eq!(net.b.0.epoch(), epoch, "B numbered its link to A again");
}

/// A's greeting to B on the air (its frame's counter, its nonce), once B, under way,
/// answered it and faulted `0x86` (its chart where it was).
fn greeted_b_under_way(net: &Net) -> (u32, u32) {
    let restarted = 0x80 | config_schema::alarm::FAULT_PEER_RESTART;
    let greeting = (net.air.iter().map(|f| open(f)))
        .find_map(|(h, aux, payload)| match Message::parse(&payload) {
            Ok(Message::Challenge { nonce }) if h.src == A => Some((aux.frame_counter, nonce)),
            _ => None,
        })
        .expect("A greets B");
    assert!(
        net.trace.contains(&(B, A, "ChallengeAnswer")),
        "{:?}",
        net.trace
    );
    let b = net.b.0.status(0, Default::default());
    assert_eq!(
        (b.fault, b.states.as_slice()),
        (Some(restarted), [1].as_slice())
    );
    greeting
}

/// Whether `psdu` is not one of the node's frames to its peers (its answer to the tool).
fn open_to_tool(psdu: &[u8]) -> bool {
    !matches!(Frame::parse(psdu), Ok(Frame::Data { header, .. }) if header.dst == 0x0100)
}

/// A booted again: its table and keys from flash, its links in a new epoch.
fn rebooted_a() -> NodeCore {
    NodeCore::new(A, u64::MAX, Some(table_a()), 7).with_link_keys(link_keys(A, &[B], GENERATION))
}

/// A lossy radio between A and B: each frame lost with probability `loss`, copied with
/// probability `dup`, and delivered 0 to `delay` ms late (so reordered), from a seeded
/// generator.
struct Lossy {
    rng: u64,
    loss: f64,
    dup: f64,
    delay: u64,
    /// (when, frame) not delivered yet.
    air: Vec<(u64, Vec<u8>)>,
}

impl Lossy {
    fn next(&mut self) -> f64 {
        self.rng ^= self.rng << 13;
        self.rng ^= self.rng >> 7;
        self.rng ^= self.rng << 17;
        (self.rng >> 11) as f64 / (1u64 << 53) as f64
    }

    /// `ms` milliseconds of `net` over this radio, pressing A's button at each time of
    /// `presses`.
    fn run(&mut self, net: &mut Net, ms: u64, presses: &[u64]) {
        let end = net.now + ms;
        while net.now < end {
            net.now += 1;
            if presses.contains(&net.now) {
                net.press();
            }
            net.a.0.poll(net.now, &mut net.a.1);
            net.b.0.poll(net.now, &mut net.b.1);
            let mut sent = std::mem::take(&mut net.a.1.out);
            sent.append(&mut net.b.1.out);
            for f in sent {
                if self.next() < self.loss {
                    continue;
                }
                let copies = if self.next() < self.dup { 2 } else { 1 };
                for _ in 0..copies {
                    let late = (self.next() * (self.delay + 1) as f64) as u64;
                    self.air.push((net.now + late, f.clone()));
                }
            }
            let (due, later) = std::mem::take(&mut self.air)
                .into_iter()
                .partition(|(at, _)| *at <= net.now);
            self.air = later;
            for (_, f) in due {
                net.deliver(&f);
            }
        }
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(200))]

    /// B, A or both reboot with nothing in flight, B at rest, and A's button is pressed
    /// (while B greets A and after; once A's greetings are over if A rebooted: a press
    /// before its peer hears the last of them faults it, `restart`), on a radio that
    /// loses, copies and reorders frames (up to 150 ms late: past a greeting's retry):
    /// every press is delivered to B exactly once (its lamp toggled once per press).
    #[test]
    fn a_reboot_on_a_lossy_radio_delivers_each_press_once(
        rebooted in 0u8..3,
        seed in 1u64..,
        presses in proptest::collection::vec(1u64..600, 1..4),
        loss in 0.0f64..0.35,
        dup in 0.0f64..0.2,
        delay in 0u64..150,
    ) {
        let mut net = Net::established();
        // B at rest: its lamp off again.
        net.press();
        net.run(400);
        if rebooted != 1 {
            net.b.0 = node_b();
        }
        if rebooted != 0 {
            net.a.0 = rebooted_a();
        }
        net.b.1.lamp.clear();
        let start = match rebooted {
            0 => net.now,
            _ => net.now + node_fw::restart::GREETED_WITHIN_MS + 300,
        };
        let mut at: Vec<u64> = presses.iter().map(|p| start + p).collect();
        at.sort_unstable();
        at.dedup();
        let mut radio = Lossy { rng: seed, loss, dup, delay, air: Vec::new() };
        radio.run(&mut net, 6_000, &at);
        let toggles: Vec<bool> = (0..at.len()).map(|i| i % 2 == 0).collect();
        proptest::prop_assert_eq!(&net.b.1.lamp, &toggles, "{:?}", net.trace);
    }
}

/// An unsecured frame `msg` from `src` to `dst` on `pan`, as anyone in radio range can send.
fn in_clear(pan: u16, dst: u16, src: u16, msg: &Message) -> Vec<u8> {
    let mut payload = [0u8; MAX_PAYLOAD];
    let n = msg.emit(&mut payload).unwrap();
    let header = Header {
        seq: 0,
        pan_id: pan,
        dst,
        src,
        ack_request: false,
        secured: false,
    };
    let mut psdu = [0u8; MAX_PSDU];
    let len = mac::emit_data(&header, &payload[..n], &mut psdu).unwrap();
    psdu[..len].to_vec()
}

/// A's press in `epoch`, forged by anyone: in clear, to B, on the config PAN.
fn event_on_the_config_pan(epoch: u16) -> Vec<u8> {
    let press = Message::Event {
        epoch,
        seq: 0,
        topic: 3,
    };
    in_clear(CONFIG_PAN, B, A, &press)
}

#[test]
fn an_event_in_clear_on_the_config_pan_moves_nothing_on_a_secured_robot() {
    let mut net = Net::established();
    assert_eq!(net.b.1.lamp, [true]);
    let epoch = net.a.0.epoch().wrapping_add(1);
    let forged = event_on_the_config_pan(epoch);
    let dropped = net.b.0.counters().dropped;
    net.b.0.receive(&forged, net.now, &mut net.b.1);
    assert_eq!(net.b.1.lamp, [true], "the forged event moved B's lamp");
    assert_eq!(net.b.0.counters().dropped, dropped + 1);
}

#[test]
fn an_event_in_clear_on_the_config_pan_neither_moves_a_keyed_node_nor_cuts_its_real_link() {
    use node_fw::provision::ManagementKey;
    let mut net = Net::new();
    net.b.0 = node_b().with_management_key(ManagementKey::from_bytes([0x5A; 16]));
    net.press();
    net.run(400);
    assert_eq!(net.b.1.lamp, [true]);
    // An epoch far ahead of A's: taken, it would make every real event of A's look old.
    let epoch = net.a.0.epoch().wrapping_add(0x4000);
    let forged = event_on_the_config_pan(epoch);
    net.b.0.receive(&forged, net.now, &mut net.b.1);
    assert_eq!(net.b.1.lamp, [true], "the forged event moved B's lamp");
    net.b.1.out.clear();
    net.press();
    net.run(2_000);
    assert_eq!(net.b.1.lamp, [true, false], "the real press after it");
    assert_eq!(net.a.0.link_alarms(), 0);
}

#[test]
fn an_ack_in_clear_on_the_config_pan_loses_no_event() {
    let mut net = Net::established();
    net.press();
    net.a.1.out.clear(); // A's event lost on the air
    let epoch = net.a.0.epoch();
    for next in 1..=4u16 {
        let ack = in_clear(CONFIG_PAN, A, B, &Message::EventAck { epoch, next });
        net.a.0.receive(&ack, net.now, &mut net.a.1);
    }
    net.run(2_000);
    assert_eq!(
        net.b.1.lamp,
        [true, false],
        "the press, delivered on a resend"
    );
}
