//! The commands that talk to nodes over the (simulated) radio: medium, scan, push, status,
//! start, home, reset, plant, monitor, gateway, and the node runners (`node`, `qemu-node`).

use std::io;
use std::net::SocketAddr;
use std::os::fd::AsRawFd;
use std::path::Path;
use std::time::{Duration, Instant};

use config_schema::wire::medium::{Link, Peer};
use config_schema::wire::msg::{Command, ConfigReply, Message, Refusal, SecurityReport, Status};
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use medium::Conn;
use node_fw::ota::Progress;
use node_fw::switch::Verdict;
use robot_net::demo;
use robot_net::push::{self, Ids};
use robot_net::radio::{ToolRadio, TOOL_ADDR};
use robot_net::{home, live_plant, release, show};

use robot_compiler::model::Security;

use crate::cli::{
    HomeArgs, KeysArg, MachineArgs, MediumAddr, PushArgs, QemuNodeArgs, SwitchArgs, VerifyHow,
};
use crate::commands::{alarms, offline, operator};
use crate::failure::{exit, Failure};
use crate::out::{errln, out, outln};
use crate::tool_keys::{self, KeysFrom, KEYS_ENV};

/// The medium to talk to: the one at `--medium`, or with `--serial` one bridged to the air
/// started here (it lives as long as the command). If the serial line ends or fails (the
/// gateway unplugged), that is said, and the medium stops: the command then fails as on
/// a medium that went away, not as if every node were silent.
pub(crate) fn resolve(at: &MediumAddr) -> Result<SocketAddr, Failure> {
    match &at.serial {
        None => Ok(at.medium),
        Some(serial) => {
            let (m, up) = medium::bridge(serial, at.baud, SocketAddr::from(([127, 0, 0, 1], 0)))?;
            let addr = m.addr();
            let port = serial.display().to_string();
            std::thread::spawn(move || {
                let why = match up.join() {
                    Ok(Ok(())) => String::from("the gateway closed the serial line"),
                    Ok(Err(e)) => format!("the serial line failed: {e}"),
                    Err(_) => String::from("the bridge to the serial line stopped"),
                };
                errln!("error: {port}: {why}");
                m.stop();
            });
            Ok(addr)
        }
    }
}

fn connect(at: &MediumAddr) -> Result<ToolRadio, Failure> {
    let medium = resolve(at)?;
    ToolRadio::connect(medium, TOOL_ADDR)
        .map_err(|e| Failure::error(format!("cannot reach the medium at {medium}: {e}")))
}

/// The tool's radio, secured with the machine secret of `keys` if given (the key file and
/// the counter file are read before the medium is reached).
fn connect_keyed(at: &MediumAddr, keys: Option<&KeysFrom>) -> Result<ToolRadio, Failure> {
    let keys = keys
        .map(|k| tool_keys::open(k.path()))
        .transpose()
        .map_err(Failure::error)?;
    let mut radio = connect(at)?;
    if let Some(k) = keys {
        radio.secure(k.secret, k.counter);
    }
    Ok(radio)
}

/// [`connect_keyed`] for robot `c` (`robot`, its file): its security decides the keys
/// ([`push_keys`]), and an unsecured robot's radio says so ([`plain_if_off`]).
fn connect_robot(
    at: &MediumAddr,
    robot: &Path,
    c: &robot_compiler::Compiled,
    keys: &KeysArg,
) -> Result<ToolRadio, Failure> {
    let keys = push_keys(robot, c, KeysFrom::resolve(keys.keys.as_deref()))?;
    let mut radio = connect_keyed(at, keys.as_ref())?;
    plain_if_off(&mut radio, c);
    Ok(radio)
}

/// [`connect_robot`] when a robot is given (`robot`: its file and the robot), else the
/// radio with the keys given, if any.
fn connect_maybe_robot(
    at: &MediumAddr,
    robot: Option<(&Path, &robot_compiler::Compiled)>,
    keys: &KeysArg,
) -> Result<ToolRadio, Failure> {
    match robot {
        Some((path, c)) => connect_robot(at, path, c, keys),
        None => connect_keyed(at, KeysFrom::resolve(keys.keys.as_deref()).as_ref()),
    }
}

/// An unsecured robot's radio says so ([`ToolRadio::choose_plain`]).
fn plain_if_off(radio: &mut ToolRadio, c: &robot_compiler::Compiled) {
    if c.robot.security == Security::Off {
        radio.choose_plain();
    }
}

/// How long a command to one node is resent until answered.
const ANSWER_WITHIN: Duration = Duration::from_secs(5);

/// How long `scan` asks a robot's node that did not announce itself before it says that
/// node did not answer.
const ASK_QUIET: Duration = Duration::from_secs(1);

