//! Over-the-air configuration under faults, end to end with real node processes: lost and
//! corrupted frames, a wrong total CRC, an invalid blob, a stale generation, a node killed
//! in the middle of a transfer, and one killed between persisting the new table and
//! flipping to it. In every case the node ends up running exactly the old table or the new
//! one, its status says which, and it still works.

mod e2e_support;

use std::future::Future;
use std::pin::pin;
use std::task::{Context, Poll, Waker};

use config_schema::wire::mac;
use config_schema::wire::msg::{Command, Message, Refusal, CHUNK_DATA};
use node_fw::host::flash::HostFlash;
use node_fw::node::CONFIG_PAN;
use node_fw::ota::Progress;
use node_fw::slots::Slots;
use robot_net::radio::TOOL_ADDR;

use e2e_support::*;

/// Runs a future that never waits (the host flash answers at once).
fn now<F: Future>(f: F) -> F::Output {
    let mut f = pin!(f);
    let mut cx = Context::from_waker(Waker::noop());
    loop {
        if let Poll::Ready(v) = f.as_mut().poll(&mut cx) {
            return v;
        }
    }
}

#[test]
fn push_completes_through_lost_and_corrupted_frames() {
    let c = robot("paint-robot.ron", 1);
    let mut bed = bring_up(
        &c,
        options(
            medium::Config {
                loss: 0.25,
                corrupt: 0.2,
                seed: 0x07A0_0001,
                ..medium::Config::default()
            },
            None,
        ),
    );
    let outcomes = push_and_home(&mut bed, &c);
    let statuses = assert_running(&mut bed, &c);
    let stats = bed.medium().stats();
    assert!(stats.lost > 0 && stats.corrupted > 0, "{stats:?}");
    let retries: u32 = outcomes.iter().map(|o| o.stats.retries).sum();
    assert!(retries > 0, "lost chunks and replies were resent");
    let dropped: u32 = statuses.iter().map(|s| s.counters.dropped).sum();
    assert!(
        dropped > 0,
        "corrupted frames failed their FCS at the nodes"
    );
    bed.stop();
}

#[test]
fn a_lost_chunk_is_resent_and_a_corrupted_one_dropped() {
    let c = robot("paint-robot.ron", 1);
    let dip = robot("paint-robot-double-dip.ron", 2);
    let (vc, node) = role_of(&c, "VC");
    let mut bed = bring_up(&c, options(medium::Config::default(), None));
    push_and_home(&mut bed, &c);
    let blob = &dip.blobs[vc];
    // Two chunks (the packed tables fit one or two: the double dip's VC is 92 bytes).
    assert!(blob.len() > CHUNK_DATA, "two chunks at least");
    let before = status(&mut bed, node);

    // Chunk 0's first copy arrives with a flipped bit (sent by hand: the tool's radio only
    // sends good frames); chunk 1 is lost the first time.
    let mut raw = RawClient::join(bed.medium().addr(), 0x0101);
    let (mut lost, mut corrupted) = (0, 0);
    let (progress, acked, stats) = drive(
        bed.radio(),
        node,
        blob,
        2,
        |m, _| match m {
            Message::ConfigChunk { offset, .. } if usize::from(*offset) == CHUNK_DATA => {
                lost += 1;
                if lost == 1 {
                    Fate::Lose
                } else {
                    Fate::Send
                }
            }
            Message::ConfigChunk { offset: 0, .. } => {
                corrupted += 1;
                if corrupted == 1 {
                    let mut psdu = frame(CONFIG_PAN, node, TOOL_ADDR, 0, &payload(m));
                    psdu[mac::DATA_HEADER_LEN + 8] ^= 0x10;
                    raw.send_psdu(&psdu);
                    Fate::Lose
                } else {
                    Fate::Send
                }
            }
            _ => Fate::Send,
        },
        |m| m,
    );
    assert_eq!((progress, acked), (Progress::Done, blob.len()));
    assert!(lost >= 2 && corrupted >= 2, "both chunks were resent");
    assert!(stats.retries > 0);
    let after = status(&mut bed, node);
    assert_eq!((after.role.as_str(), after.generation), ("VC", 2));
    assert_eq!(after.counters.dropped - before.counters.dropped, 1);
    // Switched at its idle point: homed, in the new table's idle states.
    assert_eq!(after.states.as_slice(), idle(&dip.tables[vc]).as_slice());
    bed.stop();
}

