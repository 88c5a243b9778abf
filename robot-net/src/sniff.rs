//! The monitor's reading of the air: every frame in readable form, secured frames opened
//! when the machine secret is at hand (docs/security.md).
//!
//! Management frames (config PAN, key index 0) are tried with the management key of each
//! end of the exchange (the node is one of them; the tool's address need not be known).
//! Link frames (the robot's PAN, key index `1 + generation % 255`) carry no generation, so
//! the sniffer tries the generations it has seen in opened management traffic (and the
//! one it was given) whose key index matches. A frame that does not open is shown, marked
//! with why; no key is ever printed.

use std::collections::BTreeSet;

use config_schema::wire::mac::{Frame, Header, BROADCAST};
use config_schema::wire::msg::{ConfigReply, Message};
use config_schema::wire::security::{
    self, ext_addr, link_key_index, AuxHeader, AuxRepr, SecError, SecurityLevel, KEY_LEN,
};
use node_fw::node::{CONFIG_PAN, MANAGEMENT_KEY_INDEX};
use robot_keys::{link_key, management_key, MachineSecret};

use crate::show;

/// Generations remembered at most (the oldest is forgotten first).
pub const MAX_GENERATIONS: usize = 32;

/// Describes frames, opening the secured ones it has a key for.
pub struct Sniffer {
    secret: Option<MachineSecret>,
    generations: BTreeSet<u32>,
}

impl Sniffer {
    /// A sniffer with the machine secret (or none: secured frames show as sealed) and a
    /// generation to try for link frames before any is seen.
    pub fn new(secret: Option<MachineSecret>, generation: Option<u32>) -> Sniffer {
        let mut s = Sniffer {
            secret,
            generations: BTreeSet::new(),
        };
        if let Some(g) = generation {
            s.learn(g);
        }
        s
    }

    /// The generations it tries for link frames, lowest first.
    pub fn generations(&self) -> impl Iterator<Item = u32> + '_ {
        self.generations.iter().copied()
    }

    fn learn(&mut self, generation: u32) {
        self.generations.insert(generation);
        while self.generations.len() > MAX_GENERATIONS {
            self.generations.pop_first();
        }
    }

    /// One frame in readable form: `SRC -> DST  secured LEVEL key K counter C: MESSAGE`
    /// (or the reason it did not open), `SRC -> DST  unsecured: MESSAGE`, `ack SEQ`.
    pub fn describe(&mut self, psdu: &[u8]) -> String {
        let (header, payload) = match Frame::parse(psdu) {
            Ok(Frame::Data { header, payload }) => (header, payload),
            Ok(Frame::Ack { seq, .. }) => return format!("ack {seq}"),
            Err(e) => return format!("bad frame ({e}), {} bytes", psdu.len()),
        };
        let ends = format!("{:#06x} -> {:#06x}", header.src, header.dst);
        if !header.secured {
            return format!("{ends}  unsecured: {}", show::message_text(payload));
        }
        let (aux, sealed) = match AuxHeader::new_checked(payload) {
            Ok(view) => (
                AuxRepr::parse(&view),
                payload.len().saturating_sub(view.header_len()),
            ),
            Err(e) => return format!("{ends}  secured, but {e}"),
        };
        let fields = format!(
            "{:?} key {} counter {}",
            aux.level,
            aux.key_id
                .index()
                .map_or_else(|| "implicit".to_string(), |i| i.to_string()),
            aux.frame_counter
        );
        if self.secret.is_none() {
            return format!("{ends}  secured (no key) {fields}: {sealed} bytes sealed");
        }
        let what = match self.open_with(psdu, &header, &aux) {
            Ok(payload) => show::message_text(&payload),
            Err(SecError::BadMic) => format!("BAD MIC, {sealed} bytes sealed"),
            Err(SecError::UnknownKey) => format!("unknown key, {sealed} bytes sealed"),
            Err(e) => format!("refused ({e}), {sealed} bytes sealed"),
        };
        format!("{ends}  secured {fields}: {what}")
    }

    /// The plain payload of a secured frame (what a listener acts on: the demo's watch
    /// reads the machine's fault events with it).
    pub fn open(&mut self, psdu: &[u8]) -> Result<Vec<u8>, SecError> {
        let (header, payload) = match Frame::parse(psdu)? {
            Frame::Data { header, payload } if header.secured => (header, payload),
            _ => return Err(SecError::NotSecured),
        };
        let aux = AuxRepr::parse(&AuxHeader::new_checked(payload)?);
        self.open_with(psdu, &header, &aux)
    }

    /// Opens the frame with each candidate key in turn: the plain payload, or `UnknownKey`
    /// (no key, or no candidate for its key index), or the last candidate's error.
    fn open_with(
        &mut self,
        psdu: &[u8],
        header: &Header,
        aux: &AuxRepr,
    ) -> Result<Vec<u8>, SecError> {
        let Some(secret) = self.secret.as_ref() else {
            return Err(SecError::UnknownKey);
        };
        let index = aux.key_id.index();
        let nonce_addr = ext_addr(header.pan_id, header.src);
        let keys: Vec<[u8; KEY_LEN]> = if header.pan_id == CONFIG_PAN {
            let mut ends = vec![header.src];
            if header.dst != header.src && header.dst != BROADCAST {
                ends.push(header.dst);
            }
            ends.into_iter()
                .filter(|_| index == Some(MANAGEMENT_KEY_INDEX))
                .map(|node| *management_key(secret, node).expose())
                .collect()
        } else {
            self.generations
                .iter()
                .filter(|g| Some(link_key_index(**g)) == index)
                .map(|g| *link_key(secret, *g, header.src, header.dst).expose())
                .collect()
        };
        let mut scratch = [0u8; config_schema::wire::mac::MAX_PAYLOAD];
        if keys.is_empty() {
            // The codec says why: a level or header it refuses, else the unknown key.
            return match security::open_at(psdu, SecurityLevel::EncMic64, |_, _| None, &mut scratch)
            {
                Ok(_) => Err(SecError::UnknownKey),
                Err(e) => Err(e),
            };
        }
        let mut last = SecError::UnknownKey;
        for key in keys {
            let opened = security::open_at(
                psdu,
                SecurityLevel::EncMic64,
                |_, _| Some((key, nonce_addr)),
                &mut scratch,
            );
            match opened {
                Ok(o) => {
                    let plain = o.payload.to_vec();
                    if header.pan_id == CONFIG_PAN {
                        if let Some(g) = Message::parse(o.payload).ok().and_then(|m| generation(&m))
                        {
                            self.learn(g);
                        }
                    }
                    return Ok(plain);
                }
                // Refused before any key was tried: no other key changes that.
                Err(e @ (SecError::Level { .. } | SecError::Malformed | SecError::NoMic)) => {
                    return Err(e)
                }
                Err(e) => last = e,
            }
        }
        Err(last)
    }
}