/// Sends `cmd` to `node` every 150 ms until `pick` takes an answer acknowledging it; a
/// repeat never runs twice on the node.
fn ask<T>(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    node: u16,
    cmd: Command,
    pick: impl Fn(Message<'_>, u16) -> Option<T>,
) -> Result<T, Failure> {
    let asked = match ask_counted(radio, ids, node, cmd, pick)? {
        Ok(t) => return Ok(t),
        Err(asked) => asked,
    };
    let hint = if radio.secured() || radio.plain_chosen() {
        ""
    } else {
        "; a node with a management key takes only secured frames: pass --keys"
    };
    Err(Failure::error(format!(
        "node {node:#06x} did not answer (asked {asked} times in {} s){hint}",
        ANSWER_WITHIN.as_secs()
    )))
}

/// [`push::ask`] within [`ANSWER_WITHIN`]: the answer, or how many times the node was
/// asked without one.
fn ask_counted<T>(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    node: u16,
    cmd: Command,
    pick: impl Fn(Message<'_>, u16) -> Option<T>,
) -> Result<Result<T, u64>, Failure> {
    let sent_before = radio.stats.sent;
    let answer = push::ask(radio, ids, node, cmd, ANSWER_WITHIN, pick).map_err(Failure::error)?;
    Ok(answer.ok_or(radio.stats.sent.saturating_sub(sent_before)))
}

/// `cmd` to every role's node of `c` at once ([`push::ask_each`], each asked until it
/// answers, at most [`ANSWER_WITHIN`]): per role, in role order, its answer as `pick` takes
/// it, or how many times it was asked without one.
fn ask_every_role<T>(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &robot_compiler::Compiled,
    cmd: Command,
    pick: impl Fn(Message<'_>, u16) -> Option<T>,
) -> Result<Vec<Result<T, u64>>, Failure> {
    let answers =
        home::ask_roles(radio, ids, c, cmd, ANSWER_WITHIN, pick).map_err(Failure::error)?;
    Ok(answers.into_iter().map(|a| a.map_err(u64::from)).collect())
}

/// The status of every role's node of `c`, in role order; a node that does not answer
/// fails the command, named, with how often it was asked and `not_sent` (what was not
/// sent for want of it).
fn robot_statuses(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &robot_compiler::Compiled,
    not_sent: &str,
) -> Result<Vec<Status>, Failure> {
    let answers = ask_every_role(radio, ids, c, Command::Status, push::status_answer)?;
    (c.ir.roles.iter().zip(answers))
        .map(|(r, answer)| {
            answer.map_err(|asked| {
                Failure::error(format!(
                    "node {:#06x} ({}) did not answer Status (asked {asked} times in {} s): \
                     {not_sent}",
                    r.address,
                    r.name,
                    ANSWER_WITHIN.as_secs()
                ))
            })
        })
        .collect()
}

/// A command to one node, resent until its status comes back.
fn command(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    node: u16,
    cmd: Command,
) -> Result<Status, Failure> {
    ask(radio, ids, node, cmd, push::status_answer)
}

/// The node's security report (`Command::Security`).
fn security(radio: &mut ToolRadio, ids: &mut Ids, node: u16) -> Result<SecurityReport, Failure> {
    ask(radio, ids, node, Command::Security, push::security_answer)
}

/// `medium`: runs until interrupted. A capture (`--pcap`) that cannot be written is said
/// on standard error once, within a second: the medium carries on without it.
pub fn medium(config: medium::Config) -> Result<(), Failure> {
    let listen = config.listen;
    let pcap = config.pcap.clone();
    let m = medium::Medium::start(config)
        .map_err(|e| Failure::error(format!("medium on {listen}: {e}")))?;
    outln!("medium listening on {}", m.addr());
    let mut said = false;
    loop {
        std::thread::sleep(Duration::from_secs(1));
        if let (Some(why), Some(path), false) = (m.stats().pcap_error, &pcap, said) {
            errln!(
                "error: --pcap {}: a frame could not be written ({why}): the capture ends \
                 there, the medium carries on",
                path.display()
            );
            said = true;
        }
    }
}

pub fn scan(robot: Option<&Path>, at: &MediumAddr, keys: &KeysArg) -> Result<(), Failure> {
    let c = robot.map(demo::load).transpose()?;
    let mut radio = connect_keyed(at, KeysFrom::resolve(keys.keys.as_deref()).as_ref())?;
    let mut ids = Ids::default();
    let mut found =
        push::scan(&mut radio, &mut ids, Duration::from_secs(2)).map_err(Failure::error)?;
    // A secured node answers a broadcast once a second, to whoever asks first (loss, or
    // another tool asking, can keep it from being heard): the robot's nodes that did not
    // announce themselves are asked directly (secured, with the keys).
    if let Some(c) = &c {
        let quiet: Vec<u16> = (c.robot.nodes.iter())
            .map(|n| n.address)
            .filter(|a| !found.contains_key(a))
            .collect();
        for addr in quiet {
            let nonce = push::identify_nonce();
            let announce = push::ask(
                &mut radio,
                &mut ids,
                addr,
                Command::Identify { nonce },
                ASK_QUIET,
                |m, _| match m {
                    Message::Announce(a) if a.nonce == nonce => Some(a),
                    _ => None,
                },
            )
            .map_err(Failure::error)?;
            found.extend(announce.map(|a| (addr, a)));
        }
    }
    // The robot's nodes' statuses, as they answered.
    let mut statuses = Vec::new();
    for (addr, a) in &found {
        let role = show::role_text(&a.role, a.generation);
        let status = match &c {
            Some(c) => robot_status(&mut radio, &mut ids, c, *addr)?,
            None => None,
        };
        let (trial, homed) = match (&c, &status) {
            (Some(c), Some(s)) => (
                if s.trial { " on trial" } else { "" },
                format!("  {}", standing_text(c, *addr, s)),
            ),
            // A node the robot declares with no role that still runs one (the role moved
            // away while it was off): said, with the way out.
            (Some(c), None) if !a.role.is_empty() && release::plays_no_role(c, *addr) => (
                "",
                format!("  {}", release::stale_text(&a.role, a.generation)),
            ),
            _ => ("", String::new()),
        };
        outln!(
            "{addr:#06x}  firmware {}  generation {}{trial}{}  {role}{homed}",
            a.firmware,
            a.generation,
            show::staged_note(a.staged)
        );
        statuses.extend(status.map(|s| (*addr, s)));
    }
    // Generations apart: a switch-over not finished, or a trial a power cut split. (Not
    // when a node runs another robot's table: then another robot was pushed over this
    // one, and its line says so; there is no switch-over to finish.)
    let by_node: Vec<(u16, &Status)> = statuses.iter().map(|(a, s)| (*a, s)).collect();
    if let (Some(c), Some(home::Generations::Mixed { trial, off })) =
        (&c, home::generations(&by_node))
    {
        let other = (statuses.iter()).any(|(addr, s)| {
            let role = c.ir.roles.iter().position(|r| r.address == *addr);
            let at = role.and_then(|i| Some((c.ir.roles.get(i)?, c.tables.get(i)?)));
            at.is_some_and(|(r, t)| home::standing(&r.name, t, s) == home::Standing::Other)
        });
        if trial.is_some() || !other {
            outln!("{}", mixed_text(c, trial, &off));
        }
    }
    // The robot's nodes that did not answer, by name and role.
    if let Some(c) = &c {
        for n in c
            .robot
            .nodes
            .iter()
            .filter(|n| !found.contains_key(&n.address))
        {
            let role = c.ir.roles.iter().find(|r| r.address == n.address);
            let role = role.map_or("(no role)", |r| r.name.as_str());
            outln!(
                "{:#06x}  {role}  did not answer (node {})",
                n.address,
                n.name
            );
        }
    }
    outln!("{} node(s)", found.len());
    if found.is_empty() {
        return Err(Failure::error(if radio.secured() {
            "no node answered: are they running, on this medium, and keyed by this machine \
             secret (a node drops what another machine's keys secure)?"
        } else {
            "no node answered: a node with a management key answers only secured frames \
             (pass --keys)"
        }));
    }
    Ok(())
}

pub fn push(flags: &PushArgs) -> Result<(), Failure> {
    let (robot, at) = (&flags.robot, &flags.at);
    let c = demo::generation_of(demo::load(robot)?, flags.generation)?;
    let mut targets = demo::targets(&c);
    if let Some(role) = &flags.role {
        super::known_role(robot, &c.ir, role)?;
        if let Some(node) = flags.node {
            elsewhere_without_peers(robot, &c, role, node)?;
        }
        targets.retain(|t| &t.role == role);
        if let (Some(addr), Some(t)) = (flags.node, targets.first_mut()) {
            t.addr = addr;
        }
    }
    let keys = push_keys(robot, &c, KeysFrom::resolve(flags.keys.keys.as_deref()))?;
    verify_before_push(robot, &c, flags.no_verify)?;
    let mut radio = connect_keyed(at, keys.as_ref())?;
    plain_if_off(&mut radio, &c);
    let mut ids = Ids::default();
    if let (Some(role), Security::On) = (&flags.role, c.robot.security) {
        role_alone_at_the_machines_generation(&mut radio, &mut ids, &c, role)?;
    }
    let mut outcomes = push_with_bars(&mut radio, &targets, flags.force)?;
    // Pushed again after a switch-over that did not finish: the nodes that switched run
    // this generation already.
    let table_of = |role: &str| role_table(&c, role).map(|(_, t)| t);
    let generation = c.ir.generation;
    push::running_already(
        &mut radio,
        &mut ids,
        &mut outcomes,
        (generation, flags.trial),
        table_of,
        ANSWER_WITHIN,
    )
    .map_err(|e| lost(e, Phase::Transfer))?;
    // Whether a role moves to a node that ran another (or none): then a node of the
    // robot without a role that does not answer may be the one it moved away from.
    let mut moved = false;
    if !flags.stage_only {
        moved = before_switch(&mut radio, &mut ids, &outcomes, !flags.now)?;
    }
    let verdict = if flags.stage_only {
        None
    } else {
        Some(
            push::switch_over_as(
                &mut radio,
                &mut outcomes,
                c.ir.generation,
                flags.now,
                flags.trial,
                Duration::from_secs(flags.wait),
            )
            .map_err(|e| {
                // Where each node stood when the medium was lost: what `scan` would show.
                push_lines(&outcomes);
                lost(e, Phase::Switch)
            })?,
        )
    };
    let one_role = flags.role.as_deref().map(|r| (r, c.ir.generation));
    // A robot that says `security: Off` pushed in clear: a keyed node drops it unread.
    let plain = c.robot.security == Security::Off;
    report_push(&outcomes, verdict, flags.trial, one_role, plain)?;
    if verdict == Some(Verdict::Switched) && flags.role.is_none() {
        // On trial they are released once it is confirmed: a rollback finds the machine
        // as it was.
        let how = if flags.trial {
            release::Release::AfterTrial
        } else {
            release::Release::Now { force: flags.force }
        };
        release_roleless_nodes(&mut radio, &mut ids, &c, (c.ir.generation, how), moved)?;
    }
    // A trial is watched for --watch / --watch-cycles, else for the window the robot
    // declares.
    let given = flags.watch.is_some() || flags.watch_cycles.is_some();
    let window = if given {
        push::TrialWindow {
            time: flags.watch.map(Duration::from_secs),
            cycles: flags.watch_cycles,
        }
    } else if flags.trial {
        push::TrialWindow {
            time: c
                .robot
                .trial_seconds
                .map(|s| Duration::from_secs(u64::from(s))),
            cycles: c.robot.trial_cycles,
        }
    } else {
        push::TrialWindow::default()
    };
    if window == push::TrialWindow::default() {
        return Ok(());
    }
    watch(&mut radio, &outcomes, window, flags.wait)
}

/// A trial window for people: `30 s`, `3 cycles`, `3 cycles or 30 s`.
fn window_text(window: push::TrialWindow) -> String {
    let time = window.time.map(|t| format!("{} s", t.as_secs()));
    let cycles = window.cycles.map(|n| match n {
        1 => String::from("1 cycle"),
        n => format!("{n} cycles"),
    });
    match (cycles, time) {
        (Some(c), Some(t)) => format!("{c} or {t}"),
        (Some(c), None) => c,
        (None, Some(t)) => t,
        (None, None) => String::from("ever"),
    }
}

/// `push --trial --watch S`: the trial, watched until confirmed, a fault, or its end.
fn watch(
    radio: &mut ToolRadio,
    outcomes: &[push::Pushed],
    window: push::TrialWindow,
    wait: u64,
) -> Result<(), Failure> {
    let nodes: Vec<u16> = outcomes.iter().map(|o| o.addr).collect();
    let mut ids = Ids::default();
    let first = nodes.first().copied().unwrap_or(0);
    let previous = command(radio, &mut ids, first, Command::Status)?.previous;
    outln!(
        "watching the trial for {} (rolled back to generation {previous} unless confirmed: \
         type `confirm` here, or run `config-tool confirm`)",
        window_text(window)
    );
    // `confirm` typed on standard input, or a `confirm` of another run (the key file's
    // counter is shared): the watch sees no node on trial any more.
    let asked = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let said = asked.clone();
    std::thread::spawn(move || {
        let mut stdin = io::stdin().lock();
        while let Ok(Some(line)) = operator::next_line(&mut stdin) {
            match line {
                Ok(l) if l.trim() == "confirm" => {
                    said.store(true, std::sync::atomic::Ordering::Relaxed);
                    break;
                }
                Ok(l) if l.trim().is_empty() => {}
                _ => errln!("push: type `confirm` to keep the trial"),
            }
        }
    });
    let confirm_asked = || asked.load(std::sync::atomic::Ordering::Relaxed);
    let end = push::watch_trial_for(
        radio,
        &mut ids,
        (&nodes, previous),
        window,
        (Duration::from_millis(500), Duration::from_secs(wait)),
        &confirm_asked,
    )
    .map_err(Failure::error)?;
    match end {
        push::TrialEnd::Confirmed => {
            outln!("confirmed: the trial generation stays");
            Ok(())
        }
        push::TrialEnd::Faulted { node, rolled_back } => Err(Failure {
            code: exit::PUSH_FAILED,
            ..Failure::error(format!(
                "node {node:#06x} faulted during the trial: {}",
                back_text(previous, rolled_back)
            ))
        }),
        push::TrialEnd::Reverted { node, rolled_back } => Err(Failure {
            code: exit::PUSH_FAILED,
            ..Failure::error(format!(
                "node {node:#06x} runs generation {previous} again during the trial (a power \
                 cut, or a rollback from another terminal): {}",
                back_text(previous, rolled_back)
            ))
        }),
        push::TrialEnd::Superseded { node, generation } => Err(Failure {
            code: exit::PUSH_FAILED,
            ..Failure::error(format!(
                "node {node:#06x} runs generation {generation}, pushed from another terminal \
                 during the trial: the watch ends, nothing rolled back"
            ))
        }),
        push::TrialEnd::Expired { rolled_back } => Err(Failure {
            code: exit::PUSH_FAILED,
            ..Failure::error(format!(
                "the trial was not confirmed within {}: {}",
                window_text(window),
                back_text(previous, rolled_back)
            ))
        }),
    }
}

/// How a watched trial's rollback to generation `previous` ended, in words.
fn back_text(previous: u32, rolled_back: Verdict) -> String {
    match push::rollback_verdict_text(rolled_back) {
        None => format!("every node back to generation {previous}"),
        Some(why) => format!("the rollback to generation {previous}: {why}"),
    }
}

/// The keys `push` secures with: a secured robot (the default) needs them; an unsecured one
/// (`security: Off`) is pushed without, and refuses an explicit `--keys`.
pub(crate) fn push_keys(
    robot: &Path,
    c: &robot_compiler::Compiled,
    keys: Option<KeysFrom>,
) -> Result<Option<KeysFrom>, Failure> {
    match (c.robot.security, keys) {
        (Security::On, None) => Err(Failure::usage(format!(
            "{} is secured (frame security is on unless the robot says `security: Off`): \
             pass --keys FILE, the machine secret's key file (`config-tool keys new`), or set \
             {KEYS_ENV}",
            robot.display()
        ))),
        (Security::On, keys) => Ok(keys),
        (Security::Off, Some(KeysFrom::Flag(_))) => Err(Failure::usage(format!(
            "{} says `security: Off`: its nodes are pushed and commanded unsecured; drop \
             --keys, or remove the setting to secure them",
            robot.display()
        ))),
        (Security::Off, _) => Ok(None),
    }
}

/// Role `role` of `c` and its table.
fn role_table<'c>(
    c: &'c robot_compiler::Compiled,
    role: &str,
) -> Option<(&'c robot_compiler::ir::RoleIr, &'c config_schema::Table)> {
    let i = c.ir.roles.iter().position(|r| r.name == role)?;
    Some((c.ir.roles.get(i)?, c.tables.get(i)?))
}

/// `push --role R --node N`: a role that talks with peers goes to the node the robot
/// assigns it only (they publish to, and hear from, that address); one without peers may
/// go anywhere (a role on a bench).
fn elsewhere_without_peers(
    robot: &Path,
    c: &robot_compiler::Compiled,
    role: &str,
    node: u16,
) -> Result<(), Failure> {
    let Some((r, t)) = role_table(c, role) else {
        return Ok(());
    };
    if r.address == node || t.peers.is_empty() {
        return Ok(());
    }
    let peers: Vec<String> = t.peers.iter().map(|p| format!("{p:#06x}")).collect();
    Err(Failure::usage(format!(
        "{}: role {role} talks with its peers ({}) at {:#06x}, its node in the robot: on \
         {node:#06x} it would hear none of them, nor they it; to move {role} there, assign \
         it to that node in the robot (`assign`) and push every role",
        robot.display(),
        peers.join(", "),
        r.address
    )))
}

/// Before a switch-over: the nodes that staged are asked their statuses. With
/// `refuse_faulted` (a switch-over at the idle point) faulted ones fail the push at once (a
/// faulted machine never reaches its idle point: the switch-over would wait out `--wait`
/// for nothing), every one named with the ways out; the lines of the push are printed
/// first. A node that does not answer has no say here (the switch-over finds it silent).
/// Returns whether a role moves (a node takes a role it did not run, on a machine that ran
/// a generation): then a silent node without a role may be the one it moved away from.
fn before_switch(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    outcomes: &[push::Pushed],
    refuse_faulted: bool,
) -> Result<bool, Failure> {
    let staged: Vec<&push::Pushed> = (outcomes.iter())
        .filter(|o| o.progress == Progress::Done && !o.running)
        .collect();
    if staged.is_empty() {
        return Ok(false);
    }
    let addrs: Vec<u16> = staged.iter().map(|o| o.addr).collect();
    let answers = push::statuses_of(radio, ids, &addrs, ANSWER_WITHIN)
        .map_err(|e| lost(e, Phase::Transfer))?;
    // A role moved: a node takes a role it did not run, on a machine that ran a
    // generation before (a first push configures every node: nothing moved away).
    let ran = |s: &Status| s.generation != 0;
    let moved = (answers.iter()).any(|a| a.as_ref().is_ok_and(ran))
        && (staged.iter().zip(&answers))
            .any(|(o, a)| a.as_ref().is_ok_and(|s| s.role.as_str() != o.role));
    let faulted: Vec<(u16, &str, u8)> = (staged.iter().zip(answers))
        .filter_map(|(o, a)| Some((o.addr, o.role.as_str(), a.ok()?.fault?)))
        .collect();
    let Some(why) = home::faulted_push_text(&faulted).filter(|_| refuse_faulted) else {
        return Ok(moved);
    };
    push_lines(outcomes);
    Err(Failure {
        code: exit::PUSH_FAILED,
        ..Failure::error(why)
    })
}

/// After a switch-over (or a confirmed trial): the robot's nodes that play no role in it
/// and still run a table, released or named as `how` says ([`release::roleless`]), a line
/// each. The machine's own switch-over is over by then: a failure here says so.
fn release_roleless_nodes(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &robot_compiler::Compiled,
    (generation, how): (u32, release::Release),
    name_silent: bool,
) -> Result<(), Failure> {
    let lines = release::roleless(radio, ids, c, generation, how, name_silent)
        .map_err(|e| lost(e, Phase::Release))?;
    for line in lines {
        outln!("{line}");
    }
    Ok(())
}

/// `push --role` of a secured robot: the role's node must take the generation its peers
/// run (each generation has link keys of its own), so the robot's other roles' nodes are
/// asked theirs first; refused (status 6, nothing sent) at another. Nodes that do not
/// answer, or run another robot's role, have no say; a role without peers goes at any.
fn role_alone_at_the_machines_generation(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &robot_compiler::Compiled,
    role: &str,
) -> Result<(), Failure> {
    // A role without peers shares no link keys: any generation will do.
    if role_table(c, role).is_none_or(|(_, t)| t.peers.is_empty()) {
        return Ok(());
    }
    let roles: Vec<_> = c.ir.roles.iter().filter(|r| r.name != role).collect();
    let addrs: Vec<u16> = roles.iter().map(|r| r.address).collect();
    let answers = push::statuses_of(radio, ids, &addrs, ANSWER_WITHIN).map_err(Failure::error)?;
    let others: Vec<(u16, u32, bool)> = (roles.iter().zip(answers))
        .filter_map(|(r, a)| {
            let s = a.ok().filter(|s| s.role.as_str() == r.name)?;
            Some((r.address, s.generation, s.trial))
        })
        .collect();
    match home::role_alone_refusal(role, c.ir.generation, &others) {
        Some(why) => Err(Failure::refused(format!("{why}; nothing was sent"))),
        None => Ok(()),
    }
}

/// `verify` on the whole robot (every role, whatever `--role` says), with `verify`'s
/// defaults, before any node is contacted: a robot that fails is refused with the report
/// `verify` prints (its counterexample) and `verify`'s status; one that passes gets a line.
/// `--no-verify` skips it, and says so.
fn verify_before_push(
    robot: &Path,
    c: &robot_compiler::Compiled,
    skip: bool,
) -> Result<(), Failure> {
    let name = robot.display();
    if skip {
        errln!("warning: push --no-verify: {name} was not verified");
        return Ok(());
    }
    let unverified = "nothing was sent (--no-verify pushes it unverified)";
    let verified = offline::verification(&name.to_string(), c, VerifyHow::default())
        .map_err(|e| Failure::error(format!("{name}: verify cannot run: {e}; {unverified}")))?;
    let report = verified.deciding();
    if report.ok() {
        outln!("{}", verified.passed_line());
        return Ok(());
    }
    out!("{}", verified.text);
    let why = match &report.violation {
        Some(v) => format!("fails verify ({})", v.property),
        None => format!(
            "was not verified: verify stopped at {} states without an answer",
            report.states
        ),
    };
    Err(Failure::error(format!("{name} {why}: {unverified}")))
}

fn bars(targets: &[push::Target]) -> (MultiProgress, Vec<ProgressBar>) {
    let multi = MultiProgress::new();
    let style = ProgressStyle::with_template("{prefix:>8} [{bar:30}] {pos:>5}/{len} bytes {msg}")
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
    let bars = targets
        .iter()
        .map(|t| {
            let b = multi.add(ProgressBar::new(t.blob.len() as u64));
            b.set_style(style.clone());
            b.set_prefix(format!("{} {:#06x}", t.role, t.addr));
            b
        })
        .collect();
    (multi, bars)
}

/// The phases of a push.
#[derive(Debug, Clone, Copy)]
enum Phase {
    Transfer,
    Switch,
    /// Releasing the nodes that play no role, after the machine switched.
    Release,
}

/// A push's radio failed (the medium closed the connection: a gateway unplugged): what
/// that leaves the machine in and what to do, status 3.
fn lost(e: std::io::Error, phase: Phase) -> Failure {
    let what = match phase {
        Phase::Transfer => format!(
            "{e} during the transfer: nothing switched (what a node staged, it keeps): push \
             again"
        ),
        Phase::Switch => format!(
            "{e} during the switch-over: nodes may run different generations (`scan` shows \
             each one's): push again to finish it, or roll back"
        ),
        Phase::Release => format!(
            "{e} while releasing the nodes that play no role: the machine itself switched; \
             push again to release them"
        ),
    };
    Failure {
        code: exit::PUSH_FAILED,
        ..Failure::error(what)
    }
}

fn push_with_bars(
    radio: &mut ToolRadio,
    targets: &[push::Target],
    force: bool,
) -> Result<Vec<push::Pushed>, Failure> {
    let (_multi, bars) = bars(targets);
    let outcomes = push::push(radio, targets, force, &mut |i, acked, _| {
        if let Some(b) = bars.get(i) {
            b.set_position(acked as u64);
        }
    })
    .map_err(|e| lost(e, Phase::Transfer))?;
    for (b, o) in bars.iter().zip(&outcomes) {
        b.finish_with_message(o.verdict());
    }
    Ok(outcomes)
}

/// A push's lines: one per node (where it stands), then the summary.
fn push_lines(outcomes: &[push::Pushed]) {
    for o in outcomes {
        outln!("{}", demo::push_line(o));
    }
    outln!("{}", demo::push_summary(outcomes));
}

/// `push`'s report: a line per node, the summary, how the switch-over ended; `one_role`:
/// only that role was pushed, as that generation (`--role`).
fn report_push(
    outcomes: &[push::Pushed],
    verdict: Option<Verdict>,
    trial: bool,
    one_role: Option<(&str, u32)>,
    plain: bool,
) -> Result<(), Failure> {
    push_lines(outcomes);
    if !outcomes.iter().all(|o| o.progress == Progress::Done) {
        let silent = outcomes.iter().any(|o| o.progress == Progress::GaveUp);
        // Refused as not newer than what a node runs: the generation to give.
        let newest = (outcomes.iter())
            .filter_map(|o| match o.progress {
                Progress::Refused(Refusal::Stale { running }) if !o.running => Some(running),
                _ => None,
            })
            .max();
        let hint = if plain && silent {
            "; the robot says `security: Off`, so its tables went in clear: a node with a \
             management key takes only secured frames (push a robot with security on, with \
             --keys)"
                .to_string()
        } else if let Some(running) = newest {
            format!(
                "; a node runs generation {running}: push with --generation {}",
                running.saturating_add(1)
            )
        } else {
            String::new()
        };
        return Err(Failure {
            code: exit::PUSH_FAILED,
            ..Failure::error(format!(
                "not every node staged its table: nothing switched{hint}"
            ))
        });
    }
    let failed = |what: &str| {
        Err(Failure {
            code: exit::PUSH_FAILED,
            ..Failure::error(what)
        })
    };
    if !outcomes.is_empty() && outcomes.iter().all(|o| o.running) {
        outln!("every node runs this generation's table already: nothing to switch");
        return Ok(());
    }
    match verdict {
        None => {
            outln!("staged on every node: `push` the same generation again to switch");
            Ok(())
        }
        Some(Verdict::Switched) if trial => {
            outln!(
                "switched on trial: `config-tool confirm` keeps it; a power cut or \
                 `config-tool rollback` returns to the previous generation"
            );
            Ok(())
        }
        Some(Verdict::Switched) => {
            match one_role {
                Some((role, generation)) => outln!(
                    "switched: {role}'s node runs generation {generation} (the robot's other \
                     nodes run theirs)"
                ),
                None => outln!("switched: every node runs the new generation"),
            };
            Ok(())
        }
        Some(Verdict::NotIdle) => {
            let under_way: Vec<String> = (outcomes.iter())
                .filter(|o| o.not_idle)
                .map(|o| format!("{:#06x} ({})", o.addr, o.role))
                .collect();
            let who = match under_way.as_slice() {
                [] => String::from(":"),
                [one] => format!(": {one} was not at its idle point;"),
                many => format!(": {} were not at their idle points;", many.join(", ")),
            };
            failed(&format!(
                "the machine was not idle within --wait{who} nothing switched (the tables stay \
                 staged; push again, or --now for a stopped machine)"
            ))
        }
        Some(Verdict::Aborted) => failed(concat!(
            "a node refused or stopped answering before the switch: nothing switched (the ",
            "tables stay staged)"
        )),
        Some(Verdict::Partial) | Some(Verdict::Busy) => failed(concat!(
            "the switch-over did not finish: the nodes marked `staged, not switched` run the ",
            "old generation; push again to finish it (or --now)"
        )),
    }
}

pub fn status(
    robot: Option<&Path>,
    at: &MediumAddr,
    node: u16,
    keys: &KeysArg,
) -> Result<(), Failure> {
    let c = robot.map(demo::load).transpose()?;
    let mut radio = connect_maybe_robot(at, robot.zip(c.as_ref()), keys)?;
    let mut ids = Ids::default();
    let s = command(&mut radio, &mut ids, node, Command::Status)?;
    let r = security(&mut radio, &mut ids, node)?;
    outln!("{}", show::status_text(node, &s));
    outln!("{}", show::security_text(&r));
    if let Some(c) = &c {
        outln!("  homing: {}", standing_text(c, node, &s));
    }
    Ok(())
}

/// Whether node `node` (status `s`) of robot `c` is homed, in words.
fn standing_text(c: &robot_compiler::Compiled, node: u16, s: &Status) -> String {
    let role =
        c.ir.roles
            .iter()
            .zip(&c.tables)
            .find(|(r, _)| r.address == node);
    match role {
        Some((r, t)) => {
            let standing = home::standing(&r.name, t, s);
            let text = match standing {
                home::Standing::NotHomed => "not homed (config-tool home)".to_string(),
                other => other.text(),
            };
            // Its links, only if it runs this robot's table (whose peers name them).
            match home::link_note(node, t, s).filter(|_| standing != home::Standing::Other) {
                Some(links) => format!("{text}; {links}"),
                None => text,
            }
        }
        None if release::plays_no_role(c, node) => match s.role.is_empty() {
            true => "plays no role in this robot".to_string(),
            false => release::stale_text(&s.role, s.generation),
        },
        None => "not a node of this robot".to_string(),
    }
}

/// The status of `node` if it is a node of robot `c`'s roles (`None`: another node).
fn robot_status(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &robot_compiler::Compiled,
    node: u16,
) -> Result<Option<Status>, Failure> {
    if !c.ir.roles.iter().any(|r| r.address == node) {
        return Ok(None);
    }
    command(radio, ids, node, Command::Status).map(Some)
}

/// `scan`'s line for a robot whose nodes run different generations: those on trial run
/// `trial` (if any), `off` are the others with theirs.
fn mixed_text(c: &robot_compiler::Compiled, trial: Option<u32>, off: &[(u16, u32)]) -> String {
    let who = |addr: u16| {
        let role = c.ir.roles.iter().find(|r| r.address == addr);
        format!("{addr:#06x} ({})", role.map_or("?", |r| r.name.as_str()))
    };
    let off: Vec<String> = off
        .iter()
        .map(|&(a, g)| format!("{} runs generation {g}", who(a)))
        .collect();
    home::generations_text(trial, &off)
}

/// A role's node and its status: (role, address, status).
type RoleStatus = (String, u16, Status);

/// The radio, the robot `flags.robot` and the statuses of every node of it.
fn machine(
    flags: &MachineArgs,
) -> Result<(ToolRadio, robot_compiler::Compiled, Vec<RoleStatus>), Failure> {
    let c = demo::load(&flags.robot)?;
    let mut radio = connect_robot(&flags.at, &flags.robot, &c, &flags.keys)?;
    let mut ids = Ids::default();
    let statuses = robot_statuses(&mut radio, &mut ids, &c, "nothing was sent")?;
    let nodes = (c.ir.roles.iter().zip(statuses))
        .map(|(r, s)| (r.name.clone(), r.address, s))
        .collect();
    Ok((radio, c, nodes))
}

/// Which generation(s) the robot's nodes run ([`home::generations`]: `Mixed` is a trial a
/// power cut split, or a switch-over that did not finish).
fn generations(nodes: &[RoleStatus]) -> Option<home::Generations> {
    let statuses: Vec<(u16, &Status)> = nodes.iter().map(|n| (n.1, &n.2)).collect();
    home::generations(&statuses)
}

/// `confirm`: the generation on trial stays.
pub fn confirm(flags: &MachineArgs) -> Result<(), Failure> {
    let (mut radio, c, nodes) = machine(flags)?;
    let trial: Vec<u16> = nodes.iter().filter(|n| n.2.trial).map(|n| n.1).collect();
    if trial.is_empty() {
        outln!("nothing on trial: every node's generation is confirmed");
        return Ok(());
    }
    // A trial of another table (the robot's roles, another robot's tables) is not the
    // one this robot's file stands for: confirming it would keep what was not asked.
    let other = (nodes.iter().zip(&c.tables)).find(|((_, _, s), t)| s.trial && !home::runs(t, s));
    if let Some(((role, addr, s), _)) = other {
        return Err(Failure::refused(format!(
            "node {addr:#06x} ({role}) runs generation {} on trial, not this robot's table: \
             nothing confirmed (confirm with the robot that was pushed)",
            s.generation
        )));
    }
    // A node that left the trial (a power cut) runs another generation: confirming the
    // others would leave the machine on two.
    if let Some(home::Generations::Mixed {
        trial: Some(generation),
        off,
    }) = generations(&nodes)
    {
        for (role, addr, s) in &nodes {
            let what = match off.iter().find(|o| o.0 == *addr) {
                Some(_) => format!("generation {}  NOT on trial", s.generation),
                None => format!("generation {generation}  on trial"),
            };
            outln!("  {role:<6} {addr:#06x}  {what}");
        }
        return Err(Failure {
            code: exit::PUSH_FAILED,
            ..Failure::error(format!(
                "not every node runs generation {generation} on trial (a power cut returns a \
                 node to its previous generation): nothing confirmed; `config-tool rollback` \
                 returns the others to theirs"
            ))
        });
    }
    let generation = nodes
        .iter()
        .find(|n| n.2.trial)
        .map_or(0, |n| n.2.generation);
    let answers =
        push::confirm(&mut radio, &trial, generation, ANSWER_WITHIN).map_err(Failure::error)?;
    let mut all = true;
    for (role, addr, _) in nodes.iter().filter(|n| n.2.trial) {
        let answer = answers.iter().find(|a| a.0 == *addr).and_then(|a| a.1);
        let what = match answer {
            Some(ConfigReply::Confirmed) => "confirmed".to_string(),
            Some(ConfigReply::Refused(why)) => {
                all = false;
                format!("NOT confirmed: refused: {why}")
            }
            Some(other) => {
                all = false;
                format!("NOT confirmed: answered {other:?}")
            }
            None => {
                all = false;
                "NOT confirmed: no answer".to_string()
            }
        };
        outln!("  {role:<6} {addr:#06x}  generation {generation}  {what}");
    }
    if all {
        // The trial kept: the nodes that play no role in it are released now.
        let how = release::Release::Now { force: false };
        release_roleless_nodes(
            &mut radio,
            &mut Ids::default(),
            &c,
            (generation, how),
            false,
        )
    } else {
        Err(Failure {
            code: exit::PUSH_FAILED,
            ..Failure::error(
                "not every node confirmed: a power cut returns those to the previous generation",
            )
        })
    }
}

/// `rollback`: every node back to its previous generation, together.
pub fn rollback(flags: &SwitchArgs) -> Result<(), Failure> {
    let (mut radio, _, nodes) = machine(&flags.machine)?;
    // Nodes off the machine's generation (a trial a power cut split, a switch-over that
    // did not finish) run the previous generation already; the others return to it.
    let back: Vec<u16> = match generations(&nodes) {
        Some(home::Generations::Mixed { off, .. }) => off.iter().map(|o| o.0).collect(),
        _ => Vec::new(),
    };
    let moving: Vec<&RoleStatus> = nodes.iter().filter(|n| !back.contains(&n.1)).collect();
    let previous: Vec<u32> = moving.iter().map(|n| n.2.previous).collect();
    let target = previous.first().copied().unwrap_or(0);
    let back_on_target = nodes
        .iter()
        .filter(|n| back.contains(&n.1))
        .all(|n| n.2.generation == target && !n.2.trial);
    if target == 0 || previous.iter().any(|&p| p != target) || !back_on_target {
        let each: Vec<String> = nodes
            .iter()
            .map(|(role, _, s)| format!("{role} {}", s.previous))
            .collect();
        return Err(Failure::error(format!(
            "no common previous generation to return to (per node: {})",
            each.join(", ")
        )));
    }
    // A faulted machine never reaches its idle point: said at once, not after --wait.
    let faulted: Vec<(u16, &str, u8)> = (moving.iter())
        .filter_map(|(role, addr, s)| Some((*addr, role.as_str(), s.fault?)))
        .collect();
    if let Some(why) = home::faulted_rollback_text(&faulted).filter(|_| !flags.now) {
        return Err(Failure {
            code: exit::PUSH_FAILED,
            ..Failure::error(why)
        });
    }
    let addrs: Vec<u16> = moving.iter().map(|n| n.1).collect();
    let (verdict, states) = push::rollback(
        &mut radio,
        &addrs,
        target,
        flags.now,
        Duration::from_secs(flags.wait),
    )
    .map_err(Failure::error)?;
    for (role, addr, _) in &nodes {
        let state = states.iter().find(|s| s.0 == *addr).map(|s| s.1);
        let what = match state {
            _ if back.contains(addr) => "on it already".to_string(),
            state => push::rollback_state_text(state),
        };
        outln!("  {role:<6} {addr:#06x}  generation {target}  {what}");
    }
    match push::rollback_verdict_text(verdict) {
        None => Ok(()),
        Some(why) => Err(Failure {
            code: exit::PUSH_FAILED,
            ..Failure::error(why)
        }),
    }
}

/// `start`: START to `node`, or with the robot to its start role's node once every node
/// of it is homed, at rest and not faulted (refused otherwise: nothing is sent).
pub fn start(
    robot: Option<&Path>,
    at: &MediumAddr,
    node: Option<u16>,
    keys: &KeysArg,
) -> Result<(), Failure> {
    let c = robot.map(demo::load).transpose()?;
    let start_role = c.as_ref().and_then(|c| {
        let (role, _) = c.ir.start.as_ref()?;
        c.ir.roles.get(*role)
    });
    let start_node = start_role.map(|r| r.address);
    // With the robot, START goes to its start input: another node's charts take none
    // (it said "started" with the machine at rest), and any other address is not the
    // robot's.
    if let (Some(c), Some(n)) = (&c, node) {
        if let Some(r) = start_role.filter(|r| r.address != n) {
            return Err(Failure::usage(format!(
                "--node {n:#06x}: the robot's START input is on node {:#06x} (role {}), \
                 where START goes (leave out --node)",
                r.address, r.name
            )));
        }
        if !c.ir.roles.iter().any(|r| r.address == n) {
            return Err(Failure::usage(format!(
                "--node {n:#06x} is no node of robot `{}`",
                c.ir.name
            )));
        }
    }
    let node = node.or(start_node).ok_or_else(|| {
        Failure::usage("the robot has no start input: give the node to START with --node")
    })?;
    // With the robot, its security decides, as for `home` and `ack`: a secured robot's
    // nodes take only secured frames.
    let mut radio = connect_maybe_robot(at, robot.zip(c.as_ref()), keys)?;
    let mut ids = Ids::default();
    if let Some(c) = &c {
        let statuses = robot_statuses(&mut radio, &mut ids, c, "START was not sent")?;
        let standing = home::nodes(c, &statuses);
        // A machine only not homed: a latched fault alarm is said first (acknowledging it
        // comes before homing, which refuses it).
        let not_homed = home::only_not_homed(&standing);
        let refusal = home::refusal(&standing, false);
        if let (Some(why), false) = (&refusal, not_homed) {
            return Err(Failure::refused(format!("{why}; START was not sent")));
        }
        let (nodes, silent) = node_alarms(&mut radio, &mut ids, c, Command::Alarms)?;
        if let Some(n) = silent.first() {
            return Err(Failure::error(n.failure("START was not sent")));
        }
        if let Some(why) = alarms::blocking_text(c, &nodes) {
            let then = if not_homed {
                ", then home (config-tool home)"
            } else {
                ""
            };
            return Err(Failure::refused(format!("{why}{then}; START was not sent")));
        }
        if let Some(why) = refusal {
            return Err(Failure::refused(format!("{why}; START was not sent")));
        }
        home::after_greetings(&mut radio, nodes.iter().map(|n| n.report.now_ms))?;
    }
    command(&mut radio, &mut ids, node, Command::Start)?;
    if c.is_some() {
        outln!("{node:#06x}: started");
    } else {
        // Unchecked: the node took the command, which does not say it started anything.
        outln!(
            "{node:#06x}: START acknowledged (unchecked without the robot: a node not homed, \
             under way or faulted ignores it)"
        );
    }
    Ok(())
}

/// Every node's alarms of robot `c` (`Command::Alarms`, or `Command::Ack` to acknowledge),
/// and the nodes that did not answer: one silent node does not hide the others'.
fn node_alarms(
    radio: &mut ToolRadio,
    ids: &mut Ids,
    c: &robot_compiler::Compiled,
    cmd: Command,
) -> Result<(Vec<alarms::NodeAlarms>, Vec<alarms::Silent>), Failure> {
    // Each answer stamped as it comes: the node's alarm ages count back from then (after
    // every node answered, a silent one's wait moved every alarm 5 s later).
    let stamped = |m: Message<'_>, id: u16| {
        push::alarms_answer(m, id).map(|report| (report, std::time::SystemTime::now()))
    };
    let answers = ask_every_role(radio, ids, c, cmd, stamped)?;
    let (mut out, mut silent) = (Vec::new(), Vec::new());
    for (r, answer) in c.ir.roles.iter().zip(answers) {
        match answer {
            Ok((report, read_at)) => out.push(alarms::NodeAlarms {
                role: r.name.clone(),
                addr: r.address,
                report,
                read_at,
            }),
            Err(asked) => silent.push(alarms::Silent {
                role: r.name.clone(),
                addr: r.address,
                asked,
                within: ANSWER_WITHIN,
            }),
        }
    }
    Ok((out, silent))
}

/// The robot, and the tool's radio to its nodes with the robot's keys.
fn robot_radio(
    robot: &Path,
    at: &MediumAddr,
    keys: &KeysArg,
) -> Result<(robot_compiler::Compiled, ToolRadio), Failure> {
    let c = demo::load(robot)?;
    let radio = connect_robot(at, robot, &c, keys)?;
    Ok((c, radio))
}

/// `alarms`: every node's alarms; with `watch`, again whenever they change (until
/// interrupted).
pub fn alarms(robot: &Path, at: &MediumAddr, keys: &KeysArg, watch: bool) -> Result<(), Failure> {
    let (c, mut radio) = robot_radio(robot, at, keys)?;
    let mut ids = Ids::default();
    let mut last: Vec<String> = Vec::new();
    loop {
        let (nodes, silent) = node_alarms(&mut radio, &mut ids, &c, Command::Alarms)?;
        // Compared without the wall time (it moves with every read).
        let now: Vec<String> = alarms::lines(&c, &nodes, &silent);
        let key = |l: &[String]| -> Vec<String> {
            l.iter()
                .map(|x| x.split("UTC").last().unwrap_or(x).to_string())
                .collect()
        };
        if key(&now) != key(&last) {
            let mut read = true;
            if watch && !last.is_empty() {
                read &= outln!("--");
            }
            for l in &now {
                read &= outln!("{l}");
            }
            // Watching for a reader that went away (`alarms --watch | head`): done.
            if !read {
                return Ok(());
            }
            last = now;
        }
        if !watch {
            return match silent.first() {
                Some(n) => Err(Failure::error(n.failure("its alarms are not shown"))),
                None => Ok(()),
            };
        }
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// `ack`: acknowledge on every node; print what stayed and why (exit 6 if a fault alarm
/// stayed).
pub fn ack(robot: &Path, at: &MediumAddr, keys: &KeysArg) -> Result<(), Failure> {
    let (c, mut radio) = robot_radio(robot, at, keys)?;
    let mut ids = Ids::default();
    // What was acknowledged already, so that only what this `ack` did is counted.
    let (before, _) = node_alarms(&mut radio, &mut ids, &c, Command::Alarms)?;
    let (nodes, silent) = node_alarms(&mut radio, &mut ids, &c, Command::Ack)?;
    // Node by node: each answer beside what the same node said before (no alarm, if it
    // did not answer then).
    let (before, after): (Vec<_>, Vec<_>) = nodes
        .iter()
        .map(|n| {
            let mut was = n.report.clone();
            was.alarms = (before.iter().find(|b| b.addr == n.addr))
                .map(|b| b.report.alarms.clone())
                .unwrap_or_default();
            (was, n.report.clone())
        })
        .unzip();
    outln!("{}", home::acknowledged(&before, &after));
    let stayed = alarms::stayed(&c, &nodes);
    for l in &stayed {
        outln!("{l}");
    }
    for n in &silent {
        outln!("{}", n.line());
    }
    if let Some(why) = alarms::blocking_text(&c, &nodes) {
        return Err(Failure::refused(format!(
            "{why}: the machine cannot restart"
        )));
    }
    match silent.first() {
        Some(n) => Err(Failure::error(
            n.failure("its alarms were not acknowledged"),
        )),
        None => Ok(()),
    }
}

/// `home`: HOME to the robot's home role's node, then every node's status until each
/// chart rests in its idle state (homed), a node faults, or `--wait` passes.
pub fn home(flags: &HomeArgs) -> Result<(), Failure> {
    let c = demo::load(&flags.robot)?;
    let keys = push_keys(
        &flags.robot,
        &c,
        KeysFrom::resolve(flags.keys.keys.as_deref()),
    )?;
    if c.ir.home.is_none() {
        // Only a sequence robot has a homing sequence: nothing to do, as `scan` says.
        outln!(
            "nothing to home: {} has no homing sequence (its nodes start at rest): start it",
            flags.robot.display()
        );
        return Ok(());
    }
    let mut radio = connect_keyed(&flags.at, keys.as_ref())?;
    plain_if_off(&mut radio, &c);
    let mut ids = Ids::default();
    // Every node answers first (else HOME is not sent, and the silent node is named).
    let before = robot_statuses(&mut radio, &mut ids, &c, "HOME was not sent")?;
    let (end, took) = home::home_from(
        &mut radio,
        &mut ids,
        &c,
        &before,
        (ANSWER_WITHIN, Duration::from_secs(flags.wait)),
        &mut || {
            outln!("{}", demo::homing_line(&c));
        },
    )?;
    match end {
        home::HomeEnd::Homed => {
            outln!("homed: every chart idle in {:.2} s", took.as_secs_f64());
            Ok(())
        }
        home::HomeEnd::Refused(why) => Err(Failure::refused(format!("{why}; HOME was not sent"))),
        home::HomeEnd::Ignored { role, addr } => Err(Failure::refused(format!(
            "node {addr:#06x} ({role}) did not start homing (armed for a switch-over?): \
             finish the push first"
        ))),
        home::HomeEnd::Faulted {
            role,
            addr,
            code,
            others,
        } => Err(Failure {
            code: exit::FAULTED,
            ..Failure::error(home::homing_faulted_text(
                &role,
                addr,
                code,
                &demo::fault_meaning(code),
                &others,
            ))
        }),
        home::HomeEnd::NotDone(waiting) => Err(Failure::error(format!(
            "homing did not end within {} s: {}",
            flags.wait,
            waiting.join(", ")
        ))),
    }
}

pub fn reset(at: &MediumAddr, node: u16, keys: &KeysArg) -> Result<(), Failure> {
    let mut radio = connect_keyed(at, KeysFrom::resolve(keys.keys.as_deref()).as_ref())?;
    let s = command(&mut radio, &mut Ids::default(), node, Command::Reset)?;
    outln!("{}", show::reset_text(node, &s));
    Ok(())
}

/// `plant`: the robot's machine on the medium, in real time; prints every step.
pub fn plant(robot: &Path, at: &MediumAddr) -> Result<(), Failure> {
    let c = demo::load(robot)?;
    let actuators = live_plant::actuators(&c)?;
    for a in &actuators {
        outln!(
            "{:<4} on node {:#06x}: valves {:?}, home {:?}, end {:?}",
            a.name,
            a.addr,
            a.valves,
            a.home,
            a.end
        );
    }
    if at.serial.is_some() {
        return Err(Failure::error(
            "the plant is the simulated machine: it needs a medium, not --serial",
        ));
    }
    let medium = at.medium;
    let motors = robot_net::live_motor::motors(&c)?;
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let (steps_tx, steps) = std::sync::mpsc::channel();
    // The medium going away, whenever the plant meets it (attaching, or running).
    let gone = || {
        Failure::error(format!(
            "plant on {medium}: the medium {}",
            closed_why(medium)
        ))
    };
    let failed = move |e: io::Error| match medium::went_away(&e) {
        true => gone(),
        false => Failure::error(format!("plant on {medium}: {e}")),
    };
    // What else the plant reports, in words, beside the steps (balls, motors).
    let (said_tx, said) = std::sync::mpsc::channel::<(Duration, String)>();
    let said_steps = said_tx.clone();
    // The operator's requests to the motors (its contacts and buttons, from standard
    // input): the plant runs while their sender lives, after the input ends too.
    let mut _operator = None;
    // The medium's clock zero: what the plant says beside the steps is stamped on it.
    let medium_start = || {
        live_plant::medium_start(medium, Duration::from_secs(2))
            .map_err(failed)?
            .ok_or_else(|| {
                Failure::error(format!(
                    "plant on {medium}: the medium did not tell its clock"
                ))
            })
    };
    let handle = if let Some(s) = &c.robot.sorting {
        // A sorting station: the robot's feed at its sensors, each ball's landing said.
        let balls = robot_net::live_feed::ball_feed(&c, &actuators, &s.feed)?;
        let start = medium_start()?;
        let conn = live_plant::attach_fed(medium, &actuators, &balls).map_err(failed)?;
        outln!("feed: {} ball(s): {}", s.feed.len(), s.feed.join(" "));
        let (landed_tx, landed) = std::sync::mpsc::channel::<robot_net::live_feed::Landing>();
        let feed = s.feed.clone();
        std::thread::spawn(move || {
            for l in landed {
                let colour = feed.get(l.ball).map_or("?", String::as_str);
                let mut line = format!("ball {} ({colour}) landed in bin {}", l.ball + 1, l.bin);
                for g in &l.met_moving {
                    line.push_str(&format!("; it met gate {g} moving"));
                }
                let _ = said_tx.send((l.at, line));
            }
        });
        let flag = stop.clone();
        std::thread::spawn(move || {
            live_plant::run_fed(conn, actuators, (balls, start), landed_tx, steps_tx, flag)
        })
    } else if !motors.motors.is_empty() || !motors.inputs.is_empty() {
        // Motors: their carriages timed on the medium's clock, each motion said.
        let start = medium_start()?;
        let conn = live_plant::attach_motors(medium, &actuators, &motors).map_err(failed)?;
        let (operate, operated) = std::sync::mpsc::channel();
        if !motors.inputs.is_empty() {
            // The operator's inputs, a line of standard input each (its end leaves them
            // where they are: the plant runs on).
            outln!("{}", operator::usage(&motors.inputs));
            let (inputs, to_plant) = (motors.inputs.clone(), operate.clone());
            std::thread::spawn(move || {
                let mut stdin = io::stdin().lock();
                while let Ok(Some(line)) = operator::next_line(&mut stdin) {
                    match line.and_then(|l| operator::parse(&inputs, &l)) {
                        Ok(Some(op)) => {
                            if to_plant.send(op).is_err() {
                                break;
                            }
                        }
                        Ok(None) => {}
                        Err(why) => errln!("plant: refused: {why}"),
                    }
                }
            });
        }
        _operator = Some(operate);
        let (seen_tx, seen) = std::sync::mpsc::channel();
        let names: Vec<String> = motors.motors.iter().map(|m| m.name.clone()).collect();
        let inputs = motors.inputs.clone();
        std::thread::spawn(move || {
            use robot_net::live_motor::Motion;
            for m in seen {
                let (line, at) = match m {
                    Motion::Run { motor, run, at, .. } => {
                        let name = names.get(motor).map_or("?", String::as_str);
                        (format!("{name} {}", demo::Moved::Run(run)), at)
                    }
                    Motion::Arrived { motor, end, at } => {
                        let name = names.get(motor).map_or("?", String::as_str);
                        (format!("{name} {}", demo::Moved::Arrived(end)), at)
                    }
                    Motion::Input { input, level, at } => {
                        match inputs.get(input).and_then(|i| operator::said(i, level)) {
                            Some(line) => (line, at),
                            None => continue,
                        }
                    }
                    Motion::Held { .. } => continue,
                };
                let _ = said_tx.send((at, line));
            }
        });
        let flag = stop.clone();
        let plant = (motors, operated, seen_tx, start);
        std::thread::spawn(move || live_plant::run_motors(conn, actuators, plant, steps_tx, flag))
    } else {
        drop(said_tx);
        let conn = live_plant::attach(medium, &actuators).map_err(failed)?;
        let flag = stop.clone();
        std::thread::spawn(move || live_plant::run_attached(conn, actuators, None, steps_tx, flag))
    };
    outln!("plant on {medium}: the nodes' switches set, waiting for their outputs");
    // The steps said as the rest is, in the order they come, until the plant ends (and
    // with it every sender).
    std::thread::spawn(move || {
        for step in steps {
            let _ = said_steps.send((step.at, step.to_string()));
        }
    });
    for (at, line) in said {
        outln!("{:>9.3}  {line}", at.as_secs_f64());
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    // The plant runs until the medium ends its connection (or an error ends it): it never
    // stops of itself, so an end is the medium gone.
    match handle.join() {
        Ok(Ok(())) => Err(gone()),
        Ok(Err(e)) => Err(failed(e)),
        Err(_) => Err(Failure::error("the plant stopped")),
    }
}

/// Why the medium at `medium` closed a plant's or monitor's connection: it went away, or,
/// since it still welcomes a client, it dropped that one for falling behind (it does so to
/// a plant or monitor that does not read its frames: `monitor | less` left on a page).
fn closed_why(medium: SocketAddr) -> &'static str {
    match Conn::join(medium, Peer::Monitor) {
        Ok(_) => {
            "dropped this connection: it did not read fast enough (the medium drops a plant \
             or monitor that falls behind; it still runs)"
        }
        Err(_) => "closed the connection (it went away)",
    }
}

/// `monitor`: every frame (decoded; secured ones opened with the keys of `keys`, the
/// machine secret's file) and pin change on the medium, on the medium's clock: pin changes
/// as the medium stamped them, frames (and generation changes) at the time they reached
/// the monitor, from the medium's clock asked at the start (`Link::Clock`).
pub fn monitor(
    at: &MediumAddr,
    for_: Option<Duration>,
    keys: Option<&Path>,
    generation: Option<u32>,
) -> Result<(), Failure> {
    let secret = keys
        .map(robot_keys::load_machine_secret)
        .transpose()
        .map_err(|e| Failure::error(e.to_string()))?;
    let mut sniffer = robot_net::sniff::Sniffer::new(secret, generation);
    let medium = resolve(at)?;
    let mut conn = Conn::join(medium, Peer::Monitor)
        .map_err(|e| Failure::error(format!("cannot reach the medium at {medium}: {e}")))?;
    let asked = Instant::now();
    conn.send(&Link::Clock)
        .map_err(|e| Failure::error(format!("monitor: {e}")))?;
    let end = for_.map(|d| robot_net::deadline(asked, d));
    // The medium's clock once its answer came; what is heard before waits for it (a
    // medium that does not answer within `CLOCK_WITHIN`: the monitor's own, from its start).
    let mut clock: Option<MediumClock> = None;
    let mut early: Vec<(Stamp, String)> = Vec::new();
    // Each pin's last level seen: a level told again (a plant repeats its switches'
    // levels) is no change.
    let mut levels: std::collections::HashMap<(u16, u8, bool), bool> = Default::default();
    loop {
        let mut until = end.unwrap_or_else(|| Instant::now() + Duration::from_secs(3600));
        if clock.is_none() {
            until = until.min(asked + CLOCK_WITHIN);
        }
        let got = conn.recv(until, |link| {
            let here = Stamp::Here(Instant::now());
            Some(match link {
                Link::Now { at_us } => Heard::Now(at_us, Instant::now()),
                Link::Frame(psdu) => Heard::Line(here, sniffer.describe(psdu)),
                Link::Seen {
                    addr,
                    pin,
                    level,
                    output,
                    ..
                } if levels.insert((addr, pin, output), level) == Some(level) => return None,
                Link::Seen {
                    at_us,
                    addr,
                    pin,
                    level,
                    output,
                } => Heard::Line(
                    Stamp::Medium(at_us),
                    format!(
                        "pin {addr:#06x}.{pin} = {} ({})",
                        u8::from(level),
                        if output { "output" } else { "input" }
                    ),
                ),
                Link::Running { addr, generation } => Heard::Line(
                    here,
                    format!("node {addr:#06x} runs generation {generation}"),
                ),
                _ => return None,
            })
        });
        let heard = match got {
            Ok(heard) => heard,
            Err(e) if medium::went_away(&e) => {
                return Err(Failure::error(format!(
                    "monitor: the medium at {medium} {}",
                    closed_why(medium)
                )))
            }
            Err(e) => return Err(Failure::error(format!("monitor: {e}"))),
        };
        let mut lines = Vec::new();
        match (heard, &clock) {
            (Some(Heard::Now(at_us, received)), None) => {
                // The answer left the medium about halfway between the ask and its arrival.
                let half = received.duration_since(asked) / 2;
                clock = Some(MediumClock {
                    at_us,
                    here: asked + half,
                });
                lines.append(&mut early);
            }
            (Some(Heard::Now(..)), Some(_)) => {}
            (Some(Heard::Line(stamp, text)), None) => early.push((stamp, text)),
            (Some(Heard::Line(stamp, text)), Some(_)) => lines.push((stamp, text)),
            (None, None) if Instant::now() >= asked + CLOCK_WITHIN => {
                errln!(
                    "monitor: the medium did not tell its clock: frames are stamped with the \
                     monitor's (since it started), pins with the medium's"
                );
                clock = Some(MediumClock {
                    at_us: 0,
                    here: asked,
                });
                lines.append(&mut early);
            }
            (None, _) => {}
        }
        if let Some(clock) = &clock {
            for (stamp, text) in lines {
                let line = format!("{:>9.3}  {text}", clock.seconds(stamp));
                // Its reader went away (`monitor | head`): done, as a filter is.
                if !outln!("{line}") {
                    return Ok(());
                }
            }
        }
        if end.is_some_and(|e| Instant::now() >= e) {
            return Ok(());
        }
    }
}

/// How long `monitor` waits for the medium's clock before it stamps frames with its own.
const CLOCK_WITHIN: Duration = Duration::from_secs(2);

/// What `monitor` heard: the medium's clock (`at_us` when it answered, and when the
/// answer arrived here), or a line to print at its stamp.
enum Heard {
    Now(u64, Instant),
    Line(Stamp, String),
}

/// When something happened: on the medium's clock (µs since it started), or when it
/// reached the monitor.
#[derive(Clone, Copy)]
enum Stamp {
    Medium(u64),
    Here(Instant),
}

/// The medium's clock as the monitor knows it: it read `at_us` at `here`.
struct MediumClock {
    at_us: u64,
    here: Instant,
}

impl MediumClock {
    /// `stamp` in seconds since the medium started.
    fn seconds(&self, stamp: Stamp) -> f64 {
        let us = match stamp {
            Stamp::Medium(at_us) => at_us as f64,
            Stamp::Here(t) if t >= self.here => {
                self.at_us as f64 + t.duration_since(self.here).as_micros() as f64
            }
            Stamp::Here(t) => self.at_us as f64 - self.here.duration_since(t).as_micros() as f64,
        };
        us / 1e6
    }
}

/// `gateway`: a medium bridged to the air through an nRF52840 gateway; runs until the
/// serial line closes.
pub fn gateway(serial: &Path, baud: u32, listen: SocketAddr) -> Result<(), Failure> {
    let (m, up) = medium::bridge(serial, baud, listen)?;
    outln!(
        "medium listening on {}, bridged to the air through {}",
        m.addr(),
        serial.display()
    );
    // It runs as long as the serial line does: its end is the gateway gone.
    match up.join() {
        Ok(Ok(())) => Err(Failure::error(format!(
            "{}: the gateway closed the serial line",
            serial.display()
        ))),
        Ok(Err(e)) => Err(Failure::error(format!("{}: {e}", serial.display()))),
        Err(_) => Err(Failure::error("the gateway bridge stopped")),
    }
}

/// `qemu-node`: QEMU running one node. With `--end-with-parent` it becomes QEMU (exec),
/// which connects the node's UART to the medium: whoever started it ends the node by
/// ending it. Started by hand (Linux), it stays QEMU's parent: it connects the UART itself
/// and ends the node, and itself (successfully), when the medium closes that connection,
/// as a host node does.
pub fn qemu_node(a: QemuNodeArgs) -> Result<(), Failure> {
    demo::check_elf(&a.elf)?;
    let key = match &a.key {
        Some(path) => Some(
            node_fw::host::key::load(path, a.addr)
                .map_err(|e| Failure::error(format!("key file: {e}")))?,
        ),
        None => None,
    };
    // Kept open across the exec (or the spawn): QEMU reads the key from it at start-up.
    let key_fd = key.as_ref().map(key_memfd).transpose()?;
    let key_path = key_fd
        .as_ref()
        .map(|fd| std::path::PathBuf::from(format!("/proc/self/fd/{}", fd.as_raw_fd())));
    let args = |uart| {
        demo::qemu_args(
            &a.elf,
            a.addr,
            key_path.as_deref(),
            uart,
            a.flash.as_deref(),
            a.count.as_deref(),
        )
    };
    #[cfg(target_os = "linux")]
    if !a.end_with_parent {
        return watched::run(&a, args);
    }
    if a.end_with_parent {
        end_with_parent()?;
    }
    let mut cmd = std::process::Command::new(&a.qemu);
    cmd.args(args(demo::Uart::Medium(a.medium))?);
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        Err(qemu_failed(&a.qemu, cmd.exec()))
    }
    #[cfg(not(unix))]
    {
        let status = cmd.status().map_err(|e| qemu_failed(&a.qemu, e))?;
        qemu_ended(status)
    }
}

/// QEMU could not be started.
fn qemu_failed(qemu: &Path, e: io::Error) -> Failure {
    Failure::error(format!(
        "cannot run {}: {e} (Debian: apt-get install qemu-system-arm)",
        qemu.display()
    ))
}

/// `qemu-node`'s result once QEMU ended on its own with `status`.
#[cfg(any(target_os = "linux", not(unix)))]
fn qemu_ended(status: std::process::ExitStatus) -> Result<(), Failure> {
    if status.success() {
        Ok(())
    } else {
        Err(Failure::error(format!("qemu: {status}")))
    }
}

/// A QEMU node started by hand: QEMU a child of this process, its UART a socket this
/// process connected to the medium and keeps a handle of (never reading from it), so that
/// it sees the medium close the connection.
#[cfg(target_os = "linux")]
mod watched {
    use std::io;
    use std::net::TcpStream;
    use std::os::fd::{AsRawFd, OwnedFd};
    use std::os::unix::process::CommandExt;
    use std::process::{Child, Command};

    use robot_net::demo::Uart;
    use rustix::event::{poll, PollFd, PollFlags};
    use rustix::io::{fcntl_setfd, Errno, FdFlags};
    use rustix::process::{
        getpid, getppid, kill_process, pidfd_open, set_parent_process_death_signal, Pid,
        PidfdFlags, Signal,
    };

    use super::{qemu_ended, qemu_failed, Failure, QemuNodeArgs};
    use crate::out::outln;

    /// Starts QEMU with its UART on a connection to the medium, then waits for whichever
    /// comes first: QEMU ending (its status is this command's), or the medium closing the
    /// connection (QEMU is ended, and this command succeeds).
    pub fn run(
        a: &QemuNodeArgs,
        args: impl Fn(Uart) -> Result<Vec<std::ffi::OsString>, robot_net::NetError>,
    ) -> Result<(), Failure> {
        let medium = TcpStream::connect(a.medium)
            .map_err(|e| Failure::error(format!("cannot reach the medium at {}: {e}", a.medium)))?;
        let uart = |e: io::Error| Failure::error(format!("the medium's connection: {e}"));
        medium.set_nodelay(true).map_err(uart)?;
        // Inherited by QEMU (the standard library opens it close-on-exec).
        fcntl_setfd(&medium, FdFlags::empty()).map_err(|e| uart(e.into()))?;
        let mut cmd = Command::new(&a.qemu);
        cmd.args(args(Uart::Socket(medium.as_raw_fd()))?);
        let parent = getpid();
        // SAFETY: only system calls between the fork and the exec (no allocation, no lock).
        unsafe {
            cmd.pre_exec(move || {
                // QEMU ends with this process, however this one ends.
                set_parent_process_death_signal(Some(Signal::KILL))?;
                if getppid() != Some(parent) {
                    return Err(io::Error::other("qemu-node ended while starting QEMU"));
                }
                Ok(())
            });
        }
        let mut qemu = cmd.spawn().map_err(|e| qemu_failed(&a.qemu, e))?;
        // QEMU's end as an event where the kernel has them (Linux 5.3), else looked at
        // every 100 ms.
        let pid = Pid::from_raw(qemu.id() as i32);
        let pidfd = pid.and_then(|pid| pidfd_open(pid, PidfdFlags::empty()).ok());
        match watch(&medium, &mut qemu, pidfd.as_ref()) {
            Ok(Some(status)) => qemu_ended(status),
            Ok(None) => {
                end(&mut qemu, pid, pidfd.as_ref());
                outln!(
                    "qemu-node {:#06x}: the medium closed the connection: the node stops",
                    a.addr
                );
                Ok(())
            }
            Err(e) => {
                end(&mut qemu, pid, pidfd.as_ref());
                Err(Failure::error(format!("qemu-node: {e}")))
            }
        }
    }

    /// How long QEMU has to end on SIGTERM before it is killed.
    const GRACE: rustix::time::Timespec = rustix::time::Timespec {
        tv_sec: 2,
        tv_nsec: 0,
    };
    /// How often QEMU's end is looked at without a pidfd.
    const EVERY: rustix::time::Timespec = rustix::time::Timespec {
        tv_sec: 0,
        tv_nsec: 100_000_000,
    };

    /// Waits until QEMU ends (its status) or the medium closes the connection (`None`).
    fn watch(
        medium: &TcpStream,
        qemu: &mut Child,
        pidfd: Option<&OwnedFd>,
    ) -> io::Result<Option<std::process::ExitStatus>> {
        loop {
            let gone = PollFlags::RDHUP | PollFlags::HUP | PollFlags::ERR;
            let mut fds = vec![PollFd::new(medium, PollFlags::RDHUP)];
            if let Some(fd) = pidfd {
                fds.push(PollFd::new(fd, PollFlags::IN));
            }
            match poll(&mut fds, pidfd.is_none().then_some(&EVERY)) {
                Ok(_) | Err(Errno::INTR) => {}
                Err(e) => return Err(e.into()),
            }
            if fds[0].revents().intersects(gone) {
                return Ok(None);
            }
            if let Some(status) = qemu.try_wait()? {
                return Ok(Some(status));
            }
        }
    }

    /// Ends QEMU as a shutdown would (SIGTERM: it closes its files), killed if it has not
    /// ended within [`GRACE`]; reaped.
    fn end(qemu: &mut Child, pid: Option<Pid>, pidfd: Option<&OwnedFd>) {
        if let (Some(pid), Some(fd)) = (pid, pidfd) {
            if kill_process(pid, Signal::TERM).is_ok() {
                let mut fds = [PollFd::new(fd, PollFlags::IN)];
                // Interrupted or not, what follows kills it if it still runs.
                let _ = poll(&mut fds, Some(&GRACE));
            }
        }
        if !matches!(qemu.try_wait(), Ok(Some(_))) {
            let _ = qemu.kill();
        }
        let _ = qemu.wait();
    }
}

/// This process (QEMU after the exec: the setting is kept across it) is killed when its
/// parent ends.
#[cfg(target_os = "linux")]
fn end_with_parent() -> Result<(), Failure> {
    use rustix::process::{set_parent_process_death_signal, Signal};
    set_parent_process_death_signal(Some(Signal::KILL))
        .map_err(|e| Failure::error(format!("--end-with-parent: {e}")))
}

#[cfg(not(target_os = "linux"))]
fn end_with_parent() -> Result<(), Failure> {
    Err(Failure::error("qemu-node --end-with-parent: Linux only"))
}

/// The key's 16 bytes in an anonymous memory file (no path, owner-only, never on a command
/// line), inherited by QEMU across `exec` (no close-on-exec flag).
#[cfg(target_os = "linux")]
fn key_memfd(key: &node_fw::provision::ManagementKey) -> Result<std::os::fd::OwnedFd, Failure> {
    use rustix::fs::{memfd_create, MemfdFlags};
    let fd = memfd_create("node-key", MemfdFlags::empty())
        .map_err(|e| Failure::error(format!("key for QEMU: {e}")))?;
    let mut file = std::fs::File::from(fd);
    let bytes: Vec<u8> = key.words().iter().flat_map(|w| w.to_le_bytes()).collect();
    io::Write::write_all(&mut file, &bytes)
        .map_err(|e| Failure::error(format!("key for QEMU: {e}")))?;
    Ok(file.into())
}

#[cfg(not(target_os = "linux"))]
fn key_memfd(_: &node_fw::provision::ManagementKey) -> Result<std::os::fd::OwnedFd, Failure> {
    Err(Failure::error(
        "qemu-node --key hands the key to QEMU through a memory file: Linux only",
    ))
}

/// `node`: one generic node in this process (what `demo` starts).
pub fn node(args: node_fw::host::Args) -> Result<(), Failure> {
    node_fw::host::run(args).map_err(|e| Failure::as_is(exit::ERROR, format!("node: {e}")))
}

#[cfg(test)]
mod tests {
    use super::closed_why;

    /// A plant's or monitor's connection closed by a medium that still runs was dropped
    /// (it fell behind); by one that stopped, the medium went away. Both said "went away",
    /// and a `monitor | less` left on a page sent its user looking for a dead medium.
    #[test]
    fn a_medium_that_still_runs_dropped_the_connection_one_that_stopped_went_away() {
        let m = medium::Medium::start(medium::Config::default()).unwrap();
        let at = m.addr();
        assert_eq!(
            closed_why(at),
            "dropped this connection: it did not read fast enough (the medium drops a plant \
             or monitor that falls behind; it still runs)"
        );
        m.stop();
        drop(m);
        assert_eq!(closed_why(at), "closed the connection (it went away)");
    }
}
