//! Homing a machine over the radio (docs/running-a-robot.md#homing): where each node
//! stands, from its status and its role's compiled table ([`standing`]: homed, not homed,
//! moving, faulted), the machine as a whole ([`machine`]), and [`home`]: the HOME command
//! to the node of the robot's home role (`ir.home`, step 1's), then its statuses until
//! every chart of every node rests in its idle state, or a node faults.

use std::time::{Duration, Instant};

use config_schema::alarm::{Alarm, AlarmReport};
use config_schema::wire::msg::{Command, Message, Status};
use config_schema::{Table, TableId};
use robot_compiler::compile::Compiled;
use robot_compiler::model::Security;

use crate::error::NetError;
use crate::push::{self, Ids};
use crate::radio::ToolRadio;

/// Where one node stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Standing {
    /// Every chart in its idle state: homed, at rest between cycles.
    Homed,
    /// A chart rests in its initial state, which is not its idle one (after a boot, a
    /// reset or an activation of a stopped machine): the actuators may be anywhere.
    NotHomed,
    /// A chart is in neither state: a cycle or homing is under way.
    Moving,
    /// Faulted, with its fault code.
    Faulted(u8),
    /// The node does not run the role's table (another role, or another table of it).
    Other,
}

impl Standing {
    /// In words, as `status` and `scan` print it.
    pub fn text(self) -> String {
        match self {
            Standing::Homed => "homed".to_string(),
            Standing::NotHomed => "not homed".to_string(),
            Standing::Moving => "moving (a cycle or homing under way)".to_string(),
            Standing::Faulted(code) => format!("faulted ({code:#04x})"),
            Standing::Other => "not running this robot's table".to_string(),
        }
    }
}

/// The links of a node (running table `t`, status `s`) that its peers do not acknowledge,
/// in words for `status` and `scan` after its standing (`None`: none): a node at rest
/// whose link is in alarm or broken is homed, but the machine will not run a cycle
/// through it. `node`: its address, for the reset that re-establishes a broken link.
pub fn link_note(node: u16, t: &Table, s: &Status) -> Option<String> {
    let peers = |bits: u8| -> Vec<String> {
        (t.peers.iter().enumerate().take(8))
            .filter(|(i, _)| bits & (1 << i) != 0)
            .map(|(_, p)| format!("{p:#06x}"))
            .collect()
    };
    let mut notes = Vec::new();
    let alarm = peers(s.link_alarms & !s.links_broken);
    if !alarm.is_empty() {
        notes.push(format!(
            "link to {} in alarm (the peer does not acknowledge)",
            alarm.join(", ")
        ));
    }
    let broken = peers(s.links_broken);
    if !broken.is_empty() {
        notes.push(format!(
            "link to {} broken (config-tool reset --node {node:#06x} re-establishes it)",
            broken.join(", ")
        ));
    }
    (!notes.is_empty()).then(|| notes.join("; "))
}

/// What an `Ack` acknowledged, as `ack` and the panel say it: `acknowledged: N alarm(s) on
/// M node(s)`, then ` (K acknowledged before)` if any were. `before` are the nodes' alarms
/// read just before the `Ack`, `after` its answers, node by node in the same order. An
/// alarm is the same one when its source, level and node time raised are.
pub fn acknowledged(before: &[AlarmReport], after: &[AlarmReport]) -> String {
    let same =
        |a: &Alarm, b: &Alarm| (a.source, a.level, a.raised_ms) == (b.source, b.level, b.raised_ms);
    let (mut now, mut already) = (0, 0);
    for (b, report) in before.iter().zip(after) {
        for a in report.alarms.iter().filter(|a| a.acked) {
            if b.alarms.iter().any(|x| x.acked && same(x, a)) {
                already += 1;
            } else {
                now += 1;
            }
        }
    }
    let already = match already {
        0 => String::new(),
        n => format!(" ({n} acknowledged before)"),
    };
    format!(
        "acknowledged: {now} alarm(s) on {} node(s){already}",
        after.len()
    )
}

/// The generations a machine's nodes run, from their statuses (`(address, status)`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Generations {
    /// Every node runs `generation` and none is on trial.
    Confirmed { generation: u32 },
    /// Every node runs `generation` on trial.
    OnTrial { generation: u32 },
    /// Not all the same: the nodes on trial run `trial` (if any is on trial), and `off`
    /// lists every node on another generation, with the generation it runs (a power cut
    /// during a trial returns a node to its previous one).
    Mixed {
        trial: Option<u32>,
        off: Vec<(u16, u32)>,
    },
}

/// Which generation(s) the nodes of `statuses` run (`None`: no node).
pub fn generations(statuses: &[(u16, &Status)]) -> Option<Generations> {
    let runs: Vec<(u16, u32, bool)> = (statuses.iter())
        .map(|(a, s)| (*a, s.generation, s.trial))
        .collect();
    generations_of(&runs)
}

/// [`generations`] of `(address, generation, on trial)`: the machine's generation is the
/// one on trial if a node is on trial (a power cut takes a node off a trial, never onto
/// one), else the newest (a switch-over that did not finish leaves the nodes it did not
/// reach on the older one).
fn generations_of(runs: &[(u16, u32, bool)]) -> Option<Generations> {
    let newest = runs.iter().max_by_key(|r| r.1);
    let &(_, generation, trial) = runs.iter().find(|r| r.2).or(newest)?;
    let off: Vec<(u16, u32)> = (runs.iter())
        .filter(|r| r.1 != generation || r.2 != trial)
        .map(|r| (r.0, r.1))
        .collect();
    Some(match (off.is_empty(), trial) {
        (true, true) => Generations::OnTrial { generation },
        (true, false) => Generations::Confirmed { generation },
        (false, trial) => Generations::Mixed {
            trial: trial.then_some(generation),
            off,
        },
    })
}

