//! The node's part of the two-phase switch-over (docs/reconfiguration.md): a pushed table is
//! staged (persisted, not running); the tool arms every node (each holds any START from
//! then on and says whether it is idle), waits until all are idle at once, and tells each
//! to go. A node switches only when armed and idle, or on an explicit `now`.
//!
//! The same steps return to the previous generation (a rollback: its slot is kept until
//! the next stage overwrites it), and a switch may be a **trial**: activated but not
//! confirmed, so a power cut boots the previous generation again until `Confirm`.
//!
//! Pure state: the node asks [`SwitchOver::step`] what to do with a `Switch` message and
//! tells it what happened; time comes in as milliseconds.

use config_schema::limits::MAX_ROLES;
use config_schema::wire::msg::{ConfigReply, Message, Refusal, SwitchStep};

/// An armed node that hears nothing more from the tool for this long disarms (and runs a
/// START it held): a tool that died does not leave the machine refusing to start.
pub const ARM_HOLD_MS: u64 = 30_000;

/// Where the node's switch-over stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SwitchOver {
    /// The generation staged in flash (0: none).
    staged: u32,
    /// The previous generation, kept in the other slot for a rollback (0: none).
    previous: u32,
    /// The running generation is on trial (activated, not confirmed).
    trial: bool,
    /// Armed for the staged generation until this time.
    armed_until: Option<u64>,
    /// A START came while armed: it runs after the switch (or on disarm).
    held_start: bool,
    /// A switch in progress (the board activates the slot): who asked, and what.
    activating: Option<(u16, Target)>,
    /// A confirmation in progress: who asked.
    confirming: Option<u16>,
}

/// What a switch switches to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// The staged table; `trial`: not confirmed yet.
    Staged { trial: bool },
    /// The previous table (a rollback: the running one is revoked).
    Previous,
}

/// What the node does with a `Switch` message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// Answer this.
    Reply(ConfigReply),
    /// Activate the target's table (the board reads it from flash), then answer
    /// `Activated`.
    Activate(Target),
    /// Confirm the running table (on trial) in flash, then answer `Confirmed`.
    Confirm,
    /// Disarmed: answer `Disarmed`, and run the held START if there was one.
    Disarmed { start: bool },
}

impl SwitchOver {
    /// The generation staged (0: none).
    pub fn staged(&self) -> u32 {
        self.staged
    }

    /// A table of `generation` was staged (0: the staged one is gone). It went to the slot
    /// of the previous generation, which is gone then.
    pub fn set_staged(&mut self, generation: u32) {
        if generation != self.staged {
            self.armed_until = None;
        }
        if generation != 0 {
            self.previous = 0;
        }
        self.staged = generation;
    }

    /// The node booted with `generation` in its other slot, confirmed (0: none).
    pub fn set_previous(&mut self, generation: u32) {
        self.previous = generation;
    }

    /// The previous generation a rollback returns to (0: none).
    pub fn previous(&self) -> u32 {
        self.previous
    }

    /// Whether the running generation is on trial.
    pub fn trial(&self) -> bool {
        self.trial
    }

    /// Whether START is held.
    pub fn armed(&self) -> bool {
        self.armed_until.is_some()
    }

    /// When an armed node disarms by itself.
    pub fn deadline(&self) -> Option<u64> {
        self.armed_until
    }

    /// A START while armed is held; returns whether it was.
    pub fn hold_start(&mut self) -> bool {
        if self.armed() {
            self.held_start = true;
        }
        self.armed()
    }

    /// The activation in progress, if one is: who asked, and what.
    pub fn activating(&self) -> Option<(u16, Target)> {
        self.activating
    }

    /// Who asked for the confirmation in progress, if one is.
    pub fn confirming(&self) -> Option<u16> {
        self.confirming
    }

    /// A `Switch { generation, step }` from `from`, with the running generation `running`
    /// and whether the node is idle.
    pub fn step(
        &mut self,
        generation: u32,
        step: SwitchStep,
        from: u16,
        running: u32,
        idle: bool,
        now: u64,
    ) -> Action {
        if self.activating.is_some() || self.confirming.is_some() {
            // The board is at its flash: the answer comes when it is done.
            return Action::Reply(ConfigReply::Busy);
        }
        if step == SwitchStep::Disarm {
            return self.disarm();
        }
        if step == SwitchStep::Confirm {
            if generation != running || running == 0 {
                return Action::Reply(ConfigReply::Refused(Refusal::NotStaged {
                    staged: self.staged,
                }));
            }
            if !self.trial {
                return Action::Reply(ConfigReply::Confirmed);
            }
            self.confirming = Some(from);
            return Action::Confirm;
        }
        if generation == running && running != 0 && self.staged != generation {
            // Switched already (the answer was lost).
            return Action::Reply(ConfigReply::Activated);
        }
        let rollback = generation == self.previous && self.previous != 0;
        if (self.staged != generation && !rollback) || generation == 0 {
            return Action::Reply(ConfigReply::Refused(Refusal::NotStaged {
                staged: self.staged,
            }));
        }
        match step {
            SwitchStep::Arm { ask } => {
                self.armed_until = Some(now + ARM_HOLD_MS);
                Action::Reply(ConfigReply::Armed { idle, ask })
            }
            SwitchStep::Go {
                now: at_once,
                trial,
            } => {
                if at_once || (self.armed() && idle) {
                    let target = if rollback {
                        Target::Previous
                    } else {
                        Target::Staged { trial }
                    };
                    self.activating = Some((from, target));
                    Action::Activate(target)
                } else {
                    Action::Reply(ConfigReply::Busy)
                }
            }
            SwitchStep::Disarm | SwitchStep::Confirm => self.disarm(),
        }
    }

