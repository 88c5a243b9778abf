//! What securing and opening one frame costs on this Cortex-M3, measured once at boot when
//! counting (provisioning flag `FLAG_COUNT`; under `-icount shift=0` a nanosecond is one
//! instruction): what the node core calls for every secured frame
//! (`security::secure_default_with`, `security::open_default_with`: ENC-MIC-64 over the
//! node's cipher, `node_fw::cipher::NodeCipher`, whose key schedule is kept after the
//! first frame), with a fixed key of its own (never the node's), interrupts masked, for a
//! short payload (a command) and the largest one (a chunk); and the AES alone: its key
//! schedule (once per key on the node) and one block.

use aes::cipher::{BlockCipherEncrypt, KeyInit};
use aes::Aes128;
use config_schema::wire::mac::{Header, MAX_PAYLOAD, MAX_PSDU};
use config_schema::wire::security::{
    self, ext_addr, AuxRepr, BlockCipher, KEY_LEN, MAX_SECURED_PAYLOAD,
};
use node_fw::cipher::NodeCipher;

use crate::time;

/// The payload sizes measured: a command, and a full secured frame.
pub const SIZES: [usize; 2] = [4, MAX_SECURED_PAYLOAD];
const ROUNDS: u32 = 16;
const KEY: [u8; KEY_LEN] = [0x42; KEY_LEN];
const PAN: u16 = 0xFFFF;

/// Nanoseconds per secure and per open of one frame, for each of [`SIZES`]; `None` if the
/// codec refused (it does not: the frames fit).
pub fn secure_and_open() -> Option<[(u64, u64); SIZES.len()]> {
    let mut out = [(0, 0); SIZES.len()];
    for (size, cost) in SIZES.iter().zip(out.iter_mut()) {
        *cost = one_size(*size)?;
    }
    Some(out)
}

/// Nanoseconds of one AES-128 key schedule and of one block encrypted.
pub fn aes() -> (u64, u64) {
    cortex_m::interrupt::free(|_| {
        let t0 = time::cycles();
        let mut cipher = Aes128::new(&KEY.into());
        for i in 1..ROUNDS {
            let key = core::hint::black_box([i as u8; KEY_LEN]);
            cipher = Aes128::new(&key.into());
        }
        let t1 = time::cycles();
        let mut block = [0u8; 16].into();
        for _ in 0..ROUNDS {
            cipher.encrypt_block(core::hint::black_box(&mut block));
        }
        let t2 = time::cycles();
        core::hint::black_box(&block);
        (ns(t1.saturating_sub(t0)), ns(t2.saturating_sub(t1)))
    })
}

/// Nanoseconds per round of `cycles` timer cycles.
fn ns(cycles: u64) -> u64 {
    cycles * time::NS_PER_CYCLE / u64::from(ROUNDS)
}

fn one_size(size: usize) -> Option<(u64, u64)> {
    let header = Header {
        seq: 1,
        pan_id: PAN,
        dst: 0x0011,
        src: 0x0100,
        ack_request: false,
        secured: true,
    };
    let payload = [0x5Au8; MAX_SECURED_PAYLOAD];
    let payload = payload.get(..size)?;
    let mut psdu = [0u8; MAX_PSDU];
    let mut scratch = [0u8; MAX_PAYLOAD];
    // The key's schedule kept before the count, as a node's keys are after their first
    // frame.
    let _ = NodeCipher::new(&KEY);
    cortex_m::interrupt::free(|_| {
        let t0 = time::cycles();
        let mut n = 0;
        for i in 0..ROUNDS {
            let aux = AuxRepr::new(0, i);
            n = security::secure_default_with::<NodeCipher>(
                &header,
                &aux,
                &KEY,
                ext_addr(PAN, 0x0100),
                payload,
                &mut psdu,
            )
            .ok()?;
        }
        let t1 = time::cycles();
        for _ in 0..ROUNDS {
            let opened = security::open_default_with::<NodeCipher, _>(
                psdu.get(..n)?,
                |_, _| Some((KEY, ext_addr(PAN, 0x0100))),
                &mut scratch,
            )
            .ok()?;
            if opened.payload != payload {
                return None;
            }
        }
        let t2 = time::cycles();
        Some((ns(t1.saturating_sub(t0)), ns(t2.saturating_sub(t1))))
    })
}
