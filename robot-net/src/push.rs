//! Pushing tables over the air and talking to nodes: `push` (every role at once, each an
//! OTA transfer of `node_fw::ota`), `scan`, `status` and reliable commands.

use std::collections::BTreeMap;
use std::io;
use std::time::{Duration, Instant};

use config_schema::alarm::AlarmReport;
use config_schema::link_keys;
use config_schema::wire::mac::BROADCAST;
use config_schema::wire::msg::{
    Announce, Command, ConfigReply, Message, Refusal, SecurityReport, Status, SwitchStep,
};
use config_schema::Table;
use node_fw::ota::{Progress, Sender, TransferStats};
use node_fw::switch::{Coordinator, NodeState, Verdict};

use crate::radio::ToolRadio;

/// One table to push.
#[derive(Debug, Clone)]
pub struct Target {
    pub role: String,
    pub addr: u16,
    pub blob: Vec<u8>,
    pub generation: u32,
}

/// How one push ended.
#[derive(Debug, Clone, PartialEq)]
pub struct Pushed {
    pub role: String,
    pub addr: u16,
    /// The transfer: `Done` once the node staged the table.
    pub progress: Progress,
    /// Where the node stands in the switch-over to the staged table (`None`: not
    /// switched, or not asked to).
    pub switch: Option<NodeState>,
    pub stats: TransferStats,
    pub bytes: usize,
    /// Bytes of the link key block sent after the table (0: unsecured).
    pub key_bytes: usize,
    pub elapsed: Duration,
    /// The node ran the pushed table already (it refused the transfer as not newer, and
    /// its status shows this very table: [`running_already`]).
    pub running: bool,
    /// Its last answer in the switch-over said it was not at its idle point (the machine
    /// under way, or stalled there): why a switch-over at the idle point did not come.
    pub not_idle: bool,
}

impl Pushed {
    /// How it ended, in words: `activated`, `staged`, `refused: <the node's reason>`, ...
    pub fn verdict(&self) -> String {
        match (self.progress, self.switch) {
            (Progress::Done, None | Some(NodeState::Switched)) if self.running => {
                "runs this table already".to_string()
            }
            (Progress::Done, Some(NodeState::Switched)) => "activated".to_string(),
            (Progress::Done, None) => "staged".to_string(),
            (Progress::Done, Some(NodeState::Refused(why))) => {
                format!("staged, not switched: refused: {why}")
            }
            (Progress::Done, Some(NodeState::Silent)) => {
                "staged, not switched: the node stopped answering".to_string()
            }
            (Progress::Done, Some(NodeState::Unheard)) => {
                "staged, told to switch, then stopped answering: it runs the old generation \
                 or the new one (scan tells)"
                    .to_string()
            }
            (Progress::Done, Some(NodeState::Going)) => {
                "staged, told to switch: its answer not heard".to_string()
            }
            (Progress::Done, Some(NodeState::Disarmed)) if self.not_idle => {
                "staged, not switched: not at its idle point".to_string()
            }
            (Progress::Done, Some(_)) => "staged, not switched".to_string(),
            (progress, _) => Self::transfer_verdict(progress),
        }
    }

    /// Whether the node runs the pushed table.
    pub fn switched(&self) -> bool {
        self.switch == Some(NodeState::Switched)
    }

    fn transfer_verdict(progress: Progress) -> String {
        match progress {
            Progress::Done => "staged".to_string(),
            Progress::Refused(why) => format!("refused: {why}"),
            Progress::GaveUp => {
                "FAILED: the node stopped answering (is it running, in range?)".into()
            }
            Progress::Busy => "still sending".into(),
        }
    }
}

