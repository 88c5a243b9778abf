//! The payload of a table blob (schema 7): the [`Table`] as a stream of bit fields, each
//! as wide as the table's own counts make it. docs/table-format.md ("Payload") gives it
//! field by field.
//!
//! Fields go least significant bit first, from bit 0 of byte 0 on; the last byte is padded
//! with zero bits. Counts are Elias gamma codes (`n + 1`: as many zero bits as it has bits
//! after its leading one, a one, then those bits), so a small count is short. A reference
//! is as wide as the count it indexes (an event id takes `bits(events)`, a chart-local
//! state `bits(states of the chart)`); an optional one takes one value more (0 is `None`,
//! `n + 1` is `Some(n)`). The shapes a compiled table has are one-bit flags: an event
//! reference is most often the lowest event not named yet, a transition leaves the state
//! the previous one entered and enters the next state and triggers on its chart's next
//! unused input (all three: one bit), routes one per chart input are only their events, a
//! chart's inputs are the ones its transitions use, a publication publishes the event
//! emitted after the previous one's under the next topic, a subscription raises the next
//! event nothing on the node raises, an expression follows the previous one; an output low
//! on fault and start, no safety declaration, a drive of every output take a bit. Timer
//! durations are declared once (in decimal floating point) and referenced.
//!
//! A table the compact form cannot express (only an invalid one: a reference past its
//! count, pools not laid out chart by chart, a channel outside 11..=26) takes the wide
//! form: the same fields with every reference at the full width of its type and the pools'
//! ends as they are, so that the validator, not the encoder, names its problem. `decode`
//! reads whatever bytes it is given without panicking, and the blob's `decode` validates
//! the result.

use core::fmt;

use heapless::Vec;

use crate::alarm::{AlarmDecl, AlarmLevel, Safety, MAX_DECLARED_ALARMS};
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
    /// (encoding) The table cannot be written in the compact form: see the module docs.
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

/// Bits of a chart's resting-state mask: one a state, for its first 32 states.
const fn rest_width(states: usize) -> u32 {
    if states < 32 {
        states as u32
    } else {
        32
    }
}

/// Section names, in stream order (for [`encode`]'s marks).
pub const SECTIONS: [&str; 16] = [
    "form, role, network",
    "events, vars",
    "inputs",
    "outputs",
    "timers, durations",
    "code",
    "charts",
    "states (action counts)",
    "actions",
    "transitions",
    "routes",
    "start, home, boot",
    "peers",
    "publications",
    "subscriptions",
    "safety",
];

/// Distinct timer durations a table may have.
pub const MAX_TIMER_DURATIONS: usize = MAX_ACTIONS;

/// Fixed field widths.
const ROLE_LEN_BITS: u32 = 4;
const CHANNEL_BITS: u32 = 5;
const PIN_WIDTH_BITS: u32 = 3;
const OP_BITS: u32 = 5;
const COUNT_WIDTH_BITS: u32 = 3;
const EXPR_LEN_BITS: u32 = 5;
const PEER_WIDTH_BITS: u32 = 5;
const TOPIC_WIDTH_BITS: u32 = 3;
const DECADE_BITS: u32 = 2;

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

    /// `n` as the Elias gamma code of `n + 1`.
    fn gamma(&mut self, n: u64) -> R<()> {
        let v = n + 1;
        let tail = 63 - v.leading_zeros();
        for _ in 0..tail {
            self.put(0, 1)?;
        }
        self.put(1, 1)?;
        for i in 0..tail {
            self.put(((v >> i) & 1) as u32, 1)?;
        }
        Ok(())
    }

    fn count(&mut self, n: usize) -> R<()> {
        self.gamma(n as u64)
    }

    /// A signed value: zigzag, then gamma.
    fn sv(&mut self, v: i32) -> R<()> {
        self.gamma(u64::from(((v << 1) ^ (v >> 31)) as u32))
    }
}

/// Reads the payload field by field. The first error is kept and every field after it
/// reads as 0, so the fields need no error path each (what is built after an error is
/// thrown away); every list is read to at most one element past its capacity, so every
/// loop ends.
struct Reader<'a> {
    bytes: &'a [u8],
    bit: usize,
    err: Option<PackError>,
}

impl Reader<'_> {
    /// Keeps `e` if it is the first error.
    #[inline(never)]
    fn fail(&mut self, e: PackError) {
        if self.err.is_none() {
            self.err = Some(e);
        }
    }

    /// The first error, else `e` (a check that stops the decoder).
    #[inline(never)]
    fn stop(&self, e: PackError) -> PackError {
        self.err.unwrap_or(e)
    }

    /// `x`, or `e` and 0 if it does not fit.
    #[inline(never)]
    fn ok_u8(&mut self, x: Option<u8>, e: PackError) -> u8 {
        x.unwrap_or_else(|| {
            self.fail(e);
            0
        })
    }

    #[inline(never)]
    fn get(&mut self, width: u32) -> u32 {
        let mut v = 0u32;
        if self.err.is_some() {
            return 0;
        }
        for i in 0..width.min(32) {
            let Some(byte) = self.bytes.get(self.bit / 8) else {
                self.fail(PackError::End);
                return 0;
            };
            if (byte >> (self.bit % 8)) & 1 != 0 {
                v |= 1 << i;
            }
            self.bit += 1;
        }
        v
    }

    #[inline(never)]
    fn u8(&mut self, width: u32) -> u8 {
        let v = self.get(width);
        self.ok_u8(u8::try_from(v).ok(), PackError::Value("byte"))
    }

    fn flag(&mut self) -> bool {
        self.get(1) != 0
    }

    /// A gamma code (at most 32 bits after the leading one).
    #[inline(never)]
    fn gamma(&mut self) -> u64 {
        let mut tail = 0u32;
        while !self.flag() {
            tail += 1;
            if tail > 32 {
                self.fail(PackError::Value("count"));
            }
            if self.err.is_some() {
                return 0;
            }
        }
        let mut v = 1u64 << tail;
        for i in 0..tail {
            v |= u64::from(self.get(1)) << i;
        }
        v - 1
    }

    #[inline(never)]
    fn count(&mut self) -> usize {
        let n = self.gamma();
        usize::try_from(n).unwrap_or_else(|_| {
            self.fail(PackError::Value("count"));
            0
        })
    }

    /// A list's count, at most one past `cap`: the element past the capacity is read,
    /// then refused.
    #[inline(never)]
    fn list(&mut self, cap: usize) -> usize {
        self.count().min(cap + 1)
    }

    #[inline(never)]
    fn sv(&mut self) -> i32 {
        let z = u32::try_from(self.gamma()).unwrap_or_else(|_| {
            self.fail(PackError::Value("constant"));
            0
        });
        ((z >> 1) as i32) ^ -((z & 1) as i32)
    }

    /// An optional reference (`0`: none, `n + 1`: `Some(n)`) `width` wide.
    #[inline(never)]
    fn opt(&mut self, width: u32) -> Option<u8> {
        let v = self.get(width);
        let n = v.checked_sub(1)?;
        Some(self.ok_u8(u8::try_from(n).ok(), PackError::Value("reference")))
    }

    /// `x` pushed onto `v`, or `Capacity(what)`.
    fn push<T, const N: usize>(&mut self, v: &mut Vec<T, N>, x: T, what: &'static str) {
        if v.push(x).is_err() {
            self.full(what);
        }
    }

    /// A list that had no room: `Capacity(what)`. Out of line, not in each element type's
    /// push; the push itself says whether it had room (no check of its own before it).
    #[inline(never)]
    fn full(&mut self, what: &'static str) {
        self.fail(PackError::Capacity(what));
    }
}

