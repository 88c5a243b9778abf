//! Every [`Message`] written and read by hand, byte for byte as postcard writes and reads
//! it (the wire format is postcard's; the tool, the monitor and the nodes keep it), without
//! serde: one small reader and writer, no code per element type. postcard's rules, as its
//! deserializer applies them: an enum is its variant index as a varint `u32`; `u16`,
//! `u32`, `u64` and lengths (`usize`) are varints (LEB128, at most `ceil(bits / 7)` bytes,
//! the last one holding only the bits left; longer encodings of a value than the shortest
//! are read too); `u8` is one byte; `bool` and an `Option`'s tag are one byte, 0 or 1; a
//! text or a byte string is its length, then its bytes; a list is its length, then its
//! elements; a struct is its fields in order. The tests hold both directions equal to
//! postcard's, errors included.

use heapless::{String, Vec};

use super::*;
use crate::alarm::{Alarm, AlarmLevel, AlarmReport, AlarmSource};

type R<T> = Result<T, MessageError>;

/// Reads a message's fields from the front of a payload. The first error is kept and
/// every field after it reads as 0 (empty), so the fields need no error path each: what
/// is built after an error is thrown away, and a length read as 0 ends every loop.
pub(super) struct In<'a> {
    rest: &'a [u8],
    err: Option<MessageError>,
}

impl<'a> In<'a> {
    pub(super) fn new(payload: &'a [u8]) -> Self {
        In {
            rest: payload,
            err: None,
        }
    }

    /// The first error, or that something follows the message.
    pub(super) fn end(&self) -> R<()> {
        match self.err {
            Some(e) => Err(e),
            None if self.rest.is_empty() => Ok(()),
            None => Err(MessageError::Trailing),
        }
    }

    /// Keeps `e` if it is the first error.
    #[inline(never)]
    fn fail(&mut self, e: MessageError) {
        if self.err.is_none() {
            self.err = Some(e);
        }
    }

    #[inline(never)]
    fn byte(&mut self) -> u8 {
        match self.rest.split_first() {
            Some((&b, rest)) if self.err.is_none() => {
                self.rest = rest;
                b
            }
            _ => {
                self.fail(MessageError::End);
                0
            }
        }
    }

    /// A varint of a `bits`-bit type (16, 32 or 64).
    #[inline(never)]
    fn varint(&mut self, bits: u32) -> u64 {
        if self.err.is_some() {
            return 0;
        }
        // Read in place (not byte by byte through `byte`): the hot path of every event.
        let max = bits.div_ceil(7) as usize;
        let last = (1u8 << (bits % 7)) - 1;
        let mut out = 0u64;
        for (i, &b) in self.rest.iter().take(max).enumerate() {
            out |= u64::from(b & 0x7F) << (7 * i);
            if b & 0x80 == 0 {
                self.rest = self.rest.get(i + 1..).unwrap_or_default();
                if i + 1 == max && b > last {
                    self.fail(MessageError::Varint);
                }
                return out;
            }
        }
        // Every byte there had its continuation bit: the payload ended inside the varint,
        // or it is longer than its type allows.
        let e = if self.rest.len() < max {
            MessageError::End
        } else {
            MessageError::Varint
        };
        self.fail(e);
        0
    }

    fn u16(&mut self) -> u16 {
        // At most 16 bits: the last byte is checked.
        self.varint(16) as u16
    }

    fn u32(&mut self) -> u32 {
        self.varint(32) as u32
    }

    /// A list's length, or `cap + 1` if it is longer than `cap` (postcard reads the element
    /// past the capacity, then refuses it).
    fn len(&mut self, cap: usize) -> usize {
        (self.varint(usize::BITS) as usize).min(cap + 1)
    }

    /// A variant index below `n` (0 if it is not).
    #[inline(never)]
    fn variant(&mut self, n: u32) -> u32 {
        let v = self.u32();
        if v < n {
            v
        } else {
            self.fail(MessageError::Variant);
            0
        }
    }

    #[inline(never)]
    fn bool(&mut self) -> bool {
        match self.byte() {
            0 => false,
            1 => true,
            _ => {
                self.fail(MessageError::Bool);
                false
            }
        }
    }

