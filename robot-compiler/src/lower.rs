//! IR -> `config_schema::Table` per role: event ids, pins, timers, charts, routes, and the
//! radio links (robot-wide topic ids, peers, publications, subscriptions). Everything is
//! ordered by declaration, never by hash order, so the same robot gives the same bytes.

use config_schema::limits::*;
use config_schema::{
    Action, Input, Output, Publication, Route, Subscription, Table, Timer, Transition,
};

use crate::ir::{ActionIr, Ir, RoleIr};

/// A capacity of a role's table exceeded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Over {
    pub role: usize,
    /// The limit's name in `config_schema::limits`.
    pub limit: &'static str,
    pub count: usize,
    pub max: usize,
}

impl std::fmt::Display for Over {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} needs {} but {} is {} (over by {})",
            self.limit
                .trim_start_matches("MAX_")
                .to_lowercase()
                .replace('_', " "),
            self.count,
            self.limit,
            self.max,
            self.count - self.max
        )
    }
}

/// A published event: (publishing role, event id), in topic order.
pub fn topics(ir: &Ir) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for (ri, r) in ir.roles.iter().enumerate() {
        for (e, name) in r.events.iter().enumerate() {
            let used = ir.roles.iter().any(|q| {
                q.imports
                    .iter()
                    .any(|(from, ev, _)| *from == r.name && ev == name)
            });
            if used {
                out.push((ri, e));
            }
        }
    }
    out
}

/// The peers of role `ri`: other roles it publishes to or subscribes from, in role order.
pub fn peers(ir: &Ir, ri: usize) -> Vec<usize> {
    let me = &ir.roles[ri];
    (0..ir.roles.len())
        .filter(|&q| {
            let other = &ir.roles[q];
            q != ri
                && (me.imports.iter().any(|(from, _, _)| *from == other.name)
                    || other.imports.iter().any(|(from, _, _)| *from == me.name))
        })
        .collect()
}

/// Every capacity a role's table would exceed.
pub fn capacity(ir: &Ir) -> Vec<Over> {
    let mut out = Vec::new();
    for (ri, r) in ir.roles.iter().enumerate() {
        // The length of every expression: guards and assignments.
        let exprs: Vec<usize> = r
            .charts
            .iter()
            .flat_map(|c| {
                c.transitions
                    .iter()
                    .filter_map(|t| t.guard.as_ref().map(|g| g.1.len()))
                    .chain(c.states.iter().flat_map(|s| {
                        s.actions.iter().filter_map(|a| match a {
                            ActionIr::Set { ops, .. } => Some(ops.len()),
                            _ => None,
                        })
                    }))
            })
            .collect();
        let code: usize = exprs.iter().sum();
        let longest_expr = exprs.iter().copied().max().unwrap_or(0);
        let published = topics(ir).iter().filter(|(q, _)| *q == ri).count();
        let checks: [(&'static str, usize, usize); 15] = [
            ("MAX_EVENTS", r.events.len(), MAX_EVENTS),
            ("MAX_VARS", r.vars.len(), MAX_VARS),
            ("MAX_INPUTS", r.inputs.len(), MAX_INPUTS),
            ("MAX_OUTPUTS", r.outputs.len(), MAX_OUTPUTS),
            ("MAX_TIMERS", r.timers.len(), MAX_TIMERS),
            ("MAX_CHARTS", r.charts.len(), MAX_CHARTS),
            (
                "MAX_STATES",
                r.charts.iter().map(|c| c.states.len()).sum(),
                MAX_STATES,
            ),
            (
                "MAX_TRANSITIONS",
                r.charts.iter().map(|c| c.transitions.len()).sum(),
                MAX_TRANSITIONS,
            ),
            (
                "MAX_CHART_INPUTS",
                r.charts.iter().map(|c| c.inputs.len()).max().unwrap_or(0),
                MAX_CHART_INPUTS,
            ),
            (
                "MAX_ACTIONS",
                r.charts
                    .iter()
                    .flat_map(|c| c.states.iter().map(|s| s.actions.len()))
                    .sum(),
                MAX_ACTIONS,
            ),
            ("MAX_CODE", code, MAX_CODE),
            ("MAX_EXPR_LEN", longest_expr, MAX_EXPR_LEN),
            ("MAX_ROUTES", r.routes.len(), MAX_ROUTES),
            ("MAX_PEERS", peers(ir, ri).len(), MAX_PEERS),
            ("MAX_PUBLICATIONS", published, MAX_PUBLICATIONS),
        ];
        for (limit, count, max) in checks {
            if count > max {
                out.push(Over {
                    role: ri,
                    limit,
                    count,
                    max,
                });
            }
        }
        for (limit, count, max) in [
            ("MAX_SUBSCRIPTIONS", r.imports.len(), MAX_SUBSCRIPTIONS),
            ("MAX_ROLE_NAME", r.name.len(), MAX_ROLE_NAME),
        ] {
            if count > max {
                out.push(Over {
                    role: ri,
                    limit,
                    count,
                    max,
                });
            }
        }
    }
    out
}

/// Why lowering failed (the checks should have caught it first).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LowerError {
    Capacity(Vec<Over>),
    /// A name that does not resolve, or a table that does not validate.
    Internal {
        role: String,
        message: String,
    },
}

impl std::fmt::Display for LowerError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LowerError::Capacity(over) => {
                for o in over {
                    writeln!(f, "{o}")?;
                }
                Ok(())
            }
            LowerError::Internal { role, message } => write!(f, "role {role}: {message}"),
        }
    }
}

