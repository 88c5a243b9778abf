//! The codec against postcard: every message written as postcard writes it, and any bytes
//! (messages, damaged messages, noise) read as postcard reads them, errors included.

extern crate std;

// `prop_oneof!` of more than ten strategies names `vec!`.
use std::vec;

use proptest::prelude::*;

use super::super::*;
use crate::alarm::{Alarm, AlarmLevel, AlarmReport, AlarmSource};

/// postcard's answer for a payload, its error put in our terms (serde's own errors,
/// `SerdeDeCustom`, are an unknown variant or a capacity: both `Variant` here).
fn postcard_parse(payload: &[u8]) -> Result<Message<'_>, MessageError> {
    match postcard::take_from_bytes::<Message<'_>>(payload) {
        Ok((msg, [])) => Ok(msg),
        Ok(_) => Err(MessageError::Trailing),
        Err(e) => Err(match e {
            postcard::Error::DeserializeUnexpectedEnd => MessageError::End,
            postcard::Error::DeserializeBadVarint => MessageError::Varint,
            postcard::Error::DeserializeBadBool => MessageError::Bool,
            postcard::Error::DeserializeBadOption => MessageError::Option,
            postcard::Error::DeserializeBadUtf8 => MessageError::Utf8,
            postcard::Error::SerdeDeCustom => MessageError::Variant,
            other => panic!("postcard error {other:?} not expected"),
        }),
    }
}

/// What a node hears of `msg`: nothing of an answer or report meant for the tool.
fn acted(msg: Message<'_>) -> Option<Message<'_>> {
    let for_the_tool = matches!(
        msg,
        Message::ConfigReply { .. }
            | Message::Status(_)
            | Message::Announce(_)
            | Message::Security(_)
            | Message::Alarms(_)
    );
    (!for_the_tool).then_some(msg)
}

fn ours(payload: &[u8]) -> Result<Message<'_>, MessageError> {
    Message::parse(payload).map_err(|e| match e {
        MessageError::Capacity => MessageError::Variant,
        e => e,
    })
}

/// Bytes a chunk's data is cut from.
static DATA: [u8; CHUNK_DATA] = {
    let mut d = [0u8; CHUNK_DATA];
    let mut i = 0;
    while i < CHUNK_DATA {
        d[i] = (i as u8).wrapping_mul(37) ^ 0x5A;
        i += 1;
    }
    d
};

/// Small and large values (varints of every length).
fn n32() -> impl Strategy<Value = u32> {
    prop_oneof![0u32..300, any::<u32>(), Just(u32::MAX)]
}

fn n64() -> impl Strategy<Value = u64> {
    prop_oneof![0u64..300, any::<u64>(), Just(u64::MAX)]
}

fn n16() -> impl Strategy<Value = u16> {
    prop_oneof![0u16..300, any::<u16>(), Just(u16::MAX)]
}

fn role() -> impl Strategy<Value = String<MAX_ROLE_NAME>> {
    "[a-zA-Z0-9é]{0,6}".prop_map(|s| {
        let mut r = String::new();
        r.push_str(&s).expect("at most 12 bytes");
        r
    })
}

fn refusal() -> impl Strategy<Value = Refusal> {
    prop_oneof![
        n32().prop_map(|running| Refusal::Stale { running }),
        Just(Refusal::TooLong),
        Just(Refusal::OutOfSequence),
        Just(Refusal::Crc),
        Just(Refusal::Invalid),
        Just(Refusal::Flash),
        (
            any::<u8>(),
            prop_oneof![0u64..300, any::<u64>(), Just(u64::MAX)]
        )
            .prop_map(|(pin, board)| Refusal::Pin { pin, board }),
        n32().prop_map(|staged| Refusal::NotStaged { staged }),
        n32().prop_map(|transfer| Refusal::Superseded { transfer }),
        Just(Refusal::OnTrial),
    ]
}

