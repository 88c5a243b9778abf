//! The payload of a table blob (schema 5): the [`Table`] as a stream of bit fields, each
//! as wide as the table's own counts make it (docs/table-format.md, "Payload").
//!
//! Fields go least significant bit first, from bit 0 of byte 0 on; the last byte is padded
//! with zero bits. A reference is as wide as the count it indexes (an event id takes
//! `bits(events)`, a chart-local state `bits(states of the chart)`), an optional reference
//! takes one value more (0 is `None`, `n + 1` is `Some(n)`), and the common shapes of a
//! compiled table are one-bit flags (a transition from where the previous one went, to the
//! next state; a route to the next input of the same chart; a publication of the next
//! topic; an expression right after the previous one). Timer durations are declared once
//! and referenced. `encode` fails with [`PackError::Unencodable`] on a table it cannot
//! write so (only an invalid one: a reference past its count, pools not laid out chart by
//! chart); `decode` reads whatever bytes it is given without panicking, and the blob's
//! `decode` validates the result.

use core::fmt;

use heapless::{String, Vec};

use crate::alarm::{AlarmDecl, AlarmLevel, Safety};
use crate::guard::{Expr, Op};
use crate::limits::*;
use crate::table::*;

/// Why a payload could not be read (or a table written).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PackError {
    /// The payload ends inside a field.
    End,
    /// A list longer than its capacity (`limits.rs`), or a pool end past 255.
    Capacity(&'static str),
    /// A field holds a value that is none of its kind's (a level, an action or operation
    /// code), or the padding is not zero.
    Value(&'static str),
    /// The role name is not UTF-8.
    Utf8,
    /// The output buffer is too small.
    Full,
    /// (encoding) The table cannot be written in this form: see the module docs.
    Unencodable(&'static str),
}

impl fmt::Display for PackError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PackError::End => write!(f, "the payload ends inside a field"),
            PackError::Capacity(what) => write!(f, "{what}: over capacity"),
            PackError::Value(what) => write!(f, "{what}: not a valid value"),
            PackError::Utf8 => write!(f, "the role name is not UTF-8"),
            PackError::Full => write!(f, "output buffer too small"),
            PackError::Unencodable(what) => write!(f, "{what}: cannot be encoded"),
        }
    }
}

impl core::error::Error for PackError {}

type R<T> = Result<T, PackError>;

/// Bits to write any of `n` values (`0..n`): 0 for one value or none.
pub const fn bits(n: usize) -> u32 {
    if n <= 1 {
        0
    } else {
        usize::BITS - (n - 1).leading_zeros()
    }
}

/// Bits of the field widths (`uv`: 0..=32).
const WIDTH_BITS: u32 = 6;

/// Action codes.
const A_SET: u32 = 0;
const A_DRIVE: u32 = 1;
const A_EMIT: u32 = 2;
const A_PUBLISH: u32 = 3;
const A_START: u32 = 4;
const A_CANCEL: u32 = 5;
const A_FAULT: u32 = 6;

/// Section names, in stream order (for [`sections`]).
pub const SECTIONS: [&str; 16] = [
    "role, network",
    "events, commands",
    "vars",
    "inputs",
    "outputs",
    "timers, durations",
    "code",
    "charts",
    "states",
    "actions",
    "transitions",
    "routes",
    "peers",
    "publications",
    "subscriptions",
    "safety",
];

struct Writer<'a> {
    buf: &'a mut [u8],
    bit: usize,
}

impl Writer<'_> {
    fn put(&mut self, value: u32, width: u32) -> R<()> {
        if width > 32 || (width < 32 && value >> width != 0) {
            return Err(PackError::Unencodable("field"));
        }
        for i in 0..width {
            let byte = self.buf.get_mut(self.bit / 8).ok_or(PackError::Full)?;
            if (value >> i) & 1 != 0 {
                *byte |= 1 << (self.bit % 8);
            } else {
                *byte &= !(1 << (self.bit % 8));
            }
            self.bit += 1;
        }
        Ok(())
    }

    /// `value` in a field `width` wide, or `Unencodable(what)` if it does not fit.
    fn field(&mut self, value: usize, width: u32, what: &'static str) -> R<()> {
        let v = u32::try_from(value).map_err(|_| PackError::Unencodable(what))?;
        if width < 32 && v >> width != 0 {
            return Err(PackError::Unencodable(what));
        }
        self.put(v, width)
    }

    fn flag(&mut self, b: bool) -> R<()> {
        self.put(u32::from(b), 1)
    }

    /// An unsigned value of any size: its width (6 bits), then that many bits.
    fn uv(&mut self, v: u32) -> R<()> {
        let w = 32 - v.leading_zeros();
        self.put(w, WIDTH_BITS)?;
        self.put(v, w)
    }

    /// A signed value: zigzag, then [`Writer::uv`].
    fn sv(&mut self, v: i32) -> R<()> {
        self.uv(((v << 1) ^ (v >> 31)) as u32)
    }
}

