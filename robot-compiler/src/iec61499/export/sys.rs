//! The robot as an IEC 61499-2 system (`.sys`), in the element order Eclipse 4diac IDE
//! writes: `VersionInfo`, the `Application` (its `SubAppNetwork`: an FB per chart and a
//! service FB per role, `<ROLE>_IO`, for the node's pins, timers and faults; the event
//! connections), a `Device` per node with a `Resource` per role it plays (the FBs mapped
//! there, the connections inside it, and each connection the mapping cuts as a
//! `PUBLISH_0` on the publishing resource and a `SUBSCRIBE_0` on the subscribing one, the
//! paper's step), then the `Mapping` of every FB.

use super::fbt::identifier;
use super::xml::Writer;
use super::Instance;
use crate::compile::Compiled;
use crate::iec61499::services;

/// One event connection of the application: (source role, `FB.EVENT`) -> (destination
/// role, `FB.EVENT`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Connection {
    pub from_role: usize,
    pub source: String,
    pub to_role: usize,
    pub destination: String,
}

impl Connection {
    /// Whether the mapping cuts it (its ends are on different resources).
    pub fn cut(&self) -> bool {
        self.from_role != self.to_role
    }
}

/// The name of role `ri`'s service FB (and its type).
pub fn io_name(c: &Compiled, ri: usize) -> String {
    format!("{}_IO", identifier(&c.ir.roles[ri].name))
}

/// A role's service FB's event outputs (each with the node event it stands for) and
/// inputs.
pub type IoEvents = (Vec<(String, String)>, Vec<String>);

/// The type of the FBs joining the sources of a chart input fed by several events.
pub const MERGE: &str = "E_MERGE";

/// An `E_MERGE` of the application (its name, its role), joining two sources of one
/// chart input.
pub type Merge = (String, usize);

/// Every connection of the application, the `E_MERGE`s joining the sources of each chart
/// input that several events feed (`merged`), and per role the service FB's event
/// outputs and inputs (in order of first use).
pub fn connections(
    c: &Compiled,
    instances: &[Instance],
) -> (Vec<Connection>, Vec<Merge>, Vec<IoEvents>) {
    let mut io: Vec<IoEvents> = vec![(Vec::new(), Vec::new()); c.ir.roles.len()];
    let mut out = Vec::new();
    let push = |v: &mut Vec<String>, n: &str| {
        if !v.iter().any(|x| x == n) {
            v.push(n.to_string());
        }
    };
    for inst in instances {
        let r = &c.ir.roles[inst.role];
        for (k, input) in inst.inputs.iter().enumerate() {
            // Each source of each event routed to the input: every import the local event
            // stands for (several peers' events may be subscribed as one, a peer's fault
            // from each of them), else the role's own event.
            let sources = r
                .routes
                .iter()
                .filter(|(_, ch, i)| *ch == inst.chart && *i == k)
                .flat_map(|(e, _, _)| {
                    let imported: Vec<(usize, String)> = (r.imports.iter())
                        .filter(|(_, _, local)| local == e)
                        .map(|(role, their, _)| {
                            let from = c.ir.roles.iter().position(|x| &x.name == role);
                            (from.unwrap_or(0), their.clone())
                        })
                        .collect();
                    if imported.is_empty() {
                        vec![(inst.role, e.clone())]
                    } else {
                        imported
                    }
                });
            for (from, event) in sources.collect::<Vec<_>>() {
                let source = instances
                    .iter()
                    .filter(|i| i.role == from)
                    .find_map(|i| {
                        i.emits
                            .iter()
                            .find(|(ev, _)| *ev == event)
                            .map(|(_, o)| format!("{}.{o}", i.name))
                    })
                    .unwrap_or_else(|| {
                        let n = identifier(&event);
                        if !io[from].0.iter().any(|(x, _)| *x == n) {
                            io[from].0.push((n.clone(), event.clone()));
                        }
                        format!("{}.{n}", io_name(c, from))
                    });
                let conn = Connection {
                    from_role: from,
                    source,
                    to_role: inst.role,
                    destination: format!("{}.{input}", inst.name),
                };
                if !out.contains(&conn) {
                    out.push(conn);
                }
            }
        }
        // A lifted chart's timers: each fed from the role's IO block, the output of the
        // role's timer event, so the import gives the charts sharing it one timer.
        for (timer, event) in &inst.timers {
            let destination = format!("{}.{timer}", inst.name);
            if out.iter().any(|x| x.destination == destination) {
                continue;
            }
            let n = identifier(event);
            if !io[inst.role].0.iter().any(|(x, _)| *x == n) {
                io[inst.role].0.push((n.clone(), event.clone()));
            }
            out.push(Connection {
                from_role: inst.role,
                source: format!("{}.{n}", io_name(c, inst.role)),
                to_role: inst.role,
                destination,
            });
        }
        for s in &inst.services {
            let n = format!("{}_{s}", inst.name);
            push(&mut io[inst.role].1, &n);
            out.push(Connection {
                from_role: inst.role,
                source: format!("{}.{s}", inst.name),
                to_role: inst.role,
                destination: format!("{}.{n}", io_name(c, inst.role)),
            });
        }
    }
    let taken: Vec<String> = (instances.iter().map(|i| i.name.clone()))
        .chain((0..c.ir.roles.len()).map(|ri| io_name(c, ri)))
        .collect();
    let (out, merges) = merged(out, taken);
    (out, merges, io)
}