    #[inline(never)]
    fn bytes(&mut self) -> &'a [u8] {
        let n = self.varint(usize::BITS) as usize;
        match self.rest.split_at_checked(n) {
            Some((b, rest)) if self.err.is_none() => {
                self.rest = rest;
                b
            }
            _ => {
                self.fail(MessageError::End);
                &[]
            }
        }
    }

    #[inline(never)]
    fn role(&mut self) -> String<MAX_ROLE_NAME> {
        match crate::text::role_name(self.bytes()) {
            Ok(role) => role,
            Err(e) => {
                self.fail(match e {
                    crate::text::NameError::Utf8 => MessageError::Utf8,
                    crate::text::NameError::Capacity => MessageError::Capacity,
                });
                String::new()
            }
        }
    }

    /// A table's identity: 4 bytes as they are (postcard's `[u8; 4]`).
    fn table_id(&mut self) -> TableId {
        TableId([self.byte(), self.byte(), self.byte(), self.byte()])
    }

    /// `u32`s into `c`, in order.
    #[inline(never)]
    fn fill(&mut self, c: &mut [u32]) {
        for x in c {
            *x = self.u32();
        }
    }

    /// `n` `u32`s read and dropped.
    #[inline(never)]
    fn skip_u32s(&mut self, n: usize) {
        for _ in 0..n {
            self.u32();
        }
    }

    /// A list of `n` elements read (`n` from [`In::len`]) is refused if it is longer than
    /// its capacity `cap`, as pushing its elements would be.
    fn full_past(&mut self, n: usize, cap: usize) {
        if n > cap {
            self.fail(MessageError::Capacity);
        }
    }

    /// `x` pushed onto `list`: `Capacity` if it is full.
    fn push<T, const N: usize>(&mut self, list: &mut Vec<T, N>, x: T) {
        if list.push(x).is_err() {
            self.fail(MessageError::Capacity);
        }
    }
}

/// Reads one message (what follows it is the caller's).
pub(super) fn message<'a>(r: &mut In<'a>) -> Message<'a> {
    let v = r.variant(14);
    for_nodes(r, v).unwrap_or_else(|| for_the_tool(r, v))
}

/// Reads one message as a node hears it: the ones it acts on whole, the ones meant for the
/// tool only checked (`None`), so a node builds none of them.
pub(super) fn heard<'a>(r: &mut In<'a>) -> Option<Message<'a>> {
    let v = r.variant(14);
    let msg = for_nodes(r, v);
    if msg.is_none() {
        check_for_the_tool(r, v);
    }
    msg
}

/// The message of variant `v` if it is one nodes act on.
fn for_nodes<'a>(r: &mut In<'a>, v: u32) -> Option<Message<'a>> {
    Some(match v {
        0 => Message::Event {
            epoch: r.u16(),
            seq: r.u16(),
            topic: r.byte(),
        },
        1 => Message::EventAck {
            epoch: r.u16(),
            next: r.u16(),
        },
        2 => Message::ConfigBegin {
            generation: r.u32(),
            len: r.u16(),
            crc: r.u32(),
            force: r.bool(),
        },
        3 => Message::ConfigChunk {
            generation: r.u32(),
            offset: r.u16(),
            data: r.bytes(),
        },
        4 => Message::ConfigEnd {
            generation: r.u32(),
        },
        6 => Message::Command {
            id: r.u16(),
            command: command(r),
        },
        10 => Message::Challenge { nonce: r.u32() },
        11 => Message::ChallengeAnswer { nonce: r.u32() },
        12 => Message::Switch {
            generation: r.u32(),
            step: switch_step(r),
        },
        _ => return None,
    })
}

