//! The Embassy runtime on the seams an MCU board uses: `embedded-hal` output pins,
//! `embedded-hal-async` input pins (through `WaitInputs`), a NOR flash, and a radio, all
//! faked in memory and run on Embassy's std executor. A table pushed over the radio is
//! persisted, activated and driven; a later boot on the same flash runs it; a flash that
//! fails refuses the table and keeps the old one; a radio that swallows a frame costs that
//! frame only.

use std::cell::{Cell, RefCell};
use std::convert::Infallible;
use std::future::poll_fn;
use std::rc::Rc;
use std::task::{Poll, Waker};

use config_schema::wire::mac::{self, Frame, Header, MAX_PSDU};
use config_schema::wire::msg::{Command, ConfigReply, Message, Refusal, RuntimeCounters, Status};
use config_schema::Table;
use embassy_futures::join::join;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::channel::Channel;
use embassy_time::{Instant, Timer};
use embedded_hal::digital::{ErrorType, InputPin, OutputPin};
use embedded_hal_async::digital::Wait;
use embedded_storage_async::nor_flash::{self as nor, NorFlash, ReadNorFlash};
use node_fw::host::block_on;
use node_fw::node::CONFIG_PAN;
use node_fw::runtime::{
    self, mpdu_of, psdu_of, Board, Boot, Inputs, Pins, Radio, Received, Stats, Stop, WaitInputs,
};
use node_fw::slots::{PowerCut, RamFlash, Slots};
use node_fw::{ota, switch};
use test_tables::{blob, lamp_table, BEACON, BUTTON, LAMP};

const ADDR: u16 = 0x0009;
const TOOL: u16 = 0x0100;
/// Every wait of the scripts below (in Embassy time).
const WAIT_MS: u64 = 10_000;

// ---------------------------------------------------------------- fake hardware

/// Output pin `pin`: every level it is driven to lands in the shared log.
struct FakeOut {
    pin: u8,
    log: Rc<RefCell<Vec<(u8, bool)>>>,
}

impl ErrorType for FakeOut {
    type Error = Infallible;
}

impl OutputPin for FakeOut {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.log.borrow_mut().push((self.pin, false));
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.log.borrow_mut().push((self.pin, true));
        Ok(())
    }
}

fn outputs(log: &Rc<RefCell<Vec<(u8, bool)>>>) -> [FakeOut; 10] {
    std::array::from_fn(|i| FakeOut {
        pin: i as u8,
        log: log.clone(),
    })
}

/// The outside of an input pin: its level, and who waits for an edge.
#[derive(Default)]
struct Line {
    level: Cell<bool>,
    edges: Cell<u32>,
    waker: RefCell<Option<Waker>>,
}

impl Line {
    fn set(&self, level: bool) {
        if self.level.replace(level) != level {
            self.edges.set(self.edges.get() + 1);
            if let Some(w) = self.waker.borrow_mut().take() {
                w.wake();
            }
        }
    }
}

struct FakeIn(Rc<Line>);

impl ErrorType for FakeIn {
    type Error = Infallible;
}

impl InputPin for FakeIn {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(self.0.level.get())
    }
    fn is_low(&mut self) -> Result<bool, Infallible> {
        Ok(!self.0.level.get())
    }
}

impl Wait for FakeIn {
    async fn wait_for_high(&mut self) -> Result<(), Infallible> {
        unimplemented!("the runtime waits for edges")
    }
    async fn wait_for_low(&mut self) -> Result<(), Infallible> {
        unimplemented!("the runtime waits for edges")
    }
    async fn wait_for_rising_edge(&mut self) -> Result<(), Infallible> {
        unimplemented!("the runtime waits for edges")
    }
    async fn wait_for_falling_edge(&mut self) -> Result<(), Infallible> {
        unimplemented!("the runtime waits for edges")
    }
    async fn wait_for_any_edge(&mut self) -> Result<(), Infallible> {
        let start = self.0.edges.get();
        poll_fn(|cx| {
            if self.0.edges.get() != start {
                Poll::Ready(Ok(()))
            } else {
                *self.0.waker.borrow_mut() = Some(cx.waker().clone());
                Poll::Pending
            }
        })
        .await
    }
}

/// The air around the node: frames to it (`None`: the radio is gone), frames from it.
struct Air {
    to_node: Channel<NoopRawMutex, Option<Vec<u8>>, 16>,
    from_node: RefCell<Vec<Vec<u8>>>,
    /// The radio never completes this many more sends.
    swallow: Cell<u32>,
}

