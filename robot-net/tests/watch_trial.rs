//! A watched trial (`push::watch_trial_for`) against scripted nodes on the medium: each
//! answers `Status` and `Switch` as a node does, and loses power (boots the previous
//! generation, the trial slot revoked) after the status answers its script says.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use config_schema::blob::TableId;
use config_schema::wire::mac::{self, Frame, Header, MAX_PSDU};
use config_schema::wire::medium::{Link, Peer};
use config_schema::wire::msg::{Command, ConfigReply, Message, Refusal, Status, SwitchStep};
use node_fw::switch::Verdict;
use robot_net::push::{self, Ids, TrialEnd, TrialWindow};
use robot_net::radio::{ToolRadio, TOOL_ADDR};

const CONFIG_PAN: u16 = 0xFFFF;

/// What a scripted node runs: (generation, on trial, previous).
#[derive(Clone, Copy, Debug)]
struct Runs {
    generation: u32,
    trial: bool,
    previous: u32,
}

fn status(ack: u16, r: Runs) -> Status {
    Status {
        ack,
        role: heapless::String::new(),
        generation: r.generation,
        table: TableId::NONE,
        staged: 0,
        previous: r.previous,
        trial: r.trial,
        states: heapless::Vec::new(),
        outputs: 0,
        inputs: 0,
        fault: None,
        link_alarms: 0,
        links_broken: 0,
        links_restarted: 0,
        epoch: 0,
        counters: Default::default(),
        runtime: Default::default(),
        cycles: 0,
    }
}

/// A scripted node: what it runs, after how many status answers it loses power (`None`:
/// never), whether it has, and the confirmations it was asked for.
struct Script {
    runs: Mutex<Runs>,
    cut_after: Option<u32>,
    statuses: AtomicU32,
    cut: AtomicBool,
    confirms: AtomicU32,
    /// Answers the first `Confirm` with a late copy of the switch-over's `Activated`.
    late_first: bool,
}

impl Script {
    fn new(cut_after: Option<u32>) -> Arc<Script> {
        let runs = if cut_after == Some(0) {
            AFTER_POWER_CUT
        } else {
            ON_TRIAL
        };
        Arc::new(Script {
            runs: Mutex::new(runs),
            cut_after,
            statuses: AtomicU32::new(0),
            cut: AtomicBool::new(false),
            confirms: AtomicU32::new(0),
            late_first: false,
        })
    }

    /// [`Script::new`] whose first `Confirm` is answered by a late `Activated`.
    fn late_first() -> Arc<Script> {
        let mut s = Arc::into_inner(Script::new(None)).expect("one");
        s.late_first = true;
        Arc::new(s)
    }

    fn runs(&self) -> Runs {
        *self.runs.lock().unwrap()
    }

    /// The answer to `msg`, as `node_fw::switch` and the node give it.
    fn answer(&self, msg: Message) -> Option<Message<'static>> {
        let mut r = self.runs.lock().unwrap();
        match msg {
            Message::Command {
                id,
                command: Command::Status,
            } => {
                let status = status(id, *r);
                let n = self.statuses.fetch_add(1, Ordering::SeqCst) + 1;
                if self.cut_after == Some(n) {
                    *r = AFTER_POWER_CUT;
                    self.cut.store(true, Ordering::SeqCst);
                }
                Some(Message::Status(status))
            }
            Message::Switch { generation, step } => {
                let reply = match step {
                    SwitchStep::Confirm => {
                        let n = self.confirms.fetch_add(1, Ordering::SeqCst);
                        if self.late_first && n == 0 {
                            ConfigReply::Activated
                        } else if generation == r.generation {
                            r.trial = false;
                            ConfigReply::Confirmed
                        } else {
                            ConfigReply::Refused(Refusal::NotStaged { staged: 0 })
                        }
                    }
                    SwitchStep::Disarm => ConfigReply::Disarmed,
                    _ if generation == r.generation => ConfigReply::Activated,
                    SwitchStep::Arm { ask } if generation == r.previous => {
                        ConfigReply::Armed { idle: true, ask }
                    }
                    SwitchStep::Go { .. } if generation == r.previous => {
                        *r = Runs {
                            generation,
                            trial: false,
                            previous: 0,
                        };
                        ConfigReply::Activated
                    }
                    _ => ConfigReply::Refused(Refusal::NotStaged { staged: 0 }),
                };
                Some(Message::ConfigReply { generation, reply })
            }
            _ => None,
        }
    }
}

