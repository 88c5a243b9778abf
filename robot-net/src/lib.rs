//! A machine over the radio: the tool's radio on a medium ([`radio`]), OTA push and
//! reliable commands ([`push`]), homing ([`home`]), the real-time plant ([`live_plant`], its motors [`live_motor`]), a monitor that
//! reports faults and outputs as they happen ([`watch`]), the monitor's reading of
//! the air, secured frames opened ([`sniff`]), and the test bed that runs a
//! whole machine on this host ([`demo`]).

pub mod demo;
mod error;
pub mod home;
pub mod live_feed;
pub mod live_motor;
pub mod live_plant;
pub mod push;
pub mod radio;
pub mod release;
pub mod show;
pub mod sniff;
pub mod watch;

pub use error::NetError;
