//! AES-128 on the nRF52840's AES-ECB peripheral: the block cipher under the node's frame
//! security (`node_fw::cipher`, feature `ecb`), instead of AES in software.
//!
//! The peripheral encrypts one block per STARTECB, reading key and cleartext from RAM by
//! EasyDMA and writing the ciphertext after them: ECBDATAPTR points at
//! `key[16] | cleartext[16] | ciphertext[16]`, all in AES byte order (the key's first byte
//! at the lowest address). A block takes about 7 us (nRF52840 PS, ECB: t_ECB); the CPU
//! waits on ENDECB, at most [`MAX_POLLS`] reads, and ERRORECB (aborted: by STOPECB, or by
//! the CCM/AAR peripherals, which this image never uses) or no end within the bound is a
//! [`CipherFault`]: the frame is not sent, or not accepted.
//!
//! Built, not run: no nRF52840 hardware here and QEMU does not emulate it (docs/boards.md).
//! The software cipher it replaces is tested on the host against the same vectors.

use core::sync::atomic::{compiler_fence, Ordering};

use config_schema::wire::security::{CipherFault, BLOCK_LEN, KEY_LEN};
use embassy_nrf::pac::ECB;

/// ENDECB polls before a block is given up (about 7 us at 64 MHz is a few hundred
/// cycles; this is milliseconds).
const MAX_POLLS: u32 = 100_000;

/// Makes the ECB peripheral the node's AES-128 (once, at boot). embassy-nrf has no ECB
/// driver (nor a singleton for it): nothing else in the image touches it.
pub fn install() {
    ECB.intenclr().write(|w| {
        w.set_endecb(true);
        w.set_errorecb(true);
    });
    node_fw::cipher::install(encrypt);
}

/// Encrypts `block` in place under `key`.
fn encrypt(key: &[u8; KEY_LEN], block: &mut [u8; BLOCK_LEN]) -> Result<(), CipherFault> {
    // key | cleartext | ciphertext, on the stack (RAM, as EasyDMA needs).
    // Three blocks, contiguous: no slicing, so no panic location in the image.
    let mut data: [[u8; BLOCK_LEN]; 3] = [*key, *block, [0; BLOCK_LEN]];
    ECB.events_endecb().write_value(0);
    ECB.events_errorecb().write_value(0);
    ECB.ecbdataptr().write_value(data.as_mut_ptr() as u32);
    // The buffer is written before the peripheral reads it.
    compiler_fence(Ordering::SeqCst);
    ECB.tasks_startecb().write_value(1);
    let mut done = false;
    for _ in 0..MAX_POLLS {
        if ECB.events_errorecb().read() != 0 {
            break;
        }
        if ECB.events_endecb().read() != 0 {
            done = true;
            break;
        }
    }
    if !done {
        ECB.tasks_stopecb().write_value(1);
    }
    // The ciphertext is read after the peripheral wrote it.
    compiler_fence(Ordering::SeqCst);
    ECB.events_endecb().write_value(0);
    ECB.events_errorecb().write_value(0);
    if !done {
        return Err(CipherFault);
    }
    let [_, _, cipher] = data;
    *block = cipher;
    Ok(())
}
