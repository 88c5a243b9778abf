//! The radio of this board: CMSDK UART0, connected by QEMU (`-chardev socket`) to the
//! simulated medium, carrying the medium's own framing (`config_schema::wire::medium`:
//! u16 LE length + postcard `Link`). Frames are PSDUs with FCS (added and checked here, the radio edge: the core deals in MPDUs); output pins go out as
//! `Link::Pin`; inputs come in as `Link::Pin` for this node's address (from the plant).
//!
//! Both directions are interrupt driven through byte rings. Receive: the interrupt moves
//! bytes into the ring; when the ring is full it stops reading (QEMU's UART holds one byte
//! and then holds the TCP stream back), so nothing is lost on the way in. A task parses the
//! ring into frames and input changes (bounded channels, waiting for room). Transmit: a
//! message goes into the ring whole or not at all (a cancelled send leaves no half message),
//! and the TX interrupt feeds the UART.

use core::cell::RefCell;
use core::convert::Infallible;
use core::future::poll_fn;
use core::task::Poll;

use config_schema::wire::mac::MAX_PSDU;
use config_schema::wire::medium::{Deframer, Link, MAX_LINK};
use critical_section::Mutex;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::waitqueue::AtomicWaker;
use heapless::Deque;
use node_fw::runtime::{mpdu_of, psdu_of, Inputs, Pins, Psdu, Radio, Received};

use crate::vectors::{self, Irq};

const UART0: usize = 0x4000_4000;
const DATA: usize = 0x0;
const STATE: usize = 0x4;
const CTRL: usize = 0x8;
const INTSTATUS: usize = 0xC;
const BAUDDIV: usize = 0x10;
const STATE_TX_FULL: u32 = 1;
const STATE_RX_FULL: u32 = 1 << 1;
const CTRL_TX_EN: u32 = 1;
const CTRL_RX_EN: u32 = 1 << 1;
const CTRL_TX_INT: u32 = 1 << 2;
const CTRL_RX_INT: u32 = 1 << 3;
const INT_TX: u32 = 1;
const INT_RX: u32 = 1 << 1;

const RX_RING: usize = 512;
const TX_RING: usize = 1024;
/// Received frames waiting for the runtime.
const RX_FRAMES: usize = 4;
/// Input changes waiting for the runtime.
const RX_PINS: usize = 16;

fn read(off: usize) -> u32 {
    // SAFETY: a CMSDK UART register.
    unsafe { core::ptr::read_volatile((UART0 + off) as *const u32) }
}

fn write(off: usize, v: u32) {
    // SAFETY: a CMSDK UART register.
    unsafe { core::ptr::write_volatile((UART0 + off) as *mut u32, v) }
}

struct Rings {
    rx: Deque<u8, RX_RING>,
    /// The RX interrupt is off because the ring was full.
    rx_paused: bool,
    tx: Deque<u8, TX_RING>,
}

static RINGS: Mutex<RefCell<Rings>> = Mutex::new(RefCell::new(Rings {
    rx: Deque::new(),
    rx_paused: false,
    tx: Deque::new(),
}));
static RX_WAKER: AtomicWaker = AtomicWaker::new();
static TX_WAKER: AtomicWaker = AtomicWaker::new();
static FRAMES: Channel<CriticalSectionRawMutex, Psdu, RX_FRAMES> = Channel::new();
static PINS: Channel<CriticalSectionRawMutex, (u8, bool), RX_PINS> = Channel::new();

/// Counters of what came in from the medium.
#[derive(Debug, Clone, Copy)]
pub struct Counters {
    pub garbage: u32,
    pub oversized: u32,
    /// Frames handed to the runtime.
    pub frames: u32,
    /// `Pin` messages handed to the runtime (the plant repeats levels).
    pub pins: u32,
    /// Of those, the ones that changed a level.
    pub changes: u32,
}

static COUNTERS: Mutex<RefCell<Counters>> = Mutex::new(RefCell::new(Counters {
    garbage: 0,
    oversized: 0,
    frames: 0,
    pins: 0,
    changes: 0,
}));

