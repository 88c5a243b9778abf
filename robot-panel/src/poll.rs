//! The panel's radio: one thread owns the tool's radio (secured with the machine's keys
//! as the CLI's), asks every node its status and alarms (its security counters less
//! often), and carries out the operator's orders between two rounds with the same
//! `robot_net` functions the CLI commands use: `push::command` (START, RESET),
//! `home::home`, `home::alarms` (ACK), `push::confirm`.

use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use config_schema::wire::msg::{Command, Message, Status};
use robot_compiler::compile::Compiled;
use robot_net::home::{self, HomeEnd, Standing};
use robot_net::push::{self, Ids};
use robot_net::radio::ToolRadio;
use robot_net::{demo, release, show, NetError};

use crate::buttons::{self, Button};
use crate::model::Machine;
use crate::shared::Shared;

/// An operator's order and where its outcome goes (`Err`: refused or failed, in words).
pub struct Order {
    pub button: Button,
    pub reply: Sender<Result<String, String>>,
    /// Taken by the radio thread, or given up on by the page, whichever comes first.
    pub claim: Claim,
}

/// Who has an order: the radio thread that carries it out, or the page that stopped
/// waiting for it. An order the page gave up on (answered "not carried out") is never
/// carried out later; one the radio thread took is waited for until it ends.
#[derive(Debug, Clone, Default)]
pub struct Claim(Arc<AtomicU8>);

const PENDING: u8 = 0;
const TAKEN: u8 = 1;
const GIVEN_UP: u8 = 2;

impl Claim {
    fn settle(&self, to: u8) -> bool {
        (self.0)
            .compare_exchange(PENDING, to, Ordering::SeqCst, Ordering::SeqCst)
            .is_ok()
    }

    /// The radio thread takes the order: `false` if the page gave up on it first (then
    /// it is not carried out).
    pub fn take(&self) -> bool {
        self.settle(TAKEN)
    }

    /// The page gives up waiting for the order: `false` if the radio thread took it
    /// already (it is under way).
    pub fn give_up(&self) -> bool {
        self.settle(GIVEN_UP)
    }
}

/// How long a node is asked before it counts as not answering (a round of the poll).
pub const POLL_ANSWER: Duration = Duration::from_millis(450);
/// How long an order's command to one node is resent until answered (as the CLI's).
pub const ANSWER_WITHIN: Duration = Duration::from_secs(5);
/// Between two rounds of questions (the pins come from the medium as they change; the
/// questions are for the charts' states, the alarms and the counters, and take air).
pub const ROUND: Duration = Duration::from_millis(200);
/// The alarms are asked every so many rounds.
const ALARMS_EVERY: u64 = 2;
/// The security counters are asked every so many rounds.
const SECURITY_EVERY: u64 = 10;
/// How long homing may take.
const HOME_WAIT: Duration = Duration::from_secs(60);

struct Poll {
    c: Arc<Compiled>,
    machine: Arc<Machine>,
    radio: ToolRadio,
    ids: Ids,
    shared: Arc<Shared>,
}