/// Pushes every target at once; `progress(i, acked, total)` reports each step. Returns when
/// every transfer is done, refused or given up.
pub fn push(
    radio: &mut ToolRadio,
    targets: &[Target],
    force: bool,
    progress: &mut dyn FnMut(usize, usize, usize),
) -> io::Result<Vec<Pushed>> {
    let start = Instant::now();
    let now_ms = || start.elapsed().as_millis() as u64;
    let transfers: Vec<Vec<u8>> = targets.iter().map(|t| transfer(radio, t)).collect();
    let mut senders: Vec<Sender> = transfers
        .iter()
        .zip(targets)
        .map(|(bytes, t)| Sender::new(bytes, t.generation, force))
        .collect();
    let mut finished: Vec<Option<Duration>> = vec![None; targets.len()];
    let mut out: Vec<(u16, Message)> = Vec::new();
    // Challenges answered before this push (a command's) do not count for its transfers.
    radio.take_challengers();
    for (s, t) in senders.iter_mut().zip(targets) {
        s.start(now_ms(), |m| out.push((t.addr, m)));
    }
    loop {
        let sent = !out.is_empty();
        for (dst, m) in out.drain(..) {
            radio.send(dst, &m)?;
        }
        if sent {
            // Every answer waits for the tool's frames to leave the (shared) air.
            let clear = radio
                .air_clear()
                .saturating_duration_since(start)
                .as_millis() as u64;
            for s in &mut senders {
                s.on_air(clear);
            }
        }
        for (i, s) in senders.iter().enumerate() {
            if s.progress() != Progress::Busy && finished[i].is_none() {
                finished[i] = Some(start.elapsed());
            }
        }
        if senders.iter().all(|s| s.progress() != Progress::Busy) {
            break;
        }
        let next = senders
            .iter()
            .filter(|s| s.progress() == Progress::Busy)
            .map(|s| s.deadline())
            .min()
            .unwrap_or(0);
        // The first answer by the earliest deadline, then every answer already here: no
        // timeout is declared while its answer waits to be read (a tool that ran late,
        // descheduled on a busy host, resent to every node whose answer was queued).
        let mut until = (start + Duration::from_millis(next)).max(Instant::now());
        while let Some(r) = radio.recv(until)? {
            if let Some(Message::ConfigReply { generation, reply }) = r.message() {
                for (i, (s, t)) in senders.iter_mut().zip(targets).enumerate() {
                    if t.addr == r.src {
                        s.on_reply(generation, reply, now_ms(), |m| out.push((t.addr, m)));
                        progress(i, s.acked(), transfers[i].len());
                    }
                }
            }
            until = Instant::now();
        }
        for challenger in radio.take_challengers() {
            for (s, t) in senders.iter_mut().zip(targets) {
                if t.addr == challenger {
                    s.challenged();
                }
            }
        }
        let now = now_ms();
        for (s, t) in senders.iter_mut().zip(targets) {
            s.poll(now, |m| out.push((t.addr, m)));
        }
    }
    Ok(senders
        .iter()
        .zip(targets.iter().zip(&transfers))
        .zip(finished)
        .map(|((s, (t, bytes)), f)| Pushed {
            role: t.role.clone(),
            addr: t.addr,
            progress: s.progress(),
            switch: None,
            stats: s.stats(),
            bytes: t.blob.len(),
            key_bytes: bytes.len() - t.blob.len(),
            elapsed: f.unwrap_or_else(|| start.elapsed()),
            running: false,
            not_idle: false,
        })
        .collect())
}

/// The nodes of `pushed` that refused the transfer as not newer than the generation they
/// run, where that is the pushed `generation`, asked their status (at once, within
/// `timeout`): one that runs this very table (its identity is `table_of` its role's at
/// that generation), on trial if and only if the push is (`trial`), counts as staged,
/// [`Pushed::running`]: the switch-over finds it
/// switched already. A push again after a switch-over that did not finish (a node lost on
/// the way: the others run the new generation, it runs the old one with the new one
/// staged) then switches the rest, where every node that had switched refused it.
pub fn running_already<'t>(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    pushed: &mut [Pushed],
    (generation, trial): (u32, bool),
    table_of: impl Fn(&str) -> Option<&'t Table>,
    timeout: Duration,
) -> io::Result<()> {
    let stale = Progress::Refused(Refusal::Stale {
        running: generation,
    });
    let asked: Vec<(usize, &Table)> = (pushed.iter().enumerate())
        .filter(|(_, p)| p.progress == stale)
        .filter_map(|(i, p)| Some((i, table_of(&p.role)?)))
        .collect();
    let addrs: Vec<u16> = (asked.iter())
        .filter_map(|&(i, _)| Some(pushed.get(i)?.addr))
        .collect();
    let statuses = ask_each(radio, ids, &addrs, Command::Status, timeout, status_answer)?;
    // On trial as this push would switch it (a push on trial over nodes that run the
    // generation confirmed, or the other way round, would leave the machine half on
    // trial): else refused as it was.
    let same = |s: &Status| s.generation == generation && s.trial == trial;
    for ((i, table), status) in asked.into_iter().zip(statuses) {
        if status.is_ok_and(|s| same(&s) && crate::home::runs(table, &s)) {
            if let Some(p) = pushed.get_mut(i) {
                p.progress = Progress::Done;
                p.running = true;
            }
        }
    }
    Ok(())
}

