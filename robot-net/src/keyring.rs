//! Opening any frame of the machine with the machine secret: what a tool that only listens
//! (the demo's watch, a monitor) needs to read secured traffic.
//!
//! A management frame (config PAN, key index 0) is under the management key of its node
//! end; an event frame (the robot's PAN) is under `link_key(G, src, dst)` for the
//! generation G whose key index it carries, among the generations this keyring was told
//! of. Replay is not checked here: a listener acts on nothing.

use config_schema::wire::security::{self, ext_addr, link_key_index, Opened, SecError};
use robot_keys::MachineSecret;

use node_fw::node::CONFIG_PAN;

/// The machine secret and the generations whose link keys may be in use.
#[derive(Clone)]
pub struct Keyring {
    secret: MachineSecret,
    generations: Vec<u32>,
    /// Addresses that are not nodes (the tool's): a management frame from one is under
    /// the key of its destination.
    tools: Vec<u16>,
}

impl std::fmt::Debug for Keyring {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Keyring")
            .field("generations", &self.generations)
            .finish_non_exhaustive()
    }
}

impl Keyring {
    pub fn new(secret: MachineSecret) -> Keyring {
        Keyring {
            secret,
            generations: Vec::new(),
            tools: vec![crate::radio::TOOL_ADDR],
        }
    }

    /// Link keys of `generation` may be in use (the latest told wins a shared index).
    pub fn add_generation(&mut self, generation: u32) {
        self.generations.retain(|&g| g != generation);
        self.generations.push(generation);
    }

    /// Opens a secured frame (any level with a MIC: a listener reports what it saw).
    pub fn open<'s>(&self, psdu: &[u8], scratch: &'s mut [u8]) -> Result<Opened<'s>, SecError> {
        security::open(
            psdu,
            |header, aux| {
                let index = aux.key_id.index()?;
                let key = if header.pan_id == CONFIG_PAN {
                    let node = if self.tools.contains(&header.src) {
                        header.dst
                    } else {
                        header.src
                    };
                    (index == 0).then(|| robot_keys::management_key(&self.secret, node))?
                } else {
                    let g = self
                        .generations
                        .iter()
                        .rev()
                        .find(|&&g| link_key_index(g) == index)?;
                    robot_keys::link_key(&self.secret, *g, header.src, header.dst)
                };
                Some((*key.expose(), ext_addr(header.pan_id, header.src)))
            },
            scratch,
        )
    }
}