/// The message of variant `v`, one meant for the tool (answers and reports of nodes:
/// `ConfigReply` 5, `Status` 7, `Announce` 8, `Security` 9, `Alarms` 13).
fn for_the_tool<'a>(r: &mut In<'a>, v: u32) -> Message<'a> {
    match v {
        5 => Message::ConfigReply {
            generation: r.u32(),
            reply: config_reply(r),
        },
        7 => Message::Status(status(r)),
        8 => Message::Announce(Announce {
            firmware: r.u16(),
            generation: r.u32(),
            role: r.role(),
            table: r.table_id(),
            staged: r.u32(),
            nonce: r.varint(64),
        }),
        9 => Message::Security(security(r)),
        _ => Message::Alarms(alarms(r)),
    }
}

/// Reads a message meant for the tool without building it: the fields of
/// [`for_the_tool`], in its order, with its checks (the tests hold `parse_node` to `parse`).
fn check_for_the_tool(r: &mut In, v: u32) {
    match v {
        5 => {
            r.u32();
            match r.variant(8) {
                0 => {
                    r.u16();
                }
                2 => match r.variant(10) {
                    0 | 7 | 8 => {
                        r.u32();
                    }
                    6 => {
                        r.byte();
                        r.varint(64);
                    }
                    _ => {}
                },
                4 => {
                    r.bool();
                    r.u16();
                }
                _ => {}
            }
        }
        7 => {
            // Status: ack, role, generation, table, staged, previous, trial, states,
            // outputs, inputs, fault, link alarms, broken, restarted, epoch, counters,
            // runtime counters, cycles.
            r.u16();
            r.role();
            r.u32();
            r.table_id();
            r.skip_u32s(2);
            r.bool();
            let n = r.len(MAX_CHARTS);
            for _ in 0..n {
                r.byte();
            }
            r.full_past(n, MAX_CHARTS);
            r.u16();
            r.u16();
            match r.byte() {
                0 => {}
                1 => {
                    r.byte();
                }
                _ => r.fail(MessageError::Option),
            }
            r.byte();
            r.byte();
            r.byte();
            r.u16();
            // The counters, then the runtime's: tx queue full, its high-water mark (a
            // byte), tx failed, flash failures.
            r.skip_u32s(6);
            r.byte();
            r.skip_u32s(2);
            r.byte();
        }
        8 => {
            r.u16();
            r.u32();
            r.role();
            r.table_id();
            r.u32();
            r.varint(64);
        }
        9 => {
            r.u16();
            r.bool();
            r.skip_u32s(9);
        }
        _ => {
            // Alarms: ack, now, the alarms (source, level, raised, acked, persists),
            // dropped.
            r.u16();
            r.u32();
            let n = r.len(crate::alarm::MAX_ALARMS);
            for _ in 0..n {
                match r.variant(4) {
                    0 => {
                        r.byte();
                        r.byte();
                    }
                    1 => {}
                    _ => {
                        r.byte();
                    }
                }
                r.variant(3);
                r.u32();
                r.bool();
                r.bool();
            }
            r.full_past(n, crate::alarm::MAX_ALARMS);
            r.u16();
        }
    }
}

fn config_reply(r: &mut In) -> ConfigReply {
    match r.variant(8) {
        0 => ConfigReply::Next { next: r.u16() },
        1 => ConfigReply::Activated,
        2 => ConfigReply::Refused(refusal(r)),
        3 => ConfigReply::Staged,
        4 => ConfigReply::Armed {
            idle: r.bool(),
            ask: r.u16(),
        },
        5 => ConfigReply::Busy,
        6 => ConfigReply::Disarmed,
        _ => ConfigReply::Confirmed,
    }
}

fn refusal(r: &mut In) -> Refusal {
    match r.variant(10) {
        0 => Refusal::Stale { running: r.u32() },
        1 => Refusal::TooLong,
        2 => Refusal::OutOfSequence,
        3 => Refusal::Crc,
        4 => Refusal::Invalid,
        5 => Refusal::Flash,
        6 => Refusal::Pin {
            pin: r.byte(),
            board: r.varint(64),
        },
        7 => Refusal::NotStaged { staged: r.u32() },
        8 => Refusal::Superseded { transfer: r.u32() },
        _ => Refusal::OnTrial,
    }
}

/// The number of commands (their variants in the order `Command` declares them).
const COMMANDS: u32 = 8;

