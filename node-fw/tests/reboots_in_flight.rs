//! Two secured nodes that reboot at random times while frames of their old lives are still
//! in the air (held up to 2.5 s), on a radio that loses, copies and reorders: no life of
//! the subscriber takes a press twice, and once the radio settles a press reaches its last
//! life (no link stalls). Each press is on its own button and topic and toggles its own
//! output at B: a second delivery of a press to one life of B drives its pin low again.
//! (Across lives a press can be taken again: one the old life took, its acknowledgement
//! lost, goes to the new one.)
use config_schema::wire::mac::MAX_PAYLOAD;
use config_schema::wire::msg::Message;
use config_schema::wire::security::{self, ext_addr};
use config_schema::{Action, Output, Publication, Subscription, Table, Transition};
use node_fw::node::{Io, NodeCore};
use test_tables::{button, link_keys, pair_key, route};

const A: u16 = 1;
const B: u16 = 2;
const C: u16 = 3;
const PAN: u16 = 0x4242;
const N: usize = 8;

fn table_a() -> Table {
    let mut t = Table::empty("A");
    t.generation = 1;
    t.header.pan_id = PAN;
    t.peers.push(B).unwrap();
    for i in 0..N {
        let press = button(&mut t, i as u8);
        t.publications
            .push(Publication {
                event: press,
                topic: 10 + i as u8,
                subscribers: 0b1,
            })
            .unwrap();
    }
    t
}
fn table_b() -> Table {
    let mut t = Table::empty("B");
    t.generation = 1;
    t.header.pan_id = PAN;
    t.peers.push(A).unwrap();
    t.peers.push(C).unwrap();
    for i in 0..N {
        let ev = t.push_event().unwrap();
        t.outputs.push(Output::safe(20 + i as u8, false)).unwrap();
        t.subscriptions
            .push(Subscription {
                publisher: 0,
                topic: 10 + i as u8,
                event: ev,
            })
            .unwrap();
        let m = 1u16 << i;
        let off: &[Action] = &[Action::Drive { mask: m, value: 0 }];
        let on: &[Action] = &[Action::Drive { mask: m, value: m }];
        let tr = |from, to| Transition {
            from,
            to,
            trigger: Some(0),
            guard: None,
        };
        let c = t
            .push_chart(0, 1, &[off, on], &[tr(0, 1), tr(1, 0)])
            .unwrap();
        // Both states at rest: B is never under way (a peer's greeting faults nothing).
        t.charts[c as usize].idle = 1;
        route(&mut t, ev, c, 0);
    }
    t
}

#[derive(Default)]
struct Board {
    out: Vec<Vec<u8>>,
    pins: Vec<(u8, bool)>,
    counter: u32,
}
impl Io for Board {
    fn transmit(&mut self, psdu: &[u8]) {
        self.out.push(psdu.to_vec());
    }
    fn set_pin(&mut self, pin: u8, level: bool) {
        if pin >= 20 {
            self.pins.push((pin - 20, level));
        }
    }
    fn next_frame_counter(&mut self) -> Option<u32> {
        self.counter += 1;
        Some(self.counter)
    }
}

fn kind(psdu: &[u8]) -> String {
    let mut scratch = [0u8; MAX_PAYLOAD];
    match security::open(
        psdu,
        |h, _| Some((pair_key(h.src, h.dst), ext_addr(h.pan_id, h.src))),
        &mut scratch,
    ) {
        Ok(o) => format!(
            "{}>{} c{} {:?}",
            o.header.src,
            o.header.dst,
            o.aux.frame_counter,
            Message::parse(o.payload).unwrap()
        ),
        Err(_) => "?".into(),
    }
}

