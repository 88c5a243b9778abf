//! Application messages: postcard inside the MAC payload of a data frame.
//!
//! The publisher of an event and the sender of every message is the frame's source
//! address; the MAC layer carries no meaning beyond addressing and integrity, so a security
//! layer (auxiliary security header + MIC) can wrap these payloads unchanged.

use heapless::{String, Vec};
use serde::{Deserialize, Serialize};

use crate::alarm::AlarmReport;
use crate::blob::TableId;
use crate::limits::{MAX_CHARTS, MAX_ROLE_NAME};
use crate::table::Topic;

/// Bytes of table data in one OTA chunk: fits a secured data frame (ENC-MIC-64, 102 bytes
/// of payload) with the chunk's own fields.
pub const CHUNK_DATA: usize = 88;

/// One application message.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum Message<'a> {
    /// A published event. `epoch` changes whenever the publisher restarts its numbering
    /// (boot, new table); `seq` counts this publisher's events to this subscriber.
    Event { epoch: u16, seq: u16, topic: Topic },
    /// Cumulative acknowledgement: every event of `epoch` before `next` arrived, in order.
    EventAck { epoch: u16, next: u16 },
    /// Start of a table transfer.
    ConfigBegin {
        generation: u32,
        len: u16,
        crc: u32,
        force: bool,
    },
    /// `data` is the blob from byte `offset`.
    ConfigChunk {
        generation: u32,
        offset: u16,
        #[serde(borrow)]
        data: &'a [u8],
    },
    /// All chunks sent: check, activate, persist.
    ConfigEnd { generation: u32 },
    /// The node's answer to every config message.
    ConfigReply { generation: u32, reply: ConfigReply },
    /// An operator command. `id` tells repeats apart: a node runs each (sender, id) once
    /// (of the last eight that act, START, RESET, HOME, ACK, whoever sent them, forgotten
    /// after 30 s without one: `node_fw::node::REPEAT_MS`) and answers
    /// every copy (a `Status`, whose `ack` is the id), so the tool can resend a START until
    /// it is acknowledged without ever starting a second cycle, while other runs of the
    /// tool send their own commands in between.
    Command { id: u16, command: Command },
    /// The node's status: the answer to every command but `Identify`.
    Status(Status),
    /// "Here I am": periodic while unconfigured, and on `Command::Identify`.
    Announce(Announce),
    /// The node's frame security counters: the answer to `Command::Security`.
    Security(SecurityReport),
    /// A secured node does not know the sender's frame counter (it rebooted): prove your
    /// frames are fresh by answering `nonce` (the counter of this very frame, which the
    /// node never used before; bit 31 set: a greeting, the sender booted). In clear, on a
    /// robot without link keys: the epoch a booted subscriber asks for, or `0x8000_0000`,
    /// its greeting (docs/radio-protocol.md).
    Challenge { nonce: u32 },
    /// The answer to a `Challenge`: its counter becomes the sender's floor at the node.
    ChallengeAnswer { nonce: u32 },
    /// The switch-over to `generation`, the staged one or (a rollback) the previous one
    /// (answered by `ConfigReply`).
    Switch { generation: u32, step: SwitchStep },
    /// The node's latched alarms: the answer to `Command::Alarms` and `Command::Ack`.
    Alarms(AlarmReport),
}

/// One step of the two-phase switch-over (docs/reconfiguration.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum SwitchStep {
    /// Get ready: hold any START until the switch, and say whether the node is idle.
    /// `ask` numbers the tool's asks of this node, each one more: the answer carries it,
    /// so a late or duplicated answer to an earlier ask is told from the answer to this
    /// one.
    Arm { ask: u16 },
    /// Switch to the generation now if armed and idle; with `now`, whatever the node is
    /// doing (a stopped or faulted machine). `trial`: not confirmed yet (a power cut, or a
    /// rollback, returns to the previous generation).
    Go { now: bool, trial: bool },
    /// The switch-over is off: run a held START on the running table.
    Disarm,
    /// The running generation (on trial) is confirmed: it stays the boot table.
    Confirm,
}

