//! Software AES-128 with its key schedules kept: the node secures and opens every frame
//! under one of a few keys (its management key, the send and receive keys of each peer
//! it talks with), and the `aes` crate's key schedule costs more than one block (5,500
//! instructions against 4,300 on a Cortex-M3, docs/security.md): computed once per key
//! and kept in [`SCHEDULES`] slots, the oldest replaced first, not computed again for
//! every frame. The schedule is a function of the key alone, so a kept one is the one a
//! fresh computation would give: the same blocks, the same frames.
//!
//! The slots are one static behind a critical section (the codec asks for a cipher by
//! its key, without a place of the node's to keep it); a schedule is computed outside the
//! critical section (interrupts are not held off for it) and copied out of it. The
//! slots hold what the node's RAM holds already, its keys, expanded; a new generation's
//! link keys make the node forget them ([`forget`], wiped), as it drops the old keys.

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use config_schema::wire::security::{BlockCipher, CipherFault, SoftAes, BLOCK_LEN, KEY_LEN};
use zeroize::Zeroize;

/// Key schedules kept: the management key and the send and receive keys of three peers.
pub const SCHEDULES: usize = 8;

/// Keys (as one 128-bit word each: a key compares in four word compares on a 32-bit
/// core, not a `memcmp` call) and their schedules, the oldest replaced first.
struct Slots {
    slots: [Option<(u128, SoftAes)>; SCHEDULES],
    /// The slot the next new key takes.
    next: usize,
}

impl Slots {
    const fn new() -> Slots {
        Slots {
            slots: [const { None }; SCHEDULES],
            next: 0,
        }
    }

    /// The schedule kept for `key`, in its slot.
    fn kept(&self, key: u128) -> Option<&SoftAes> {
        self.slots
            .iter()
            .flatten()
            .find_map(|(k, cipher)| (*k == key).then_some(cipher))
    }

    /// The schedule kept for `key`.
    fn find(&self, key: &[u8; KEY_LEN]) -> Option<SoftAes> {
        self.kept(u128::from_ne_bytes(*key)).cloned()
    }

    /// Keeps `cipher`, the schedule of `key`, in place of the oldest (unless `key` has
    /// one already: another caller computed it meanwhile).
    fn keep(&mut self, key: &[u8; KEY_LEN], cipher: &SoftAes) {
        let key = u128::from_ne_bytes(*key);
        if self.kept(key).is_some() {
            return;
        }
        if let Some(slot) = self.slots.get_mut(self.next % SCHEDULES) {
            *slot = Some((key, cipher.clone()));
        }
        self.next = (self.next + 1) % SCHEDULES;
    }
}

impl Drop for Slots {
    /// The keys wiped (each schedule wipes itself: the `aes` crate's `zeroize`).
    fn drop(&mut self) {
        for (key, _) in self.slots.iter_mut().flatten() {
            key.zeroize();
        }
    }
}

/// Forgets every kept schedule, the keys and schedules wiped: the node's link keys
/// changed, and the schedules of keys it no longer holds are not kept on.
pub fn forget() {
    critical_section::with(|cs| drop(KEPT.borrow(cs).replace(Slots::new())));
}

static KEPT: critical_section::Mutex<RefCell<Slots>> =
    critical_section::Mutex::new(RefCell::new(Slots::new()));

/// Key schedules computed and blocks encrypted so far (wrapping): what a board that counts
/// its instructions attributes to the AES (the QEMU board's `--icount` figures). Shared
/// by every node of a process (one on a board).
static SCHEDULED: AtomicU32 = AtomicU32::new(0);
static BLOCKS: AtomicU32 = AtomicU32::new(0);

/// The software AES's work so far: key schedules computed, blocks encrypted (each
/// wrapping; a difference of two readings is the work between them).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AesWork {
    pub schedules: u32,
    pub blocks: u32,
}

/// The software AES's work so far.
pub fn work() -> AesWork {
    AesWork {
        schedules: SCHEDULED.load(Ordering::Relaxed),
        blocks: BLOCKS.load(Ordering::Relaxed),
    }
}

/// The `aes` crate's AES-128 under one key, its schedule kept between frames.
#[derive(Clone)]
pub struct KeptSoftAes(SoftAes);

