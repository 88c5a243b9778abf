//! The generic node firmware.
//!
//! - [`ecc`]: the table interpreter (pure, `no_std`, no allocation, no Embassy).
#![cfg_attr(not(feature = "std"), no_std)]
#![forbid(unsafe_code)]

pub mod ecc;