/// Where a table transfer stands, from the receiving node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ConfigReply {
    /// Send bytes from `next` on (acknowledges everything before it).
    Next { next: u16 },
    /// The new table is checked, persisted and running.
    Activated,
    /// The transfer was refused; the old table keeps running.
    Refused(Refusal),
    /// The new table is checked and persisted, not running: it waits for the switch.
    Staged,
    /// Armed for the switch-over: START is held; `idle`: every chart in its initial
    /// state, no timer running, nothing in flight, no fault; `ask`: the `Arm` answered.
    Armed { idle: bool, ask: u16 },
    /// Not switched: the node is not armed or not idle (ask again).
    Busy,
    /// Disarmed: the running table goes on.
    Disarmed,
    /// The running generation is confirmed (no longer on trial).
    Confirmed,
}

/// Why a transfer was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Refusal {
    /// The generation is not newer than the running one (and not forced).
    Stale { running: u32 },
    /// Longer than a blob may be.
    TooLong,
    /// A chunk for another generation or offset than the transfer in progress.
    OutOfSequence,
    /// The whole blob's CRC-32 does not match `ConfigBegin`.
    Crc,
    /// The blob does not decode or validate.
    Invalid,
    /// Persisting to flash failed.
    Flash,
    /// The table uses board pin `pin`, which this node's board lacks (`board`: bit n, the
    /// board has pin n).
    Pin { pin: u8, board: u64 },
    /// A switch to a generation that is neither the staged one nor the previous one
    /// (`staged`: 0 for none).
    NotStaged { staged: u32 },
    /// A transfer of an older generation than the one in progress (not forced).
    Superseded { transfer: u32 },
    /// The running generation is on trial: confirm it or roll it back first (a new table
    /// would go over the previous one, the only confirmed table).
    OnTrial,
}

impl core::fmt::Display for Refusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Refusal::Stale { running } => {
                write!(f, "generation not newer than the running {running}")
            }
            Refusal::TooLong => write!(f, "table longer than a node accepts"),
            Refusal::OutOfSequence => write!(f, "out of sequence (the node lost the transfer)"),
            Refusal::Crc => write!(f, "CRC mismatch"),
            Refusal::Invalid => write!(f, "the table does not decode or validate"),
            Refusal::Flash => write!(f, "flash write failed"),
            Refusal::NotStaged { staged: 0 } => write!(f, "no generation is staged"),
            Refusal::NotStaged { staged } => {
                write!(f, "generation {staged} is staged, not this one")
            }
            Refusal::OnTrial => write!(
                f,
                "the running generation is on trial: confirm or roll back first"
            ),
            Refusal::Superseded { transfer } => {
                write!(
                    f,
                    "a transfer of the newer generation {transfer} is in progress"
                )
            }
            Refusal::Pin { pin, board } => {
                write!(
                    f,
                    "the table uses pin {pin}, which the board lacks (its pins: "
                )?;
                write_pins(f, board)?;
                write!(f, ")")
            }
        }
    }
}

/// A pin mask as ranges: `0-15`, `0-3 8 10-11`, `none`.
fn write_pins(f: &mut core::fmt::Formatter<'_>, mask: u64) -> core::fmt::Result {
    if mask == 0 {
        return write!(f, "none");
    }
    let (mut pin, mut first) = (0u32, true);
    while pin < 64 {
        if mask & (1 << pin) == 0 {
            pin += 1;
            continue;
        }
        let start = pin;
        while pin < 64 && mask & (1 << pin) != 0 {
            pin += 1;
        }
        let sep = if first { "" } else { " " };
        first = false;
        match pin - start {
            1 => write!(f, "{sep}{start}")?,
            _ => write!(f, "{sep}{start}-{}", pin - 1)?,
        }
    }
    Ok(())
}