struct Reader<'a> {
    bytes: &'a [u8],
    bit: usize,
}

impl Reader<'_> {
    fn get(&mut self, width: u32) -> R<u32> {
        let mut v = 0u32;
        for i in 0..width.min(32) {
            let byte = self.bytes.get(self.bit / 8).ok_or(PackError::End)?;
            if (byte >> (self.bit % 8)) & 1 != 0 {
                v |= 1 << i;
            }
            self.bit += 1;
        }
        Ok(v)
    }

    fn u8(&mut self, width: u32) -> R<u8> {
        u8::try_from(self.get(width)?).map_err(|_| PackError::Value("byte"))
    }

    fn flag(&mut self) -> R<bool> {
        Ok(self.get(1)? != 0)
    }

    fn uv(&mut self) -> R<u32> {
        let w = self.get(WIDTH_BITS)?;
        if w > 32 {
            return Err(PackError::Value("width"));
        }
        self.get(w)
    }

    fn sv(&mut self) -> R<i32> {
        let z = self.uv()?;
        Ok(((z >> 1) as i32) ^ -((z & 1) as i32))
    }

    /// An optional reference (`0`: none, `n + 1`: `Some(n)`) `width` wide.
    fn opt(&mut self, width: u32) -> R<Option<u8>> {
        let v = self.get(width)?;
        match v.checked_sub(1) {
            None => Ok(None),
            Some(n) => u8::try_from(n).map(Some).map_err(|_| PackError::Value("reference")),
        }
    }
}

fn push<T, const N: usize>(v: &mut Vec<T, N>, x: T, what: &'static str) -> R<()> {
    v.push(x).map_err(|_| PackError::Capacity(what))
}

fn opt_value(o: Option<u8>) -> usize {
    o.map_or(0, |n| usize::from(n) + 1)
}

/// The widths that follow from the table's counts.
#[derive(Clone, Copy)]
struct Widths {
    event: u32,
    event_opt: u32,
    var: u32,
    var_opt: u32,
    input: u32,
    input_opt: u32,
    outputs: u32,
    timer: u32,
    duration: u32,
    code: u32,
    chart: u32,
    peer: u32,
    peers: u32,
}

impl Widths {
    /// The widths of a table with `events` events and nothing else yet.
    fn new(events: usize) -> Widths {
        Widths {
            event: bits(events),
            event_opt: bits(events + 1),
            var: 0,
            var_opt: 0,
            input: 0,
            input_opt: 0,
            outputs: 0,
            timer: 0,
            duration: 0,
            code: 0,
            chart: 0,
            peer: 0,
            peers: 0,
        }
    }

    fn vars(&mut self, n: usize) {
        self.var = bits(n);
        self.var_opt = bits(n + 1);
    }

    fn inputs(&mut self, n: usize) {
        self.input = bits(n);
        self.input_opt = bits(n + 1);
    }

    fn peers(&mut self, n: usize) {
        self.peer = bits(n);
        self.peers = n as u32;
    }

    /// Every width of `t` (with `durations` distinct timer durations).
    fn of(t: &Table, durations: usize) -> Widths {
        let mut wd = Widths::new(usize::from(t.events));
        wd.vars(t.vars.len());
        wd.inputs(t.inputs.len());
        wd.outputs = t.outputs.len() as u32;
        wd.timer = bits(t.timers.len());
        wd.duration = bits(durations);
        wd.code = bits(t.code.len() + 1);
        wd.chart = bits(t.charts.len());
        wd.peers(t.peers.len());
        wd
    }
}

