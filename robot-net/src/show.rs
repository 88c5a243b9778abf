//! What nodes say, in readable form: a status, a security report, the answer to a reset,
//! a frame.

use config_schema::wire::mac::Frame;
use config_schema::wire::msg::{Message, SecurityReport, Status};
use config_schema::wire::security::{AuxHeader, AuxRepr};

/// A node's role as it reports it, for people: `(unconfigured)` without a table, `(no
/// role)` for a table with none (a node a push released: it plays no role in the robot).
pub fn role_text(role: &str, generation: u32) -> &str {
    match (role.is_empty(), generation) {
        (false, _) => role,
        (true, 0) => "(unconfigured)",
        (true, _) => "(no role)",
    }
}

/// A status in readable form.
pub fn status_text(addr: u16, s: &Status) -> String {
    let role = role_text(&s.role, s.generation);
    let states: Vec<String> = s.states.iter().map(|x| format!("S{x}")).collect();
    let (c, r) = (s.counters, s.runtime);
    format!(
        "{addr:#06x}  role {role}  generation {}{}{}\n  states {}  outputs {:#06x}  inputs {:#06x}  fault {}\n  link alarms {:#010b}  broken {:#010b}  epoch {}\n  frames sent {} received {} retried {} dropped {}  events delivered {}\n  tx queue full {}  high-water {}  radio failures {}  flash failures {}",
        s.generation,
        if s.trial { "  on trial" } else { "" },
        staged_note(s.staged),
        if states.is_empty() { "-".to_string() } else { states.join(" ") },
        s.outputs,
        s.inputs,
        s.fault.map_or("none".to_string(), |f| format!("{f:#04x}")),
        s.link_alarms,
        s.links_broken,
        s.epoch,
        c.sent,
        c.received,
        c.retried,
        c.dropped,
        c.delivered,
        r.tx_queue_full,
        r.tx_queue_high,
        r.tx_failed,
        r.flash_failures,
    )
}

/// `  staged N` when generation N waits for the switch-over, else nothing.
pub fn staged_note(staged: u32) -> String {
    match staged {
        0 => String::new(),
        g => format!("  staged {g}"),
    }
}

/// A node's security report as the line `status` prints after the status: whether it
/// has a management key, the frames it dropped by reason, the senders it challenged after
/// its boot (normal: the first frame of each sender), the frames it could not secure.
pub fn security_text(r: &SecurityReport) -> String {
    let c = r.counters;
    format!(
        "  security {}  dropped: not secured {}  bad MIC {}  replayed {}  unknown key {}  \
         wrong level {}  malformed {}  replay table full {}  challenged after boot {}  \
         not sent (no frame counter) {}",
        if r.keyed {
            "on"
        } else {
            "off (no management key)"
        },
        c.not_secured,
        c.bad_mic,
        c.replayed,
        c.unknown_key,
        c.wrong_level,
        c.malformed,
        c.table_full,
        c.challenged,
        c.no_counter,
    )
}

/// The answer to `reset`: which links the node re-established (in which epoch).
pub fn reset_text(addr: u16, s: &Status) -> String {
    let peers: Vec<String> = (0..8)
        .filter(|i| s.links_restarted & (1 << i) != 0)
        .map(|i| format!("#{i}"))
        .collect();
    let links = if peers.is_empty() {
        "no link needed re-establishing".to_string()
    } else {
        format!(
            "links to peer {} re-established in epoch {}",
            peers.join(" "),
            s.epoch
        )
    };
    format!("{addr:#06x}: reset; {links}")
}

/// A frame's (clear or opened) payload in readable form: the message, a chunk's data as
/// its length, or why it is not a message.
pub fn message_text(payload: &[u8]) -> String {
    match Message::parse(payload) {
        Ok(Message::ConfigChunk {
            generation,
            offset,
            data,
        }) => format!(
            "ConfigChunk {{ generation: {generation}, offset: {offset}, {} bytes }}",
            data.len()
        ),
        Ok(m) => format!("{m:?}"),
        Err(e) => format!("({e})"),
    }
}