impl Default for Air {
    fn default() -> Self {
        Air {
            to_node: Channel::new(),
            from_node: RefCell::default(),
            swallow: Cell::new(0),
        }
    }
}

struct FakeRadio(Rc<Air>);

impl Radio for FakeRadio {
    type Error = &'static str;
    // The radio edge in software: the air carries PSDUs.
    async fn send(&mut self, mpdu: &[u8]) -> Result<(), &'static str> {
        if self.0.swallow.get() > 0 {
            self.0.swallow.set(self.0.swallow.get() - 1);
            return core::future::pending().await;
        }
        let psdu = psdu_of(mpdu).ok_or("not an MPDU")?;
        self.0.from_node.borrow_mut().push(psdu.to_vec());
        Ok(())
    }
    async fn receive(&mut self, buf: &mut [u8; MAX_PSDU]) -> Result<Received, &'static str> {
        let psdu = self.0.to_node.receive().await.ok_or("gone")?;
        Ok(mpdu_of(&psdu, buf))
    }
}

const FLASH: usize = 2 * Slots::<RamFlash<1>>::slot_size();

/// A RAM flash that outlives one boot, and can be made to fail: `broken` (every erase and
/// write fails), `fail_reads` (the next reads fail), `fail_op` (that erase or write,
/// counted from 1 in `ops`, fails and writes nothing; the others work: a transient
/// error, not a power cut).
#[derive(Clone, Default)]
struct Flash {
    cells: Rc<RefCell<RamFlash<FLASH>>>,
    broken: Rc<Cell<bool>>,
    fail_reads: Rc<Cell<u32>>,
    ops: Rc<Cell<usize>>,
    fail_op: Rc<Cell<Option<usize>>>,
}

impl Flash {
    /// One more erase or write: whether it fails.
    fn fails(&self) -> bool {
        let n = self.ops.get() + 1;
        self.ops.set(n);
        self.broken.get() || self.fail_op.get() == Some(n)
    }
}

impl nor::ErrorType for Flash {
    type Error = PowerCut;
}

impl ReadNorFlash for Flash {
    const READ_SIZE: usize = 1;
    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), PowerCut> {
        if self.fail_reads.get() > 0 {
            self.fail_reads.set(self.fail_reads.get() - 1);
            return Err(PowerCut);
        }
        let mut cells = self.cells.borrow_mut();
        embassy_futures::block_on(cells.read(offset, bytes))
    }
    fn capacity(&self) -> usize {
        FLASH
    }
}

impl NorFlash for Flash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = 1024;
    async fn erase(&mut self, from: u32, to: u32) -> Result<(), PowerCut> {
        if self.fails() {
            return Err(PowerCut);
        }
        let mut cells = self.cells.borrow_mut();
        embassy_futures::block_on(cells.erase(from, to))
    }
    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), PowerCut> {
        if self.fails() {
            return Err(PowerCut);
        }
        let mut cells = self.cells.borrow_mut();
        embassy_futures::block_on(cells.write(offset, bytes))
    }
}

// ---------------------------------------------------------------- the tool's side

/// The tool, in the same executor as the node.
struct Tool {
    air: Rc<Air>,
    seq: u8,
    id: u16,
    /// How many of the node's frames were already looked at.
    seen: usize,
}

impl Tool {
    async fn send(&mut self, msg: &Message<'_>) {
        let mut payload = [0u8; mac::MAX_PAYLOAD];
        let n = msg.emit(&mut payload).unwrap();
        let header = Header {
            seq: self.seq,
            pan_id: CONFIG_PAN,
            dst: ADDR,
            src: TOOL,
            ack_request: false,
            secured: false,
        };
        self.seq = self.seq.wrapping_add(1);
        let mut psdu = [0u8; MAX_PSDU];
        let len = mac::emit_data(&header, &payload[..n], &mut psdu).unwrap();
        self.air.to_node.send(Some(psdu[..len].to_vec())).await;
    }