/// The variant of `c` (serde's: declaration order).
fn command_variant(c: &Command) -> u8 {
    match c {
        Command::Start => 0,
        Command::Reset => 1,
        Command::Identify { .. } => 2,
        Command::Status => 3,
        Command::Security => 4,
        Command::Home => 5,
        Command::Alarms => 6,
        Command::Ack => 7,
    }
}

fn command(r: &mut In) -> Command {
    match r.variant(COMMANDS) {
        0 => Command::Start,
        1 => Command::Reset,
        2 => Command::Identify {
            nonce: r.varint(64),
        },
        3 => Command::Status,
        4 => Command::Security,
        5 => Command::Home,
        6 => Command::Alarms,
        _ => Command::Ack,
    }
}

fn switch_step(r: &mut In) -> SwitchStep {
    match r.variant(4) {
        0 => SwitchStep::Arm { ask: r.u16() },
        1 => SwitchStep::Go {
            now: r.bool(),
            trial: r.bool(),
        },
        2 => SwitchStep::Disarm,
        _ => SwitchStep::Confirm,
    }
}

fn status(r: &mut In) -> Status {
    let ack = r.u16();
    let role = r.role();
    let generation = r.u32();
    let table = r.table_id();
    let staged = r.u32();
    let previous = r.u32();
    let trial = r.bool();
    let mut states = Vec::new();
    for _ in 0..r.len(MAX_CHARTS) {
        // Element by element, as postcard: the one past the capacity is read, then refused.
        let s = r.byte();
        r.push(&mut states, s);
    }
    let outputs = r.u16();
    let inputs = r.u16();
    let fault = match r.byte() {
        0 => None,
        1 => Some(r.byte()),
        _ => {
            r.fail(MessageError::Option);
            None
        }
    };
    let [link_alarms, links_broken, links_restarted] = [r.byte(), r.byte(), r.byte()];
    let epoch = r.u16();
    let mut c = [0u32; 5];
    r.fill(&mut c);
    let [sent, received, retried, dropped, delivered] = c;
    let tx_queue_full = r.u32();
    let tx_queue_high = r.byte();
    let tx_failed = r.u32();
    let flash_failures = r.u32();
    Status {
        ack,
        role,
        generation,
        table,
        staged,
        previous,
        trial,
        states,
        outputs,
        inputs,
        fault,
        link_alarms,
        links_broken,
        links_restarted,
        epoch,
        counters: Counters {
            sent,
            received,
            retried,
            dropped,
            delivered,
        },
        runtime: RuntimeCounters {
            tx_queue_full,
            tx_queue_high,
            tx_failed,
            flash_failures,
        },
        cycles: r.byte(),
    }
}

fn security(r: &mut In) -> SecurityReport {
    let ack = r.u16();
    let keyed = r.bool();
    let mut c = [0u32; 9];
    r.fill(&mut c);
    let [not_secured, bad_mic, replayed, unknown_key, wrong_level, malformed, table_full, no_counter, challenged] =
        c;
    SecurityReport {
        ack,
        keyed,
        counters: SecurityCounters {
            not_secured,
            bad_mic,
            replayed,
            unknown_key,
            wrong_level,
            malformed,
            table_full,
            no_counter,
            challenged,
        },
    }
}

fn alarms(r: &mut In) -> AlarmReport {
    let ack = r.u16();
    let now_ms = r.u32();
    let mut alarms = Vec::new();
    for _ in 0..r.len(crate::alarm::MAX_ALARMS) {
        let source = match r.variant(4) {
            0 => AlarmSource::Chart {
                chart: r.byte(),
                code: r.byte(),
            },
            1 => AlarmSource::EStop,
            2 => AlarmSource::Link { peer: r.byte() },
            _ => AlarmSource::Declared { index: r.byte() },
        };
        let level = match r.variant(3) {
            0 => AlarmLevel::Info,
            1 => AlarmLevel::Warning,
            _ => AlarmLevel::Fault,
        };
        let alarm = Alarm {
            source,
            level,
            raised_ms: r.u32(),
            acked: r.bool(),
            persists: r.bool(),
        };
        r.push(&mut alarms, alarm);
    }
    AlarmReport {
        ack,
        now_ms,
        alarms,
        dropped: r.u16(),
    }
}