/// What goes over the air for `t`: its blob, then, when the radio is secured, the node's
/// link key block for the table's peers (`config_schema::link_keys`), inside the secured
/// transfer. A blob that does not decode goes alone (the node refuses it anyway).
fn transfer(radio: &ToolRadio, t: &Target) -> Vec<u8> {
    let mut bytes = t.blob.clone();
    let keys = config_schema::decode(&t.blob)
        .ok()
        .and_then(|table| radio.link_keys(table.generation, t.addr, &table.peers));
    if let Some(keys) = keys {
        let mut block = [0u8; link_keys::MAX_LEN];
        if let Some(n) = keys.encode(&mut block) {
            bytes.extend_from_slice(&block[..n]);
        }
    }
    bytes
}

/// How long a switch-over waits, by default, for the machine to be idle at once (the
/// cycle in progress to end).
pub const SWITCH_WAIT: Duration = Duration::from_secs(60);

/// Switches every node of `pushed` over to the table it staged, together
/// (`node_fw::switch::Coordinator`): at the machine's next idle point within `wait`, or
/// (`now`) at once. Fills in each one's `switch`; returns the verdict. Only if every one
/// staged it: otherwise nothing is armed or switched ([`Verdict::Aborted`]), the staged
/// tables stay staged, and the machine runs on its old generation, whole.
pub fn switch_over(
    radio: &mut ToolRadio,
    pushed: &mut [Pushed],
    generation: u32,
    now: bool,
    wait: Duration,
) -> io::Result<Verdict> {
    switch_over_as(radio, pushed, generation, now, false, wait)
}

/// [`switch_over`]; `trial`: activated on trial, not confirmed (a power cut or a
/// [`rollback`] returns to the previous generation; [`confirm`] keeps it).
pub fn switch_over_as(
    radio: &mut ToolRadio,
    pushed: &mut [Pushed],
    generation: u32,
    now: bool,
    trial: bool,
    wait: Duration,
) -> io::Result<Verdict> {
    if pushed.is_empty() || pushed.iter().any(|p| p.progress != Progress::Done) {
        return Ok(Verdict::Aborted);
    }
    let nodes: Vec<u16> = pushed.iter().map(|p| p.addr).collect();
    let mut c = Coordinator::new(&nodes, generation, now, millis(wait), 0);
    if trial {
        c = c.on_trial();
    }
    let mut not_idle = Vec::new();
    let (verdict, states) = coordinate(radio, c, &mut not_idle);
    // Where each node stands, also when the medium was lost on the way.
    for (addr, state) in states {
        for p in pushed.iter_mut().filter(|p| p.addr == addr) {
            p.switch = Some(state);
            p.not_idle = not_idle.contains(&addr);
        }
    }
    verdict
}

/// Runs a coordinator to its end: the verdict (or how the medium was lost) and where
/// each node stands (then, as far as the tool heard); `not_idle` gets the nodes whose
/// last `Armed` answer said they were not at their idle point.
fn coordinate(
    radio: &mut ToolRadio,
    mut c: Coordinator,
    not_idle: &mut Vec<u16>,
) -> (io::Result<Verdict>, Vec<(u16, NodeState)>) {
    let verdict = run_coordinator(radio, &mut c, not_idle);
    (verdict, c.nodes().collect())
}

/// `wait` in whole milliseconds, the longest a `u64` holds if longer (it was cut to its
/// low 64 bits: a wait of 2^64 ms + 384 ms was 384 ms).
fn millis(wait: Duration) -> u64 {
    u64::try_from(wait.as_millis()).unwrap_or(u64::MAX)
}