    /// The node's next frame, parsed, within `ms`.
    async fn next(&mut self, ms: u64) -> Option<Message<'static>> {
        let deadline = Instant::now().as_millis() + ms;
        loop {
            let frame = self.air.from_node.borrow().get(self.seen).cloned();
            if let Some(psdu) = frame {
                self.seen += 1;
                let Ok(Frame::Data { payload, .. }) = Frame::parse(&psdu) else {
                    panic!("the node sent a frame that does not parse");
                };
                let owned: &'static [u8] = Box::leak(payload.to_vec().into_boxed_slice());
                return Some(Message::parse(owned).unwrap());
            }
            if Instant::now().as_millis() >= deadline {
                return None;
            }
            Timer::after_millis(1).await;
        }
    }

    async fn status(&mut self) -> Status {
        self.id += 1;
        let id = self.id;
        self.send(&Message::Command {
            id,
            command: Command::Status,
        })
        .await;
        loop {
            match self.next(WAIT_MS).await {
                Some(Message::Status(s)) => return s,
                Some(_) => continue,
                None => panic!("no status"),
            }
        }
    }

    /// Asks for the status until `done` holds (at most `WAIT_MS`); returns the last one.
    async fn status_until(&mut self, done: impl Fn(&Status) -> bool) -> Status {
        let deadline = Instant::now().as_millis() + WAIT_MS;
        loop {
            let s = self.status().await;
            if done(&s) || Instant::now().as_millis() >= deadline {
                return s;
            }
            Timer::after_millis(1).await;
        }
    }

    async fn push(&mut self, table: &Table) -> ota::Progress {
        let bytes = blob(table);
        let mut tx = ota::Sender::new(&bytes, table.generation, false);
        let mut out = Vec::new();
        tx.start(Instant::now().as_millis(), |m| out.push(m));
        if self.carry(&mut tx, &mut out).await != ota::Progress::Done {
            return tx.progress();
        }
        // Staged: switch it over (the node is idle), as `push` does.
        match self.switch(table.generation, false).await {
            switch::Verdict::Switched => ota::Progress::Done,
            _ => ota::Progress::Refused(config_schema::wire::msg::Refusal::Flash),
        }
    }

    /// Carries the transfer of `tx` (started: its first messages in `out`) until it is
    /// done or refused (at most `WAIT_MS`).
    async fn carry<'b>(
        &mut self,
        tx: &mut ota::Sender<'b>,
        out: &mut Vec<Message<'b>>,
    ) -> ota::Progress {
        let now = || Instant::now().as_millis();
        let start = now();
        while tx.progress() == ota::Progress::Busy && now() - start < WAIT_MS {
            for m in std::mem::take(out) {
                self.send(&m).await;
            }
            if let Some(Message::ConfigReply { generation, reply }) = self.next(5).await {
                tx.on_reply(generation, reply, now(), |m| out.push(m));
            }
            tx.poll(now(), |m| out.push(m));
        }
        tx.progress()
    }

    /// Switches the node (idle) over to the staged `generation`, as a trial if `trial`.
    async fn switch(&mut self, generation: u32, trial: bool) -> switch::Verdict {
        let now = || Instant::now().as_millis();
        let start = now();
        let addr = ADDR;
        let mut c = switch::Coordinator::new(&[addr], generation, false, WAIT_MS, now());
        if trial {
            c = c.on_trial();
        }
        let mut out: Vec<(u16, Message<'static>)> = Vec::new();
        while c.verdict() == switch::Verdict::Busy && now() - start < WAIT_MS {
            c.poll(now(), |a, m| out.push((a, m)));
            for (_, m) in std::mem::take(&mut out) {
                self.send(&m).await;
            }
            if let Some(Message::ConfigReply { generation, reply }) = self.next(5).await {
                c.on_reply(addr, generation, reply, now(), |a, m| out.push((a, m)));
            }
        }
        c.verdict()
    }

    async fn close(&self) {
        self.air.to_node.send(None).await;
    }
}

