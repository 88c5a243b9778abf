//! Over-the-air transfer: the node stages a table only when the whole blob arrived, its
//! CRC matches and it decodes and validates; anything else leaves the old table running.

mod support;
use support::{blob, Channel, Rng};

use config_schema::wire::msg::{ConfigReply, Message, Refusal, CHUNK_DATA};
use config_schema::Table;
use node_fw::ota::{Outcome, Progress, Receiver, Sender};

/// `ConfigBegin`'s `crc` of a transfer of `bytes`.
fn transfer_crc(bytes: &[u8]) -> u32 {
    config_schema::blob::TRANSFER_CRC.checksum(bytes)
}

/// What the node ended with.
struct Node {
    rx: Receiver,
    running: u32,
    activations: Vec<Table>,
}

impl Node {
    fn new(running: u32) -> Self {
        Node {
            rx: Receiver::new(),
            running,
            activations: Vec::new(),
        }
    }
    /// Handles a message as the runtime would; returns the reply.
    fn handle(&mut self, msg: &Message) -> Option<(u32, ConfigReply)> {
        let generation = match *msg {
            Message::ConfigBegin { generation, .. }
            | Message::ConfigChunk { generation, .. }
            | Message::ConfigEnd { generation } => generation,
            _ => return None,
        };
        match self.rx.on_message(msg, self.running, 0)? {
            Outcome::Reply(r) => Some((generation, r)),
            // Staged, and (this test's node) switched to at once.
            Outcome::Stage { generation, len } => {
                self.running = generation;
                // What the node would switch to: the staged blob, decoded.
                self.activations
                    .push(config_schema::decode(self.rx.blob(len)).unwrap());
                Some((generation, ConfigReply::Staged))
            }
        }
    }
}

/// Runs a transfer over a lossy channel pair until the sender settles (or `limit` ms).
fn transfer(node: &mut Node, sender: &mut Sender, loss: f64, dup: f64, seed: u64) -> u64 {
    let mut rng = Rng::new(seed);
    let mut down: Channel<Message> = Channel::new(loss, dup, (1, 6));
    let mut up: Channel<(u32, ConfigReply)> = Channel::new(loss, dup, (1, 6));
    let mut now = 0;
    let mut out = Vec::new();
    sender.start(now, |m| out.push(m));
    while sender.progress() == Progress::Busy && now < 60_000 {
        for m in out.drain(..) {
            if std::env::var("OTA_TRACE").is_ok() {
                eprintln!("{now} -> {m:?}");
            }
            down.send(&mut rng, now, m);
        }
        for m in down.due(now) {
            if let Some(r) = node.handle(&m) {
                up.send(&mut rng, now, r);
            }
        }
        for (generation, reply) in up.due(now) {
            sender.on_reply(generation, reply, now, |m| out.push(m));
        }
        sender.poll(now, |m| out.push(m));
        now += 1;
    }
    now
}

#[test]
fn a_clean_transfer_activates_the_decoded_table_once() {
    let (table, bytes) = blob(5, 30);
    assert!(bytes.len() > 2 * CHUNK_DATA, "spans several chunks");
    let mut node = Node::new(4);
    let mut tx = Sender::new(&bytes, 5, false);
    transfer(&mut node, &mut tx, 0.0, 0.0, 1);
    assert_eq!(tx.progress(), Progress::Done);
    assert_eq!(node.activations, vec![table]);
    assert_eq!(node.running, 5);
    let chunks = bytes.len().div_ceil(CHUNK_DATA) as u32;
    // begin + chunks + end, nothing resent.
    assert_eq!(tx.stats().frames, chunks + 2);
    assert_eq!(tx.stats().retries, 0);
    assert_eq!(tx.stats().bytes as usize, bytes.len());
}

#[test]
fn lossy_transfers_complete_with_exactly_one_activation() {
    let (table, bytes) = blob(9, 40);
    for seed in 1..=30 {
        let mut node = Node::new(2);
        let mut tx = Sender::new(&bytes, 9, false);
        transfer(&mut node, &mut tx, 0.2, 0.1, seed);
        assert_eq!(tx.progress(), Progress::Done, "seed {seed}");
        assert_eq!(node.activations, vec![table.clone()], "seed {seed}");
    }
}

