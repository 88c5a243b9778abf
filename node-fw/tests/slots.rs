//! The two flash slots: a table is staged (checked, not running), then activated; the node
//! boots the confirmed table activated last (not the highest generation); a power cut at
//! any write leaves it with the old table or the new one, never a mix; a trial a power cut
//! interrupted is not booted.

mod support;
use support::blob;

use config_schema::link_keys::Deployment;
use config_schema::TableId;
use embassy_futures::block_on;
use node_fw::slots::{
    Boot, Loaded, RamFlash, SlotError, SlotState, Slots, StagedSlot, CONFIRMED, HEADER, STAGED,
};

type Flash = RamFlash<{ 10 * 1024 }>;

fn slots(flash: Flash) -> Slots<Flash> {
    Slots::new(flash).unwrap()
}

/// The booted (slot, generation).
fn running(boot: &Boot) -> Option<(usize, u32)> {
    boot.running
        .as_ref()
        .map(|l| (l.slot, l.deployed.table.generation))
}

/// The identity of blob `b`: its last four bytes, the CRC.
fn trailer(b: &[u8]) -> TableId {
    TableId(b[b.len() - 4..].try_into().unwrap())
}

fn load(s: &mut Slots<Flash>) -> Boot {
    block_on(s.load()).unwrap()
}

#[test]
fn an_erased_flash_has_no_table() {
    let mut s = slots(Flash::new());
    assert_eq!(load(&mut s), Boot::default());
}

#[test]
fn a_too_small_flash_is_refused() {
    assert!(matches!(
        Slots::new(RamFlash::<4096>::new()),
        Err(SlotError::Geometry)
    ));
}

#[test]
fn stores_alternate_slots_and_the_one_activated_last_boots() {
    let mut s = slots(Flash::new());
    let (t1, b1) = blob(1, 5);
    let (t2, b2) = blob(2, 50);
    assert_eq!(block_on(s.store(None, &b1, 0)), Ok(0));
    let boot = load(&mut s);
    assert_eq!(
        boot.running,
        Some(Loaded {
            slot: 0,
            deployed: Deployment {
                id: trailer(&b1),
                table: t1,
                keys: None,
            }
        })
    );
    assert_eq!(boot.next_serial, 1);
    assert_eq!(block_on(s.store(Some(0), &b2, 1)), Ok(1));
    let boot = load(&mut s);
    assert_eq!(
        boot.running,
        Some(Loaded {
            slot: 1,
            deployed: Deployment {
                id: trailer(&b2),
                table: t2,
                keys: None,
            }
        })
    );
    assert_eq!(
        (boot.staged, boot.abandoned, boot.next_serial),
        (None, None, 2)
    );
    // The layout: length, the staged marker, the serial, the confirmed marker, the blob.
    let flash = s.into_inner();
    let base = Slots::<Flash>::slot_size();
    let word = |at: usize| flash.bytes[base + at..base + at + 4].to_vec();
    assert_eq!(word(0), (b2.len() as u32).to_le_bytes());
    assert_eq!(word(16), STAGED.to_le_bytes());
    assert_eq!(word(32), 1u32.to_le_bytes());
    assert_eq!(word(48), CONFIRMED.to_le_bytes());
    assert_eq!(word(64), [0xFF; 4]);
    assert_eq!(flash.bytes[base + HEADER..base + HEADER + b2.len()], b2[..]);
}

#[test]
fn a_staged_table_does_not_boot_and_is_reported_until_activated() {
    let mut s = slots(Flash::new());
    let (_, b1) = blob(1, 5);
    let (_, b2) = blob(2, 5);
    block_on(s.store(None, &b1, 0)).unwrap();
    assert_eq!(block_on(s.stage(Some(0), &b2)), Ok(1));
    let boot = load(&mut s);
    assert_eq!(running(&boot), Some((0, 1)));
    assert_eq!(
        boot.staged,
        Some(StagedSlot {
            slot: 1,
            generation: 2
        })
    );
    block_on(s.activate(1, boot.next_serial, false)).unwrap();
    let boot = load(&mut s);
    assert_eq!((running(&boot), boot.staged), (Some((1, 2)), None));
    // Activated once: a second activation of the same slot is refused.
    assert_eq!(block_on(s.activate(1, 9, false)), Err(SlotError::NotStaged));
}

/// Issue 12: push GR at generation 60, then force generation 3: after a restart the node
/// ran generation 60 again.
#[test]
fn a_forced_downgrade_survives_a_restart() {
    let mut s = slots(Flash::new());
    let (_, b60) = blob(60, 5);
    let (_, b3) = blob(3, 5);
    block_on(s.store(None, &b60, 0)).unwrap();
    block_on(s.store(Some(0), &b3, 1)).unwrap();
    assert_eq!(running(&load(&mut s)), Some((1, 3)));
}

#[test]
fn a_trial_cut_by_a_power_cut_boots_the_confirmed_table() {
    let mut s = slots(Flash::new());
    let (_, b1) = blob(1, 5);
    let (_, b2) = blob(2, 5);
    block_on(s.store(None, &b1, 0)).unwrap();
    block_on(s.stage(Some(0), &b2)).unwrap();
    block_on(s.activate(1, 1, true)).unwrap();
    let boot = load(&mut s);
    assert_eq!((running(&boot), boot.abandoned), (Some((0, 1)), Some(1)));
    // Revoked, it is gone for good; confirmed instead, it would have booted.
    block_on(s.revoke(1)).unwrap();
    let boot = load(&mut s);
    assert_eq!(
        (running(&boot), boot.abandoned, boot.staged),
        (Some((0, 1)), None, None)
    );
    let mut s = slots(Flash::new());
    block_on(s.store(None, &b1, 0)).unwrap();
    block_on(s.stage(Some(0), &b2)).unwrap();
    block_on(s.activate(1, 1, true)).unwrap();
    block_on(s.confirm(1)).unwrap();
    assert_eq!(running(&load(&mut s)), Some((1, 2)));
    assert_eq!(
        block_on(s.state(1)),
        Ok(SlotState {
            staged: true,
            serial: Some(1),
            confirmed: true,
            revoked: false
        })
    );
}