fn reply() -> impl Strategy<Value = ConfigReply> {
    prop_oneof![
        n16().prop_map(|next| ConfigReply::Next { next }),
        Just(ConfigReply::Activated),
        refusal().prop_map(ConfigReply::Refused),
        Just(ConfigReply::Staged),
        (any::<bool>(), any::<u16>()).prop_map(|(idle, ask)| ConfigReply::Armed { idle, ask }),
        Just(ConfigReply::Busy),
        Just(ConfigReply::Disarmed),
        Just(ConfigReply::Confirmed),
    ]
}

fn command() -> impl Strategy<Value = Command> {
    // Every command; the properties compare their bytes to postcard's (serde's order).
    prop_oneof![
        prop::sample::select(vec![
            Command::Start,
            Command::Reset,
            Command::Status,
            Command::Security,
            Command::Home,
            Command::Alarms,
            Command::Ack,
        ]),
        n64().prop_map(|nonce| Command::Identify { nonce }),
    ]
}

fn step() -> impl Strategy<Value = SwitchStep> {
    prop_oneof![
        any::<u16>().prop_map(|ask| SwitchStep::Arm { ask }),
        (any::<bool>(), any::<bool>()).prop_map(|(now, trial)| SwitchStep::Go { now, trial }),
        Just(SwitchStep::Disarm),
        Just(SwitchStep::Confirm),
    ]
}

fn table_id() -> impl Strategy<Value = TableId> {
    any::<[u8; 4]>().prop_map(TableId)
}

fn status() -> impl Strategy<Value = Status> {
    let head = (
        n16(),
        role(),
        n32(),
        table_id(),
        n32(),
        n32(),
        any::<bool>(),
    );
    let states = proptest::collection::vec(any::<u8>(), 0..=MAX_CHARTS);
    let pins = (n16(), n16(), proptest::option::of(any::<u8>()));
    let links = (any::<u8>(), any::<u8>(), any::<u8>(), n16());
    let counters = (
        proptest::array::uniform5(n32()),
        (n32(), any::<u8>(), n32(), n32()),
    );
    (head, states, pins, links, counters, any::<u8>()).prop_map(
        |(head, states, pins, links, (c, rt), cycles)| Status {
            ack: head.0,
            role: head.1,
            generation: head.2,
            table: head.3,
            staged: head.4,
            previous: head.5,
            trial: head.6,
            states: Vec::from_slice(&states).expect("within capacity"),
            outputs: pins.0,
            inputs: pins.1,
            fault: pins.2,
            link_alarms: links.0,
            links_broken: links.1,
            links_restarted: links.2,
            epoch: links.3,
            counters: Counters {
                sent: c[0],
                received: c[1],
                retried: c[2],
                dropped: c[3],
                delivered: c[4],
            },
            runtime: RuntimeCounters {
                tx_queue_full: rt.0,
                tx_queue_high: rt.1,
                tx_failed: rt.2,
                flash_failures: rt.3,
            },
            cycles,
        },
    )
}

fn security() -> impl Strategy<Value = SecurityReport> {
    (n16(), any::<bool>(), proptest::array::uniform9(n32())).prop_map(|(ack, keyed, c)| {
        SecurityReport {
            ack,
            keyed,
            counters: SecurityCounters {
                not_secured: c[0],
                bad_mic: c[1],
                replayed: c[2],
                unknown_key: c[3],
                wrong_level: c[4],
                malformed: c[5],
                table_full: c[6],
                no_counter: c[7],
                challenged: c[8],
            },
        }
    })
}

