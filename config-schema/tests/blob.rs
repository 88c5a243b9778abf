//! The blob envelope: round trip, exact layout, and every `DecodeError` from a precise
//! mutation.

mod common;

use common::{blob, payload, realistic, seal};
use config_schema::blob::{envelope, Envelope, CRC32, HEADER_LEN, MAGIC, TRAILER_LEN};
use config_schema::{
    decode, encode, DecodeError, EncodeError, Invalid, Level, Output, Place, Table,
};

#[test]
fn a_realistic_table_round_trips() {
    let t = realistic();
    let b = blob(&t);
    println!("realistic VC table: {} bytes of blob", b.len());
    assert_eq!(decode(&b), Ok(t.clone()));
    // Deterministic: the same table gives the same bytes.
    assert_eq!(blob(&t), b);
    // The generation travels in the envelope, not the payload.
    let mut g2 = t.clone();
    g2.generation = 7;
    let b2 = blob(&g2);
    assert_eq!(payload(&b2), payload(&b));
    assert_eq!(decode(&b2).map(|t| t.generation), Ok(7));
}

#[test]
fn the_envelope_layout_is_exact() {
    let t = realistic();
    let b = blob(&t);
    let n = b.len() - HEADER_LEN - TRAILER_LEN;
    assert_eq!(&b[0..4], b"ECCT");
    assert_eq!(MAGIC, *b"ECCT");
    assert_eq!(&b[4..6], &[4, 0], "schema version 4, little-endian");
    assert_eq!(
        &b[6..10],
        &[0x04, 0x03, 0x02, 0x01],
        "generation, little-endian"
    );
    assert_eq!(usize::from(u16::from_le_bytes([b[10], b[11]])), n);
    let crc = CRC32.checksum(&b[..HEADER_LEN + n]);
    assert_eq!(&b[HEADER_LEN + n..], &crc.to_le_bytes());
    assert_eq!(
        envelope(&b),
        Ok(Envelope {
            version: 4,
            generation: 0x0102_0304,
            payload_len: n,
            crc,
        })
    );
    // The CRC is CRC-32/ISO-HDLC (the zlib / Ethernet CRC).
    assert_eq!(CRC32.checksum(b"123456789"), 0xCBF4_3926);
}

#[test]
fn the_payload_of_an_empty_table_is_postcard_field_by_field() {
    let t = Table::empty("r");
    let p = payload(&blob(&t));
    #[rustfmt::skip]
    let want = [
        1, b'r', // role: length, bytes
        0,       // pan_id (varint)
        11,      // channel
        0,       // events
        0,       // start: None
        0,       // home: None
        0,       // boot: None
        0, 0, 0, 0, // vars, inputs, outputs, timers: empty
        0, 0, 0, 0, // charts, states, transitions, actions
        0, 0, 0, 0, 0, // code, routes, peers, publications, subscriptions
        0, 0, 0, 0,    // safety: estop None, link_fault false, restart 0, alarms empty
    ];
    assert_eq!(p, want);
    assert_eq!(decode(&seal(&want, 9)).map(|t| t.generation), Ok(9));
}

/// An output is its pin, its fault and start levels (`Low` 0, `High` 1, `Hold` 2) and its
/// home level (a bool).
#[test]
fn an_output_is_pin_fault_start_home() {
    let mut t = Table::empty("r");
    let gripper = Output {
        pin: 9,
        fault: Level::Hold,
        start: Level::Low,
        home: false,
    };
    t.outputs.push(gripper).unwrap();
    t.outputs.push(Output::safe(10, true)).unwrap();
    let p = payload(&blob(&t));
    #[rustfmt::skip]
    let want = [
        1, b'r', 0, 11, 0, 0, // role, pan_id, channel, events, start
        0, 0,                 // home, boot
        0,                    // vars
        0,                    // inputs
        2,                    // outputs: two
        9, 2, 0, 0,           //   pin 9, fault Hold, start Low, home low
        10, 1, 1, 1,          //   pin 10, High, High, high
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, // timers .. subscriptions
        0, 0, 0, 0,           // safety: none
    ];
    assert_eq!(p, want);
    assert_eq!(decode(&seal(&want, 0)), Ok(t));
    // A level past `Hold` is not a level.
    let mut bad = want;
    bad[12] = 3;
    assert!(matches!(
        decode(&seal(&bad, 1)),
        Err(DecodeError::Postcard(_))
    ));
}

