//! Wire formats, parsed and emitted without allocation and without panics on any input
//! (smoltcp style: this layer knows bytes, not protocol state).
//!
//! - [`mac`]: IEEE 802.15.4-2006 MAC frames (the subset the nodes use).
//! - [`security`]: IEEE 802.15.4 frame security: the auxiliary security header, AES-128-CCM*
//!   secure / open of a data frame, and the receivers' replay guard.
//! - [`msg`]: the application messages inside them (postcard).
//! - [`medium`]: the framing of a connection to the simulated medium (and UART bridges).

pub mod mac;
pub mod medium;
pub mod msg;

/// The short address `config-tool` sends and receives from (push, commands, status): no
/// node may have it.
pub const TOOL_ADDR: u16 = 0x0100;
pub mod security;

/// `dst = src` if they are as long (else `None`, nothing copied). Not `copy_from_slice`:
/// where the optimizer leaves that out of line, its panic location (the caller's source
/// path) stays in a firmware image, whose size then depends on where the checkout lives.
pub(crate) fn copy(dst: &mut [u8], src: &[u8]) -> Option<()> {
    if dst.len() != src.len() {
        return None;
    }
    dst.iter_mut().zip(src).for_each(|(d, s)| *d = *s);
    Some(())
}