/// Runs one boot of the node on `flash`, with the link epochs of `boot_count`, beside
/// `script`; returns why the node stopped.
fn boot<S>(
    boot_count: Boot<'static>,
    flash: Flash,
    lines: &[Rc<Line>; 10],
    pins: &Rc<RefCell<Vec<(u8, bool)>>>,
    air: Rc<Air>,
    script: impl FnOnce(Tool) -> S + 'static,
) -> (Stop<&'static str>, Stats)
where
    S: std::future::Future<Output = ()> + 'static,
{
    let outs = outputs(pins);
    let ins: [FakeIn; 10] = std::array::from_fn(|i| FakeIn(lines[i].clone()));
    let tool = Tool {
        air: air.clone(),
        seq: 0,
        id: 0,
        seen: 0,
    };
    let node = async move {
        let mut ins = ins;
        let board = Board {
            radio: FakeRadio(air),
            outputs: outs,
            inputs: WaitInputs::new(&mut ins),
            flash,
            pin_mask: runtime::pin_range(10),
        };
        runtime::run_secured(ADDR, boot_count, board, &mut (), None).await
    };
    block_on(async move { join(node, script(tool)).await.0 }).expect("spawned")
}

/// Waits (at most `WAIT_MS`) until `log` holds `n` entries.
async fn wait_len(log: &RefCell<Vec<(u8, bool)>>, n: usize) {
    let deadline = Instant::now().as_millis() + WAIT_MS;
    while log.borrow().len() < n && Instant::now().as_millis() < deadline {
        Timer::after_millis(1).await;
    }
}

fn lines() -> [Rc<Line>; 10] {
    std::array::from_fn(|_| Rc::new(Line::default()))
}

// ---------------------------------------------------------------- tests

#[test]
fn pushed_table_is_persisted_driven_and_booted_again() {
    let flash = Flash::default();
    let lines = lines();
    let pins = Rc::new(RefCell::new(Vec::new()));
    let button = lines[usize::from(BUTTON)].clone();
    let seen = pins.clone();
    let (stop, stats) = boot(
        Boot::Epoch(1),
        flash.clone(),
        &lines,
        &pins,
        Rc::default(),
        move |mut tool| {
            async move {
                // Boot: every output off, then the unconfigured node announces itself.
                let all_off: Vec<(u8, bool)> = (0..10).map(|p| (p, false)).collect();
                assert_eq!(*seen.borrow(), all_off);
                assert!(
                    matches!(tool.next(WAIT_MS).await, Some(Message::Announce(a)) if a.generation == 0)
                );
                // The button is held while the table arrives: the new engine starts with it
                // pressed, and no phantom press toggles the lamp.
                button.set(true);
                seen.borrow_mut().clear();
                assert_eq!(tool.push(&lamp_table(3)).await, ota::Progress::Done);
                let s = tool.status().await;
                assert_eq!((s.role.as_str(), s.generation), ("lamp", 3));
                assert_eq!((s.inputs, s.states.as_slice()), (1, &[0][..]));
                assert_eq!(*seen.borrow(), vec![(LAMP, false), (BEACON, true)]);
                // Released, then pressed: the lamp goes on.
                button.set(false);
                assert_eq!(tool.status_until(|s| s.inputs == 0).await.inputs, 0);
                button.set(true);
                wait_len(&seen, 3).await;
                let s = tool.status_until(|s| s.inputs == 1).await;
                assert_eq!((s.inputs, s.states.as_slice()), (1, &[1][..]));
                assert_eq!(
                    *seen.borrow(),
                    vec![(LAMP, false), (BEACON, true), (LAMP, true)]
                );
                tool.close().await;
            }
        },
    );
    assert_eq!(stop, Stop::Radio("gone"));
    assert_eq!(
        (stats.activations, stats.flash_failures, stats.tx_failed),
        (1, 0, 0)
    );

    // Next boot on the same flash, the button still held: the table runs at once (outputs
    // off, then safe), and the engine starts from the button's real level.
    pins.borrow_mut().clear();
    let seen = pins.clone();
    let button = lines[usize::from(BUTTON)].clone();
    let (_, stats) = boot(
        Boot::Epoch(1),
        flash,
        &lines,
        &pins,
        Rc::default(),
        move |mut tool| async move {
            let s = tool.status().await;
            assert_eq!((s.role.as_str(), s.generation), ("lamp", 3));
            assert_eq!((s.inputs, s.states.as_slice()), (1, &[0][..]));
            let mut expected: Vec<(u8, bool)> = (0..10).map(|p| (p, false)).collect();
            expected.extend([(LAMP, false), (BEACON, true)]);
            assert_eq!(*seen.borrow(), expected);
            button.set(false);
            assert_eq!(tool.status_until(|s| s.inputs == 0).await.inputs, 0);
            button.set(true);
            expected.push((LAMP, true));
            wait_len(&seen, expected.len()).await;
            assert_eq!(*seen.borrow(), expected);
            tool.close().await;
        },
    );
    assert_eq!(stats.activations, 0, "booted, not pushed");
}

/// A node on a board with a boot counter takes link epochs (here an operator's reset of
/// a link its peer never acknowledges, one epoch each) until half of those its boot count
/// reserves are left: then the runtime has the board count one more boot, once, and the
/// node goes on in the same epochs (the next boot starts 256 further).
#[test]
fn the_runtime_counts_a_boot_once_half_the_reserved_epochs_are_taken() {
    let lines = lines();
    let pins = Rc::new(RefCell::new(Vec::new()));
    let button = lines[usize::from(BUTTON)].clone();
    // What the board's counter was asked, at which epoch of the node's (read by status).
    let counts = Rc::new(RefCell::new(Vec::new()));
    let asked = counts.clone();
    // (The executor takes a future that borrows nothing: the counter is leaked, as the
    // host board's is.)
    let count: &'static mut dyn FnMut() -> Option<u32> = Box::leak(Box::new(move || {
        asked.borrow_mut().push(());
        Some(8)
    }));
    let boot_count = Boot::Counted {
        boots: 7,
        persisted: true,
        count,
    };
    let seen = counts.clone();
    let mut table = lamp_table(3);
    table.peers.push(0x0042).unwrap();
    let press = table.inputs[0].rise.unwrap();
    (table.publications)
        .push(config_schema::Publication {
            event: press,
            topic: 1,
            subscribers: 0b1,
        })
        .unwrap();
    let (_, stats) = boot(
        boot_count,
        Flash::default(),
        &lines,
        &pins,
        Rc::default(),
        move |mut tool| async move {
            assert_eq!(tool.push(&table).await, ota::Progress::Done);
            assert_eq!(tool.status().await.epoch, 7 * 256 + 1, "the table's");
            for epoch in 7 * 256 + 2..=7 * 256 + 130 {
                // A press the peer never acknowledges, then the reset that numbers the
                // link again.
                button.set(true);
                tool.status_until(|s| s.inputs == 1).await;
                button.set(false);
                tool.status_until(|s| s.inputs == 0).await;
                tool.id += 1;
                let id = tool.id;
                (tool.send(&Message::Command {
                    id,
                    command: Command::Reset,
                }))
                .await;
                let s = tool.status_until(|s| s.epoch == epoch).await;
                assert_eq!(s.epoch, epoch);
                let expected = usize::from(epoch >= 7 * 256 + 128);
                assert_eq!(seen.borrow().len(), expected, "at epoch {epoch}");
            }
            tool.close().await;
        },
    );
    assert_eq!(counts.borrow().len(), 1);
    assert_eq!(stats.flash_failures, 0);
}