fn run_coordinator(
    radio: &mut ToolRadio,
    c: &mut Coordinator,
    not_idle: &mut Vec<u16>,
) -> io::Result<Verdict> {
    let start = Instant::now();
    let now_ms = || start.elapsed().as_millis() as u64;
    let mut out: Vec<(u16, Message<'static>)> = Vec::new();
    while c.verdict() == Verdict::Busy {
        c.poll(now_ms(), |a, m| out.push((a, m)));
        for (dst, m) in out.drain(..) {
            radio.send(dst, &m)?;
        }
        // The first answer by the deadline, then every answer already here, before the
        // coordinator's next poll can declare a timeout (as `push` does).
        // A deadline past what an `Instant` holds (a wait of ages): a second's sleep.
        let deadline = start.checked_add(Duration::from_millis(c.deadline()));
        let mut until = deadline
            .unwrap_or_else(|| Instant::now() + Duration::from_secs(1))
            .max(Instant::now());
        while let Some(r) = radio.recv(until)? {
            if let Some(Message::ConfigReply { generation, reply }) = r.message() {
                if let ConfigReply::Armed { idle, .. } = reply {
                    not_idle.retain(|&a| a != r.src);
                    if !idle {
                        not_idle.push(r.src);
                    }
                }
                c.on_reply(r.src, generation, reply, now_ms(), |a, m| out.push((a, m)));
            }
            until = Instant::now();
        }
    }
    Ok(c.verdict())
}

/// Returns every node of `nodes` to its previous generation `generation` together, at the
/// machine's next idle point within `wait` (or `now`): a rollback. Where each ended.
pub fn rollback(
    radio: &mut ToolRadio,
    nodes: &[u16],
    generation: u32,
    now: bool,
    wait: Duration,
) -> io::Result<(Verdict, Vec<(u16, NodeState)>)> {
    let c = Coordinator::new(nodes, generation, now, millis(wait), 0);
    let (verdict, states) = coordinate(radio, c, &mut Vec::new());
    Ok((verdict?, states))
}

/// Where one node stands after a rollback, in words (`rolled back`, or why not).
pub fn rollback_state_text(state: Option<NodeState>) -> String {
    match state {
        Some(NodeState::Switched) => "rolled back".into(),
        Some(NodeState::Going) => "told to roll back: its answer not heard".into(),
        Some(NodeState::Refused(why)) => format!("NOT rolled back: refused: {why}"),
        Some(NodeState::Silent) => "NOT rolled back: the node stopped answering".into(),
        Some(NodeState::Unheard) => {
            "told to roll back, then stopped answering: on either generation (scan tells)".into()
        }
        Some(NodeState::Arming | NodeState::Armed { .. } | NodeState::Disarmed) => {
            "NOT rolled back: on the new generation still".into()
        }
        None => "NOT rolled back: not asked".into(),
    }
}

/// Why a rollback did not finish, in words, with what to do (`None`: it did).
pub fn rollback_verdict_text(verdict: Verdict) -> Option<String> {
    Some(match verdict {
        Verdict::Switched => return None,
        Verdict::NotIdle => "the machine did not come to rest within --wait: nothing rolled \
                             back (every node stays on the new generation); rollback again \
                             once it rests, or rollback --now for a machine stopped away from \
                             its idle point (a fault, a stall)"
            .into(),
        Verdict::Aborted => "a node refused or stopped answering before the rollback: \
                             nothing rolled back (every node stays on the new generation)"
            .into(),
        Verdict::Partial | Verdict::Busy => "the rollback did not finish: the nodes marked \
                                             NOT rolled back run the new generation; \
                                             rollback again to finish it (or --now)"
            .into(),
    })
}

/// How a watched trial ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TrialEnd {
    /// Every node's generation was confirmed (`config-tool confirm`) within the window.
    Confirmed,
    /// A node faulted during the trial: every node was rolled back at once.
    Faulted { node: u16, rolled_back: Verdict },
    /// Not confirmed within the window: every node was rolled back at its idle point.
    Expired { rolled_back: Verdict },
    /// A node runs the previous generation again during the trial (a power cut: its
    /// trial slot revoked at boot; or a `rollback` of another run of the tool), `node` the
    /// first seen: the others were rolled back at their idle point, so the machine runs
    /// one generation (nothing was confirmed after it).
    Reverted { node: u16, rolled_back: Verdict },
    /// A node runs a generation newer than the trial's (another run of the tool pushed
    /// it): the watch ends, nothing rolled back or confirmed by it.
    Superseded { node: u16, generation: u32 },
}

