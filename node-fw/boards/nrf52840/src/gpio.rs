//! The node's pins: table pin `n` is `PIN_NAMES[n]` (see docs/boards.md). Which of them are
//! outputs is the table's business, not the board's: every pin starts as an input with a
//! pull-down (a valve driver sees low: off), and becomes a push-pull output the first time
//! the table drives it (at boot or activation the table drives every output to its safe
//! level, so outputs are outputs before anything moves). Inputs are read as levels from
//! the ports' IN registers and woken by the GPIOTE PORT event: one waker for every pin
//! ([`PortHandler`]), each input pin sensing the level it does not have.

use core::cell::Cell;
use core::future::poll_fn;
use core::task::Poll;

use embassy_nrf::gpio::AnyPin;
use embassy_nrf::interrupt::{self, typelevel, InterruptExt};
use embassy_nrf::pac;
use embassy_nrf::pac::gpio::vals::{Detectmode, Dir, Drive, Input, Pull as PinPull, Sense};
use embassy_nrf::Peri;
use embassy_sync::waitqueue::AtomicWaker;
use node_fw::runtime::{Inputs, Pins};

/// Table pins this board has.
pub const PINS: usize = 16;

/// The physical pin of every table pin (nRF52840 DK: Arduino header pins, clear of the
/// DK's LEDs, buttons, UART, QSPI and NFC).
#[allow(dead_code)] // documentation: docs/boards.md
pub const PIN_NAMES: [&str; PINS] = [
    "P1.01", "P1.02", "P1.03", "P1.04", "P1.05", "P1.06", "P1.07", "P1.08", "P1.10", "P1.11",
    "P1.12", "P1.13", "P1.14", "P1.15", "P0.03", "P0.04",
];

/// `PIN_NAMES` as numbers: 32 x port + pin.
const PHYSICAL: [u8; PINS] = [33, 34, 35, 36, 37, 38, 39, 40, 42, 43, 44, 45, 46, 47, 3, 4];

/// The port of a physical pin and the pin's number in it.
fn port(physical: u8) -> (pac::gpio::Gpio, usize) {
    let port = if physical & 32 != 0 { pac::P1 } else { pac::P0 };
    (port, usize::from(physical & 31))
}

/// Woken by every PORT event (the input wait: one future, one waker for all pins).
static PORT_WAKER: AtomicWaker = AtomicWaker::new();

/// The GPIOTE interrupt (embassy-nrf's `gpiote` driver is not linked: its waker per pin,
/// 48 of them, and a future per pin): a PORT event turns off the sense of each pin that
/// latched (else it latches again at once), clears the latches and wakes the input wait,
/// which arms the pins again.
pub struct PortHandler;

impl typelevel::Handler<typelevel::GPIOTE> for PortHandler {
    unsafe fn on_interrupt() {
        let event = pac::GPIOTE.events_port(0);
        if event.read() == 0 {
            return;
        }
        event.write_value(0);
        for p in [pac::P0, pac::P1] {
            let latched = p.latch().read().0;
            let mut bits = latched;
            while bits != 0 {
                let pin = bits.trailing_zeros() as usize;
                p.pin_cnf(pin).modify(|w| w.set_sense(Sense::Disabled));
                bits &= bits - 1;
            }
            p.latch().write(|w| w.0 = latched);
        }
        PORT_WAKER.wake();
    }
}

/// Latched detection on both ports, the PORT event's interrupt on (once, at boot).
fn listen() {
    for p in [pac::P0, pac::P1] {
        p.detectmode()
            .write(|w| w.set_detectmode(Detectmode::Ldetect));
        p.latch().write(|w| w.0 = u32::MAX);
    }
    pac::GPIOTE.intenset(0).write(|w| w.set_port(true));
    interrupt::GPIOTE.unpend();
    // SAFETY: the handler (`PortHandler`, bound in main) touches only the ports' sense,
    // latches and the waker, which the input wait expects to change under it.
    unsafe { interrupt::GPIOTE.enable() };
}

