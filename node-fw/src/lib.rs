//! The generic node firmware.
//!
//! - [`ecc`]: the table interpreter (pure, `no_std`, no allocation, no Embassy).
//! - `sim` (feature `std`): the host's deterministic virtual-time world with plant models.
#![cfg_attr(not(feature = "std"), no_std)]
#![forbid(unsafe_code)]

pub mod ecc;
#[cfg(feature = "std")]
pub mod sim;
