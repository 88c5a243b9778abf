//! `panel`: the operator's page of the running machine (docs/panel.md). The port is
//! taken first (a second panel on it is refused before anything else is opened), then
//! the keys as `home` takes them (a secured robot needs them), the medium, and the page.

use std::net::SocketAddr;
use std::path::Path;

use robot_net::demo;
use robot_net::radio::{ToolRadio, TOOL_ADDR};
use robot_panel::{Listener, Panel};

use crate::cli::{KeysArg, MediumAddr};
use crate::commands::radio::{push_keys, resolve};
use crate::failure::Failure;
use crate::out::outln;
use crate::tool_keys::{self, KeysFrom};

pub fn panel(
    robot: &Path,
    at: &MediumAddr,
    listen: SocketAddr,
    keys: &KeysArg,
) -> Result<(), Failure> {
    let listener = Listener::bind(listen).map_err(Failure::error)?;
    let c = demo::load(robot)?;
    let keys = push_keys(robot, &c, KeysFrom::resolve(keys.keys.as_deref()))?;
    let keys = (keys.as_ref())
        .map(|k| tool_keys::open(k.path()))
        .transpose()
        .map_err(Failure::error)?;
    let medium = resolve(at)?;
    let mut radio = ToolRadio::connect(medium, TOOL_ADDR)
        .map_err(|e| Failure::error(format!("cannot reach the medium at {medium}: {e}")))?;
    let secret = keys.as_ref().map(|k| k.secret.clone());
    if let Some(k) = keys {
        radio.secure(k.secret, k.counter);
    }
    let panel = Panel::start(listener, c, medium, secret).map_err(Failure::error)?;
    outln!("panel of {} on {}", robot.display(), panel.url());
    if let Some(t) = panel.token() {
        outln!(
            "token: {t} (the panel listens off loopback: every request must carry it, as \
             the address above does)"
        );
    }
    panel.serve(radio);
    Ok(())
}