/// The connections with each input that several sources feed fed by a chain of
/// `E_MERGE`s on the input's resource instead, as IEC 61499 has it (an event input has
/// one source): the first joins the first two sources (`EI1`, `EI2`), each next one the
/// chain so far (`EI1`) and the next source (`EI2`), the last's `EO` feeds the input.
/// The import folds the chain back into the input's sources, in this order (the order of
/// the role's routes). `taken`: the FB names already used.
fn merged(conns: Vec<Connection>, mut taken: Vec<String>) -> (Vec<Connection>, Vec<Merge>) {
    let mut out: Vec<Connection> = Vec::new();
    let mut merges = Vec::new();
    for conn in &conns {
        let sources: Vec<&Connection> = (conns.iter())
            .filter(|x| x.destination == conn.destination)
            .collect();
        if sources.len() < 2 {
            out.push(conn.clone());
            continue;
        }
        if !std::ptr::eq(sources[0], conn) {
            continue;
        }
        let role = conn.to_role;
        let mut fed = sources[0].clone();
        for s in &sources[1..] {
            let base = identifier(&format!("{}_MERGE", conn.destination));
            let mut name = base.clone();
            let mut k = 2;
            while taken.iter().any(|n| n.eq_ignore_ascii_case(&name)) {
                name = format!("{base}_{k}");
                k += 1;
            }
            taken.push(name.clone());
            for (input, from) in [("EI1", &fed), ("EI2", *s)] {
                out.push(Connection {
                    destination: format!("{name}.{input}"),
                    to_role: role,
                    ..from.clone()
                });
            }
            fed = Connection {
                from_role: role,
                source: format!("{name}.EO"),
                to_role: role,
                destination: conn.destination.clone(),
            };
            merges.push((name, role));
        }
        out.push(fed);
    }
    (out, merges)
}