/// How long a trial is watched: a time, a number of cycles, or whichever ends first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TrialWindow {
    pub time: Option<Duration>,
    /// Cycles the machine completes on the trial generation (counted by the nodes'
    /// `Status::cycles`: a START at the idle point, the node back at it).
    pub cycles: Option<u32>,
}

/// Cycles counted by `nodes` since the watch began, from their one-byte, wrapping
/// counters (read at least every 255 cycles: twice a second is plenty).
#[derive(Debug, Default)]
struct CycleCount {
    last: Vec<(u16, u8)>,
    done: u32,
}

impl CycleCount {
    fn saw(&mut self, node: u16, count: u8) {
        match self.last.iter_mut().find(|(n, _)| *n == node) {
            Some((_, last)) => {
                self.done = self
                    .done
                    .saturating_add(u32::from(count.wrapping_sub(*last)));
                *last = count;
            }
            None => self.last.push((node, count)),
        }
    }
}

/// [`watch_trial`] for a window in time and / or cycles: it ends (unconfirmed: rolled
/// back at the idle point) when the first of them is over; with neither, only a confirm or
/// a fault ends it.
#[allow(clippy::too_many_arguments)]
pub fn watch_trial_for(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    (nodes, previous): (&[u16], u32),
    window: TrialWindow,
    (every, wait): (Duration, Duration),
    confirm_asked: &dyn Fn() -> bool,
) -> io::Result<TrialEnd> {
    // A window past what an `Instant` holds has no end.
    let end = window.time.and_then(|t| Instant::now().checked_add(t));
    let mut cycles = CycleCount::default();
    let mut confirmed_once = false;
    // The trial's generation, once a node was seen on it.
    let mut watched: Option<u32> = None;
    loop {
        // Every node's status: a fault rolls every node back at once; a node that runs
        // the previous generation (it lost power: the trial slot is revoked at boot) ends
        // the trial; the trial is over when every node runs a newer one, confirmed.
        let mut confirmed = true;
        let mut trial = None;
        for &node in nodes {
            let Some(s) = command(radio, ids, node, Command::Status, every.max(RETRY_FLOOR))?
            else {
                confirmed = false;
                continue;
            };
            if s.fault.is_some() {
                let (rolled_back, _) = rollback(radio, nodes, previous, true, wait)?;
                return Ok(TrialEnd::Faulted { node, rolled_back });
            }
            if s.generation == previous && !s.trial {
                let (rolled_back, _) = rollback(radio, nodes, previous, false, wait)?;
                return Ok(TrialEnd::Reverted { node, rolled_back });
            }
            if watched.is_some_and(|w| s.generation > w) {
                let generation = s.generation;
                return Ok(TrialEnd::Superseded { node, generation });
            }
            cycles.saw(node, s.cycles);
            if s.trial {
                trial = Some(s.generation);
                watched = watched.max(Some(s.generation));
            }
            confirmed &= !s.trial;
        }
        if confirmed {
            return Ok(TrialEnd::Confirmed);
        }
        // Confirmed by whoever runs the watch (or by a `confirm` of another run: then no
        // node is on trial any more), only after a round in which every node ran the
        // trial: then the next round sees how it went.
        if let (false, Some(generation), true) = (confirmed_once, trial, confirm_asked()) {
            confirm(radio, nodes, generation, wait)?;
            confirmed_once = true;
            continue;
        }
        let timed_out = end.is_some_and(|e| Instant::now() >= e);
        let cycled = window.cycles.is_some_and(|n| cycles.done >= n);
        if timed_out || cycled {
            let (rolled_back, _) = rollback(radio, nodes, previous, false, wait)?;
            return Ok(TrialEnd::Expired { rolled_back });
        }
        let next = Instant::now() + every;
        let until = end.map_or(next, |e| next.min(e));
        // Whatever comes meanwhile (late answers) is not for the watch.
        while radio.recv(until)?.is_some() {}
    }
}