#[test]
fn a_stale_generation_is_refused_unless_forced() {
    let (table, bytes) = blob(3, 2);
    for running in [3, 7] {
        let mut node = Node::new(running);
        let mut tx = Sender::new(&bytes, 3, false);
        transfer(&mut node, &mut tx, 0.0, 0.0, 1);
        assert_eq!(tx.progress(), Progress::Refused(Refusal::Stale { running }));
        assert!(node.activations.is_empty());
    }
    let mut node = Node::new(7);
    let mut tx = Sender::new(&bytes, 3, true);
    transfer(&mut node, &mut tx, 0.0, 0.0, 1);
    assert_eq!(tx.progress(), Progress::Done);
    assert_eq!(node.activations, vec![table]);
}

#[test]
fn a_wrong_total_crc_is_refused_and_nothing_is_activated() {
    let (_, bytes) = blob(2, 10);
    let mut rx = Receiver::new();
    let begin = Message::ConfigBegin {
        generation: 2,
        len: bytes.len() as u16,
        crc: 0xDEAD_BEEF,
        force: false,
    };
    assert_eq!(
        rx.on_message(&begin, 1, 0),
        Some(Outcome::Reply(ConfigReply::Next { next: 0 }))
    );
    for (i, data) in bytes.chunks(CHUNK_DATA).enumerate() {
        let chunk = Message::ConfigChunk {
            generation: 2,
            offset: (i * CHUNK_DATA) as u16,
            data,
        };
        rx.on_message(&chunk, 1, 0);
    }
    assert_eq!(
        rx.on_message(&Message::ConfigEnd { generation: 2 }, 1, 0),
        Some(Outcome::Reply(ConfigReply::Refused(Refusal::Crc)))
    );
    assert_eq!(rx.receiving(), None);
}

#[test]
fn a_blob_that_does_not_decode_is_refused() {
    let (_, mut bytes) = blob(2, 3);
    bytes[0] = b'X'; // bad magic, but the transfer CRC covers the damaged bytes
    let mut node = Node::new(1);
    let mut tx = Sender::new(&bytes, 2, false);
    transfer(&mut node, &mut tx, 0.0, 0.0, 1);
    assert_eq!(tx.progress(), Progress::Refused(Refusal::Invalid));
    assert!(node.activations.is_empty());
    assert_eq!(node.running, 1);
}

#[test]
fn chunks_out_of_place_are_not_staged_and_the_node_says_where_it_is() {
    let (_, bytes) = blob(2, 40);
    assert!(bytes.len() > 3 * CHUNK_DATA);
    let mut rx = Receiver::new();
    let begin = Message::ConfigBegin {
        generation: 2,
        len: bytes.len() as u16,
        crc: transfer_crc(&bytes),
        force: false,
    };
    rx.on_message(&begin, 0, 0);
    let chunk = |offset: usize| Message::ConfigChunk {
        generation: 2,
        offset: offset as u16,
        data: &bytes[offset..(offset + CHUNK_DATA).min(bytes.len())],
    };
    let next = |n| Some(Outcome::Reply(ConfigReply::Next { next: n }));
    // Chunk 1 before chunk 0: staged, but the node still needs byte 0.
    assert_eq!(rx.on_message(&chunk(CHUNK_DATA), 0, 0), next(0), "early");
    assert_eq!(rx.on_message(&chunk(0), 0, 0), next(2 * CHUNK_DATA as u16));
    assert_eq!(
        rx.on_message(&chunk(0), 0, 0),
        next(2 * CHUNK_DATA as u16),
        "dup"
    );
    // A chunk off its place, or cut short, is not staged.
    let misplaced = Message::ConfigChunk {
        generation: 2,
        offset: 2 * CHUNK_DATA as u16 + 1,
        data: &bytes[..CHUNK_DATA],
    };
    assert_eq!(rx.on_message(&misplaced, 0, 0), next(2 * CHUNK_DATA as u16));
    let short = Message::ConfigChunk {
        generation: 2,
        offset: 2 * CHUNK_DATA as u16,
        data: &bytes[2 * CHUNK_DATA..2 * CHUNK_DATA + 10],
    };
    assert_eq!(rx.on_message(&short, 0, 0), next(2 * CHUNK_DATA as u16));
    let other = Message::ConfigChunk {
        generation: 3,
        offset: CHUNK_DATA as u16,
        data: &bytes[..4],
    };
    assert_eq!(
        rx.on_message(&other, 0, 0),
        Some(Outcome::Reply(ConfigReply::Refused(Refusal::OutOfSequence)))
    );
    // An early end is answered with where the node is.
    assert_eq!(
        rx.on_message(&Message::ConfigEnd { generation: 2 }, 0, 0),
        next(2 * CHUNK_DATA as u16)
    );
    assert_eq!(rx.receiving(), Some(2));
}

