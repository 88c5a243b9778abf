//! The radio, measured on the simulated medium's 250 kbit/s airtime model with real node
//! processes (`config-tool node`), each figure printed beside its lower bound:
//! - pushing the four paint-robot tables: airtime and wall time; the lower bound is the
//!   airtime of the protocol's minimal exchange (begin, chunks, end and one answer each);
//! - node-to-node latency per hop: from a cylinder reaching its switch to the next actuator
//!   (on another node) starting, in wall time (the host's processes and TCP included), and
//!   the airtime every hop spent; beside it the airtime model's own bound on a hop (the
//!   event frame's airtime, in frames as the nodes sent them) and the host's overhead
//!   beyond it; the airtime per hop against an event and its acknowledgement;
//! - frames per cycle between nodes (tool traffic excluded); the lower bound is one event
//!   and one acknowledgement per radio publication.
//!
//! `cargo bench -p config-tool --bench radio`

mod support;
use support::{bed_of, paint_robot};

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use config_schema::link_keys;
use config_schema::wire::mac::{self, Frame, Header, MAX_PSDU};
use config_schema::wire::medium::{Link, Peer};
use config_schema::wire::msg::{Command, ConfigReply, Message, SwitchStep, CHUNK_DATA};
use config_schema::wire::security::DEFAULT_OVERHEAD;
use medium::{self, Conn};
use robot_net::demo;
use robot_net::radio::TOOL_ADDR;

/// Airtime of one message in a secured data frame (ENC-MIC-64: the auxiliary header and
/// the MIC on top), us.
fn airtime(msg: &Message) -> u64 {
    airtime_plain(msg) + security_us()
}

/// What securing adds to a frame's airtime, us.
fn security_us() -> u64 {
    u64::from(mac::airtime_us(DEFAULT_OVERHEAD)) - u64::from(mac::airtime_us(0))
}

/// Airtime of one message in an unsecured data frame, us.
fn airtime_plain(msg: &Message) -> u64 {
    let mut payload = [0u8; mac::MAX_PAYLOAD];
    let n = msg.emit(&mut payload).expect("fits");
    let header = Header {
        seq: 0,
        pan_id: 0xFFFF,
        dst: 1,
        src: 2,
        ack_request: false,
        secured: false,
    };
    let mut psdu = [0u8; MAX_PSDU];
    let len = mac::emit_data(&header, &payload[..n], &mut psdu).expect("frame");
    u64::from(mac::airtime_us(len))
}

/// The airtime of the minimal transfer of `blob`: every message once, each answered once.
fn push_lower_bound(blob: &[u8]) -> u64 {
    let g = 1;
    let mut t = airtime(&Message::ConfigBegin {
        generation: g,
        len: blob.len() as u16,
        crc: u32::MAX,
        force: false,
    });
    for (i, chunk) in blob.chunks(CHUNK_DATA).enumerate() {
        t += airtime(&Message::ConfigChunk {
            generation: g,
            offset: (i * CHUNK_DATA) as u16,
            data: chunk,
        });
    }
    t += airtime(&Message::ConfigEnd { generation: g });
    let chunks = blob.len().div_ceil(CHUNK_DATA);
    for i in 0..=chunks {
        t += airtime(&Message::ConfigReply {
            generation: g,
            reply: ConfigReply::Next {
                next: (i * CHUNK_DATA).min(blob.len()) as u16,
            },
        });
    }
    t + airtime(&Message::ConfigReply {
        generation: g,
        reply: ConfigReply::Activated,
    })
}

/// What the monitor counted: frames between nodes (not to or from the tool, not broadcast)
/// and their airtime, the airtime of the tool's frames and of their answers, and every
/// frame it saw (to wait until it has seen what the medium sent).
#[derive(Default)]
struct Counted {
    node_frames: AtomicU64,
    node_air_us: AtomicU64,
    tool_air_us: AtomicU64,
    all_frames: AtomicU64,
    /// The medium's frame count when the monitor joined (it sees every frame after).
    base: AtomicU64,
}

impl Counted {
    /// Returns once the monitor has seen `frames` frames (the medium's count): its figures
    /// then cover everything sent so far.
    fn caught_up(&self, frames: u64) {
        while self.base.load(Ordering::Relaxed) + self.all_frames.load(Ordering::Relaxed) < frames {
            std::thread::yield_now();
        }
    }
}

