//! The generic node on QEMU's `mps2-an385` (Cortex-M3): every node boots this same ELF.
//!
//! - address: the provisioning word ([`provision`], `-device loader`);
//! - radio and pins: CMSDK UART0 bridged by QEMU to the simulated medium ([`uart`]);
//! - time: CMSDK TIMER0/1 ([`time`]);
//! - table slots and frame counter: emulated flash, persistent in a host file through
//!   semihosting ([`flash`], [`counter`]);
//! - security: with a management key in the provisioning area, the config PAN is secured
//!   (`runtime::run_secured`);
//! - executor: Embassy's raw executor in a WFI loop (QEMU treats WFE as a no-op, so the
//!   stock thread executor would keep a host core busy).
//!
//! ```text
//! qemu-system-arm -M mps2-an385 -display none -monitor none \
//!   -kernel qemu-mps2 -device loader,addr=0x003ff000,data=0xA5010003,data-len=4 \
//!   -chardev socket,id=radio,host=127.0.0.1,port=15400,nodelay=on -serial chardev:radio \
//!   -semihosting-config enable=on,target=native,arg=flash=node-0003.flash
//! ```
#![no_std]
#![no_main]

mod bench;
mod counter;
mod flash;
mod provision;
mod semihosting;
mod time;
mod uart;
mod vectors;

use core::fmt::Write as _;
use core::sync::atomic::{AtomicBool, Ordering};

use config_schema::wire::medium::{Link, Peer};
use cortex_m_rt::entry;
use embassy_executor::raw;
use node_fw::cipher;
use node_fw::provision::ManagementKey;
use node_fw::runtime::{self, Board};

use counter::Counter;

use flash::{Backing, QemuFlash};

/// The firmware's semihosting log (QEMU's console), when the emulator has semihosting.
struct Log;

impl log::Log for Log {
    fn enabled(&self, m: &log::Metadata<'_>) -> bool {
        m.level() <= log::max_level()
    }
    fn log(&self, r: &log::Record<'_>) {
        let mut s = heapless::String::<256>::new();
        let _ = write!(s, "{:<5} {}", r.level(), r.args());
        let _ = s.push('\n');
        let _ = s.push('\0');
        semihosting::write0(s.as_bytes());
    }
    fn flush(&self) {}
}

static LOG: Log = Log;

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    let mut s = heapless::String::<200>::new();
    let _ = write!(s, "panic: {info}\n\0");
    semihosting::write0(s.as_bytes());
    loop {
        cortex_m::asm::wfi();
    }
}

/// Set by the executor's pender (a task was woken): poll again before sleeping.
static WORK: AtomicBool = AtomicBool::new(false);

#[export_name = "__pender"]
fn pender(_context: *mut ()) {
    WORK.store(true, Ordering::Release);
}

/// Inside `NodeCore`, per kind of stimulus (frames, input changes): timer cycles, the
/// stimuli, and the software AES's key schedules and blocks among them.
#[derive(Clone, Copy, Default)]
struct CoreCount {
    cycles: u64,
    stimuli: u32,
    schedules: u32,
    blocks: u32,
}

static CORE: critical_section::Mutex<core::cell::Cell<[CoreCount; 2]>> =
    critical_section::Mutex::new(core::cell::Cell::new(
        [CoreCount {
            cycles: 0,
            stimuli: 0,
            schedules: 0,
            blocks: 0,
        }; 2],
    ));

/// Times the core's handling of each stimulus, and counts its AES work (when counting).
struct CoreProbe {
    on: bool,
    at: u64,
    aes: cipher::AesWork,
}