/// Writes a message's fields into a buffer. A byte past its end is not written and the
/// message comes out as `Full`, so the fields need no error path each.
pub(super) struct Out<'b> {
    buf: &'b mut [u8],
    at: usize,
    full: bool,
}

impl<'b> Out<'b> {
    pub(super) fn new(buf: &'b mut [u8]) -> Self {
        Out {
            buf,
            at: 0,
            full: false,
        }
    }

    /// The bytes written, or `Full`.
    pub(super) fn len(&self) -> R<usize> {
        if self.full {
            Err(MessageError::Full)
        } else {
            Ok(self.at)
        }
    }

    #[inline(never)]
    fn byte(&mut self, b: u8) {
        match self.buf.get_mut(self.at) {
            Some(slot) => {
                *slot = b;
                self.at += 1;
            }
            None => self.full = true,
        }
    }

    #[inline(never)]
    fn varint(&mut self, v: u64) {
        let mut v = v;
        while v >= 0x80 {
            self.byte((v as u8) | 0x80);
            v >>= 7;
        }
        self.byte(v as u8);
    }

    fn u32(&mut self, v: u32) {
        self.varint(u64::from(v))
    }

    fn u16(&mut self, v: u16) {
        self.varint(u64::from(v))
    }

    fn bool(&mut self, b: bool) {
        self.byte(u8::from(b))
    }

    /// Bytes as they are (an array: no length).
    fn raw(&mut self, b: &[u8]) {
        for &x in b {
            self.byte(x);
        }
    }

    #[inline(never)]
    fn bytes(&mut self, b: &[u8]) {
        self.varint(b.len() as u64);
        for &x in b {
            self.byte(x);
        }
    }

    fn counters(&mut self, c: &[u32]) {
        for &x in c {
            self.u32(x);
        }
    }
}

/// Writes `m`.
pub(super) fn emit(m: &Message<'_>, w: &mut Out) {
    match m {
        Message::Event { epoch, seq, topic } => {
            w.byte(0);
            w.u16(*epoch);
            w.u16(*seq);
            w.byte(*topic)
        }
        Message::EventAck { epoch, next } => {
            w.byte(1);
            w.u16(*epoch);
            w.u16(*next)
        }
        Message::ConfigBegin {
            generation,
            len,
            crc,
            force,
        } => {
            w.byte(2);
            w.u32(*generation);
            w.u16(*len);
            w.u32(*crc);
            w.bool(*force)
        }
        Message::ConfigChunk {
            generation,
            offset,
            data,
        } => {
            w.byte(3);
            w.u32(*generation);
            w.u16(*offset);
            w.bytes(data)
        }
        Message::ConfigEnd { generation } => {
            w.byte(4);
            w.u32(*generation)
        }
        Message::ConfigReply { generation, reply } => {
            w.byte(5);
            w.u32(*generation);
            emit_reply(reply, w)
        }
        Message::Command { id, command } => {
            w.byte(6);
            w.u16(*id);
            w.byte(command_variant(command));
            if let Command::Identify { nonce } = command {
                w.varint(*nonce)
            }
        }
        Message::Status(s) => {
            w.byte(7);
            emit_status(s, w)
        }
        Message::Announce(a) => {
            w.byte(8);
            w.u16(a.firmware);
            w.u32(a.generation);
            w.bytes(a.role.as_bytes());
            w.raw(&a.table.0);
            w.u32(a.staged);
            w.varint(a.nonce)
        }
        Message::Security(s) => {
            w.byte(9);
            w.u16(s.ack);
            w.bool(s.keyed);
            let c = &s.counters;
            w.counters(&[
                c.not_secured,
                c.bad_mic,
                c.replayed,
                c.unknown_key,
                c.wrong_level,
                c.malformed,
                c.table_full,
                c.no_counter,
                c.challenged,
            ])
        }
        Message::Challenge { nonce } => {
            w.byte(10);
            w.u32(*nonce)
        }
        Message::ChallengeAnswer { nonce } => {
            w.byte(11);
            w.u32(*nonce)
        }
        Message::Switch { generation, step } => {
            w.byte(12);
            w.u32(*generation);
            match *step {
                SwitchStep::Arm { ask } => {
                    w.byte(0);
                    w.u16(ask)
                }
                SwitchStep::Go { now, trial } => {
                    w.byte(1);
                    w.bool(now);
                    w.bool(trial)
                }
                SwitchStep::Disarm => w.byte(2),
                SwitchStep::Confirm => w.byte(3),
            }
        }
        Message::Alarms(a) => {
            w.byte(13);
            emit_alarms(a, w)
        }
    }
}