/// A node on trial refuses a push: staged, the new table would go over the previous one,
/// the only confirmed one. So is a transfer begun before the trial and carried on during
/// it (it was staged, over generation 1: after a power cut before `confirm` the node booted
/// no table at all, generation 0). Now its next chunk is refused `OnTrial`, nothing is
/// staged, and a power cut boots generation 1.
#[test]
fn a_transfer_begun_before_a_trial_is_refused_on_trial_and_a_power_cut_boots_the_confirmed_table() {
    let flash = Flash::default();
    let lines = lines();
    let pins = Rc::new(RefCell::new(Vec::new()));
    boot(
        Boot::Epoch(1),
        flash.clone(),
        &lines,
        &pins,
        Rc::default(),
        move |mut tool| async move {
            assert_eq!(tool.push(&lamp_table(1)).await, ota::Progress::Done);
            let two = blob(&lamp_table(2));
            let mut tx = ota::Sender::new(&two, 2, false);
            let mut out = Vec::new();
            tx.start(Instant::now().as_millis(), |m| out.push(m));
            assert_eq!(tool.carry(&mut tx, &mut out).await, ota::Progress::Done);
            // Generation 3's transfer begins (its begin answered) ...
            let three = blob(&lamp_table(3));
            let mut tx = ota::Sender::new(&three, 3, false);
            let mut out = Vec::new();
            tx.start(Instant::now().as_millis(), |m| out.push(m));
            for m in std::mem::take(&mut out) {
                tool.send(&m).await;
            }
            let Some(Message::ConfigReply { generation, reply }) = tool.next(WAIT_MS).await else {
                panic!("no answer to the begin");
            };
            assert_eq!((generation, reply), (3, ConfigReply::Next { next: 0 }));
            tx.on_reply(generation, reply, Instant::now().as_millis(), |m| {
                out.push(m)
            });
            // ... then generation 2 goes on trial, then generation 3's chunks.
            assert_eq!(tool.switch(2, true).await, switch::Verdict::Switched);
            assert_eq!(
                tool.carry(&mut tx, &mut out).await,
                ota::Progress::Refused(Refusal::OnTrial)
            );
            let s = tool.status().await;
            assert_eq!((s.generation, s.trial, s.staged), (2, true, 0));
            tool.close().await;
        },
    );
    // A power cut before `confirm`: the previous, confirmed generation boots.
    boot(
        Boot::Epoch(1),
        flash,
        &lines,
        &pins,
        Rc::default(),
        move |mut tool| async move {
            let s = tool.status().await;
            assert_eq!((s.role.as_str(), s.generation, s.trial), ("lamp", 1, false));
            tool.close().await;
        },
    );
}