/// Watches a trial of `nodes` (rolled back to `previous` if it fails) for `window`:
/// every `every`, each node's status; a fault rolls every node back at once, a window
/// that ends unconfirmed rolls them back at the machine's idle point (within `wait`).
/// Supervised by the tool: a tool that dies leaves the trial to `confirm`, `rollback` or
/// a power cut.
pub fn watch_trial(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    nodes: &[u16],
    previous: u32,
    window: Duration,
    every: Duration,
    wait: Duration,
) -> io::Result<TrialEnd> {
    let window = TrialWindow {
        time: Some(window),
        cycles: None,
    };
    watch_trial_for(
        radio,
        ids,
        (nodes, previous),
        window,
        (every, wait),
        &|| false,
    )
}

/// The least time a status is asked for before a watched node counts as not answering.
const RETRY_FLOOR: Duration = Duration::from_millis(500);

/// Confirms generation `generation` (on trial) on every node of `nodes`, resending until
/// each answers; each node's last answer (`None`: it never answered).
pub fn confirm(
    radio: &mut ToolRadio,
    nodes: &[u16],
    generation: u32,
    timeout: Duration,
) -> io::Result<Vec<(u16, Option<ConfigReply>)>> {
    let mut answers: Vec<(u16, Option<ConfigReply>)> = nodes.iter().map(|&n| (n, None)).collect();
    let end = crate::deadline(Instant::now(), timeout);
    let step = Message::Switch {
        generation,
        step: SwitchStep::Confirm,
    };
    // A confirmation's own answers: `Confirmed`, or refused. Anything else of the
    // generation (`Busy` at its flash, a late `Activated` or `Armed` of the switch-over
    // before) is not its answer: asked again.
    let done = |a: &Option<ConfigReply>| {
        matches!(a, Some(ConfigReply::Confirmed | ConfigReply::Refused(_)))
    };
    while Instant::now() < end && answers.iter().any(|a| !done(&a.1)) {
        for (n, a) in &answers {
            if !done(a) {
                radio.send(*n, &step)?;
            }
        }
        let until = (Instant::now() + Duration::from_millis(150)).min(end);
        while let Some(r) = radio.recv(until)? {
            if let Some(Message::ConfigReply {
                generation: g,
                reply,
            }) = r.message()
            {
                if let Some(a) = answers.iter_mut().find(|a| a.0 == r.src && g == generation) {
                    // A final answer stays (a late copy of anything else is not this one's).
                    if !done(&a.1) {
                        a.1 = Some(reply);
                    }
                }
            }
        }
    }
    Ok(answers)
}

/// Command ids: start somewhere new at random in every run, then count up. A node runs
/// each (sender, id) of a command that acts once (it remembers the last eight, whichever
/// run of the tool sent them, until 30 s pass without one: `node_fw::node::
/// RECENT_COMMANDS`, `REPEAT_MS`) and answers a repeat without running it. Random, an id
/// is not known before it is sent (it is encrypted on a secured radio), so an answer
/// recorded earlier cannot be made to answer it; the price: among runs at once, a command
/// that acts meets one of the last eight another run sent about once in 8,000. (Drawn from
/// the shared frame counter instead, the first command of every 32nd run drew the same
/// id: each run starts at a fresh reservation of 1024, and the header carries the counter
/// in clear.)
pub struct Ids(u16);

impl Default for Ids {
    fn default() -> Self {
        Ids(rand::random())
    }
}

impl Ids {
    /// The next id; never 0, which an unprompted `Announce` carries.
    pub fn fresh(&mut self) -> u16 {
        self.0 = self.0.wrapping_add(1).max(1);
        self.0
    }
}

/// A fresh random nonce for an `Identify` (never 0, which an unprompted `Announce`
/// carries): its answers, and no earlier ones, carry it back.
pub fn identify_nonce() -> u64 {
    rand::random::<u64>().max(1)
}