/// The pins, shared by the outputs and the inputs (one task uses both). Levels are set and read
/// through the ports' registers (`OUTSET` / `OUTCLR`, `IN`, `PIN_CNF`): the pins are only
/// owned here, configured by their numbers (`PHYSICAL`).
pub struct Gpio {
    _pins: [Peri<'static, AnyPin>; PINS],
    /// Bit n: table pin n is an output.
    outputs: Cell<u32>,
}

impl Gpio {
    /// `pins` are the pins of `PHYSICAL`, in its order.
    pub fn new(pins: [Peri<'static, AnyPin>; PINS]) -> Self {
        for &physical in &PHYSICAL {
            configure(physical, false);
        }
        listen();
        Gpio {
            _pins: pins,
            outputs: Cell::new(0),
        }
    }

    fn is_output(&self, pin: usize) -> bool {
        self.outputs.get() & (1 << pin) != 0
    }
}

/// Physical pin `physical` as a push-pull output (as `Flex::set_as_output(OutputDrive::Standard)`
/// writes `PIN_CNF`) or as an input with a pull-down (as `Flex::set_as_input(Pull::Down)`
/// does), its sense off.
fn configure(physical: u8, output: bool) {
    let (p, pin) = port(physical);
    p.pin_cnf(pin).write(|w| {
        if output {
            w.set_dir(Dir::Output);
            w.set_input(Input::Disconnect);
            w.set_pull(PinPull::Disabled);
        } else {
            w.set_dir(Dir::Input);
            w.set_input(Input::Connect);
            w.set_pull(PinPull::Pulldown);
        }
        w.set_drive(Drive::S0s1);
        w.set_sense(Sense::Disabled);
    });
}

/// Physical pin `physical`'s output latch to `level` (a pin that is not yet an output
/// drives it once it becomes one).
fn drive(physical: u8, level: bool) {
    let (p, pin) = port(physical);
    if level {
        p.outset().write(|w| w.0 = 1 << pin);
    } else {
        p.outclr().write(|w| w.0 = 1 << pin);
    }
}

/// The outputs.
pub struct GpioPins<'a>(pub &'a Gpio);

impl Pins for GpioPins<'_> {
    fn set(&mut self, pin: u8, level: bool) {
        let i = usize::from(pin);
        let Some(&physical) = PHYSICAL.get(i) else {
            return;
        };
        drive(physical, level);
        if !self.0.is_output(i) {
            configure(physical, true);
            self.0.outputs.set(self.0.outputs.get() | 1 << i);
        }
    }

    fn all_off(&mut self) {
        for (i, &physical) in PHYSICAL.iter().enumerate() {
            if self.0.is_output(i) {
                drive(physical, false);
            }
        }
    }
}

/// The inputs: every pin that is not an output.
pub struct GpioInputs<'a> {
    gpio: &'a Gpio,
    reported: u32,
}

impl<'a> GpioInputs<'a> {
    pub fn new(gpio: &'a Gpio) -> Self {
        GpioInputs { gpio, reported: 0 }
    }

    /// The levels of the input pins (bit n: table pin n), from the ports' IN registers.
    fn read(&self) -> u32 {
        let (p0, p1) = (pac::P0.in_().read().0, pac::P1.in_().read().0);
        table_pins(p0, p1) & !self.gpio.outputs.get()
    }
}

/// Port words (P0, P1) as table pins (bit n: table pin n): P1.01..=P1.08 are pins 0..=7,
/// P1.10..=P1.15 pins 8..=13, P0.03 and P0.04 pins 14 and 15 (`PHYSICAL`, checked below).
const fn table_pins(p0: u32, p1: u32) -> u32 {
    ((p1 >> 1) & 0xFF) | ((p1 >> 10) & 0x3F) << 8 | ((p0 >> 3) & 0x3) << 14
}

// `table_pins` moves each pin of `PHYSICAL` to its table pin.
const _: () = {
    let mut i = 0;
    while i < PINS {
        let bit = 1u32 << (PHYSICAL[i] & 31);
        let (p0, p1) = if PHYSICAL[i] & 32 != 0 {
            (0, bit)
        } else {
            (bit, 0)
        };
        assert!(table_pins(p0, p1) == 1 << i);
        i += 1;
    }
};

impl Inputs for GpioInputs<'_> {
    fn levels(&mut self) -> u64 {
        self.reported = self.read();
        u64::from(self.reported)
    }

    async fn change(&mut self) -> (u8, bool) {
        let now = poll_fn(|cx| {
            // Registered first: a change from here on wakes this wait again.
            PORT_WAKER.register(cx.waker());
            let now = self.read();
            if now != self.reported {
                return Poll::Ready(now);
            }
            // Each input pin senses the level it does not have (again: the interrupt
            // turned off the sense of a pin that latched, a glitch's too): a change from
            // here on latches and the PORT event wakes the wait; one between the read
            // and the arming latches at once.
            for (i, &physical) in PHYSICAL.iter().enumerate() {
                if !self.gpio.is_output(i) {
                    let sense = if now & (1 << i) != 0 {
                        Sense::Low
                    } else {
                        Sense::High
                    };
                    let (p, pin) = port(physical);
                    p.pin_cnf(pin).modify(|w| w.set_sense(sense));
                }
            }
            Poll::Pending
        })
        .await;
        let pin = (now ^ self.reported).trailing_zeros();
        self.reported ^= 1 << pin;
        (pin as u8, now & (1 << pin) != 0)
    }
}