struct Rng(u64);
impl Rng {
    fn f(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A and B, their boards, the frames in the air (when due, to whom), the lives so far,
/// and what each life of B took.
struct World {
    a: NodeCore,
    ab: Board,
    b: NodeCore,
    bb: Board,
    now: u64,
    air: Vec<(u64, u16, Vec<u8>)>,
    a_life: u16,
    b_life: u16,
    trace: Vec<String>,
    /// Per B life: deliveries per button.
    b_got: Vec<[u32; N]>,
}
impl World {
    fn new() -> Self {
        let mut w = World {
            a: NodeCore::new(A, u64::MAX, Some(table_a()), 1).with_link_keys(link_keys(A, &[B], 1)),
            ab: Board::default(),
            b: NodeCore::new(B, u64::MAX, Some(table_b()), 1).with_link_keys(link_keys(
                B,
                &[A, C],
                1,
            )),
            bb: Board::default(),
            now: 0,
            air: vec![],
            a_life: 0,
            b_life: 0,
            trace: vec![],
            b_got: vec![[0; N]],
        };
        w.a.poll(0, &mut w.ab);
        w
    }
    fn reboot_a(&mut self) {
        self.a_life += 1;
        self.trace.push(format!("{} REBOOT A", self.now));
        self.a = NodeCore::new(A, u64::MAX, Some(table_a()), 100 * self.a_life + 1)
            .with_link_keys(link_keys(A, &[B], 1));
    }
    fn reboot_b(&mut self) {
        self.b_life += 1;
        self.trace.push(format!("{} REBOOT B", self.now));
        self.b = NodeCore::new(B, u64::MAX, Some(table_b()), 100 * self.b_life + 1)
            .with_link_keys(link_keys(B, &[A, C], 1));
        self.b_got.push([0; N]);
    }
    fn press(&mut self, i: usize) {
        self.trace.push(format!("{} PRESS {i}", self.now));
        self.a.input(i as u8, true, self.now, &mut self.ab);
        self.a.input(i as u8, false, self.now, &mut self.ab);
    }
    /// One ms: the nodes polled, what they sent put in the air (each copy `fate` gives it,
    /// after its delay: none if lost), what is due delivered.
    fn step(&mut self, fate: &mut dyn FnMut(&str) -> Vec<u64>) {
        self.now += 1;
        self.a.poll(self.now, &mut self.ab);
        self.b.poll(self.now, &mut self.bb);
        let mut sent: Vec<(u16, Vec<u8>)> = self.ab.out.drain(..).map(|f| (B, f)).collect();
        sent.extend(self.bb.out.drain(..).map(|f| (A, f)));
        for (dst, f) in sent {
            let k = kind(&f);
            for d in fate(&k) {
                self.air.push((self.now + d, dst, f.clone()));
            }
        }
        let (due, later): (Vec<_>, Vec<_>) = std::mem::take(&mut self.air)
            .into_iter()
            .partition(|(at, _, _)| *at <= self.now);
        self.air = later;
        for (_, dst, f) in due {
            let k = kind(&f);
            if k.contains(">1") || k.contains(">2") {
                self.trace.push(format!("{} {}", self.now, k));
            }
            match dst {
                A => self.a.receive(&f, self.now, &mut self.ab),
                B => {
                    self.b.receive(&f, self.now, &mut self.bb);
                    for (i, level) in self.bb.pins.drain(..) {
                        if i as usize >= N {
                            continue;
                        }
                        // Initial drive of outputs at boot: ignore lows.
                        if level || self.b_got.last().unwrap()[i as usize] > 0 {
                            self.b_got.last_mut().unwrap()[i as usize] += 1;
                            self.trace
                                .push(format!("{} B{} DELIVERED {i}", self.now, self.b_life));
                        }
                    }
                }
                _ => {}
            }
        }
        self.bb.pins.retain(|_| false);
    }
}

/// The nodes established on a perfect radio, then `events` (ms after the start: 0 a press
/// of the next button, 1 a reboot of A, 2 one of B) for 1.5 s on a radio of `loss`,
/// `dup`, `delay` (5 % of the frames held up to 2.5 s), 3 s to settle, a last press and 3 s
/// more: what went wrong, if anything.
fn scenario(
    seed: u64,
    loss: f64,
    dup: f64,
    delay: u64,
    events: &[(u64, u8)],
) -> Result<(), String> {
    let mut rng = Rng(seed.max(1));
    let mut w = World::new();
    // Established: perfect radio for 500 ms.
    for _ in 0..500 {
        w.step(&mut |_| vec![0]);
    }
    w.bb.pins.clear();
    let start = w.now;
    let mut next_button = 0usize;
    let mut fate = |_: &str| -> Vec<u64> {
        let mut v = vec![];
        if rng.f() < loss {
            return v;
        }
        let copies = if rng.f() < dup { 2 } else { 1 };
        for _ in 0..copies {
            let d = if rng.f() < 0.05 {
                (rng.f() * 2500.0) as u64
            } else {
                (rng.f() * (delay + 1) as f64) as u64
            };
            v.push(d);
        }
        v
    };
    let end = start + 1500;
    while w.now < end {
        for &(t, what) in events {
            if start + t == w.now + 1 {
                match what {
                    0 => {
                        if next_button < N - 1 {
                            w.press(next_button);
                            next_button += 1;
                        }
                    }
                    1 => w.reboot_a(),
                    _ => w.reboot_b(),
                }
            }
        }
        w.step(&mut fate);
    }
    // Settle on the same radio, then check a fresh press reaches the last B once.
    for _ in 0..3000 {
        w.step(&mut fate);
    }
    w.press(N - 1);
    for _ in 0..3000 {
        w.step(&mut fate);
    }
    for (life, got) in w.b_got.iter().enumerate() {
        if got.iter().any(|&n| n > 1) {
            return Err(format!(
                "B life {life} got a press twice: {got:?}\n{}",
                w.trace.join("\n")
            ));
        }
    }
    if w.b_got.last().unwrap()[N - 1] != 1 {
        return Err(format!(
            "stall: the last press did not reach the last B: {:?}\n{}",
            w.b_got,
            w.trace.join("\n")
        ));
    }
    Ok(())
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(300))]
    #[test]
    fn reboots_with_old_frames_in_the_air_deliver_each_press_once_per_life(
        seed in 1u64..,
        events in proptest::collection::vec((1u64..1200, 0u8..3), 1..12),
        loss in 0.0f64..0.35,
        dup in 0.0f64..0.2,
        delay in 0u64..300,
    ) {
        if let Err(e) = scenario(seed, loss, dup, delay, &events) {
            let short: String = e.lines().take(1).collect();
            eprintln!("{e}");
            proptest::prop_assert!(false, "{}", short);
        }
    }
}
