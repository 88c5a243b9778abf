//! The shared channel: who is connected, what is in flight, and the faults of each
//! delivery. The [`Hub`] holds it under one lock: a connection's thread hands its client's
//! messages to it in order (levels are relayed at once, frames put on the air), and the air
//! thread delivers each frame when its airtime ends. Nobody waits on a client while
//! holding it (every client has its own outbox).

use std::cmp::Reverse;
use std::collections::{BTreeMap, BTreeSet, BinaryHeap, HashMap, VecDeque};
use std::sync::{Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use config_schema::wire::mac::{self, BROADCAST};
use config_schema::wire::medium::{Link, Peer};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::outbox::{Outbox, Refused};
use super::{limits, ClientId, Config, Counters, Event, PcapLog};

struct Client {
    peer: Peer,
    outbox: Outbox,
    /// When each of its frames still waiting for (or on) the air leaves it.
    tx_queue: VecDeque<Instant>,
    /// A node's outputs it drove high (bit = pin number, pins 0 to 63): they drop when it
    /// goes away, as a power cut de-energizes its valves.
    high: u64,
}

/// A frame due at a client.
#[derive(PartialEq, Eq, PartialOrd, Ord)]
struct Due {
    at: Instant,
    seq: u64,
    to: ClientId,
    psdu: Vec<u8>,
}

pub(super) struct Air {
    config: Config,
    rng: StdRng,
    clients: HashMap<ClientId, Client>,
    due: BinaryHeap<Reverse<Due>>,
    seq: u64,
    air_free: Instant,
    start: Instant,
    pcap: Option<PcapLog>,
    counters: Counters,
    /// Cut links: (from, to) radio addresses.
    cuts: BTreeSet<(u16, u16)>,
    /// The generation each connected node last said it runs: told to a plant or monitor
    /// that joins later (one entry per connected node).
    running: BTreeMap<u16, u32>,
    /// Told to stop: nothing more is relayed.
    stopped: bool,
}

/// The air, shared by the connections' threads and the air thread.
pub(super) struct Hub {
    air: Mutex<Air>,
    /// Signalled when the earliest delivery moves earlier, or the medium stops.
    due: Condvar,
}

impl Hub {
    pub fn new(air: Air) -> Hub {
        Hub {
            air: Mutex::new(air),
            due: Condvar::new(),
        }
    }

    fn lock(&self) -> MutexGuard<'_, Air> {
        self.air.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Handles `event` on the caller's thread; `false` once the medium stopped.
    pub fn handle(&self, event: Event) -> bool {
        let mut air = self.lock();
        if air.stopped {
            return false;
        }
        let before = air.next_due();
        air.handle(event);
        air.count_clients();
        let after = air.next_due();
        if air.stopped || after.is_some_and(|a| before.is_none_or(|b| a < b)) {
            self.due.notify_one();
        }
        true
    }

    /// The air thread: delivers every frame when it is due, until the medium stops; then
    /// closes every connection.
    pub fn run(&self) {
        // A delivery is a timed wait: let it end when the airtime does.
        super::precise_timers();
        let mut air = self.lock();
        while !air.stopped {
            air.deliver_due();
            air.count_clients();
            let timeout = air
                .next_due()
                .map(|at| at.saturating_duration_since(Instant::now()))
                .unwrap_or(Duration::from_millis(100));
            air = match self.due.wait_timeout(air, timeout) {
                Ok((air, _)) => air,
                Err(p) => p.into_inner().0,
            };
        }
        for client in air.clients.values() {
            client.outbox.close();
        }
    }
}

impl Air {
    pub fn new(config: Config, start: Instant, pcap: Option<PcapLog>, counters: Counters) -> Air {
        Air {
            rng: StdRng::seed_from_u64(config.seed),
            config,
            clients: HashMap::new(),
            due: BinaryHeap::new(),
            seq: 0,
            air_free: start,
            start,
            pcap,
            counters,
            cuts: BTreeSet::new(),
            running: BTreeMap::new(),
            stopped: false,
        }
    }

    /// The clients and the frames in flight, as the stats show them.
    fn count_clients(&self) {
        let (clients, queued) = (self.clients.len() as u64, self.due.len() as u64);
        self.counters.count(|s| {
            s.clients = clients;
            s.queued = queued;
        });
    }

    fn next_due(&self) -> Option<Instant> {
        self.due.peek().map(|d| d.0.at)
    }

    fn handle(&mut self, event: Event) {
        match event {
            Event::Joined(id, peer, outbox) => {
                let told = |o: &Outbox| {
                    !matches!(peer, Peer::Plant | Peer::Monitor)
                        || self.running.iter().all(|(&addr, &generation)| {
                            o.put(&Link::Running { addr, generation }).is_ok()
                        })
                };
                if outbox.put(&Link::Welcome).is_ok() && told(&outbox) {
                    let tx_queue = VecDeque::new();
                    self.clients.insert(
                        id,
                        Client {
                            peer,
                            outbox,
                            tx_queue,
                            high: 0,
                        },
                    );
                } else {
                    outbox.close();
                }
            }
            Event::Left(id) => self.drop_client(id),
            Event::Frame(id, psdu) => self.transmit(id, psdu),
            Event::Pin(id, addr, pin, level) => self.pin(id, addr, pin, level),
            Event::Running(id, addr, generation) => self.running(id, addr, generation),
            Event::Sync(id, n) => {
                self.send(id, &Link::Synced(n));
            }
            Event::Clock(id) => {
                let at_us = self.start.elapsed().as_micros() as u64;
                self.send(id, &Link::Now { at_us });
            }
            Event::Cut { from, to } => {
                // Bounded: one entry per pair of 16-bit addresses at most, and only the
                // tool process (not a client) can cut.
                self.cuts.insert((from, to));
            }
            Event::Stop => self.stopped = true,
        }
    }

    fn drop_client(&mut self, id: ClientId) {
        if let Some(c) = self.clients.remove(&id) {
            if let Peer::Node { addr } = c.peer {
                self.running.remove(&addr);
                // Its power is gone: every output it held high drops.
                let mut high = c.high;
                while high != 0 {
                    let pin = high.trailing_zeros() as u8;
                    high &= high - 1;
                    self.output(id, addr, pin, false);
                }
            }
            c.outbox.close();
        }
    }

    /// Queues `msg` for client `to`. A radio that cannot keep up loses it; a plant or a
    /// monitor that cannot keep up is disconnected (it would miss levels).
    fn send(&mut self, to: ClientId, msg: &Link) -> bool {
        let Some(client) = self.clients.get(&to) else {
            return false;
        };
        match client.outbox.put(msg) {
            Ok(()) => true,
            Err(Refused::Full) if radio_addr(client.peer).is_some() => {
                self.counters.count(|s| s.overruns += 1);
                false
            }
            Err(Refused::Full) => {
                self.counters.count(|s| s.slow += 1);
                self.drop_client(to);
                false
            }
            Err(Refused::Gone) => {
                self.drop_client(to);
                false
            }
        }
    }

    /// A frame goes on the air: after the frames before it, for its airtime; unless its
    /// sender already has `TX_QUEUE` frames waiting (a channel access failure).
    fn transmit(&mut self, from: ClientId, psdu: Vec<u8>) {
        let now = Instant::now();
        let Some(sender) = self.clients.get_mut(&from) else {
            return;
        };
        while sender.tx_queue.front().is_some_and(|t| *t <= now) {
            sender.tx_queue.pop_front();
        }
        if sender.tx_queue.len() >= limits::TX_QUEUE {
            self.counters.count(|s| s.busy += 1);
            return;
        }
        let airtime = Duration::from_micros(u64::from(mac::airtime_us(psdu.len())));
        let on_air = self.air_free.max(now);
        self.air_free = on_air + airtime;
        let arrives = self.air_free;
        sender.tx_queue.push_back(arrives);
        let sender_addr = radio_addr(sender.peer);
        if let Some(pcap) = &mut self.pcap {
            if let Err(e) = pcap.write(on_air.duration_since(self.start), &psdu) {
                self.counters.count(|s| {
                    s.pcap_unwritten += 1;
                    s.pcap_error.get_or_insert(e.kind());
                });
            }
        }
        self.counters.count(|s| {
            s.frames += 1;
            s.bytes += psdu.len() as u64;
            s.airtime_us += airtime.as_micros() as u64;
        });
        let dst = psdu_dst(&psdu);
        let targets: Vec<(ClientId, bool, bool)> = self
            .clients
            .iter()
            .filter(|(id, _)| **id != from)
            .filter(|(_, c)| match (radio_addr(c.peer), dst) {
                (Some(a), Some(d)) => a == d || d == BROADCAST,
                _ => c.peer == Peer::Monitor,
            })
            .map(|(id, c)| {
                let cut = match (sender_addr, radio_addr(c.peer)) {
                    (Some(s), Some(r)) => self.cuts.contains(&(s, r)),
                    _ => false,
                };
                (*id, c.peer == Peer::Monitor, cut)
            })
            .collect();
        for (to, monitor, cut) in targets {
            if monitor {
                self.schedule(to, arrives, psdu.clone());
                continue;
            }
            if cut {
                self.counters.count(|s| s.cut += 1);
                continue;
            }
            if self.rng.random_bool(self.config.loss.clamp(0.0, 1.0)) {
                self.counters.count(|s| s.lost += 1);
                continue;
            }
            let copies = if self.rng.random_bool(self.config.dup.clamp(0.0, 1.0)) {
                self.counters.count(|s| s.duplicated += 1);
                2
            } else {
                1
            };
            for _ in 0..copies {
                let mut bytes = psdu.clone();
                if self.rng.random_bool(self.config.corrupt.clamp(0.0, 1.0)) && !bytes.is_empty() {
                    let i = self.rng.random_range(0..bytes.len());
                    if let Some(b) = bytes.get_mut(i) {
                        *b ^= 1 << self.rng.random_range(0..8);
                    }
                    self.counters.count(|s| s.corrupted += 1);
                }
                let (lo, hi) = self.config.delay_ms;
                let extra = if hi > lo {
                    self.rng.random_range(lo..=hi)
                } else {
                    lo
                };
                self.schedule(to, arrives + Duration::from_millis(extra), bytes);
            }
        }
    }

    fn schedule(&mut self, to: ClientId, at: Instant, psdu: Vec<u8>) {
        self.seq += 1;
        self.due.push(Reverse(Due {
            at,
            seq: self.seq,
            to,
            psdu,
        }));
    }

    fn deliver_due(&mut self) {
        let now = Instant::now();
        while self.due.peek().is_some_and(|d| d.0.at <= now) {
            let Some(Reverse(d)) = self.due.pop() else {
                break;
            };
            let monitor = self
                .clients
                .get(&d.to)
                .is_some_and(|c| c.peer == Peer::Monitor);
            if self.send(d.to, &Link::Frame(&d.psdu)) && !monitor {
                self.counters.count(|s| s.delivered += 1);
            }
        }
    }

    /// Output levels go from a node to plants and monitors; input levels from a plant to the
    /// node with that address (and monitors). Plants and monitors get them stamped.
    fn pin(&mut self, from: ClientId, addr: u16, pin: u8, level: bool) {
        let Some(client) = self.clients.get_mut(&from) else {
            return;
        };
        let sender = client.peer;
        if sender == (Peer::Node { addr }) {
            if let Some(bit) = 1u64.checked_shl(u32::from(pin)) {
                client.high = if level {
                    client.high | bit
                } else {
                    client.high & !bit
                };
            }
            self.output(from, addr, pin, level);
            return;
        }
        // A plant's input level (a node's own outputs went above; another's are not its
        // to say).
        let at_us = self.start.elapsed().as_micros() as u64;
        let seen = Link::Seen {
            at_us,
            addr,
            pin,
            level,
            output: false,
        };
        let plain = Link::Pin { addr, pin, level };
        let targets: Vec<(ClientId, bool)> = self
            .clients
            .iter()
            .filter(|(id, _)| **id != from)
            .filter_map(|(id, c)| {
                let stamped = match (sender, c.peer) {
                    (Peer::Plant, Peer::Node { addr: a }) if a == addr => false,
                    (Peer::Plant, Peer::Monitor) => true,
                    _ => return None,
                };
                Some((*id, stamped))
            })
            .collect();
        for (to, stamped) in targets {
            self.send(to, if stamped { &seen } else { &plain });
        }
    }

    /// Output `pin` of node `addr` (client `from`, or gone) is at `level`: plants and
    /// monitors get it, stamped.
    fn output(&mut self, from: ClientId, addr: u16, pin: u8, level: bool) {
        let at_us = self.start.elapsed().as_micros() as u64;
        let seen = Link::Seen {
            at_us,
            addr,
            pin,
            level,
            output: true,
        };
        let targets: Vec<ClientId> = (self.clients.iter())
            .filter(|(id, c)| **id != from && matches!(c.peer, Peer::Plant | Peer::Monitor))
            .map(|(id, _)| *id)
            .collect();
        for to in targets {
            self.send(to, &seen);
        }
    }

    /// A node's running generation goes to plants and monitors, in order with its pins;
    /// only a node may say it, and only of itself.
    fn running(&mut self, from: ClientId, addr: u16, generation: u32) {
        let Some(Peer::Node { addr: a }) = self.clients.get(&from).map(|c| c.peer) else {
            return;
        };
        if a != addr {
            return;
        }
        self.running.insert(addr, generation);
        let targets: Vec<ClientId> = self
            .clients
            .iter()
            .filter(|(_, c)| matches!(c.peer, Peer::Plant | Peer::Monitor))
            .map(|(id, _)| *id)
            .collect();
        for to in targets {
            self.send(to, &Link::Running { addr, generation });
        }
    }
}

fn radio_addr(peer: Peer) -> Option<u16> {
    match peer {
        Peer::Node { addr } | Peer::Tool { addr } => Some(addr),
        Peer::Plant | Peer::Monitor => None,
    }
}

/// The destination short address of a data frame (without checking the FCS: a corrupted
/// frame still reaches its receiver, which drops it). `None` for anything else.
fn psdu_dst(psdu: &[u8]) -> Option<u16> {
    let fc = u16::from_le_bytes([*psdu.first()?, *psdu.get(1)?]);
    match fc & 0b111 {
        0b001 if (fc >> 10) & 0b11 == 0b10 => {
            Some(u16::from_le_bytes([*psdu.get(5)?, *psdu.get(6)?]))
        }
        _ => None,
    }
}
