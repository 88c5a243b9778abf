//! The implicit shapes of the packed payload (docs/table-format.md, "Payload"): each is
//! read back into the same `Table` as written, takes the bits the format gives it, and a
//! table not of the shape takes the explicit form and still round-trips.

use config_schema::pack::{self, PackError, SECTIONS};
use config_schema::{Action, Level, Output, Subscription, Table, Transition};
use test_tables::route;

/// Bits of each section of `t`'s compact payload.
fn sections(t: &Table) -> Vec<usize> {
    let mut marks = [0usize; SECTIONS.len()];
    let mut buf = [0u8; 4096];
    pack::encode_form(t, &mut buf, Some(&mut marks), false).expect("compact");
    (0..SECTIONS.len())
        .map(|i| marks[i] - i.checked_sub(1).map_or(0, |p| marks[p]))
        .collect()
}

fn section(t: &Table, name: &str) -> usize {
    let i = SECTIONS.iter().position(|s| *s == name).expect("a section");
    sections(t)[i]
}

/// Encodes and decodes `t`'s payload.
fn round_trip(t: &Table) -> Table {
    let mut buf = [0u8; 4096];
    let n = pack::encode(t, &mut buf, None).expect("encodes");
    let (back, left) = pack::decode(&buf[..n]).expect("decodes");
    assert_eq!(left, 0);
    back
}

fn step(from: u8, to: u8, trigger: Option<u8>) -> Transition {
    Transition {
        from,
        to,
        trigger,
        guard: None,
    }
}

/// Two charts: a ring of three states on inputs 0, 1, 0 (chart 0, two inputs) and one
/// state on input 0 (chart 1); five events, routed one per chart input.
fn two_charts() -> Table {
    let mut t = Table::empty("r");
    for _ in 0..5 {
        t.push_event().unwrap();
    }
    let emit = [Action::Emit(4)];
    t.push_chart(
        0,
        2,
        &[&[], &emit, &[]],
        &[
            step(0, 1, Some(0)),
            step(1, 2, Some(1)),
            step(2, 0, Some(0)),
        ],
    )
    .unwrap();
    t.push_chart(0, 1, &[&[], &[]], &[step(0, 1, Some(0))])
        .unwrap();
    for (event, chart, input) in [(0, 0, 0), (1, 0, 1), (2, 1, 0)] {
        route(&mut t, event, chart, input);
    }
    t
}

#[test]
fn routes_one_per_chart_input_are_their_events_only() {
    let t = two_charts();
    assert_eq!(round_trip(&t), t);
    // The shape's flag, then three fresh events (0, 1 and 2: none named before).
    assert_eq!(section(&t, "routes"), 1 + 3);
    // Swapped, the first two are no longer in chart input order: a count, then each
    // route's event, chart and input.
    let mut swapped = t.clone();
    swapped.routes.swap(0, 1);
    assert_eq!(round_trip(&swapped), swapped);
    assert!(section(&swapped, "routes") > 1 + 3 + 3);
    // A chart input without a route is not the shape either.
    let mut short = t.clone();
    short.routes.pop();
    assert_eq!(round_trip(&short), short);
}

#[test]
fn chart_inputs_follow_from_the_triggers_their_transitions_use() {
    let t = two_charts();
    let back = round_trip(&t);
    assert_eq!(back.charts[0].inputs, 2);
    assert_eq!(back.charts[1].inputs, 1);
    // An input no transition triggers on: its count is written.
    let mut unused = t.clone();
    unused.charts[1].inputs = 3;
    assert_eq!(round_trip(&unused), unused);
    assert!(section(&unused, "charts") > section(&t, "charts"));
    // An input used before the one after the last: its count is written too.
    let mut skipping = t.clone();
    skipping.transitions[0].trigger = Some(1);
    skipping.transitions[1].trigger = Some(0);
    assert_eq!(round_trip(&skipping), skipping);
}