fn opt_value(o: Option<u8>) -> usize {
    o.map_or(0, |n| usize::from(n) + 1)
}

/// The widths that follow from the table's counts.
#[derive(Clone, Copy)]
struct Widths {
    event: u32,
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
    /// The wide form: every reference at the full width of its type.
    wide: bool,
}

impl Widths {
    /// The widths of a table with `events` events and nothing else yet.
    fn new(events: usize) -> Widths {
        Widths {
            event: bits(events),
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
            wide: false,
        }
    }

    /// The widths of the wide form: a `u8` reference 8 bits (an optional one 9), a mask
    /// as wide as its type.
    fn wide(durations: usize) -> Widths {
        Widths {
            event: 8,
            var: 8,
            var_opt: 9,
            input: 8,
            input_opt: 9,
            outputs: 16,
            timer: 8,
            duration: bits(durations),
            code: 8,
            chart: 8,
            peer: 8,
            peers: 8,
            wide: true,
        }
    }

    /// A chart-local state.
    fn state(&self, states: usize) -> u32 {
        if self.wide {
            8
        } else {
            bits(states)
        }
    }

    /// An optional chart input (a trigger).
    fn trigger(&self, inputs: u8) -> u32 {
        if self.wide {
            9
        } else {
            bits(usize::from(inputs) + 1)
        }
    }

    /// A chart input of a route.
    fn chart_input(&self, inputs: u8) -> u32 {
        if self.wide {
            8
        } else {
            bits(usize::from(inputs))
        }
    }