/// Why `role` may not be pushed alone at `generation` to a secured robot's node (`None`:
/// it may): `others` are the robot's other roles' nodes that answered running their roles,
/// as `(address, generation, on trial)`. Each generation of a secured robot has link keys
/// of its own, so the role's node would share none with peers on the machine's generation
/// (the one on trial, else the newest) if it is another.
pub fn role_alone_refusal(
    role: &str,
    generation: u32,
    others: &[(u16, u32, bool)],
) -> Option<String> {
    let machine = match generations_of(others)? {
        Generations::Confirmed { generation } | Generations::OnTrial { generation } => generation,
        Generations::Mixed { trial, .. } => trial.or_else(|| others.iter().map(|o| o.1).max())?,
    };
    (machine != generation).then(|| {
        format!(
            "the robot's other nodes run generation {machine}, and each generation of a \
             secured robot has link keys of its own: {role} alone at generation {generation} \
             would share none with its peers; push every role at generation {generation}, or \
             {role} at generation {machine} (--generation {machine}, with --force over a node \
             that runs it)"
        )
    })
}

/// Nodes on different generations, in words (`off` says what each node off the
/// machine's generation runs: `0x0014 (RC) runs generation 1`), with what to do: a trial
/// a power cut split (`trial`: its generation), or a switch-over that did not finish.
pub fn generations_text(trial: Option<u32>, off: &[String]) -> String {
    match trial {
        Some(generation) => trial_split_text(generation, off),
        None => format!(
            "the nodes run different generations: {}: push again to finish the \
             switch-over, or roll back",
            off.join(", ")
        ),
    }
}

/// Whether the node that answered `s` runs `table`: the identity it reports is that of
/// `table` compiled at the node's generation (the same roles and charts are not enough:
/// two robots may share them).
pub fn runs(table: &Table, s: &Status) -> bool {
    TableId::at(table, s.generation).is_ok_and(|id| id == s.table)
}

/// Where the node running `s` stands, against `table`, the table of role `role`.
pub fn standing(role: &str, table: &Table, s: &Status) -> Standing {
    if s.role.as_str() != role || s.states.len() != table.charts.len() {
        return Standing::Other;
    }
    // A fault first, whatever table the node runs: it needs a reset either way, and the
    // operator sees it (and the panel offers RESET).
    if let Some(code) = s.fault {
        return Standing::Faulted(code);
    }
    if !runs(table, s) {
        return Standing::Other;
    }
    let mut homed = true;
    for (chart, &state) in table.charts.iter().zip(s.states.iter()) {
        if chart.rests_in(state) {
            continue;
        }
        if state != chart.initial {
            return Standing::Moving;
        }
        homed = false;
    }
    if homed {
        Standing::Homed
    } else {
        Standing::NotHomed
    }
}

/// One role's node and where it stands.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Node {
    pub role: String,
    pub addr: u16,
    pub standing: Standing,
    /// The generation it runs, and whether on trial.
    pub generation: u32,
    pub trial: bool,
    /// The peers its links to are in alarm or broken (they do not acknowledge: a peer
    /// that restarted, or went away).
    pub stalled: Vec<u16>,
    /// Its links are secured (the robot's `security`): each generation has link keys of
    /// its own, so a node shares none with a peer on another generation.
    pub secured: bool,
    /// The robot has a homing sequence (else a machine whose faults are cleared is
    /// started again, not homed).
    pub homes: bool,
}

/// Where every role's node stands; `statuses` in role order.
pub fn nodes(c: &Compiled, statuses: &[Status]) -> Vec<Node> {
    c.ir.roles
        .iter()
        .zip(&c.tables)
        .zip(statuses)
        .map(|((r, t), s)| Node {
            role: r.name.clone(),
            addr: r.address,
            standing: standing(&r.name, t, s),
            generation: s.generation,
            trial: s.trial,
            stalled: (t.peers.iter().enumerate().take(8))
                .filter(|(i, _)| (s.link_alarms | s.links_broken) & (1 << i) != 0)
                .map(|(_, &p)| p)
                .collect(),
            secured: c.robot.security == Security::On,
            homes: c.ir.home.is_some(),
        })
        .collect()
}

/// Whether the machine `nodes` describe is only not homed: no node faulted, moving or
/// running another table, one not homed ([`machine`]).
pub fn only_not_homed(nodes: &[Node]) -> bool {
    machine(nodes).is_some_and(|n| n.standing == Standing::NotHomed)
}

/// The addresses of the faulted nodes of `nodes`, in order.
fn faulted_addrs(nodes: &[Node]) -> Vec<u16> {
    (nodes.iter())
        .filter(|n| matches!(n.standing, Standing::Faulted(_)))
        .map(|n| n.addr)
        .collect()
}

/// The machine as a whole: the first node that is not this robot's, else the first
/// faulted, else the first moving; else not homed if any node is; else homed.
pub fn machine(nodes: &[Node]) -> Option<&Node> {
    let first = |f: &dyn Fn(Standing) -> bool| nodes.iter().find(|n| f(n.standing));
    first(&|s| s == Standing::Other)
        .or_else(|| first(&|s| matches!(s, Standing::Faulted(_))))
        .or_else(|| first(&|s| s == Standing::Moving))
        .or_else(|| first(&|s| s == Standing::NotHomed))
}

/// Why a command refuses the machine `nodes` describe (`None`: homed, at rest), in words
/// naming the node and what to do: `start` refuses a machine not homed, `home` does not.
pub fn refusal(nodes: &[Node], homing: bool) -> Option<String> {
    if let Some(split) = split_generations(nodes) {
        return Some(split);
    }
    let n = machine(nodes)?;
    let who = format!("node {:#06x} ({})", n.addr, n.role);
    Some(match n.standing {
        Standing::Other => {
            // Every one of them: the operator checks or pushes them all.
            let others: Vec<String> = (nodes.iter())
                .filter(|n| n.standing == Standing::Other)
                .map(|n| format!("{:#06x} ({})", n.addr, n.role))
                .collect();
            let who = match others.as_slice() {
                [_] => format!("{who} does not run"),
                _ => format!("nodes {} do not run", others.join(", ")),
            };
            format!(
                "{who} this robot's table (another robot's, or this file changed since its \
                 push): check the file, or push it"
            )
        }
        Standing::Faulted(_) => faulted_text(nodes),
        Standing::Moving => {
            let then = if homing { "home" } else { "START" };
            let mut why =
                format!("{who} is moving (a cycle or homing under way): {then} once it is at rest");
            if let Some(stall) = stall_note(nodes) {
                why = format!("{why}; {stall}");
            }
            why
        }
        Standing::NotHomed if homing => return None,
        Standing::NotHomed => "not homed: run config-tool home".to_string(),
        Standing::Homed => return None,
    })
}

