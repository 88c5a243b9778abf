//! A machine over the radio: the tool's radio on a medium ([`radio`]), OTA push and
//! reliable commands ([`push`]), the real-time plant ([`live_plant`]), a monitor that
//! reports faults and outputs as they happen ([`watch`]), and the test bed that runs a
//! whole machine on this host ([`demo`]); [`keyring`] opens any secured frame of the
//! machine for a listener.

pub mod demo;
mod error;
pub mod keyring;
pub mod live_plant;
pub mod push;
pub mod radio;
pub mod show;
pub mod watch;

pub use error::NetError;