/// Field widths of the fixed-size counts.
const ROLE_LEN_BITS: u32 = 4;
const CHANNEL_BITS: u32 = 5;
const EVENTS_BITS: u32 = 7;
const VARS_BITS: u32 = 6;
const INPUTS_BITS: u32 = 5;
const OUTPUTS_BITS: u32 = 5;
const PIN_WIDTH_BITS: u32 = 3;
const TIMERS_BITS: u32 = 4;
const DURATIONS_BITS: u32 = 4;
const CODE_BITS: u32 = 8;
const OP_BITS: u32 = 5;
const CHARTS_BITS: u32 = 4;
const CHART_STATES_BITS: u32 = 7;
const CHART_TRANSITIONS_BITS: u32 = 8;
const CHART_INPUTS_BITS: u32 = 6;
const ACTION_COUNT_WIDTH_BITS: u32 = 3;
const ACTION_BITS: u32 = 3;
const FAULT_BITS: u32 = 8;
const EXPR_LEN_BITS: u32 = 5;
const ROUTES_BITS: u32 = 7;
const PEERS_BITS: u32 = 4;
const PEER_WIDTH_BITS: u32 = 5;
const PUBLICATIONS_BITS: u32 = 5;
const SUBSCRIPTIONS_BITS: u32 = 6;
const TOPIC_WIDTH_BITS: u32 = 4;
const ALARMS_BITS: u32 = 4;

/// The distinct durations of the table's timer starts, in order of first use.
fn durations(t: &Table) -> R<Vec<u32, MAX_TIMER_DURATIONS>> {
    let mut d: Vec<u32, MAX_TIMER_DURATIONS> = Vec::new();
    for a in &t.actions {
        if let Action::StartTimer { ms, .. } = *a {
            if !d.contains(&ms) {
                d.push(ms)
                    .map_err(|_| PackError::Unencodable("timer durations"))?;
            }
        }
    }
    Ok(d)
}

/// Distinct timer durations a table may have (a field of 4 bits counts them).
pub const MAX_TIMER_DURATIONS: usize = 15;

fn put_expr(w: &mut Writer, e: Expr, cursor: &mut usize, wd: &Widths) -> R<()> {
    let start = usize::from(e.start);
    w.flag(start == *cursor)?;
    if start != *cursor {
        w.field(start, wd.code, "expression start")?;
    }
    let len = usize::from(e.len)
        .checked_sub(1)
        .ok_or(PackError::Unencodable("expression length"))?;
    w.field(len, EXPR_LEN_BITS, "expression length")?;
    *cursor = start + usize::from(e.len);
    Ok(())
}

fn get_expr(r: &mut Reader, cursor: &mut usize, wd: &Widths) -> R<Expr> {
    let start = if r.flag()? {
        u8::try_from(*cursor).map_err(|_| PackError::Value("expression start"))?
    } else {
        r.u8(wd.code)?
    };
    let len = r.u8(EXPR_LEN_BITS)? + 1;
    *cursor = usize::from(start) + usize::from(len);
    Ok(Expr { start, len })
}