/// The machine's nodes on different generations, in words (`None`: they run one): a
/// trial a power cut split, or, on a secured robot, a switch-over that did not finish
/// (its nodes share no link keys with the others: no cycle runs across them). An
/// unsecured robot's nodes may run different generations of one robot (`push --role`).
fn split_generations(nodes: &[Node]) -> Option<String> {
    let runs: Vec<(u16, u32, bool)> = (nodes.iter())
        .map(|n| (n.addr, n.generation, n.trial))
        .collect();
    let Some(Generations::Mixed { trial, mut off }) = generations_of(&runs) else {
        return None;
    };
    // A node that confirmed the trial generation (a `confirm` one node did not hear)
    // shares its keys with the others: not a split.
    off.retain(|&(_, g)| Some(g) != trial);
    if off.is_empty() {
        return None;
    }
    // Not a switch-over to finish when a node runs another robot's table (another robot
    // pushed over this one): that node is named as not running it.
    let other = nodes.iter().any(|n| n.standing == Standing::Other);
    if trial.is_none() && (other || !nodes.iter().any(|n| n.secured)) {
        return None;
    }
    let off: Vec<String> = (off.iter())
        .map(|&(addr, generation)| {
            let role = nodes
                .iter()
                .find(|n| n.addr == addr)
                .map(|n| n.role.as_str());
            format!(
                "{addr:#06x} ({}) runs generation {generation}",
                role.unwrap_or("?")
            )
        })
        .collect();
    Some(generations_text(trial, &off))
}

/// The faulted nodes of `nodes`, every one of them, with the operator's way out: reset
/// each, acknowledge the alarms the faults latched (a node refuses HOME while one is),
/// then home (a robot without homing: start).
fn faulted_text(nodes: &[Node]) -> String {
    let faulted: Vec<(u16, &str, u8)> = (nodes.iter())
        .filter_map(|n| match n.standing {
            Standing::Faulted(code) => Some((n.addr, n.role.as_str(), code)),
            _ => None,
        })
        .collect();
    let (who, resets) = faulted_words(&faulted);
    // A robot without homing rests where its faults are cleared: started again.
    let then = match nodes.first().is_none_or(|n| n.homes) {
        true => "config-tool home",
        false => "config-tool start",
    };
    format!("{who}: {resets}, acknowledge the alarms (config-tool ack), then {then}")
}

/// A node that faulted while homing (`code`, what it means in words: `meaning`; `others`:
/// the nodes its fault stopped), with the way out: reset each, acknowledge the alarms
/// the faults latched (a node refuses HOME while one is), home again.
pub fn homing_faulted_text(
    role: &str,
    addr: u16,
    code: u8,
    meaning: &str,
    others: &[u16],
) -> String {
    let resets: Vec<String> = (std::iter::once(&addr).chain(others))
        .map(|a| format!("config-tool reset --node {a:#06x}"))
        .collect();
    let (stopped, them) = match others {
        [] => (String::new(), "it"),
        _ => {
            let each: Vec<String> = others.iter().map(|a| format!("{a:#06x}")).collect();
            (format!(", which stopped {}", each.join(", ")), "each")
        }
    };
    format!(
        "homing faulted: node {addr:#06x} ({role}): {meaning} (code {code:#04x}){stopped}; \
         reset {them} ({}), acknowledge the alarms (config-tool ack), then home again",
        resets.join("; ")
    )
}

/// Why a push does not wait for the idle point of a machine whose nodes `faulted`
/// (`(address, role, fault code)`) are: it never comes. `None`: no node is faulted.
pub fn faulted_push_text(faulted: &[(u16, &str, u8)]) -> Option<String> {
    if faulted.is_empty() {
        return None;
    }
    let (who, resets) = faulted_words(faulted);
    Some(format!(
        "{who}: a faulted machine does not reach its idle point, so nothing switched (the \
         tables stay staged): push again with --now to switch at once, or {resets}, \
         acknowledge the alarms (config-tool ack), home, and push again"
    ))
}

/// Why a rollback at the idle point does not wait for a machine whose nodes `faulted`
/// are: it never comes. `None`: no node is faulted.
pub fn faulted_rollback_text(faulted: &[(u16, &str, u8)]) -> Option<String> {
    if faulted.is_empty() {
        return None;
    }
    let (who, resets) = faulted_words(faulted);
    Some(format!(
        "{who}: a faulted machine does not reach its idle point, so nothing rolled back: \
         rollback --now to return at once, or {resets}, acknowledge the alarms (config-tool \
         ack), home, and roll back again"
    ))
}

/// Faulted nodes `(address, role, fault code)` in words (`node 0x0011 (VC) is faulted
/// (0x81)`, `nodes ... are faulted`), and the resets they need (`reset it (...)`).
fn faulted_words(faulted: &[(u16, &str, u8)]) -> (String, String) {
    let resets: Vec<String> = (faulted.iter())
        .map(|(addr, _, _)| format!("config-tool reset --node {addr:#06x}"))
        .collect();
    let (who, them) = match faulted {
        [(addr, role, code)] => (
            format!("node {addr:#06x} ({role}) is faulted ({code:#04x})"),
            "it",
        ),
        _ => {
            let each: Vec<String> = (faulted.iter())
                .map(|(addr, role, code)| format!("{addr:#06x} ({role}, {code:#04x})"))
                .collect();
            (format!("nodes {} are faulted", each.join(", ")), "each")
        }
    };
    (who, format!("reset {them} ({})", resets.join("; ")))
}