fn alarm() -> impl Strategy<Value = Alarm> {
    let source = prop_oneof![
        (any::<u8>(), any::<u8>()).prop_map(|(chart, code)| AlarmSource::Chart { chart, code }),
        Just(AlarmSource::EStop),
        any::<u8>().prop_map(|peer| AlarmSource::Link { peer }),
        any::<u8>().prop_map(|index| AlarmSource::Declared { index }),
    ];
    let level = prop_oneof![
        Just(AlarmLevel::Info),
        Just(AlarmLevel::Warning),
        Just(AlarmLevel::Fault)
    ];
    (source, level, n32(), any::<bool>(), any::<bool>()).prop_map(
        |(source, level, raised_ms, acked, persists)| Alarm {
            source,
            level,
            raised_ms,
            acked,
            persists,
        },
    )
}

fn alarms() -> impl Strategy<Value = AlarmReport> {
    let list = proptest::collection::vec(alarm(), 0..=crate::alarm::MAX_ALARMS);
    (n16(), n32(), list, n16()).prop_map(|(ack, now_ms, list, dropped)| AlarmReport {
        ack,
        now_ms,
        alarms: Vec::from_slice(&list).expect("within capacity"),
        dropped,
    })
}

fn message() -> impl Strategy<Value = Message<'static>> {
    prop_oneof![
        (n16(), n16(), any::<u8>()).prop_map(|(epoch, seq, topic)| Message::Event {
            epoch,
            seq,
            topic
        }),
        (n16(), n16()).prop_map(|(epoch, next)| Message::EventAck { epoch, next }),
        (n32(), n16(), n32(), any::<bool>()).prop_map(|(generation, len, crc, force)| {
            Message::ConfigBegin {
                generation,
                len,
                crc,
                force,
            }
        }),
        (n32(), n16(), 0..=CHUNK_DATA).prop_map(|(generation, offset, n)| {
            Message::ConfigChunk {
                generation,
                offset,
                data: &DATA[..n],
            }
        }),
        n32().prop_map(|generation| Message::ConfigEnd { generation }),
        (n32(), reply()).prop_map(|(generation, reply)| Message::ConfigReply { generation, reply }),
        (n16(), command()).prop_map(|(id, command)| Message::Command { id, command }),
        status().prop_map(Message::Status),
        (n16(), n32(), role(), table_id(), n32(), n64()).prop_map(
            |(firmware, generation, role, table, staged, nonce)| {
                Message::Announce(Announce {
                    firmware,
                    generation,
                    role,
                    table,
                    staged,
                    nonce,
                })
            }
        ),
        security().prop_map(Message::Security),
        n32().prop_map(|nonce| Message::Challenge { nonce }),
        n32().prop_map(|nonce| Message::ChallengeAnswer { nonce }),
        (n32(), step()).prop_map(|(generation, step)| Message::Switch { generation, step }),
        alarms().prop_map(Message::Alarms),
    ]
}

/// How a message's bytes are damaged.
#[derive(Debug, Clone, Copy)]
enum Damage {
    Cut(usize),
    Set(usize, u8),
    Insert(usize, u8),
    Append(u8),
}