#[test]
fn wrong_crc_invalid_blob_and_stale_generations_are_refused() {
    let c = robot("paint-robot.ron", 1);
    let dip = robot("paint-robot-double-dip.ron", 2);
    let (vc, node) = role_of(&c, "VC");
    let mut bed = bring_up(&c, options(medium::Config::default(), None));
    push_and_home(&mut bed, &c);

    // A wrong total CRC in the begin: every chunk arrives, the end is refused.
    let (progress, acked, _) = drive(
        bed.radio(),
        node,
        &dip.blobs[vc],
        2,
        |_, _| Fate::Send,
        |m| match m {
            Message::ConfigBegin {
                generation,
                len,
                crc,
                force,
            } => Message::ConfigBegin {
                generation,
                len,
                crc: crc ^ 0x0000_0100,
                force,
            },
            m => m,
        },
    );
    assert_eq!(progress, Progress::Refused(Refusal::Crc));
    assert_eq!(acked, dip.blobs[vc].len());
    let s = status(&mut bed, node);
    assert_eq!(
        (s.role.as_str(), s.generation),
        ("VC", 1),
        "the old table runs"
    );

    // A blob with the right CRC that is not a table.
    let junk: Vec<u8> = (0..150u8).map(|i| i.wrapping_mul(37)).collect();
    let (progress, _, _) = drive(bed.radio(), node, &junk, 2, |_, _| Fate::Send, |m| m);
    assert_eq!(progress, Progress::Refused(Refusal::Invalid));
    assert_eq!(status(&mut bed, node).generation, 1);

    // The same generation again: stale, on every node.
    let again = bed.push(&c, false, &mut |_, _, _| {}).unwrap();
    for o in &again {
        assert_eq!(o.progress, Progress::Refused(Refusal::Stale { running: 1 }));
    }
    assert_running(&mut bed, &c);

    // Newer: accepted; then the older one is stale, unless forced.
    push_ok(&mut bed, &dip);
    let older = bed.push(&c, false, &mut |_, _, _| {}).unwrap();
    for o in &older {
        assert_eq!(o.progress, Progress::Refused(Refusal::Stale { running: 2 }));
    }
    assert_running(&mut bed, &dip);
    let forced = bed.push(&c, true, &mut |_, _, _| {}).unwrap();
    assert!(forced.iter().all(|o| o.progress == Progress::Done));
    assert_running(&mut bed, &c);
    exact_cycle(&mut bed, &c, 1);
    bed.stop();
}

/// Issue 11: a captured START replayed after the node rebooted (its memory of the tool's
/// counter gone) started the cycle again. Secured: the node challenges the tool instead
/// of acting; nothing starts, and the tool, answering the challenge, commands it again.
#[test]
fn a_start_replayed_after_the_node_rebooted_is_challenged_and_starts_nothing() {
    let flash = TempDir::new("replay-reboot");
    let c = robot("paint-robot.ron", 1);
    let mut bed = bring_up(&c, options(medium::Config::default(), Some(&flash)));
    push_and_home(&mut bed, &c);
    let secret = bed.secret().expect("a secured bed").clone();
    let (start_role, _) = c.ir.start.clone().expect("a start input");
    let node = c.ir.roles[start_role].address;
    let mut monitor = Monitor::join(bed.medium().addr());
    exact_cycle(&mut bed, &c, 1);
    let is_start = |psdu: &[u8]| {
        open_from_tool(&secret, node, psdu).is_some_and(|p| {
            matches!(
                Message::parse(&p),
                Ok(Message::Command {
                    command: Command::Start,
                    ..
                })
            )
        })
    };
    let captured = monitor
        .psdus_until(|p| is_start(p))
        .pop()
        .expect("captured");

    bed.kill_node(node);
    bed.start_node(node).unwrap();
    bed.wait_for_nodes(&[node]).unwrap();
    let mut raw = RawClient::join(bed.medium().addr(), 0xBEEF).keyed(&secret);
    raw.send_psdu(&captured);
    // Asked on the same connection: the answers come after the replay.
    let after = raw.status(node);
    // Nothing started (booted, the node is not homed either: the counters below say the
    // replay was challenged, not run).
    assert_eq!(
        after.states.as_slice(),
        initial(&c.tables[start_role]).as_slice(),
        "nothing started"
    );
    let report = raw.security(node);
    assert!(report.counters.challenged >= 2, "{report:?}");
    assert_eq!(
        report.counters.replayed, 0,
        "refused before any floor: challenged"
    );
    // The tool answers the node's challenge and commands it again. (A whole cycle right
    // after the reboot of a subscriber mid-epoch is the event links' matter: the
    // publisher's numbering goes on where the rebooted receiver starts afresh.)
    let s = status(&mut bed, node);
    assert_eq!(
        s.states.as_slice(),
        initial(&c.tables[start_role]).as_slice()
    );
    assert!(bed.radio().stats.challenges >= 1);
    bed.stop();
}