/// Operator commands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Command {
    /// The START of the paper.
    Start,
    /// Leave a fault: back to the initial state.
    Reset,
    /// Answer with an `Announce` carrying `nonce` back (may be broadcast: a scan). A
    /// random 64-bit nonce per ask: a node answers an unsecured broadcast ask (once a
    /// second), so with a narrower one an attacker could have it sign an answer to every
    /// value and replay the one a later scan asks for.
    Identify { nonce: u64 },
    /// Only answer with the status.
    Status,
    /// Answer with the frame security counters (`Message::Security`) instead of the status.
    Security,
    /// Start homing: raise the table's `home` event (docs/reconfiguration.md).
    Home,
    /// Answer with the latched alarms (`Message::Alarms`) instead of the status.
    Alarms,
    /// Acknowledge every latched alarm whose cause is gone (a fault alarm whose cause
    /// persists stays); answered with the alarms as they are after it.
    Ack,
}

/// What a node counted of frame security (every reason a frame was dropped, and what it
/// could not send), answering command `ack`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SecurityReport {
    /// The id of the command this answers.
    pub ack: u16,
    /// Whether the node has a management key (frames on the config PAN are secured).
    pub keyed: bool,
    pub counters: SecurityCounters,
}

/// Frames a secured node dropped, per reason, and frames it could not secure.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SecurityCounters {
    /// A management frame (config PAN) without security.
    pub not_secured: u32,
    /// The MIC did not verify (forged, damaged, wrong key).
    pub bad_mic: u32,
    /// A frame counter not above the last one accepted from that sender.
    pub replayed: u32,
    /// A key index the node has no key for (or a frame claiming to come from the node).
    pub unknown_key: u32,
    /// Secured at another level than ENC-MIC-64.
    pub wrong_level: u32,
    /// A malformed auxiliary security header, or any other codec refusal.
    pub malformed: u32,
    /// A new sender, and the replay table was full.
    pub table_full: u32,
    /// Frames not sent: no frame counter (exhausted, or the flash failed).
    pub no_counter: u32,
    /// Authentic frames from a sender whose counter the node did not know yet (after its
    /// boot): not acted on, the sender challenged.
    pub challenged: u32,
}

/// What `config-tool status` shows of a node.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Status {
    /// The id of the command this answers.
    pub ack: u16,
    pub role: String<MAX_ROLE_NAME>,
    pub generation: u32,
    /// The running table's identity (its blob's CRC; [`TableId::NONE`] without a table).
    pub table: TableId,
    /// The generation staged for the switch-over (0: none).
    pub staged: u32,
    /// The previous generation a rollback returns to (0: none).
    pub previous: u32,
    /// The running generation is on trial (not confirmed).
    pub trial: bool,
    pub states: Vec<u8, MAX_CHARTS>,
    pub outputs: u16,
    pub inputs: u16,
    /// Fault code, if faulted.
    pub fault: Option<u8>,
    /// Bit i: the link to peer i is in alarm (the peer stopped acknowledging; still
    /// retrying).
    pub link_alarms: u8,
    /// Bit i: the link to peer i is broken (its queue overflowed: nothing more is sent on
    /// it until a `Reset` or a new table re-establishes it).
    pub links_broken: u8,
    /// Bit i: the last `Reset` re-established the link to peer i in a new epoch.
    pub links_restarted: u8,
    /// The epoch of the node's newest link numbering.
    pub epoch: u16,
    pub counters: Counters,
    pub runtime: RuntimeCounters,
    /// Cycles since boot, modulo 256, that this node's START (button or command) began at
    /// its idle point and that ended with the node back at it (the trial window's count:
    /// one byte, so the largest status still fits a secured frame).
    pub cycles: u8,
}

/// What the board's runtime counted (zero where a board has no such thing).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RuntimeCounters {
    /// Frames dropped because the transmit queue was full.
    pub tx_queue_full: u32,
    /// The most frames the transmit queue ever held (a queue holds at most 255).
    pub tx_queue_high: u8,
    /// Frames the radio refused or did not take in time.
    pub tx_failed: u32,
    /// Pushed tables that could not be persisted.
    pub flash_failures: u32,
}