#[test]
fn encode_needs_room_for_the_whole_blob() {
    let t = realistic();
    let n = blob(&t).len();
    let mut buf = vec![0u8; n];
    assert_eq!(encode(&t, &mut buf), Ok(n));
    for short in [0, 5, HEADER_LEN, n - TRAILER_LEN - 1, n - 1] {
        let mut buf = vec![0u8; short];
        assert_eq!(
            encode(&t, &mut buf),
            Err(EncodeError::BufferTooSmall),
            "{short}"
        );
    }
}

#[test]
fn bad_magic() {
    let mut b = blob(&realistic());
    b[0] = b'X';
    assert_eq!(decode(&b), Err(DecodeError::BadMagic));
    let mut b = blob(&realistic());
    b[3] ^= 0x01;
    assert_eq!(decode(&b), Err(DecodeError::BadMagic));
}

#[test]
fn unsupported_version() {
    let mut b = blob(&realistic());
    // Version 1: one safe level per output, not read by this build; version 2: no idle
    // states, no HOME event; version 3: no safety declarations.
    b[4] = 1;
    assert_eq!(decode(&b), Err(DecodeError::UnsupportedVersion(1)));
    b[4] = 2;
    assert_eq!(decode(&b), Err(DecodeError::UnsupportedVersion(2)));
    b[4] = 3;
    assert_eq!(decode(&b), Err(DecodeError::UnsupportedVersion(3)));
    b[4] = 5;
    assert_eq!(decode(&b), Err(DecodeError::UnsupportedVersion(5)));
    b[4] = 0;
    b[5] = 1;
    assert_eq!(decode(&b), Err(DecodeError::UnsupportedVersion(256)));
}

#[test]
fn truncated() {
    let b = blob(&realistic());
    let n = b.len();
    // Shorter than an envelope.
    for len in [0, 1, 15] {
        assert_eq!(
            decode(&b[..len]),
            Err(DecodeError::Truncated { len, need: 16 })
        );
    }
    // Shorter than the envelope says.
    for len in [16, n - 4, n - 1] {
        assert_eq!(
            decode(&b[..len]),
            Err(DecodeError::Truncated { len, need: n })
        );
    }
}

#[test]
fn length_mismatch() {
    let mut b = blob(&realistic());
    let n = b.len();
    b.push(0);
    assert_eq!(
        decode(&b),
        Err(DecodeError::LengthMismatch {
            len: n + 1,
            expected: n
        })
    );
    // The header's length field says one byte less than the blob has.
    let mut b = blob(&realistic());
    let len = u16::from_le_bytes([b[10], b[11]]) - 1;
    b[10..12].copy_from_slice(&len.to_le_bytes());
    assert_eq!(
        decode(&b),
        Err(DecodeError::LengthMismatch {
            len: n,
            expected: n - 1
        })
    );
}

#[test]
fn crc_mismatch() {
    let good = blob(&realistic());
    let n = good.len();
    let stored = u32::from_le_bytes(good[n - 4..].try_into().unwrap());
    // A payload bit, a generation bit, a CRC bit.
    for (at, bit) in [(HEADER_LEN + 3, 0x10), (7, 0x01), (n - 1, 0x80)] {
        let mut b = good.clone();
        b[at] ^= bit;
        let stored_now = u32::from_le_bytes(b[n - 4..].try_into().unwrap());
        let computed = CRC32.checksum(&b[..n - 4]);
        assert_ne!(stored_now, computed);
        assert_eq!(
            decode(&b),
            Err(DecodeError::Crc {
                stored: stored_now,
                computed
            }),
            "byte {at}"
        );
        if at < n - 4 {
            assert_eq!(stored_now, stored);
        }
    }
}

