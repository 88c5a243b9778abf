//! Table builders and blob helpers shared by the tests of the workspace's crates (a
//! dev-dependency only): a table's blob, a table as a node loads it, a hand-sealed envelope,
//! and the small "lamp" role the node and runtime tests push. With feature `robots`:
//! `robots`, the robots of `robot-configs/` compiled and exported.

#[cfg(feature = "robots")]
pub mod robots;

use config_schema::blob::{CRC32, HEADER_LEN, TRAILER_LEN};
use config_schema::limits::MAX_BLOB;
use config_schema::{
    decode, encode, validate, Action, DecodeError, EventId, Input, Output, Route, Table, Transition,
};

/// The blob of a (valid) table.
pub fn blob(t: &Table) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_BLOB];
    let n = encode(t, &mut buf).unwrap();
    buf.truncate(n);
    buf
}

/// Validates, encodes and decodes the table (checked equal): what a node would run.
pub fn load(t: Table) -> Table {
    validate(&t).unwrap();
    let back = decode(&blob(&t)).unwrap();
    assert_eq!(back, t, "{} round trip", t.header.role);
    back
}

/// A table the interpreter may run though `validate` refuses it for its time bound
/// (`config_schema::cost`): its structure checked, no round trip (`decode` would refuse it).
pub fn load_untimed(t: Table) -> Table {
    config_schema::validate_structure(&t).unwrap();
    t
}

/// The payload of a blob (no envelope).
pub fn payload(blob: &[u8]) -> Vec<u8> {
    blob[HEADER_LEN..blob.len() - TRAILER_LEN].to_vec()
}

/// A blob around `payload` with a correct envelope (magic, this build's schema version, `generation`, length,
/// CRC recomputed), so decoding reaches the payload parser and the validator.
pub fn seal(payload: &[u8], generation: u32) -> Vec<u8> {
    let mut b = Vec::with_capacity(payload.len() + HEADER_LEN + TRAILER_LEN);
    b.extend_from_slice(&config_schema::blob::MAGIC);
    b.push(config_schema::SCHEMA_VERSION as u8);
    b.extend_from_slice(&generation.to_le_bytes());
    b.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    b.extend_from_slice(payload);
    let crc = CRC32.checksum(&b);
    b.extend_from_slice(&crc.to_le_bytes());
    b
}

/// What [`edge_sweep`] saw: tables whose blob decoded to them exactly, tables the
/// validator refused.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Sweep {
    pub exact: usize,
    pub refused: usize,
}

/// Every byte of `t`'s serde form set to each edge value (and each of its bits flipped),
/// one at a time: whatever table that makes and `encode` writes must decode to itself
/// exactly or be refused by the validator. Panics, naming the byte, if the parser refuses
/// a blob the encoder wrote or a table comes back changed.
pub fn edge_sweep(t: &Table) -> Sweep {
    let mut sweep = Sweep::default();
    let mut buf = vec![0u8; 8 * MAX_BLOB];
    let form = postcard::to_slice(t, &mut buf)
        .expect("the form fits")
        .to_vec();
    for at in 0..form.len() {
        let sets = [0u8, 1, 2, 7, 8, 15, 16, 127, 128, 254, 255].map(|v| (v, None));
        let flips = (0..8).map(|bit| (form[at] ^ (1 << bit), Some(bit)));
        for (value, bit) in sets.into_iter().chain(flips) {
            let mut bytes = form.clone();
            bytes[at] = value;
            let Ok((mut mutated, _)) = postcard::take_from_bytes::<Table>(&bytes) else {
                continue;
            };
            mutated.generation = t.generation;
            let Ok(n) = encode(&mutated, &mut buf) else {
                continue;
            };
            let role = &t.header.role;
            match decode(&buf[..n]) {
                Ok(back) => {
                    assert_eq!(back, mutated, "{role}: byte {at} = {value} (flip {bit:?})");
                    sweep.exact += 1;
                }
                Err(DecodeError::Invalid(_)) => sweep.refused += 1,
                Err(e) => panic!("{role}: byte {at} = {value} (flip {bit:?}): {e:?}"),
            }
        }
    }
    sweep
}

/// Routes `event` to input `input` of chart `chart`.
pub fn route(t: &mut Table, event: EventId, chart: u8, input: u8) {
    t.routes
        .push(Route {
            event,
            chart,
            input,
        })
        .unwrap();
}

/// The PAN of [`lamp_table`].
pub const PAN: u16 = 0x4242;
/// The button and lamp pins of [`lamp_table`].
pub const BUTTON: u8 = 5;
pub const LAMP: u8 = 7;
/// An output whose safe level is high.
pub const BEACON: u8 = 8;

/// "lamp" (on [`PAN`]): every rise of the button (pin [`BUTTON`]) toggles the lamp (pin
/// [`LAMP`]); the beacon's (pin [`BEACON`]) safe level is high.
pub fn lamp_table(generation: u32) -> Table {
    lamp_with(generation, &[Action::Drive { mask: 1, value: 1 }])
}

/// The lamp table whose "on" state runs `on`.
pub fn lamp_with(generation: u32, on: &[Action]) -> Table {
    let mut t = Table::empty("lamp");
    t.generation = generation;
    t.header.pan_id = PAN;
    let press = button(&mut t, BUTTON);
    for (pin, safe) in [(LAMP, false), (BEACON, true)] {
        t.outputs.push(Output::safe(pin, safe)).unwrap();
    }
    toggle(&mut t, press, on);
    t
}

/// A new event, raised by every rise of a new input on pin `pin` (no mirror variable).
pub fn button(t: &mut Table, pin: u8) -> EventId {
    let press = t.push_event().unwrap();
    t.inputs
        .push(Input {
            pin,
            rise: Some(press),
            fall: None,
            var: None,
        })
        .unwrap();
    press
}

/// Chart 0 (its input 0 routed from `event`): every `event` toggles between off (output 0
/// low) and on (runs `on`).
pub fn toggle(t: &mut Table, event: EventId, on: &[Action]) {
    let off: &[Action] = &[Action::Drive { mask: 1, value: 0 }];
    let tr = |from, to| Transition {
        from,
        to,
        trigger: Some(0),
        guard: None,
    };
    t.push_chart(0, 1, &[off, on], &[tr(0, 1), tr(1, 0)])
        .unwrap();
    route(t, event, 0, 0);
}

/// The key of `from`'s frames to `to` in the tests' link keys (one per ordered pair; what
/// the tool would derive from the machine's secret).
pub fn pair_key(from: u16, to: u16) -> [u8; 16] {
    [(from as u8) << 4 | to as u8; 16]
}

/// Link keys of `generation` for `node` and its `peers`, each direction's key
/// [`pair_key`].
pub fn link_keys(node: u16, peers: &[u16], generation: u32) -> config_schema::link_keys::LinkKeys {
    use config_schema::link_keys::{LinkKeys, PeerKeys};
    let mut k = LinkKeys {
        generation,
        peers: Default::default(),
    };
    for &peer in peers {
        k.peers
            .push(PeerKeys {
                peer,
                send: pair_key(node, peer),
                receive: pair_key(peer, node),
            })
            .unwrap();
    }
    k
}