/// Writes `t`'s payload into `buf`; returns its length in bytes. `marks`, if given, gets
/// the bit offset where each of [`SECTIONS`] ends.
pub fn encode(t: &Table, buf: &mut [u8], mut marks: Option<&mut [usize; 16]>) -> R<usize> {
    let mut w = Writer { buf, bit: 0 };
    let mut mark = |w: &Writer, i: usize| {
        if let Some(m) = marks.as_deref_mut() {
            if let Some(slot) = m.get_mut(i) {
                *slot = w.bit;
            }
        }
    };
    let durations = durations(t)?;
    let wd = Widths::of(t, durations.len());
    // Role and network.
    let role = t.header.role.as_bytes();
    w.field(role.len(), ROLE_LEN_BITS, "role")?;
    for &b in role {
        w.put(u32::from(b), 8)?;
    }
    w.put(u32::from(t.header.pan_id), 16)?;
    let channel = usize::from(t.header.channel)
        .checked_sub(usize::from(*CHANNELS.start()))
        .ok_or(PackError::Unencodable("channel"))?;
    w.field(channel, CHANNEL_BITS, "channel")?;
    mark(&w, 0);
    // Events and the commands' events.
    w.field(usize::from(t.events), EVENTS_BITS, "events")?;
    for e in [t.start, t.home, t.boot] {
        w.field(opt_value(e), wd.event_opt, "event")?;
    }
    mark(&w, 1);
    w.field(t.vars.len(), VARS_BITS, "vars")?;
    for &v in &t.vars {
        w.sv(v)?;
    }
    mark(&w, 2);
    // Pins: one width for inputs and outputs.
    let pins = t.inputs.iter().map(|i| i.pin).chain(t.outputs.iter().map(|o| o.pin));
    let pin_width = bits(usize::from(pins.max().unwrap_or(0)) + 1);
    w.field(pin_width as usize, PIN_WIDTH_BITS, "pin")?;
    w.field(t.inputs.len(), INPUTS_BITS, "inputs")?;
    for i in &t.inputs {
        w.field(usize::from(i.pin), pin_width, "pin")?;
        w.field(opt_value(i.rise), wd.event_opt, "event")?;
        w.field(opt_value(i.fall), wd.event_opt, "event")?;
        w.field(opt_value(i.var), wd.var_opt, "variable")?;
    }
    mark(&w, 3);
    w.field(t.outputs.len(), OUTPUTS_BITS, "outputs")?;
    for o in &t.outputs {
        w.field(usize::from(o.pin), pin_width, "pin")?;
        w.put(level(o.fault), 2)?;
        w.put(level(o.start), 2)?;
        w.flag(o.home)?;
    }
    mark(&w, 4);
    w.field(t.timers.len(), TIMERS_BITS, "timers")?;
    for tm in &t.timers {
        w.field(usize::from(tm.event), wd.event, "event")?;
    }
    w.field(durations.len(), DURATIONS_BITS, "timer durations")?;
    for &d in &durations {
        w.uv(d)?;
    }
    mark(&w, 5);
    w.field(t.code.len(), CODE_BITS, "code")?;
    for &op in &t.code {
        put_op(&mut w, op, &wd)?;
    }
    mark(&w, 6);
    // Charts: their counts, then the states, actions and transitions pools in order.
    w.field(t.charts.len(), CHARTS_BITS, "charts")?;
    let mut prev = (0usize, 0usize);
    for c in &t.charts {
        let (s_end, t_end) = (usize::from(c.states_end), usize::from(c.transitions_end));
        let states = s_end
            .checked_sub(prev.0)
            .ok_or(PackError::Unencodable("chart states"))?;
        let transitions = t_end
            .checked_sub(prev.1)
            .ok_or(PackError::Unencodable("chart transitions"))?;
        prev = (s_end, t_end);
        w.field(states, CHART_STATES_BITS, "chart states")?;
        w.field(transitions, CHART_TRANSITIONS_BITS, "chart transitions")?;
        w.field(usize::from(c.inputs), CHART_INPUTS_BITS, "chart inputs")?;
        let sw = bits(states);
        w.field(usize::from(c.initial), sw, "initial state")?;
        w.field(usize::from(c.idle), sw, "idle state")?;
    }
    if prev != (t.states.len(), t.transitions.len()) {
        return Err(PackError::Unencodable("chart pools"));
    }
    mark(&w, 7);
    let mut counts = [0usize; MAX_STATES];
    let mut start = 0usize;
    for (s, count) in t.states.iter().zip(counts.iter_mut()) {
        let end = usize::from(s.actions_end);
        *count = end
            .checked_sub(start)
            .ok_or(PackError::Unencodable("state actions"))?;
        start = end;
    }
    if start != t.actions.len() {
        return Err(PackError::Unencodable("state actions"));
    }
    let counts = counts.get(..t.states.len()).unwrap_or(&[]);
    let count_width = bits(counts.iter().copied().max().unwrap_or(0) + 1);
    w.field(count_width as usize, ACTION_COUNT_WIDTH_BITS, "state actions")?;
    for &n in counts {
        w.field(n, count_width, "state actions")?;
    }
    mark(&w, 8);
    let mut cursor = 0usize;
    for &a in &t.actions {
        put_action(&mut w, a, &wd, &durations, &mut cursor)?;
    }
    mark(&w, 9);
    let mut first = 0usize;
    for (i, c) in t.charts.iter().enumerate() {
        let end = usize::from(c.transitions_end);
        let states = t.chart_states(i).len();
        let sw = bits(states);
        let mut prev_to = usize::from(c.idle);
        for tr in t.transitions.get(first..end).unwrap_or(&[]) {
            let (from, to) = (usize::from(tr.from), usize::from(tr.to));
            w.flag(from == prev_to)?;
            if from != prev_to {
                w.field(from, sw, "state")?;
            }
            w.flag(to == from + 1)?;
            if to != from + 1 {
                w.field(to, sw, "state")?;
            }
            w.field(
                opt_value(tr.trigger),
                bits(usize::from(c.inputs) + 1),
                "trigger",
            )?;
            w.flag(tr.guard.is_some())?;
            if let Some(g) = tr.guard {
                put_expr(&mut w, g, &mut cursor, &wd)?;
            }
            prev_to = to;
        }
        first = end;
    }
    mark(&w, 10);
    w.field(t.routes.len(), ROUTES_BITS, "routes")?;
    let mut chart = 0usize;
    let mut next_input = [0usize; MAX_CHARTS];
    for r in &t.routes {
        w.field(usize::from(r.event), wd.event, "event")?;
        let c = usize::from(r.chart);
        w.flag(c == chart)?;
        if c != chart {
            w.field(c, wd.chart, "chart")?;
        }
        chart = c;
        let inputs = t.charts.get(c).ok_or(PackError::Unencodable("chart"))?.inputs;
        let next = next_input.get_mut(c).ok_or(PackError::Unencodable("chart"))?;
        let input = usize::from(r.input);
        w.flag(input == *next)?;
        if input != *next {
            w.field(input, bits(usize::from(inputs)), "chart input")?;
        }
        *next = input + 1;
    }
    mark(&w, 11);
    w.field(t.peers.len(), PEERS_BITS, "peers")?;
    let peer_width = bits(usize::from(t.peers.iter().copied().max().unwrap_or(0)) + 1);
    w.field(peer_width as usize, PEER_WIDTH_BITS, "peer")?;
    for &p in &t.peers {
        w.field(usize::from(p), peer_width, "peer")?;
    }
    mark(&w, 12);
    let topics = t
        .publications
        .iter()
        .map(|p| p.topic)
        .chain(t.subscriptions.iter().map(|s| s.topic));
    let topic_width = bits(usize::from(topics.max().unwrap_or(0)) + 1);
    w.field(t.publications.len(), PUBLICATIONS_BITS, "publications")?;
    w.field(topic_width as usize, TOPIC_WIDTH_BITS, "topic")?;
    let mut next_topic = 0usize;
    for p in &t.publications {
        w.field(usize::from(p.event), wd.event, "event")?;
        let topic = usize::from(p.topic);
        w.flag(topic == next_topic)?;
        if topic != next_topic {
            w.field(topic, topic_width, "topic")?;
        }
        next_topic = topic + 1;
        w.field(usize::from(p.subscribers), wd.peers, "subscribers")?;
    }
    mark(&w, 13);
    w.field(t.subscriptions.len(), SUBSCRIPTIONS_BITS, "subscriptions")?;
    let mut prev_event: Option<usize> = None;
    for s in &t.subscriptions {
        w.field(usize::from(s.publisher), wd.peer, "publisher")?;
        w.field(usize::from(s.topic), topic_width, "topic")?;
        let e = usize::from(s.event);
        let same = prev_event == Some(e);
        let next = prev_event.map(|p| p + 1) == Some(e);
        w.flag(same)?;
        if !same {
            w.flag(next)?;
            if !next {
                w.field(e, wd.event, "event")?;
            }
        }
        prev_event = Some(e);
    }
    mark(&w, 14);
    let safety = &t.safety;
    w.field(opt_value(safety.estop), wd.input_opt, "estop")?;
    w.flag(safety.link_fault)?;
    w.field(usize::from(safety.restart), t.inputs.len() as u32, "restart")?;
    w.field(safety.alarms.len(), ALARMS_BITS, "alarms")?;
    for a in &safety.alarms {
        w.put(a.level as u32, 2)?;
        put_expr(&mut w, a.when, &mut cursor, &wd)?;
    }
    mark(&w, 15);
    let len = w.bit.div_ceil(8);
    // Zero the padding of the last byte.
    let pad = (8 - w.bit % 8) % 8;
    w.put(0, pad as u32)?;
    Ok(len)
}

