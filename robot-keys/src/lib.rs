//! The tool's keys (docs/security.md): the machine secret ([`MachineSecret`], one per
//! machine, in a key file only its owner can read: [`file`](mod@file)) and the keys derived from it
//! ([`derive`](mod@derive)): each node's management key and the per-generation pairwise link keys.
//!
//! The node never derives: it is provisioned with its management key at flash time, and
//! gets its link keys inside its authenticated push. Secrets print as `<secret>` in
//! `Debug` and are zeroed when dropped; only [`Key::expose`] and
//! [`MachineSecret::expose`] show the bytes.

pub mod derive;
pub mod file;
mod secret;

pub use derive::{link_key, link_keys, management_key};
pub use file::{load_machine_secret, write_machine_secret, write_secret_file, KeyFileError};
pub use secret::{Key, MachineSecret, KEY_LEN, SECRET_LEN};