/// Runs the panel's radio on this thread (the tool's radio stays on the thread that
/// opened it) until `stop`, or until the medium goes away; then every order is refused,
/// saying so, until the senders are gone.
pub fn run(
    c: Arc<Compiled>,
    machine: Arc<Machine>,
    radio: ToolRadio,
    shared: Arc<Shared>,
    orders: Receiver<Order>,
    stop: Arc<AtomicBool>,
) {
    let mut p = Poll {
        c,
        machine,
        radio,
        ids: Ids::default(),
        shared,
    };
    let mut round = 0u64;
    while !stop.load(Ordering::Relaxed) {
        if let Err(e) = p.round(round) {
            p.lost(&e);
            break;
        }
        round += 1;
        match orders.recv_timeout(ROUND) {
            // The page gave up on it: its operator was told it was not carried out.
            Ok(order) if !order.claim.take() => {}
            Ok(order) => {
                let outcome = p.order(order.button);
                if let Err(NetError::Radio(e)) = &outcome {
                    p.lost(e);
                }
                let text = p.outcome(order.button, outcome);
                let _ = order.reply.send(text);
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => return,
        }
    }
    // No radio any more: every order is refused, saying why.
    while let Ok(order) = orders.recv() {
        let why = p.shared.read(|l| l.medium_lost.clone()).1;
        let why = why.unwrap_or_else(|| "the panel's radio stopped".into());
        let _ = order.reply.send(Err(format!("no medium: {why}")));
    }
}

impl Poll {
    fn lost(&self, e: &std::io::Error) {
        let why = match e.kind() {
            std::io::ErrorKind::UnexpectedEof => "the medium closed".to_string(),
            _ => format!("the medium failed: {e}"),
        };
        self.shared.update(|l| {
            l.medium_lost.get_or_insert(why);
            l.running = false;
            l.busy = None;
            true
        });
    }

    /// One round: every node's status and alarms (and now and then its security
    /// counters); then, while cycles run, START again at the idle point.
    fn round(&mut self, round: u64) -> std::io::Result<()> {
        let addrs: Vec<u16> = self.c.ir.roles.iter().map(|r| r.address).collect();
        let statuses: Vec<Result<Status, u32>> = self
            .ask_when(true, &addrs, Command::Status, push::status_answer)?
            .collect();
        // The alarms and counters of the nodes that answered, when due.
        let answered: Vec<u16> = (addrs.iter().zip(&statuses))
            .filter(|(_, s)| s.is_ok())
            .map(|(&a, _)| a)
            .collect();
        let mut alarms = self.ask_when(
            round.is_multiple_of(ALARMS_EVERY),
            &answered,
            Command::Alarms,
            push::alarms_answer,
        )?;
        let mut security = self.ask_when(
            round.is_multiple_of(SECURITY_EVERY),
            &answered,
            Command::Security,
            push::security_answer,
        )?;
        for (i, s) in statuses.into_iter().enumerate() {
            let Ok(s) = s else {
                self.shared.update(|l| match l.nodes.get_mut(i) {
                    Some(n) if n.silent.is_none() => {
                        n.silent = Some(SystemTime::now());
                        true
                    }
                    _ => false,
                });
                continue;
            };
            let alarms = alarms.next().and_then(Result::ok);
            let security = security.next().and_then(Result::ok);
            let (c, machine) = (&self.c, &self.machine);
            self.shared.update(|l| {
                l.levels_from(c, machine, i, &s);
                let Some(n) = l.nodes.get_mut(i) else {
                    return false;
                };
                let mut changed = n.silent.take().is_some();
                // The command id moves with every answer: compared without it.
                let same = |a: &Status, b: &Status| {
                    Status {
                        ack: 0,
                        ..a.clone()
                    } == Status {
                        ack: 0,
                        ..b.clone()
                    }
                };
                if !n.status.as_ref().is_some_and(|old| same(old, &s)) {
                    changed = true;
                }
                n.status = Some(s);
                if let Some(a) = alarms {
                    let (old, _) = n.alarms.get_or_insert((a.clone(), SystemTime::now()));
                    changed |= old.alarms != a.alarms || old.dropped != a.dropped;
                    n.alarms = Some((a, SystemTime::now()));
                }
                if let Some(r) = security {
                    changed |= n.security != Some((r.keyed, r.counters));
                    n.security = Some((r.keyed, r.counters));
                }
                changed
            });
        }
        self.cycles_on()
    }

    /// When `due`, `command` to every node of `addrs` at once (`push::ask_each`, within
    /// [`POLL_ANSWER`]): their answers in that order; else none.
    fn ask_when<T>(
        &mut self,
        due: bool,
        addrs: &[u16],
        command: Command,
        pick: impl Fn(Message<'_>, u16) -> Option<T>,
    ) -> std::io::Result<std::vec::IntoIter<Result<T, u32>>> {
        let answers = if due {
            let (radio, ids) = (&mut self.radio, &mut self.ids);
            push::ask_each(radio, ids, addrs, command, POLL_ANSWER, pick)?
        } else {
            Vec::new()
        };
        Ok(answers.into_iter())
    }

    /// While cycles run: a fault ends them; at the idle point START is pressed again.
    fn cycles_on(&mut self) -> std::io::Result<()> {
        let (_, (running, faulted, start)) = self.shared.read(|l| {
            let faulted = (l.nodes.iter())
                .filter_map(|n| n.status.as_ref())
                .any(|s| s.fault.is_some());
            // START's rule, as if the cycles were not running (they are, by the panel).
            let mut idle = l.clone();
            idle.running = false;
            let start = buttons::check(Button::Start, &self.c, &idle);
            (l.running, faulted, start.is_ok())
        });
        if !running {
            return Ok(());
        }
        if faulted {
            self.shared.update(|l| {
                l.running = false;
                l.said = Some("cycles stopped: a node faulted".into());
                true
            });
            return Ok(());
        }
        if start {
            match self.start() {
                Ok(_) => {}
                Err(NetError::Radio(e)) => return Err(e),
                Err(e) => self.shared.update(|l| {
                    l.running = false;
                    l.said = Some(format!("cycles stopped: {e}"));
                    true
                }),
            }
        }
        Ok(())
    }

    /// Carries out an order: checked again against the machine as it is now (the
    /// server checked it against what the page showed).
    fn order(&mut self, b: Button) -> Result<String, NetError> {
        let (_, allowed) = self.shared.read(|l| buttons::check(b, &self.c, l));
        if let Err(why) = allowed {
            return Ok(format!("refused: {why}"));
        }
        self.shared.update(|l| {
            l.busy = Some(b.name().to_string());
            true
        });
        let out = match b {
            Button::Start => match self.start() {
                Ok(s) if !s.starts_with("refused: ") => {
                    self.shared.update(|l| {
                        l.running = true;
                        true
                    });
                    Ok(s)
                }
                other => other,
            },
            Button::Stop => {
                self.shared.update(|l| {
                    l.running = false;
                    true
                });
                Ok("STOP: the cycle under way ends; START is not pressed again".into())
            }
            Button::Reset => self.reset(),
            Button::Ack => self.ack(),
            Button::Home => self.home(),
            Button::Confirm => self.confirm(),
        };
        self.shared.update(|l| {
            l.busy = None;
            true
        });
        out
    }

    /// How an order ended, in words (also kept for the page).
    fn outcome(&self, b: Button, out: Result<String, NetError>) -> Result<String, String> {
        let text = match out {
            Ok(t) if t.starts_with("refused: ") => Err(t),
            Ok(t) => Ok(t),
            Err(e) => Err(format!("{}: {e}", b.name())),
        };
        let said = match &text {
            Ok(t) | Err(t) => t.clone(),
        };
        self.shared.update(|l| {
            l.said = Some(said);
            true
        });
        text
    }

    fn statuses(&mut self) -> Result<Vec<Status>, NetError> {
        home::statuses(&mut self.radio, &mut self.ids, &self.c, ANSWER_WITHIN)
    }

    /// START to the start role's node once every node is homed, at rest, not faulted and
    /// no fault alarm is latched (as `config-tool start ROBOT`).
    fn start(&mut self) -> Result<String, NetError> {
        let c = self.c.clone();
        let (role, _) = c.ir.start.as_ref().ok_or(NetError::NoStart)?;
        let r = c.ir.roles.get(*role).ok_or(NetError::NoStart)?;
        let statuses = self.statuses()?;
        if let Some(why) = home::refusal(&home::nodes(&c, &statuses), false) {
            return Ok(format!("refused: {why}; START was not sent"));
        }
        let reports = home::alarms(
            &mut self.radio,
            &mut self.ids,
            &c,
            Command::Alarms,
            ANSWER_WITHIN,
        )?;
        for (n, report) in c.ir.roles.iter().zip(&reports) {
            if let Some(a) = report.blocking() {
                return Ok(format!(
                    "refused: node {:#06x} ({}) has a fault alarm latched: {}; START was not \
                     sent",
                    n.address,
                    n.name,
                    demo::alarm_text(&c, &n.name, a.source)
                ));
            }
        }
        home::after_greetings(&mut self.radio, reports.iter().map(|r| r.now_ms))?;
        self.node_command(r.address, Command::Start)?;
        Ok(format!(
            "START sent to node {:#06x} ({})",
            r.address, r.name
        ))
    }

    fn node_command(&mut self, addr: u16, command: Command) -> Result<Status, NetError> {
        push::command(&mut self.radio, &mut self.ids, addr, command, ANSWER_WITHIN)?.ok_or_else(
            || NetError::NoAnswer {
                addr,
                role: (self.c.ir.roles.iter())
                    .find(|r| r.address == addr)
                    .map(|r| r.name.clone()),
                command: format!("{command:?}"),
            },
        )
    }

    /// RESET to every node that is faulted or has a broken link (as `config-tool reset`).
    fn reset(&mut self) -> Result<String, NetError> {
        let statuses = self.statuses()?;
        let c = self.c.clone();
        let mut said = Vec::new();
        for ((r, s), n) in
            c.ir.roles
                .iter()
                .zip(&statuses)
                .zip(home::nodes(&c, &statuses))
        {
            if matches!(n.standing, Standing::Faulted(_)) || s.links_broken != 0 {
                let after = self.node_command(r.address, Command::Reset)?;
                said.push(show::reset_text(r.address, &after));
            }
        }
        Ok(said.join("; "))
    }

    /// ACK on every node (as `config-tool ack`): what stayed latched, and why.
    fn ack(&mut self) -> Result<String, NetError> {
        let c = self.c.clone();
        // What was acknowledged already, so that only what this ACK did is counted.
        let (radio, ids) = (&mut self.radio, &mut self.ids);
        let before = home::alarms(radio, ids, &c, Command::Alarms, ANSWER_WITHIN)?;
        let reports = home::alarms(radio, ids, &c, Command::Ack, ANSWER_WITHIN)?;
        let mut text = home::acknowledged(&before, &reports);
        let stayed: Vec<String> = (c.ir.roles.iter().zip(&reports))
            .flat_map(|(r, report)| {
                report.alarms.iter().filter(|a| !a.acked).map(|a| {
                    format!(
                        "{} stayed: {}",
                        r.name,
                        demo::alarm_text(&c, &r.name, a.source)
                    )
                })
            })
            .collect();
        let now = SystemTime::now();
        self.shared.update(|l| {
            for (n, report) in l.nodes.iter_mut().zip(reports) {
                n.alarms = Some((report, now));
            }
            true
        });
        for s in stayed {
            text.push_str("; ");
            text.push_str(&s);
        }
        Ok(text)
    }

    /// Homing (as `config-tool home`).
    fn home(&mut self) -> Result<String, NetError> {
        let c = self.c.clone();
        let within = (ANSWER_WITHIN, HOME_WAIT);
        let (end, took) = home::home(&mut self.radio, &mut self.ids, &c, within, &mut || {})?;
        Ok(match end {
            HomeEnd::Homed => format!("homed: every chart idle in {:.2} s", took.as_secs_f64()),
            HomeEnd::Refused(why) => format!("refused: {why}; HOME was not sent"),
            HomeEnd::Ignored { role, addr } => format!(
                "refused: node {addr:#06x} ({role}) did not start homing (armed for a \
                 switch-over?)"
            ),
            HomeEnd::Faulted {
                role, addr, code, ..
            } => format!(
                "homing faulted: node {addr:#06x} ({role}): {} (code {code:#04x})",
                demo::fault_meaning(code)
            ),
            HomeEnd::NotDone(waiting) => format!(
                "homing did not end within {} s: {}",
                HOME_WAIT.as_secs(),
                waiting.join(", ")
            ),
        })
    }

    /// CONFIRM the generation on trial on every node that runs it (as `config-tool
    /// confirm`).
    fn confirm(&mut self) -> Result<String, NetError> {
        let statuses = self.statuses()?;
        let c = self.c.clone();
        let trial: Vec<(u16, u32)> = (c.ir.roles.iter().zip(&statuses))
            .filter(|(_, s)| s.trial)
            .map(|(r, s)| (r.address, s.generation))
            .collect();
        let Some(&(_, generation)) = trial.first() else {
            return Ok("refused: nothing on trial".into());
        };
        let nodes: Vec<u16> = trial.iter().map(|t| t.0).collect();
        let answers = push::confirm(&mut self.radio, &nodes, generation, ANSWER_WITHIN)?;
        let confirmed = answers
            .iter()
            .filter(|a| a.1 == Some(config_schema::wire::msg::ConfigReply::Confirmed))
            .count();
        let mut said = format!(
            "generation {generation} confirmed on {confirmed} of {} node(s)",
            nodes.len()
        );
        // Kept on every node: the nodes that play no role in it are released now.
        if confirmed == nodes.len() {
            let how = release::Release::Now { force: false };
            let (radio, ids) = (&mut self.radio, &mut self.ids);
            for line in release::roleless(radio, ids, &c, generation, how, false)? {
                said.push_str("; ");
                said.push_str(&line);
            }
        }
        Ok(said)
    }
}