#[test]
fn a_table_the_flash_cannot_hold_is_refused_and_nothing_changes() {
    let flash = Flash::default();
    flash.broken.set(true);
    let broken = flash.broken.clone();
    let lines = lines();
    let pins = Rc::new(RefCell::new(Vec::new()));
    let seen = pins.clone();
    let (_, stats) = boot(
        Boot::Epoch(1),
        flash,
        &lines,
        &pins,
        Rc::default(),
        move |mut tool| async move {
            seen.borrow_mut().clear();
            assert_eq!(
                tool.push(&lamp_table(2)).await,
                ota::Progress::Refused(Refusal::Flash)
            );
            let s = tool.status().await;
            assert_eq!(
                (s.role.as_str(), s.generation),
                ("", 0),
                "still unconfigured"
            );
            // Status shows the runtime's counters: the flash failure, and the transmit
            // queue's high-water mark (one frame at a time here), nothing dropped.
            assert_eq!(
                s.runtime,
                RuntimeCounters {
                    tx_queue_full: 0,
                    tx_queue_high: 1,
                    tx_failed: 0,
                    flash_failures: 1,
                }
            );
            assert!(seen.borrow().is_empty(), "no output moved");
            broken.set(false);
            assert_eq!(tool.push(&lamp_table(2)).await, ota::Progress::Done);
            assert_eq!(tool.status().await.generation, 2);
            tool.close().await;
        },
    );
    assert_eq!((stats.flash_failures, stats.activations), (1, 1));
}

/// The fake board has pins 0..=9: a table with its beacon on pin 12 is refused, naming the
/// pin and the board's pins, and the node stays as it was.
#[test]
fn a_table_naming_a_pin_the_board_lacks_is_refused() {
    let lines = lines();
    let pins = Rc::new(RefCell::new(Vec::new()));
    let seen = pins.clone();
    let (_, stats) = boot(
        Boot::Epoch(1),
        Flash::default(),
        &lines,
        &pins,
        Rc::default(),
        move |mut tool| async move {
            seen.borrow_mut().clear();
            let mut t = lamp_table(2);
            t.outputs[1].pin = 12;
            assert_eq!(
                tool.push(&t).await,
                ota::Progress::Refused(Refusal::Pin {
                    pin: 12,
                    board: 0x3FF
                })
            );
            assert_eq!(tool.status().await.generation, 0, "still unconfigured");
            assert!(seen.borrow().is_empty(), "no output moved");
            tool.close().await;
        },
    );
    assert_eq!((stats.flash_failures, stats.activations), (0, 0));
}

#[test]
fn a_radio_that_never_takes_a_frame_costs_that_frame_only() {
    let air = Rc::new(Air::default());
    air.swallow.set(1); // the first announcement
    let lines = lines();
    let pins = Rc::new(RefCell::new(Vec::new()));
    let (_, stats) = boot(
        Boot::Epoch(1),
        Flash::default(),
        &lines,
        &pins,
        air,
        |mut tool| async move {
            let s = tool.status().await;
            assert_eq!(s.generation, 0);
            tool.close().await;
        },
    );
    assert_eq!(stats.tx_failed, 1);
    assert_eq!(stats.tx_queue_full, 0);
}

#[test]
fn a_flash_too_small_for_two_slots_stops_the_runtime() {
    let lines = lines();
    let pins = Rc::new(RefCell::new(Vec::new()));
    let board = Board {
        radio: FakeRadio(Rc::default()),
        outputs: outputs(&pins),
        inputs: (),
        flash: RamFlash::<1024>::new(),
        pin_mask: runtime::pin_range(10),
    };
    let (stop, _) = block_on(runtime::run(ADDR, 1, board)).unwrap();
    assert_eq!(stop, Stop::FlashGeometry);
    assert_eq!(pins.borrow().len(), 10, "outputs off before anything else");
    drop(lines);
}

#[test]
fn wait_inputs_report_levels_so_no_edge_is_lost() {
    let lines = lines();
    let mut ins: [FakeIn; 10] = std::array::from_fn(|i| FakeIn(lines[i].clone()));
    let mut inputs = WaitInputs::new(&mut ins);
    lines[3].set(true);
    lines[6].set(true);
    // The levels at boot, which are then not reported as changes.
    assert_eq!(inputs.levels(), (1 << 3) | (1 << 6));
    let next =
        |inputs: &mut WaitInputs<'_, FakeIn, 10>| embassy_futures::poll_once(inputs.change());
    assert_eq!(next(&mut inputs), Poll::Pending);
    // Changes made while nobody waited are reported, in pin order.
    lines[6].set(false);
    lines[2].set(true);
    assert_eq!(next(&mut inputs), Poll::Ready((2, true)));
    assert_eq!(next(&mut inputs), Poll::Ready((6, false)));
    assert_eq!(next(&mut inputs), Poll::Pending);
    // A pulse shorter than one look is not seen (levels are the truth).
    lines[3].set(false);
    lines[3].set(true);
    assert_eq!(next(&mut inputs), Poll::Pending);
    // No inputs at all: never.
    assert_eq!(().levels(), 0);
    assert_eq!(embassy_futures::poll_once(().change()), Poll::Pending);
}