#[test]
fn a_power_cut_at_any_write_leaves_the_old_or_the_new_table() {
    let (_, b1) = blob(1, 5);
    let (_, b2) = blob(2, 7);
    let (_, b3) = blob(3, 40);
    // Running gen 2 in slot 1; gen 1 is the older table in slot 0, about to be overwritten.
    let mut base = slots(Flash::new());
    block_on(base.store(None, &b1, 0)).unwrap();
    block_on(base.store(Some(0), &b2, 1)).unwrap();
    let before = base.into_inner();
    let mut outcomes = Vec::new();
    for cut in 0.. {
        let mut flash = before.clone();
        flash.fail_after = Some(cut);
        let mut s = slots(flash);
        let stored = block_on(s.store(Some(1), &b3, 2));
        let mut flash = s.into_inner();
        flash.fail_after = None; // power back on
        let mut s = slots(flash);
        let boot = load(&mut s);
        let booted = running(&boot);
        outcomes.push(booted);
        if stored.is_ok() {
            assert_eq!(booted, Some((0, 3)));
            break;
        }
        assert!(
            booted == Some((1, 2)) || booted == Some((0, 3)),
            "cut at write {cut}: booted {booted:?}"
        );
        // Staged but not activated (the cut came between): reported, not booted.
        if let Some(staged) = boot.staged {
            assert_eq!(
                (staged.slot, staged.generation, booted),
                (0, 3, Some((1, 2)))
            );
        }
    }
    // Every cut before the confirmation boots the old table; the confirming write itself
    // was cut halfway, which is not a marker either.
    let last = outcomes.len() - 1;
    assert!(
        outcomes[..last].iter().all(|o| *o == Some((1, 2))),
        "{outcomes:?}"
    );
    assert!(
        outcomes.len() >= 6,
        "erase, body, tail/len, staged, serial and confirmed writes were all cut"
    );
}

#[test]
fn a_damaged_slot_falls_back_to_the_other() {
    let mut s = slots(Flash::new());
    let (_, b1) = blob(1, 5);
    let (_, b2) = blob(2, 5);
    block_on(s.store(None, &b1, 0)).unwrap();
    block_on(s.store(Some(0), &b2, 1)).unwrap();
    let mut flash = s.into_inner();
    let base = Slots::<Flash>::slot_size();
    flash.bytes[base + HEADER + 20] ^= 0x40; // a bit flipped in gen 2's blob
    let mut s = slots(flash);
    assert_eq!(running(&load(&mut s)), Some((0, 1)));
}

/// A power cut during a switch-over's activation writes (the serial, then, unless a trial,
/// the confirmation): the slot reads as a trial the cut interrupted. The node boots the old
/// table and the switched-to one is abandoned (the runtime revokes it): G is pushed again
/// (docs/reconfiguration.md, failure cases).
#[test]
fn a_power_cut_during_the_activation_boots_the_old_table_and_abandons_the_new() {
    let (_, b1) = blob(1, 5);
    let (_, b2) = blob(2, 5);
    let mut base = slots(Flash::new());
    block_on(base.store(None, &b1, 0)).unwrap();
    block_on(base.stage(Some(0), &b2)).unwrap();
    let base = base.into_inner();
    for (trial, cut) in [(false, 1), (false, 2), (true, 1)] {
        let mut f = Flash::new();
        f.bytes = base.bytes;
        f.fail_after = Some(cut);
        let mut s = slots(f);
        assert!(block_on(s.activate(1, 1, trial)).is_err());
        let mut f = s.into_inner();
        f.fail_after = None;
        let boot = load(&mut slots(f));
        let staged = boot.staged.map(|s| s.generation);
        assert_eq!(
            (running(&boot), staged, boot.abandoned),
            (Some((0, 1)), None, Some(1)),
            "trial {trial}, cut at write {cut}"
        );
    }
}

/// A power cut that tears the activation's serial (the write applied halfway: 0xFFFF_0001
/// for 1) numbers the next activations from the confirmed table's serial, not from the
/// torn word: counted from it, the serials came to 0xFFFF_FFFF (the erased word, "never
/// activated") within 65,535 activations, and that table was not booted.
#[test]
fn a_torn_serial_does_not_number_the_next_activations() {
    let (_, b1) = blob(1, 5);
    let (_, b2) = blob(2, 5);
    let mut s = slots(Flash::new());
    s.store_now(None, &b1, 0).unwrap();
    s.stage_now(Some(0), &b2).unwrap();
    // The power cut at the activation's first write, the serial's.
    let mut f = Flash::new();
    f.bytes = s.into_inner().bytes;
    f.fail_after = Some(1);
    let mut s = slots(f);
    assert!(s.activate_now(1, 1, false).is_err());
    let mut f = s.into_inner();
    f.fail_after = None;
    let mut s = slots(f);
    let mut buf = [0u8; config_schema::limits::MAX_BLOB];
    let survey = s.survey_now(&mut buf).unwrap();
    assert_eq!(survey.running.map(|r| r.slot), Some(0));
    assert_eq!(format!("{:#010x}", survey.next_serial), "0x00000001");
}