/// One frame in readable form.
pub fn describe(psdu: &[u8]) -> String {
    match Frame::parse(psdu) {
        Ok(Frame::Data { header, payload }) if header.secured => {
            let what = match AuxHeader::new_checked(payload) {
                Ok(view) => {
                    let aux = AuxRepr::parse(&view);
                    let sealed = payload.len().saturating_sub(view.header_len());
                    format!(
                        "secured {:?}, key {}, counter {}, {sealed} bytes sealed",
                        aux.level,
                        aux.key_id
                            .index()
                            .map_or_else(|| "implicit".to_string(), |i| i.to_string()),
                        aux.frame_counter,
                    )
                }
                Err(e) => format!("secured, but {e}"),
            };
            format!("{:#06x} -> {:#06x}  {what}", header.src, header.dst)
        }
        Ok(Frame::Data { header, payload }) => {
            format!(
                "{:#06x} -> {:#06x}  {}",
                header.src,
                header.dst,
                message_text(payload)
            )
        }
        Ok(Frame::Ack { seq, .. }) => format!("ack {seq}"),
        Err(e) => format!("bad frame ({e}), {} bytes", psdu.len()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_secured_frame_is_described_by_its_security_header() {
        use config_schema::wire::mac::Header;
        use config_schema::wire::security::{ext_addr, secure};
        let header = Header {
            seq: 0,
            pan_id: 0xFFFF,
            dst: 0x0011,
            src: 0x0100,
            ack_request: false,
            secured: false,
        };
        let mut psdu = [0u8; 127];
        let n = secure(
            &header,
            &AuxRepr::new(0, 42),
            &[1; 16],
            ext_addr(0xFFFF, 0x0100),
            &[0, 1, 2, 3, 4],
            &mut psdu,
        )
        .unwrap();
        assert_eq!(
            describe(&psdu[..n]),
            "0x0100 -> 0x0011  secured EncMic64, key 0, counter 42, 13 bytes sealed"
        );
    }
    use config_schema::wire::msg::{Counters, RuntimeCounters};

    fn status() -> Status {
        Status {
            ack: 9,
            role: heapless::String::try_from("GR").unwrap(),
            generation: 3,
            table: config_schema::TableId::NONE,
            staged: 0,
            previous: 0,
            trial: false,
            states: heapless::Vec::from_slice(&[2, 0]).unwrap(),
            outputs: 0x0002,
            inputs: 0x0001,
            fault: None,
            link_alarms: 0b100,
            links_broken: 0b001,
            links_restarted: 0,
            epoch: 257,
            counters: Counters {
                sent: 19,
                received: 36,
                retried: 4,
                dropped: 1,
                delivered: 2,
            },
            runtime: RuntimeCounters {
                tx_queue_full: 5,
                tx_queue_high: 32,
                tx_failed: 1,
                flash_failures: 2,
            },
            cycles: 7,
        }
    }

    #[test]
    fn status_tells_an_alarm_from_a_broken_link_and_shows_the_runtime_counters() {
        assert_eq!(
            status_text(0x0013, &status()),
            "0x0013  role GR  generation 3\n  \
             states S2 S0  outputs 0x0002  inputs 0x0001  fault none\n  \
             link alarms 0b00000100  broken 0b00000001  epoch 257\n  \
             frames sent 19 received 36 retried 4 dropped 1  events delivered 2\n  \
             tx queue full 5  high-water 32  radio failures 1  flash failures 2"
        );
    }

    #[test]
    fn the_security_line_names_every_reason_with_its_count() {
        use config_schema::wire::msg::SecurityCounters;
        let r = SecurityReport {
            ack: 1,
            keyed: true,
            counters: SecurityCounters {
                not_secured: 1,
                bad_mic: 2,
                replayed: 3,
                unknown_key: 4,
                wrong_level: 5,
                malformed: 6,
                table_full: 7,
                no_counter: 8,
                challenged: 9,
            },
        };
        assert_eq!(
            security_text(&r),
            "  security on  dropped: not secured 1  bad MIC 2  replayed 3  unknown key 4  \
             wrong level 5  malformed 6  replay table full 7  challenged after boot 9  \
             not sent (no frame counter) 8"
        );
        assert_eq!(
            security_text(&SecurityReport::default()),
            "  security off (no management key)  dropped: not secured 0  bad MIC 0  \
             replayed 0  unknown key 0  wrong level 0  malformed 0  replay table full 0  \
             challenged after boot 0  not sent (no frame counter) 0"
        );
    }

    #[test]
    fn reset_says_which_links_it_re_established() {
        let mut s = status();
        s.links_broken = 0;
        s.link_alarms = 0;
        assert_eq!(
            reset_text(0x0013, &s),
            "0x0013: reset; no link needed re-establishing"
        );
        s.links_restarted = 0b101;
        s.epoch = 258;
        assert_eq!(
            reset_text(0x0013, &s),
            "0x0013: reset; links to peer #0 #2 re-established in epoch 258"
        );
    }
}
