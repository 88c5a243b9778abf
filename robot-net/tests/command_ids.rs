//! `push::Ids`: the ids of commands, drawn by runs of the tool at once. Every run sends
//! from the tool's address, and a node answers a (sender, id) it remembers without running
//! it, so no run may draw the id of a command that acts another drew shortly before.
//! Secured, those are the frame counters the runs of a key file share; unsecured, a run
//! counts up from a random start. The ids of asks are apart from them (bit 15 clear).

use std::cell::Cell;
use std::io;
use std::rc::Rc;

use config_schema::wire::msg::Command;
use robot_keys::MachineSecret;
use robot_net::push::Ids;
use robot_net::radio::{CounterSource, ToolRadio, TOOL_ADDR};

/// A counter shared as the runs of one key file share their counter file: every draw
/// above every one before, whichever run drew it.
fn shared_counter(next: &Rc<Cell<u32>>) -> CounterSource {
    let next = Rc::clone(next);
    Box::new(move || {
        let n = next.get();
        next.set(n + 1);
        Ok(n)
    })
}

fn secured(medium: &medium::Medium, counter: CounterSource) -> ToolRadio {
    let mut radio = ToolRadio::connect(medium.addr(), TOOL_ADDR).expect("tool");
    radio.secure(MachineSecret::from_bytes([7; 32]), counter);
    radio
}

#[test]
fn two_secured_runs_draw_the_counters_they_share_as_ids_and_never_the_same() {
    let medium = medium::Medium::start(medium::Config::default()).expect("medium");
    // Across a multiple of 32,768: the counter's low 15 bits wrap.
    let next = Rc::new(Cell::new(0x0002_FFFD));
    let (mut a, mut b) = (
        secured(&medium, shared_counter(&next)),
        secured(&medium, shared_counter(&next)),
    );
    // Two runs' ids start at random: the same start in both is what a collision was.
    let (mut ids_a, mut ids_b) = (Ids::default(), Ids::default());
    let acting = [Command::Start, Command::Home, Command::Reset, Command::Ack];
    let mut drawn = Vec::new();
    for (i, &command) in acting.iter().cycle().take(8).enumerate() {
        let (radio, ids) = if i % 2 == 0 {
            (&mut a, &mut ids_a)
        } else {
            (&mut b, &mut ids_b)
        };
        drawn.push(ids.fresh(radio, command).expect("id"));
    }
    assert_eq!(
        drawn,
        [0xFFFD, 0xFFFE, 0xFFFF, 0x8000, 0x8001, 0x8002, 0x8003, 0x8004]
    );
    assert_eq!(next.get(), 0x0003_0005, "one counter per command that acts");
    medium.stop();
}

#[test]
fn a_command_that_only_asks_spends_no_counter_and_its_id_is_apart() {
    let medium = medium::Medium::start(medium::Config::default()).expect("medium");
    let next = Rc::new(Cell::new(40));
    let mut radio = secured(&medium, shared_counter(&next));
    let mut ids = Ids::default();
    assert_eq!(
        ids.fresh(&mut radio, Command::Start).expect("id"),
        0x8000 | 40
    );
    let asks = [
        Command::Status,
        Command::Alarms,
        Command::Security,
        Command::Identify { nonce: 9 },
    ];
    let ids_of_asks: Vec<u16> = (asks.iter())
        .map(|&c| ids.fresh(&mut radio, c).expect("id"))
        .collect();
    assert_eq!(next.get(), 41, "no counter spent on an ask");
    assert!(
        ids_of_asks.iter().all(|&id| id != 0 && id & 0x8000 == 0),
        "{ids_of_asks:x?}"
    );
    let first = ids_of_asks[0];
    let want: Vec<u16> = (0..4).map(|i| ((first + i) & 0x7FFF).max(1)).collect();
    assert_eq!(ids_of_asks, want, "one after the other");
    assert_eq!(
        ids.fresh(&mut radio, Command::Ack).expect("id"),
        0x8000 | 41
    );
    medium.stop();
}

#[test]
fn a_counter_that_cannot_be_drawn_is_the_commands_error() {
    let medium = medium::Medium::start(medium::Config::default()).expect("medium");
    let mut radio = secured(
        &medium,
        Box::new(|| Err(io::Error::other("counter file: used up"))),
    );
    let mut ids = Ids::default();
    let e = ids
        .fresh(&mut radio, Command::Start)
        .expect_err("no counter");
    assert_eq!(e.to_string(), "counter file: used up");
    assert!(
        ids.fresh(&mut radio, Command::Status).is_ok(),
        "an ask needs none"
    );
    medium.stop();
}

#[test]
fn an_unsecured_run_counts_up_from_where_it_started() {
    let medium = medium::Medium::start(medium::Config::default()).expect("medium");
    let mut radio = ToolRadio::connect(medium.addr(), TOOL_ADDR).expect("tool");
    let mut ids = Ids::default();
    let first = ids.fresh(&mut radio, Command::Start).expect("id");
    assert_eq!(first & 0x8000, 0x8000, "a command that acts: {first:x}");
    let then: Vec<u16> = (0..3)
        .map(|_| ids.fresh(&mut radio, Command::Home).expect("id"))
        .collect();
    let want: Vec<u16> = (1..4).map(|i| 0x8000 | first.wrapping_add(i)).collect();
    assert_eq!(then, want);
    medium.stop();
}