#[test]
fn output_pins_are_addressed_by_table_pin_number() {
    let log = Rc::new(RefCell::new(Vec::new()));
    let mut outs = outputs(&log);
    outs.set(7, true);
    outs.set(200, true); // no such pin: ignored
    outs.as_mut_slice().set(2, false);
    outs.all_off();
    let mut expected = vec![(7, true), (2, false)];
    expected.extend((0..10).map(|p| (p, false)));
    assert_eq!(*log.borrow(), expected);
}

/// Prints the RAM the runtime's future takes on these fake seams (the whole node: core with
/// its OTA staging buffer, slot buffer, transmit queue): a figure for MCU boards.
#[test]
fn runtime_future_size() {
    let lines = lines();
    let pins = Rc::new(RefCell::new(Vec::new()));
    let mut ins: [FakeIn; 10] = std::array::from_fn(|i| FakeIn(lines[i].clone()));
    let board = Board {
        radio: FakeRadio(Rc::default()),
        outputs: outputs(&pins),
        inputs: WaitInputs::new(&mut ins),
        flash: Flash::default(),
        pin_mask: runtime::pin_range(10),
    };
    let size = std::mem::size_of_val(&runtime::run(ADDR, 1, board));
    eprintln!(
        "runtime future: {size} bytes (NodeCore {}, Table {})",
        std::mem::size_of::<node_fw::node::NodeCore>(),
        std::mem::size_of::<Table>()
    );
    // As on a board: the transfer staged outside the future (a flash page).
    let mut ins: [FakeIn; 10] = std::array::from_fn(|i| FakeIn(lines[i].clone()));
    let board = Board {
        radio: FakeRadio(Rc::default()),
        outputs: outputs(&pins),
        inputs: WaitInputs::new(&mut ins),
        flash: Flash::default(),
        pin_mask: runtime::pin_range(10),
    };
    let mut staging = ota::RamStaging::new();
    let mut count = || Some(2);
    let boot = Boot::Counted {
        boots: 1,
        persisted: true,
        count: &mut count,
    };
    let staged = std::mem::size_of_val(&runtime::run_staged(
        ADDR,
        boot,
        board,
        &mut (),
        None,
        &mut staging,
        &mut (),
    ));
    eprintln!(
        "runtime future, staging outside it (run_staged, as the boards): {staged} bytes \
         (NodeCore {})",
        std::mem::size_of::<node_fw::node::NodeCore<&mut ota::RamStaging>>()
    );
    for (part, bytes) in node_fw::node::footprint()
        .into_iter()
        .chain(runtime::footprint())
    {
        eprintln!("  {part:<28} {bytes:>6}");
    }
    let mut slots = Slots::new(Flash::default()).unwrap();
    eprintln!(
        "  {:<28} {:>6}",
        "Slots::load future",
        std::mem::size_of_val(&slots.load())
    );
    assert!(size > std::mem::size_of::<node_fw::node::NodeCore>());
}

// ---------------------------------------------------------------- transient flash errors

impl Tool {
    /// Transfers `table` and waits for `Staged` (no switch).
    async fn stage(&mut self, table: &Table) -> bool {
        let bytes = blob(table);
        let mut tx = ota::Sender::new(&bytes, table.generation, false);
        let mut out = Vec::new();
        tx.start(Instant::now().as_millis(), |m| out.push(m));
        self.carry(&mut tx, &mut out).await == ota::Progress::Done
    }
}

