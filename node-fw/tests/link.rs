//! Reliable event delivery over a lossy, duplicating, reordering channel: every event arrives
//! exactly once and in publisher order, or the link stalls with an alarm; never out of turn.

use config_schema::wire::msg::Message;
use node_fw::link::{LinkState, Receiver, Sender, ALARM_AFTER, ASK_MS, QUEUE, WINDOW};
use proptest::prelude::*;

mod support;
use support::{Channel, Rng};

struct Run {
    delivered: Vec<u8>,
    sender: Sender,
    receiver: Receiver,
    frames: usize,
    end: u64,
}

/// Publishes `topics` (one every `gap` ms: a machine publishes a few events a second, so
/// the queue does not fill; overflow has its own test) across the channel pair and runs until
/// every event is acknowledged or `limit` ms pass.
fn run(topics: &[u8], gap: u64, loss: f64, dup: f64, seed: u64, limit: u64) -> Run {
    run_on((1, 12), topics, gap, loss, dup, seed, limit)
}

/// [`run`] over channels whose frames take `delay` ms (a range) each way.
fn run_on(
    delay: (u64, u64),
    topics: &[u8],
    gap: u64,
    loss: f64,
    dup: f64,
    seed: u64,
    limit: u64,
) -> Run {
    let mut rng = Rng::new(seed);
    let mut forward = Channel::new(loss, dup, delay);
    let mut back = Channel::new(loss, dup, delay);
    let mut sender = Sender::new(7);
    let mut receiver = Receiver::new();
    let mut delivered = Vec::new();
    let mut now = 0;
    let mut next_topic = 0;
    while now < limit {
        if next_topic < topics.len() && now >= next_topic as u64 * gap {
            let mut out = Vec::new();
            if sender
                .push(topics[next_topic], now, |m| out.push(m))
                .is_err()
            {
                panic!(
                    "queue overflow at {now} ms, seed {seed}: {:?}",
                    sender.counters()
                );
            }
            for m in out {
                forward.send(&mut rng, now, m);
            }
            next_topic += 1;
        }
        for msg in forward.due(now) {
            let Message::Event { epoch, seq, topic } = msg else {
                panic!("not an event: {msg:?}")
            };
            let got = receiver.on_event(epoch, seq, topic);
            delivered.extend(got.deliver.iter().copied());
            if let Some(ack) = got.ack {
                back.send(&mut rng, now, ack);
            }
        }
        for msg in back.due(now) {
            let Message::EventAck { epoch, next } = msg else {
                panic!("not an ack: {msg:?}")
            };
            let mut out = Vec::new();
            sender.on_ack(epoch, next, now, |m| out.push(m));
            for m in out {
                forward.send(&mut rng, now, m);
            }
        }
        let mut out = Vec::new();
        sender.poll(now, |m| out.push(m));
        for m in out {
            forward.send(&mut rng, now, m);
        }
        if next_topic == topics.len() && sender.unacked() == 0 {
            break;
        }
        now += 1;
    }
    Run {
        delivered,
        sender,
        receiver,
        frames: forward.sent + back.sent,
        end: now,
    }
}

#[test]
fn a_clean_channel_delivers_in_order_with_one_frame_each_way() {
    let topics: Vec<u8> = (0..50).collect();
    let r = run(&topics, 20, 0.0, 0.0, 1, 10_000);
    assert_eq!(r.delivered, topics);
    assert_eq!(r.sender.unacked(), 0);
    assert_eq!(r.sender.counters().retried, 0);
    assert_eq!(r.frames, 100);
    assert_eq!(r.sender.state(), LinkState::Ok);
}

/// A flood the link can carry does not break it: 5,000 events, one a millisecond, over a
/// channel of 1 ms each way (a round trip of 2 ms, so at most a window in flight).
#[test]
fn a_flood_the_link_keeps_up_with_never_breaks_it() {
    let topics: Vec<u8> = (0..5_000u32).map(|i| (i % 251) as u8).collect();
    let r = run_on((1, 1), &topics, 1, 0.0, 0.0, 5, 20_000);
    assert_eq!(r.delivered, topics);
    assert_eq!(r.sender.state(), LinkState::Ok);
    assert_eq!(r.sender.counters().retried, 0);
    assert_eq!(r.frames, 2 * topics.len());
}

