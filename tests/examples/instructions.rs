//! Runs the table interpreter over a count of stimuli, for `bench/instructions.sh`, which
//! counts its instructions with callgrind twice (N and 2N) and divides the difference by N:
//! what one more stimulus costs, with start-up, compilation and the table's build taken
//! out.
//!
//! ```text
//! instructions ctu1 N      N pulses into one E_CTU chart (bench/robots/e-ctu.ron, ONE),
//!                          its effects taken as a node takes them (outputs, publications,
//!                          timers, faults; no trace: `NodeEffects` keeps none)
//! instructions ctu2 N      N pulses into two E_CTU charts in series (TWO), likewise
//! instructions ctu1-trace N, ctu2-trace N
//!                          the same with every transition's trace taken too (the sink
//!                          the VC figures use, which a node does not have)
//! instructions vc N        N cycles of the paper robot's VC chart, interpreted
//! instructions vc-hand N   the same N cycles through the hand-written `match`
//! instructions node N       N presses of a button on node A, published to node B, whose
//!                           chart toggles a lamp; every frame delivered, unsecured. The
//!                           script counts only inside one of `a_edge` (A's input change
//!                           that publishes), `a_level` (A told a level it has), `b_event`
//!                           (B receives the event: MAC, link, ack, chart, lamp) and
//!                           `a_ack` (A receives B's ack)
//! instructions node-secured N
//!                           the same with link keys (events and acks secured at
//!                           ENC-MIC-64, as a machine's nodes run by default; the `aes`
//!                           crate picks the CPU's AES instructions where it has them)
//! ```
//!
//! Prints what the run left (counts, states), so the work cannot be optimised away and a
//! wrong run shows.

use std::hint::black_box;
use std::process::ExitCode;

use config_schema::{Publication, Table, Topic};
use node_fw::ecc::{Effects, Engine};
use robot_compiler::{compile, Compiled, Source};
use robot_tests::paper_robot;
use robot_tests::vc_dispatch::{engine, run_hand, run_interpreter, HandVc, Sum};

fn e_ctu() -> Result<Compiled, String> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../bench/robots/e-ctu.ron");
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    compile::compile(&Source::new(path, text))
        .map_err(|d| format!("e-ctu.ron does not compile: {d:?}"))
}

/// Role `role`'s table, the (publisher, topic) of SRC's PULSE as it subscribes to it, and
/// the index of its variable `var`.
fn counter<'c>(
    c: &'c Compiled,
    role: &str,
    var: &str,
) -> Result<(&'c Table, u8, Topic, usize), String> {
    let i =
        c.ir.roles
            .iter()
            .position(|r| r.name == role)
            .ok_or("no role")?;
    let (r, table) = (&c.ir.roles[i], &c.tables[i]);
    let local = r
        .imports
        .iter()
        .find(|(from, event, _)| from == "SRC" && event == "PULSE")
        .map(|(_, _, local)| local)
        .ok_or("no SRC/PULSE")?;
    let event = r.events.iter().position(|e| e == local).ok_or("no event")?;
    let sub = table
        .subscriptions
        .iter()
        .find(|s| usize::from(s.event) == event)
        .ok_or("no subscription")?;
    let v = r
        .vars
        .iter()
        .position(|(name, _)| name == var)
        .ok_or_else(|| format!("no var {var}: {:?}", r.vars))?;
    Ok((table, sub.publisher, sub.topic, v))
}

/// The effects a node takes from its charts (outputs, publications; timers and faults
/// are none here), folded as `Sum` folds them, without the trace of each transition:
/// `NodeCore`'s effects keep no trace.
#[derive(Default)]
struct Untraced(Sum);

impl Effects for Untraced {
    #[inline]
    fn output(&mut self, output: u8, value: bool) {
        self.0.output(output, value);
    }
    #[inline]
    fn publish(&mut self, p: &Publication) {
        self.0.publish(p);
    }
}

/// `n` pulses of SRC/PULSE into role `role`, the effects taken by `fx`.
fn pulses<F: Effects>(
    c: &Compiled,
    role: &str,
    var: &str,
    n: u64,
    mut fx: F,
    folded: impl Fn(&F) -> u64,
) -> Result<String, String> {
    let (table, publisher, topic, cv) = counter(c, role, var)?;
    let mut e = Engine::new(table);
    e.reset(&mut fx);
    for _ in 0..n {
        e.remote(black_box(publisher), black_box(topic), &mut fx);
    }
    Ok(format!(
        "{var} = {:?}, effects {:#x}",
        e.var(cv),
        folded(&fx)
    ))
}