impl runtime::Probe for CoreProbe {
    fn start(&mut self) {
        if self.on {
            self.aes = cipher::aes_work();
            self.at = time::cycles();
        }
    }
    fn stop(&mut self, work: runtime::Work) {
        if self.on {
            let spent = time::cycles().saturating_sub(self.at);
            let aes = cipher::aes_work();
            let i = usize::from(work == runtime::Work::Input);
            critical_section::with(|cs| {
                let cell = CORE.borrow(cs);
                let mut v = cell.get();
                if let Some(c) = v.get_mut(i) {
                    c.cycles += spent;
                    c.stimuli += 1;
                    c.schedules = c
                        .schedules
                        .wrapping_add(aes.schedules.wrapping_sub(self.aes.schedules));
                    c.blocks = c
                        .blocks
                        .wrapping_add(aes.blocks.wrapping_sub(self.aes.blocks));
                }
                cell.set(v);
            });
        }
    }
}

#[embassy_executor::task]
async fn node(
    addr: u16,
    epoch: u16,
    boots: Option<u32>,
    flash: QemuFlash,
    counting: bool,
    key: Option<ManagementKey>,
    mut counter: Option<Counter>,
) {
    // With a flash file its boot count reserves the link epochs (`node_fw::epoch`): counted
    // again, on the boot page's own handle, when this boot has taken most of them.
    let mut boot_counter = flash.boot_counter();
    let board = Board {
        radio: uart::UartRadio,
        outputs: uart::UartPins { addr },
        inputs: uart::UartInputs::new(),
        flash,
        pin_mask: runtime::pin_range(uart::TABLE_PINS),
    };
    let mut probe = CoreProbe {
        on: counting,
        at: 0,
        aes: cipher::AesWork::default(),
    };
    let mut next = || counter.as_mut().and_then(Counter::next);
    let security = key.map(|key| runtime::Security {
        key,
        counter: &mut next,
    });
    let mut count = || boot_counter.count_boot();
    let boot = match boots {
        Some(boots) => runtime::Boot::Counted {
            boots,
            persisted: true,
            count: &mut count,
        },
        None => runtime::Boot::Epoch(epoch),
    };
    let staging = flash::QemuStaging::new();
    let (stop, stats) =
        runtime::run_staged(addr, boot, board, &mut probe, security, staging, &mut ()).await;
    log::error!("node {addr:#06x}: stopped: {stop:?} ({stats:?})");
}

/// Timer cycles the core was awake (not in WFI), interrupt handlers included.
static BUSY: critical_section::Mutex<core::cell::Cell<u64>> =
    critical_section::Mutex::new(core::cell::Cell::new(0));

/// Logs the busy time and the stimuli every second when they changed (provisioning flag
/// `FLAG_COUNT`; under `-icount shift=0` a nanosecond is one instruction).
#[embassy_executor::task]
async fn count(addr: u16) {
    let mut last = (u64::MAX, 0, 0);
    loop {
        embassy_time::Timer::after_secs(1).await;
        let busy = critical_section::with(|cs| BUSY.borrow(cs).get()) * time::NS_PER_CYCLE;
        let c = uart::counters();
        let [frame, input] = critical_section::with(|cs| CORE.borrow(cs).get());
        if (busy, c.frames, c.pins) != last {
            last = (busy, c.frames, c.pins);
            log::info!(
                "node {addr:#06x}: count: busy_ns {busy} frames {} pins {} changes {} \
                 core_frame_ns {} core_frames {} core_input_ns {} core_inputs {} \
                 core_frame_aes {} {} core_input_aes {} {}",
                c.frames,
                c.pins,
                c.changes,
                frame.cycles * time::NS_PER_CYCLE,
                frame.stimuli,
                input.cycles * time::NS_PER_CYCLE,
                input.stimuli,
                frame.schedules,
                frame.blocks,
                input.schedules,
                input.blocks,
            );
        }
    }
}

/// Says why and stays off the air (a node that cannot secure must not talk).
fn off_the_air(addr: u16, why: core::fmt::Arguments<'_>) -> ! {
    log::error!("node {addr:#06x}: {why}: staying off the air");
    loop {
        cortex_m::asm::wfi();
    }
}

/// The semihosting command line's `flash=PATH`.
fn flash_path(buf: &mut [u8]) -> Option<&[u8]> {
    let line = semihosting::cmdline(buf)?;
    line.split(|&b| b == b' ')
        .find_map(|w| w.strip_prefix(b"flash="))
        .filter(|p| !p.is_empty())
}