/// A trial a power cut split, in words: `off` says what each node off generation `trial`
/// runs (`0x0014 (RC) runs generation 1`).
fn trial_split_text(trial: u32, off: &[String]) -> String {
    format!(
        "not every node runs generation {trial} on trial: {} (a power cut returns a node to \
         its previous generation): `config-tool rollback` returns the others to theirs",
        off.join(", ")
    )
}

/// The first node with a link in alarm, in words, with what re-establishes it: what
/// keeps a machine `moving` that never comes to rest.
pub fn stall_note(nodes: &[Node]) -> Option<String> {
    let n = nodes.iter().find(|n| !n.stalled.is_empty())?;
    let peers: Vec<String> = n.stalled.iter().map(|p| format!("{p:#06x}")).collect();
    Some(format!(
        "node {:#06x} ({}) has its link to {} in alarm (the peer does not acknowledge): \
         config-tool reset --node {:#06x} re-establishes it",
        n.addr,
        n.role,
        peers.join(", "),
        n.addr
    ))
}

/// How homing ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HomeEnd {
    /// Every chart of every node rests in its idle state.
    Homed,
    /// Nothing was sent: the machine's state refuses homing (in words, [`refusal`]).
    Refused(String),
    /// The home node answered the HOME command but did not start homing (armed for a
    /// switch-over).
    Ignored { role: String, addr: u16 },
    /// A node faulted while homing (the one that detected the fault), and the addresses
    /// of the other nodes faulted then (stopped by its fault: each needs a reset too).
    Faulted {
        role: String,
        addr: u16,
        code: u8,
        others: Vec<u16>,
    },
    /// Not every node at rest within the wait: the roles still moving or not homed.
    NotDone(Vec<String>),
}

/// How often the nodes' statuses are asked for while homing runs.
pub const POLL: Duration = Duration::from_millis(50);

/// Rounds of statuses asked at most after a node faulted while homing, until the faulted
/// nodes are the same two rounds running.
const SETTLE_ROUNDS: usize = 5;

/// The status of every role's node of `c` (each asked until it answers, at most
/// `timeout`).
pub fn statuses(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &Compiled,
    timeout: Duration,
) -> Result<Vec<Status>, NetError> {
    every_role(radio, ids, c, Command::Status, timeout, push::status_answer)
}