fn run(what: &str, n: u64) -> Result<String, String> {
    match what {
        "ctu1" => pulses(&e_ctu()?, "ONE", "c1.CV", n, Untraced::default(), |f| {
            f.0 .0
        }),
        "ctu2" => pulses(&e_ctu()?, "TWO", "c2.CV", n, Untraced::default(), |f| {
            f.0 .0
        }),
        "ctu1-trace" => pulses(&e_ctu()?, "ONE", "c1.CV", n, Sum::default(), |f| f.0),
        "ctu2-trace" => pulses(&e_ctu()?, "TWO", "c2.CV", n, Sum::default(), |f| f.0),
        "vc" | "vc-hand" => {
            let table = paper_robot::vc_table().map_err(|e| format!("{e:?}"))?;
            let mut fx = Sum::default();
            if what == "vc" {
                let mut e = engine(&table);
                for _ in 0..n {
                    run_interpreter(&mut e, &mut fx);
                }
            } else {
                let mut h = HandVc::new(&table);
                for _ in 0..n {
                    run_hand(&mut h, &mut fx);
                }
            }
            Ok(format!("effects {:#x}", fx.0))
        }
        "node" => node::presses(n, false),
        "node-secured" => node::presses(n, true),
        _ => Err(format!(
            "unknown run `{what}`: ctu1, ctu2, ctu1-trace, ctu2-trace, vc, vc-hand, node or \
             node-secured"
        )),
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(what), Some(n)) = (args.first(), args.get(1).and_then(|n| n.parse().ok())) else {
        eprintln!(
            "usage: instructions ctu1|ctu2|ctu1-trace|ctu2-trace|vc|vc-hand|node|node-secured N"
        );
        return ExitCode::from(2);
    };
    match run(what, n) {
        Ok(left) => {
            println!("{what} {n}: {left}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("instructions: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Two `NodeCore`s on a perfect radio, for the figures per stimulus inside the node core.
mod node {
    use config_schema::link_keys::{LinkKeys, PeerKeys};
    use config_schema::{Action, Output, Publication, Subscription, Table};
    use node_fw::node::{Io, NodeCore};
    use std::hint::black_box;
    use test_tables::{button, toggle};

    const A: u16 = 0x0001;
    const B: u16 = 0x0002;
    const PAN: u16 = 0x4242;
    const BUTTON: u8 = 5;
    const LAMP: u8 = 7;

    /// What a node sent, without allocating (an allocation would be counted as the core's).
    struct Board {
        frames: [[u8; 127]; 4],
        lens: [usize; 4],
        sent: usize,
        pins: u64,
        /// The last frame counter handed out (secured frames).
        counter: u32,
    }

    impl Board {
        fn new() -> Self {
            Board {
                frames: [[0; 127]; 4],
                lens: [0; 4],
                sent: 0,
                pins: 0,
                counter: 0,
            }
        }
    }

    impl Io for Board {
        fn transmit(&mut self, psdu: &[u8]) {
            // The core sends MPDUs (`transmit_mpdu`): a PSDU is kept as its MPDU.
            if let Ok(mpdu) = config_schema::wire::mac::strip_fcs(psdu) {
                self.transmit_mpdu(mpdu);
            }
        }
        /// A board's radio path: the MPDU as the core sends it (the FCS is the radio's).
        fn transmit_mpdu(&mut self, mpdu: &[u8]) {
            if let (Some(f), Some(l)) =
                (self.frames.get_mut(self.sent), self.lens.get_mut(self.sent))
            {
                let n = mpdu.len().min(127);
                f[..n].copy_from_slice(&mpdu[..n]);
                *l = n;
                self.sent += 1;
            }
        }
        fn set_pin(&mut self, pin: u8, level: bool) {
            self.pins ^= u64::from(level) << pin;
        }
        fn next_frame_counter(&mut self) -> Option<u32> {
            self.counter += 1;
            Some(self.counter)
        }
    }

    /// `node`'s link keys with its one `peer` (each direction its own key, as the tool
    /// derives them).
    fn link_keys(node: u16, peer: u16) -> Result<LinkKeys, String> {
        let key = |from: u16, to: u16| [(from as u8) << 4 | to as u8; 16];
        let mut keys = LinkKeys {
            generation: 1,
            peers: Default::default(),
        };
        (keys.peers.push(PeerKeys {
            peer,
            send: key(node, peer),
            receive: key(peer, node),
        }))
        .map_err(|_| "link keys")?;
        Ok(keys)
    }

    fn tables() -> Result<(Table, Table), String> {
        let mut a = Table::empty("A");
        a.generation = 1;
        a.header.pan_id = PAN;
        let press = button(&mut a, BUTTON);
        a.peers.push(B).map_err(|_| "peers")?;
        (a.publications.push(Publication {
            event: press,
            topic: 3,
            subscribers: 0b1,
        }))
        .map_err(|_| "publications")?;
        let mut b = Table::empty("B");
        b.generation = 1;
        b.header.pan_id = PAN;
        let pressed = b.push_event().map_err(|_| "events")?;
        (b.outputs.push(Output::safe(LAMP, false))).map_err(|_| "outputs")?;
        b.peers.push(A).map_err(|_| "peers")?;
        (b.subscriptions.push(Subscription {
            publisher: 0,
            topic: 3,
            event: pressed,
        }))
        .map_err(|_| "subscriptions")?;
        toggle(&mut b, pressed, &[Action::Drive { mask: 1, value: 1 }]);
        Ok((a, b))
    }

    #[inline(never)]
    fn a_edge(a: &mut NodeCore, level: bool, now: u64, io: &mut Board) {
        black_box(1u8); // keeps the four probes apart (no identical-code folding)
        a.input(black_box(BUTTON), level, now, io);
    }

    #[inline(never)]
    fn a_level(a: &mut NodeCore, level: bool, now: u64, io: &mut Board) {
        black_box(2u8); // keeps the four probes apart (no identical-code folding)
        a.input(black_box(BUTTON), level, now, io);
    }

    #[inline(never)]
    fn b_event(b: &mut NodeCore, mpdu: &[u8], now: u64, io: &mut Board) {
        black_box(3u8); // keeps the four probes apart (no identical-code folding)
        b.receive_mpdu(black_box(mpdu), now, io);
    }

    #[inline(never)]
    fn a_ack(a: &mut NodeCore, mpdu: &[u8], now: u64, io: &mut Board) {
        black_box(4u8); // keeps the four probes apart (no identical-code folding)
        a.receive_mpdu(black_box(mpdu), now, io);
    }

    /// Moves what `from` sent to `to` through `deliver`; returns how many frames.
    fn carry(
        from: &mut Board,
        to: &mut NodeCore,
        to_io: &mut Board,
        now: u64,
        deliver: fn(&mut NodeCore, &[u8], u64, &mut Board),
    ) -> usize {
        let n = from.sent;
        for i in 0..n {
            let (f, l) = (from.frames[i], from.lens[i]);
            deliver(to, &f[..l], now, to_io);
        }
        from.sent = 0;
        n
    }

    /// `n` presses, the events and acks secured with link keys if `secured`.
    pub fn presses(n: u64, secured: bool) -> Result<String, String> {
        let (ta, tb) = tables()?;
        let mut a = NodeCore::new(A, u64::MAX, Some(ta), 1);
        let mut b = NodeCore::new(B, u64::MAX, Some(tb), 1);
        if secured {
            a = a.with_link_keys(link_keys(A, B)?);
            b = b.with_link_keys(link_keys(B, A)?);
            if !(a.links_secured() && b.links_secured()) {
                return Err("the link keys were not taken".into());
            }
        }
        let (mut ia, mut ib) = (Board::new(), Board::new());
        a.boot(&mut ia);
        b.boot(&mut ib);
        let (mut events, mut acks) = (0, 0);
        let mut now = 0;
        // Past the boot's greetings (`restart::GREETED_WITHIN_MS`): the figures are those of
        // a machine that runs. (A greeting heard with B's lamp on, its chart under way,
        // faults B: the figures were then those of a faulted node's.)
        while now <= node_fw::restart::GREETED_WITHIN_MS {
            now += 10;
            a.poll(now, &mut ia);
            b.poll(now, &mut ib);
            while carry(&mut ia, &mut b, &mut ib, now, deliver)
                + carry(&mut ib, &mut a, &mut ia, now, deliver)
                > 0
            {}
        }
        for _ in 0..n {
            for level in [true, false] {
                now += 10;
                a_edge(&mut a, level, now, &mut ia);
                a_level(&mut a, level, now, &mut ia);
                a.poll(now, &mut ia);
                b.poll(now, &mut ib);
                // Until nothing is left to carry: a secured link's first frames run its
                // freshness handshake (greetings, a challenge and its answer).
                loop {
                    let e = carry(&mut ia, &mut b, &mut ib, now, b_event);
                    let k = carry(&mut ib, &mut a, &mut ia, now, a_ack);
                    events += e;
                    acks += k;
                    if e + k == 0 {
                        break;
                    }
                }
            }
        }
        // Every press toggled B's lamp (its chart on after an odd count), none faulted it.
        let status = b.status(0, Default::default());
        if status.fault.is_some() || status.states.first() != Some(&((n % 2) as u8)) {
            return Err(format!("B did not run every press: {status:?}"));
        }
        Ok(format!(
            "{events} events, {acks} acks, lamp pins {:#x}",
            ib.pins
        ))
    }

    /// Delivers a frame outside the probes (before the measured presses).
    fn deliver(to: &mut NodeCore, mpdu: &[u8], now: u64, io: &mut Board) {
        to.receive_mpdu(mpdu, now, io);
    }
}
