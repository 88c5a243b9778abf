//! The blob envelope: round trip, exact layout, and every `DecodeError` from a precise
//! mutation.

mod common;

use common::{blob, payload, realistic, seal};
use config_schema::blob::{envelope, Envelope, CRC32, HEADER_LEN, MAGIC, TRAILER_LEN};
use config_schema::pack::PackError;
use config_schema::{
    decode, encode, DecodeError, EncodeError, Invalid, Level, Op, Output, Place, Table,
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
    assert_eq!(HEADER_LEN + TRAILER_LEN, 12);
    assert_eq!(b[0], 0xEC);
    assert_eq!(MAGIC, [0xEC]);
    assert_eq!(b[1], 7, "schema version 7");
    assert_eq!(
        &b[2..6],
        &[0x04, 0x03, 0x02, 0x01],
        "generation, little-endian"
    );
    assert_eq!(usize::from(u16::from_le_bytes([b[6], b[7]])), n);
    let crc = CRC32.checksum(&b[..HEADER_LEN + n]);
    assert_eq!(&b[HEADER_LEN + n..], &crc.to_le_bytes());
    assert_eq!(
        envelope(&b),
        Ok(Envelope {
            version: 7,
            generation: 0x0102_0304,
            payload_len: n,
            crc,
        })
    );
    // The CRC is CRC-32/ISO-HDLC (the zlib / Ethernet CRC).
    assert_eq!(CRC32.checksum(b"123456789"), 0xCBF4_3926);
}

/// Fields `(value, width)` packed least significant bit first, the last byte padded with
/// zero bits: what `config_schema::pack` writes.
fn bits(fields: &[(u32, u32)]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut at = 0usize;
    for &(value, width) in fields {
        assert!(
            width == 32 || value >> width == 0,
            "{value} in {width} bits"
        );
        for i in 0..width {
            if at.is_multiple_of(8) {
                out.push(0);
            }
            if (value >> i) & 1 != 0 {
                *out.last_mut().unwrap() |= 1 << (at % 8);
            }
            at += 1;
        }
    }
    out
}

/// Fields of an empty table for role "r" after the role (`Table::empty`): every count
/// zero, as one-bit gamma codes.
#[rustfmt::skip]
const EMPTY_REST: [(u32, u32); 21] = [
    (1, 1),          // events: gamma(0)
    (1, 1),          // vars: none
    (0, 3),          // pin width 0
    (1, 1),          // inputs: none
    (1, 1),          // outputs: none
    (1, 1), (1, 1),  // timers, durations: none
    (1, 1),          // code: none
    (1, 1),          // charts: none
    (0, 3), (0, 1),  // width of the states' action counts: 0; no common count
    (1, 1),          // routes: one per chart input (there is none)
    (0, 2), (0, 2), (0, 2), // start, home, boot: not fresh, None
    (1, 1), (0, 5),  // peers: none, address width 0
    (0, 3), (1, 1),  // topic width 0, publications: none
    (1, 1),          // subscriptions: none
    (1, 1),          // safety: none declared
];

#[test]
fn the_payload_of_an_empty_table_bit_by_bit() {
    let t = Table::empty("r");
    let p = payload(&blob(&t));
    #[rustfmt::skip]
    let mut fields = vec![
        (0, 1),                       // the compact form
        (1, 4), (u32::from(b'r'), 8), // role: length, bytes
        (0, 16),                      // pan_id
        (0, 5),                       // channel 11 (11 + 0)
    ];
    fields.extend_from_slice(&EMPTY_REST);
    let want = bits(&fields);
    assert_eq!(p, want);
    assert_eq!(p, [0x42, 0x0E, 0x00, 0x00, 0x8C, 0x1F, 0x02, 0x01, 0x0E]);
    assert_eq!(decode(&seal(&want, 9)).map(|t| t.generation), Ok(9));
}

