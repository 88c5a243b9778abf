//! `embassy-time` driver on the CMSDK APB timers of the mps2 (25 MHz): TIMER0 runs free
//! with a one-second period and counts the seconds in its interrupt, TIMER1 is the
//! one-shot alarm for the timer queue. Ticks are microseconds (embassy-time's 1 MHz).

use core::cell::{Cell, RefCell};
use core::task::Waker;

use critical_section::{CriticalSection, Mutex};
use embassy_time_driver::Driver;
use embassy_time_queue_utils::Queue;

use crate::vectors::{self, Irq};

const TIMER0: usize = 0x4000_0000;
const TIMER1: usize = 0x4000_1000;
const CTRL: usize = 0x0;
const VALUE: usize = 0x4;
const RELOAD: usize = 0x8;
const INTSTATUS: usize = 0xC;
const CTRL_ENABLE: u32 = 1;
const CTRL_IRQ: u32 = 1 << 3;

/// Timer clock cycles per microsecond (mps2 SYSCLK 25 MHz).
const CYCLES_PER_US: u32 = 25;
/// TIMER0's period: one second.
const PERIOD: u32 = 1_000_000 * CYCLES_PER_US;
/// The longest alarm (the queue is looked at again then).
const MAX_ALARM_US: u64 = 60_000_000;

fn reg(base: usize, off: usize) -> *mut u32 {
    (base + off) as *mut u32
}

fn read(base: usize, off: usize) -> u32 {
    // SAFETY: a CMSDK timer register.
    unsafe { core::ptr::read_volatile(reg(base, off)) }
}

fn write(base: usize, off: usize, v: u32) {
    // SAFETY: a CMSDK timer register.
    unsafe { core::ptr::write_volatile(reg(base, off), v) }
}

struct CmsdkTime {
    seconds: Mutex<Cell<u32>>,
    queue: Mutex<RefCell<Queue>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: CmsdkTime = CmsdkTime {
    seconds: Mutex::new(Cell::new(0)),
    queue: Mutex::new(RefCell::new(Queue::new())),
});

impl CmsdkTime {
    fn now_cs(&self, cs: CriticalSection<'_>) -> u64 {
        loop {
            let pending1 = read(TIMER0, INTSTATUS) & 1;
            let value = read(TIMER0, VALUE);
            let pending2 = read(TIMER0, INTSTATUS) & 1;
            if pending1 == pending2 {
                // A wrap not yet counted by the interrupt counts here.
                let s = u64::from(self.seconds.borrow(cs).get()) + u64::from(pending1);
                let into = PERIOD.saturating_sub(value) / CYCLES_PER_US;
                return s * 1_000_000 + u64::from(into);
            }
        }
    }

    /// Sets TIMER1 for the queue's next expiry (waking what expired meanwhile).
    fn arm(&self, cs: CriticalSection<'_>) {
        let mut queue = self.queue.borrow_ref_mut(cs);
        loop {
            let now = self.now_cs(cs);
            let next = queue.next_expiration(now);
            write(TIMER1, CTRL, 0);
            write(TIMER1, INTSTATUS, 1);
            if next == u64::MAX {
                return;
            }
            let now = self.now_cs(cs);
            if next <= now {
                continue;
            }
            let us = (next - now).min(MAX_ALARM_US) as u32;
            let cycles = us.max(1) * CYCLES_PER_US;
            write(TIMER1, RELOAD, cycles);
            write(TIMER1, VALUE, cycles);
            write(TIMER1, CTRL, CTRL_ENABLE | CTRL_IRQ);
            return;
        }
    }
}

/// Timer cycles since boot (40 ns each; under `-icount shift=0`, 40 instructions).
pub fn cycles() -> u64 {
    critical_section::with(|cs| loop {
        let pending1 = read(TIMER0, INTSTATUS) & 1;
        let value = read(TIMER0, VALUE);
        let pending2 = read(TIMER0, INTSTATUS) & 1;
        if pending1 == pending2 {
            let s = u64::from(DRIVER.seconds.borrow(cs).get()) + u64::from(pending1);
            return s * u64::from(PERIOD) + u64::from(PERIOD.saturating_sub(value));
        }
    })
}

/// Nanoseconds per timer cycle.
pub const NS_PER_CYCLE: u64 = 1000 / CYCLES_PER_US as u64;

impl Driver for CmsdkTime {
    fn now(&self) -> u64 {
        critical_section::with(|cs| self.now_cs(cs))
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            let changed = self.queue.borrow_ref_mut(cs).schedule_wake(at, waker);
            if changed {
                self.arm(cs);
            }
        })
    }
}

/// Starts TIMER0 and enables both timer interrupts.
pub fn init() {
    write(TIMER0, CTRL, 0);
    write(TIMER0, RELOAD, PERIOD);
    write(TIMER0, VALUE, PERIOD);
    write(TIMER0, INTSTATUS, 1);
    write(TIMER0, CTRL, CTRL_ENABLE | CTRL_IRQ);
    write(TIMER1, CTRL, 0);
    write(TIMER1, INTSTATUS, 1);
    vectors::unmask(Irq::Timer0);
    vectors::unmask(Irq::Timer1);
}

/// TIMER0: one more second.
pub extern "C" fn timer0_irq() {
    write(TIMER0, INTSTATUS, 1);
    critical_section::with(|cs| {
        let s = DRIVER.seconds.borrow(cs);
        s.set(s.get().wrapping_add(1));
    });
}

/// TIMER1: the alarm; wake what expired and arm the next one.
pub extern "C" fn timer1_irq() {
    write(TIMER1, CTRL, 0);
    write(TIMER1, INTSTATUS, 1);
    critical_section::with(|cs| DRIVER.arm(cs));
}
