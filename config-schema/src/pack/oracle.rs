//! The field-by-field reader as it was before it kept its first error instead of
//! returning at each field: the oracle the reader is held to (same table or same error
//! for any bytes).

use heapless::{String, Vec};

use super::MAX_TIMER_DURATIONS;
use super::{all_outputs, bits, emitted, expected_publication, next_subscribed};
use super::{ActionCtx, PackError, Seen, Widths, R};
use super::{A_CANCEL, A_DRIVE, A_EMIT, A_FAULT, A_PUBLISH, A_SET, A_START};
use super::{CHANNEL_BITS, PEER_WIDTH_BITS, PIN_WIDTH_BITS, ROLE_LEN_BITS, TOPIC_WIDTH_BITS};
use super::{COUNT_WIDTH_BITS, DECADE_BITS, EXPR_LEN_BITS, OP_BITS};
use crate::alarm::{AlarmDecl, AlarmLevel, Safety};
use crate::guard::{Expr, Op};
use crate::limits::*;
use crate::table::*;

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

    /// A gamma code (at most 32 bits after the leading one).
    fn gamma(&mut self) -> R<u64> {
        let mut tail = 0u32;
        while !self.flag()? {
            tail += 1;
            if tail > 32 {
                return Err(PackError::Value("count"));
            }
        }
        let mut v = 1u64 << tail;
        for i in 0..tail {
            v |= u64::from(self.get(1)?) << i;
        }
        Ok(v - 1)
    }

    fn count(&mut self) -> R<usize> {
        usize::try_from(self.gamma()?).map_err(|_| PackError::Value("count"))
    }

    fn sv(&mut self) -> R<i32> {
        let z = u32::try_from(self.gamma()?).map_err(|_| PackError::Value("constant"))?;
        Ok(((z >> 1) as i32) ^ -((z & 1) as i32))
    }

    /// An optional reference (`0`: none, `n + 1`: `Some(n)`) `width` wide.
    fn opt(&mut self, width: u32) -> R<Option<u8>> {
        let v = self.get(width)?;
        match v.checked_sub(1) {
            None => Ok(None),
            Some(n) => u8::try_from(n)
                .map(Some)
                .map_err(|_| PackError::Value("reference")),
        }
    }
}

fn push<T, const N: usize>(v: &mut Vec<T, N>, x: T, what: &'static str) -> R<()> {
    v.push(x).map_err(|_| PackError::Capacity(what))
}

impl Reader<'_> {
    fn event(&mut self, seen: &mut Seen, wd: &Widths) -> R<u8> {
        let e = if self.flag()? {
            seen.fresh()
        } else {
            self.u8(wd.event)?
        };
        seen.mark(e);
        Ok(e)
    }

    fn event_opt(&mut self, seen: &mut Seen, wd: &Widths) -> R<Option<u8>> {
        let e = if self.flag()? {
            Some(seen.fresh())
        } else if self.flag()? {
            Some(self.u8(wd.event)?)
        } else {
            None
        };
        if let Some(e) = e {
            seen.mark(e);
        }
        Ok(e)
    }
}

fn get_duration(r: &mut Reader) -> R<u32> {
    let k = r.get(DECADE_BITS)?;
    let m = u32::try_from(r.gamma()?).map_err(|_| PackError::Value("duration"))?;
    m.checked_mul(10u32.pow(k))
        .ok_or(PackError::Value("duration"))
}

fn get_expr(r: &mut Reader, cursor: &mut usize, wd: &Widths) -> R<Expr> {
    let start = if r.flag()? {
        u8::try_from(*cursor).map_err(|_| PackError::Value("expression start"))?
    } else {
        r.u8(wd.code)?
    };
    let len = if wd.wide {
        r.u8(8)?
    } else {
        r.u8(EXPR_LEN_BITS)? + 1
    };
    *cursor = usize::from(start) + usize::from(len);
    Ok(Expr { start, len })
}