    /// The board confirmed the running table (`ok`) or failed to: who asked.
    pub fn confirmed(&mut self, ok: bool) -> Option<u16> {
        if ok {
            self.trial = false;
        }
        self.confirming.take()
    }

    fn disarm(&mut self) -> Action {
        let start = self.armed() && self.held_start;
        self.armed_until = None;
        self.held_start = false;
        Action::Disarmed { start }
    }

    /// The board activated the target (`ok`) or failed to, `running` being the generation
    /// that ran until then: who asked, and whether a held START is to run now (on the new
    /// table).
    pub fn activated(&mut self, ok: bool, running: u32) -> (Option<u16>, bool) {
        let asked = self.activating.take();
        let start = ok && self.held_start;
        if ok {
            match asked.map(|(_, t)| t) {
                Some(Target::Staged { trial }) => {
                    // The old table stays in its slot: the rollback target (a trial's is
                    // not confirmed, so it is no target).
                    self.previous = if self.trial { self.previous } else { running };
                    self.staged = 0;
                    self.trial = trial;
                }
                Some(Target::Previous) => {
                    // The rolled-back table is revoked: nothing to return to.
                    self.previous = 0;
                    self.trial = false;
                }
                None => {}
            }
            self.armed_until = None;
            self.held_start = false;
        }
        (asked.map(|(from, _)| from), start)
    }

    /// Time passed: an armed node left alone too long disarms. Returns whether to run a
    /// held START.
    pub fn poll(&mut self, now: u64) -> bool {
        match self.armed_until {
            Some(until)
                if now >= until && self.activating.is_none() && self.confirming.is_none() =>
            {
                matches!(self.disarm(), Action::Disarmed { start: true })
            }
            _ => false,
        }
    }
}

/// The tool resends a switch step to a node that has not answered after this long.
pub const RETRY_MS: u64 = 150;
/// Resends without any answer before the tool gives a node up.
pub const GIVE_UP_AFTER: u8 = 40;

/// Where one node stands in the tool's switch-over.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeState {
    /// Not armed yet (or to be armed again: it rebooted).
    Arming,
    /// Armed; `idle` as of its answer, the `at`-th answer the tool took.
    Armed { idle: bool, at: u32 },
    /// Told to go; waiting for `Activated`.
    Going,
    /// Runs the new generation.
    Switched,
    /// Refused (it has not staged this generation, or its flash failed).
    Refused(Refusal),
    /// Stopped answering before it was told to go: it runs the old generation.
    Silent,
    /// Told to go, then never heard from again: it may have switched (persisted the new
    /// table, then lost its power before its answer), or not.
    Unheard,
    /// Disarmed after the switch-over was called off.
    Disarmed,
}

/// How the tool's switch-over ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Still at it.
    Busy,
    /// Every node switched.
    Switched,
    /// The machine was not idle at once within the wait: every node disarmed, nothing
    /// switched.
    NotIdle,
    /// A node refused or stopped answering before anything switched: every node
    /// disarmed, nothing switched.
    Aborted,
    /// Some nodes switched and some did not answer any more, or were not idle when told
    /// to go and did not become idle again within the wait (those are disarmed): the
    /// machine is mixed (the tool says which; run again, or `--now`).
    Partial,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Arming every node.
    Arming,
    /// Every node armed by the `since`-th answer: waiting for an answer from each, after
    /// it, that says idle.
    Waiting {
        since: u32,
    },
    /// Telling every node to go.
    Going,
    /// Calling it off: disarming.
    Disarming,
    Done,
}

/// The tool's side of the switch-over of one machine: arm every node, wait until each says
/// idle after all were armed, then tell each to go, resending until each confirms.
#[derive(Debug, Clone)]
pub struct Coordinator {
    generation: u32,
    now: bool,
    /// Switch as a trial (`Go { trial }`).
    trial: bool,
    /// Until when the machine may take to become idle.
    wait_until: u64,
    /// How long it may take: to become idle, and again to switch once told to go.
    wait_ms: u64,
    /// Until when the nodes told to go may take to switch (a node no longer idle when its
    /// `Go` comes is armed and told again until then).
    go_until: u64,
    phase: Phase,
    verdict: Verdict,
    /// Answers taken so far (orders them).
    answers: u32,
    nodes: heapless::Vec<Peer, MAX_ROLES>,
}

/// One node of the switch-over, as the tool follows it.
#[derive(Debug, Clone, Copy)]
struct Peer {
    addr: u16,
    state: NodeState,
    /// Sends of the step due without an answer.
    tries: u8,
    /// When the step is sent (again).
    due: u64,
    /// The last `Arm` it was sent and the last whose answer was taken
    /// (`SwitchStep::Arm::ask`). An answer is taken only if it answers an ask newer than
    /// that one: a late or duplicated answer to an earlier ask (say idle before the
    /// machine moved again) is not.
    asked: u16,
    answered: u16,
}

impl Peer {
    /// The step due is sent at `now_ms`, its tries counted afresh.
    fn ask_at(&mut self, now_ms: u64) {
        self.tries = 0;
        self.due = now_ms;
    }