#[test]
fn twenty_percent_loss_with_duplication_and_reordering_delivers_exactly_once_in_order() {
    let topics: Vec<u8> = (0..200).map(|i| (i % 251) as u8).collect();
    for seed in 1..=20 {
        let r = run(&topics, 40, 0.2, 0.1, seed, 60_000);
        assert_eq!(r.delivered, topics, "seed {seed}");
        assert_eq!(r.sender.unacked(), 0, "seed {seed}");
        assert!(
            r.sender.counters().retried > 0,
            "seed {seed}: loss forced retries"
        );
    }
}

#[test]
fn a_silent_peer_raises_the_alarm_and_nothing_is_delivered() {
    let r = run(&[1, 2, 3], 1, 1.0, 0.0, 3, 5_000);
    assert!(r.delivered.is_empty());
    assert_eq!(r.sender.state(), LinkState::Alarm);
    assert_eq!(r.sender.unacked(), 3);
    assert!(r.end >= 5_000 - 1);
}

#[test]
fn the_alarm_needs_alarm_after_timeouts_and_clears_on_progress() {
    let mut s = Sender::new(1);
    let mut sent = Vec::new();
    s.push(9, 0, |m| sent.push(m)).unwrap();
    assert_eq!(
        sent,
        vec![Message::Event {
            epoch: 1,
            seq: 0,
            topic: 9
        }]
    );
    let mut timeouts = 0;
    let mut now = 0;
    while s.state() == LinkState::Ok {
        now = s.deadline().unwrap();
        s.poll(now, |_| {});
        timeouts += 1;
    }
    assert_eq!(timeouts, ALARM_AFTER as usize);
    s.on_ack(1, 1, now, |_| {});
    assert_eq!(s.state(), LinkState::Ok);
    assert_eq!(s.unacked(), 0);
    assert_eq!(s.deadline(), None);
}

#[test]
fn a_renumbered_link_resends_at_once_and_stays_in_alarm_until_acknowledged() {
    // A peer that challenges (it booted) has not acknowledged anything yet: a renumbering
    // is no progress (before, every challenge cleared the alarm, and a link that never
    // delivered for a minute showed none).
    let mut s = Sender::new(1);
    s.push(9, 0, |_| {}).unwrap();
    let mut now = 0;
    while s.state() == LinkState::Ok {
        now = s.deadline().unwrap();
        s.poll(now, |_| {});
    }
    now += 1;
    s.renumber(2, now);
    assert_eq!((s.state(), s.deadline()), (LinkState::Alarm, Some(now)));
    let mut sent = Vec::new();
    s.poll(now, |m| sent.push(m));
    assert_eq!(
        sent,
        vec![Message::Event {
            epoch: 2,
            seq: 0,
            topic: 9
        }]
    );
    s.on_ack(2, 1, now + 1, |_| {});
    assert_eq!((s.state(), s.unacked()), (LinkState::Ok, 0));
}

#[test]
fn only_the_window_is_in_flight_and_acks_open_it() {
    let mut s = Sender::new(0);
    let mut sent = Vec::new();
    for topic in 0..6 {
        s.push(topic, 0, |m| sent.push(m)).unwrap();
    }
    let seqs = |v: &[Message]| -> Vec<u16> {
        v.iter()
            .map(|m| match m {
                Message::Event { seq, .. } => *seq,
                _ => panic!(),
            })
            .collect()
    };
    assert_eq!(seqs(&sent), (0..WINDOW as u16).collect::<Vec<_>>());
    sent.clear();
    s.on_ack(0, 2, 1, |m| sent.push(m));
    assert_eq!(seqs(&sent), vec![4, 5]);
    sent.clear();
    // A stale or foreign acknowledgement changes nothing.
    s.on_ack(0, 1, 2, |m| sent.push(m));
    s.on_ack(5, 6, 2, |m| sent.push(m));
    assert!(sent.is_empty());
    assert_eq!(s.unacked(), 4);
}