/// Lowers every role to its table.
pub fn lower(ir: &Ir) -> Result<Vec<Table>, LowerError> {
    let over = capacity(ir);
    if !over.is_empty() {
        return Err(LowerError::Capacity(over));
    }
    let topics = topics(ir);
    (0..ir.roles.len())
        .map(|ri| {
            lower_role(ir, ri, &topics).map_err(|message| LowerError::Internal {
                role: ir.roles[ri].name.clone(),
                message,
            })
        })
        .collect()
}

fn u8_of(x: usize, what: &str) -> Result<u8, String> {
    u8::try_from(x).map_err(|_| format!("{what} {x} does not fit in a byte"))
}

fn lower_role(ir: &Ir, ri: usize, topics: &[(usize, usize)]) -> Result<Table, String> {
    let r: &RoleIr = &ir.roles[ri];
    let mut t = Table::empty(&r.name);
    t.generation = ir.generation;
    t.header.pan_id = ir.pan_id;
    t.header.channel = ir.channel;
    let ev = |name: &str| -> Result<u8, String> {
        r.event_id(name)
            .ok_or_else(|| format!("unknown event `{name}`"))
            .and_then(|e| u8_of(e, "event"))
    };
    t.events = u8_of(r.events.len(), "events")?;
    t.start = r.start.as_deref().map(ev).transpose()?;
    let full = |e: config_schema::Full| e.to_string();
    for (_, init) in &r.vars {
        t.vars.push(*init).map_err(|_| "vars full")?;
    }
    for i in &r.inputs {
        let var = match &i.var {
            Some(v) => Some(u8_of(
                r.vars
                    .iter()
                    .position(|(n, _)| n == v)
                    .ok_or("unknown var")?,
                "var",
            )?),
            None => None,
        };
        t.inputs
            .push(Input {
                pin: i.pin,
                rise: i.rise.as_deref().map(ev).transpose()?,
                fall: i.fall.as_deref().map(ev).transpose()?,
                var,
            })
            .map_err(|_| "inputs full")?;
    }
    for o in &r.outputs {
        t.outputs
            .push(Output {
                pin: o.pin,
                safe: o.safe,
            })
            .map_err(|_| "outputs full")?;
    }
    for tm in &r.timers {
        t.timers
            .push(Timer {
                event: ev(&tm.event)?,
            })
            .map_err(|_| "timers full")?;
    }
    for c in &r.charts {
        let mut transitions = Vec::new();
        for tr in &c.transitions {
            let guard = match &tr.guard {
                Some((_, ops)) => Some(t.push_expr(ops).map_err(full)?),
                None => None,
            };
            transitions.push(Transition {
                from: u8_of(tr.from, "state")?,
                to: u8_of(tr.to, "state")?,
                trigger: tr.trigger.map(|i| u8_of(i, "input")).transpose()?,
                guard,
            });
        }
        let mut states: Vec<Vec<Action>> = Vec::new();
        for s in &c.states {
            let mut actions = Vec::new();
            for a in &s.actions {
                actions.push(match a {
                    ActionIr::Set { var, ops, .. } => Action::Set {
                        var: u8_of(*var, "var")?,
                        expr: t.push_expr(ops).map_err(full)?,
                    },
                    ActionIr::Drive { mask, value, .. } => Action::Drive {
                        mask: *mask,
                        value: *value,
                    },
                    ActionIr::Emit(e) => Action::Emit(ev(e)?),
                    ActionIr::StartTimer { timer, ms } => Action::StartTimer {
                        timer: u8_of(*timer, "timer")?,
                        ms: *ms,
                    },
                    ActionIr::CancelTimer(timer) => Action::CancelTimer(u8_of(*timer, "timer")?),
                    ActionIr::Fault(code) => Action::Fault(*code),
                });
            }
            states.push(actions);
        }
        let refs: Vec<&[Action]> = states.iter().map(|s| s.as_slice()).collect();
        t.push_chart(
            u8_of(c.initial, "state")?,
            u8_of(c.inputs.len(), "chart inputs")?,
            &refs,
            &transitions,
        )
        .map_err(full)?;
    }
    for (e, chart, input) in &r.routes {
        t.routes
            .push(Route {
                event: ev(e)?,
                chart: u8_of(*chart, "chart")?,
                input: u8_of(*input, "input")?,
            })
            .map_err(|_| "routes full")?;
    }
    let peers = peers(ir, ri);
    for &q in &peers {
        t.peers
            .push(ir.roles[q].address)
            .map_err(|_| "peers full")?;
    }
    for (topic, &(q, e)) in topics.iter().enumerate() {
        if q != ri {
            continue;
        }
        let name = &r.events[e];
        let mut mask = 0u8;
        for (pi, &p) in peers.iter().enumerate() {
            if ir.roles[p]
                .imports
                .iter()
                .any(|(from, x, _)| *from == r.name && x == name)
            {
                mask |= 1 << pi;
            }
        }
        t.publications
            .push(Publication {
                event: u8_of(e, "event")?,
                topic: u8_of(topic, "topic")?,
                subscribers: mask,
            })
            .map_err(|_| "publications full")?;
    }
    for (from, x, local) in &r.imports {
        let q = ir
            .roles
            .iter()
            .position(|q| q.name == *from)
            .ok_or_else(|| format!("unknown role `{from}`"))?;
        let topic = topics
            .iter()
            .position(|&(tq, te)| tq == q && ir.roles[q].events[te] == *x)
            .ok_or_else(|| format!("`{from}/{x}` is not published"))?;
        let publisher = peers.iter().position(|&p| p == q).ok_or("no such peer")?;
        t.subscriptions
            .push(Subscription {
                publisher: u8_of(publisher, "peer")?,
                topic: u8_of(topic, "topic")?,
                event: ev(local)?,
            })
            .map_err(|_| "subscriptions full")?;
    }
    config_schema::validate(&t).map_err(|e| format!("invalid table: {e}"))?;
    Ok(t)
}