/// A node at `addr` on the medium that answers as `script` says until `stop`.
fn scripted_node(
    medium: std::net::SocketAddr,
    addr: u16,
    script: Arc<Script>,
    stop: Arc<AtomicBool>,
) {
    let mut conn = medium::Conn::join(medium, Peer::Node { addr }).expect("join");
    std::thread::spawn(move || {
        let mut seq = 0u8;
        while !stop.load(Ordering::Relaxed) {
            // Wakes to look at `stop`; every frame is taken as it comes.
            let until = Instant::now() + Duration::from_millis(20);
            let Ok(got) = conn.recv(until, |l| match l {
                Link::Frame(p) => Some(p.to_vec()),
                _ => None,
            }) else {
                return;
            };
            let Some(psdu) = got else { continue };
            let Ok(Frame::Data { header, payload }) = Frame::parse(&psdu) else {
                continue;
            };
            if header.dst != addr {
                continue;
            }
            let Some(answer) = Message::parse(payload).ok().and_then(|m| script.answer(m)) else {
                continue;
            };
            let mut buf = [0u8; mac::MAX_PAYLOAD];
            let n = answer.emit(&mut buf).expect("emit");
            let h = Header {
                seq,
                pan_id: CONFIG_PAN,
                dst: header.src,
                src: addr,
                ack_request: false,
                secured: false,
            };
            seq = seq.wrapping_add(1);
            let mut out = [0u8; MAX_PSDU];
            let len = mac::emit_data(&h, &buf[..n], &mut out).expect("frame");
            if conn.send(&Link::Frame(&out[..len])).is_err() {
                return;
            }
        }
    });
}

const ON_TRIAL: Runs = Runs {
    generation: 2,
    trial: true,
    previous: 1,
};
/// What a node on trial boots after a power cut: the previous generation, confirmed
/// (the trial slot is revoked at boot).
const AFTER_POWER_CUT: Runs = Runs {
    generation: 1,
    trial: false,
    previous: 0,
};

/// Watches a trial of generation 2 on nodes with `scripts` for `window`, `confirm` typed
/// when `typed()` says so; how it ended.
fn watch(scripts: &[(u16, Arc<Script>)], window: Duration, typed: &dyn Fn() -> bool) -> TrialEnd {
    let medium = medium::Medium::start(medium::Config::default()).expect("medium");
    let stop = Arc::new(AtomicBool::new(false));
    for (addr, script) in scripts {
        scripted_node(medium.addr(), *addr, script.clone(), stop.clone());
    }
    let nodes: Vec<u16> = scripts.iter().map(|s| s.0).collect();
    let mut radio = ToolRadio::connect(medium.addr(), TOOL_ADDR).expect("tool");
    let window = TrialWindow {
        time: Some(window),
        cycles: None,
    };
    let every = (Duration::from_millis(50), Duration::from_secs(5));
    let end = push::watch_trial_for(
        &mut radio,
        &mut Ids::default(),
        (&nodes, 1),
        window,
        every,
        typed,
    )
    .expect("radio");
    stop.store(true, Ordering::Relaxed);
    medium.stop();
    end
}

/// Every node of the machine loses power during a watched trial and boots generation 1.
/// The watch said `Confirmed` ("confirmed: the trial generation stays", exit 0) though no
/// one confirmed and no node runs the trial generation.
#[test]
fn a_power_cut_of_the_whole_machine_during_a_watched_trial_ends_it_reverted() {
    let scripts = [
        (0x0031, Script::new(Some(1))),
        (0x0032, Script::new(Some(1))),
    ];
    let end = watch(&scripts, Duration::from_secs(600), &|| false);
    assert_eq!(
        end,
        TrialEnd::Reverted {
            node: 0x0031,
            rolled_back: Verdict::Switched
        }
    );
    assert!(scripts.iter().all(|s| s.1.runs().generation == 1));
}