fn level(l: Level) -> u32 {
    match l {
        Level::Low => 0,
        Level::High => 1,
        Level::Hold => 2,
    }
}

fn get_level(r: &mut Reader) -> R<Level> {
    match r.get(2)? {
        0 => Ok(Level::Low),
        1 => Ok(Level::High),
        2 => Ok(Level::Hold),
        _ => Err(PackError::Value("level")),
    }
}

fn put_op(w: &mut Writer, op: Op, wd: &Widths) -> R<()> {
    let code = match op {
        Op::Const(_) => 0,
        Op::Var(_) => 1,
        Op::Input(_) => 2,
        Op::Not => 3,
        Op::And => 4,
        Op::Or => 5,
        Op::Eq => 6,
        Op::Ne => 7,
        Op::Lt => 8,
        Op::Le => 9,
        Op::Gt => 10,
        Op::Ge => 11,
        Op::Add => 12,
        Op::Sub => 13,
        Op::Mul => 14,
        Op::Div => 15,
        Op::Rem => 16,
        Op::Wrap { .. } => 17,
    };
    w.put(code, OP_BITS)?;
    match op {
        Op::Const(c) => w.sv(c),
        Op::Var(v) => w.field(usize::from(v), wd.var, "variable"),
        Op::Input(i) => w.field(usize::from(i), wd.input, "input"),
        Op::Wrap { bits, signed } => {
            w.put(u32::from(bits), 8)?;
            w.flag(signed)
        }
        _ => Ok(()),
    }
}

