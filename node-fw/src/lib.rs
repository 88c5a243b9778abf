//! The generic node firmware.
//!
//! - [`alarms`]: the node's latched alarms (pure, shared with the simulator).
//! - [`cipher`]: the AES-128 under frame security (software, or the board's hardware).
//! - [`cylinder`]: the pneumatic plant's rules (valve, power-up, sensors, travel), pure.
//! - [`ecc`]: the table interpreter (pure, `no_std`, no allocation, no Embassy).
//! - [`link`]: reliable, ordered event delivery over a lossy radio (pure state machines).
//! - [`node`]: the whole node as one pure state machine: frames in, frames and pins out.
//! - [`ota`]: over-the-air table transfer, node and tool sides (pure state machines).
//! - [`provision`]: what a node is given at flash time (address, flags, management key).
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
pub mod frame_counter;
#[cfg(feature = "std")]
pub mod host;
pub mod link;
pub mod node;
pub mod ota;
pub mod peer_security;
pub mod provision;
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