/// Radio and delivery counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Counters {
    pub sent: u32,
    pub received: u32,
    pub retried: u32,
    pub dropped: u32,
    pub delivered: u32,
}

/// A node introducing itself.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Announce {
    pub firmware: u16,
    pub generation: u32,
    /// Empty while unconfigured.
    pub role: String<MAX_ROLE_NAME>,
    /// The running table's identity (its blob's CRC; [`TableId::NONE`] while
    /// unconfigured).
    pub table: TableId,
    /// The generation staged for the switch-over (0: none).
    pub staged: u32,
    /// The nonce of the `Identify` this answers (0: unprompted, the periodic announcement
    /// of an unconfigured node). The tool takes only the answers to its own ask: a secured
    /// announcement recorded earlier and replayed does not say that a node is there.
    pub nonce: u64,
}

/// Why a payload is not a message (postcard's reasons: the codec reads what postcard reads
/// and refuses what it refuses).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MessageError {
    /// The payload ends inside a field.
    End,
    /// A varint longer than its type allows.
    Varint,
    /// A `bool` that is neither 0 nor 1.
    Bool,
    /// An `Option` whose tag is neither 0 nor 1.
    Option,
    /// A text that is not UTF-8.
    Utf8,
    /// A variant index past its type's variants.
    Variant,
    /// A text or list longer than its capacity.
    Capacity,
    /// Bytes left after the message.
    Trailing,
    /// (writing) The buffer is too small.
    Full,
}

impl core::fmt::Display for MessageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let why = match self {
            MessageError::End => "it ends inside a field",
            MessageError::Varint => "a varint too long for its type",
            MessageError::Bool => "a bool neither 0 nor 1",
            MessageError::Option => "an option tag neither 0 nor 1",
            MessageError::Utf8 => "a text not UTF-8",
            MessageError::Variant => "an unknown variant",
            MessageError::Capacity => "a list or text over its capacity",
            MessageError::Trailing => "bytes after the message",
            MessageError::Full => "the buffer is too small",
        };
        write!(f, "malformed message: {why}")
    }
}

impl core::error::Error for MessageError {}