#[test]
fn a_trigger_of_an_implicit_chart_must_be_an_input_used_before() {
    let t = two_charts();
    let mut buf = [0u8; 4096];
    let n = pack::encode(&t, &mut buf, None).unwrap();
    let marks = {
        let mut m = [0usize; SECTIONS.len()];
        pack::encode_form(&t, &mut [0u8; 4096], Some(&mut m), false).unwrap();
        m
    };
    // Chart 0's transitions: the guarded flag, two chain steps, then S2 -> S0 on input 0
    // (used before): not a step, from the previous state, not to the next and its state
    // (2 bits), not fresh, then `opt` of the two inputs used so far (2 bits: 1 is input
    // 0). Set to 3, input 2, one no transition used before: refused.
    let transitions = marks[SECTIONS.iter().position(|s| *s == "transitions").unwrap() - 1];
    let trigger = transitions + 1 + 2 + (1 + 1 + 1 + 2 + 1);
    let mut bad = buf[..n].to_vec();
    for i in 0..2 {
        let bit = trigger + i;
        bad[bit / 8] |= 1 << (bit % 8);
    }
    assert_eq!(
        pack::decode(&bad).map(|_| ()),
        Err(PackError::Value("trigger"))
    );
}

#[test]
fn a_chain_step_is_one_bit() {
    let t = two_charts();
    // Chart 0: the guarded flag, two chain steps (a bit each), then S2 -> S0 on input 0
    // (a bit, from the previous: a bit, not to the next: a bit and 2, not fresh: a bit and
    // 2); chart 1: the guarded flag, a chain step.
    assert_eq!(
        section(&t, "transitions"),
        (1 + 2 + (1 + 1 + 3 + 3)) + (1 + 1)
    );
}

#[test]
fn no_safety_declared_is_one_bit_and_low_levels_one_bit_an_output() {
    let mut t = two_charts();
    assert_eq!(section(&t, "safety"), 1);
    t.outputs.push(Output::safe(0, false)).unwrap();
    t.outputs
        .push(Output {
            pin: 1,
            fault: Level::Hold,
            start: Level::Low,
            home: true,
        })
        .unwrap();
    assert_eq!(round_trip(&t), t);
    // A count of 2 (3 bits); pin, a bit (both low) or a bit and 4, home.
    assert_eq!(section(&t, "outputs"), 3 + (1 + 1 + 1) + (1 + 1 + 4 + 1));
    t.safety.link_fault = true;
    assert_eq!(round_trip(&t), t);
}

#[test]
fn a_subscription_raises_the_next_event_nothing_on_the_node_raises() {
    let mut t = two_charts();
    t.peers.push(0x0011).unwrap();
    t.peers.push(0x0012).unwrap();
    for (publisher, topic, event) in [(0, 0, 0), (1, 0, 0), (1, 1, 1), (0, 1, 3)] {
        t.subscriptions
            .push(Subscription {
                publisher,
                topic,
                event,
            })
            .unwrap();
    }
    assert_eq!(round_trip(&t), t);
    // A count of 4 (5 bits); each: publisher (a bit), topic (a bit), then the same event
    // (a bit), or not and the next (2 bits), or neither and its id (2 + 3 bits): 0 (the
    // first event nothing on the node raises), 0 again, 1, then 3 (the next is 2).
    assert_eq!(
        section(&t, "subscriptions"),
        5 + (2 + 2) + (2 + 1) + (2 + 2) + (2 + 5)
    );
}

#[test]
fn peers_at_consecutive_addresses_are_a_bit_each() {
    let mut t = two_charts();
    for p in [0x0011, 0x0012, 0x0013, 0x0020] {
        t.peers.push(p).unwrap();
    }
    assert_eq!(round_trip(&t), t);
    // A count of 4 (5 bits), the address width (5 bits, 6 wide), the first (a bit and 6),
    // two next ones (a bit each), the last (a bit and 6).
    assert_eq!(section(&t, "peers"), 5 + 5 + 7 + 1 + 1 + 7);
}