    /// Whether an `Armed` answering ask `ask` is taken (and if so, it is the last taken).
    fn takes_answer_to(&mut self, ask: u16) -> bool {
        let newer = ask.wrapping_sub(self.answered) as i16 > 0;
        let sent = self.asked.wrapping_sub(ask) as i16 >= 0;
        if newer && sent {
            self.answered = ask;
        }
        newer && sent
    }
}

impl Coordinator {
    /// A switch-over of `nodes` to `generation`: at the machine's next idle point within
    /// `wait_ms`, or (`now`) at once whatever the machine does. At most [`MAX_ROLES`]
    /// nodes: more is `Aborted` at once, nothing sent (none left out of a switch-over
    /// that moves the others).
    pub fn new(nodes: &[u16], generation: u32, now: bool, wait_ms: u64, start: u64) -> Self {
        let mut c = Coordinator {
            generation,
            now,
            trial: false,
            wait_until: start.saturating_add(wait_ms),
            wait_ms,
            go_until: start.saturating_add(wait_ms),
            phase: if now { Phase::Going } else { Phase::Arming },
            verdict: Verdict::Busy,
            answers: 0,
            nodes: heapless::Vec::new(),
        };
        let state = if now {
            NodeState::Going
        } else {
            NodeState::Arming
        };
        for &addr in nodes {
            let peer = Peer {
                addr,
                state,
                tries: 0,
                due: start,
                asked: 0,
                answered: 0,
            };
            if c.nodes.push(peer).is_err() {
                c.nodes.clear();
                c.verdict = Verdict::Aborted;
                c.phase = Phase::Done;
                break;
            }
        }
        c
    }

    /// The switch as a trial: activated, not confirmed (a power cut, or a rollback,
    /// returns to the previous generation).
    pub fn on_trial(mut self) -> Self {
        self.trial = true;
        self
    }

    /// How it ended (`Busy` until every node has its last answer: a call-off is over when
    /// every node disarmed).
    pub fn verdict(&self) -> Verdict {
        if self.phase == Phase::Done {
            self.verdict
        } else {
            Verdict::Busy
        }
    }

