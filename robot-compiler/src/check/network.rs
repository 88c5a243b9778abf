//! The network (channel, PAN id, security), nodes and role assignment: addresses used
//! twice, unknown roles and nodes, a role played by no node or by two, a node playing two
//! roles; a robot that turns frame security off (a warning).

use std::collections::{BTreeMap, BTreeSet};

use config_schema::limits::{CHANNELS, MAX_ROLES};

use super::duplicate;
use crate::diag::Diagnostic;
use crate::model::{Robot, Security};
use crate::source::Source;

pub fn check(robot: &Robot, src: &Source, out: &mut Vec<Diagnostic>) {
    if robot.security == Security::Off {
        out.push(
            Diagnostic::warning(
                src.span("security"),
                "frame security is off: anyone in radio range can push a table to these \
                 nodes, press START or forge their events",
            )
            .label("unsecured")
            .help(
                "remove `security: Off` to secure every frame (push then needs the machine \
                 secret: --keys)",
            ),
        );
    }
    // A trial window of nothing rolls back at once.
    for (key, value, unit, what) in [
        ("trial_seconds", robot.trial_seconds, "seconds", "time"),
        ("trial_cycles", robot.trial_cycles, "cycles", "cycles"),
    ] {
        if value == Some(0) {
            out.push(
                Diagnostic::error(
                    src.span(key),
                    format!(
                        "a trial of 0 {unit} rolls back at once: give it the {what} the operator \
                         needs to see the new sequence run"
                    ),
                )
                .label("zero"),
            );
        }
    }
    if !CHANNELS.contains(&robot.network.channel) {
        out.push(
            Diagnostic::error(
                src.span("network.channel"),
                format!(
                    "channel {} is not an IEEE 802.15.4 2.4 GHz channel",
                    robot.network.channel
                ),
            )
            .label(format!("{}..={}", CHANNELS.start(), CHANNELS.end())),
        );
    }
    if robot.network.pan_id == 0xFFFF {
        out.push(Diagnostic::error(
            src.span("network.pan_id"),
            "PAN id 0xffff is the broadcast PAN id",
        ));
    }
    if robot.roles.len() > MAX_ROLES {
        out.push(
            Diagnostic::error(
                src.span(&format!("roles[{MAX_ROLES}]")),
                format!(
                    "{} roles: a robot has at most {MAX_ROLES} (MAX_ROLES), the nodes one \
                     switch-over moves together",
                    robot.roles.len()
                ),
            )
            .label("one role too many"),
        );
    }
    let mut addrs: BTreeMap<u16, usize> = BTreeMap::new();
    for (i, n) in robot.nodes.iter().enumerate() {
        let here = src.span(&format!("nodes[{i}].address"));
        if n.address == 0xFFFF || n.address == 0xFFFE {
            out.push(Diagnostic::error(
                here.clone(),
                format!("address {:#06x} is reserved by IEEE 802.15.4", n.address),
            ));
        }
        if n.address == config_schema::wire::TOOL_ADDR {
            out.push(Diagnostic::error(
                here.clone(),
                format!(
                    "address {:#06x} is config-tool's own on the radio: the tool's frames and \
                     the answers to them would reach this node too",
                    n.address
                ),
            ));
        }
        match addrs.get(&n.address) {
            Some(&first) => {
                let (line, col) = src.line_col(src.span(&format!("nodes[{first}].address")).start);
                out.push(
                    Diagnostic::error(
                        here,
                        format!(
                            "address {:#06x} is used by nodes `{}` and `{}`",
                            n.address, robot.nodes[first].name, n.name
                        ),
                    )
                    .label(format!("first used at {line}:{col}")),
                );
            }
            None => {
                addrs.insert(n.address, i);
            }
        }
    }
    let mut roles: BTreeMap<&str, usize> = BTreeMap::new();
    let mut nodes: BTreeMap<&str, usize> = BTreeMap::new();
    let role_names: BTreeSet<&str> = robot.roles.iter().map(|r| r.name.as_str()).collect();
    let node_names: BTreeSet<&str> = robot.nodes.iter().map(|n| n.name.as_str()).collect();
    for (k, (role, node)) in robot.assign.iter().enumerate() {
        if !role_names.contains(role.as_str()) {
            out.push(
                Diagnostic::error(
                    src.span(&format!("assign[{k}][0]")),
                    format!("unknown role `{role}`"),
                )
                .help(format!(
                    "roles: {}",
                    robot
                        .roles
                        .iter()
                        .map(|r| r.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )),
            );
        } else if let Some(&first) = roles.get(role.as_str()) {
            out.push(
                duplicate(
                    src,
                    "assignment of role",
                    role,
                    &format!("assign[{first}][0]"),
                    &format!("assign[{k}][0]"),
                )
                .help("a role runs on exactly one node: remove one of the two lines"),
            );
        } else {
            roles.insert(role, k);
        }
        if !node_names.contains(node.as_str()) {
            out.push(
                Diagnostic::error(
                    src.span(&format!("assign[{k}][1]")),
                    format!("unknown node `{node}`"),
                )
                .help(format!(
                    "nodes: {}",
                    robot
                        .nodes
                        .iter()
                        .map(|n| n.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )),
            );
        } else if let Some(&first) = nodes.get(node.as_str()) {
            out.push(
                duplicate(
                    src,
                    "use of node",
                    node,
                    &format!("assign[{first}][1]"),
                    &format!("assign[{k}][1]"),
                )
                .help("a node plays one role: give the other role its own node"),
            );
        } else {
            nodes.insert(node, k);
        }
    }
    for (i, r) in robot.roles.iter().enumerate() {
        if !roles.contains_key(r.name.as_str()) {
            out.push(
                Diagnostic::error(
                    src.span(&format!("roles[{i}].name")),
                    format!("role `{}` is assigned to no node", r.name),
                )
                .help(format!("add `(\"{}\", \"NODE\")` to `assign`", r.name)),
            );
        }
    }
}