fn damage() -> impl Strategy<Value = Damage> {
    prop_oneof![
        any::<usize>().prop_map(Damage::Cut),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Damage::Set(i, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Damage::Insert(i, b)),
        any::<u8>().prop_map(Damage::Append),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn every_message_is_written_as_postcard_writes_it(msg in message(), room in 0usize..=140) {
        let (mut a, mut b) = ([0u8; 140], [0u8; 140]);
        let ours = msg.emit(&mut a[..room]);
        match postcard::to_slice(&msg, &mut b[..room]) {
            Ok(theirs) => {
                let n = theirs.len();
                prop_assert_eq!(ours, Ok(n));
                prop_assert_eq!(&a[..n], &b[..n]);
                prop_assert_eq!(Message::parse(&a[..n]), Ok(msg.clone()));
            }
            Err(e) => {
                prop_assert_eq!(e, postcard::Error::SerializeBufferFull);
                prop_assert_eq!(ours, Err(MessageError::Full));
            }
        }
    }

    #[test]
    fn damaged_messages_are_read_as_postcard_reads_them(
        msg in message(), damages in proptest::collection::vec(damage(), 1..4),
    ) {
        let mut buf = [0u8; 140];
        let n = msg.emit(&mut buf).expect("fits");
        let mut bytes: std::vec::Vec<u8> = buf[..n].to_vec();
        for d in damages {
            let len = bytes.len();
            match d {
                Damage::Cut(i) => bytes.truncate(i % (len + 1)),
                Damage::Set(i, b) if len > 0 => bytes[i % len] = b,
                Damage::Set(..) => {}
                Damage::Insert(i, b) => bytes.insert(i % (len + 1), b),
                Damage::Append(b) => bytes.push(b),
            }
        }
        prop_assert_eq!(ours(&bytes), postcard_parse(&bytes));
        prop_assert_eq!(Message::parse_node(&bytes), Message::parse(&bytes).map(acted));
    }

    #[test]
    fn a_node_hears_what_it_acts_on(msg in message()) {
        let mut buf = [0u8; 140];
        let n = msg.emit(&mut buf).expect("fits");
        prop_assert_eq!(Message::parse_node(&buf[..n]), Ok(acted(msg.clone())));
    }

    #[test]
    fn any_bytes_are_read_as_postcard_reads_them(
        tag in prop_oneof![0u8..16, any::<u8>()],
        body in proptest::collection::vec(any::<u8>(), 0..48),
    ) {
        let mut bytes = vec![tag];
        bytes.extend_from_slice(&body);
        prop_assert_eq!(ours(&bytes), postcard_parse(&bytes));
        prop_assert_eq!(Message::parse_node(&bytes), Message::parse(&bytes).map(acted));
    }
}

#[test]
fn postcard_rules_hold_field_by_field() {
    // Longer encodings than the shortest are read; the last byte of a varint holds only
    // the bits its type has left.
    assert_eq!(
        Message::parse(&[0x0A, 0x80, 0x80, 0x80, 0x80, 0x00]),
        Ok(Message::Challenge { nonce: 0 })
    );
    assert_eq!(
        Message::parse(&[0x0A, 0xFF, 0xFF, 0xFF, 0xFF, 0x0F]),
        Ok(Message::Challenge { nonce: u32::MAX })
    );
    assert_eq!(
        Message::parse(&[0x0A, 0xFF, 0xFF, 0xFF, 0xFF, 0x10]),
        Err(MessageError::Varint)
    );
    assert_eq!(
        Message::parse(&[0x0A, 0x80, 0x80, 0x80, 0x80, 0x80]),
        Err(MessageError::Varint)
    );
    assert_eq!(
        Message::parse(&[0x01, 0x80, 0x80, 0x04, 0x00]),
        Err(MessageError::Varint)
    );
    // A bool is 0 or 1; so is an option's tag.
    assert_eq!(Message::parse(&[0x02, 1, 2, 3, 2]), Err(MessageError::Bool));
    // A variant index is a varint too: 0x80 0x00 is the Event variant.
    assert_eq!(
        Message::parse(&[0x80, 0x00, 1, 2, 3]),
        Ok(Message::Event {
            epoch: 1,
            seq: 2,
            topic: 3
        })
    );
    assert_eq!(
        Message::parse(&[0x06, 0x00, 0x08]),
        Err(MessageError::Variant)
    );
    // An announcement whose role is 13 bytes, or not UTF-8.
    let mut long = [b'r'; 20];
    long[..5].copy_from_slice(&[0x08, 0x01, 0x02, 13, b'r']);
    assert_eq!(Message::parse(&long), Err(MessageError::Capacity));
    assert_eq!(
        Message::parse(&[0x08, 0x01, 0x02, 1, 0xFF, 0]),
        Err(MessageError::Utf8)
    );
    assert_eq!(
        Message::parse(&[0x08, 0x01, 0x02, 2, b'r']),
        Err(MessageError::End)
    );
}