#[test]
fn an_interrupted_transfer_activates_nothing_and_a_newer_one_restarts() {
    let (_, old) = blob(4, 30);
    let (table, new) = blob(5, 12);
    let mut node = Node::new(3);
    // The tool dies after the begin and two chunks.
    let mut tx = Sender::new(&old, 4, false);
    let mut out = Vec::new();
    tx.start(0, |m| out.push(m));
    let reply = node.handle(&out[0]).unwrap();
    out.clear();
    tx.on_reply(reply.0, reply.1, 1, |m| out.push(m));
    for m in out.iter().take(2) {
        node.handle(m);
    }
    assert_eq!(node.rx.receiving(), Some(4));
    assert!(node.activations.is_empty());
    assert_eq!(node.running, 3);
    // A newer transfer starts over.
    let mut tx = Sender::new(&new, 5, false);
    transfer(&mut node, &mut tx, 0.0, 0.0, 2);
    assert_eq!(tx.progress(), Progress::Done);
    assert_eq!(node.activations, vec![table]);
}

#[test]
fn a_lost_activated_reply_is_answered_again_not_refused() {
    let (_, bytes) = blob(6, 3);
    let mut node = Node::new(0);
    let mut tx = Sender::new(&bytes, 6, false);
    transfer(&mut node, &mut tx, 0.0, 0.0, 1);
    assert_eq!(node.running, 6);
    assert_eq!(
        node.handle(&Message::ConfigEnd { generation: 6 }),
        Some((6, ConfigReply::Activated))
    );
    assert_eq!(node.activations.len(), 1);
}

#[test]
fn a_node_that_never_answers_makes_the_tool_give_up() {
    let (_, bytes) = blob(6, 3);
    let mut node = Node::new(0);
    let mut tx = Sender::new(&bytes, 6, false);
    transfer(&mut node, &mut tx, 1.0, 0.0, 1);
    assert_eq!(tx.progress(), Progress::GaveUp);
    assert!(node.activations.is_empty());
}

#[test]
fn a_late_chunk_copy_after_activation_is_answered_activated() {
    let (_, bytes) = blob(6, 3);
    let mut node = Node::new(0);
    let mut tx = Sender::new(&bytes, 6, false);
    transfer(&mut node, &mut tx, 0.0, 0.0, 1);
    assert_eq!(node.running, 6);
    let late = Message::ConfigChunk {
        generation: 6,
        offset: 0,
        data: &bytes[..CHUNK_DATA.min(bytes.len())],
    };
    assert_eq!(node.handle(&late), Some((6, ConfigReply::Activated)));
    assert_eq!(node.activations.len(), 1);
}

#[test]
fn a_node_that_loses_the_transfer_gets_it_again_from_the_start() {
    let (table, bytes) = blob(8, 40);
    let mut node = Node::new(7);
    let mut tx = Sender::new(&bytes, 8, false);
    let mut out = Vec::new();
    tx.start(0, |m| out.push(m));
    let mut now = 0;
    let mut forgotten = false;
    while tx.progress() == Progress::Busy && now < 10_000 {
        let mut replies = Vec::new();
        for m in out.drain(..) {
            if let Some(r) = node.handle(&m) {
                replies.push(r);
            }
            // The node restarts after staging its first chunk: the transfer is gone.
            if !forgotten && matches!(m, Message::ConfigChunk { .. }) {
                node.rx = Receiver::new();
                forgotten = true;
            }
        }
        for (generation, reply) in replies {
            tx.on_reply(generation, reply, now, |m| out.push(m));
        }
        tx.poll(now, |m| out.push(m));
        now += 1;
    }
    assert!(forgotten);
    assert_eq!(tx.progress(), Progress::Done);
    assert_eq!(node.activations, vec![table]);
}