    /// Every node and where it stands.
    pub fn nodes(&self) -> impl Iterator<Item = (u16, NodeState)> + '_ {
        self.nodes.iter().map(|n| (n.addr, n.state))
    }

    /// When [`Coordinator::poll`] next has work.
    pub fn deadline(&self) -> u64 {
        let limit = if self.phase == Phase::Going {
            self.go_until
        } else {
            self.wait_until
        };
        self.nodes
            .iter()
            .filter(|n| self.waits_for(n.state))
            .map(|n| n.due)
            .min()
            .unwrap_or(limit)
            .min(limit)
    }

    fn waits_for(&self, s: NodeState) -> bool {
        match self.phase {
            Phase::Arming => s == NodeState::Arming,
            Phase::Waiting { since } => {
                !matches!(
                    s,
                    NodeState::Armed { idle: true, at } if at > since
                ) && s != NodeState::Switched
            }
            Phase::Going => matches!(
                s,
                NodeState::Going | NodeState::Arming | NodeState::Armed { .. }
            ),
            Phase::Disarming => !matches!(
                s,
                NodeState::Disarmed
                    | NodeState::Switched
                    | NodeState::Silent
                    | NodeState::Unheard
                    | NodeState::Refused(_)
            ),
            Phase::Done => false,
        }
    }

    fn step_for(&self, s: NodeState) -> SwitchStep {
        match (self.phase, s) {
            (Phase::Disarming, _) => SwitchStep::Disarm,
            // A node that lost its arming (it rebooted) is armed again before it goes.
            (Phase::Going, NodeState::Arming) if !self.now => SwitchStep::Arm { ask: 0 },
            (Phase::Going, _) => SwitchStep::Go {
                now: self.now,
                trial: self.trial,
            },
            _ => SwitchStep::Arm { ask: 0 },
        }
    }

    /// Sends what is due at `now_ms` (`send(node, step)`), and moves on.
    pub fn poll(&mut self, now_ms: u64, mut send: impl FnMut(u16, Message<'static>)) {
        self.poll_dyn(now_ms, &mut send)
    }

    fn poll_dyn(&mut self, now_ms: u64, send: &mut dyn FnMut(u16, Message<'static>)) {
        if self.phase == Phase::Done {
            return;
        }
        if now_ms >= self.wait_until && matches!(self.phase, Phase::Arming | Phase::Waiting { .. })
        {
            self.verdict = Verdict::NotIdle;
            self.phase = Phase::Disarming;
        }
        if now_ms >= self.go_until && self.phase == Phase::Going {
            // A node told to go that is not idle (it faulted, or moves again) within the
            // wait: the ones not switched are disarmed.
            let switched = self.nodes.iter().any(|n| n.state == NodeState::Switched);
            self.verdict = if switched {
                Verdict::Partial
            } else {
                Verdict::NotIdle
            };
            self.call_off(now_ms);
        }
        let generation = self.generation;
        for i in 0..self.nodes.len() {
            let Some(&n) = self.nodes.get(i) else { break };
            if !self.waits_for(n.state) || now_ms < n.due {
                continue;
            }
            let mut step = self.step_for(n.state);
            let Some(n) = self.nodes.get_mut(i) else {
                break;
            };
            if n.tries >= GIVE_UP_AFTER {
                n.state = match n.state {
                    NodeState::Going => NodeState::Unheard,
                    _ => NodeState::Silent,
                };
                continue;
            }
            if let SwitchStep::Arm { ask } = &mut step {
                n.asked = n.asked.wrapping_add(1);
                *ask = n.asked;
            }
            send(n.addr, Message::Switch { generation, step });
            n.tries += 1;
            n.due = now_ms + RETRY_MS;
        }
        self.advance(now_ms, send);
    }

    /// A node's answer.
    pub fn on_reply(
        &mut self,
        addr: u16,
        generation: u32,
        reply: ConfigReply,
        now_ms: u64,
        mut send: impl FnMut(u16, Message<'static>),
    ) {
        if generation != self.generation || self.phase == Phase::Done {
            return;
        }
        let phase = self.phase;
        let Some(node) = self.nodes.iter_mut().find(|n| n.addr == addr) else {
            return;
        };
        if let ConfigReply::Armed { ask, .. } = reply {
            // Only an answer to an ask newer than the last answered, and sent.
            if !node.takes_answer_to(ask) {
                return;
            }
        }
        let state = match (phase, reply) {
            (_, ConfigReply::Activated) => NodeState::Switched,
            // What a switch step is refused with (a late answer of the transfer, `Stale`,
            // `OutOfSequence`, ..., is not this switch-over's: it aborted it, and left a
            // node it had armed armed).
            (_, ConfigReply::Refused(r @ (Refusal::NotStaged { .. } | Refusal::Flash))) => {
                NodeState::Refused(r)
            }
            (Phase::Disarming, ConfigReply::Disarmed) => NodeState::Disarmed,
            (Phase::Going, ConfigReply::Armed { .. }) => NodeState::Going,
            (Phase::Going, ConfigReply::Busy) => NodeState::Arming,
            (Phase::Arming | Phase::Waiting { .. }, ConfigReply::Armed { idle, .. }) => {
                self.answers += 1;
                NodeState::Armed {
                    idle,
                    at: self.answers,
                }
            }
            _ => return,
        };
        let Some(node) = self.nodes.iter_mut().find(|n| n.addr == addr) else {
            return;
        };
        let progressed = state != node.state || matches!(state, NodeState::Armed { .. });
        node.state = state;
        if progressed {
            // Ask again at once when the step changes, else on the retry.
            node.ask_at(if matches!(state, NodeState::Armed { .. }) {
                now_ms + RETRY_MS
            } else {
                now_ms
            });
        }
        self.advance(now_ms, &mut send);
    }

    fn advance(&mut self, now_ms: u64, send: &mut dyn FnMut(u16, Message<'static>)) {
        let all = |f: &dyn Fn(NodeState) -> bool| self.nodes.iter().all(|n| f(n.state));
        let any = |f: &dyn Fn(NodeState) -> bool| self.nodes.iter().any(|n| f(n.state));
        let failed = |s: NodeState| {
            matches!(
                s,
                NodeState::Refused(_) | NodeState::Silent | NodeState::Unheard
            )
        };
        // Switched, or may have: the switch-over is not all undone.
        let moved = |s: NodeState| matches!(s, NodeState::Switched | NodeState::Unheard);
        // A node that runs the generation already (it switched in a switch-over that did
        // not finish: pushed again) answers `Activated`, and is not waited for.
        let switched = |s: NodeState| s == NodeState::Switched;
        let next = match self.phase {
            Phase::Arming | Phase::Waiting { .. } if any(&failed) => {
                self.verdict = Verdict::Aborted;
                Some(Phase::Disarming)
            }
            Phase::Arming | Phase::Waiting { .. } if all(&switched) => {
                self.verdict = Verdict::Switched;
                Some(Phase::Done)
            }
            Phase::Arming if all(&|s| matches!(s, NodeState::Armed { .. }) || switched(s)) => {
                // Ask every node once more at once: only answers after this count.
                for n in self.nodes.iter_mut() {
                    n.ask_at(now_ms);
                }
                Some(Phase::Waiting {
                    since: self.answers,
                })
            }
            Phase::Waiting { since }
                if all(&|s| {
                    matches!(s, NodeState::Armed { idle: true, at } if at > since) || switched(s)
                }) =>
            {
                for n in self.nodes.iter_mut().filter(|n| !switched(n.state)) {
                    n.state = NodeState::Going;
                    n.ask_at(now_ms);
                }
                self.go_until = now_ms.saturating_add(self.wait_ms);
                Some(Phase::Going)
            }
            Phase::Going if all(&|s| s == NodeState::Switched) => {
                self.verdict = Verdict::Switched;
                Some(Phase::Done)
            }
            Phase::Going if all(&|s| s == NodeState::Switched || failed(s)) => {
                self.verdict = if any(&moved) {
                    Verdict::Partial
                } else {
                    Verdict::Aborted
                };
                Some(Phase::Done)
            }
            Phase::Disarming if !self.nodes.iter().any(|n| self.waits_for(n.state)) => {
                Some(Phase::Done)
            }
            _ => None,
        };
        if let Some(p) = next {
            if p == Phase::Disarming {
                self.call_off(now_ms);
            } else {
                self.phase = p;
            }
            if p != Phase::Done {
                self.poll_dyn(now_ms, send);
            }
        }
    }

    /// Calls the switch-over off: every node not done with it is disarmed, from `now_ms`.
    fn call_off(&mut self, now_ms: u64) {
        self.phase = Phase::Disarming;
        for n in self.nodes.iter_mut() {
            n.ask_at(now_ms);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOOL: u16 = 0x0100;
    const ARM: SwitchStep = SwitchStep::Arm { ask: 1 };
    const GO: SwitchStep = SwitchStep::Go {
        now: false,
        trial: false,
    };
    const GO_NOW: SwitchStep = SwitchStep::Go {
        now: true,
        trial: false,
    };

    fn staged(generation: u32) -> SwitchOver {
        let mut s = SwitchOver::default();
        s.set_staged(generation);
        s
    }

    #[test]
    fn go_switches_only_when_armed_and_idle_or_now() {
        let mut s = staged(2);
        let go = GO;
        assert_eq!(
            s.step(2, go, TOOL, 1, true, 0),
            Action::Reply(ConfigReply::Busy)
        );
        let arm = SwitchStep::Arm { ask: 0 };
        assert_eq!(
            s.step(2, arm, TOOL, 1, false, 0),
            Action::Reply(ConfigReply::Armed {
                idle: false,
                ask: 0
            })
        );
        assert_eq!(
            s.step(2, go, TOOL, 1, false, 1),
            Action::Reply(ConfigReply::Busy)
        );
        assert_eq!(
            s.step(2, go, TOOL, 1, true, 2),
            Action::Activate(Target::Staged { trial: false })
        );
        assert_eq!(
            s.activating(),
            Some((TOOL, Target::Staged { trial: false }))
        );
        assert_eq!(s.activated(true, 1), (Some(TOOL), false));
        assert_eq!(s.staged(), 0);
        // The answer was lost: asked again, it is switched.
        assert_eq!(
            s.step(2, go, TOOL, 2, true, 3),
            Action::Reply(ConfigReply::Activated)
        );
        let mut s = staged(2);
        let now = GO_NOW;
        assert_eq!(
            s.step(2, now, TOOL, 1, false, 0),
            Action::Activate(Target::Staged { trial: false })
        );
    }

    #[test]
    fn a_start_while_armed_is_held_and_runs_after_the_switch_or_on_disarm() {
        let mut s = staged(2);
        assert!(!s.hold_start(), "not armed: START runs");
        s.step(2, ARM, TOOL, 1, true, 0);
        assert!(s.hold_start());
        s.step(2, GO, TOOL, 1, true, 1);
        assert_eq!(s.activated(true, 1), (Some(TOOL), true));
        let mut s = staged(2);
        s.step(2, ARM, TOOL, 1, true, 0);
        assert!(s.hold_start());
        assert_eq!(
            s.step(2, SwitchStep::Disarm, TOOL, 1, true, 1),
            Action::Disarmed { start: true }
        );
        assert!(!s.hold_start());
    }

    #[test]
    fn an_armed_node_left_alone_disarms_and_runs_its_held_start() {
        let mut s = staged(2);
        s.step(2, ARM, TOOL, 1, true, 0);
        s.hold_start();
        assert_eq!(s.deadline(), Some(ARM_HOLD_MS));
        assert!(!s.poll(ARM_HOLD_MS - 1));
        assert!(s.poll(ARM_HOLD_MS));
        assert!(!s.armed());
    }

    #[test]
    fn another_generation_than_the_staged_one_is_refused() {
        let mut s = staged(3);
        assert_eq!(
            s.step(2, ARM, TOOL, 1, true, 0),
            Action::Reply(ConfigReply::Refused(Refusal::NotStaged { staged: 3 }))
        );
        let mut none = SwitchOver::default();
        assert_eq!(
            none.step(2, GO_NOW, TOOL, 1, true, 0),
            Action::Reply(ConfigReply::Refused(Refusal::NotStaged { staged: 0 }))
        );
    }

    #[test]
    fn a_trial_is_confirmed_or_rolled_back_to_the_generation_before_it() {
        let trial = SwitchStep::Go {
            now: true,
            trial: true,
        };
        // Generation 1 runs; 2 is staged and switched to on trial.
        let mut s = staged(2);
        assert_eq!(
            s.step(2, trial, TOOL, 1, true, 0),
            Action::Activate(Target::Staged { trial: true })
        );
        s.activated(true, 1);
        assert_eq!((s.trial(), s.previous(), s.staged()), (true, 1, 0));
        // Roll back to 1: armed and idle, then go.
        assert_eq!(
            s.step(1, ARM, TOOL, 2, true, 1),
            Action::Reply(ConfigReply::Armed { idle: true, ask: 1 })
        );
        let go = GO;
        assert_eq!(
            s.step(1, go, TOOL, 2, true, 2),
            Action::Activate(Target::Previous)
        );
        s.activated(true, 2);
        assert_eq!(
            (s.trial(), s.previous()),
            (false, 0),
            "nothing to return to"
        );
        // Or confirm it.
        let mut s = staged(2);
        s.step(2, trial, TOOL, 1, true, 0);
        s.activated(true, 1);
        assert_eq!(
            s.step(2, SwitchStep::Confirm, TOOL, 2, true, 1),
            Action::Confirm
        );
        assert_eq!(s.confirmed(true), Some(TOOL));
        assert!(!s.trial());
        assert_eq!(
            s.step(2, SwitchStep::Confirm, TOOL, 2, true, 2),
            Action::Reply(ConfigReply::Confirmed),
            "confirmed already"
        );
        // A trial over a trial keeps the confirmed generation as the one to return to.
        let mut s = staged(2);
        s.step(2, trial, TOOL, 1, true, 0);
        s.activated(true, 1);
        s.set_staged(3);
        assert_eq!(s.previous(), 0, "staging went over the previous slot");
    }

    #[test]
    fn a_failed_activation_keeps_the_staged_table_and_the_arming() {
        let mut s = staged(2);
        s.step(2, ARM, TOOL, 1, true, 0);
        s.step(2, GO, TOOL, 1, true, 1);
        assert_eq!(s.activated(false, 1), (Some(TOOL), false));
        assert_eq!((s.staged(), s.armed()), (2, true));
    }

    /// Nodes (the node side of this module) and the tool's coordinator on a perfect link,
    /// with each node's idleness scripted and frames to some nodes droppable.
    struct Machine {
        nodes: heapless::Vec<(u16, SwitchOver, bool, u32), 4>,
        tool: Coordinator,
        /// (node, frames to drop before one gets through)
        drop: heapless::Vec<(u16, u32), 4>,
        /// Gos to drop to a node.
        drop_go: heapless::Vec<(u16, u32), 4>,
        /// A node that reboots (its arming lost, its staged table kept) as its first Go
        /// arrives.
        reboot_at_go: Option<u16>,
        /// A node that is no longer idle from its first Go on (it faulted, or an event set
        /// it moving).
        busy_at_go: Option<u16>,
        now: u64,
        log: heapless::Vec<(u64, u16, SwitchStep), 256>,
    }

    impl Machine {
        fn new(n: usize, now: bool) -> Machine {
            let mut nodes = heapless::Vec::new();
            let mut addrs: heapless::Vec<u16, 4> = heapless::Vec::new();
            for i in 0..n {
                let addr = 0x11 + i as u16;
                nodes.push((addr, staged(2), true, 1)).unwrap();
                addrs.push(addr).unwrap();
            }
            Machine {
                nodes,
                tool: Coordinator::new(&addrs, 2, now, 20_000, 0),
                drop: heapless::Vec::new(),
                drop_go: heapless::Vec::new(),
                reboot_at_go: None,
                busy_at_go: None,
                now: 0,
                log: heapless::Vec::new(),
            }
        }

        fn run(&mut self, until: u64) -> Verdict {
            while self.now < until && self.tool.verdict() == Verdict::Busy {
                let mut out: heapless::Vec<(u16, Message<'static>), 16> = heapless::Vec::new();
                self.tool.poll(self.now, |a, m| out.push((a, m)).unwrap());
                while let Some((addr, m)) = out.pop() {
                    let Message::Switch { generation, step } = m else {
                        panic!()
                    };
                    // Logged without the ask's number (each Arm has its own).
                    let kind = match step {
                        SwitchStep::Arm { .. } => SwitchStep::Arm { ask: 0 },
                        step => step,
                    };
                    let _ = self.log.push((self.now, addr, kind));
                    if let Some(d) = self.drop.iter_mut().find(|d| d.0 == addr && d.1 > 0) {
                        d.1 -= 1;
                        continue;
                    }
                    let go = matches!(step, SwitchStep::Go { .. });
                    if let Some(d) = self
                        .drop_go
                        .iter_mut()
                        .find(|d| d.0 == addr && d.1 > 0 && go)
                    {
                        d.1 -= 1;
                        continue;
                    }
                    if go && self.reboot_at_go == Some(addr) {
                        self.reboot_at_go = None;
                        if let Some(n) = self.nodes.iter_mut().find(|n| n.0 == addr) {
                            n.1 = staged(2);
                        }
                    }
                    let Some(n) = self.nodes.iter_mut().find(|n| n.0 == addr) else {
                        continue;
                    };
                    if go && self.busy_at_go == Some(addr) {
                        n.2 = false;
                    }
                    let reply = match n.1.step(generation, step, TOOL, n.3, n.2, self.now) {
                        Action::Reply(r) => r,
                        Action::Activate(_) => {
                            n.1.activated(true, n.3);
                            n.3 = 2;
                            ConfigReply::Activated
                        }
                        Action::Confirm => {
                            n.1.confirmed(true);
                            ConfigReply::Confirmed
                        }
                        Action::Disarmed { .. } => ConfigReply::Disarmed,
                    };
                    self.tool
                        .on_reply(addr, 2, reply, self.now, |a, m| out.push((a, m)).unwrap());
                }
                self.now += 10;
            }
            self.tool.verdict()
        }

        fn running(&self) -> heapless::Vec<u32, 4> {
            self.nodes.iter().map(|n| n.3).collect()
        }
    }

    #[test]
    fn an_idle_machine_is_armed_checked_once_more_and_switched() {
        let mut m = Machine::new(3, false);
        assert_eq!(m.run(10_000), Verdict::Switched);
        assert_eq!(m.running().as_slice(), &[2, 2, 2]);
        let steps: heapless::Vec<SwitchStep, 16> = m.log.iter().map(|l| l.2).collect();
        let arm = SwitchStep::Arm { ask: 0 };
        let go = GO;
        assert_eq!(
            steps.as_slice(),
            &[arm, arm, arm, arm, arm, arm, go, go, go]
        );
    }

    #[test]
    fn no_node_switches_before_every_node_is_idle_at_once() {
        let mut m = Machine::new(3, false);
        m.nodes[1].2 = false; // mid-cycle
        assert_eq!(m.run(1_000), Verdict::Busy);
        assert_eq!(m.running().as_slice(), &[1, 1, 1], "nothing switched");
        assert!(m.nodes.iter().all(|n| n.1.armed()));
        m.nodes[1].2 = true; // the cycle ended
        assert_eq!(m.run(2_000), Verdict::Switched);
        assert_eq!(m.running().as_slice(), &[2, 2, 2]);
    }

    #[test]
    fn a_lost_go_is_resent_and_a_node_that_rebooted_is_armed_again() {
        let mut m = Machine::new(2, false);
        // Two Gos to 0x12 are lost; 0x11 reboots between its arming and its Go.
        m.drop_go.push((0x12, 2)).unwrap();
        m.reboot_at_go = Some(0x11);
        assert_eq!(m.run(5_000), Verdict::Switched);
        assert_eq!(m.running().as_slice(), &[2, 2]);
        let to = |addr: u16| -> heapless::Vec<SwitchStep, 16> {
            m.log.iter().filter(|l| l.1 == addr).map(|l| l.2).collect()
        };
        let (arm, go) = (SwitchStep::Arm { ask: 0 }, GO);
        assert_eq!(to(0x11).as_slice(), &[arm, arm, go, arm, go]);
        assert_eq!(to(0x12).as_slice(), &[arm, arm, go, go, go]);
    }

    #[test]
    fn a_machine_that_never_idles_is_disarmed_and_nothing_switches() {
        let mut m = Machine::new(2, false);
        m.nodes[0].2 = false;
        assert_eq!(m.run(30_000), Verdict::NotIdle);
        assert_eq!(m.running().as_slice(), &[1, 1]);
        assert!(m.nodes.iter().all(|n| !n.1.armed()), "disarmed");
    }

    /// Every node said idle after all were armed, then 0x12 is no longer idle as its Go
    /// arrives (it faulted, or an event set it moving) and stays so. 0x11 switched; the
    /// tool arms 0x12 again and tells it to go while the wait lasts (from the first Go),
    /// then disarms it and ends `Partial`. (It went on for ever: each `Busy` and `Armed`
    /// counted as progress, and going had no deadline.)
    #[test]
    fn a_node_no_longer_idle_at_its_go_ends_the_switch_over_partial_within_the_wait() {
        let mut m = Machine::new(2, false);
        m.busy_at_go = Some(0x12);
        assert_eq!(m.run(3_600_000), Verdict::Partial);
        assert!(m.now < 21_000, "ended at {} ms (the wait: 20 s)", m.now);
        assert_eq!(m.running().as_slice(), &[2, 1]);
        assert!(!m.nodes[1].1.armed(), "0x12 disarmed");
        let states: heapless::Vec<(u16, NodeState), 4> = m.tool.nodes().collect();
        assert_eq!(
            states.as_slice(),
            &[(0x11, NodeState::Switched), (0x12, NodeState::Disarmed)]
        );
    }

    #[test]
    fn a_node_that_never_answers_the_arming_aborts_and_the_rest_is_disarmed() {
        let mut m = Machine::new(2, false);
        m.drop.push((0x12, u32::MAX)).unwrap();
        assert_eq!(m.run(30_000), Verdict::Aborted);
        assert_eq!(m.running().as_slice(), &[1, 1]);
        assert!(!m.nodes[0].1.armed());
    }

    /// A switch-over that did not finish, run again: 0x11 runs generation 2 already (it
    /// switched the first time), 0x12 has it staged. 0x11 answers its arming `Activated`
    /// and counts as switched; 0x12 is armed, checked once more and switched. (The
    /// coordinator waited for 0x11's arming: `NotIdle`, nothing switched.)
    #[test]
    fn a_node_that_switched_already_is_not_waited_for() {
        let mut m = Machine::new(2, false);
        m.nodes[0].1 = SwitchOver::default();
        m.nodes[0].3 = 2;
        assert_eq!(m.run(30_000), Verdict::Switched);
        assert_eq!(m.running().as_slice(), &[2, 2]);
        let to = |addr: u16| -> heapless::Vec<SwitchStep, 16> {
            m.log.iter().filter(|l| l.1 == addr).map(|l| l.2).collect()
        };
        let (arm, go) = (SwitchStep::Arm { ask: 0 }, GO);
        assert_eq!(to(0x11).as_slice(), &[arm]);
        assert_eq!(to(0x12).as_slice(), &[arm, arm, go]);
    }

    /// 0x11's first `Armed { idle: true }` (before 0x12 was armed) is duplicated and the
    /// copy comes late: after every node was armed, the tool's ask of 0x11 once more was
    /// lost and 0x11 started moving. The copy answers an earlier ask: not taken (it was,
    /// as an answer after every node was armed, and 0x12 switched while 0x11 moved).
    #[test]
    fn a_late_copy_of_an_answer_to_an_earlier_ask_is_not_taken() {
        type Out = heapless::Vec<(u16, Message<'static>), 8>;
        let mut tool = Coordinator::new(&[0x11, 0x12], 2, false, 20_000, 0);
        let (mut a, mut b) = (staged(2), staged(2));
        let answer = |n: &mut SwitchOver, m: &Message, idle: bool, now: u64| match *m {
            Message::Switch { generation, step } => {
                match n.step(generation, step, TOOL, 1, idle, now) {
                    Action::Reply(r) => r,
                    other => panic!("{other:?}"),
                }
            }
            _ => panic!("{m:?}"),
        };
        let mut out = Out::new();
        tool.poll(0, |n, m| out.push((n, m)).unwrap());
        let (to_a, to_b) = (out[0].1.clone(), out[1].1.clone());
        let first = answer(&mut a, &to_a, true, 1);
        assert!(matches!(first, ConfigReply::Armed { idle: true, .. }));
        let mut again = Out::new();
        tool.on_reply(0x11, 2, first, 2, |n, m| again.push((n, m)).unwrap());
        let busy = answer(&mut b, &to_b, false, 3);
        tool.on_reply(0x12, 2, busy, 4, |n, m| again.push((n, m)).unwrap());
        // Every node armed: each asked once more. The ask of 0x11 is lost; it moves now.
        let ask_b = again
            .iter()
            .find(|s| s.0 == 0x12)
            .expect("0x12 asked again")
            .1
            .clone();
        assert!(again.iter().any(|s| s.0 == 0x11), "0x11 asked again");
        let mut sent = Out::new();
        tool.on_reply(0x11, 2, first, 5, |n, m| sent.push((n, m)).unwrap());
        let idle_b = answer(&mut b, &ask_b, true, 6);
        tool.on_reply(0x12, 2, idle_b, 7, |n, m| sent.push((n, m)).unwrap());
        // 0x11 answers each ask from now on: moving.
        let mut now = 10;
        while now < 2_000 {
            let mut due = Out::new();
            tool.poll(now, |n, m| due.push((n, m)).unwrap());
            for (n, m) in due.iter().chain(sent.iter()) {
                assert!(
                    !matches!(
                        m,
                        Message::Switch {
                            step: SwitchStep::Go { .. },
                            ..
                        }
                    ),
                    "Go to {n:#06x} at {now} ms while 0x11 moves"
                );
            }
            sent.clear();
            for (n, m) in due.iter().filter(|d| d.0 == 0x11) {
                let r = answer(&mut a, m, false, now);
                tool.on_reply(*n, 2, r, now, |n, m| sent.push((n, m)).unwrap());
            }
            now += 10;
        }
        assert_eq!(tool.verdict(), Verdict::Busy, "waiting for 0x11");
    }

    /// A late answer of the transfer (`Refused(OutOfSequence)` of the generation) while
    /// the machine is armed is not a switch step's refusal: the switch-over goes on.
    #[test]
    fn a_late_refusal_of_the_transfer_does_not_abort_the_switch_over() {
        let mut m = Machine::new(2, false);
        let mut out: heapless::Vec<(u16, Message<'static>), 16> = heapless::Vec::new();
        let late = ConfigReply::Refused(Refusal::OutOfSequence);
        m.tool
            .on_reply(0x11, 2, late, 0, |a, s| out.push((a, s)).unwrap());
        assert!(out.is_empty());
        assert_eq!(m.run(5_000), Verdict::Switched);
        assert_eq!(m.running().as_slice(), &[2, 2]);
    }

    /// A node told to go that never answers again may have switched (its process killed
    /// after it persisted the new table, before its answer): it is `Unheard`, and the
    /// switch-over `Partial`, not a node that `stopped answering` before the switch with
    /// `nothing switched`, which the tool told the operator: the node booted the new
    /// generation.
    #[test]
    fn a_node_told_to_go_that_never_answers_is_unheard_not_silent() {
        // 0x11 alone, told to go at once (`now`) or armed first; it never answers.
        let unanswered = |now: bool| {
            let mut c = Coordinator::new(&[0x11], 2, now, 20_000, 0);
            let mut t = 0;
            while c.verdict() == Verdict::Busy && t < 60_000 {
                c.poll(t, |_, _| {});
                t += 10;
            }
            let states: heapless::Vec<_, 1> = c.nodes().map(|(_, s)| s).collect();
            (states, c.verdict())
        };
        let (states, verdict) = unanswered(true);
        assert_eq!(
            (states.as_slice(), verdict),
            (&[NodeState::Unheard][..], Verdict::Partial)
        );
        // Not armed yet, it is silent: it never heard a Go.
        let (states, verdict) = unanswered(false);
        assert_eq!(
            (states.as_slice(), verdict),
            (&[NodeState::Silent][..], Verdict::Aborted)
        );
    }

    /// More nodes than a switch-over holds: none is armed, none left out of it (the
    /// seventeenth was dropped, and the others switched without it).
    #[test]
    fn more_nodes_than_a_switch_over_holds_are_refused_whole() {
        let nodes: heapless::Vec<u16, 17> = (0..=MAX_ROLES as u16).map(|i| 0x11 + i).collect();
        let mut c = Coordinator::new(&nodes, 2, false, 20_000, 0);
        let mut sent = 0;
        c.poll(0, |_, _| sent += 1);
        assert_eq!(
            (c.verdict(), sent, c.nodes().count()),
            (Verdict::Aborted, 0, 0)
        );
    }

    #[test]
    fn now_switches_at_once_whatever_the_machine_does() {
        let mut m = Machine::new(2, true);
        m.nodes[0].2 = false;
        assert_eq!(m.run(1_000), Verdict::Switched);
        let steps: heapless::Vec<SwitchStep, 4> = m.log.iter().map(|l| l.2).collect();
        let go = GO_NOW;
        assert_eq!(steps.as_slice(), &[go, go]);
    }
}
