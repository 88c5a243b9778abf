//! A table payload as a node receives it (`pack::decode`, then `validate`), whatever the
//! bytes: never a panic; a payload that validates encodes back to a payload that decodes
//! to the same table (round trip), and the engine runs it through any stimuli (the bytes
//! after the table) to a stable state, without a panic (libFuzzer's timeout catches a
//! stimulus that does not end).
#![no_main]

use config_schema::{blob, pack, validate, Table};
use libfuzzer_sys::fuzz_target;
use node_fw::ecc::Engine;

fuzz_target!(|data: &[u8]| {
    // The envelope's checks (version, length, CRC) on the same bytes.
    let _ = blob::decode(data);
    let Ok((table, rest)) = pack::decode(data) else {
        return;
    };
    if validate(&table).is_err() {
        return;
    }
    round_trip(&table);
    let stimuli = data.get(data.len().saturating_sub(rest)..).unwrap_or(&[]);
    run(&table, stimuli);
});

fn round_trip(table: &Table) {
    let mut buf = [0u8; 4096];
    let n = pack::encode(table, &mut buf, None).expect("a valid table encodes");
    let (again, rest) = pack::decode(&buf[..n]).expect("its encoding decodes");
    assert_eq!(rest, 0);
    assert_eq!(&again, table, "decode(encode(t)) == t");
}

/// Each byte a stimulus: its top two bits the kind (an input edge, a subscribed remote
/// event, a timer, a command), the rest which one.
fn run(table: &Table, stimuli: &[u8]) {
    let mut e = Engine::new(table);
    e.reset(&mut ());
    e.boot(&mut ());
    for &b in stimuli {
        let which = usize::from(b & 0x3F);
        match b >> 6 {
            0 => {
                e.input((which & 0x1F) as u8, which & 0x20 != 0, &mut ());
            }
            1 => {
                if let Some(s) = table
                    .subscriptions
                    .get(which % table.subscriptions.len().max(1))
                {
                    e.remote(s.publisher, s.topic, &mut ());
                }
            }
            2 => e.timer_expired(which as u8, &mut ()),
            _ => match which % 4 {
                0 => {
                    e.start(&mut ());
                }
                1 => {
                    e.home(&mut ());
                }
                2 => e.reset(&mut ()),
                _ => e.fail(which as u8, &mut ()),
            },
        }
    }
}