/// The generation an authentic management message names, if any: link keys of that
/// generation may be in use.
fn generation(m: &Message) -> Option<u32> {
    match m {
        Message::ConfigBegin { generation, .. }
        | Message::ConfigEnd { generation }
        | Message::ConfigReply {
            generation,
            reply: ConfigReply::Activated,
        } => Some(*generation),
        Message::Status(s) => Some(s.generation),
        Message::Announce(a) => Some(a.generation),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use config_schema::wire::msg::{Announce, Command};
    use config_schema::wire::security::secure;

    const TOOL: u16 = 0x0100;
    const VC: u16 = 0x0011;
    const GR: u16 = 0x0012;
    const ROBOT_PAN: u16 = 0xBEEF;

    fn secret() -> MachineSecret {
        MachineSecret::from_bytes(core::array::from_fn(|i| i as u8))
    }

    fn header(pan_id: u16, src: u16, dst: u16) -> Header {
        Header {
            seq: 7,
            pan_id,
            dst,
            src,
            ack_request: true,
            secured: false,
        }
    }

    fn sealed(h: Header, index: u8, counter: u32, key: &[u8; 16], m: &Message) -> Vec<u8> {
        let mut payload = [0u8; 116];
        let n = m.emit(&mut payload).unwrap();
        let mut psdu = [0u8; 127];
        let len = secure(
            &h,
            &AuxRepr::new(index, counter),
            key,
            ext_addr(h.pan_id, h.src),
            &payload[..n],
            &mut psdu,
        )
        .unwrap();
        psdu[..len].to_vec()
    }

    fn start_from_tool() -> Vec<u8> {
        let key = management_key(&secret(), VC);
        let start = Message::Command {
            id: 3,
            command: Command::Start,
        };
        sealed(header(CONFIG_PAN, TOOL, VC), 0, 42, key.expose(), &start)
    }

    fn announce_from(node: u16, generation: u32) -> Vec<u8> {
        let key = management_key(&secret(), node);
        let m = Message::Announce(Announce {
            firmware: 1,
            generation,
            role: heapless::String::try_from("VC").unwrap(),
            table: config_schema::TableId::from_crc(0x1234_abcd),
            staged: 0,
            nonce: 0,
        });
        sealed(header(CONFIG_PAN, node, BROADCAST), 0, 9, key.expose(), &m)
    }

    fn event(generation: u32, counter: u32) -> Vec<u8> {
        let key = link_key(&secret(), generation, VC, GR);
        let m = Message::Event {
            epoch: 1,
            seq: 4,
            topic: 2,
        };
        let index = link_key_index(generation);
        sealed(header(ROBOT_PAN, VC, GR), index, counter, key.expose(), &m)
    }

    /// Flips one bit of the sealed payload and mends the FCS: only the MIC can tell.
    fn flipped(mut psdu: Vec<u8>) -> Vec<u8> {
        psdu[16] ^= 0x01;
        let n = psdu.len() - 2;
        let fcs = config_schema::wire::mac::FCS.checksum(&psdu[..n]);
        psdu[n..].copy_from_slice(&fcs.to_le_bytes());
        psdu
    }

    #[test]
    fn a_secured_management_frame_is_shown_decrypted() {
        let mut s = Sniffer::new(Some(secret()), None);
        assert_eq!(
            s.describe(&start_from_tool()),
            "0x0100 -> 0x0011  secured EncMic64 key 0 counter 42: \
             Command { id: 3, command: Start }"
        );
    }

    #[test]
    fn a_bit_flipped_frame_is_marked_bad_mic() {
        let mut s = Sniffer::new(Some(secret()), Some(5));
        assert_eq!(
            s.describe(&flipped(start_from_tool())),
            "0x0100 -> 0x0011  secured EncMic64 key 0 counter 42: BAD MIC, 11 bytes sealed"
        );
        assert_eq!(
            s.describe(&flipped(event(5, 11))),
            "0x0011 -> 0x0012  secured EncMic64 key 6 counter 11: BAD MIC, 12 bytes sealed"
        );
    }

    #[test]
    fn a_frame_under_another_secret_is_marked_bad_mic() {
        let mut s = Sniffer::new(Some(MachineSecret::from_bytes([9; 32])), None);
        assert_eq!(
            s.describe(&start_from_tool()),
            "0x0100 -> 0x0011  secured EncMic64 key 0 counter 42: BAD MIC, 11 bytes sealed"
        );
    }

    #[test]
    fn a_link_frame_opens_once_its_generation_was_seen_and_an_unknown_key_is_marked() {
        let mut s = Sniffer::new(Some(secret()), None);
        // No generation seen yet: no key has index 4.
        assert_eq!(
            s.describe(&event(3, 11)),
            "0x0011 -> 0x0012  secured EncMic64 key 4 counter 11: unknown key, 12 bytes sealed"
        );
        // The node's authentic announcement names generation 3.
        assert_eq!(
            s.describe(&announce_from(VC, 3)),
            "0x0011 -> 0xffff  secured EncMic64 key 0 counter 9: \
             Announce(Announce { firmware: 1, generation: 3, role: \"VC\", \
             table: TableId(0x1234abcd), staged: 0, nonce: 0 })"
        );
        assert_eq!(s.generations().collect::<Vec<_>>(), [3]);
        assert_eq!(
            s.describe(&event(3, 12)),
            "0x0011 -> 0x0012  secured EncMic64 key 4 counter 12: \
             Event { epoch: 1, seq: 4, topic: 2 }"
        );
        // Generation 258 shares key index 4 with 3: both are tried.
        let mut s = Sniffer::new(Some(secret()), Some(258));
        s.describe(&announce_from(VC, 3));
        assert_eq!(
            s.describe(&event(258, 13)),
            "0x0011 -> 0x0012  secured EncMic64 key 4 counter 13: \
             Event { epoch: 1, seq: 4, topic: 2 }"
        );
        // A management frame under a key index the config PAN does not use.
        let key = management_key(&secret(), VC);
        let m = Message::Command {
            id: 1,
            command: Command::Reset,
        };
        let other = sealed(header(CONFIG_PAN, TOOL, VC), 9, 1, key.expose(), &m);
        assert_eq!(
            s.describe(&other),
            "0x0100 -> 0x0011  secured EncMic64 key 9 counter 1: unknown key, 11 bytes sealed"
        );
    }

    #[test]
    fn a_frame_at_another_level_is_marked_refused_as_a_node_refuses_it() {
        let key = management_key(&secret(), VC);
        let h = header(CONFIG_PAN, TOOL, VC);
        let aux = AuxRepr {
            level: SecurityLevel::Mic32,
            ..AuxRepr::new(0, 5)
        };
        let mut psdu = [0u8; 127];
        let n = secure(
            &h,
            &aux,
            key.expose(),
            ext_addr(CONFIG_PAN, TOOL),
            &[1, 2, 3],
            &mut psdu,
        )
        .unwrap();
        let mut s = Sniffer::new(Some(secret()), None);
        assert_eq!(
            s.describe(&psdu[..n]),
            "0x0100 -> 0x0011  secured Mic32 key 0 counter 5: refused (security level Mic32, \
             not the required EncMic64), 7 bytes sealed"
        );
    }

    #[test]
    fn a_forged_announcement_teaches_no_generation() {
        let mut s = Sniffer::new(Some(secret()), None);
        s.describe(&flipped(announce_from(VC, 7)));
        assert_eq!(s.generations().count(), 0);
    }

    #[test]
    fn an_unsecured_frame_and_a_frame_without_keys() {
        let mut s = Sniffer::new(Some(secret()), None);
        let mut psdu = [0u8; 127];
        let mut payload = [0u8; 116];
        let m = Message::Command {
            id: 3,
            command: Command::Start,
        };
        let n = m.emit(&mut payload).unwrap();
        let len = config_schema::wire::mac::emit_data(
            &header(CONFIG_PAN, 0xBEEF, VC),
            &payload[..n],
            &mut psdu,
        )
        .unwrap();
        assert_eq!(
            s.describe(&psdu[..len]),
            "0xbeef -> 0x0011  unsecured: Command { id: 3, command: Start }"
        );
        let mut blind = Sniffer::new(None, Some(3));
        assert_eq!(
            blind.describe(&start_from_tool()),
            "0x0100 -> 0x0011  secured (no key) EncMic64 key 0 counter 42: 11 bytes sealed"
        );
    }
}
