//! The generic node firmware.
//!
//! - [`alarms`]: the node's latched alarms (pure, shared with the simulator).
//! - [`cipher`]: the AES-128 under frame security (software, or the board's hardware).
//! - [`cylinder`]: the pneumatic plant's rules (valve, power-up, sensors, travel), pure.
//! - [`ecc`]: the table interpreter (pure, `no_std`, no allocation, no Embassy).
//! - [`epoch`]: the link epochs a node takes, reserved ahead by its boot counter.
//! - [`link`]: reliable, ordered event delivery over a lossy radio (pure state machines).
//! - [`node`]: the whole node as one pure state machine: frames in, frames and pins out.
//! - [`ota`]: over-the-air table transfer, node and tool sides (pure state machines).
//! - [`provision`]: what a node is given at flash time (address, flags, management key).
//! - [`restart`]: a peer's restart told (its greeting) and heard (once per restart).
//! - [`slots`]: the two table slots in flash, committed last so a power cut loses nothing.
//! - [`frame_counter`]: the secured frames' counter, reserved ahead in flash, never reused.
//! - [`runtime`]: the Embassy runtime around the node, generic over radio, pins and flash.
//! - `host` (feature `std`): the host board of `node-host` (radio = the simulated medium).
//! - `sim` (feature `std`): the host's deterministic virtual-time world with plant models.
#![cfg_attr(not(feature = "std"), no_std)]
#![forbid(unsafe_code)]

pub mod alarms;
pub mod cipher;
pub mod cylinder;
pub mod ecc;
pub mod epoch;
pub mod frame_counter;
#[cfg(feature = "std")]
pub mod host;
pub mod link;
pub mod node;
pub mod ota;
pub mod peer_security;
pub mod provision;
pub mod restart;
pub mod runtime;
#[cfg(feature = "std")]
pub mod sim;
pub mod slots;
pub mod switch;

/// Whether the image secures frames (feature `frame-security`, on by default and with
/// `std`). Without it a node never secures or opens a frame, whatever keys it is given:
/// the secured paths are dead code and the crypto is not linked. Only for measuring what
/// frame security costs (`bench/footprint.sh`): such a node is not for a machine.
pub const FRAME_SECURITY: bool = cfg!(feature = "frame-security");

/// Moves element `i` of `s` to its end, the others keeping their order (`rotate_left(1)`
/// of `s[i..]`; a `Vec` then pops it: `remove(i)`). By swaps: `Vec::remove` and `rotate`
/// are a `ptr::copy`, which links compiler_builtins' `memmove` (1.5 KB on the nRF52840).
pub(crate) fn to_end<T>(s: &mut [T], i: usize) {
    for j in i..s.len().saturating_sub(1) {
        if let Some([a, b]) = s.get_mut(j..j + 2) {
            core::mem::swap(a, b);
        }
    }
}

/// One more of a counter the node reports (frames received, dropped, refused, ...):
/// modulo 2^32, as network counters go (a reader takes differences), never the overflow
/// panic of a debug build after 2^32 flooded frames (about four weeks of them). Wrapping
/// costs no instruction; holding at `u32::MAX` cost 150 B of the nRF52840's flash.
pub(crate) fn count(counter: &mut u32) {
    *counter = counter.wrapping_add(1);
}

/// `v.remove(i)` (nothing if `i` is out of range) without `ptr::copy` ([`to_end`]).
pub(crate) fn remove_at<T, const N: usize>(v: &mut heapless::Vec<T, N>, i: usize) {
    if i < v.len() {
        to_end(v, i);
        v.pop();
    }
}

#[cfg(test)]
mod tests {
    /// The swaps do what `rotate_left` and `Vec::remove` do.
    #[test]
    fn the_swaps_rotate_and_remove_as_the_std_ones() {
        for len in 0..6 {
            for i in 0..=len {
                let mut a: std::vec::Vec<u8> = (0..len as u8).collect();
                let mut b = a.clone();
                super::to_end(&mut a, i);
                if i < len {
                    b[i..].rotate_left(1);
                }
                assert_eq!(a, b, "to_end {i} of {len}");
                let mut v: heapless::Vec<u8, 8> = (0..len as u8).collect();
                let mut w: std::vec::Vec<u8> = (0..len as u8).collect();
                super::remove_at(&mut v, i);
                if i < len {
                    w.remove(i);
                }
                assert_eq!(v.as_slice(), w.as_slice(), "remove {i} of {len}");
            }
        }
    }
}