/// One boot on `flash` running `script` with a fresh tool.
fn boot_with<S>(flash: &Flash, script: impl FnOnce(Tool) -> S + 'static) -> Stats
where
    S: std::future::Future<Output = ()> + 'static,
{
    let pins = Rc::new(RefCell::new(Vec::new()));
    let script = boot(
        Boot::Epoch(1),
        flash.clone(),
        &lines(),
        &pins,
        Rc::default(),
        script,
    );
    script.1
}

/// The (generation, previous) a boot on `flash` runs.
fn booted(flash: &Flash) -> (u32, u32) {
    let got = Rc::new(Cell::new((0, 0)));
    let put = got.clone();
    boot_with(flash, move |mut tool| async move {
        let s = tool.status().await;
        put.set((s.generation, s.previous));
        tool.close().await;
    });
    got.get()
}

/// A transient flash error on the activation's confirmation (its serial written): the
/// `Go` is refused `Flash` and the node keeps generation 1; once the flash works again a
/// push of generation 2 stages it again and switches. The node refused every `Go` until
/// it rebooted (the slot had a serial: `NotStaged`), and answered the push `Staged` at
/// once, without writing, as it still took that table for staged.
#[test]
fn after_a_failed_activation_a_push_again_switches() {
    let flash = Flash::default();
    let f = flash.clone();
    let log = Rc::new(RefCell::new(Vec::new()));
    let l = log.clone();
    boot_with(&flash, move |mut tool| async move {
        assert_eq!(tool.push(&lamp_table(1)).await, ota::Progress::Done);
        assert!(tool.stage(&lamp_table(2)).await);
        // The activation's serial, then its confirmation: the confirmation fails once.
        f.fail_op.set(Some(f.ops.get() + 2));
        let first = tool.switch(2, false).await;
        let ops = f.ops.get();
        let staged = tool.stage(&lamp_table(2)).await;
        let written = f.ops.get() - ops;
        let again = tool.switch(2, false).await;
        let s = tool.status().await;
        l.borrow_mut().push(format!(
            "{first:?}; staged again {staged} ({} writes); {again:?}; runs {}",
            if written > 0 { "some" } else { "no" },
            s.generation
        ));
        tool.close().await;
    });
    assert_eq!(
        log.borrow().as_slice(),
        ["Aborted; staged again true (some writes); Switched; runs 2"]
    );
    assert_eq!(booted(&flash).0, 2);
}

/// A boot whose survey of the slots could not read the flash runs no table, and reads
/// them again before it stages one: the table running before is kept (the rollback
/// target) and the new one numbered above it. A table pushed then went to slot 0 with
/// serial 0, below the one confirmed in slot 1, and the next boot ran the older table (a
/// silent downgrade).
#[test]
fn a_boot_that_could_not_read_its_slots_reads_them_before_staging() {
    let flash = Flash::default();
    boot_with(&flash, |mut tool| async move {
        assert_eq!(tool.push(&lamp_table(1)).await, ota::Progress::Done);
        assert_eq!(tool.push(&lamp_table(2)).await, ota::Progress::Done);
        tool.close().await;
    });
    assert_eq!(booted(&flash).0, 2);
    flash.fail_reads.set(1);
    let pushed = Rc::new(Cell::new(None));
    let p = pushed.clone();
    boot_with(&flash, move |mut tool| async move {
        assert_eq!(tool.status().await.generation, 0, "booted unconfigured");
        p.set(Some(tool.push(&lamp_table(3)).await));
        tool.close().await;
    });
    assert_eq!(pushed.get(), Some(ota::Progress::Done));
    assert_eq!(
        booted(&flash),
        (3, 2),
        "the table pushed last, the one before kept"
    );
    // Unreadable again at boot and at the stage: nothing staged, nothing lost.
    flash.fail_reads.set(2);
    let p = pushed.clone();
    boot_with(&flash, move |mut tool| async move {
        p.set(Some(tool.push(&lamp_table(4)).await));
        tool.close().await;
    });
    assert_eq!(
        pushed.get(),
        Some(ota::Progress::Refused(
            config_schema::wire::msg::Refusal::Flash
        ))
    );
    assert_eq!(booted(&flash), (3, 2));
}

/// A stage that fails after erasing the previous generation's slot offers no rollback
/// to it any more (it said `previous: 1`, and a rollback was refused `Flash`).
#[test]
fn a_failed_stage_offers_no_rollback_to_the_table_it_erased() {
    let flash = Flash::default();
    let f = flash.clone();
    let previous = Rc::new(Cell::new(None));
    let p = previous.clone();
    boot_with(&flash, move |mut tool| async move {
        assert_eq!(tool.push(&lamp_table(1)).await, ota::Progress::Done);
        assert_eq!(tool.push(&lamp_table(2)).await, ota::Progress::Done);
        assert_eq!(tool.status().await.previous, 1);
        // Generation 3's stage: the erase of generation 1's slot works, the first write
        // fails once.
        f.fail_op.set(Some(f.ops.get() + 2));
        assert!(!tool.stage(&lamp_table(3)).await);
        p.set(Some(tool.status().await.previous));
        tool.close().await;
    });
    assert_eq!(previous.get(), Some(0));
}