/// An output is its pin (as wide as the table's largest pin needs), its fault and start
/// levels (`Low` 0, `High` 1, `Hold` 2, two bits) and its home level (a bit).
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
    let outputs = |fault_of_first: u32| {
        #[rustfmt::skip]
        let fields = vec![
            (0, 1), (1, 4), (u32::from(b'r'), 8), (0, 16), (0, 5), // form, role, pan, channel
            (1, 1), (1, 1),      // events, vars
            (4, 3),              // pin width 4 (pins up to 10)
            (1, 1),              // inputs: none
            (0b110, 3),          // outputs: gamma(2): 0, 1, then 1
            // pin 9, not both levels low: Hold, Low; home low
            (9, 4), (0, 1), (fault_of_first, 2), (0, 2), (0, 1),
            (10, 4), (0, 1), (1, 2), (1, 2), (1, 1), // pin 10, High, High, high
        ];
        let mut fields = fields;
        fields.extend_from_slice(&EMPTY_REST[5..]);
        bits(&fields)
    };
    let want = outputs(2);
    assert_eq!(p, want);
    assert_eq!(decode(&seal(&want, 0)), Ok(t));
    // A level past `Hold` is not a level.
    assert_eq!(
        decode(&seal(&outputs(3), 1)),
        Err(DecodeError::Payload(PackError::Value("level")))
    );
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
    b[0] ^= 0x01;
    assert_eq!(decode(&b), Err(DecodeError::BadMagic));
}

#[test]
fn unsupported_version() {
    let mut b = blob(&realistic());
    // Version 1: one safe level per output, not read by this build; version 2: no idle
    // states, no HOME event; version 3: no safety declarations; version 4: postcard.
    b[1] = 1;
    assert_eq!(decode(&b), Err(DecodeError::UnsupportedVersion(1)));
    b[1] = 2;
    assert_eq!(decode(&b), Err(DecodeError::UnsupportedVersion(2)));
    b[1] = 3;
    assert_eq!(decode(&b), Err(DecodeError::UnsupportedVersion(3)));
    // Version 4: postcard in a 16-byte envelope (its version sat at bytes 4..6).
    b[1] = 4;
    assert_eq!(decode(&b), Err(DecodeError::UnsupportedVersion(4)));
    // Version 5: the first packed payload, without its implicit shapes.
    b[1] = 5;
    assert_eq!(decode(&b), Err(DecodeError::UnsupportedVersion(5)));
    // Version 6: no resting states besides the idle one.
    b[1] = 6;
    assert_eq!(decode(&b), Err(DecodeError::UnsupportedVersion(6)));
    b[1] = 8;
    assert_eq!(decode(&b), Err(DecodeError::UnsupportedVersion(8)));
}