fn get_op(r: &mut Reader, wd: &Widths) -> R<Op> {
    Ok(match r.get(OP_BITS)? {
        0 => Op::Const(r.sv()?),
        1 => Op::Var(r.u8(wd.var)?),
        2 => Op::Input(r.u8(wd.input)?),
        3 => Op::Not,
        4 => Op::And,
        5 => Op::Or,
        6 => Op::Eq,
        7 => Op::Ne,
        8 => Op::Lt,
        9 => Op::Le,
        10 => Op::Gt,
        11 => Op::Ge,
        12 => Op::Add,
        13 => Op::Sub,
        14 => Op::Mul,
        15 => Op::Div,
        16 => Op::Rem,
        17 => Op::Wrap {
            bits: r.u8(8)?,
            signed: r.flag()?,
        },
        _ => return Err(PackError::Value("operation")),
    })
}

fn put_action(
    w: &mut Writer,
    a: Action,
    wd: &Widths,
    durations: &[u32],
    cursor: &mut usize,
) -> R<()> {
    match a {
        Action::Set { var, expr } => {
            w.put(A_SET, ACTION_BITS)?;
            w.field(usize::from(var), wd.var, "variable")?;
            put_expr(w, expr, cursor, wd)
        }
        Action::Drive { mask, value } => {
            w.put(A_DRIVE, ACTION_BITS)?;
            w.field(usize::from(mask), wd.outputs, "drive mask")?;
            w.field(usize::from(value), wd.outputs, "drive value")
        }
        Action::Emit(e) => {
            w.put(A_EMIT, ACTION_BITS)?;
            w.field(usize::from(e), wd.event, "event")
        }
        Action::Publish(e) => {
            w.put(A_PUBLISH, ACTION_BITS)?;
            w.field(usize::from(e), wd.event, "event")
        }
        Action::StartTimer { timer, ms } => {
            w.put(A_START, ACTION_BITS)?;
            w.field(usize::from(timer), wd.timer, "timer")?;
            let d = durations
                .iter()
                .position(|&d| d == ms)
                .ok_or(PackError::Unencodable("timer duration"))?;
            w.field(d, wd.duration, "timer duration")
        }
        Action::CancelTimer(timer) => {
            w.put(A_CANCEL, ACTION_BITS)?;
            w.field(usize::from(timer), wd.timer, "timer")
        }
        Action::Fault(code) => {
            w.put(A_FAULT, ACTION_BITS)?;
            w.put(u32::from(code), FAULT_BITS)
        }
    }
}

fn get_action(r: &mut Reader, wd: &Widths, durations: &[u32], cursor: &mut usize) -> R<Action> {
    Ok(match r.get(ACTION_BITS)? {
        A_SET => Action::Set {
            var: r.u8(wd.var)?,
            expr: get_expr(r, cursor, wd)?,
        },
        A_DRIVE => Action::Drive {
            mask: get_u16(r, wd.outputs)?,
            value: get_u16(r, wd.outputs)?,
        },
        A_EMIT => Action::Emit(r.u8(wd.event)?),
        A_PUBLISH => Action::Publish(r.u8(wd.event)?),
        A_START => Action::StartTimer {
            timer: r.u8(wd.timer)?,
            ms: {
                let d = r.get(wd.duration)?;
                *usize::try_from(d)
                    .ok()
                    .and_then(|d| durations.get(d))
                    .ok_or(PackError::Value("timer duration"))?
            },
        },
        A_CANCEL => Action::CancelTimer(r.u8(wd.timer)?),
        A_FAULT => Action::Fault(r.u8(FAULT_BITS)?),
        _ => return Err(PackError::Value("action")),
    })
}

fn get_u16(r: &mut Reader, width: u32) -> R<u16> {
    u16::try_from(r.get(width)?).map_err(|_| PackError::Value("mask"))
}

fn end8(n: usize, what: &'static str) -> R<u8> {
    u8::try_from(n).map_err(|_| PackError::Capacity(what))
}