pub fn counters() -> Counters {
    critical_section::with(|cs| *COUNTERS.borrow_ref(cs))
}

/// Enables UART0 (BAUDDIV 16: QEMU ignores TX below that) and its interrupts.
pub fn init() {
    write(BAUDDIV, 16);
    write(INTSTATUS, INT_TX | INT_RX);
    write(CTRL, CTRL_TX_EN | CTRL_RX_EN | CTRL_TX_INT | CTRL_RX_INT);
    vectors::unmask(Irq::Uart0Rx);
    vectors::unmask(Irq::Uart0Tx);
}

/// Receive interrupt: clear first, then drain (the UART holds one byte and takes the next
/// as soon as it is read).
pub extern "C" fn rx_irq() {
    write(INTSTATUS, INT_RX);
    critical_section::with(|cs| {
        let mut r = RINGS.borrow_ref_mut(cs);
        while read(STATE) & STATE_RX_FULL != 0 {
            if r.rx.is_full() {
                r.rx_paused = true;
                write(CTRL, read(CTRL) & !CTRL_RX_INT);
                break;
            }
            let _ = r.rx.push_back(read(DATA) as u8);
        }
    });
    RX_WAKER.wake();
}

/// Feeds the UART from the ring while it takes bytes.
fn kick(r: &mut Rings) {
    while read(STATE) & STATE_TX_FULL == 0 {
        match r.tx.pop_front() {
            Some(b) => write(DATA, u32::from(b)),
            None => break,
        }
    }
}

pub extern "C" fn tx_irq() {
    write(INTSTATUS, INT_TX);
    critical_section::with(|cs| kick(&mut RINGS.borrow_ref_mut(cs)));
    TX_WAKER.wake();
}

/// Puts `bytes` in the ring if it all fits.
fn try_send(bytes: &[u8]) -> bool {
    critical_section::with(|cs| {
        let mut r = RINGS.borrow_ref_mut(cs);
        if TX_RING - r.tx.len() < bytes.len() {
            kick(&mut r);
            return false;
        }
        for &b in bytes {
            let _ = r.tx.push_back(b);
        }
        kick(&mut r);
        true
    })
}

/// Sends one message, waiting for room (cancel-safe: all or nothing).
async fn send_async(bytes: &[u8]) {
    poll_fn(|cx| {
        TX_WAKER.register(cx.waker());
        if try_send(bytes) {
            Poll::Ready(())
        } else {
            Poll::Pending
        }
    })
    .await
}

/// Sends one message from code that cannot wait (the output pins): spins until it fits.
pub fn send_blocking(bytes: &[u8]) {
    while !try_send(bytes) {
        cortex_m::asm::nop();
    }
}

/// Sends a link message (blocking).
pub fn send_link(msg: &Link<'_>) {
    let mut buf = [0u8; MAX_LINK];
    if let Ok(n) = msg.emit(&mut buf) {
        send_blocking(&buf[..n]);
    }
}

/// Takes up to `buf.len()` bytes from the receive ring, waiting for at least one.
async fn read_some(buf: &mut [u8]) -> usize {
    poll_fn(|cx| {
        RX_WAKER.register(cx.waker());
        let (n, resume) = critical_section::with(|cs| {
            let mut r = RINGS.borrow_ref_mut(cs);
            let mut n = 0;
            while n < buf.len() {
                match r.rx.pop_front() {
                    Some(b) => {
                        buf[n] = b;
                        n += 1;
                    }
                    None => break,
                }
            }
            let resume = n > 0 && r.rx_paused;
            if resume {
                r.rx_paused = false;
                write(CTRL, read(CTRL) | CTRL_RX_INT);
            }
            (n, resume)
        });
        if resume {
            // The byte waiting in the UART raised no interrupt while it was off.
            vectors::pend(Irq::Uart0Rx);
        }
        if n > 0 {
            Poll::Ready(n)
        } else {
            Poll::Pending
        }
    })
    .await
}