#[test]
fn truncated() {
    let b = blob(&realistic());
    let n = b.len();
    // Shorter than an envelope.
    for len in [0, 1, 11] {
        assert_eq!(
            decode(&b[..len]),
            Err(DecodeError::Truncated { len, need: 12 })
        );
    }
    // Shorter than the envelope says.
    for len in [12, n - 4, n - 1] {
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
    let len = u16::from_le_bytes([b[6], b[7]]) - 1;
    b[6..8].copy_from_slice(&len.to_le_bytes());
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
    for (at, bit) in [(HEADER_LEN + 3, 0x10), (3, 0x01), (n - 1, 0x80)] {
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
fn payload_errors() {
    let p = payload(&blob(&Table::empty("r")));
    let case = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut q = p.clone();
        f(&mut q);
        decode(&seal(&q, 0))
    };
    let payload_error = |e| Err(DecodeError::Payload(e));
    // The wide form (bit 0 set) reads the same bits otherwise: here the channel is 8 bits
    // wide and the stream ends early.
    assert_eq!(case(&|q| q[0] |= 1), payload_error(PackError::End));
    // The payload ends early.
    assert_eq!(
        case(&|q| q.truncate(q.len() - 1)),
        payload_error(PackError::End)
    );
    assert_eq!(case(&|q| q.clear()), payload_error(PackError::End));
    // The role is not UTF-8: its byte is bits 5..13.
    assert_eq!(
        case(&|q| {
            q[0] |= 0xE0;
            q[1] |= 0x1F;
        }),
        payload_error(PackError::Utf8)
    );
    // A role longer than its 12-byte capacity (the length field is bits 1..5).
    assert_eq!(
        case(&|q| q[0] = (q[0] & 0xE1) | (13 << 1)),
        payload_error(PackError::Capacity("role"))
    );
    // A padding bit set (the payload is 66 bits: bit 2 of the last byte on are padding).
    assert_eq!(
        case(&|q| *q.last_mut().unwrap() |= 0x80),
        payload_error(PackError::Value("padding"))
    );
    // 33 variables: over MAX_VARS (32) while decoding. The count is bit 35 (after the
    // form, role, pan and channel, and the events' gamma code); gamma(33) is 00000100010.
    let mut fields = vec![
        (0, 1),
        (1, 4),
        (u32::from(b'r'), 8),
        (0, 16),
        (0, 5),
        (1, 1),
    ];
    fields.extend([(0, 5), (1, 1), (0b00010, 5)]);
    fields.extend([(1, 1); 33]);
    let mut q = bits(&fields);
    q.extend_from_slice(&[0; 8]);
    assert_eq!(
        decode(&seal(&q, 0)),
        payload_error(PackError::Capacity("vars"))
    );
}

#[test]
fn an_unknown_operation_is_refused() {
    // One expression of one operation: `Const(0)` is code 0; 18 and over are no
    // operation.
    let mut t = Table::empty("r");
    t.push_expr(&[Op::Const(0)]).unwrap();
    t.safety
        .alarms
        .push(config_schema::alarm::AlarmDecl {
            level: config_schema::alarm::AlarmLevel::Info,
            when: config_schema::Expr { start: 0, len: 1 },
        })
        .unwrap();
    let p = payload(&blob(&t));
    assert_eq!(decode(&seal(&p, 0)), Ok(t));
    // The code pool's count (gamma(1): 0, 1, 0) is at bit 43, its operation at bit 46.
    let code_at = 1 + 33 + 1 + 1 + 3 + 1 + 1 + 1 + 1;
    let get = |q: &[u8], at: usize| (q[at / 8] >> (at % 8)) & 1;
    assert_eq!(
        (0..3).map(|i| get(&p, code_at + i)).collect::<Vec<_>>(),
        [0, 1, 0]
    );
    let mut q = p.clone();
    // 18 = 0b10010, least significant bit first.
    for (i, b) in [0, 1, 0, 0, 1].into_iter().enumerate() {
        let at = code_at + 3 + i;
        q[at / 8] = (q[at / 8] & !(1 << (at % 8))) | (b << (at % 8));
    }
    assert_eq!(
        decode(&seal(&q, 0)),
        Err(DecodeError::Payload(PackError::Value("operation")))
    );
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
    // A reference past its count does not fit the compact form: the table goes in the
    // wide form, and the validator names the problem.
    t.routes[0].chart = 2;
    assert!(!config_schema::pack::is_compact(&t));
    assert_eq!(payload(&blob(&t))[0] & 1, 1, "the wide form");
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
            DecodeError::Truncated { len: 3, need: 12 },
            "truncated blob: 3 bytes, need 12",
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

/// Tables the compact form cannot hold (invalid ones) take the wide form and come back
/// exactly, so `decode` hands the validator the table that was encoded.
#[test]
fn the_wide_form_holds_any_table() {
    use config_schema::pack;
    let mutations: [&dyn Fn(&mut Table); 10] = [
        &|t| t.routes[0].chart = 2,
        // The largest chart input a `u8` holds: no chart has an input past it.
        &|t| t.transitions[0].trigger = Some(255),
        &|t| t.routes[0].input = 255,
        &|t| t.header.channel = 200,
        &|t| t.inputs[0].pin = 200,
        &|t| t.charts[0].states_end = 9,
        &|t| t.states[0].actions_end = 200,
        &|t| t.transitions[0].guard = Some(config_schema::Expr { start: 250, len: 0 }),
        &|t| {
            t.actions[0] = config_schema::Action::Drive {
                mask: 0xFFFF,
                value: 0x8001,
            }
        },
        &|t| t.code[0] = Op::Var(200),
    ];
    for (i, mutate) in mutations.iter().enumerate() {
        let mut t = realistic();
        mutate(&mut t);
        assert!(!pack::is_compact(&t), "mutation {i}");
        let p = payload(&blob(&t));
        assert_eq!(p[0] & 1, 1, "mutation {i}: the wide form");
        let (back, left) = pack::decode(&p).expect("decodes");
        assert_eq!(left, 0);
        t.generation = 0;
        assert_eq!(back, t, "mutation {i}");
    }
    // A valid table takes the compact form.
    assert!(pack::is_compact(&realistic()));
}

/// The wide form is not only for invalid tables: a state of more than 127 actions is over
/// the compact form's 3-bit count width, and such a table may be valid. So the node reads
/// the wide form too (refusing it would refuse a table the tool accepts).
#[test]
fn a_valid_table_may_need_the_wide_form() {
    use config_schema::{pack, validate, Action};
    let on = [Action::Drive { mask: 1, value: 1 }; 128];
    let t = test_tables::lamp_with(3, &on);
    assert_eq!(validate(&t), Ok(()));
    assert!(!pack::is_compact(&t));
    let b = blob(&t);
    assert_eq!(payload(&b)[0] & 1, 1, "the wide form");
    assert_eq!(decode(&b), Ok(t));
}

/// Every byte of a table's serde form set to each edge value (and each bit of it flipped),
/// deterministically (`test_tables::edge_sweep`): whatever table that makes, its blob
/// decodes to it exactly or the validator refuses it; the parser never refuses a blob the
/// encoder wrote. (The random field mutations of `props.rs` found a trigger of 255 that
/// did; this sweeps the class. robot-tests sweeps every compiled robot's roles.)
#[test]
fn any_one_field_at_an_edge_value_decodes_exactly_or_is_refused_by_the_validator() {
    for t in [realistic(), test_tables::lamp_table(3)] {
        let sweep = test_tables::edge_sweep(&t);
        // The sweep reaches both outcomes.
        assert!(sweep.exact > 50 && sweep.refused > 50, "{sweep:?}");
    }
}

/// A chart that rests in other states besides its idle one (schema 7) writes `idle is 0`
/// false, then the idle state 0 (which no other chart writes), its idle state and a bit
/// per state: 3 states take 1 + 2 + 2 + 3 bits where the flag alone was. A chart without
/// them costs what it did in schema 6.
#[test]
fn a_chart_with_resting_states_writes_them_after_an_idle_state_of_0() {
    use config_schema::pack::{self, SECTIONS};
    let bits_of = |t: &Table| {
        let mut marks = [0usize; SECTIONS.len()];
        let mut buf = [0u8; 256];
        pack::encode(t, &mut buf, Some(&mut marks)).unwrap();
        marks[SECTIONS.len() - 1]
    };
    let mut t = Table::empty("r");
    t.push_chart(0, 0, &[&[], &[], &[]], &[]).unwrap();
    let plain = bits_of(&t);
    t.charts[0].rests = 0b100;
    assert_eq!(bits_of(&t), plain + 7);
    assert_eq!(decode(&blob(&t)), Ok(t.clone()));
    // Idle elsewhere, resting in 0 and 2.
    t.charts[0].idle = 1;
    t.charts[0].rests = 0b101;
    assert_eq!(decode(&blob(&t)), Ok(t.clone()));
    // One state: the flag false and no bits of state, then the mask's one bit.
    let mut one = Table::empty("r");
    one.push_chart(0, 0, &[&[]], &[]).unwrap();
    let plain = bits_of(&one);
    one.charts[0].rests = 1;
    assert_eq!(bits_of(&one), plain + 1);
    assert_eq!(decode(&blob(&one)), Ok(one));
}