#[entry]
fn main() -> ! {
    let Some(p) = provision::read() else {
        // Nothing to say it with: no address, no medium. A node without an id stays off.
        loop {
            cortex_m::asm::wfi();
        }
    };
    if p.flags & provision::FLAG_SEMIHOSTING != 0 {
        semihosting::enable();
        if log::set_logger(&LOG).is_ok() {
            log::set_max_level(log::LevelFilter::Info);
        }
    }
    let addr = p.addr;
    let key = match p.key {
        Ok(key) => key,
        Err(e) => off_the_air(addr, format_args!("{e}")),
    };
    time::init();
    uart::init();
    // The node says who it is before anything else (the medium routes by it).
    uart::send_link(&Link::Hello(Peer::Node { addr }));

    let mut cmdline = [0u8; 160];
    let (mut flash, backing) = QemuFlash::open(flash_path(&mut cmdline));
    let boots = flash.count_boot();
    let (epoch, why) = match boots {
        Some(boots) => (node_fw::epoch::of_boot(boots), "boot count"),
        None => (semihosting::time().unwrap_or(0) as u16, "clock"),
    };
    let keyed = if key.is_some() {
        "management key provisioned"
    } else {
        "no management key"
    };
    log::info!("node {addr:#06x}: qemu-mps2, flash {backing:?}, epoch {epoch} ({why}), {keyed}");
    if backing == Backing::FileRefused {
        log::warn!("node {addr:#06x}: the flash file is not usable: slots in RAM");
    }
    // A keyed node's frame counter (only the value is logged, never the key).
    let counter = key.as_ref().map(|_| {
        let counter = match Counter::open(flash.frame_counter(), backing) {
            Ok(c) => c,
            Err(e) => off_the_air(addr, format_args!("frame counter: {e:?}")),
        };
        let kept = if counter.persistent() {
            "in flash"
        } else {
            "in RAM, from the clock"
        };
        match counter.start() {
            Some(n) => log::info!("node {addr:#06x}: frame counter {n} ({kept})"),
            None => log::warn!("node {addr:#06x}: frame counter used up: nothing secured is sent"),
        }
        counter
    });

    let executor: &'static mut raw::Executor =
        cortex_m::singleton!(: raw::Executor = raw::Executor::new(core::ptr::null_mut()))
            .expect("one executor");
    let executor: &'static raw::Executor = executor;
    let spawner = executor.spawner();
    spawner.spawn(uart::demux(addr).expect("demux task"));
    let counting = p.flags & provision::FLAG_COUNT != 0;
    if counting {
        match bench::secure_and_open() {
            Some(costs) => {
                for (size, (secure, open)) in bench::SIZES.iter().zip(costs) {
                    log::info!(
                        "node {addr:#06x}: security cost: payload {size} secure_ns {secure} \
                         open_ns {open}"
                    );
                }
            }
            None => log::warn!("node {addr:#06x}: security cost: the codec refused"),
        }
        let (schedule, block) = bench::aes();
        log::info!(
            "node {addr:#06x}: security cost: aes key_schedule_ns {schedule} block_ns {block}"
        );
    }
    spawner.spawn(node(addr, epoch, boots, flash, counting, key, counter).expect("node task"));
    if counting {
        spawner.spawn(count(addr).expect("count task"));
    }
    let mut awake = time::cycles();
    loop {
        // SAFETY: polled only here, never re-entered.
        unsafe { executor.poll() };
        cortex_m::interrupt::free(|_| {
            // With interrupts masked, a wake between the check and WFI still ends the WFI
            // (a pending interrupt wakes the core); its handler runs after `free`.
            if !WORK.swap(false, Ordering::AcqRel) {
                if counting {
                    let now = time::cycles();
                    critical_section::with(|cs| {
                        let busy = BUSY.borrow(cs);
                        busy.set(busy.get() + now.saturating_sub(awake));
                    });
                }
                cortex_m::asm::wfi();
                if counting {
                    awake = time::cycles();
                }
            }
        });
    }
}