/// Sends `command` to `addr` until its status comes back acknowledging it (every
/// `retry`, at most until `timeout`). A repeat never runs twice on the node.
pub fn command(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    addr: u16,
    command: Command,
    timeout: Duration,
) -> io::Result<Option<Status>> {
    ask(radio, ids, addr, command, timeout, status_answer)
}

/// `m` as the status that answers command `id` (a command's answer, for [`ask`]).
pub fn status_answer(m: Message<'_>, id: u16) -> Option<Status> {
    match m {
        Message::Status(s) if s.ack == id => Some(s),
        _ => None,
    }
}

/// `m` as the security report that answers command `id` (`Security`, for [`ask`]).
pub fn security_answer(m: Message<'_>, id: u16) -> Option<SecurityReport> {
    match m {
        Message::Security(r) if r.ack == id => Some(r),
        _ => None,
    }
}

/// `m` as the alarm report that answers command `id` (`Alarms` and `Ack`, for [`ask`]).
pub fn alarms_answer(m: Message<'_>, id: u16) -> Option<AlarmReport> {
    match m {
        Message::Alarms(a) if a.ack == id => Some(a),
        _ => None,
    }
}

/// Sends `command` to node `addr` (again every 150 ms) until `pick` takes an answer of
/// that node (given the command's id), at most `timeout`.
pub fn ask<T>(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    addr: u16,
    command: Command,
    timeout: Duration,
    pick: impl Fn(Message<'_>, u16) -> Option<T>,
) -> io::Result<Option<T>> {
    let id = ids.fresh();
    let end = crate::deadline(Instant::now(), timeout);
    let retry = Duration::from_millis(150);
    while Instant::now() < end {
        radio.send(addr, &Message::Command { id, command })?;
        let until = (Instant::now() + retry).min(end);
        while let Some(r) = radio.recv(until)? {
            if r.src != addr {
                continue;
            }
            if let Some(t) = r.message().and_then(|m| pick(m, id)) {
                return Ok(Some(t));
            }
        }
    }
    Ok(None)
}

/// [`ask`] of several nodes at once: `command` goes to each of `addrs` (each its own id,
/// again every 150 ms to those that have not answered) until `pick` took an answer of
/// every one, at most `timeout`. A round costs one round trip however many nodes it asks,
/// where asking one after the other cost one each (and a lost frame a 150 ms wait each).
/// Per node, in the order of `addrs`: its answer, or how many times it was asked.
pub fn ask_each<T>(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    addrs: &[u16],
    command: Command,
    timeout: Duration,
    pick: impl Fn(Message<'_>, u16) -> Option<T>,
) -> io::Result<Vec<Result<T, u32>>> {
    let mut asked: Vec<(u16, u16, Result<T, u32>)> =
        (addrs.iter()).map(|&a| (a, ids.fresh(), Err(0))).collect();
    let end = crate::deadline(Instant::now(), timeout);
    let retry = Duration::from_millis(150);
    while Instant::now() < end && asked.iter().any(|a| a.2.is_err()) {
        for (addr, id, answer) in &mut asked {
            if let Err(times) = answer {
                radio.send(*addr, &Message::Command { id: *id, command })?;
                *times += 1;
            }
        }
        let until = (Instant::now() + retry).min(end);
        while let Some(r) = radio.recv(until)? {
            let waiting = (asked.iter_mut()).filter(|a| a.0 == r.src && a.2.is_err());
            for (_, id, answer) in waiting {
                if let Some(t) = r.message().and_then(|m| pick(m, *id)) {
                    *answer = Ok(t);
                    break;
                }
            }
            if asked.iter().all(|a| a.2.is_ok()) {
                break;
            }
        }
    }
    Ok(asked.into_iter().map(|a| a.2).collect())
}

/// The status of each node of `addrs`, all asked at once ([`ask_each`], within `timeout`):
/// per address, in order, its status or how many times it was asked without one.
pub fn statuses_of(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    addrs: &[u16],
    timeout: Duration,
) -> io::Result<Vec<Result<Status, u32>>> {
    ask_each(radio, ids, addrs, Command::Status, timeout, status_answer)
}

/// The nodes in range: asks every node to identify itself and collects the announcements
/// that answer this ask, for `wait`. An unprompted one (an unconfigured node's periodic
/// announcement) or one answering another ask is not taken: a recorded announcement,
/// replayed, would stand in for a node that is gone (frame security proves who sent it,
/// not when; only the ask's nonce does, a fresh random 64-bit one: [`identify_nonce`]).
pub fn scan(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    wait: Duration,
) -> io::Result<BTreeMap<u16, Announce>> {
    let mut found = BTreeMap::new();
    let (id, nonce) = (ids.fresh(), identify_nonce());
    let end = crate::deadline(Instant::now(), wait);
    let mut next_ask = Instant::now();
    while Instant::now() < end {
        if Instant::now() >= next_ask {
            radio.send(
                BROADCAST,
                &Message::Command {
                    id,
                    command: Command::Identify { nonce },
                },
            )?;
            next_ask = Instant::now() + Duration::from_millis(300);
        }
        if let Some(r) = radio.recv(next_ask.min(end))? {
            if let Some(Message::Announce(a)) = r.message() {
                if a.nonce == nonce {
                    found.insert(r.src, a);
                }
            }
        }
    }
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::{rollback_state_text, rollback_verdict_text, CycleCount};
    use config_schema::wire::msg::Refusal;
    use node_fw::switch::{NodeState, Verdict};

    /// Each node's line of a rollback, in words (it printed `NOT rolled back:
    /// Some(Disarmed)`).
    #[test]
    fn a_rollbacks_node_lines_say_where_each_node_stands_in_words() {
        let said = [
            (Some(NodeState::Switched), "rolled back"),
            (
                Some(NodeState::Going),
                "told to roll back: its answer not heard",
            ),
            (
                Some(NodeState::Disarmed),
                "NOT rolled back: on the new generation still",
            ),
            (
                Some(NodeState::Armed { idle: false, at: 3 }),
                "NOT rolled back: on the new generation still",
            ),
            (
                Some(NodeState::Silent),
                "NOT rolled back: the node stopped answering",
            ),
            (
                Some(NodeState::Unheard),
                "told to roll back, then stopped answering: on either generation (scan tells)",
            ),
            (
                Some(NodeState::Refused(Refusal::NotStaged { staged: 0 })),
                "NOT rolled back: refused: no generation is staged",
            ),
            (None, "NOT rolled back: not asked"),
        ];
        for (state, text) in said {
            assert_eq!(rollback_state_text(state), text, "{state:?}");
        }
    }

    /// How a rollback that did not finish ended, in words, with what to do (it printed
    /// `the rollback did not finish: NotIdle`).
    #[test]
    fn a_rollback_that_did_not_finish_says_why_and_what_to_do() {
        assert_eq!(rollback_verdict_text(Verdict::Switched), None);
        assert_eq!(
            rollback_verdict_text(Verdict::NotIdle).as_deref(),
            Some(
                "the machine did not come to rest within --wait: nothing rolled back (every \
                 node stays on the new generation); rollback again once it rests, or \
                 rollback --now for a machine stopped away from its idle point (a fault, a \
                 stall)"
            )
        );
        assert_eq!(
            rollback_verdict_text(Verdict::Aborted).as_deref(),
            Some(
                "a node refused or stopped answering before the rollback: nothing rolled \
                 back (every node stays on the new generation)"
            )
        );
        for v in [Verdict::Partial, Verdict::Busy] {
            assert_eq!(
                rollback_verdict_text(v).as_deref(),
                Some(
                    "the rollback did not finish: the nodes marked NOT rolled back run the \
                     new generation; rollback again to finish it (or --now)"
                )
            );
        }
    }

    /// The nodes count cycles in one wrapping byte: the watch adds the differences.
    #[test]
    fn cycles_are_counted_across_the_counters_wrap() {
        let mut c = CycleCount::default();
        c.saw(0x11, 250);
        c.saw(0x12, 0);
        assert_eq!(c.done, 0, "the first reading is the baseline");
        c.saw(0x11, 252);
        c.saw(0x11, 3);
        c.saw(0x12, 1);
        assert_eq!(c.done, 10);
    }
}
