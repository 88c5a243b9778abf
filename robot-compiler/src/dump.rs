//! `dump`: a blob decoded as a node would (envelope, CRC, postcard, validation), printed
//! for people. Names are gone in a blob: events are `e3`, variables `v1`, inputs `in2`.

use std::fmt::Write;

use config_schema::blob::envelope;
use config_schema::{decode, Action, DecodeError, Level, Op, Table};

/// Bytecode back to infix text (`v0 < 3 && in1`).
pub fn expr_text(ops: &[Op]) -> String {
    let mut stack: Vec<(String, u8)> = Vec::new(); // (text, precedence)
    for op in ops {
        let (sym, prec) = match op {
            Op::Const(c) => {
                stack.push((c.to_string(), 9));
                continue;
            }
            Op::Var(v) => {
                stack.push((format!("v{v}"), 9));
                continue;
            }
            Op::Input(i) => {
                stack.push((format!("in{i}"), 9));
                continue;
            }
            Op::Not => {
                let (a, p) = stack.pop().unwrap_or_default();
                stack.push((
                    if p < 8 {
                        format!("!({a})")
                    } else {
                        format!("!{a}")
                    },
                    8,
                ));
                continue;
            }
            Op::Or => ("||", 1),
            Op::And => ("&&", 2),
            Op::Eq => ("==", 3),
            Op::Ne => ("!=", 3),
            Op::Lt => ("<", 3),
            Op::Le => ("<=", 3),
            Op::Gt => (">", 3),
            Op::Ge => (">=", 3),
            Op::Add => ("+", 4),
            Op::Sub => ("-", 4),
            Op::Mul => ("*", 5),
            Op::Div => ("/", 5),
            Op::Rem => ("%", 5),
            Op::Wrap { bits, signed } => {
                let (a, _) = stack.pop().unwrap_or_default();
                let name = crate::expr::wrap_name(*bits, *signed);
                stack.push((format!("{name}({a})"), 9));
                continue;
            }
        };
        let (b, pb) = stack.pop().unwrap_or_default();
        let (a, pa) = stack.pop().unwrap_or_default();
        let a = if pa < prec { format!("({a})") } else { a };
        let b = if pb <= prec { format!("({b})") } else { b };
        stack.push((format!("{a} {sym} {b}"), prec));
    }
    stack.pop().map(|s| s.0).unwrap_or_default()
}

/// `0`, `1` or `hold`.
pub fn level_text(l: Level) -> &'static str {
    match l {
        Level::Low => "0",
        Level::High => "1",
        Level::Hold => "hold",
    }
}

fn ev(e: Option<u8>) -> String {
    e.map_or_else(|| String::from("-"), |e| format!("e{e}"))
}