/// `command` to every role's node of `c` at once ([`push::ask_each`], within `timeout`):
/// per role, in role order, its answer as `pick` takes it, or how many times it was asked
/// without one.
pub fn ask_roles<T>(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &Compiled,
    command: Command,
    timeout: Duration,
    pick: impl Fn(Message<'_>, u16) -> Option<T>,
) -> std::io::Result<Vec<Result<T, u32>>> {
    let addrs: Vec<u16> = c.ir.roles.iter().map(|r| r.address).collect();
    push::ask_each(radio, ids, &addrs, command, timeout, pick)
}

/// [`ask_roles`]: each node's answer as `pick` takes it, in role order; the first node (in
/// role order) that did not answer within `timeout` fails it.
fn every_role<T>(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &Compiled,
    command: Command,
    timeout: Duration,
    pick: impl Fn(Message<'_>, u16) -> Option<T>,
) -> Result<Vec<T>, NetError> {
    let answers = ask_roles(radio, ids, c, command, timeout, pick)?;
    (c.ir.roles.iter().zip(answers))
        .map(|(r, a)| {
            a.map_err(|_| NetError::NoAnswer {
                addr: r.address,
                role: Some(r.name.clone()),
                command: format!("{command:?}"),
            })
        })
        .collect()
}

/// `command` (`Command::Alarms`, or `Command::Ack` to acknowledge) to every role's node of
/// `c` (each asked until it answers, at most `timeout`): each node's alarm report, in role
/// order.
pub fn alarms(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &Compiled,
    command: Command,
    timeout: Duration,
) -> Result<Vec<AlarmReport>, NetError> {
    every_role(radio, ids, c, command, timeout, push::alarms_answer)
}

/// Homes the machine of `c`: refuses one with a node faulted, moving or not running the
/// robot's table; else calls `sending` (what is about to happen can be said then, not
/// before a refusal), sends HOME to the home role's node and asks every node's status
/// (every [`POLL`]) until every chart rests in its idle state, a node faults, or `wait`
/// passes. Returns how it ended and how long it took from the HOME command.
pub fn home(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &Compiled,
    within: (Duration, Duration),
    sending: &mut dyn FnMut(),
) -> Result<(HomeEnd, Duration), NetError> {
    let before = statuses(radio, ids, c, within.0)?;
    home_from(radio, ids, c, &before, within, sending)
}

/// [`home`], the nodes' statuses `before` (in role order) asked already by the caller.
pub fn home_from(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &Compiled,
    before: &[Status],
    (answer_within, wait): (Duration, Duration),
    sending: &mut dyn FnMut(),
) -> Result<(HomeEnd, Duration), NetError> {
    let home = c.ir.home.ok_or(NetError::NoHome)?;
    let role = c.ir.roles.get(home).ok_or(NetError::NoHome)?;
    let before = nodes(c, before);
    if let Some(why) = refusal(&before, true) {
        return Ok((HomeEnd::Refused(why), Duration::ZERO));
    }
    // A node refuses HOME while a fault alarm is latched: say so, naming it.
    let reports = alarms(radio, ids, c, Command::Alarms, answer_within)?;
    for (r, report) in c.ir.roles.iter().zip(&reports) {
        if let Some(a) = report.blocking() {
            let why = format!(
                "node {:#06x} ({}) has a fault alarm latched: {}: acknowledge it first \
                 (config-tool ack)",
                r.address,
                r.name,
                crate::demo::alarm_text(c, &r.name, a.source)
            );
            return Ok((HomeEnd::Refused(why), Duration::ZERO));
        }
    }
    after_greetings(radio, reports.iter().map(|r| r.now_ms))?;
    sending();
    let t0 = Instant::now();
    let s = push::command(radio, ids, role.address, Command::Home, answer_within)?.ok_or_else(
        || NetError::NoAnswer {
            addr: role.address,
            role: Some(role.name.clone()),
            command: "Home".to_string(),
        },
    )?;
    if let Some(t) = c.tables.get(home) {
        if standing(&role.name, t, &s) == Standing::NotHomed {
            let end = HomeEnd::Ignored {
                role: role.name.clone(),
                addr: role.address,
            };
            return Ok((end, t0.elapsed()));
        }
    }
    let end = crate::deadline(t0, wait);
    let mut links = Settling::default();
    loop {
        let asked = Instant::now();
        let answers = statuses(radio, ids, c, answer_within)?;
        let now = nodes(c, &answers);
        // Homed, and what homing published acknowledged.
        let settled = links.settled(asked, Instant::now(), &answers);
        if now
            .iter()
            .any(|n| matches!(n.standing, Standing::Faulted(_)))
        {
            // Once more, every node: the one that detected it has faulted by the time a
            // peer shows its fault; it is named, not the peer. Then until the faulted
            // nodes are the same two rounds running (its fault reaches the others over
            // the radio; each needs a reset), a few rounds at most.
            let mut after = nodes(c, &statuses(radio, ids, c, answer_within)?);
            for _ in 0..SETTLE_ROUNDS {
                let again = nodes(c, &statuses(radio, ids, c, answer_within)?);
                let same = faulted_addrs(&again) == faulted_addrs(&after);
                after = again;
                if same {
                    break;
                }
            }
            return Ok((detector(&after), t0.elapsed()));
        }
        if settled && now.iter().all(|n| n.standing == Standing::Homed) {
            return Ok((HomeEnd::Homed, t0.elapsed()));
        }
        if Instant::now() >= end {
            let mut waiting: Vec<String> = now
                .iter()
                .filter(|n| n.standing != Standing::Homed)
                .map(|n| format!("{} {}", n.role, n.standing.text()))
                .collect();
            waiting.extend(stall_note(&now));
            return Ok((HomeEnd::NotDone(waiting), t0.elapsed()));
        }
        // Whatever comes meanwhile (late answers) is not for the watch.
        let until = (Instant::now() + POLL).min(end);
        while radio.recv(until)?.is_some() {}
    }
}

/// Waits until every node has been up [`node_fw::restart::GREETED_WITHIN_MS`], given each
/// node's clock (`up_ms`, ms since its boot, from its `Alarms` answer): a node that booted
/// moments ago may still be greeting its peers, and a late copy would fault a node that
/// homing or a START has set going (`node_fw::restart`). Whatever arrives meanwhile is
/// dropped.
pub fn after_greetings(
    radio: &mut ToolRadio,
    up_ms: impl Iterator<Item = u32>,
) -> Result<(), NetError> {
    let up = up_ms.map(u64::from).min();
    if let Some(left) = up.and_then(|up| node_fw::restart::GREETED_WITHIN_MS.checked_sub(up)) {
        let until = Instant::now() + Duration::from_millis(left);
        while radio.recv(until)?.is_some() {}
    }
    Ok(())
}

/// How long no node may have retransmitted before its links count as settled: twice a
/// link's longest retransmission timeout (a link holding an unacknowledged event resends
/// it at least every `RTO_MAX_MS`, so a quiet node has none; twice, for a node that polls
/// its links late).
pub const QUIET: Duration = Duration::from_millis(2 * node_fw::link::RTO_MAX_MS);

/// Whether what the nodes published has been acknowledged, from their statuses in
/// successive rounds. A link in alarm is not settled, and neither is one that has not
/// reached its alarm yet but still resends: homing that ended while an event's
/// acknowledgement was still being retried would leave the link to fall into alarm just
/// after `home` said the machine was homed. So the links settle once no link is in alarm
/// and every node's retransmission counter stayed the same for [`QUIET`].
#[derive(Debug, Default)]
struct Settling {
    /// The nodes' retransmission counters, and when the round that first showed them ended.
    since: Option<(Vec<u32>, Instant)>,
}

impl Settling {
    /// The round asked from `asked` to `answered` gave `answers`.
    fn settled(&mut self, asked: Instant, answered: Instant, answers: &[Status]) -> bool {
        let retried: Vec<u32> = answers.iter().map(|s| s.counters.retried).collect();
        let since = match &self.since {
            Some((before, at)) if *before == retried => *at,
            _ => {
                self.since = Some((retried, answered));
                answered
            }
        };
        // Each node's two snapshots were taken at least `asked - since` apart.
        let quiet = asked.saturating_duration_since(since) >= QUIET;
        quiet && answers.iter().all(|s| s.link_alarms == 0)
    }
}

/// The status fault code of a node stopped by a peer's fault.
const PEER_FAULT: u8 = 0x80 | robot_compiler::synth::FAULT_PEER;

/// The faulted node that detected the fault: the first whose fault is not a peer's, else
/// the first faulted.
fn detector(nodes: &[Node]) -> HomeEnd {
    let faulted = |own: bool| {
        nodes.iter().find_map(|n| match n.standing {
            Standing::Faulted(code) if !own || code != PEER_FAULT => Some((n, code)),
            _ => None,
        })
    };
    match faulted(true).or_else(|| faulted(false)) {
        Some((n, code)) => HomeEnd::Faulted {
            role: n.role.clone(),
            addr: n.addr,
            code,
            others: (faulted_addrs(nodes).into_iter())
                .filter(|&a| a != n.addr)
                .collect(),
        },
        None => HomeEnd::NotDone(Vec::new()),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use config_schema::wire::msg::{Counters, RuntimeCounters};

    /// A status of role `role`, generation 1, its charts in `states`, with `fault`.
    pub(crate) fn status(role: &str, states: &[u8], fault: Option<u8>) -> Status {
        Status {
            ack: 1,
            role: heapless::String::try_from(role).unwrap(),
            generation: 1,
            table: TableId::at(&table(), 1).unwrap(),
            staged: 0,
            previous: 0,
            trial: false,
            states: heapless::Vec::from_slice(states).unwrap(),
            outputs: 0,
            inputs: 0,
            fault,
            link_alarms: 0,
            links_broken: 0,
            links_restarted: 0,
            epoch: 0,
            counters: Counters::default(),
            runtime: RuntimeCounters::default(),
            cycles: 0,
        }
    }

    /// A node faulted while homing: reset, then the ack its alarm needs (the next `home`
    /// refuses a latched fault alarm; it said `reset, then home again`), then home. Every
    /// node its fault stopped is reset too (it named only the one that detected it, and
    /// following it `ack` and `home` refused for the others).
    #[test]
    fn a_homing_fault_says_reset_each_ack_then_home() {
        assert_eq!(
            homing_faulted_text("VC", 0x11, 0x81, "its motion watchdog expired", &[]),
            "homing faulted: node 0x0011 (VC): its motion watchdog expired (code 0x81); reset \
             it (config-tool reset --node 0x0011), acknowledge the alarms (config-tool ack), \
             then home again"
        );
        assert_eq!(
            homing_faulted_text(
                "HC",
                0x13,
                0x81,
                "its motion watchdog expired",
                &[0x11, 0x12]
            ),
            "homing faulted: node 0x0013 (HC): its motion watchdog expired (code 0x81), which \
             stopped 0x0011, 0x0012; reset each (config-tool reset --node 0x0013; config-tool \
             reset --node 0x0011; config-tool reset --node 0x0012), acknowledge the alarms \
             (config-tool ack), then home again"
        );
    }

    /// A role pushed alone to a secured robot goes at the machine's generation: the one
    /// on trial, else the newest; refused otherwise, saying which.
    #[test]
    fn a_role_alone_goes_at_the_machines_generation() {
        assert_eq!(role_alone_refusal("RC", 2, &[]), None);
        assert_eq!(
            role_alone_refusal("RC", 2, &[(0x11, 2, false), (0x12, 2, false)]),
            None
        );
        assert_eq!(
            role_alone_refusal("RC", 3, &[(0x11, 2, false), (0x12, 3, false)]),
            None
        );
        assert_eq!(
            role_alone_refusal("RC", 2, &[(0x11, 2, true), (0x12, 3, false)]),
            None
        );
        let refused = role_alone_refusal("RC", 3, &[(0x11, 2, true), (0x12, 1, false)]);
        assert_eq!(
            refused.as_deref(),
            Some(
                "the robot's other nodes run generation 2, and each generation of a secured \
                 robot has link keys of its own: RC alone at generation 3 would share none \
                 with its peers; push every role at generation 3, or RC at generation 2 \
                 (--generation 2, with --force over a node that runs it)"
            )
        );
        let refused = role_alone_refusal("RC", 1, &[(0x11, 4, false)]);
        assert!(refused.is_some_and(|r| r.contains("other nodes run generation 4")));
    }

    /// A second `ack` said it acknowledged every alarm again.
    #[test]
    fn an_ack_counts_only_the_alarms_it_acknowledged() {
        use config_schema::alarm::{AlarmLevel, AlarmSource};
        let node = |alarms: &[(AlarmSource, u32, bool)]| {
            let mut report = AlarmReport {
                ack: 1,
                now_ms: 1000,
                alarms: heapless::Vec::new(),
                dropped: 0,
            };
            for &(source, raised_ms, acked) in alarms {
                let alarm = Alarm {
                    source,
                    level: AlarmLevel::Fault,
                    raised_ms,
                    acked,
                    persists: false,
                };
                report.alarms.push(alarm).unwrap();
            }
            report
        };
        let estop = AlarmSource::EStop;
        let link = AlarmSource::Link { peer: 0x0012 };
        let before = [node(&[(estop, 100, true), (link, 200, false)]), node(&[])];
        // The link alarm acknowledged now; another e-stop, raised after the read, too.
        let after = [
            node(&[(estop, 100, true), (link, 200, true), (estop, 900, true)]),
            node(&[]),
        ];
        assert_eq!(
            acknowledged(&before, &after),
            "acknowledged: 2 alarm(s) on 2 node(s) (1 acknowledged before)"
        );
        assert_eq!(
            acknowledged(&after, &after),
            "acknowledged: 0 alarm(s) on 2 node(s) (3 acknowledged before)"
        );
        assert_eq!(
            acknowledged(&[node(&[])], &[node(&[])]),
            "acknowledged: 0 alarm(s) on 1 node(s)"
        );
    }

    /// A machine on trial whose node lost the trial in a power cut is mixed, that node
    /// named with the generation it went back to; all on one generation, on trial or not,
    /// is not.
    #[test]
    fn a_node_off_the_machine_s_generation_is_named() {
        let on = |generation: u32, trial: bool| Status {
            generation,
            trial,
            ..status("VC", &[0], None)
        };
        let (a, b, c) = (on(6, true), on(6, true), on(4, false));
        assert_eq!(
            generations(&[(0x11, &a), (0x12, &b), (0x14, &c)]),
            Some(Generations::Mixed {
                trial: Some(6),
                off: vec![(0x14, 4)]
            })
        );
        assert_eq!(
            generations(&[(0x11, &a), (0x12, &b)]),
            Some(Generations::OnTrial { generation: 6 })
        );
        assert_eq!(
            generations(&[(0x14, &c), (0x15, &c)]),
            Some(Generations::Confirmed { generation: 4 })
        );
        // Without a trial, the nodes behind the newest generation are named (a
        // switch-over that did not finish leaves them there), whatever the order.
        let d = on(5, false);
        for pair in [[(0x14, &c), (0x15, &d)], [(0x15, &d), (0x14, &c)]] {
            assert_eq!(
                generations(&pair),
                Some(Generations::Mixed {
                    trial: None,
                    off: vec![(0x14, 4)]
                })
            );
        }
        assert_eq!(generations(&[]), None);
    }

    /// Two charts: the first starts in S2 (not homed) and idles in S0, the second
    /// starts and idles in S0.
    fn table() -> Table {
        let mut t = Table::empty("VC");
        t.push_chart(2, 1, &[&[], &[], &[]], &[]).unwrap();
        t.push_chart(0, 1, &[&[], &[]], &[]).unwrap();
        t.charts[0].idle = 0;
        t
    }

    /// `scan` and `status` said `homed` of a node whose link was in alarm: the link is
    /// named after it.
    #[test]
    fn a_link_in_alarm_or_broken_is_named() {
        let mut t = table();
        t.peers
            .extend_from_slice(&[0x0012, 0x0014, 0x0015])
            .unwrap();
        let mut s = status("VC", &[0, 0], None);
        assert_eq!(link_note(0x0011, &t, &s), None);
        s.link_alarms = 0b010;
        assert_eq!(
            link_note(0x0011, &t, &s).as_deref(),
            Some("link to 0x0014 in alarm (the peer does not acknowledge)")
        );
        s.link_alarms = 0b011;
        s.links_broken = 0b101;
        assert_eq!(
            link_note(0x0011, &t, &s).as_deref(),
            Some(
                "link to 0x0014 in alarm (the peer does not acknowledge); link to 0x0012, \
                 0x0015 broken (config-tool reset --node 0x0011 re-establishes it)"
            )
        );
    }

    #[test]
    fn a_node_is_homed_not_homed_moving_faulted_or_not_this_robots() {
        let t = table();
        assert_eq!(
            standing("VC", &t, &status("VC", &[0, 0], None)),
            Standing::Homed
        );
        assert_eq!(
            standing("VC", &t, &status("VC", &[2, 0], None)),
            Standing::NotHomed
        );
        assert_eq!(
            standing("VC", &t, &status("VC", &[1, 0], None)),
            Standing::Moving
        );
        assert_eq!(
            standing("VC", &t, &status("VC", &[2, 1], None)),
            Standing::Moving
        );
        assert_eq!(
            standing("VC", &t, &status("VC", &[2, 0], Some(0x81))),
            Standing::Faulted(0x81)
        );
        assert_eq!(
            standing("VC", &t, &status("GR", &[0, 0], None)),
            Standing::Other
        );
        assert_eq!(standing("VC", &t, &status("", &[], None)), Standing::Other);
        // The role and its charts, another table: a guard, a timer, anything else.
        let mut other = t.clone();
        other.charts[1].idle = 1;
        assert_eq!(
            standing("VC", &other, &status("VC", &[0, 0], None)),
            Standing::Other
        );
        // A chart resting in a mode besides its idle state (a function's `Auto`) is at
        // rest: the machine is homed, not moving.
        let mut modes = t.clone();
        modes.charts[1].rests = 1 << 1;
        let mut s = status("VC", &[0, 1], None);
        s.table = TableId::at(&modes, 1).unwrap();
        assert_eq!(standing("VC", &modes, &s), Standing::Homed);
        s.states = heapless::Vec::from_slice(&[1, 1]).unwrap();
        assert_eq!(standing("VC", &modes, &s), Standing::Moving);
        // Faulted, it says so first, whichever table it runs: a reset is due either way.
        assert_eq!(
            standing("VC", &other, &status("VC", &[0, 0], Some(0x81))),
            Standing::Faulted(0x81)
        );
        // The same table at another generation is another blob.
        let later = Status {
            generation: 2,
            ..status("VC", &[0, 0], None)
        };
        assert_eq!(standing("VC", &t, &later), Standing::Other);
    }

    fn node(role: &str, addr: u16, standing: Standing) -> Node {
        Node {
            role: role.into(),
            addr,
            standing,
            generation: 1,
            trial: false,
            stalled: Vec::new(),
            secured: true,
            homes: true,
        }
    }

    fn retrying(retried: u32, link_alarms: u8) -> Status {
        let mut s = status("VC", &[0, 0], None);
        s.counters.retried = retried;
        s.link_alarms = link_alarms;
        s
    }

    #[test]
    fn links_settle_only_once_no_node_retransmitted_for_the_quiet_time() {
        let t0 = Instant::now();
        let ms = |n: u64| t0 + Duration::from_millis(n);
        let mut links = Settling::default();
        let round = |links: &mut Settling, at: u64, answers: &[Status]| {
            links.settled(ms(at), ms(at + 10), answers)
        };
        let quiet = QUIET.as_millis() as u64;
        let resending = [retrying(3, 0), retrying(1, 0)];
        let resent = [retrying(3, 0), retrying(2, 0)];
        let again = [retrying(4, 0), retrying(2, 0)];
        let alarm = [retrying(4, 0b10), retrying(2, 0)];
        // No alarm, but the second node still resends: not settled, however long.
        assert!(!round(&mut links, 0, &resending));
        assert!(!round(&mut links, 50, &resent));
        assert!(!round(&mut links, 60 + quiet - 1, &resent));
        // The same counters over the quiet time, asked from the end of the first round
        // that showed them: settled.
        assert!(round(&mut links, 60 + quiet, &resent));
        // One more resend starts the quiet time again.
        assert!(!round(&mut links, 100 + quiet, &again));
        assert!(round(&mut links, 110 + 2 * quiet, &again));
        // A link in alarm is never settled.
        assert!(!round(&mut links, 200 + 4 * quiet, &alarm));
    }

    #[test]
    fn homing_names_the_node_that_detected_a_fault_not_a_peer_it_stopped() {
        let nodes = [
            node("VC", 0x11, Standing::Faulted(PEER_FAULT)),
            node("HC", 0x13, Standing::Faulted(0x81)),
        ];
        assert_eq!(
            detector(&nodes),
            HomeEnd::Faulted {
                role: "HC".into(),
                addr: 0x13,
                code: 0x81,
                others: vec![0x11],
            }
        );
        assert_eq!(
            detector(&nodes[..1]),
            HomeEnd::Faulted {
                role: "VC".into(),
                addr: 0x11,
                code: PEER_FAULT,
                others: vec![],
            }
        );
    }

    #[test]
    fn start_refuses_a_machine_not_homed_and_home_refuses_a_faulted_or_moving_one() {
        let homed = [
            node("VC", 0x11, Standing::Homed),
            node("GR", 0x12, Standing::Homed),
        ];
        assert_eq!(refusal(&homed, false), None);
        assert_eq!(refusal(&homed, true), None);
        let unhomed = [
            node("VC", 0x11, Standing::NotHomed),
            node("GR", 0x12, Standing::Homed),
        ];
        assert_eq!(
            refusal(&unhomed, false).as_deref(),
            Some("not homed: run config-tool home")
        );
        assert_eq!(refusal(&unhomed, true), None);
        let faulted = [
            node("VC", 0x11, Standing::NotHomed),
            node("GR", 0x12, Standing::Faulted(0x82)),
        ];
        let said = "node 0x0012 (GR) is faulted (0x82): reset it (config-tool reset --node \
                    0x0012), acknowledge the alarms (config-tool ack), then config-tool home";
        assert_eq!(refusal(&faulted, true).as_deref(), Some(said));
        assert_eq!(refusal(&faulted, false).as_deref(), Some(said));
        // Every faulted node, not the first alone (the operator reset it, and was refused
        // for the next).
        let two = [
            node("VC", 0x11, Standing::Faulted(0x86)),
            node("GR", 0x12, Standing::Homed),
            node("HC", 0x13, Standing::Faulted(0x86)),
        ];
        assert_eq!(
            refusal(&two, true).as_deref(),
            Some(
                "nodes 0x0011 (VC, 0x86), 0x0013 (HC, 0x86) are faulted: reset each \
                 (config-tool reset --node 0x0011; config-tool reset --node 0x0013), \
                 acknowledge the alarms (config-tool ack), then config-tool home"
            )
        );
        // A robot without homing (a station) is started again: `home` says there is
        // nothing to home.
        let station = two.map(|n| Node { homes: false, ..n });
        assert!(refusal(&station, false).is_some_and(
            |r| r.ends_with("acknowledge the alarms (config-tool ack), then config-tool start")
        ));
        let moving = [
            node("VC", 0x11, Standing::Moving),
            node("GR", 0x12, Standing::Homed),
        ];
        assert_eq!(
            refusal(&moving, true).as_deref(),
            Some(
                "node 0x0011 (VC) is moving (a cycle or homing under way): home once it is at \
                 rest"
            )
        );
        // A machine stalled by a link in alarm (a peer that restarted and does not take
        // the events any more) was only `moving`, forever: the link is named, and how to
        // re-establish it.
        let mut stalled = moving.clone();
        stalled[1].stalled = vec![0x0014];
        assert_eq!(
            refusal(&stalled, false).as_deref(),
            Some(
                "node 0x0011 (VC) is moving (a cycle or homing under way): START once it is \
                 at rest; node 0x0012 (GR) has its link to 0x0014 in alarm (the peer does not \
                 acknowledge): config-tool reset --node 0x0012 re-establishes it"
            )
        );
        let other = [
            node("VC", 0x11, Standing::Other),
            node("GR", 0x12, Standing::Faulted(1)),
        ];
        assert_eq!(
            refusal(&other, true).as_deref(),
            Some(
                "node 0x0011 (VC) does not run this robot's table (another robot's, or this \
                 file changed since its push): check the file, or push it"
            )
        );
        // Every node that does not run it is named (only the first was).
        let others = [
            node("VC", 0x11, Standing::Other),
            node("GR", 0x12, Standing::Homed),
            node("RC", 0x14, Standing::Other),
        ];
        assert_eq!(
            refusal(&others, false).as_deref(),
            Some(
                "nodes 0x0011 (VC), 0x0014 (RC) do not run this robot's table (another \
                 robot's, or this file changed since its push): check the file, or push it"
            )
        );
        // A trial a power cut split: RC booted generation 1, the others run 2 on trial
        // (the robot's file is generation 2's, so RC's table is not it). It said `does
        // not run this robot's table`, as if the file were wrong.
        let on_trial = |role: &str, addr| Node {
            generation: 2,
            trial: true,
            ..node(role, addr, Standing::Homed)
        };
        let split = [
            on_trial("VC", 0x11),
            node("RC", 0x14, Standing::Other),
            on_trial("GR", 0x12),
        ];
        let said = "not every node runs generation 2 on trial: 0x0014 (RC) runs generation 1 \
                    (a power cut returns a node to its previous generation): `config-tool \
                    rollback` returns the others to theirs";
        assert_eq!(refusal(&split, true).as_deref(), Some(said));
        assert_eq!(refusal(&split, false).as_deref(), Some(said));
        // Another table on a node of a trial (not off it): the file, as before.
        let mut other_on_trial = split.clone();
        other_on_trial[1] = Node {
            standing: Standing::Other,
            ..on_trial("RC", 0x14)
        };
        assert!(refusal(&other_on_trial, true)
            .is_some_and(|r| r.starts_with("node 0x0014 (RC) does not run this robot's table")));
        // Off the trial with the same table (the file pushed at both generations): RC runs
        // the robot's table at its generation, and the trial is split all the same (it
        // sent HOME).
        let mut same_table = split.clone();
        same_table[1].standing = Standing::Homed;
        assert_eq!(refusal(&same_table, true).as_deref(), Some(said));
        // A switch-over that did not finish: the nodes share no link keys (it sent HOME).
        let unfinished = [
            node("VC", 0x11, Standing::Homed),
            Node {
                generation: 2,
                ..node("RC", 0x14, Standing::Homed)
            },
        ];
        let said = "the nodes run different generations: 0x0011 (VC) runs generation 1: push \
                    again to finish the switch-over, or roll back";
        assert_eq!(refusal(&unfinished, false).as_deref(), Some(said));
        // A trial one node confirmed and the others not (a `confirm` it alone heard): one
        // generation, not a split.
        let half_confirmed = [
            on_trial("VC", 0x11),
            Node {
                generation: 2,
                ..node("RC", 0x14, Standing::Homed)
            },
        ];
        assert_eq!(refusal(&half_confirmed, true), None);
        // Another robot's table on one of them: that is said, not a switch-over.
        let mut other = unfinished.clone();
        other[1].standing = Standing::Other;
        assert!(refusal(&other, false)
            .is_some_and(|r| r.starts_with("node 0x0014 (RC) does not run this robot's table")));
        // Unsecured, one role pushed alone at a newer generation runs with the others.
        let unsecured = unfinished.map(|n| Node {
            secured: false,
            ..n
        });
        assert_eq!(refusal(&unsecured, false), None);
    }
}