/// Parses what the medium sends into frames and this node's input changes, forever.
#[embassy_executor::task]
pub async fn demux(addr: u16) {
    let mut incoming = Deframer::<{ 2 * MAX_LINK }>::new();
    loop {
        match incoming.complete() {
            Ok(true) => {}
            Ok(false) => {
                let n = read_some(incoming.space()).await;
                incoming.filled(n);
                continue;
            }
            // Not a message this node can hold: skipped.
            Err(_) => {
                critical_section::with(|cs| COUNTERS.borrow_ref_mut(cs).garbage += 1);
                continue;
            }
        }
        let Ok(Some(msg)) = incoming.take() else {
            continue;
        };
        match Link::parse(msg) {
            Ok(Link::Frame(psdu)) => match Psdu::from_slice(psdu) {
                Ok(frame) => {
                    critical_section::with(|cs| COUNTERS.borrow_ref_mut(cs).frames += 1);
                    FRAMES.send(frame).await
                }
                Err(_) => critical_section::with(|cs| COUNTERS.borrow_ref_mut(cs).oversized += 1),
            },
            Ok(Link::Pin {
                addr: a,
                pin,
                level,
            }) if a == addr => {
                critical_section::with(|cs| COUNTERS.borrow_ref_mut(cs).pins += 1);
                PINS.send((pin, level)).await
            }
            _ => critical_section::with(|cs| COUNTERS.borrow_ref_mut(cs).garbage += 1),
        }
    }
}

/// The radio: PSDUs over the UART.
pub struct UartRadio;

impl Radio for UartRadio {
    type Error = Infallible;

    /// The radio edge: the MPDU goes out with its FCS appended.
    async fn send(&mut self, mpdu: &[u8]) -> Result<(), Infallible> {
        let mut buf = [0u8; MAX_LINK];
        let Some(psdu) = psdu_of(mpdu) else {
            return Ok(());
        };
        if let Ok(n) = Link::Frame(&psdu).emit(&mut buf) {
            send_async(&buf[..n]).await;
        }
        Ok(())
    }

    /// The radio edge: a PSDU off the UART, its FCS checked and cut off.
    async fn receive(&mut self, buf: &mut [u8; MAX_PSDU]) -> Result<Received, Infallible> {
        let frame = FRAMES.receive().await;
        Ok(mpdu_of(&frame, buf))
    }
}

/// Table pins of this board: all 64 a table may name (they are `Link::Pin` messages; which
/// exist is the plant's business).
pub const TABLE_PINS: usize = 64;

/// The outputs: `Link::Pin` to the medium (the plant drives the valves).
pub struct UartPins {
    pub addr: u16,
}

impl Pins for UartPins {
    fn set(&mut self, pin: u8, level: bool) {
        send_link(&Link::Pin {
            addr: self.addr,
            pin,
            level,
        });
    }
    /// No outputs of its own: until a table names them nothing is driven (the table's safe
    /// values follow at boot and at every activation), as on the host board.
    fn all_off(&mut self) {}
    fn running(&mut self, generation: u32) {
        send_link(&Link::Running {
            addr: self.addr,
            generation,
        });
    }
}

/// The inputs: `Link::Pin` from the medium, every change once, in order.
pub struct UartInputs {
    levels: u64,
}

impl UartInputs {
    pub const fn new() -> Self {
        UartInputs { levels: 0 }
    }
}

impl Inputs for UartInputs {
    fn levels(&mut self) -> u64 {
        while let Ok((pin, level)) = PINS.try_receive() {
            self.set(pin, level);
        }
        self.levels
    }

    async fn change(&mut self) -> (u8, bool) {
        let (pin, level) = PINS.receive().await;
        self.set(pin, level);
        (pin, level)
    }
}

impl UartInputs {
    fn set(&mut self, pin: u8, level: bool) {
        if pin < 64 {
            if (self.levels >> pin) & 1 != u64::from(level) {
                critical_section::with(|cs| COUNTERS.borrow_ref_mut(cs).changes += 1);
            }
            if level {
                self.levels |= 1 << pin;
            } else {
                self.levels &= !(1 << pin);
            }
        }
    }
}
