//! The last step of elaboration: each role's event ids, routes and imports put in the
//! order the packed table (`config_schema::pack`) reads them, so that most references
//! take one bit. Nothing a node does changes: events keep their names (every name map
//! reads `RoleIr::events`), a route keeps its place among the routes of its event (the
//! order a node delivers an event to its charts), and an import's place among the imports
//! matters to no one.
//!
//! - Routes go chart by chart, each chart's by input: the packed table then says nothing
//!   of a route's chart and input (docs/table-format.md, "routes"). Kept as they are if
//!   that would reorder the routes of one event.
//! - Events are numbered in the order the packed stream first names them: inputs' edges,
//!   timers, the actions' emitted events, routes, START, HOME, boot, imports, the rest. An
//!   event named for the first time is then the lowest not named yet: one bit.
//! - Imports (subscriptions) go by local event, so that each names the event of the
//!   previous one or the next: one or two bits.

use std::collections::{HashMap, HashSet};

use crate::ir::{ActionIr, Ir, RoleIr};

/// Numbers every role's events and orders its routes and imports (see the module docs).
pub fn number(ir: &mut Ir) {
    for r in &mut ir.roles {
        number_role(r);
    }
}

fn number_role(r: &mut RoleIr) {
    order_routes(r);
    number_events(r);
    let ids: HashMap<&str, usize> = r
        .events
        .iter()
        .enumerate()
        .map(|(id, e)| (e.as_str(), id))
        .collect();
    let mut imports = std::mem::take(&mut r.imports);
    imports.sort_by_key(|(_, _, local)| ids.get(local.as_str()).copied().unwrap_or(usize::MAX));
    r.imports = imports;
}

/// Routes chart by chart and input by input, unless that reorders an event's routes.
fn order_routes(r: &mut RoleIr) {
    let mut sorted = r.routes.clone();
    sorted.sort_by_key(|&(_, chart, input)| (chart, input));
    if by_event(&r.routes) == by_event(&sorted) {
        r.routes = sorted;
    }
}

/// Each event's routes (chart, input), in order.
fn by_event(routes: &[(String, usize, usize)]) -> HashMap<&str, Vec<(usize, usize)>> {
    let mut by_event: HashMap<&str, Vec<(usize, usize)>> = HashMap::new();
    for (e, c, i) in routes {
        by_event.entry(e.as_str()).or_default().push((*c, *i));
    }
    by_event
}

/// Event ids in the order the packed stream names them first.
fn number_events(r: &mut RoleIr) {
    let mut order: Vec<String> = Vec::with_capacity(r.events.len());
    let mut named: HashSet<String> = HashSet::with_capacity(r.events.len());
    let mut add = |name: &str| {
        if named.insert(name.to_string()) {
            order.push(name.to_string());
        }
    };
    for i in &r.inputs {
        for e in [&i.rise, &i.fall].into_iter().flatten() {
            add(e);
        }
    }
    for t in &r.timers {
        add(&t.event);
    }
    for c in &r.charts {
        for s in &c.states {
            for a in &s.actions {
                if let ActionIr::Emit(e) = a {
                    add(e);
                }
            }
        }
    }
    for (e, _, _) in &r.routes {
        add(e);
    }
    for e in [&r.start, &r.home, &r.boot].into_iter().flatten() {
        add(e);
    }
    for (_, _, local) in &r.imports {
        add(local);
    }
    for e in &r.events {
        add(e);
    }
    // Only names the role has (every name above is one of its events).
    let events: HashSet<&str> = r.events.iter().map(String::as_str).collect();
    order.retain(|e| events.contains(e.as_str()));
    r.events = order;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ir::{ChartIr, StateIr, TimerIr};

    fn role() -> RoleIr {
        let mut r = RoleIr {
            name: "R".into(),
            ..RoleIr::default()
        };
        for e in ["peer", "tick", "done", "go"] {
            r.event(e);
        }
        r.timers.push(TimerIr {
            name: "t".into(),
            event: "tick".into(),
        });
        r.charts.push(ChartIr {
            name: "c".into(),
            inputs: vec!["a".into(), "b".into()],
            initial: 0,
            idle: 0,
            rests: Vec::new(),
            states: vec![StateIr {
                name: "S0".into(),
                actions: vec![ActionIr::Emit("done".into())],
            }],
            transitions: Vec::new(),
        });
        r.charts.push(ChartIr {
            name: "d".into(),
            ..r.charts[0].clone()
        });
        r.charts[1].states[0].actions.clear();
        r
    }

    #[test]
    fn events_are_numbered_as_the_packed_stream_names_them() {
        let mut r = role();
        r.routes = vec![
            ("go".into(), 1, 0),
            ("peer".into(), 0, 1),
            ("tick".into(), 0, 0),
        ];
        r.imports = vec![("Q".into(), "x".into(), "peer".into())];
        number_role(&mut r);
        assert_eq!(r.events, ["tick", "done", "peer", "go"]);
        assert_eq!(
            r.routes,
            [
                ("tick".to_string(), 0, 0),
                ("peer".to_string(), 0, 1),
                ("go".to_string(), 1, 0)
            ]
        );
    }

    #[test]
    fn routes_keep_their_order_if_sorting_reorders_one_events_charts() {
        let mut r = role();
        let routes = vec![
            ("go".to_string(), 1, 0),
            ("go".to_string(), 0, 0),
            ("peer".to_string(), 0, 1),
        ];
        r.routes = routes.clone();
        number_role(&mut r);
        assert_eq!(r.routes, routes);
        assert_eq!(r.events, ["tick", "done", "go", "peer"]);
    }

    #[test]
    fn imports_go_by_local_event() {
        let mut r = role();
        r.routes = vec![("go".into(), 0, 0), ("peer".into(), 0, 1)];
        r.imports = vec![
            ("Q".into(), "y".into(), "peer".into()),
            ("Q".into(), "x".into(), "go".into()),
            ("P".into(), "y".into(), "peer".into()),
        ];
        number_role(&mut r);
        let locals: Vec<_> = r
            .imports
            .iter()
            .map(|(from, _, local)| format!("{from}:{local}"))
            .collect();
        assert_eq!(locals, ["Q:go", "Q:peer", "P:peer"]);
    }
}
