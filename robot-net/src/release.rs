//! Releasing the nodes a robot declares but gives no role (a spare, or the node a role
//! moved away from) that still run a table: nothing in the robot's other tables talks to
//! such a node, but its own charts, buttons and valves go on. Released, it runs a table with
//! no role and nothing in it at the machine's generation, switched at once; activation
//! drives its old outputs low (docs/reconfiguration.md, "Nodes that play no role").

use std::io;
use std::time::Duration;

use config_schema::wire::msg::Status;
use robot_compiler::compile::{Compiled, EncodeError};

use crate::push::{self, Ids, Target};
use crate::radio::ToolRadio;

/// How long a node that plays no role is asked for its status (a spare may be off).
pub const ASK_QUIET: Duration = Duration::from_secs(1);

/// How long the release's transfer and switch are given per node.
const RELEASE_WITHIN: Duration = Duration::from_secs(5);

/// What to do with the nodes that play no role and run a table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Release {
    /// Release them (`force`: over a generation not older, as `push --force`).
    Now { force: bool },
    /// Only name them: the robot is on trial (a rollback must find them as they were),
    /// `confirm` releases them.
    AfterTrial,
}

/// The nodes robot `c` declares with no role that run a table, released at `generation`
/// (or named, as `how` says): a line for each, in words. A node that runs no table has
/// nothing to say; one that does not answer within [`ASK_QUIET`] is named, with the way
/// to release it, when `name_silent` (a role moved in this push: the node it moved away
/// from may be off, and runs that role again when it is on) and it would have been
/// released.
pub fn roleless(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &Compiled,
    generation: u32,
    how: Release,
    name_silent: bool,
) -> io::Result<Vec<String>> {
    let roleless: Vec<_> = (c.robot.nodes.iter())
        .filter(|n| plays_no_role(c, n.address))
        .collect();
    if roleless.is_empty() {
        return Ok(Vec::new());
    }
    let addrs: Vec<u16> = roleless.iter().map(|n| n.address).collect();
    let answers = push::statuses_of(radio, ids, &addrs, ASK_QUIET)?;
    let silent: Vec<String> = (roleless.iter().zip(&answers))
        .filter(|(_, a)| name_silent && a.is_err())
        .map(|(n, _)| silent_text(&n.name, n.address))
        .collect();
    let running: Vec<(&robot_compiler::model::Node, Status)> = (roleless.into_iter().zip(answers))
        .filter_map(|(n, a)| Some((n, a.ok().filter(|s| !s.role.is_empty())?)))
        .collect();
    let force = match how {
        Release::Now { force } => force,
        Release::AfterTrial => {
            return Ok((running.iter())
                .map(|(n, s)| release_later_text(&n.name, n.address, s))
                .collect())
        }
    };
    if running.is_empty() {
        return Ok(silent);
    }
    let blob = release_blob(c, generation).map_err(|e| io::Error::other(e.to_string()))?;
    let targets: Vec<Target> = (running.iter())
        .map(|(n, _)| Target {
            role: n.name.clone(),
            addr: n.address,
            blob: blob.clone(),
            generation,
        })
        .collect();
    let mut outcomes = push::push(radio, &targets, force, &mut |_, _, _| {})?;
    let staged: Vec<usize> = (0..outcomes.len())
        .filter(|&i| outcomes[i].progress == node_fw::ota::Progress::Done)
        .collect();
    let mut go: Vec<push::Pushed> = staged.iter().map(|&i| outcomes[i].clone()).collect();
    if !go.is_empty() {
        push::switch_over(radio, &mut go, generation, true, RELEASE_WITHIN)?;
        for (&i, o) in staged.iter().zip(go) {
            outcomes[i] = o;
        }
    }
    Ok((running.iter().zip(&outcomes))
        .map(|((n, s), o)| {
            let released = o.switched().then_some(()).ok_or_else(|| o.verdict());
            released_text(&n.name, n.address, s, released)
        })
        .chain(silent)
        .collect())
}

