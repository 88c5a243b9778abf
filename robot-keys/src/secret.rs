//! The secret types: bytes that never reach a log.

use std::fmt;

use zeroize::Zeroize;

/// Length of the machine secret in bytes.
pub const SECRET_LEN: usize = 32;
/// Length of a derived key (AES-128) in bytes.
pub const KEY_LEN: usize = 16;

/// The machine secret: 32 random bytes every key of one machine is derived from.
#[derive(Clone)]
pub struct MachineSecret([u8; SECRET_LEN]);

impl MachineSecret {
    /// 32 bytes from the operating system's random source.
    pub fn generate() -> Result<MachineSecret, getrandom::Error> {
        let mut bytes = [0u8; SECRET_LEN];
        getrandom::fill(&mut bytes)?;
        Ok(MachineSecret(bytes))
    }

    /// A secret with these bytes (tests, and the key file's reader).
    pub fn from_bytes(bytes: [u8; SECRET_LEN]) -> MachineSecret {
        MachineSecret(bytes)
    }

    /// The bytes. Only the key file's writer and the derivation need them.
    pub fn expose(&self) -> &[u8; SECRET_LEN] {
        &self.0
    }
}

impl fmt::Debug for MachineSecret {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("MachineSecret(<secret>)")
    }
}

impl Drop for MachineSecret {
    fn drop(&mut self) {
        self.0.zeroize();
    }
}

/// A 128-bit key derived from the machine secret (a management or a link key).
#[derive(Clone)]
pub struct Key([u8; KEY_LEN]);

impl Key {
    pub(crate) fn from_bytes(bytes: [u8; KEY_LEN]) -> Key {
        Key(bytes)
    }

    /// The bytes: for provisioning (what to flash) and for the frame codec.
    pub fn expose(&self) -> &[u8; KEY_LEN] {
        &self.0
    }
}

impl fmt::Debug for Key {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Key(<secret>)")
    }
}

impl Drop for Key {
    fn drop(&mut self) {
        self.0.zeroize();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn debug_never_shows_the_bytes() {
        let s = MachineSecret::from_bytes([0xAB; SECRET_LEN]);
        let k = Key::from_bytes([0xCD; KEY_LEN]);
        assert_eq!(format!("{s:?}"), "MachineSecret(<secret>)");
        assert_eq!(format!("{k:?}"), "Key(<secret>)");
        assert_eq!(format!("{:?}", Some(&k)), "Some(Key(<secret>))");
    }

    #[test]
    fn generated_secrets_differ() {
        let a = MachineSecret::generate().unwrap();
        let b = MachineSecret::generate().unwrap();
        assert_ne!(a.expose(), b.expose());
        assert_ne!(a.expose(), &[0; SECRET_LEN]);
    }
}