fn emit_reply(reply: &ConfigReply, w: &mut Out) {
    match *reply {
        ConfigReply::Next { next } => {
            w.byte(0);
            w.u16(next)
        }
        ConfigReply::Activated => w.byte(1),
        ConfigReply::Refused(refusal) => {
            w.byte(2);
            emit_refusal(refusal, w)
        }
        ConfigReply::Staged => w.byte(3),
        ConfigReply::Armed { idle, ask } => {
            w.byte(4);
            w.bool(idle);
            w.u16(ask)
        }
        ConfigReply::Busy => w.byte(5),
        ConfigReply::Disarmed => w.byte(6),
        ConfigReply::Confirmed => w.byte(7),
    }
}

fn emit_refusal(refusal: Refusal, w: &mut Out) {
    let (variant, value) = match refusal {
        Refusal::Stale { running } => (0, Some(running)),
        Refusal::TooLong => (1, None),
        Refusal::OutOfSequence => (2, None),
        Refusal::Crc => (3, None),
        Refusal::Invalid => (4, None),
        Refusal::Flash => (5, None),
        Refusal::Pin { pin, board } => {
            w.byte(6);
            w.byte(pin);
            return w.varint(board);
        }
        Refusal::NotStaged { staged } => (7, Some(staged)),
        Refusal::Superseded { transfer } => (8, Some(transfer)),
        Refusal::OnTrial => (9, None),
    };
    w.byte(variant);
    if let Some(v) = value {
        w.u32(v);
    }
}

fn emit_status(s: &Status, w: &mut Out) {
    w.u16(s.ack);
    w.bytes(s.role.as_bytes());
    w.u32(s.generation);
    w.raw(&s.table.0);
    w.counters(&[s.staged, s.previous]);
    w.bool(s.trial);
    w.bytes(&s.states);
    w.u16(s.outputs);
    w.u16(s.inputs);
    match s.fault {
        None => w.byte(0),
        Some(f) => {
            w.byte(1);
            w.byte(f);
        }
    }
    w.byte(s.link_alarms);
    w.byte(s.links_broken);
    w.byte(s.links_restarted);
    w.u16(s.epoch);
    let (c, rt) = (&s.counters, &s.runtime);
    w.counters(&[c.sent, c.received, c.retried, c.dropped, c.delivered]);
    w.u32(rt.tx_queue_full);
    w.byte(rt.tx_queue_high);
    w.counters(&[rt.tx_failed, rt.flash_failures]);
    w.byte(s.cycles)
}

fn emit_alarms(a: &AlarmReport, w: &mut Out) {
    w.u16(a.ack);
    w.u32(a.now_ms);
    w.varint(a.alarms.len() as u64);
    for alarm in &a.alarms {
        match alarm.source {
            AlarmSource::Chart { chart, code } => {
                w.byte(0);
                w.byte(chart);
                w.byte(code);
            }
            AlarmSource::EStop => w.byte(1),
            AlarmSource::Link { peer } => {
                w.byte(2);
                w.byte(peer);
            }
            AlarmSource::Declared { index } => {
                w.byte(3);
                w.byte(index);
            }
        }
        w.byte(alarm.level as u8);
        w.u32(alarm.raised_ms);
        w.bool(alarm.acked);
        w.bool(alarm.persists);
    }
    w.u16(a.dropped)
}

#[cfg(test)]
mod tests;
