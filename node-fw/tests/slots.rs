//! The two flash slots: the node boots the newest committed table; a power cut at any write
//! of a store leaves it with the old table or the new one, never a mix.

mod support;
use support::blob;

use embassy_futures::block_on;
use node_fw::slots::{Loaded, RamFlash, SlotError, Slots, COMMITTED, HEADER};

type Flash = RamFlash<{ 10 * 1024 }>;

fn slots(flash: Flash) -> Slots<Flash> {
    Slots::new(flash).unwrap()
}

fn generation(loaded: Option<Loaded>) -> Option<(usize, u32)> {
    loaded.map(|l| (l.slot, l.table.generation))
}

#[test]
fn an_erased_flash_has_no_table() {
    let mut s = slots(Flash::new());
    assert_eq!(block_on(s.load()), Ok(None));
}

#[test]
fn a_too_small_flash_is_refused() {
    assert!(matches!(
        Slots::new(RamFlash::<4096>::new()),
        Err(SlotError::Geometry)
    ));
}

#[test]
fn stores_alternate_slots_and_the_newest_boots() {
    let mut s = slots(Flash::new());
    let (t1, b1) = blob(1, 5);
    let (t2, b2) = blob(2, 50);
    assert_eq!(block_on(s.store(None, &b1)), Ok(0));
    assert_eq!(
        block_on(s.load()),
        Ok(Some(Loaded {
            slot: 0,
            table: t1,
            keys: None
        }))
    );
    assert_eq!(block_on(s.store(Some(0), &b2)), Ok(1));
    assert_eq!(
        block_on(s.load()),
        Ok(Some(Loaded {
            slot: 1,
            table: t2,
            keys: None
        }))
    );
    // The layout: length, then the marker, then the blob.
    let flash = s.into_inner();
    let base = Slots::<Flash>::slot_size();
    assert_eq!(flash.bytes[base..base + 4], (b2.len() as u32).to_le_bytes());
    assert_eq!(flash.bytes[base + 16..base + 20], COMMITTED.to_le_bytes());
    assert_eq!(flash.bytes[base + HEADER..base + HEADER + b2.len()], b2[..]);
}

#[test]
fn persisted_but_not_flipped_boots_the_old_table() {
    let mut s = slots(Flash::new());
    let (_, b1) = blob(1, 5);
    let (_, b2) = blob(2, 5);
    block_on(s.store(None, &b1)).unwrap();
    block_on(s.persist(1, &b2)).unwrap();
    assert_eq!(generation(block_on(s.load()).unwrap()), Some((0, 1)));
    block_on(s.commit(1)).unwrap();
    assert_eq!(generation(block_on(s.load()).unwrap()), Some((1, 2)));
}

#[test]
fn a_power_cut_at_any_write_leaves_the_old_or_the_new_table() {
    let (_, b1) = blob(1, 5);
    let (_, b2) = blob(2, 7);
    let (_, b3) = blob(3, 40);
    // Running gen 2 in slot 1; gen 1 is the older table in slot 0, about to be overwritten.
    let mut base = slots(Flash::new());
    block_on(base.store(None, &b1)).unwrap();
    block_on(base.store(Some(0), &b2)).unwrap();
    let before = base.into_inner();
    let mut outcomes = Vec::new();
    for cut in 0.. {
        let mut flash = before.clone();
        flash.fail_after = Some(cut);
        let mut s = slots(flash);
        let stored = block_on(s.store(Some(1), &b3));
        let mut flash = s.into_inner();
        flash.fail_after = None; // power back on
        let mut s = slots(flash);
        let booted = generation(block_on(s.load()).unwrap());
        outcomes.push(booted);
        if stored.is_ok() {
            assert_eq!(booted, Some((0, 3)));
            break;
        }
        assert!(
            booted == Some((1, 2)) || booted == Some((0, 3)),
            "cut at write {cut}: booted {booted:?}"
        );
    }
    // Every cut before the marker boots the old table; the marker write itself was cut
    // halfway, which is not a marker either.
    let last = outcomes.len() - 1;
    assert!(
        outcomes[..last].iter().all(|o| *o == Some((1, 2))),
        "{outcomes:?}"
    );
    assert!(
        outcomes.len() >= 4,
        "erase, body, tail/len and marker writes were all cut"
    );
}

#[test]
fn a_damaged_committed_slot_falls_back_to_the_other() {
    let mut s = slots(Flash::new());
    let (_, b1) = blob(1, 5);
    let (_, b2) = blob(2, 5);
    block_on(s.store(None, &b1)).unwrap();
    block_on(s.store(Some(0), &b2)).unwrap();
    let mut flash = s.into_inner();
    let base = Slots::<Flash>::slot_size();
    flash.bytes[base + HEADER + 20] ^= 0x40; // a bit flipped in gen 2's blob
    let mut s = slots(flash);
    assert_eq!(generation(block_on(s.load()).unwrap()), Some((0, 1)));
}