/// Whether robot `c` declares node `addr` and gives it no role.
pub fn plays_no_role(c: &Compiled, addr: u16) -> bool {
    c.robot.nodes.iter().any(|n| n.address == addr) && c.ir.roles.iter().all(|r| r.address != addr)
}

/// A node of the robot that plays no role in it (`name` at `addr`) and did not answer,
/// in words: what it may run, and how to release it.
pub fn silent_text(name: &str, addr: u16) -> String {
    format!(
        "node {addr:#06x} ({name}) plays no role in this robot and did not answer: if it is \
         off and runs a table (a role moved away from it), it runs that table again when it \
         is on: push again then to release it"
    )
}

/// A node of the robot that plays no role in it and runs role `role` of `generation`, as
/// `scan` and `status` say it.
pub fn stale_text(role: &str, generation: u32) -> String {
    format!(
        "plays no role in this robot but runs {role} of generation {generation}: push again \
         to release it"
    )
}

/// The blob that releases a node from robot `c` (it plays no role in it): a table with
/// no role and nothing in it (no events, charts, inputs or outputs; activated, the old
/// table's outputs go off), on the robot's PAN and channel, at `generation`.
pub fn release_blob(c: &Compiled, generation: u32) -> Result<Vec<u8>, EncodeError> {
    let mut t = config_schema::Table::empty("");
    t.generation = generation;
    t.header.pan_id = c.ir.pan_id;
    t.header.channel = c.ir.channel;
    robot_compiler::compile::encode(&t)
}

/// A node of the robot that plays no role in it (`name` at `addr`), that ran a table as
/// its status `s` says, and its release (`Err`: how it ended instead, as a push line says),
/// in words.
pub fn released_text(name: &str, addr: u16, s: &Status, released: Result<(), String>) -> String {
    let ran = format!("{} of generation {}", s.role, s.generation);
    match released {
        Ok(()) => format!(
            "node {addr:#06x} ({name}) plays no role in this robot: released (it ran {ran}; \
             now no table runs there, its outputs are off)"
        ),
        Err(why) => format!(
            "node {addr:#06x} ({name}) plays no role in this robot but runs {ran}, NOT \
             released ({why}): it keeps running that table until released by a push, given \
             a role, or powered off"
        ),
    }
}

/// A node of the robot that plays no role in it (`name` at `addr`) and runs a table, as
/// its status `s` says, while the robot is on trial: released once it is confirmed.
pub fn release_later_text(name: &str, addr: u16, s: &Status) -> String {
    format!(
        "node {addr:#06x} ({name}) plays no role in this robot but runs {} of generation {}: \
         released when the trial is confirmed (config-tool confirm)",
        s.role, s.generation
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(role: &str) -> Status {
        crate::home::tests::status(role, &[], None)
    }

    /// A released node says what it ran; one that was not, why, and what it keeps doing.
    #[test]
    fn a_roleless_nodes_release_says_what_it_ran() {
        let s = status("VC");
        assert_eq!(
            released_text("node-1", 0x11, &s, Ok(())),
            "node 0x0011 (node-1) plays no role in this robot: released (it ran VC of \
             generation 1; now no table runs there, its outputs are off)"
        );
        assert_eq!(
            released_text("node-1", 0x11, &s, Err("refused: not newer".into())),
            "node 0x0011 (node-1) plays no role in this robot but runs VC of generation 1, \
             NOT released (refused: not newer): it keeps running that table until released \
             by a push, given a role, or powered off"
        );
    }

    /// On trial, a node is named with when it will be released.
    #[test]
    fn on_trial_a_roleless_node_is_released_at_the_confirmation() {
        assert_eq!(
            release_later_text("node-1", 0x11, &status("VC")),
            "node 0x0011 (node-1) plays no role in this robot but runs VC of generation 1: \
             released when the trial is confirmed (config-tool confirm)"
        );
    }
}
