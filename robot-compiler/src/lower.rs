//! IR -> `config_schema::Table` per role: event ids, pins, timers, charts, routes, and the
//! radio links (topic ids per publisher, peers, publications, subscriptions). Everything is
//! ordered by declaration, never by hash order, so the same robot gives the same bytes.

use std::collections::HashSet;

use config_schema::limits::*;
use config_schema::{
    Action, Input, Output, Publication, Route, Subscription, Table, Timer, Transition,
};

use crate::ir::{ActionIr, ChartIr, Ir, RoleIr};

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

/// A published event: (publishing role, event id, topic), role by role and each role's
/// by event id. Topics are numbered per publisher, from 0 in that order: a subscription
/// names its publisher, so the topic need only tell that publisher's events apart (and is
/// then as narrow as its publisher's count of publications).
pub fn topics(ir: &Ir) -> Vec<(usize, usize, usize)> {
    // (publisher, event) of every import, looked up once per event: linear in the robot.
    let imported: HashSet<(&str, &str)> = (ir.roles.iter())
        .flat_map(|q| q.imports.iter())
        .map(|(from, ev, _)| (from.as_str(), ev.as_str()))
        .collect();
    let mut out = Vec::new();
    for (ri, r) in ir.roles.iter().enumerate() {
        let mut topic = 0;
        for (e, name) in r.events.iter().enumerate() {
            if imported.contains(&(r.name.as_str(), name.as_str())) {
                out.push((ri, e, topic));
                topic += 1;
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
    let mut published = vec![0usize; ir.roles.len()];
    for (ri, _, _) in topics(ir) {
        if let Some(n) = published.get_mut(ri) {
            *n += 1;
        }
    }
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
        let published = published.get(ri).copied().unwrap_or(0);
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
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LowerError {
    /// Every capacity exceeded, one line each.
    #[error("{}", lines(.0))]
    Capacity(Vec<Over>),
    /// A name that does not resolve, or a table that does not validate.
    #[error("role {role}: {error}")]
    Internal { role: String, error: RoleError },
}

fn lines(over: &[Over]) -> String {
    over.iter().map(|o| format!("{o}\n")).collect()
}

/// Why one role's IR does not make a table.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RoleError {
    #[error("unknown event `{0}`")]
    UnknownEvent(String),
    #[error("unknown var")]
    UnknownVar,
    #[error("unknown role `{0}`")]
    UnknownRole(String),
    #[error("`{from}/{event}` is not published")]
    NotPublished { from: String, event: String },
    #[error("no such peer")]
    NoSuchPeer,
    /// An index or count that does not fit the table's byte.
    #[error("{what} {value} does not fit in a byte")]
    TooWide { what: &'static str, value: usize },
    /// A pool of the table (`vars`, `inputs`, ...) is full.
    #[error("{0} full")]
    PoolFull(&'static str),
    #[error(transparent)]
    Table(#[from] config_schema::Full),
    #[error("invalid table: {0}")]
    Invalid(config_schema::Invalid),
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
            let role = Lowering {
                ir,
                ri,
                r: &ir.roles[ri],
                topics: &topics,
            };
            role.lower().map_err(|error| LowerError::Internal {
                role: ir.roles[ri].name.clone(),
                error,
            })
        })
        .collect()
}

fn u8_of(x: usize, what: &'static str) -> Result<u8, RoleError> {
    u8::try_from(x).map_err(|_| RoleError::TooWide { what, value: x })
}

/// A chart's resting states as the table's mask (`config_schema::Chart::rests`): one bit
/// a state, for the first 32.
fn rest_mask(rests: &[usize]) -> Result<u32, RoleError> {
    let mut mask = 0u32;
    for &state in rests {
        let bit = u32::try_from(state).ok().filter(|b| *b < 32);
        let bit = bit.ok_or(RoleError::TooWide {
            what: "resting state",
            value: state,
        })?;
        mask |= 1 << bit;
    }
    Ok(mask)
}

/// One role being lowered: the robot's IR, the role's index and IR, and the robot's
/// topics.
struct Lowering<'a> {
    ir: &'a Ir,
    ri: usize,
    r: &'a RoleIr,
    topics: &'a [(usize, usize, usize)],
}

impl Lowering<'_> {
    /// The role's table: header, hardware, charts, routes, radio links; validated.
    fn lower(&self) -> Result<Table, RoleError> {
        let (ir, r) = (self.ir, self.r);
        let mut t = Table::empty(&r.name);
        t.generation = ir.generation;
        t.header.pan_id = ir.pan_id;
        t.header.channel = ir.channel;
        t.events = u8_of(r.events.len(), "events")?;
        t.start = r.start.as_deref().map(|e| self.ev(e)).transpose()?;
        t.home = r.home.as_deref().map(|e| self.ev(e)).transpose()?;
        t.boot = r.boot.as_deref().map(|e| self.ev(e)).transpose()?;
        self.hardware(&mut t)?;
        for c in &r.charts {
            self.chart(&mut t, c)?;
        }
        for (e, chart, input) in &r.routes {
            t.routes
                .push(Route {
                    event: self.ev(e)?,
                    chart: u8_of(*chart, "chart")?,
                    input: u8_of(*input, "input")?,
                })
                .map_err(|_| RoleError::PoolFull("routes"))?;
        }
        self.links(&mut t)?;
        self.safety(&mut t)?;
        config_schema::validate(&t).map_err(RoleError::Invalid)?;
        Ok(t)
    }

    /// The id of a node event.
    fn ev(&self, name: &str) -> Result<u8, RoleError> {
        self.r
            .event_id(name)
            .ok_or_else(|| RoleError::UnknownEvent(name.to_string()))
            .and_then(|e| u8_of(e, "event"))
    }

    /// The e-stop, restart inputs, link alarm policy and declared alarms.
    fn safety(&self, t: &mut Table) -> Result<(), RoleError> {
        let s = &self.r.safety;
        let input = |name: &str| {
            let i = self.r.inputs.iter().position(|i| i.name == name);
            i.ok_or_else(|| RoleError::UnknownEvent(name.to_string()))
                .and_then(|i| u8_of(i, "input"))
        };
        t.safety.estop = s.estop.as_deref().map(input).transpose()?;
        t.safety.link_fault = s.link_fault;
        for name in &s.restart {
            let i = input(name)?;
            t.safety.restart |= 1u16.checked_shl(u32::from(i)).unwrap_or(0);
        }
        for (_, level, _, ops) in &s.alarms {
            let when = t.push_expr(ops)?;
            let decl = config_schema::alarm::AlarmDecl {
                level: *level,
                when,
            };
            t.safety
                .alarms
                .push(decl)
                .map_err(|_| RoleError::PoolFull("alarms"))?;
        }
        Ok(())
    }

    /// Variables, inputs, outputs and timers.
    fn hardware(&self, t: &mut Table) -> Result<(), RoleError> {
        let r = self.r;
        for (_, init) in &r.vars {
            t.vars
                .push(*init)
                .map_err(|_| RoleError::PoolFull("vars"))?;
        }
        for i in &r.inputs {
            let var = match &i.var {
                Some(v) => Some(u8_of(
                    r.vars
                        .iter()
                        .position(|(n, _)| n == v)
                        .ok_or(RoleError::UnknownVar)?,
                    "var",
                )?),
                None => None,
            };
            t.inputs
                .push(Input {
                    pin: i.pin,
                    rise: i.rise.as_deref().map(|e| self.ev(e)).transpose()?,
                    fall: i.fall.as_deref().map(|e| self.ev(e)).transpose()?,
                    var,
                })
                .map_err(|_| RoleError::PoolFull("inputs"))?;
        }
        for o in &r.outputs {
            t.outputs
                .push(Output {
                    pin: o.pin,
                    fault: o.fault,
                    start: o.start,
                    home: o.home,
                })
                .map_err(|_| RoleError::PoolFull("outputs"))?;
        }
        for tm in &r.timers {
            t.timers
                .push(Timer {
                    event: self.ev(&tm.event)?,
                })
                .map_err(|_| RoleError::PoolFull("timers"))?;
        }
        Ok(())
    }

    /// One chart: its transitions' guards, then its states' actions, into the table.
    fn chart(&self, t: &mut Table, c: &ChartIr) -> Result<(), RoleError> {
        let mut transitions = Vec::new();
        for tr in &c.transitions {
            let guard = match &tr.guard {
                Some((_, ops)) => Some(t.push_expr(ops)?),
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
                actions.push(self.action(t, a)?);
            }
            states.push(actions);
        }
        let refs: Vec<&[Action]> = states.iter().map(|s| s.as_slice()).collect();
        let index = t.push_chart(
            u8_of(c.initial, "state")?,
            u8_of(c.inputs.len(), "chart inputs")?,
            &refs,
            &transitions,
        )?;
        if let Some(chart) = t.charts.get_mut(usize::from(index)) {
            chart.idle = u8_of(c.idle, "state")?;
            chart.rests = rest_mask(&c.rests)?;
        }
        Ok(())
    }

    /// One action (an assignment's expression goes into the table's code).
    fn action(&self, t: &mut Table, a: &ActionIr) -> Result<Action, RoleError> {
        Ok(match a {
            ActionIr::Set { var, ops, .. } => Action::Set {
                var: u8_of(*var, "var")?,
                expr: t.push_expr(ops)?,
            },
            ActionIr::Drive { mask, value, .. } => Action::Drive {
                mask: *mask,
                value: *value,
            },
            ActionIr::Emit(e) => Action::Emit(self.ev(e)?),
            ActionIr::StartTimer { timer, ms } => Action::StartTimer {
                timer: u8_of(*timer, "timer")?,
                ms: *ms,
            },
            ActionIr::CancelTimer(timer) => Action::CancelTimer(u8_of(*timer, "timer")?),
            ActionIr::Fault(code) => Action::Fault(*code),
        })
    }

    /// The radio links: peers, publications (with their subscribers), subscriptions.
    fn links(&self, t: &mut Table) -> Result<(), RoleError> {
        let (ir, ri, r) = (self.ir, self.ri, self.r);
        let peers = peers(ir, ri);
        for &q in &peers {
            t.peers
                .push(ir.roles[q].address)
                .map_err(|_| RoleError::PoolFull("peers"))?;
        }
        for &(q, e, topic) in self.topics {
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
                .map_err(|_| RoleError::PoolFull("publications"))?;
        }
        for (from, x, local) in &r.imports {
            let q = ir
                .roles
                .iter()
                .position(|q| q.name == *from)
                .ok_or_else(|| RoleError::UnknownRole(from.clone()))?;
            let topic = self
                .topics
                .iter()
                .find(|&&(tq, te, _)| tq == q && ir.roles[q].events[te] == *x)
                .map(|&(_, _, topic)| topic)
                .ok_or_else(|| RoleError::NotPublished {
                    from: from.clone(),
                    event: x.clone(),
                })?;
            let publisher = peers
                .iter()
                .position(|&p| p == q)
                .ok_or(RoleError::NoSuchPeer)?;
            t.subscriptions
                .push(Subscription {
                    publisher: u8_of(publisher, "peer")?,
                    topic: u8_of(topic, "topic")?,
                    event: self.ev(local)?,
                })
                .map_err(|_| RoleError::PoolFull("subscriptions"))?;
        }
        Ok(())
    }
}