/// The service FB types (`<ROLE>_IO.fbt`, an interface only) and the `.sys` text.
pub fn write(c: &Compiled, instances: &[Instance], date: &str) -> (Vec<(String, String)>, String) {
    let (conns, merges, io) = connections(c, instances);
    let mut files = Vec::new();
    for (ri, (outs, ins)) in io.iter().enumerate() {
        files.push((
            format!("{}.fbt", io_name(c, ri)),
            io_type(c, ri, outs, ins, date),
        ));
    }
    let sys = identifier(&c.ir.name);
    let app = format!("{sys}App");
    let mut w = Writer::new("System");
    w.open(
        "System",
        &[("Name", &sys), ("Comment", &format!("robot {}", c.ir.name))],
    );
    version(&mut w, date);
    w.open("Application", &[("Name", &app), ("Comment", "")]);
    w.open("SubAppNetwork", &[]);
    let fbs = fb_list(c, instances, &merges);
    for (i, (name, ty, params, _)) in fbs.iter().enumerate() {
        fb(&mut w, name, ty, params, i);
    }
    event_connections(&mut w, conns.iter());
    w.close();
    w.close();
    // Cut connections: one topic per (publishing role, source pin).
    let topic = |conn: &Connection| format!("{}/{}", c.ir.roles[conn.from_role].name, conn.source);
    let mut topics: Vec<String> = Vec::new();
    for conn in conns.iter().filter(|x| x.cut()) {
        if !topics.contains(&topic(conn)) {
            topics.push(topic(conn));
        }
    }
    let mut mapping = Vec::new();
    for (ni, node) in c.robot.nodes.iter().enumerate() {
        let dev = identifier(&node.name);
        let roles: Vec<usize> = (c.ir.roles.iter().enumerate())
            .filter(|(_, r)| {
                c.robot
                    .assign
                    .iter()
                    .any(|(role, n)| *role == r.name && *n == node.name)
            })
            .map(|(i, _)| i)
            .collect();
        let (x, y) = ((ni * 1500).to_string(), String::from("0"));
        w.open(
            "Device",
            &[
                ("Name", &dev),
                ("Type", ""),
                (
                    "Comment",
                    &format!(
                        "node {}, IEEE 802.15.4 short address {:#06x}",
                        node.name, node.address
                    ),
                ),
                ("x", &x),
                ("y", &y),
            ],
        );
        for ri in roles {
            let res = identifier(&c.ir.roles[ri].name);
            w.open(
                "Resource",
                &[
                    ("Name", &res),
                    ("Type", "EMB_RES"),
                    ("Comment", &format!("role {}", c.ir.roles[ri].name)),
                    ("x", "0"),
                    ("y", "0"),
                ],
            );
            w.open("FBNetwork", &[]);
            let mut local: Vec<Connection> = Vec::new();
            let mut k = 0;
            for (name, ty, params, role) in fbs.iter().filter(|f| f.3 == ri) {
                fb(&mut w, name, ty, params, k);
                k += 1;
                mapping.push((format!("{app}.{name}"), format!("{dev}.{res}.{name}")));
                let _ = role;
            }
            for (ti, t) in topics.iter().enumerate() {
                let id = format!("\"{t}\"");
                let publishes = conns
                    .iter()
                    .any(|x| x.cut() && x.from_role == ri && &topic(x) == t);
                let subscribes: Vec<&Connection> = (conns.iter())
                    .filter(|x| x.cut() && x.to_role == ri && &topic(x) == t)
                    .collect();
                if publishes {
                    let name = format!("PUBLISH_{}", ti + 1);
                    fb(
                        &mut w,
                        &name,
                        "PUBLISH_0",
                        &[
                            (String::from("QI"), String::from("TRUE")),
                            (String::from("ID"), id.clone()),
                        ],
                        k,
                    );
                    k += 1;
                    let source = conns
                        .iter()
                        .find(|x| &topic(x) == t)
                        .map(|x| x.source.clone())
                        .unwrap_or_default();
                    local.push(Connection {
                        from_role: ri,
                        source,
                        to_role: ri,
                        destination: format!("{name}.REQ"),
                    });
                }
                if !subscribes.is_empty() {
                    let name = format!("SUBSCRIBE_{}", ti + 1);
                    fb(
                        &mut w,
                        &name,
                        "SUBSCRIBE_0",
                        &[
                            (String::from("QI"), String::from("TRUE")),
                            (String::from("ID"), id),
                        ],
                        k,
                    );
                    k += 1;
                    for s in subscribes {
                        local.push(Connection {
                            from_role: ri,
                            source: format!("{name}.IND"),
                            to_role: ri,
                            destination: s.destination.clone(),
                        });
                    }
                }
            }
            local.splice(
                0..0,
                conns
                    .iter()
                    .filter(|x| !x.cut() && x.to_role == ri)
                    .cloned(),
            );
            event_connections(&mut w, local.iter());
            w.close();
            w.close();
        }
        w.close();
    }
    for (from, to) in &mapping {
        w.empty("Mapping", &[("From", from), ("To", to)]);
    }
    (files, w.finish())
}