impl<'a> Message<'a> {
    /// Parses a MAC payload (postcard's bytes, read by hand: the private `codec`). Never panics;
    /// trailing bytes are an error.
    pub fn parse(payload: &'a [u8]) -> Result<Message<'a>, MessageError> {
        if let Some(msg) = link::parse(payload) {
            return Ok(msg);
        }
        let mut r = codec::In::new(payload);
        let msg = codec::message(&mut r);
        r.end().map(|()| msg)
    }

    /// [`Message::parse`] as a node needs it: the messages it acts on, `None` for a
    /// message meant for the tool (`ConfigReply`, `Status`, `Announce`, `Security`,
    /// `Alarms`: answers and reports of nodes), which is checked as `parse` checks it but
    /// not built. The same errors as `parse`.
    pub fn parse_node(payload: &'a [u8]) -> Result<Option<Message<'a>>, MessageError> {
        if let Some(msg) = link::parse(payload) {
            return Ok(Some(msg));
        }
        let mut r = codec::In::new(payload);
        let msg = codec::heard(&mut r);
        r.end().map(|()| msg)
    }

    /// Writes the message into `buf` (postcard's bytes); returns its length.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, MessageError> {
        if let Some(n) = link::emit(self, buf) {
            return Ok(n);
        }
        let mut w = codec::Out::new(buf);
        codec::emit(self, &mut w);
        w.len()
    }
}

mod codec;
mod link;

pub use link::LinkMessage;

#[cfg(test)]
mod tests {
    #[test]
    fn an_event_is_its_variant_then_varints_then_the_topic() {
        let mut buf = [0u8; 8];
        let msg = Message::Event {
            epoch: 300,
            seq: 0x4000,
            topic: 7,
        };
        let n = msg.emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], &[0x00, 0xAC, 0x02, 0x80, 0x80, 0x01, 0x07]);
        let ack = Message::EventAck {
            epoch: 1,
            next: 127,
        };
        let n = ack.emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], &[0x01, 0x01, 0x7F]);
        // A longer encoding of 1 than needed is read, as postcard reads it.
        assert_eq!(Message::parse(&[0x01, 0x81, 0x00, 0x7F]), Ok(ack));
    }

    use super::*;
    // Every message must fit a secured frame (the auxiliary header and MIC taken).
    use crate::wire::security::MAX_SECURED_PAYLOAD as MAX_PAYLOAD;

    #[test]
    fn a_full_chunk_fits_one_secured_frame() {
        let data = [0xA5u8; CHUNK_DATA];
        let msg = Message::ConfigChunk {
            generation: u32::MAX,
            offset: u16::MAX,
            data: &data,
        };
        let mut buf = [0u8; 256];
        let n = msg.emit(&mut buf).unwrap();
        assert!(n <= MAX_PAYLOAD, "{n} > {MAX_PAYLOAD}");
        assert_eq!(Message::parse(&buf[..n]), Ok(msg));
    }

    #[test]
    fn events_are_a_few_bytes() {
        let msg = Message::Event {
            epoch: 3,
            seq: 200,
            topic: 7,
        };
        let mut buf = [0u8; 16];
        let n = msg.emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], &[0, 3, 0xC8, 0x01, 7]);
        assert_eq!(Message::parse(&buf[..n]), Ok(msg));
    }

    /// An `Identify` carries its nonce after the command's variant, as a varint of up to
    /// 64 bits: the `Announce` that answers carries it back.
    #[test]
    fn an_identify_carries_its_nonce() {
        let msg = Message::Command {
            id: 7,
            command: Command::Identify { nonce: 300 },
        };
        let mut buf = [0u8; 16];
        let n = msg.emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], &[6, 7, 2, 0xAC, 0x02]);
        assert_eq!(Message::parse(&buf[..n]), Ok(msg));
        let widest = [
            6, 7, 2, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x01,
        ];
        assert_eq!(
            Message::parse(&widest),
            Ok(Message::Command {
                id: 7,
                command: Command::Identify { nonce: u64::MAX },
            })
        );
        // One bit more than 64 is no nonce.
        let mut over = widest;
        over[12] = 0x02;
        assert!(Message::parse(&over).is_err());
    }

    #[test]
    fn an_announce_carries_the_table_identity_as_four_bytes_after_the_role() {
        let msg = Message::Announce(Announce {
            firmware: 1,
            generation: 300,
            role: String::try_from("VC").unwrap(),
            table: TableId::from_crc(0x1234_ABCD),
            staged: 0,
            nonce: 0x1234_5678_9ABC_DEF0,
        });
        let mut buf = [0u8; 32];
        let n = msg.emit(&mut buf).unwrap();
        assert_eq!(
            &buf[..n],
            &[
                8, 1, 0xAC, 0x02, 2, b'V', b'C', 0xCD, 0xAB, 0x34, 0x12, 0, 0xF0, 0xBD, 0xF3, 0xD5,
                0x89, 0xCF, 0x95, 0x9A, 0x12
            ]
        );
        assert_eq!(Message::parse(&buf[..n]), Ok(msg));
    }

    #[test]
    fn the_largest_status_fits_one_secured_frame() {
        let mut role = String::new();
        while role.push('W').is_ok() {}
        let mut states = Vec::new();
        while states.push(u8::MAX).is_ok() {}
        let c = u32::MAX;
        let msg = Message::Status(Status {
            ack: u16::MAX,
            role,
            generation: u32::MAX,
            table: TableId([0xFF; 4]),
            staged: u32::MAX,
            previous: u32::MAX,
            trial: true,
            states,
            outputs: u16::MAX,
            inputs: u16::MAX,
            fault: Some(u8::MAX),
            link_alarms: u8::MAX,
            links_broken: u8::MAX,
            links_restarted: u8::MAX,
            epoch: u16::MAX,
            counters: Counters {
                sent: c,
                received: c,
                retried: c,
                dropped: c,
                delivered: c,
            },
            runtime: RuntimeCounters {
                tx_queue_full: c,
                tx_queue_high: u8::MAX,
                tx_failed: c,
                flash_failures: c,
            },
            cycles: u8::MAX,
        });
        let mut buf = [0u8; 256];
        let n = msg.emit(&mut buf).unwrap();
        assert!(n <= MAX_PAYLOAD, "{n} > {MAX_PAYLOAD}");
        assert_eq!(Message::parse(&buf[..n]), Ok(msg));
    }

    #[test]
    fn the_largest_security_report_fits_one_secured_frame() {
        let c = u32::MAX;
        let msg = Message::Security(SecurityReport {
            ack: u16::MAX,
            keyed: true,
            counters: SecurityCounters {
                not_secured: c,
                bad_mic: c,
                replayed: c,
                unknown_key: c,
                wrong_level: c,
                malformed: c,
                table_full: c,
                no_counter: c,
                challenged: c,
            },
        });
        let mut buf = [0u8; 256];
        let n = msg.emit(&mut buf).unwrap();
        assert!(n <= MAX_PAYLOAD, "{n} > {MAX_PAYLOAD}");
        assert_eq!(Message::parse(&buf[..n]), Ok(msg));
    }

    #[test]
    fn the_largest_alarm_report_fits_one_secured_frame() {
        use crate::alarm::{Alarm, AlarmLevel, AlarmSource, MAX_ALARMS};
        let mut alarms = Vec::new();
        for _ in 0..MAX_ALARMS {
            let alarm = Alarm {
                source: AlarmSource::Chart {
                    chart: u8::MAX,
                    code: u8::MAX,
                },
                level: AlarmLevel::Fault,
                raised_ms: u32::MAX,
                acked: true,
                persists: true,
            };
            alarms.push(alarm).unwrap();
        }
        let msg = Message::Alarms(AlarmReport {
            ack: u16::MAX,
            now_ms: u32::MAX,
            alarms,
            dropped: u16::MAX,
        });
        let mut buf = [0u8; 256];
        let n = msg.emit(&mut buf).unwrap();
        assert!(n <= MAX_PAYLOAD, "{n} > {MAX_PAYLOAD}");
        assert_eq!(Message::parse(&buf[..n]), Ok(msg));
    }

    fn text(r: Refusal) -> String<128> {
        use core::fmt::Write;
        let mut s = String::new();
        write!(s, "{r}").unwrap();
        s
    }

    #[test]
    fn a_pin_refusal_names_the_pin_and_the_board_pins() {
        let pin = |pin, board| text(Refusal::Pin { pin, board });
        assert_eq!(
            pin(20, 0xFFFF),
            "the table uses pin 20, which the board lacks (its pins: 0-15)"
        );
        assert_eq!(
            pin(4, 0b1_0110_1111),
            "the table uses pin 4, which the board lacks (its pins: 0-3 5-6 8)"
        );
        assert_eq!(
            pin(63, u64::MAX >> 1),
            "the table uses pin 63, which the board lacks (its pins: 0-62)"
        );
        assert_eq!(
            pin(0, 1 << 63),
            "the table uses pin 0, which the board lacks (its pins: 63)"
        );
        assert_eq!(
            pin(0, 0),
            "the table uses pin 0, which the board lacks (its pins: none)"
        );
    }

    #[test]
    fn trailing_and_unknown_bytes_are_errors() {
        assert_eq!(
            Message::parse(&[0, 3, 4, 7, 0]),
            Err(MessageError::Trailing)
        );
        // A variant index whose varint goes on past the payload.
        assert_eq!(Message::parse(&[0xFF]), Err(MessageError::End));
        assert_eq!(Message::parse(&[14]), Err(MessageError::Variant));
        assert_eq!(Message::parse(&[]), Err(MessageError::End));
    }

    mod props {
        use super::super::*;
        use proptest::prelude::*;

        proptest! {
            #[test]
            fn parse_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..120)) {
                let _ = Message::parse(&bytes);
            }
        }
    }
}