fn count_frames(mut monitor: Conn, counted: Arc<Counted>) {
    let far = Instant::now() + Duration::from_secs(24 * 3600);
    let _ = monitor.recv(far, |l| {
        if let Link::Frame(psdu) = l {
            if let Ok(Frame::Data { header, .. }) = Frame::parse(psdu) {
                let air = u64::from(mac::airtime_us(psdu.len()));
                if header.src == TOOL_ADDR || header.dst == TOOL_ADDR {
                    counted.tool_air_us.fetch_add(air, Ordering::Relaxed);
                } else if header.dst != mac::BROADCAST {
                    counted.node_frames.fetch_add(1, Ordering::Relaxed);
                    counted.node_air_us.fetch_add(air, Ordering::Relaxed);
                }
            }
            counted.all_frames.fetch_add(1, Ordering::Relaxed);
        }
        None::<()>
    });
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn main() {
    let c = paint_robot();
    let (mut bed, actuators) = bed_of(&c, Duration::from_secs(60));
    let counted = Arc::new(Counted::default());
    let monitor = Conn::join(bed.medium().addr(), Peer::Monitor).expect("monitor");
    counted
        .base
        .store(bed.medium().stats().frames, Ordering::Relaxed);
    let c2 = counted.clone();
    std::thread::spawn(move || count_frames(monitor, c2));
    let tool_air = || counted.tool_air_us.load(Ordering::Relaxed);
    let node_air = || counted.node_air_us.load(Ordering::Relaxed);
    let node_frames = || counted.node_frames.load(Ordering::Relaxed);

    // Push: the transfers (stage), then the switch-over, measured apart.
    let before = bed.medium().stats();
    counted.caught_up(before.frames);
    let (tool0, node0) = (tool_air(), node_air());
    let t0 = Instant::now();
    let mut outcomes = bed.stage(&c, false, &mut |_, _, _| {}).expect("stage");
    let wall = t0.elapsed();
    let staged = bed.medium().stats();
    counted.caught_up(staged.frames);
    let tool1 = tool_air();
    assert!(outcomes
        .iter()
        .all(|o| o.progress == node_fw::ota::Progress::Done));
    let t1 = Instant::now();
    let verdict = bed
        .switch_over(
            &mut outcomes,
            c.ir.generation,
            false,
            Duration::from_secs(30),
        )
        .expect("switch");
    assert_eq!(verdict, node_fw::switch::Verdict::Switched);
    let switch_wall = t1.elapsed();
    let after = bed.medium().stats();
    counted.caught_up(after.frames);
    // Only the tool's frames and their answers: the nodes that switched greet their
    // peers (the freshness handshake) meanwhile, counted apart.
    let air = tool1 - tool0;
    let switch_air = tool_air() - tool1;
    let greetings = node_air() - node0;
    // The secured lower bound: each transfer (table and key block) in secured frames.
    let transfers: Vec<Vec<u8>> = c
        .blobs
        .iter()
        .zip(&c.tables)
        .map(|(b, t)| {
            let keys = link_keys::HEAD_LEN + t.peers.len() * link_keys::ENTRY_LEN + 4;
            vec![0u8; b.len() + keys]
        })
        .collect();
    let bound: u64 = transfers.iter().map(|b| push_lower_bound(b)).sum();
    // The switch-over's minimal exchange per node: armed, armed again once every node is
    // (the idle check), go; each answered.
    let g = c.ir.generation;
    let step = |step| {
        airtime(&Message::Switch {
            generation: g,
            step,
        })
    };
    let reply = |reply| {
        airtime(&Message::ConfigReply {
            generation: g,
            reply,
        })
    };
    let per_node = 2
        * (step(SwitchStep::Arm { ask: 1 }) + reply(ConfigReply::Armed { idle: true, ask: 1 }))
        + step(SwitchStep::Go {
            now: false,
            trial: false,
        })
        + reply(ConfigReply::Activated);
    let switch_bound = per_node * c.tables.len() as u64;
    println!(
        "security: {DEFAULT_OVERHEAD} bytes per frame (auxiliary header 6, MIC 8) = {} us of airtime at 250 kbit/s",
        security_us()
    );
    println!(
        "push of the four paint-robot tables ({} bytes, + {} bytes of link keys):",
        c.blobs.iter().map(Vec::len).sum::<usize>(),
        transfers.iter().map(Vec::len).sum::<usize>() - c.blobs.iter().map(Vec::len).sum::<usize>()
    );
    println!("  stage airtime  {:>8.2} ms   secured lower bound {:>7.2} ms   ratio {:.2}x   (target: within 1.25x)",
        air as f64 / 1e3, bound as f64 / 1e3, air as f64 / bound as f64);
    println!(
        "  stage frames   {:>8}      wall time {:.1} ms",
        staged.frames - before.frames,
        wall.as_secs_f64() * 1e3,
    );
    println!("  switch airtime {:>8.2} ms   its minimal exchange {:>7.2} ms   ratio {:.2}x   frames {}   wall time {:.1} ms",
        switch_air as f64 / 1e3, switch_bound as f64 / 1e3, switch_air as f64 / switch_bound as f64,
        after.frames - staged.frames, switch_wall.as_secs_f64() * 1e3);
    println!(
        "  (besides, until the switch returned: {:.2} ms of the nodes greeting their peers)",
        greetings as f64 / 1e3
    );

    // Cycles: latency per hop and frames between nodes, once homed (a first table starts
    // not homed: docs/reconfiguration.md), and its frames left out of the cycles' count.
    let homing = bed.home(&c).expect("home");
    assert_eq!(
        homing.end,
        robot_net::home::HomeEnd::Homed,
        "{}",
        demo::homed_line(&homing)
    );
    counted.caught_up(bed.medium().stats().frames);
    let travel = |name: &str, plus: bool| {
        actuators
            .iter()
            .find(|a| a.name == name)
            .map(|a| if plus { a.travel_ms.0 } else { a.travel_ms.1 })
            .unwrap_or(0)
    };
    let node_of = |name: &str| actuators.iter().find(|a| a.name == name).map(|a| a.addr);
    // A sensorless actuator completes on its node's dwell timer, not on arrival.
    let switched = |name: &str| actuators.iter().any(|a| a.name == name && a.double);
    let mut hops = Vec::new();
    let mut per_cycle = Vec::new();
    let air0 = node_air();
    let cycles = 3;
    for _ in 0..cycles {
        let mut steps = Vec::new();
        let n0 = node_frames();
        let cycle = bed
            .run_cycle(&c, &mut |s, _| steps.push(s.clone()))
            .expect("cycle");
        assert!(cycle.ok(), "{}", demo::cycle_line(0, &cycle));
        counted.caught_up(bed.medium().stats().frames);
        per_cycle.push(node_frames() - n0);
        for w in steps.windows(2) {
            let (a, b) = (&w[0], &w[1]);
            if node_of(&a.step.actuator) != node_of(&b.step.actuator) && switched(&a.step.actuator)
            {
                let arrived = a.at + Duration::from_millis(travel(&a.step.actuator, a.step.extend));
                hops.push(b.at.saturating_sub(arrived).as_secs_f64() * 1e3);
            }
        }
    }
    // The airtime model's own bound on one hop, in frames as the nodes sent them: their
    // link epoch (a varint of one to three bytes) and sequence numbers (under 128 here,
    // one byte; `(cycles + 1) * publications` bounds any link's) make the frames.
    let publications = robot_compiler::compile::radio_events(&c.ir).len();
    let epoch = bed
        .statuses(&c)
        .expect("status")
        .iter()
        .map(|s| s.epoch)
        .max()
        .unwrap_or(0);
    let seq = ((cycles + 1) * publications) as u16;
    let event = airtime(&Message::Event {
        epoch,
        seq,
        topic: 1,
    });
    let ack = airtime(&Message::EventAck { epoch, next: seq });
    let plain = airtime_plain(&Message::Event {
        epoch,
        seq,
        topic: 1,
    });
    let n_hops = hops.len();
    let max = hops.iter().copied().fold(0.0, f64::max);
    let med = median(&mut hops);
    let bound = event as f64 / 1e3;
    println!("node-to-node latency over {n_hops} hops (switch reached -> next actuator moves):");
    println!(
        "  median {med:>6.2} ms   max {max:>6.2} ms   the airtime model's bound {bound:.2} ms   host overhead (median - bound) {:.2} ms   (target: < 2 ms)",
        med - bound
    );
    println!("  the bound: the medium delivers the event frame when its airtime ends ({bound:.2} ms secured, {:.2} ms unsecured; epoch {epoch}); it models no CSMA, backoff or turnaround, and the ack ({:.2} ms) goes on the air after the delivery, off the hop's path",
        plain as f64 / 1e3, ack as f64 / 1e3);
    let per_hop = (node_air() - air0) as f64 / (cycles * publications) as f64;
    println!("  airtime per hop (measured) {:.2} ms: every frame between nodes over {cycles} cycles / {} hops   event + ack {:.2} ms   ratio {:.2}x   (target: within 1.1x)",
        per_hop / 1e3, cycles * publications, (event + ack) as f64 / 1e3, per_hop / (event + ack) as f64);
    println!("  (wall latency includes the host: the plant's wake-up, processes, TCP, thread wake-ups; docs/node-runtime.md has where a hop's time goes)");
    println!("frames between nodes per cycle: {per_cycle:?}   lower bound {} ({publications} publications, each an event and an ack)", 2 * publications);

    // A round of every node's status, as `home`, `start`, `status` and the panel ask it:
    // every node at once (`push::ask_each`), against one node after the other (as they
    // were asked before), in turns in the same run.
    let (mut at_once, mut in_turn) = (Vec::new(), Vec::new());
    for _ in 0..40 {
        let t = Instant::now();
        bed.statuses(&c).expect("statuses");
        at_once.push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        for r in &c.ir.roles {
            bed.command(r.address, Command::Status).expect("status");
        }
        in_turn.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let (once, turn) = (median(&mut at_once), median(&mut in_turn));
    println!(
        "a round of every node's status ({} nodes, no loss, 40 rounds): every node at once {once:.2} ms median   one after another {turn:.2} ms   ratio {:.2}x",
        c.ir.roles.len(),
        turn / once
    );
    bed.stop();
}