/// The application's FBs: (name, type, parameters, role), charts, the `E_MERGE`s, then
/// service FBs.
#[allow(clippy::type_complexity)]
fn fb_list(
    c: &Compiled,
    instances: &[Instance],
    merges: &[Merge],
) -> Vec<(String, String, Vec<(String, String)>, usize)> {
    let mut out: Vec<_> = instances
        .iter()
        .map(|i| {
            let params = i
                .params
                .iter()
                .map(|(k, v)| (k.clone(), v.to_string()))
                .collect();
            (i.name.clone(), i.ty.clone(), params, i.role)
        })
        .collect();
    for (name, ri) in merges {
        out.push((name.clone(), String::from(MERGE), Vec::new(), *ri));
    }
    for ri in 0..c.ir.roles.len() {
        out.push((io_name(c, ri), io_name(c, ri), Vec::new(), ri));
    }
    out
}

fn version(w: &mut Writer, date: &str) {
    w.empty(
        "VersionInfo",
        &[
            ("Organization", "ecc-nodes"),
            ("Version", "1.0"),
            ("Author", "config-tool export-4diac"),
            ("Date", date),
        ],
    );
}

fn fb(w: &mut Writer, name: &str, ty: &str, params: &[(String, String)], i: usize) {
    let (x, y) = (((i % 4) * 1200).to_string(), ((i / 4) * 800).to_string());
    let attrs = [
        ("Name", name),
        ("Type", ty),
        ("Comment", ""),
        ("x", &x),
        ("y", &y),
    ];
    if params.is_empty() {
        w.empty("FB", &attrs);
        return;
    }
    w.open("FB", &attrs);
    for (k, v) in params {
        w.empty("Parameter", &[("Name", k), ("Value", v)]);
    }
    w.close();
}

fn event_connections<'a>(w: &mut Writer, conns: impl Iterator<Item = &'a Connection>) {
    let mut conns = conns.peekable();
    if conns.peek().is_none() {
        return;
    }
    w.open("EventConnections", &[]);
    for conn in conns {
        w.empty(
            "Connection",
            &[
                ("Source", &conn.source),
                ("Destination", &conn.destination),
                ("Comment", ""),
            ],
        );
    }
    w.close();
}

/// Role `ri`'s service FB type: the node's pins, timers and faults as events, marked
/// [`services::IO_MARK`]; each event output's `Comment` is the node event it stands for
/// (`VC.home`), which the import reads back.
fn io_type(
    c: &Compiled,
    ri: usize,
    outs: &[(String, String)],
    ins: &[String],
    date: &str,
) -> String {
    let name = io_name(c, ri);
    let mut w = Writer::new("FBType");
    w.open(
        "FBType",
        &[
            ("Name", &name),
            ("Comment", &format!("The node services of role {}: its inputs, switches and timers raise the event outputs; the event inputs drive its valves and outputs, start and stop its timers, fault it", c.ir.roles[ri].name)),
        ],
    );
    w.empty(
        "Identification",
        &[
            ("Standard", "61499-2"),
            ("Classification", services::IO_MARK),
        ],
    );
    version(&mut w, date);
    w.open("InterfaceList", &[]);
    let ins: Vec<(String, String)> = ins.iter().map(|n| (n.clone(), String::new())).collect();
    for (list, names) in [("EventInputs", &ins[..]), ("EventOutputs", outs)] {
        if names.is_empty() {
            continue;
        }
        w.open(list, &[]);
        for (n, event) in names {
            // `boot` and `home` are node events unless an input has the name.
            let input = (c.ir.roles[ri].inputs.iter()).any(|i| i.name == *event);
            let comment = match input {
                true => event.clone(),
                false => services::io_comment(event),
            };
            w.empty(
                "Event",
                &[("Name", n), ("Type", "Event"), ("Comment", &comment)],
            );
        }
        w.close();
    }
    w.close();
    w.empty(
        "Service",
        &[
            ("RightInterface", "RESOURCE"),
            ("LeftInterface", &name),
            ("Comment", ""),
        ],
    );
    w.finish()
}