#[test]
fn an_overflowing_queue_breaks_the_link_instead_of_skipping_an_event() {
    let mut s = Sender::new(0);
    let mut sent = Vec::new();
    for topic in 0..QUEUE as u8 {
        s.push(topic, 0, |m| sent.push(m)).unwrap();
    }
    assert_eq!(sent.len(), WINDOW);
    assert_eq!(s.push(99, 0, |_| {}), Err(node_fw::link::LinkBroken));
    assert_eq!(s.state(), LinkState::Broken);
    assert_eq!(s.push(100, 0, |_| {}), Err(node_fw::link::LinkBroken));
    // What it had taken is still delivered, in order; nothing after the gap ever is.
    let mut receiver = Receiver::new();
    let mut delivered = Vec::new();
    let mut now = 0;
    while s.unacked() > 0 && now < 10_000 {
        for m in std::mem::take(&mut sent) {
            let Message::Event { epoch, seq, topic } = m else {
                panic!("not an event: {m:?}")
            };
            let got = receiver.on_event(epoch, seq, topic);
            delivered.extend(got.deliver);
            if let Some(Message::EventAck { epoch, next }) = got.ack {
                s.on_ack(epoch, next, now, |m| sent.push(m));
            }
        }
        now += 1;
        s.poll(now, |m| sent.push(m));
    }
    assert_eq!(delivered, (0..QUEUE as u8).collect::<Vec<_>>());
    assert_eq!(
        s.state(),
        LinkState::Broken,
        "acknowledgements do not mend it"
    );
    assert_eq!(s.deadline(), None);
    assert_eq!(s.push(101, now, |_| {}), Err(node_fw::link::LinkBroken));
    // Silence does not turn it into a mere alarm either.
    let mut s = Sender::new(1);
    for topic in 0..=QUEUE as u8 {
        let _ = s.push(topic, 0, |_| {});
    }
    for t in 1..=u64::from(ALARM_AFTER) + 2 {
        s.poll(t * 1_000, |_| {});
    }
    assert_eq!(s.state(), LinkState::Broken);
}

fn got(r: &mut Receiver, epoch: u16, seq: u16, topic: u8) -> Vec<u8> {
    r.on_event(epoch, seq, topic).deliver.into_iter().collect()
}

#[test]
fn the_receiver_holds_early_frames_and_drops_duplicates_and_old_epochs() {
    let mut r = Receiver::new();
    // Not the start of an epoch: nothing to anchor to, no acknowledgement.
    assert_eq!(r.on_event(4, 3, 1).ack, None);
    let first = r.on_event(4, 0, 10);
    assert_eq!(first.deliver.as_slice(), &[10]);
    assert_eq!(first.ack, Some(Message::EventAck { epoch: 4, next: 1 }));
    // Duplicate: acknowledged again, not delivered.
    let dup = r.on_event(4, 0, 10);
    assert!(dup.deliver.is_empty());
    assert_eq!(dup.ack, Some(Message::EventAck { epoch: 4, next: 1 }));
    // Seq 3 and 2 arrive before 1: held, then released in order by 1.
    assert_eq!(got(&mut r, 4, 3, 13), vec![]);
    assert_eq!(got(&mut r, 4, 2, 12), vec![]);
    assert_eq!(
        r.on_event(4, 2, 12).ack,
        Some(Message::EventAck { epoch: 4, next: 1 })
    );
    assert_eq!(got(&mut r, 4, 1, 11), vec![11, 12, 13]);
    assert_eq!(got(&mut r, 4, 2, 12), vec![], "already delivered");
    // Beyond the window: dropped.
    assert_eq!(got(&mut r, 4, 4 + WINDOW as u16 + 1, 0), vec![]);
    assert_eq!(got(&mut r, 4, 4, 14), vec![14]);
    // An older epoch is ignored entirely; a newer one restarts at 0.
    assert_eq!(r.on_event(3, 0, 99).ack, None);
    assert_eq!(got(&mut r, 5, 0, 20), vec![20]);
    assert_eq!(r.dropped, 6);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn any_loss_below_half_still_delivers_exactly_once_in_order(
        seed in any::<u64>(),
        loss in 0.0f64..0.35,
        dup in 0.0f64..0.3,
        n in 1usize..60,
    ) {
        let topics: Vec<u8> = (0..n).map(|i| (i * 7 % 256) as u8).collect();
        let r = run(&topics, 200, loss, dup, seed, 200_000);
        prop_assert_eq!(&r.delivered, &topics);
        prop_assert_eq!(r.sender.unacked(), 0);
        prop_assert_eq!(r.receiver.dropped as usize + r.delivered.len() >= topics.len(), true);
    }
}