fn get_level(r: &mut Reader) -> R<Level> {
    match r.get(2)? {
        0 => Ok(Level::Low),
        1 => Ok(Level::High),
        2 => Ok(Level::Hold),
        _ => Err(PackError::Value("level")),
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

fn get_action(r: &mut Reader, cx: &mut ActionCtx) -> R<Action> {
    let wd = cx.wd;
    // Each further bit of a code that starts `1 1`: 0 ends it.
    let mut code = (r.get(2)?, 2);
    while code.0 == (1 << code.1) - 1 && code.1 < 5 {
        code = (code.0 | r.get(1)? << code.1, code.1 + 1);
    }
    Ok(match code {
        A_SET => Action::Set {
            var: r.u8(wd.var)?,
            expr: get_expr(r, &mut cx.cursor, &wd)?,
        },
        A_DRIVE => Action::Drive {
            mask: if r.flag()? {
                all_outputs(&wd)
            } else {
                get_u16(r, wd.outputs)?
            },
            value: get_u16(r, wd.outputs)?,
        },
        A_EMIT => Action::Emit(r.event(&mut cx.seen, &wd)?),
        A_PUBLISH => Action::Publish(r.event(&mut cx.seen, &wd)?),
        A_START => Action::StartTimer {
            timer: r.u8(wd.timer)?,
            ms: {
                let d = r.get(wd.duration)?;
                *usize::try_from(d)
                    .ok()
                    .and_then(|d| cx.durations.get(d))
                    .ok_or(PackError::Value("timer duration"))?
            },
        },
        A_CANCEL => Action::CancelTimer(r.u8(wd.timer)?),
        A_FAULT => Action::Fault(u8::try_from(r.count()?).map_err(|_| PackError::Value("fault"))?),
        _ => return Err(PackError::Value("action")),
    })
}

fn get_u16(r: &mut Reader, width: u32) -> R<u16> {
    u16::try_from(r.get(width)?).map_err(|_| PackError::Value("mask"))
}

fn end8(n: usize, what: &'static str) -> R<u8> {
    u8::try_from(n).map_err(|_| PackError::Capacity(what))
}

/// Routes of any other shape (see `put_routes`).
fn get_routes(r: &mut Reader, t: &mut Table, seen: &mut Seen, wd: &Widths) -> R<()> {
    let mut chart = 0u8;
    let mut next_input = [0u8; 256];
    for _ in 0..r.count()? {
        let event = r.event(seen, wd)?;
        if !r.flag()? {
            chart = r.u8(wd.chart)?;
        }
        let inputs = match t.charts.get(usize::from(chart)) {
            Some(c) => c.inputs,
            None if wd.wide => 0,
            None => return Err(PackError::Value("chart")),
        };
        let next = next_input
            .get_mut(usize::from(chart))
            .ok_or(PackError::Value("chart"))?;
        let input = if r.flag()? {
            *next
        } else {
            r.u8(wd.chart_input(inputs))?
        };
        *next = input.saturating_add(1);
        let route = Route {
            event,
            chart,
            input,
        };
        push(&mut t.routes, route, "routes")?;
    }
    Ok(())
}

/// The safety declarations (when not all default).
fn get_safety(r: &mut Reader, t: &Table, cursor: &mut usize, wd: &Widths) -> R<Safety> {
    let estop = r.opt(wd.input_opt)?;
    let link_fault = r.flag()?;
    let restart = u16::try_from(r.get(wd.restart(t.inputs.len()))?)
        .map_err(|_| PackError::Value("restart"))?;
    let mut alarms = Vec::new();
    for _ in 0..r.count()? {
        let level = match r.get(2)? {
            0 => AlarmLevel::Info,
            1 => AlarmLevel::Warning,
            2 => AlarmLevel::Fault,
            _ => return Err(PackError::Value("alarm level")),
        };
        let when = get_expr(r, cursor, wd)?;
        push(&mut alarms, AlarmDecl { level, when }, "alarms")?;
    }
    Ok(Safety {
        estop,
        link_fault,
        restart,
        alarms,
    })
}

/// Reads a payload written by [`encode`]: the table (generation 0) and the count of bytes
/// left after it (the padding bits of its last byte must be zero).
pub fn decode(bytes: &[u8]) -> R<(Table, usize)> {
    let mut r = Reader { bytes, bit: 0 };
    let wide = r.flag()?;
    let mut t = Table::empty("");
    let mut seen = Seen::default();
    let role_len = r.get(ROLE_LEN_BITS)? as usize;
    if role_len > MAX_ROLE_NAME {
        return Err(PackError::Capacity("role"));
    }
    let mut role = [0u8; MAX_ROLE_NAME];
    for b in role.iter_mut().take(role_len) {
        *b = r.u8(8)?;
    }
    let name =
        core::str::from_utf8(role.get(..role_len).unwrap_or(&[])).map_err(|_| PackError::Utf8)?;
    let mut role_name = String::new();
    role_name
        .push_str(name)
        .map_err(|_| PackError::Capacity("role"))?;
    t.header.role = role_name;
    t.header.pan_id = u16::try_from(r.get(16)?).map_err(|_| PackError::Value("pan"))?;
    t.header.channel = if wide {
        r.u8(8)?
    } else {
        r.u8(CHANNEL_BITS)? + CHANNELS.start()
    };
    t.events = u8::try_from(r.count()?).map_err(|_| PackError::Capacity("events"))?;
    let mut wd = if wide {
        Widths::wide(0)
    } else {
        Widths::new(usize::from(t.events))
    };
    for _ in 0..r.count()? {
        push(&mut t.vars, r.sv()?, "vars")?;
    }
    if !wide {
        wd.vars(t.vars.len());
    }
    let pin_width = if wide { 8 } else { r.get(PIN_WIDTH_BITS)? };
    for _ in 0..r.count()? {
        let input = Input {
            pin: r.u8(pin_width)?,
            rise: r.event_opt(&mut seen, &wd)?,
            fall: r.event_opt(&mut seen, &wd)?,
            var: r.opt(wd.var_opt)?,
        };
        push(&mut t.inputs, input, "inputs")?;
    }
    if !wide {
        wd.inputs(t.inputs.len());
    }
    for _ in 0..r.count()? {
        let pin = r.u8(pin_width)?;
        let (fault, start) = if r.flag()? {
            (Level::Low, Level::Low)
        } else {
            (get_level(&mut r)?, get_level(&mut r)?)
        };
        let output = Output {
            pin,
            fault,
            start,
            home: r.flag()?,
        };
        push(&mut t.outputs, output, "outputs")?;
    }
    if !wide {
        wd.outputs = t.outputs.len() as u32;
    }
    for _ in 0..r.count()? {
        let event = r.event(&mut seen, &wd)?;
        push(&mut t.timers, Timer { event }, "timers")?;
    }
    if !wide {
        wd.timer = bits(t.timers.len());
    }
    let mut durations: Vec<u32, MAX_TIMER_DURATIONS> = Vec::new();
    for _ in 0..r.count()? {
        push(&mut durations, get_duration(&mut r)?, "timer durations")?;
    }
    wd.duration = bits(durations.len());
    for _ in 0..r.count()? {
        let op = get_op(&mut r, &wd)?;
        push(&mut t.code, op, "code")?;
    }
    if !wide {
        wd.code = bits(t.code.len() + 1);
    }
    let (mut s_end, mut t_end) = (0usize, 0usize);
    let mut implicit_inputs = [false; MAX_CHARTS];
    for _ in 0..r.count()? {
        let s_first = s_end;
        if wide {
            s_end = usize::from(r.u8(8)?);
            t_end = usize::from(r.u8(8)?);
        } else {
            s_end = s_end.saturating_add(r.count()?);
            t_end = t_end.saturating_add(r.count()?);
        }
        let sw = wd.state(s_end.saturating_sub(s_first));
        // Implicit inputs: counted as the chart's transitions are read.
        let implicit = r.flag()?;
        if let Some(slot) = implicit_inputs.get_mut(t.charts.len()) {
            *slot = implicit;
        }
        let inputs = if implicit {
            0
        } else {
            u8::try_from(r.count()?).map_err(|_| PackError::Value("chart inputs"))?
        };
        let states = u32::try_from(s_end.saturating_sub(s_first).min(32))
            .map_err(|_| PackError::Value("states"))?;
        let (idle, rests) = if r.flag()? {
            (0, 0)
        } else {
            let idle = r.u8(sw)?;
            if idle == 0 {
                (r.u8(sw)?, r.get(states)?)
            } else {
                (idle, 0)
            }
        };
        let initial = if r.flag()? { idle } else { r.u8(sw)? };
        let chart = Chart {
            states_end: end8(s_end, "states")?,
            transitions_end: end8(t_end, "transitions")?,
            inputs,
            initial,
            idle,
            rests,
        };
        push(&mut t.charts, chart, "charts")?;
    }
    let (states, transitions) = if wide {
        (r.count()?, r.count()?)
    } else {
        (s_end, t_end)
    };
    if states > MAX_STATES {
        return Err(PackError::Capacity("states"));
    }
    if transitions > MAX_TRANSITIONS {
        return Err(PackError::Capacity("transitions"));
    }
    if !wide {
        wd.chart = bits(t.charts.len());
    }
    let actions = if wide {
        let actions = r.count()?;
        for _ in 0..states {
            let actions_end = r.u8(8)?;
            push(&mut t.states, State { actions_end }, "states")?;
        }
        actions
    } else {
        let count_width = r.get(COUNT_WIDTH_BITS)?;
        let mode = if r.flag()? {
            Some(r.get(count_width)? as usize)
        } else {
            None
        };
        let mut actions = 0usize;
        for _ in 0..states {
            actions += match mode {
                Some(m) if r.flag()? => m,
                _ => r.get(count_width)? as usize,
            };
            let actions_end = end8(actions, "actions")?;
            push(&mut t.states, State { actions_end }, "states")?;
        }
        actions
    };
    if actions > MAX_ACTIONS {
        return Err(PackError::Capacity("actions"));
    }
    let mut cx = ActionCtx {
        wd,
        durations: &durations,
        cursor: 0,
        seen,
    };
    for _ in 0..actions {
        let a = get_action(&mut r, &mut cx)?;
        push(&mut t.actions, a, "actions")?;
    }
    let ActionCtx {
        mut cursor,
        mut seen,
        ..
    } = cx;
    // (transitions, state width, trigger width, idle state) of each run.
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
        let guarded = r.flag()?;
        let mut prev_to = idle;
        let mut next_input = 0u8;
        for _ in 0..n {
            let step = r.flag()?;
            let from = if step || r.flag()? {
                prev_to
            } else {
                r.u8(sw)?
            };
            let to = if step || r.flag()? {
                from.checked_add(1).ok_or(PackError::Value("state"))?
            } else {
                r.u8(sw)?
            };
            let trigger = if step || r.flag()? {
                Some(next_input)
            } else {
                match tw {
                    Some(tw) => r.opt(tw)?,
                    // One of the inputs used so far, or none.
                    None => match r.opt(bits(usize::from(next_input) + 1))? {
                        Some(i) if i >= next_input => return Err(PackError::Value("trigger")),
                        other => other,
                    },
                }
            };
            if let Some(i) = trigger {
                next_input = next_input.max(i.saturating_add(1));
            }
            let guard = if guarded && r.flag()? {
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
        if tw.is_none() {
            if let Some(c) = t.charts.get_mut(ci) {
                c.inputs = next_input;
            }
        }
    }
    if r.flag()? {
        // One route per chart input, chart by chart.
        for (c, chart) in t.charts.iter().enumerate() {
            let c = u8::try_from(c).map_err(|_| PackError::Value("chart"))?;
            for input in 0..chart.inputs {
                let event = r.event(&mut seen, &wd)?;
                let route = Route {
                    event,
                    chart: c,
                    input,
                };
                push(&mut t.routes, route, "routes")?;
            }
        }
    } else {
        get_routes(&mut r, &mut t, &mut seen, &wd)?;
    }
    t.start = r.event_opt(&mut seen, &wd)?;
    t.home = r.event_opt(&mut seen, &wd)?;
    t.boot = r.event_opt(&mut seen, &wd)?;
    let peers = r.count()?;
    let peer_width = r.get(PEER_WIDTH_BITS)?;
    let mut next = None;
    for _ in 0..peers {
        let p = match next {
            Some(p) if r.flag()? => p,
            None if r.flag()? => return Err(PackError::Value("peer")),
            _ => u16::try_from(r.get(peer_width)?).map_err(|_| PackError::Value("peer"))?,
        };
        push(&mut t.peers, p, "peers")?;
        next = p.checked_add(1);
    }
    if !wide {
        wd.peers(t.peers.len());
    }
    let topic_width = if wide { 8 } else { r.get(TOPIC_WIDTH_BITS)? };
    let emitted = emitted(&t.actions, &t.routes);
    let mut prev_event = None;
    let mut next_topic = 0u16;
    for _ in 0..r.count()? {
        let event = if r.flag()? {
            expected_publication(&emitted, prev_event).ok_or(PackError::Value("event"))?
        } else {
            r.u8(wd.event)?
        };
        prev_event = Some(event);
        let topic = if r.flag()? {
            u8::try_from(next_topic).map_err(|_| PackError::Value("topic"))?
        } else {
            r.u8(topic_width)?
        };
        next_topic = u16::from(topic) + 1;
        let subscribers = r.u8(wd.peers)?;
        let p = Publication {
            event,
            topic,
            subscribers,
        };
        push(&mut t.publications, p, "publications")?;
    }
    let mut prev_event: Option<u8> = None;
    for _ in 0..r.count()? {
        let publisher = r.u8(wd.peer)?;
        let topic = r.u8(topic_width)?;
        let same = r.flag()?;
        let event = match prev_event {
            Some(p) if same => p,
            _ if same => return Err(PackError::Value("event")),
            p if r.flag()? => next_subscribed(&t, p).ok_or(PackError::Value("event"))?,
            _ => r.u8(wd.event)?,
        };
        prev_event = Some(event);
        let s = Subscription {
            publisher,
            topic,
            event,
        };
        push(&mut t.subscriptions, s, "subscriptions")?;
    }
    if !r.flag()? {
        t.safety = get_safety(&mut r, &t, &mut cursor, &wd)?;
    }
    let used = r.bit.div_ceil(8);
    let pad = (8 - r.bit % 8) % 8;
    if r.get(pad as u32)? != 0 {
        return Err(PackError::Value("padding"));
    }
    Ok((t, bytes.len().saturating_sub(used)))
}

mod tests {
    extern crate std;

    use std::vec::Vec;

    use proptest::prelude::*;

    /// The payloads of every compiled robot's roles (the golden blobs' hex, envelope cut).
    fn payloads() -> Vec<Vec<u8>> {
        let golden = include_str!("../../../tests/fixtures/blobs.golden");
        let mut out = Vec::new();
        for line in golden.lines() {
            let Some(hex) = line.split(' ').nth(3) else {
                continue;
            };
            let bytes: Vec<u8> = (0..hex.len() / 2)
                .map(|i| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).expect("hex"))
                .collect();
            out.push(bytes[8..bytes.len() - 4].to_vec());
        }
        assert!(out.len() > 50, "{} payloads", out.len());
        out
    }

    fn same(payload: &[u8]) -> Result<(), TestCaseError> {
        prop_assert_eq!(super::super::decode(payload), super::decode(payload));
        Ok(())
    }

    #[test]
    fn every_compiled_role_reads_as_before() {
        for p in payloads() {
            assert!(super::super::decode(&p).is_ok());
            same(&p).unwrap();
            // Every truncation.
            for n in 0..p.len() {
                same(&p[..n]).unwrap();
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]

        /// A compiled role with bits flipped, bytes set, cut or inserted: the same table or
        /// the same first error as the reader that returned at each field.
        #[test]
        fn damaged_roles_read_as_before(
            which in any::<usize>(),
            edits in proptest::collection::vec((0u8..4, any::<usize>(), any::<u8>()), 1..5),
        ) {
            let all = payloads();
            let mut p = all[which % all.len()].clone();
            for (kind, at, v) in edits {
                let len = p.len();
                match kind {
                    0 if len > 0 => p[at % len] ^= 1 << (v % 8),
                    1 if len > 0 => p[at % len] = v,
                    2 => p.truncate(at % (len + 1)),
                    _ => p.insert(at % (len + 1), v),
                }
            }
            same(&p)?;
        }

        /// Noise, mostly small bytes (short codes, zero runs).
        #[test]
        fn random_payloads_read_as_before(
            p in proptest::collection::vec(prop_oneof![0u8..4, any::<u8>()], 0..200),
        ) {
            same(&p)?;
        }
    }
}