/// Reads a payload written by [`encode`]: the table (generation 0) and the bytes left
/// after it (non-zero only past the padding byte, which must be zero bits).
pub fn decode(bytes: &[u8]) -> R<(Table, usize)> {
    let mut r = Reader { bytes, bit: 0 };
    let mut t = Table::empty("");
    let role_len = r.get(ROLE_LEN_BITS)?;
    let mut role = [0u8; 16];
    let role_len = usize::try_from(role_len).map_err(|_| PackError::Capacity("role"))?;
    if role_len > MAX_ROLE_NAME {
        return Err(PackError::Capacity("role"));
    }
    for b in role.iter_mut().take(role_len) {
        *b = r.u8(8)?;
    }
    let name = core::str::from_utf8(role.get(..role_len).unwrap_or(&[]))
        .map_err(|_| PackError::Utf8)?;
    let mut role_name = String::new();
    role_name
        .push_str(name)
        .map_err(|_| PackError::Capacity("role"))?;
    t.header.role = role_name;
    t.header.pan_id = u16::try_from(r.get(16)?).map_err(|_| PackError::Value("pan"))?;
    t.header.channel = r.u8(CHANNEL_BITS)? + CHANNELS.start();
    t.events = r.u8(EVENTS_BITS)?;
    // Counts known so far; the rest follow.
    let mut wd = Widths::new(usize::from(t.events));
    t.start = r.opt(wd.event_opt)?;
    t.home = r.opt(wd.event_opt)?;
    t.boot = r.opt(wd.event_opt)?;
    let vars = r.get(VARS_BITS)?;
    for _ in 0..vars {
        push(&mut t.vars, r.sv()?, "vars")?;
    }
    wd.vars(t.vars.len());
    let pin_width = r.get(PIN_WIDTH_BITS)?;
    let inputs = r.get(INPUTS_BITS)?;
    for _ in 0..inputs {
        let input = Input {
            pin: r.u8(pin_width)?,
            rise: r.opt(wd.event_opt)?,
            fall: r.opt(wd.event_opt)?,
            var: r.opt(wd.var_opt)?,
        };
        push(&mut t.inputs, input, "inputs")?;
    }
    wd.inputs(t.inputs.len());
    let outputs = r.get(OUTPUTS_BITS)?;
    for _ in 0..outputs {
        let output = Output {
            pin: r.u8(pin_width)?,
            fault: get_level(&mut r)?,
            start: get_level(&mut r)?,
            home: r.flag()?,
        };
        push(&mut t.outputs, output, "outputs")?;
    }
    wd.outputs = t.outputs.len() as u32;
    let timers = r.get(TIMERS_BITS)?;
    for _ in 0..timers {
        let event = r.u8(wd.event)?;
        push(&mut t.timers, Timer { event }, "timers")?;
    }
    wd.timer = bits(t.timers.len());
    let mut durations: Vec<u32, MAX_TIMER_DURATIONS> = Vec::new();
    for _ in 0..r.get(DURATIONS_BITS)? {
        push(&mut durations, r.uv()?, "timer durations")?;
    }
    wd.duration = bits(durations.len());
    let code = r.get(CODE_BITS)?;
    for _ in 0..code {
        let op = get_op(&mut r, &wd)?;
        push(&mut t.code, op, "code")?;
    }
    wd.code = bits(t.code.len() + 1);
    let charts = r.get(CHARTS_BITS)?;
    let (mut s_end, mut t_end) = (0usize, 0usize);
    for _ in 0..charts {
        let states = r.get(CHART_STATES_BITS)? as usize;
        let transitions = r.get(CHART_TRANSITIONS_BITS)? as usize;
        let inputs = r.u8(CHART_INPUTS_BITS)?;
        let sw = bits(states);
        s_end += states;
        t_end += transitions;
        let chart = Chart {
            states_end: end8(s_end, "states")?,
            transitions_end: end8(t_end, "transitions")?,
            inputs,
            initial: r.u8(sw)?,
            idle: r.u8(sw)?,
        };
        push(&mut t.charts, chart, "charts")?;
    }
    if s_end > MAX_STATES {
        return Err(PackError::Capacity("states"));
    }
    if t_end > MAX_TRANSITIONS {
        return Err(PackError::Capacity("transitions"));
    }
    wd.chart = bits(t.charts.len());
    let count_width = r.get(ACTION_COUNT_WIDTH_BITS)?;
    let mut actions = 0usize;
    for _ in 0..s_end {
        actions += r.get(count_width)? as usize;
        let actions_end = end8(actions, "actions")?;
        push(&mut t.states, State { actions_end }, "states")?;
    }
    if actions > MAX_ACTIONS {
        return Err(PackError::Capacity("actions"));
    }
    let mut cursor = 0usize;
    for _ in 0..actions {
        let a = get_action(&mut r, &wd, &durations, &mut cursor)?;
        push(&mut t.actions, a, "actions")?;
    }
    let mut s_first = 0usize;
    for c in t.charts.clone().iter() {
        let states = usize::from(c.states_end).saturating_sub(s_first);
        s_first = usize::from(c.states_end);
        let sw = bits(states);
        let tw = bits(usize::from(c.inputs) + 1);
        let mut prev_to = c.idle;
        let n = usize::from(c.transitions_end).saturating_sub(t.transitions.len());
        for _ in 0..n {
            let from = if r.flag()? { prev_to } else { r.u8(sw)? };
            let to = if r.flag()? {
                from.checked_add(1).ok_or(PackError::Value("state"))?
            } else {
                r.u8(sw)?
            };
            let trigger = r.opt(tw)?;
            let guard = if r.flag()? {
                Some(get_expr(&mut r, &mut cursor, &wd)?)
            } else {
                None
            };
            let tr = Transition {
                from,
                to,
                trigger,
                guard,
            };
            push(&mut t.transitions, tr, "transitions")?;
            prev_to = to;
        }
    }
    let routes = r.get(ROUTES_BITS)?;
    let mut chart = 0u8;
    let mut next_input = [0u8; MAX_CHARTS];
    for _ in 0..routes {
        let event = r.u8(wd.event)?;
        if !r.flag()? {
            chart = r.u8(wd.chart)?;
        }
        let inputs = t
            .charts
            .get(usize::from(chart))
            .ok_or(PackError::Value("chart"))?
            .inputs;
        let next = next_input
            .get_mut(usize::from(chart))
            .ok_or(PackError::Value("chart"))?;
        let input = if r.flag()? {
            *next
        } else {
            r.u8(bits(usize::from(inputs)))?
        };
        *next = input.checked_add(1).ok_or(PackError::Value("chart input"))?;
        push(
            &mut t.routes,
            Route {
                event,
                chart,
                input,
            },
            "routes",
        )?;
    }
    let peers = r.get(PEERS_BITS)?;
    let peer_width = r.get(PEER_WIDTH_BITS)?;
    for _ in 0..peers {
        let p = u16::try_from(r.get(peer_width)?).map_err(|_| PackError::Value("peer"))?;
        push(&mut t.peers, p, "peers")?;
    }
    wd.peers(t.peers.len());
    let publications = r.get(PUBLICATIONS_BITS)?;
    let topic_width = r.get(TOPIC_WIDTH_BITS)?;
    let mut next_topic = 0u8;
    for _ in 0..publications {
        let event = r.u8(wd.event)?;
        let topic = if r.flag()? {
            next_topic
        } else {
            r.u8(topic_width)?
        };
        next_topic = topic.checked_add(1).ok_or(PackError::Value("topic"))?;
        let subscribers = r.u8(wd.peers)?;
        push(
            &mut t.publications,
            Publication {
                event,
                topic,
                subscribers,
            },
            "publications",
        )?;
    }
    let subscriptions = r.get(SUBSCRIPTIONS_BITS)?;
    let mut prev_event: Option<u8> = None;
    for _ in 0..subscriptions {
        let publisher = r.u8(wd.peer)?;
        let topic = r.u8(topic_width)?;
        let event = match prev_event {
            Some(p) if r.flag()? => p,
            Some(p) if r.flag()? => p.checked_add(1).ok_or(PackError::Value("event"))?,
            Some(_) => r.u8(wd.event)?,
            None => {
                // Neither flag can hold for the first: both are written as zero.
                if r.flag()? || r.flag()? {
                    return Err(PackError::Value("event"));
                }
                r.u8(wd.event)?
            }
        };
        prev_event = Some(event);
        push(
            &mut t.subscriptions,
            Subscription {
                publisher,
                topic,
                event,
            },
            "subscriptions",
        )?;
    }
    let estop = r.opt(wd.input_opt)?;
    let link_fault = r.flag()?;
    let restart = u16::try_from(r.get(t.inputs.len() as u32)?)
        .map_err(|_| PackError::Value("restart"))?;
    let mut alarms = Vec::new();
    for _ in 0..r.get(ALARMS_BITS)? {
        let level = match r.get(2)? {
            0 => AlarmLevel::Info,
            1 => AlarmLevel::Warning,
            2 => AlarmLevel::Fault,
            _ => return Err(PackError::Value("alarm level")),
        };
        let when = get_expr(&mut r, &mut cursor, &wd)?;
        push(&mut alarms, AlarmDecl { level, when }, "alarms")?;
    }
    t.safety = Safety {
        estop,
        link_fault,
        restart,
        alarms,
    };
    let used = r.bit.div_ceil(8);
    let pad = (8 - r.bit % 8) % 8;
    if r.get(pad as u32)? != 0 {
        return Err(PackError::Value("padding"));
    }
    Ok((t, bytes.len().saturating_sub(used)))
}