/// One node lost power during a watched trial (it boots generation 1, the other stays on
/// trial), then `confirm` is typed. The watch confirmed the other and said `Confirmed`:
/// the machine on two generations, exit 0. Now it confirms nothing and rolls the other
/// back at the idle point: the machine on one generation.
#[test]
fn confirm_typed_after_a_power_cut_at_one_node_confirms_nothing_and_rolls_the_rest_back() {
    let scripts = [(0x0041, Script::new(Some(0))), (0x0042, Script::new(None))];
    let end = watch(&scripts, Duration::from_secs(600), &|| true);
    assert_eq!(
        end,
        TrialEnd::Reverted {
            node: 0x0041,
            rolled_back: Verdict::Switched
        }
    );
    assert_eq!(scripts[1].1.confirms.load(Ordering::SeqCst), 0);
    assert!(scripts.iter().all(|s| s.1.runs().generation == 1));
}

/// The power cut comes after the round of statuses that `confirm` follows: the other node
/// is confirmed, the next round sees the cut, and the confirmed node is rolled back too.
#[test]
fn a_power_cut_as_confirm_goes_out_ends_with_the_machine_on_one_generation() {
    let scripts = [(0x0045, Script::new(Some(1))), (0x0046, Script::new(None))];
    let cut = scripts[0].1.clone();
    let end = watch(&scripts, Duration::from_secs(600), &|| {
        cut.cut.load(Ordering::SeqCst)
    });
    assert_eq!(
        end,
        TrialEnd::Reverted {
            node: 0x0045,
            rolled_back: Verdict::Switched
        }
    );
    // Confirmed (asked more than once only if its answer came slowly).
    assert!(scripts[1].1.confirms.load(Ordering::SeqCst) >= 1);
    assert!(scripts.iter().all(|s| s.1.runs().generation == 1));
}

/// `confirm` typed during a watch of the longest window there is: confirmed (the window's
/// end, past what an `Instant` holds, panicked).
#[test]
fn a_trial_watched_for_the_longest_window_is_confirmed() {
    let scripts = [(0x0051, Script::new(None))];
    let end = watch(&scripts, Duration::from_secs(u64::MAX), &|| true);
    assert_eq!(end, TrialEnd::Confirmed);
    assert!(!scripts[0].1.runs().trial, "confirmed");
}

/// A late `Activated` of the switch-over comes as the first answer to `confirm`: not
/// taken as its answer (it was: the tool stopped asking and said "NOT confirmed:
/// answered Activated"); asked again, the node confirms.
#[test]
fn confirm_takes_only_a_confirmations_answers() {
    let medium = medium::Medium::start(medium::Config::default()).expect("medium");
    let stop = Arc::new(AtomicBool::new(false));
    let script = Script::late_first();
    scripted_node(medium.addr(), 0x0061, script.clone(), stop.clone());
    let mut radio = ToolRadio::connect(medium.addr(), TOOL_ADDR).expect("tool");
    let answers = push::confirm(&mut radio, &[0x0061], 2, Duration::from_secs(5)).expect("radio");
    stop.store(true, Ordering::Relaxed);
    medium.stop();
    assert_eq!(answers, [(0x0061, Some(ConfigReply::Confirmed))]);
    // Asked again after the late answer (more than once if its answers came slowly).
    assert!(script.confirms.load(Ordering::SeqCst) >= 2);
    assert!(!script.runs().trial, "confirmed");
}

/// Another run of the tool pushes generation 3 to every node during the watch of
/// generation 2's trial. The watch said `Confirmed` ("confirmed: the trial generation
/// stays", exit 0): no node was on trial any more. Now it ends superseded, rolling
/// nothing back and confirming nothing.
#[test]
fn a_newer_generation_pushed_elsewhere_during_a_watched_trial_ends_it_superseded() {
    let scripts = [(0x0061, Script::new(None)), (0x0062, Script::new(None))];
    let pushed = Runs {
        generation: 3,
        trial: false,
        previous: 2,
    };
    // Asked once a round: after the first round (both seen on trial), the push lands.
    let end = watch(&scripts, Duration::from_secs(600), &|| {
        for (_, s) in &scripts {
            if s.statuses.load(Ordering::SeqCst) >= 1 {
                *s.runs.lock().unwrap() = pushed;
            }
        }
        false
    });
    assert_eq!(
        end,
        TrialEnd::Superseded {
            node: 0x0061,
            generation: 3
        }
    );
    assert!(scripts.iter().all(|s| s.1.runs().generation == 3));
    assert!(scripts
        .iter()
        .all(|s| s.1.confirms.load(Ordering::SeqCst) == 0));
}
