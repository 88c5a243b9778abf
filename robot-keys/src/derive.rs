//! Key derivation: HKDF-SHA256 (RFC 5869) from the machine secret.
//!
//! Why HKDF-SHA256 and not AES-CMAC (NIST SP 800-108): the input is a 32-byte secret and
//! only the tool derives (nodes are provisioned), so nothing favours reusing the nodes'
//! AES; HKDF is built to take a 256-bit secret whole (extract, then expand), has the
//! published vectors of RFC 5869 that the tests check, and the RustCrypto `hkdf` and
//! `sha2` crates are well kept.
//!
//! ```text
//! PRK            = HKDF-Extract(salt = "robot-keys v1", IKM = machine secret)
//! management key = HKDF-Expand(PRK, "management" 0x00 node(u16 BE), 16)
//! link key       = HKDF-Expand(PRK, "link" 0x00 generation(u32 BE) sender(u16 BE)
//!                                   receiver(u16 BE), 16)
//! ```
//!
//! The labels hold no 0x00 and every field after it has a fixed width, so no two inputs
//! share an `info`. HKDF is one-way: a key reveals neither the secret nor another key.

use config_schema::link_keys::{LinkKeys, PeerKeys};
use hkdf::Hkdf;
use sha2::Sha256;

use crate::secret::{Key, MachineSecret, KEY_LEN};

/// HKDF's salt: names the scheme and its version (a new scheme takes a new salt).
pub const SALT: &[u8] = b"robot-keys v1";

/// The management key of node `node`: it protects what passes between the tool and that
/// node (config transfer, commands, status), and is what the node is provisioned with.
pub fn management_key(secret: &MachineSecret, node: u16) -> Key {
    expand(secret, &[b"management", &[0], &node.to_be_bytes()])
}

/// The link key for events from `sender` to `receiver` in tables of `generation`: one
/// key per direction and per generation, delivered to both nodes inside their pushes.
pub fn link_key(secret: &MachineSecret, generation: u32, sender: u16, receiver: u16) -> Key {
    expand(
        secret,
        &[
            b"link",
            &[0],
            &generation.to_be_bytes(),
            &sender.to_be_bytes(),
            &receiver.to_be_bytes(),
        ],
    )
}

/// The link key block of node `node` for a table of `generation` with `peers`: per peer the
/// key `node` sends under and the key it opens the peer's frames with. `None` if there are
/// more peers than a table may have.
pub fn link_keys(
    secret: &MachineSecret,
    generation: u32,
    node: u16,
    peers: &[u16],
) -> Option<LinkKeys> {
    let mut keys = LinkKeys {
        generation,
        peers: Default::default(),
    };
    for &peer in peers {
        keys.peers
            .push(PeerKeys {
                peer,
                send: *link_key(secret, generation, node, peer).expose(),
                receive: *link_key(secret, generation, peer, node).expose(),
            })
            .ok()?;
    }
    Some(keys)
}

fn expand(secret: &MachineSecret, info: &[&[u8]]) -> Key {
    let hk = Hkdf::<Sha256>::new(Some(SALT), secret.expose());
    let mut okm = [0u8; KEY_LEN];
    hk.expand_multi_info(info, &mut okm)
        .expect("16 bytes is a valid HKDF-SHA256 output length");
    let key = Key::from_bytes(okm);
    zeroize::Zeroize::zeroize(&mut okm);
    key
}

#[cfg(test)]
mod tests {
    use std::collections::HashSet;

    use super::*;

    fn hex(s: &str) -> Vec<u8> {
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    }

    fn okm(salt: Option<&[u8]>, ikm: &[u8], info: &[u8]) -> Vec<u8> {
        let mut out = vec![0u8; 42];
        Hkdf::<Sha256>::new(salt, ikm)
            .expand(info, &mut out)
            .unwrap();
        out
    }

    /// RFC 5869, A.1 (test case 1): HKDF-SHA256 with salt and info.
    #[test]
    fn rfc5869_test_case_1() {
        let ikm = [0x0b; 22];
        let salt = hex("000102030405060708090a0b0c");
        let info = hex("f0f1f2f3f4f5f6f7f8f9");
        let (prk, _) = Hkdf::<Sha256>::extract(Some(&salt), &ikm);
        assert_eq!(
            prk.to_vec(),
            hex("077709362c2e32df0ddc3f0dc47bba6390b6c73bb50f9c3122ec844ad7c2b3e5")
        );
        assert_eq!(
            okm(Some(&salt), &ikm, &info),
            hex("3cb25f25faacd57a90434f64d0362f2a2d2d0a90cf1a5a4c5db02d56ecc4c5bf34007208d5b887185865")
        );
    }

    /// RFC 5869, A.3 (test case 3): no salt, no info.
    #[test]
    fn rfc5869_test_case_3() {
        let ikm = [0x0b; 22];
        assert_eq!(
            okm(None, &ikm, &[]),
            hex("8da4e775a563c18f715f802a063c5a31b8a11f5c5ee1879ec3454e5f3c738d2d9d201395faa4b61a96c8")
        );
    }

    fn secret() -> MachineSecret {
        let mut b = [0u8; 32];
        for (i, x) in b.iter_mut().enumerate() {
            *x = i as u8;
        }
        MachineSecret::from_bytes(b)
    }

    /// The scheme itself, against an HKDF written separately (Python's hmac + hashlib,
    /// RFC 5869 section 2) over the same salt and info encoding.
    #[test]
    fn derived_keys_match_an_independent_hkdf() {
        let s = secret();
        assert_eq!(
            management_key(&s, 0x0011).expose().to_vec(),
            hex("a65fc7a6fd940aa8567e4224a6c1ce5e")
        );
        assert_eq!(
            management_key(&s, 0x0012).expose().to_vec(),
            hex("b4c8fe54b94d9b23911be3ac7411f16e")
        );
        assert_eq!(
            link_key(&s, 1, 0x0011, 0x0012).expose().to_vec(),
            hex("80ff28139f69a0011b800414c8911ebb")
        );
        assert_eq!(
            link_key(&s, 1, 0x0012, 0x0011).expose().to_vec(),
            hex("e5899deac378227033e99f5c70e5a15a")
        );
        assert_eq!(
            link_key(&s, 2, 0x0011, 0x0012).expose().to_vec(),
            hex("e6a1f34b4c5dc2f280393ca8531d1649")
        );
    }

    #[test]
    fn nodes_generations_and_directions_get_different_keys() {
        let s = secret();
        let mut seen = HashSet::new();
        let nodes = [0x0000, 0x0001, 0x0011, 0x0012, 0x0100, 0x1100, 0xFFFD];
        for n in nodes {
            assert!(
                seen.insert(*management_key(&s, n).expose()),
                "management {n:#06x}"
            );
        }
        for g in [0, 1, 2, 0x0100_0000, u32::MAX] {
            for a in nodes {
                for b in nodes {
                    if a != b {
                        let k = link_key(&s, g, a, b);
                        assert!(seen.insert(*k.expose()), "link {g} {a:#06x}->{b:#06x}");
                    }
                }
            }
        }
        // Another machine's secret gives other keys for the same node.
        let other = MachineSecret::from_bytes([7; 32]);
        assert_ne!(
            management_key(&other, 0x0011).expose(),
            management_key(&s, 0x0011).expose()
        );
    }

    #[test]
    fn derivation_is_deterministic() {
        let s = secret();
        assert_eq!(
            management_key(&s, 3).expose(),
            management_key(&s.clone(), 3).expose()
        );
    }
}