impl BlockCipher for KeptSoftAes {
    fn new(key: &[u8; KEY_LEN]) -> Self {
        if let Some(cipher) = critical_section::with(|cs| KEPT.borrow_ref(cs).find(key)) {
            return KeptSoftAes(cipher);
        }
        let cipher = SoftAes::new(key);
        SCHEDULED.fetch_add(1, Ordering::Relaxed);
        critical_section::with(|cs| KEPT.borrow_ref_mut(cs).keep(key, &cipher));
        KeptSoftAes(cipher)
    }

    fn encrypt(&self, block: &mut [u8; BLOCK_LEN]) -> Result<(), CipherFault> {
        BLOCKS.fetch_add(1, Ordering::Relaxed);
        self.0.encrypt(block)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use config_schema::wire::security::fips197::{CIPHER, KEY, PLAIN};

    fn key(i: u8) -> [u8; KEY_LEN] {
        [i; KEY_LEN]
    }

    /// `cipher`'s encryption of `PLAIN`.
    fn block(cipher: &impl BlockCipher) -> [u8; BLOCK_LEN] {
        let mut b = PLAIN;
        assert_eq!(cipher.encrypt(&mut b), Ok(()));
        b
    }

    /// The node's cipher gives FIPS-197's block, fresh, kept, and after more keys than
    /// slots (the first one's schedule replaced and computed again).
    #[test]
    fn a_kept_schedule_encrypts_as_a_fresh_one() {
        assert_eq!(block(&KeptSoftAes::new(&KEY)), CIPHER);
        assert_eq!(block(&KeptSoftAes::new(&KEY)), CIPHER);
        for i in 0..=SCHEDULES as u8 {
            let k = key(i);
            assert_eq!(block(&KeptSoftAes::new(&k)), block(&SoftAes::new(&k)));
        }
        assert_eq!(block(&KeptSoftAes::new(&KEY)), CIPHER);
    }

    /// Every schedule computed and every block encrypted is counted (other tests' work
    /// may add to the counts meanwhile: at least these).
    #[test]
    fn the_work_is_counted() {
        let before = work();
        let fresh = [0xA7; KEY_LEN];
        let cipher = KeptSoftAes::new(&fresh);
        let mut b = PLAIN;
        cipher.encrypt(&mut b).unwrap();
        cipher.encrypt(&mut b).unwrap();
        let after = work();
        assert!(after.schedules.wrapping_sub(before.schedules) >= 1);
        assert!(after.blocks.wrapping_sub(before.blocks) >= 2);
    }

    /// Forgotten, a key is expanded again, the same.
    #[test]
    fn forgotten_schedules_are_computed_again() {
        assert_eq!(block(&KeptSoftAes::new(&KEY)), CIPHER);
        forget();
        assert_eq!(block(&KeptSoftAes::new(&KEY)), CIPHER);
    }

    /// The slots keep the last `SCHEDULES` keys, each once, the oldest replaced first;
    /// a kept schedule is the key's.
    #[test]
    fn the_oldest_key_is_replaced_first() {
        let mut slots = Slots::new();
        assert!(slots.find(&key(0)).is_none());
        for i in 0..SCHEDULES as u8 {
            slots.keep(&key(i), &SoftAes::new(&key(i)));
        }
        // Kept again: not a second slot.
        slots.keep(&key(0), &SoftAes::new(&key(0)));
        for i in 0..SCHEDULES as u8 {
            let kept = slots.find(&key(i)).map(|c| block(&c));
            assert_eq!(kept, Some(block(&SoftAes::new(&key(i)))), "key {i}");
        }
        let n = SCHEDULES as u8;
        slots.keep(&key(n), &SoftAes::new(&key(n)));
        assert!(slots.find(&key(0)).is_none(), "the oldest replaced");
        assert!(slots.find(&key(1)).is_some());
        assert_eq!(
            slots.find(&key(n)).map(|c| block(&c)),
            Some(block(&SoftAes::new(&key(n))))
        );
        slots.keep(&key(n + 1), &SoftAes::new(&key(n + 1)));
        assert!(slots.find(&key(1)).is_none(), "then the next oldest");
        assert!(slots.find(&key(2)).is_some());
    }
}