    /// The restart mask over `inputs` inputs.
    fn restart(&self, inputs: usize) -> u32 {
        if self.wide {
            16
        } else {
            inputs as u32
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

/// The events named so far (inputs, timers, actions, routes, commands, in stream order):
/// an event named for the first time is most often the lowest not named yet.
#[derive(Default)]
struct Seen(u64);

impl Seen {
    /// The lowest event not named yet (64 when all are).
    fn fresh(&self) -> u8 {
        (!self.0).trailing_zeros() as u8
    }

    fn mark(&mut self, e: u8) {
        if let Some(bit) = 1u64.checked_shl(u32::from(e)) {
            self.0 |= bit;
        }
    }
}

impl Writer<'_> {
    /// An event: a flag (it is the lowest not named yet), else its id.
    fn event(&mut self, e: u8, seen: &mut Seen, wd: &Widths) -> R<()> {
        let fresh = e == seen.fresh();
        self.flag(fresh)?;
        if !fresh {
            self.field(usize::from(e), wd.event, "event")?;
        }
        seen.mark(e);
        Ok(())
    }

    /// An optional event: a flag (it is the lowest not named yet), else a flag (`Some`) and
    /// then its id.
    fn event_opt(&mut self, e: Option<u8>, seen: &mut Seen, wd: &Widths) -> R<()> {
        let fresh = e.is_some() && e == Some(seen.fresh());
        self.flag(fresh)?;
        if !fresh {
            self.flag(e.is_some())?;
            if let Some(e) = e {
                self.field(usize::from(e), wd.event, "event")?;
            }
        }
        if let Some(e) = e {
            seen.mark(e);
        }
        Ok(())
    }
}

impl Reader<'_> {
    #[inline(never)]
    fn event(&mut self, seen: &mut Seen, wd: &Widths) -> u8 {
        let e = if self.flag() {
            seen.fresh()
        } else {
            self.u8(wd.event)
        };
        seen.mark(e);
        e
    }

    #[inline(never)]
    fn event_opt(&mut self, seen: &mut Seen, wd: &Widths) -> Option<u8> {
        let e = if self.flag() {
            Some(seen.fresh())
        } else if self.flag() {
            Some(self.u8(wd.event))
        } else {
            None
        };
        if let Some(e) = e {
            seen.mark(e);
        }
        e
    }
}

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

/// The events the table's actions emit or publish, each once, in action order, but those
/// routed to a chart (kept on the node, seldom published).
fn emitted(actions: &[Action], routes: &[Route]) -> Vec<u8, MAX_ACTIONS> {
    let mut out: Vec<u8, MAX_ACTIONS> = Vec::new();
    for a in actions {
        if let Action::Emit(e) | Action::Publish(e) = *a {
            if !out.contains(&e) && !routes.iter().any(|r| r.event == e) {
                // As many as the actions: never full.
                let _ = out.push(e);
            }
        }
    }
    out
}

/// The event a publication is expected to publish: the one emitted after the previous
/// publication's (the first emitted for the first publication).
fn expected_publication(emitted: &[u8], prev: Option<u8>) -> Option<u8> {
    let next = match prev {
        None => 0,
        Some(p) => emitted.iter().position(|&e| e == p)? + 1,
    };
    emitted.get(next).copied()
}

/// A duration in decimal floating point: `m * 10^k` (`k` in 2 bits, the largest that
/// divides), `m` a gamma code.
fn put_duration(w: &mut Writer, ms: u32) -> R<()> {
    let mut k = 0;
    let mut m = ms;
    while k < 3 && m != 0 && m.is_multiple_of(10) {
        m /= 10;
        k += 1;
    }
    w.put(k, DECADE_BITS)?;
    w.gamma(u64::from(m))
}

#[inline(never)]
fn get_duration(r: &mut Reader) -> u32 {
    let k = r.get(DECADE_BITS);
    let m = u32::try_from(r.gamma()).ok();
    m.and_then(|m| m.checked_mul(10u32.pow(k)))
        .unwrap_or_else(|| {
            r.fail(PackError::Value("duration"));
            0
        })
}

fn put_expr(w: &mut Writer, e: Expr, cursor: &mut usize, wd: &Widths) -> R<()> {
    let start = usize::from(e.start);
    w.flag(start == *cursor)?;
    if start != *cursor {
        w.field(start, wd.code, "expression start")?;
    }
    if wd.wide {
        w.put(u32::from(e.len), 8)?;
    } else {
        let len = usize::from(e.len)
            .checked_sub(1)
            .ok_or(PackError::Unencodable("expression length"))?;
        w.field(len, EXPR_LEN_BITS, "expression length")?;
    }
    *cursor = start + usize::from(e.len);
    Ok(())
}

#[inline(never)]
fn get_expr(r: &mut Reader, cursor: &mut usize, wd: &Widths) -> Expr {
    let start = if r.flag() {
        r.ok_u8(
            u8::try_from(*cursor).ok(),
            PackError::Value("expression start"),
        )
    } else {
        r.u8(wd.code)
    };
    let len = if wd.wide {
        r.u8(8)
    } else {
        r.u8(EXPR_LEN_BITS) + 1
    };
    *cursor = usize::from(start) + usize::from(len);
    Expr { start, len }
}

fn level(l: Level) -> u32 {
    match l {
        Level::Low => 0,
        Level::High => 1,
        Level::Hold => 2,
    }
}

#[inline(never)]
fn get_level(r: &mut Reader) -> Level {
    match r.get(2) {
        0 => Level::Low,
        1 => Level::High,
        2 => Level::Hold,
        _ => {
            r.fail(PackError::Value("level"));
            Level::Low
        }
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

#[inline(never)]
fn get_op(r: &mut Reader, wd: &Widths) -> Op {
    match r.get(OP_BITS) {
        0 => Op::Const(r.sv()),
        1 => Op::Var(r.u8(wd.var)),
        2 => Op::Input(r.u8(wd.input)),
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
            bits: r.u8(8),
            signed: r.flag(),
        },
        _ => {
            r.fail(PackError::Value("operation"));
            Op::Not
        }
    }
}

/// Action codes (a prefix code, by how often a compiled table has each: the three a motion
/// step uses take two bits, a watchdog's cancel three).
const A_DRIVE: (u32, u32) = (0b00, 2);
const A_START: (u32, u32) = (0b10, 2);
const A_EMIT: (u32, u32) = (0b01, 2);
const A_CANCEL: (u32, u32) = (0b011, 3);
const A_FAULT: (u32, u32) = (0b0111, 4);
const A_SET: (u32, u32) = (0b01111, 5);
const A_PUBLISH: (u32, u32) = (0b11111, 5);

struct ActionCtx<'a> {
    wd: Widths,
    durations: &'a [u32],
    cursor: usize,
    seen: Seen,
}

fn put_action(w: &mut Writer, a: Action, cx: &mut ActionCtx) -> R<()> {
    let code = |w: &mut Writer, (c, n): (u32, u32)| w.put(c, n);
    let wd = cx.wd;
    match a {
        Action::Set { var, expr } => {
            code(w, A_SET)?;
            w.field(usize::from(var), wd.var, "variable")?;
            put_expr(w, expr, &mut cx.cursor, &wd)
        }
        Action::Drive { mask, value } => {
            code(w, A_DRIVE)?;
            let all = all_outputs(&wd);
            w.flag(mask == all)?;
            if mask != all {
                w.field(usize::from(mask), wd.outputs, "drive mask")?;
            }
            w.field(usize::from(value), wd.outputs, "drive value")
        }
        Action::Emit(e) => {
            code(w, A_EMIT)?;
            w.event(e, &mut cx.seen, &wd)
        }
        Action::Publish(e) => {
            code(w, A_PUBLISH)?;
            w.event(e, &mut cx.seen, &wd)
        }
        Action::StartTimer { timer, ms } => {
            code(w, A_START)?;
            w.field(usize::from(timer), wd.timer, "timer")?;
            let d = cx
                .durations
                .iter()
                .position(|&d| d == ms)
                .ok_or(PackError::Unencodable("timer duration"))?;
            w.field(d, wd.duration, "timer duration")
        }
        Action::CancelTimer(timer) => {
            code(w, A_CANCEL)?;
            w.field(usize::from(timer), wd.timer, "timer")
        }
        Action::Fault(c) => {
            code(w, A_FAULT)?;
            w.count(usize::from(c))
        }
    }
}

#[inline(never)]
fn get_action(r: &mut Reader, cx: &mut ActionCtx) -> Action {
    let wd = cx.wd;
    // Each further bit of a code that starts `1 1`: 0 ends it.
    let mut code = (r.get(2), 2);
    while code.0 == (1 << code.1) - 1 && code.1 < 5 {
        code = (code.0 | r.get(1) << code.1, code.1 + 1);
    }
    match code {
        A_SET => Action::Set {
            var: r.u8(wd.var),
            expr: get_expr(r, &mut cx.cursor, &wd),
        },
        A_DRIVE => Action::Drive {
            mask: if r.flag() {
                all_outputs(&wd)
            } else {
                get_u16(r, wd.outputs)
            },
            value: get_u16(r, wd.outputs),
        },
        A_EMIT => Action::Emit(r.event(&mut cx.seen, &wd)),
        A_PUBLISH => Action::Publish(r.event(&mut cx.seen, &wd)),
        A_START => Action::StartTimer {
            timer: r.u8(wd.timer),
            ms: {
                let d = r.get(wd.duration);
                let ms = usize::try_from(d).ok().and_then(|d| cx.durations.get(d));
                ms.copied().unwrap_or_else(|| {
                    r.fail(PackError::Value("timer duration"));
                    0
                })
            },
        },
        A_CANCEL => Action::CancelTimer(r.u8(wd.timer)),
        A_FAULT => {
            let n = r.count();
            Action::Fault(r.ok_u8(u8::try_from(n).ok(), PackError::Value("fault")))
        }
        _ => {
            r.fail(PackError::Value("action"));
            Action::Fault(0)
        }
    }
}

/// The drive mask of every output.
fn all_outputs(wd: &Widths) -> u16 {
    u16::try_from((1u32 << wd.outputs.min(16)) - 1).unwrap_or(u16::MAX)
}

#[inline(never)]
fn get_u16(r: &mut Reader, width: u32) -> u16 {
    let v = r.get(width);
    u16::try_from(v).unwrap_or_else(|_| {
        r.fail(PackError::Value("mask"));
        0
    })
}

/// The event a subscription is expected to raise: the lowest after the previous one's
/// (from 0 for the first) that nothing on the node raises (an input's edge, a timer, an
/// action, START, HOME, the boot).
fn next_subscribed(t: &Table, prev: Option<u8>) -> Option<u8> {
    let first = match prev {
        Some(p) => p.checked_add(1)?,
        None => 0,
    };
    (first..t.events).find(|&e| {
        let edge = t
            .inputs
            .iter()
            .any(|i| i.rise == Some(e) || i.fall == Some(e));
        let timer = t.timers.iter().any(|tm| tm.event == e);
        let action = t.actions.iter().any(|a| match *a {
            Action::Emit(x) | Action::Publish(x) => x == e,
            _ => false,
        });
        let command = [t.start, t.home, t.boot].contains(&Some(e));
        !(edge || timer || action || command)
    })
}

/// Whether chart `c`'s inputs are the ones its `transitions` trigger on, each first used
/// in input order (as the compiler numbers them): then the chart's count of inputs is
/// where its transitions' triggers end, and a trigger used before is `opt` of those used
/// so far.
fn inputs_are_implicit(c: &Chart, transitions: Option<&[Transition]>) -> bool {
    let mut next = 0u8;
    for tr in transitions.unwrap_or(&[]) {
        match tr.trigger {
            Some(i) if i == next => next += 1,
            Some(i) if i > next => return false,
            _ => {}
        }
    }
    transitions.is_some() && next == c.inputs
}

/// Whether `t`'s routes are one per chart input, chart by chart and input by input (as
/// the compiler lays them out): then each is only its event.
fn routes_are_implicit(t: &Table) -> bool {
    let inputs = t.charts.iter().enumerate();
    let mut inputs = inputs.flat_map(|(c, chart)| (0..chart.inputs).map(move |i| (c, i)));
    t.routes
        .iter()
        .all(|r| inputs.next() == Some((usize::from(r.chart), r.input)))
        && inputs.next().is_none()
}

/// Routes of any other shape: a count, then each route's event, chart and input.
fn put_routes(w: &mut Writer, t: &Table, seen: &mut Seen, wd: &Widths) -> R<()> {
    w.count(t.routes.len())?;
    let mut chart = 0usize;
    let mut next_input = [0usize; 256];
    for r in &t.routes {
        w.event(r.event, seen, wd)?;
        let c = usize::from(r.chart);
        w.flag(c == chart)?;
        if c != chart {
            w.field(c, wd.chart, "chart")?;
        }
        chart = c;
        let inputs = match t.charts.get(c) {
            Some(chart) => chart.inputs,
            None if wd.wide => 0,
            None => return Err(PackError::Unencodable("chart")),
        };
        let next = next_input
            .get_mut(c)
            .ok_or(PackError::Unencodable("chart"))?;
        let input = usize::from(r.input);
        w.flag(input == *next)?;
        if input != *next {
            w.field(input, wd.chart_input(inputs), "chart input")?;
        }
        *next = input + 1;
    }
    Ok(())
}

/// A pool's end, or `Capacity(what)` past 255.
fn end8(r: &mut Reader, n: usize, what: &'static str) -> u8 {
    r.ok_u8(u8::try_from(n).ok(), PackError::Capacity(what))
}

/// Writes `t`'s payload into `buf`; returns its length in bytes. The compact form (first
/// bit 0) if it can hold `t` (every table the compiler makes), else the wide form (first
/// bit 1): every reference at the full width of its type and the pools' ends as they are,
/// so that any table, even one the compact form cannot express (an invalid one), has a
/// payload and the validator, not the encoder, names its problem. `marks`, if given, gets
/// the bit offset where each of [`SECTIONS`] ends.
pub fn encode(t: &Table, buf: &mut [u8], marks: Option<&mut [usize; SECTIONS.len()]>) -> R<usize> {
    match encode_form(t, buf, marks, false) {
        Err(PackError::Unencodable(_)) => encode_form(t, buf, None, true),
        other => other,
    }
}

/// Whether [`encode`] writes `t` in the compact form.
pub fn is_compact(t: &Table) -> bool {
    let mut buf = [0u8; crate::limits::MAX_TABLE_BLOB];
    encode_form(t, &mut buf, None, false).is_ok()
}

/// The compact form of `t` (`wide` false: `Unencodable` if it cannot hold `t`) or its
/// wide form (`wide` true: never `Unencodable`).
pub fn encode_form(
    t: &Table,
    buf: &mut [u8],
    mut marks: Option<&mut [usize; SECTIONS.len()]>,
    wide: bool,
) -> R<usize> {
    let mut w = Writer { buf, bit: 0 };
    let mut mark = |w: &Writer, i: usize| {
        if let Some(slot) = marks.as_deref_mut().and_then(|m| m.get_mut(i)) {
            *slot = w.bit;
        }
    };
    w.flag(wide)?;
    let durations = durations(t)?;
    let wd = if wide {
        Widths::wide(durations.len())
    } else {
        Widths::of(t, durations.len())
    };
    let mut seen = Seen::default();
    // Role and network.
    let role = t.header.role.as_bytes();
    w.field(role.len(), ROLE_LEN_BITS, "role")?;
    for &b in role {
        w.put(u32::from(b), 8)?;
    }
    w.put(u32::from(t.header.pan_id), 16)?;
    if wide {
        w.put(u32::from(t.header.channel), 8)?;
    } else {
        let channel = usize::from(t.header.channel)
            .checked_sub(usize::from(*CHANNELS.start()))
            .ok_or(PackError::Unencodable("channel"))?;
        w.field(channel, CHANNEL_BITS, "channel")?;
    }
    mark(&w, 0);
    w.count(usize::from(t.events))?;
    w.count(t.vars.len())?;
    for &v in &t.vars {
        w.sv(v)?;
    }
    mark(&w, 1);
    // Pins: one width for inputs and outputs (8 in the wide form).
    let pin_width = if wide {
        8
    } else {
        let pins = t.inputs.iter().map(|i| i.pin);
        let pins = pins.chain(t.outputs.iter().map(|o| o.pin));
        let pin_width = bits(usize::from(pins.max().unwrap_or(0)) + 1);
        w.field(pin_width as usize, PIN_WIDTH_BITS, "pin")?;
        pin_width
    };
    w.count(t.inputs.len())?;
    for i in &t.inputs {
        w.field(usize::from(i.pin), pin_width, "pin")?;
        w.event_opt(i.rise, &mut seen, &wd)?;
        w.event_opt(i.fall, &mut seen, &wd)?;
        w.field(opt_value(i.var), wd.var_opt, "variable")?;
    }
    mark(&w, 2);
    w.count(t.outputs.len())?;
    for o in &t.outputs {
        w.field(usize::from(o.pin), pin_width, "pin")?;
        // Low on a fault and at the start (most outputs): a bit.
        let low = o.fault == Level::Low && o.start == Level::Low;
        w.flag(low)?;
        if !low {
            w.put(level(o.fault), 2)?;
            w.put(level(o.start), 2)?;
        }
        w.flag(o.home)?;
    }
    mark(&w, 3);
    w.count(t.timers.len())?;
    for tm in &t.timers {
        w.event(tm.event, &mut seen, &wd)?;
    }
    w.count(durations.len())?;
    for &d in &durations {
        put_duration(&mut w, d)?;
    }
    mark(&w, 4);
    w.count(t.code.len())?;
    for &op in &t.code {
        put_op(&mut w, op, &wd)?;
    }
    mark(&w, 5);
    // Charts: their counts (compact) or ends (wide), then the pools.
    w.count(t.charts.len())?;
    let mut prev = (0usize, 0usize);
    for c in &t.charts {
        let (s_end, t_end) = (usize::from(c.states_end), usize::from(c.transitions_end));
        if wide {
            w.put(u32::from(c.states_end), 8)?;
            w.put(u32::from(c.transitions_end), 8)?;
        } else {
            let states = s_end
                .checked_sub(prev.0)
                .ok_or(PackError::Unencodable("chart states"))?;
            let transitions = t_end
                .checked_sub(prev.1)
                .ok_or(PackError::Unencodable("chart transitions"))?;
            w.count(states)?;
            w.count(transitions)?;
        }
        let n_states = s_end.saturating_sub(prev.0);
        let sw = wd.state(n_states);
        let implicit = !wide && inputs_are_implicit(c, t.transitions.get(prev.1..t_end));
        prev = (s_end, t_end);
        w.flag(implicit)?;
        if !implicit {
            w.count(usize::from(c.inputs))?;
        }
        // Idle most often the first state, initial most often idle. A chart that rests in
        // other states too (rare) writes the idle state 0 after its flag, which no other
        // chart writes (it sets the flag): its idle state and resting states follow.
        if c.rests != 0 {
            w.flag(false)?;
            w.field(0, sw, "idle state")?;
            w.field(usize::from(c.idle), sw, "idle state")?;
            w.field(c.rests as usize, rest_width(n_states), "resting states")?;
        } else {
            w.flag(c.idle == 0)?;
            if c.idle != 0 {
                w.field(usize::from(c.idle), sw, "idle state")?;
            }
        }
        w.flag(c.initial == c.idle)?;
        if c.initial != c.idle {
            w.field(usize::from(c.initial), sw, "initial state")?;
        }
    }
    if wide {
        w.count(t.states.len())?;
        w.count(t.transitions.len())?;
    } else if prev != (t.states.len(), t.transitions.len()) {
        return Err(PackError::Unencodable("chart pools"));
    }
    mark(&w, 6);
    if wide {
        w.count(t.actions.len())?;
        for s in &t.states {
            w.put(u32::from(s.actions_end), 8)?;
        }
    } else {
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
        w.field(count_width as usize, COUNT_WIDTH_BITS, "state actions")?;
        // The most common count (the lowest of a tie), if a bit for it and the count for
        // the others is shorter than every count.
        let freq = |m: usize| counts.iter().filter(|&&n| n == m).count();
        let mode = (0..=counts.iter().copied().max().unwrap_or(0))
            .max_by_key(|&m| (freq(m), core::cmp::Reverse(m)));
        let w_ = count_width as usize;
        let mode =
            mode.filter(|&m| w_ + counts.len() + (counts.len() - freq(m)) * w_ < counts.len() * w_);
        w.flag(mode.is_some())?;
        if let Some(m) = mode {
            w.field(m, count_width, "state actions")?;
        }
        for &n in counts {
            if let Some(m) = mode {
                w.flag(n == m)?;
                if n == m {
                    continue;
                }
            }
            w.field(n, count_width, "state actions")?;
        }
    }
    mark(&w, 7);
    let mut cx = ActionCtx {
        wd,
        durations: &durations,
        cursor: 0,
        seen,
    };
    for &a in &t.actions {
        put_action(&mut w, a, &mut cx)?;
    }
    let ActionCtx {
        mut cursor,
        mut seen,
        ..
    } = cx;
    mark(&w, 8);
    // Transitions chart by chart (compact), or the pool as one run (wide).
    // (transitions, state width, trigger width (none: as the chart's inputs so far), idle).
    let mut runs: Vec<(core::ops::Range<usize>, u32, Option<u32>, usize), MAX_CHARTS> = Vec::new();
    if wide {
        let _ = runs.push((0..t.transitions.len(), 8, Some(9), 0));
    } else {
        let mut first = 0usize;
        for (i, c) in t.charts.iter().enumerate() {
            let end = usize::from(c.transitions_end);
            let sw = wd.state(t.chart_states(i).len());
            let transitions = t.transitions.get(first..end);
            let tw = (!inputs_are_implicit(c, transitions)).then(|| wd.trigger(c.inputs));
            let _ = runs.push((first..end, sw, tw, usize::from(c.idle)));
            first = end;
        }
    }
    for (range, sw, tw, idle) in runs {
        let transitions = t.transitions.get(range).unwrap_or(&[]);
        let guarded = transitions.iter().any(|tr| tr.guard.is_some());
        w.flag(guarded)?;
        let mut prev_to = idle;
        let mut next_input = 0usize;
        for tr in transitions {
            let (from, to) = (usize::from(tr.from), usize::from(tr.to));
            let fresh = tr.trigger.map(usize::from) == Some(next_input);
            // A step of a chain (the most common shape): a bit.
            let step = from == prev_to && to == from + 1 && fresh;
            w.flag(step)?;
            if !step {
                w.flag(from == prev_to)?;
                if from != prev_to {
                    w.field(from, sw, "state")?;
                }
                w.flag(to == from + 1)?;
                if to != from + 1 {
                    w.field(to, sw, "state")?;
                }
                w.flag(fresh)?;
                if !fresh {
                    let tw = tw.unwrap_or_else(|| bits(next_input + 1));
                    w.field(opt_value(tr.trigger), tw, "trigger")?;
                }
            }
            if let Some(i) = tr.trigger {
                next_input = next_input.max(usize::from(i) + 1);
            }
            if guarded {
                w.flag(tr.guard.is_some())?;
            }
            if let Some(g) = tr.guard {
                put_expr(&mut w, g, &mut cursor, &wd)?;
            }
            prev_to = to;
        }
    }
    mark(&w, 9);
    let implicit = !wide && routes_are_implicit(t);
    w.flag(implicit)?;
    if implicit {
        for r in &t.routes {
            w.event(r.event, &mut seen, &wd)?;
        }
    } else {
        put_routes(&mut w, t, &mut seen, &wd)?;
    }
    mark(&w, 10);
    for e in [t.start, t.home, t.boot] {
        w.event_opt(e, &mut seen, &wd)?;
    }
    mark(&w, 11);
    w.count(t.peers.len())?;
    let peer_width = bits(usize::from(t.peers.iter().copied().max().unwrap_or(0)) + 1);
    w.field(peer_width as usize, PEER_WIDTH_BITS, "peer")?;
    let mut next = None;
    for &p in &t.peers {
        w.flag(next == Some(p))?;
        if next != Some(p) {
            w.field(usize::from(p), peer_width, "peer")?;
        }
        next = p.checked_add(1);
    }
    mark(&w, 12);
    let topics = t.publications.iter().map(|p| p.topic);
    let topics = topics.chain(t.subscriptions.iter().map(|s| s.topic));
    let topic_width = if wide {
        8
    } else {
        let topic_width = bits(usize::from(topics.max().unwrap_or(0)) + 1);
        w.field(topic_width as usize, TOPIC_WIDTH_BITS, "topic")?;
        topic_width
    };
    w.count(t.publications.len())?;
    let emitted = emitted(&t.actions, &t.routes);
    let mut prev_event = None;
    let mut next_topic = 0usize;
    for p in &t.publications {
        let expected = expected_publication(&emitted, prev_event) == Some(p.event);
        w.flag(expected)?;
        if !expected {
            w.field(usize::from(p.event), wd.event, "event")?;
        }
        prev_event = Some(p.event);
        let topic = usize::from(p.topic);
        w.flag(topic == next_topic)?;
        if topic != next_topic {
            w.field(topic, topic_width, "topic")?;
        }
        next_topic = topic + 1;
        w.field(usize::from(p.subscribers), wd.peers, "subscribers")?;
    }
    mark(&w, 13);
    w.count(t.subscriptions.len())?;
    let mut prev_event: Option<usize> = None;
    for s in &t.subscriptions {
        w.field(usize::from(s.publisher), wd.peer, "publisher")?;
        w.field(usize::from(s.topic), topic_width, "topic")?;
        let e = usize::from(s.event);
        let same = prev_event == Some(e);
        let next = next_subscribed(t, prev_event.map(|p| p as u8)) == Some(s.event);
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
    // No e-stop, no link fault, no restart input, no alarm: a bit.
    let none = *safety == Safety::default();
    w.flag(none)?;
    if !none {
        w.field(opt_value(safety.estop), wd.input_opt, "estop")?;
        w.flag(safety.link_fault)?;
        let restart_width = wd.restart(t.inputs.len());
        w.field(usize::from(safety.restart), restart_width, "restart")?;
        w.count(safety.alarms.len())?;
        for a in &safety.alarms {
            w.put(a.level as u32, 2)?;
            put_expr(&mut w, a.when, &mut cursor, &wd)?;
        }
    }
    mark(&w, 15);
    let len = w.bit.div_ceil(8);
    // Zero the padding of the last byte.
    let pad = (8 - w.bit % 8) % 8;
    w.put(0, pad as u32)?;
    Ok(len)
}

/// Routes of any other shape (see `put_routes`).
#[inline(never)]
fn get_routes(r: &mut Reader, t: &mut Table, seen: &mut Seen, wd: &Widths) -> R<()> {
    let mut chart = 0u8;
    let mut next_input = [0u8; 256];
    for _ in 0..r.list(t.routes.capacity()) {
        let event = r.event(seen, wd);
        if !r.flag() {
            chart = r.u8(wd.chart);
        }
        let inputs = match t.charts.get(usize::from(chart)) {
            Some(c) => c.inputs,
            None if wd.wide => 0,
            None => return Err(r.stop(PackError::Value("chart"))),
        };
        let Some(next) = next_input.get_mut(usize::from(chart)) else {
            return Err(r.stop(PackError::Value("chart")));
        };
        let input = if r.flag() {
            *next
        } else {
            r.u8(wd.chart_input(inputs))
        };
        // Saturating, as a trigger's: the encoder writes an input of 255 and never a
        // fresh one after it.
        *next = input.saturating_add(1);
        let route = Route {
            event,
            chart,
            input,
        };
        r.push(&mut t.routes, route, "routes");
    }
    Ok(())
}

/// The safety declarations (when not all default).
#[inline(never)]
fn get_safety(r: &mut Reader, t: &Table, cursor: &mut usize, wd: &Widths) -> Safety {
    let estop = r.opt(wd.input_opt);
    let link_fault = r.flag();
    let restart = r.get(wd.restart(t.inputs.len()));
    let restart = u16::try_from(restart).unwrap_or_else(|_| {
        r.fail(PackError::Value("restart"));
        0
    });
    let mut alarms: Vec<AlarmDecl, MAX_DECLARED_ALARMS> = Vec::new();
    for _ in 0..r.list(alarms.capacity()) {
        let level = match r.get(2) {
            0 => AlarmLevel::Info,
            1 => AlarmLevel::Warning,
            2 => AlarmLevel::Fault,
            _ => {
                r.fail(PackError::Value("alarm level"));
                AlarmLevel::Info
            }
        };
        let when = get_expr(r, cursor, wd);
        r.push(&mut alarms, AlarmDecl { level, when }, "alarms");
    }
    Safety {
        estop,
        link_fault,
        restart,
        alarms,
    }
}

#[cfg(test)]
mod oracle;

/// Reads a payload written by [`encode`]: the table (generation 0) and the count of bytes
/// left after it (the padding bits of its last byte must be zero).
pub fn decode(bytes: &[u8]) -> R<(Table, usize)> {
    let mut r = Reader {
        bytes,
        bit: 0,
        err: None,
    };
    let wide = r.flag();
    let mut t = Table::empty("");
    let mut seen = Seen::default();
    let role_len = r.get(ROLE_LEN_BITS) as usize;
    if role_len > MAX_ROLE_NAME {
        return Err(r.stop(PackError::Capacity("role")));
    }
    let mut role = [0u8; MAX_ROLE_NAME];
    for b in role.iter_mut().take(role_len) {
        *b = r.u8(8);
    }
    // At most MAX_ROLE_NAME bytes: it fits.
    match crate::text::role_name(role.get(..role_len).unwrap_or(&[])) {
        Ok(name) => t.header.role = name,
        Err(_) => r.fail(PackError::Utf8),
    }
    // 16 bits: a u16.
    t.header.pan_id = r.get(16) as u16;
    t.header.channel = if wide {
        r.u8(8)
    } else {
        r.u8(CHANNEL_BITS) + CHANNELS.start()
    };
    let events = u8::try_from(r.count()).ok();
    t.events = r.ok_u8(events, PackError::Capacity("events"));
    let mut wd = if wide {
        Widths::wide(0)
    } else {
        Widths::new(usize::from(t.events))
    };
    for _ in 0..r.list(t.vars.capacity()) {
        let v = r.sv();
        r.push(&mut t.vars, v, "vars");
    }
    if !wide {
        wd.vars(t.vars.len());
    }
    let pin_width = if wide { 8 } else { r.get(PIN_WIDTH_BITS) };
    for _ in 0..r.list(t.inputs.capacity()) {
        let input = Input {
            pin: r.u8(pin_width),
            rise: r.event_opt(&mut seen, &wd),
            fall: r.event_opt(&mut seen, &wd),
            var: r.opt(wd.var_opt),
        };
        r.push(&mut t.inputs, input, "inputs");
    }
    if !wide {
        wd.inputs(t.inputs.len());
    }
    for _ in 0..r.list(t.outputs.capacity()) {
        let pin = r.u8(pin_width);
        let (fault, start) = if r.flag() {
            (Level::Low, Level::Low)
        } else {
            (get_level(&mut r), get_level(&mut r))
        };
        let output = Output {
            pin,
            fault,
            start,
            home: r.flag(),
        };
        r.push(&mut t.outputs, output, "outputs");
    }
    if !wide {
        wd.outputs = t.outputs.len() as u32;
    }
    for _ in 0..r.list(t.timers.capacity()) {
        let event = r.event(&mut seen, &wd);
        r.push(&mut t.timers, Timer { event }, "timers");
    }
    if !wide {
        wd.timer = bits(t.timers.len());
    }
    let mut durations: Vec<u32, MAX_TIMER_DURATIONS> = Vec::new();
    for _ in 0..r.list(durations.capacity()) {
        let d = get_duration(&mut r);
        r.push(&mut durations, d, "timer durations");
    }
    wd.duration = bits(durations.len());
    for _ in 0..r.list(t.code.capacity()) {
        let op = get_op(&mut r, &wd);
        r.push(&mut t.code, op, "code");
    }
    if !wide {
        wd.code = bits(t.code.len() + 1);
    }
    let (mut s_end, mut t_end) = (0usize, 0usize);
    let mut implicit_inputs = [false; MAX_CHARTS];
    for _ in 0..r.list(t.charts.capacity()) {
        let s_first = s_end;
        if wide {
            s_end = usize::from(r.u8(8));
            t_end = usize::from(r.u8(8));
        } else {
            s_end = s_end.saturating_add(r.count());
            t_end = t_end.saturating_add(r.count());
        }
        let sw = wd.state(s_end.saturating_sub(s_first));
        // Implicit inputs: counted as the chart's transitions are read.
        let implicit = r.flag();
        if let Some(slot) = implicit_inputs.get_mut(t.charts.len()) {
            *slot = implicit;
        }
        let inputs = if implicit {
            0
        } else {
            let n = u8::try_from(r.count()).ok();
            r.ok_u8(n, PackError::Value("chart inputs"))
        };
        let (idle, rests) = match r.flag() {
            true => (0, 0),
            false => match r.u8(sw) {
                // Resting states besides idle: idle, then their mask.
                0 => (r.u8(sw), r.get(rest_width(s_end.saturating_sub(s_first)))),
                idle => (idle, 0),
            },
        };
        let initial = if r.flag() { idle } else { r.u8(sw) };
        let chart = Chart {
            states_end: end8(&mut r, s_end, "states"),
            transitions_end: end8(&mut r, t_end, "transitions"),
            inputs,
            initial,
            idle,
            rests,
        };
        r.push(&mut t.charts, chart, "charts");
    }
    let (states, transitions) = if wide {
        (r.count(), r.count())
    } else {
        (s_end, t_end)
    };
    if states > MAX_STATES {
        return Err(r.stop(PackError::Capacity("states")));
    }
    if transitions > MAX_TRANSITIONS {
        return Err(r.stop(PackError::Capacity("transitions")));
    }
    if !wide {
        wd.chart = bits(t.charts.len());
    }
    let actions = if wide {
        let actions = r.count();
        for _ in 0..states {
            let actions_end = r.u8(8);
            r.push(&mut t.states, State { actions_end }, "states");
        }
        actions
    } else {
        let count_width = r.get(COUNT_WIDTH_BITS);
        let mode = if r.flag() {
            Some(r.get(count_width) as usize)
        } else {
            None
        };
        let mut actions = 0usize;
        for _ in 0..states {
            actions += match mode {
                Some(m) if r.flag() => m,
                _ => r.get(count_width) as usize,
            };
            let actions_end = end8(&mut r, actions, "actions");
            r.push(&mut t.states, State { actions_end }, "states");
        }
        actions
    };
    if actions > MAX_ACTIONS {
        return Err(r.stop(PackError::Capacity("actions")));
    }
    let mut cx = ActionCtx {
        wd,
        durations: &durations,
        cursor: 0,
        seen,
    };
    for _ in 0..actions {
        let a = get_action(&mut r, &mut cx);
        r.push(&mut t.actions, a, "actions");
    }
    let ActionCtx {
        mut cursor,
        mut seen,
        ..
    } = cx;
    // (transitions, state width, trigger width (none: implicit inputs), idle state).
    let mut runs: Vec<(usize, u32, Option<u32>, u8), MAX_CHARTS> = Vec::new();
    if wide {
        let _ = runs.push((transitions, 8, Some(9), 0));
    } else {
        let mut s_first = 0usize;
        let mut t_first = 0usize;
        for (c, &implicit) in t.charts.iter().zip(&implicit_inputs) {
            let sw = wd.state(usize::from(c.states_end).saturating_sub(s_first));
            let n = usize::from(c.transitions_end).saturating_sub(t_first);
            s_first = usize::from(c.states_end);
            t_first = usize::from(c.transitions_end);
            let tw = (!implicit).then(|| wd.trigger(c.inputs));
            let _ = runs.push((n, sw, tw, c.idle));
        }
    }
    for (ci, (n, sw, tw, idle)) in runs.into_iter().enumerate() {
        let guarded = r.flag();
        let mut prev_to = idle;
        let mut next_input = 0u8;
        for _ in 0..n {
            let step = r.flag();
            let from = if step || r.flag() { prev_to } else { r.u8(sw) };
            let to = if step || r.flag() {
                r.ok_u8(from.checked_add(1), PackError::Value("state"))
            } else {
                r.u8(sw)
            };
            let trigger = if step || r.flag() {
                Some(next_input)
            } else {
                match tw {
                    Some(tw) => r.opt(tw),
                    // One of the inputs used so far, or none.
                    None => match r.opt(bits(usize::from(next_input) + 1)) {
                        Some(i) if i >= next_input => {
                            r.fail(PackError::Value("trigger"));
                            None
                        }
                        other => other,
                    },
                }
            };
            if let Some(i) = trigger {
                // Saturating: the encoder writes a trigger of 255 (no chart has an input
                // past it: the validator refuses it) and never a fresh input after it.
                next_input = next_input.max(i.saturating_add(1));
            }
            let guard = if guarded && r.flag() {
                Some(get_expr(&mut r, &mut cursor, &wd))
            } else {
                None
            };
            let tr = Transition {
                from,
                to,
                trigger,
                guard,
            };
            r.push(&mut t.transitions, tr, "transitions");
            prev_to = to;
        }
        if tw.is_none() {
            if let Some(c) = t.charts.get_mut(ci) {
                c.inputs = next_input;
            }
        }
    }
    if r.flag() {
        // One route per chart input, chart by chart.
        for (c, chart) in t.charts.iter().enumerate() {
            let c = r.ok_u8(u8::try_from(c).ok(), PackError::Value("chart"));
            for input in 0..chart.inputs {
                let event = r.event(&mut seen, &wd);
                let route = Route {
                    event,
                    chart: c,
                    input,
                };
                r.push(&mut t.routes, route, "routes");
            }
        }
    } else {
        get_routes(&mut r, &mut t, &mut seen, &wd)?;
    }
    t.start = r.event_opt(&mut seen, &wd);
    t.home = r.event_opt(&mut seen, &wd);
    t.boot = r.event_opt(&mut seen, &wd);
    let peers = r.list(t.peers.capacity());
    let peer_width = r.get(PEER_WIDTH_BITS);
    let mut next = None;
    for _ in 0..peers {
        let p = match next {
            Some(p) if r.flag() => p,
            None if r.flag() => {
                r.fail(PackError::Value("peer"));
                0
            }
            _ => {
                let p = r.get(peer_width);
                u16::try_from(p).unwrap_or_else(|_| {
                    r.fail(PackError::Value("peer"));
                    0
                })
            }
        };
        r.push(&mut t.peers, p, "peers");
        next = p.checked_add(1);
    }
    if !wide {
        wd.peers(t.peers.len());
    }
    let topic_width = if wide { 8 } else { r.get(TOPIC_WIDTH_BITS) };
    let emitted = emitted(&t.actions, &t.routes);
    let mut prev_event = None;
    let mut next_topic = 0u16;
    for _ in 0..r.list(t.publications.capacity()) {
        let event = if r.flag() {
            let e = expected_publication(&emitted, prev_event);
            r.ok_u8(e, PackError::Value("event"))
        } else {
            r.u8(wd.event)
        };
        prev_event = Some(event);
        let topic = if r.flag() {
            r.ok_u8(u8::try_from(next_topic).ok(), PackError::Value("topic"))
        } else {
            r.u8(topic_width)
        };
        next_topic = u16::from(topic) + 1;
        let subscribers = r.u8(wd.peers);
        let p = Publication {
            event,
            topic,
            subscribers,
        };
        r.push(&mut t.publications, p, "publications");
    }
    let mut prev_event: Option<u8> = None;
    for _ in 0..r.list(t.subscriptions.capacity()) {
        let publisher = r.u8(wd.peer);
        let topic = r.u8(topic_width);
        let same = r.flag();
        let event = match prev_event {
            Some(p) if same => p,
            _ if same => r.ok_u8(None, PackError::Value("event")),
            p if r.flag() => {
                let e = next_subscribed(&t, p);
                r.ok_u8(e, PackError::Value("event"))
            }
            _ => r.u8(wd.event),
        };
        prev_event = Some(event);
        let s = Subscription {
            publisher,
            topic,
            event,
        };
        r.push(&mut t.subscriptions, s, "subscriptions");
    }
    if !r.flag() {
        t.safety = get_safety(&mut r, &t, &mut cursor, &wd);
    }
    let used = r.bit.div_ceil(8);
    let pad = (8 - r.bit % 8) % 8;
    if r.get(pad as u32) != 0 {
        r.fail(PackError::Value("padding"));
    }
    match r.err {
        Some(e) => Err(e),
        None => Ok((t, bytes.len().saturating_sub(used))),
    }
}
