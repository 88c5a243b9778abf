//! The node's pins: table pin `n` is `PIN_NAMES[n]` (see docs/boards.md). Which of them are
//! outputs is the table's business, not the board's: every pin starts as an input with a
//! pull-down (a valve driver sees low: off), and becomes a push-pull output the first time
//! the table drives it (at boot or activation the table drives every output to its safe
//! level, so outputs are outputs before anything moves). Inputs are read as levels and
//! woken by GPIOTE PORT events (`wait_for_any_edge`).

use core::cell::{Cell, RefCell};

use embassy_futures::select::select_array;
use embassy_nrf::gpio::{Flex, OutputDrive, Pull};
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

/// The pins, shared by the outputs and the inputs (one task uses both, never at once: the
/// runtime drives outputs only while no input wait is pending).
pub struct Gpio {
    pins: [RefCell<Flex<'static>>; PINS],
    /// Bit n: table pin n is an output.
    outputs: Cell<u32>,
}

impl Gpio {
    pub fn new(mut pins: [Flex<'static>; PINS]) -> Self {
        for p in pins.iter_mut() {
            p.set_as_input(Pull::Down);
        }
        Gpio {
            pins: pins.map(RefCell::new),
            outputs: Cell::new(0),
        }
    }

    fn is_output(&self, pin: usize) -> bool {
        self.outputs.get() & (1 << pin) != 0
    }
}

/// The outputs.
pub struct GpioPins<'a>(pub &'a Gpio);

impl Pins for GpioPins<'_> {
    fn set(&mut self, pin: u8, level: bool) {
        let i = usize::from(pin);
        let Some(cell) = self.0.pins.get(i) else {
            return;
        };
        let Ok(mut p) = cell.try_borrow_mut() else {
            return;
        };
        if level {
            p.set_high();
        } else {
            p.set_low();
        }
        if !self.0.is_output(i) {
            p.set_as_output(OutputDrive::Standard);
            self.0.outputs.set(self.0.outputs.get() | 1 << i);
        }
    }

    fn all_off(&mut self) {
        for (i, cell) in self.0.pins.iter().enumerate() {
            if self.0.is_output(i) {
                if let Ok(mut p) = cell.try_borrow_mut() {
                    p.set_low();
                }
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

    fn read(&self) -> u32 {
        let mut levels = 0;
        for (i, cell) in self.gpio.pins.iter().enumerate() {
            if !self.gpio.is_output(i) {
                if let Ok(p) = cell.try_borrow() {
                    if p.is_high() {
                        levels |= 1 << i;
                    }
                }
            }
        }
        levels
    }
}

impl Inputs for GpioInputs<'_> {
    fn levels(&mut self) -> u64 {
        self.reported = self.read();
        u64::from(self.reported)
    }

    // The borrows held across the wait end when the runtime drops this future, which it
    // does before it drives any output; `Pins` use `try_borrow_mut` all the same.
    #[allow(clippy::await_holding_refcell_ref)]
    async fn change(&mut self) -> (u8, bool) {
        loop {
            let now = self.read();
            let changed = now ^ self.reported;
            if changed != 0 {
                let pin = changed.trailing_zeros();
                self.reported ^= 1 << pin;
                return (pin as u8, now & (1 << pin) != 0);
            }
            let gpio = self.gpio;
            let waits: [_; PINS] = core::array::from_fn(|i| async move {
                if gpio.is_output(i) {
                    core::future::pending::<()>().await;
                }
                match gpio.pins[i].try_borrow_mut() {
                    Ok(mut p) => p.wait_for_any_edge().await,
                    Err(_) => core::future::pending::<()>().await,
                }
            });
            select_array(waits).await;
        }
    }
}