/// Issue 12: a `ConfigBegin` of an older generation that is still newer than the running
/// one replaced a newer transfer in progress.
#[test]
fn an_older_begin_does_not_replace_a_newer_transfer_and_a_staged_one_is_answered_staged() {
    let (_, bytes) = blob(7, 30);
    let begin = |generation, force| Message::ConfigBegin {
        generation,
        len: bytes.len() as u16,
        crc: transfer_crc(&bytes),
        force,
    };
    let mut rx = Receiver::new();
    let next = |n| Some(Outcome::Reply(ConfigReply::Next { next: n }));
    assert_eq!(rx.on_message(&begin(7, false), 4, 0), next(0));
    assert_eq!(
        rx.on_message(&begin(5, false), 4, 0),
        Some(Outcome::Reply(ConfigReply::Refused(Refusal::Superseded {
            transfer: 7
        })))
    );
    assert_eq!(rx.receiving(), Some(7));
    // Forced, it does (the operator's explicit downgrade).
    assert_eq!(rx.on_message(&begin(5, true), 4, 0), next(0));
    assert_eq!(rx.receiving(), Some(5));
    // Generation 7 staged by this receiver: a begin offering that table is answered so,
    // not restarted.
    let mut rx = Receiver::new();
    take_whole(&mut rx, 7, &bytes);
    rx.persisted(true);
    assert_eq!(
        rx.on_message(&begin(7, false), 4, 7),
        Some(Outcome::Reply(ConfigReply::Staged))
    );
    assert_eq!(rx.receiving(), None);
}

/// Takes `bytes` whole as generation `generation` into `rx` (the running generation 4,
/// nothing staged): begin, every chunk, end, which asks for the blob to be staged.
fn take_whole(rx: &mut Receiver, generation: u32, bytes: &[u8]) {
    let begin = Message::ConfigBegin {
        generation,
        len: bytes.len() as u16,
        crc: transfer_crc(bytes),
        force: false,
    };
    assert_eq!(
        rx.on_message(&begin, 4, 0),
        Some(Outcome::Reply(ConfigReply::Next { next: 0 }))
    );
    for (i, data) in bytes.chunks(CHUNK_DATA).enumerate() {
        let chunk = Message::ConfigChunk {
            generation,
            offset: (i * CHUNK_DATA) as u16,
            data,
        };
        assert!(rx.on_message(&chunk, 4, 0).is_some());
    }
    assert_eq!(
        rx.on_message(&Message::ConfigEnd { generation }, 4, 0),
        Some(Outcome::Stage {
            generation,
            len: bytes.len()
        })
    );
}

/// Another table of the staged generation replaces the staged one: a push of generation 7
/// is not answered `Staged` because some generation 7 is. Found: a node with the double
/// dip staged as generation 12 answered a push of the paint robot as generation 12
/// `Staged`, and the switch-over ran the double dip. After a boot, or when persisting
/// failed, the receiver cannot tell the tables apart: it takes the table again.
#[test]
fn another_table_of_the_staged_generation_replaces_it() {
    let (_, bytes) = blob(7, 30);
    let begin = |crc: u32| Message::ConfigBegin {
        generation: 7,
        len: bytes.len() as u16,
        crc,
        force: false,
    };
    let crc = transfer_crc(&bytes);
    let mut rx = Receiver::new();
    take_whole(&mut rx, 7, &bytes);
    rx.persisted(true);
    let next0 = Some(Outcome::Reply(ConfigReply::Next { next: 0 }));
    assert_eq!(rx.on_message(&begin(crc ^ 1), 4, 7), next0);
    assert_eq!(rx.receiving(), Some(7));
    // Persisting failed: what is staged is unknown, the same table is taken again.
    let mut rx = Receiver::new();
    take_whole(&mut rx, 7, &bytes);
    rx.persisted(false);
    assert_eq!(rx.on_message(&begin(crc), 4, 7), next0);
    // After a boot (a new receiver), too.
    assert_eq!(Receiver::new().on_message(&begin(crc), 4, 7), next0);
}

/// Polls `tx`, the node silent, until it gives up, calling `challenged` after each timeout
/// `i` the node answered with a challenge (`answered(i)`); returns the timeouts it took
/// after the first send.
fn timeouts_until_given_up(tx: &mut Sender, answered: impl Fn(u32) -> bool) -> u32 {
    let mut now = 0;
    tx.poll(now, |_| {});
    for i in 0..1000 {
        now = tx.deadline();
        tx.poll(now, |_| {});
        if tx.progress() == Progress::GaveUp {
            return i + 1;
        }
        if answered(i) {
            tx.challenged();
        }
    }
    1000
}