/// The readable form of a decoded table.
pub fn table_text(t: &Table) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "role {}  generation {}  pan {:#06x}  channel {}",
        t.header.role, t.generation, t.header.pan_id, t.header.channel
    );
    let _ = writeln!(
        o,
        "events {}  start {}  home {}  boot {}",
        t.events,
        ev(t.start),
        ev(t.home),
        ev(t.boot)
    );
    for (i, v) in t.vars.iter().enumerate() {
        let _ = writeln!(o, "var v{i} = {v}");
    }
    for (i, x) in t.inputs.iter().enumerate() {
        let var = x.var.map_or_else(|| String::from("-"), |v| format!("v{v}"));
        let _ = writeln!(
            o,
            "input in{i}: pin {}  rise {}  fall {}  mirror {var}",
            x.pin,
            ev(x.rise),
            ev(x.fall)
        );
    }
    for (i, x) in t.outputs.iter().enumerate() {
        let _ = writeln!(
            o,
            "output out{i}: pin {}  fault {}  start {}  home {}",
            x.pin,
            level_text(x.fault),
            level_text(x.start),
            u8::from(x.home)
        );
    }
    for (i, x) in t.timers.iter().enumerate() {
        let _ = writeln!(o, "timer t{i}: expiry e{}", x.event);
    }
    for c in 0..t.charts.len() {
        let chart = t.charts[c];
        let _ = write!(
            o,
            "chart {c}: {} inputs, initial S{}, idle S{}",
            chart.inputs, chart.initial, chart.idle
        );
        let rests: Vec<String> = (0..32u8)
            .filter(|&k| chart.rests & (1 << k) != 0)
            .map(|k| format!("S{k}"))
            .collect();
        if !rests.is_empty() {
            let _ = write!(o, ", also rests in {}", rests.join(" "));
        }
        let _ = writeln!(o);
        let states = t.chart_states(c);
        for (local, s) in states.clone().enumerate() {
            let actions: Vec<String> = t.actions[t.state_actions(s)]
                .iter()
                .map(|a| action_text(t, a))
                .collect();
            let _ = writeln!(o, "  S{local}: {}", actions.join("; "));
        }
        for ti in t.chart_transitions(c) {
            let tr = t.transitions[ti];
            let on = tr
                .trigger
                .map_or_else(|| String::from("(no event)"), |i| format!("in{i}"));
            let guard = tr
                .guard
                .map_or_else(String::new, |g| format!(" [{}]", expr_text(t.expr(g))));
            let _ = writeln!(o, "  T{ti}: S{} --{on}{guard}--> S{}", tr.from, tr.to);
        }
    }
    for r in &t.routes {
        let _ = writeln!(o, "route e{} -> chart {} in{}", r.event, r.chart, r.input);
    }
    for (i, p) in t.peers.iter().enumerate() {
        let _ = writeln!(o, "peer p{i}: {p:#06x}");
    }
    for p in &t.publications {
        let _ = writeln!(
            o,
            "publish e{} as topic {} to peers {:#010b}",
            p.event, p.topic, p.subscribers
        );
    }
    for s in &t.subscriptions {
        let _ = writeln!(
            o,
            "subscribe p{} topic {} -> e{}",
            s.publisher, s.topic, s.event
        );
    }
    let safety = &t.safety;
    let restart: Vec<String> = (0..16u8)
        .filter(|&i| safety.restart & (1 << i) != 0)
        .map(|i| format!("in{i}"))
        .collect();
    let _ = writeln!(
        o,
        "safety: estop {}  on link alarm {}  restart {}",
        safety
            .estop
            .map_or_else(|| String::from("-"), |i| format!("in{i}")),
        if safety.link_fault { "fault" } else { "stall" },
        if restart.is_empty() {
            String::from("-")
        } else {
            restart.join(" ")
        }
    );
    for (i, a) in safety.alarms.iter().enumerate() {
        let _ = writeln!(
            o,
            "alarm a{i}: {:?} when {}",
            a.level,
            expr_text(t.expr(a.when))
        );
    }
    o
}

fn action_text(t: &Table, a: &Action) -> String {
    match *a {
        Action::Set { var, expr } => format!("v{var} := {}", expr_text(t.expr(expr))),
        Action::Drive { mask, value } => {
            let bits: Vec<String> = (0..16)
                .filter(|i| mask & (1 << i) != 0)
                .map(|i| format!("out{i}={}", u8::from(value & (1 << i) != 0)))
                .collect();
            format!("drive {}", bits.join(","))
        }
        Action::Emit(e) => format!("emit e{e}"),
        Action::Publish(e) => format!("publish e{e}"),
        Action::StartTimer { timer, ms } => format!("start t{timer} {ms} ms"),
        Action::CancelTimer(timer) => format!("cancel t{timer}"),
        Action::Fault(code) => format!("fault {code}"),
    }
}

/// Decodes a blob and returns its readable form, or the decode error.
pub fn dump(bytes: &[u8]) -> Result<String, DecodeError> {
    let env = envelope(bytes)?;
    let table = decode(bytes)?;
    let mut o = format!(
        "blob: {} bytes (payload {}), schema {}, generation {}, CRC-32 {:#010x}\n",
        bytes.len(),
        env.payload_len,
        env.version,
        env.generation,
        env.crc
    );
    o.push_str(&table_text(&table));
    Ok(o)
}
