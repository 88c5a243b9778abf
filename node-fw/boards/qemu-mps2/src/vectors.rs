//! The device interrupt vectors of the mps2-an385 this board uses (cortex-m-rt's `device`
//! feature: the table is ours): UART0 RX (0) and TX (1), TIMER0 (8), TIMER1 (9).

use cortex_m::interrupt::InterruptNumber;
use cortex_m::peripheral::NVIC;

#[derive(Debug, Clone, Copy)]
#[repr(u16)]
pub enum Irq {
    Uart0Rx = 0,
    Uart0Tx = 1,
    Timer0 = 8,
    Timer1 = 9,
}

// SAFETY: the numbers are the mps2-an385's.
unsafe impl InterruptNumber for Irq {
    fn number(self) -> u16 {
        self as u16
    }
}

pub fn unmask(irq: Irq) {
    // SAFETY: the handlers are in the table below; nothing relies on the line being masked.
    unsafe { NVIC::unmask(irq) }
}

pub fn pend(irq: Irq) {
    NVIC::pend(irq)
}

extern "C" fn unused() {}

#[link_section = ".vector_table.interrupts"]
#[no_mangle]
#[used]
pub static __INTERRUPTS: [extern "C" fn(); 32] = {
    let mut v: [extern "C" fn(); 32] = [unused; 32];
    v[0] = crate::uart::rx_irq;
    v[1] = crate::uart::tx_irq;
    v[8] = crate::time::timer0_irq;
    v[9] = crate::time::timer1_irq;
    v
};