#[test]
fn node_killed_mid_transfer_restarts_with_the_old_table_then_takes_a_new_push() {
    let flash = TempDir::new("mid-transfer");
    let c = robot("paint-robot.ron", 1);
    let dip = robot("paint-robot-double-dip.ron", 2);
    let (vc, node) = role_of(&c, "VC");
    let mut bed = bring_up(&c, options(medium::Config::default(), Some(&flash)));
    push_and_home(&mut bed, &c);
    assert_running(&mut bed, &c);

    // Only the first chunk gets through; the power goes once the node acknowledged it.
    let blob = &dip.blobs[vc];
    let (progress, acked, _) = drive(
        bed.radio(),
        node,
        blob,
        2,
        |m, acked| match m {
            _ if acked >= CHUNK_DATA => Fate::Stop,
            Message::ConfigChunk { offset, .. } if usize::from(*offset) >= CHUNK_DATA => Fate::Lose,
            _ => Fate::Send,
        },
        |m| m,
    );
    assert_eq!(progress, Progress::Busy);
    assert_eq!(acked, CHUNK_DATA);
    assert!(blob.len() > CHUNK_DATA, "a chunk after the first");
    bed.kill_node(node);
    bed.start_node(node).unwrap();
    let found = bed.wait_for_nodes(&[node]).unwrap();
    assert_eq!(
        (found[&node].role.as_str(), found[&node].generation),
        ("VC", 1)
    );
    // It runs the old table from flash, booted not homed; homed (the rods are home: the
    // plant moves nothing), with its peers, for a whole cycle.
    assert_not_homed_node(&mut bed, &c, "VC");
    assert_eq!(home_ok(&mut bed, &c), Vec::<String>::new());
    assert_running(&mut bed, &c);
    exact_cycle(&mut bed, &c, 1);

    // A new push goes through; a restart now boots the new table.
    push_ok(&mut bed, &dip);
    assert_running(&mut bed, &dip);
    bed.kill_node(node);
    bed.start_node(node).unwrap();
    let found = bed.wait_for_nodes(&[node]).unwrap();
    assert_eq!(found[&node].generation, 2);
    assert_not_homed_node(&mut bed, &dip, "VC");
    bed.stop();
}

#[test]
fn node_killed_between_persisting_and_flipping_boots_the_old_table() {
    let flash = TempDir::new("before-flip");
    let c = robot("paint-robot.ron", 1);
    let dip = robot("paint-robot-double-dip.ron", 2);
    let (vc, node) = role_of(&c, "VC");
    let mut bed = bring_up(&c, options(medium::Config::default(), Some(&flash)));
    push_and_home(&mut bed, &c);
    assert_running(&mut bed, &c);
    bed.kill_node(node);

    // What the node had done when the power went: the new blob written to the inactive
    // slot, its commit marker not yet.
    let path = flash.flash(node);
    let mut slots = Slots::new(HostFlash::open(&path).unwrap()).unwrap();
    let loaded = now(slots.load())
        .unwrap()
        .running
        .expect("the old table is committed");
    assert_eq!(
        (
            loaded.deployed.table.generation,
            loaded.deployed.table.header.role.as_str()
        ),
        (1, "VC")
    );
    let inactive = 1 - loaded.slot;
    now(slots.persist(inactive, &dip.blobs[vc])).unwrap();
    let mut buf = [0u8; config_schema::limits::MAX_BLOB + 16];
    assert_eq!(now(slots.read_blob(inactive, &mut buf)).unwrap(), None);
    let reloaded = now(slots.load()).unwrap().running.unwrap();
    assert_eq!(
        (reloaded.slot, reloaded.deployed.table.generation),
        (loaded.slot, 1)
    );
    drop(slots);

    bed.start_node(node).unwrap();
    let found = bed.wait_for_nodes(&[node]).unwrap();
    assert_eq!(
        (found[&node].role.as_str(), found[&node].generation),
        ("VC", 1)
    );
    assert_not_homed_node(&mut bed, &c, "VC");
    assert_eq!(home_ok(&mut bed, &c), Vec::<String>::new());
    assert_running(&mut bed, &c);
    exact_cycle(&mut bed, &c, 1);

    // The next push replaces the half-written slot and commits it.
    push_ok(&mut bed, &dip);
    assert_running(&mut bed, &dip);
    bed.kill_node(node);
    let mut slots = Slots::new(HostFlash::open(&path).unwrap()).unwrap();
    let newest = now(slots.load()).unwrap().running.unwrap();
    assert_eq!(
        (newest.slot, newest.deployed.table.generation),
        (inactive, 2)
    );
    drop(slots);
    bed.start_node(node).unwrap();
    assert_eq!(bed.wait_for_nodes(&[node]).unwrap()[&node].generation, 2);
    assert_not_homed_node(&mut bed, &dip, "VC");
    bed.stop();
}