proptest! {
    /// The short path of the event expected next (`Receiver::next_in_order`, the topic
    /// delivered alone), taking every other event to `Receiver::receive`, answers and
    /// delivers as `receive` alone does, and leaves the receiver as it does.
    #[test]
    fn the_event_expected_next_is_taken_as_receive_takes_it(
        events in proptest::collection::vec((0u16..3, 0u16..8, any::<u8>()), 0..40),
    ) {
        let (mut short, mut general) = (Receiver::new(), Receiver::new());
        for (epoch, seq, topic) in events {
            let mut deliver = heapless::Vec::new();
            let ack = general.receive(epoch, seq, topic, &mut deliver);
            let (ours, delivered) = match short.next_in_order(epoch, seq) {
                Some(next) => (Some(next), vec![topic]),
                None => {
                    let mut d = heapless::Vec::new();
                    (short.receive(epoch, seq, topic, &mut d), d.to_vec())
                }
            };
            prop_assert_eq!(ours, ack);
            prop_assert_eq!(delivered, deliver.to_vec());
            prop_assert_eq!(short, general);
        }
    }
}

/// A fresh receiver (its node booted while the publisher numbered on) asks for the link
/// numbered again in the epoch after the one it dropped, `ASK_MS` after the first event it
/// dropped, then at most once per `ASK_MS`, and takes no older epoch from then on; once it
/// took an epoch it never asks.
#[test]
fn a_fresh_receiver_asks_for_a_newer_epoch_once_per_interval() {
    let mut r = Receiver::new();
    // Seq 5 of epoch 7: dropped, noted; its seq 0 may be just behind (reordered).
    assert_eq!(got(&mut r, 7, 5, 1), vec![]);
    assert_eq!(r.ask(7, 100 - ASK_MS), None);
    assert_eq!(r.ask(7, 99), None);
    // Still only frames past seq 0: ask for 8.
    assert_eq!(r.ask(7, 100), Some(8));
    // Within the interval: no second ask.
    assert_eq!(got(&mut r, 7, 6, 2), vec![]);
    assert_eq!(r.ask(7, 100 + ASK_MS - 1), None);
    // Epoch 7's seq 0 (a late copy) is older than what it asked for: not taken.
    assert_eq!(r.on_event(7, 0, 3).ack, None);
    // Still epoch 7 after the interval (the publisher did not hear): the same epoch again.
    assert_eq!(r.ask(7, 100 + ASK_MS), Some(8));
    // Epoch 8 arrived, seq 1 first (its seq 0 lost): no ask (the publisher heard) until the
    // interval passes; then one newer than 8, and 8 is not taken any more.
    assert_eq!(got(&mut r, 8, 1, 4), vec![]);
    assert_eq!(r.ask(8, 100 + ASK_MS + 10), None);
    assert_eq!(r.ask(8, 100 + 2 * ASK_MS), Some(9));
    assert_eq!(
        r.on_event(8, 0, 5).ack,
        None,
        "epoch 8 may be numbered again in 9"
    );
    // Epoch 9 from seq 0: taken, in order; no more asks.
    assert_eq!(got(&mut r, 9, 0, 6), vec![6]);
    assert_eq!(got(&mut r, 9, 1, 7), vec![7]);
    assert_eq!(r.ask(9, 10_000), None);
    assert_eq!(r.ask(3, 10_000), None);
    assert_eq!(r.dropped, 5);
}

/// A receiver that took an epoch without asking (the publisher's first event reached it)
/// never asks: a gap in its epoch is the sender's to fill.
#[test]
fn a_receiver_that_took_an_epoch_never_asks() {
    let mut r = Receiver::new();
    assert_eq!(got(&mut r, 2, 0, 1), vec![1]);
    assert_eq!(got(&mut r, 2, 3, 4), vec![]);
    assert_eq!(r.ask(2, 0), None);
    assert_eq!(got(&mut r, 3, 2, 4), vec![]);
    assert_eq!(r.ask(3, 1000), None);
    assert_eq!(r.ask(3, 2000), None);
}

/// A link that just started, its seq 1 reordered ahead of its seq 0: the receiver waits
/// (no ask), and takes the epoch from seq 0 when it comes.
#[test]
fn a_new_link_whose_seq_0_comes_second_asks_nothing() {
    let mut r = Receiver::new();
    assert_eq!(got(&mut r, 2, 1, 11), vec![]);
    assert_eq!(r.ask(2, 0), None);
    assert_eq!(got(&mut r, 2, 0, 10), vec![10]);
    assert_eq!(got(&mut r, 2, 1, 11), vec![11]);
    assert_eq!(r.ask(2, ASK_MS), None);
}