#[test]
fn postcard_errors() {
    let p = payload(&blob(&Table::empty("r")));
    let case = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut q = p.clone();
        f(&mut q);
        decode(&seal(&q, 0))
    };
    use postcard::Error::*;
    // The payload ends early.
    assert_eq!(
        case(&|q| q.truncate(q.len() - 1)),
        Err(DecodeError::Postcard(DeserializeUnexpectedEnd))
    );
    assert_eq!(
        case(&|q| q.clear()),
        Err(DecodeError::Postcard(DeserializeUnexpectedEnd))
    );
    // `start` is an Option: tag 2 is neither None nor Some.
    assert_eq!(
        case(&|q| q[5] = 2),
        Err(DecodeError::Postcard(DeserializeBadOption))
    );
    // The role is not UTF-8.
    assert_eq!(
        case(&|q| q[1] = 0xFF),
        Err(DecodeError::Postcard(DeserializeBadUtf8))
    );
    // pan_id varint that never ends (u16 takes at most 3 bytes).
    assert_eq!(
        case(&|q| {
            q.splice(2..3, [0x80, 0x80, 0x80, 0x01]);
        }),
        Err(DecodeError::Postcard(DeserializeBadVarint))
    );
    // A role longer than its 12-byte capacity.
    assert_eq!(
        case(&|q| {
            q.splice(0..2, std::iter::once(13).chain(*b"ABCDEFGHIJKLM"));
        }),
        Err(DecodeError::Postcard(SerdeDeCustom))
    );
    // 33 variables: over MAX_VARS (32) while decoding.
    assert_eq!(
        case(&|q| {
            q.splice(8..9, std::iter::once(33).chain([0; 33]));
        }),
        Err(DecodeError::Postcard(SerdeDeCustom))
    );
}

#[test]
fn postcard_rejects_an_unknown_action_variant() {
    // One chart with one state whose action is Fault(9); Action::Fault is variant 6.
    let mut t = Table::empty("r");
    t.push_chart(0, 0, &[&[config_schema::Action::Fault(9)]], &[])
        .unwrap();
    let p = payload(&blob(&t));
    let at = p
        .windows(2)
        .position(|w| w == [6, 9])
        .expect("Fault(9) in the payload");
    let mut q = p.clone();
    q[at] = 7;
    assert_eq!(
        decode(&seal(&q, 0)),
        // serde's derived visitor reports an unknown variant index as a custom error.
        Err(DecodeError::Postcard(postcard::Error::SerdeDeCustom))
    );
    assert_eq!(decode(&seal(&p, 0)), Ok(t));
}

#[test]
fn trailing_bytes() {
    let p = payload(&blob(&realistic()));
    let mut q = p.clone();
    q.extend_from_slice(&[0, 0, 0]);
    assert_eq!(decode(&seal(&q, 0)), Err(DecodeError::TrailingBytes(3)));
}

#[test]
fn semantic_errors_come_after_the_envelope_and_payload_checks() {
    let mut t = realistic();
    t.events = 65;
    let b = blob(&t);
    assert_eq!(
        decode(&b),
        Err(DecodeError::Invalid(Invalid::Capacity {
            what: "events",
            count: 65,
            max: 64
        }))
    );
    // The same blob with a bad CRC reports the CRC, not the table.
    let mut b2 = b.clone();
    b2[HEADER_LEN] ^= 1;
    assert!(matches!(decode(&b2), Err(DecodeError::Crc { .. })));
    t.events = 7;
    t.routes[0].chart = 2;
    assert_eq!(
        decode(&blob(&t)),
        Err(DecodeError::Invalid(Invalid::Chart {
            at: Place::Route(0),
            chart: 2
        }))
    );
}

#[test]
fn errors_display_readably() {
    let shown = [
        (
            DecodeError::Truncated { len: 3, need: 16 },
            "truncated blob: 3 bytes, need 16",
        ),
        (DecodeError::BadMagic, "not a table blob (bad magic)"),
        (
            DecodeError::Invalid(Invalid::State {
                at: Place::Transition(4),
                state: 9,
            }),
            "invalid table: transition #4: state 9 does not exist in its chart",
        ),
    ];
    for (e, s) in shown {
        assert_eq!(e.to_string(), s);
    }
}