#[test]
fn a_node_that_challenges_is_not_silent_a_timeout_it_answered_does_not_count() {
    let (_, bytes) = blob(6, 3);
    // Silent: gives up after GIVE_UP_AFTER timeouts.
    let mut silent = Sender::new(&bytes, 6, false);
    let limit = u32::from(node_fw::ota::GIVE_UP_AFTER);
    assert_eq!(timeouts_until_given_up(&mut silent, |_| false), limit);
    // Every other timeout answered by a challenge whose answer was lost: those do not count
    // toward giving up...
    let mut half = Sender::new(&bytes, 6, false);
    assert_eq!(
        timeouts_until_given_up(&mut half, |i| i % 2 == 0),
        2 * limit - 1
    );
    // ...but a node that challenges forever and never takes an answer is given up on too,
    // after at most GIVE_UP_AFTER answered timeouts more.
    let mut always = Sender::new(&bytes, 6, false);
    assert_eq!(timeouts_until_given_up(&mut always, |_| true), 2 * limit);
}

/// Two tables of generation 7 whose blobs are the same length and differ (an output's pin).
fn two_tables_of_one_length() -> (Vec<u8>, Vec<u8>) {
    let (mut table, _) = blob(7, 30);
    let x = test_tables::blob(&table);
    table.outputs[0].pin = 4;
    let y = test_tables::blob(&table);
    assert_eq!(x.len(), y.len());
    assert_ne!(x, y);
    (x, y)
}

/// The begin of a transfer of `bytes` at generation 7.
fn begin_of(bytes: &[u8], force: bool) -> Message<'_> {
    Message::ConfigBegin {
        generation: 7,
        len: bytes.len() as u16,
        crc: transfer_crc(bytes),
        force,
    }
}

/// The transfer's CRC tells tables apart: a CRC-32/ISO-HDLC over bytes that end with
/// their own would be the same (its residue) for every blob of one length.
#[test]
fn the_transfer_crc_differs_between_tables_of_one_length() {
    let (x, y) = two_tables_of_one_length();
    assert_ne!(transfer_crc(&x), transfer_crc(&y));
}

/// An edited robot pushed again at the staged generation, its blob as long as the staged
/// one: taken (answered `Next{0}`), not `Staged`, or the switch-over runs the old table.
#[test]
fn another_table_of_one_length_at_the_staged_generation_is_taken() {
    let (x, y) = two_tables_of_one_length();
    let mut rx = Receiver::new();
    take_whole(&mut rx, 7, &x);
    rx.persisted(true);
    assert_eq!(
        rx.on_message(&begin_of(&y, false), 4, 7),
        Some(Outcome::Reply(ConfigReply::Next { next: 0 }))
    );
    // X is still what is staged (Y's transfer goes to the staging area until its end).
    assert_eq!(
        rx.on_message(&begin_of(&x, false), 4, 7),
        Some(Outcome::Reply(ConfigReply::Staged))
    );
}

/// A push cut after its chunks and before its end, the robot edited, pushed again at that
/// generation: the new table's begin starts the transfer over, and its end stages it, not
/// the bytes of the first.
#[test]
fn the_begin_of_another_table_restarts_the_transfer_in_progress() {
    let (x, y) = two_tables_of_one_length();
    let mut rx = Receiver::new();
    rx.on_message(&begin_of(&x, false), 4, 0);
    for (i, data) in x.chunks(CHUNK_DATA).enumerate() {
        let offset = (i * CHUNK_DATA) as u16;
        let chunk = Message::ConfigChunk {
            generation: 7,
            offset,
            data,
        };
        rx.on_message(&chunk, 4, 0);
    }
    // The same table's begin again (its answer lost): where the transfer stands.
    assert_eq!(
        rx.on_message(&begin_of(&x, false), 4, 0),
        Some(Outcome::Reply(ConfigReply::Next {
            next: x.len() as u16
        }))
    );
    // Another table's: from the start.
    assert_eq!(
        rx.on_message(&begin_of(&y, false), 4, 0),
        Some(Outcome::Reply(ConfigReply::Next { next: 0 }))
    );
    assert_eq!(
        rx.on_message(&Message::ConfigEnd { generation: 7 }, 4, 0),
        Some(Outcome::Reply(ConfigReply::Next { next: 0 }))
    );
    take_whole(&mut rx, 7, &y);
    assert_eq!(rx.blob(y.len()), &y[..]);
}
