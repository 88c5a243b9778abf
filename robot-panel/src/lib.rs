//! The operator's panel (docs/panel.md): one web page of the running machine, served by
//! the tool. The page model comes from the robot file ([`model`]); the live machine
//! ([`live`]) is fed by a monitor on the medium ([`feed`]: every pin change as it
//! happens) and by the tool's radio asking each node its status and alarms ([`poll`]),
//! which also carries out the operator's buttons ([`buttons`]: each allowed only when the
//! machine's state allows it) through the same `robot_net` functions as the CLI. The
//! server ([`server`]) sends the page (plain HTML, SVG and a little JavaScript, embedded
//! in the binary) and pushes every change to it as a server-sent event.

pub mod buttons;
mod error;
pub mod feed;
pub mod http;
pub mod live;
pub mod model;
pub mod poll;
pub mod server;
pub mod shared;
pub mod streams;
pub mod view;

pub use error::PanelError;
pub use server::{Listener, Panel};
