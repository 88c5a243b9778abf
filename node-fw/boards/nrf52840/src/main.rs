//! The generic node on the nRF52840 (flash once; the role comes over the air):
//!
//! - address: UICR CUSTOMER[0], the provisioning word (`0xA5` magic in bits 31..24, the
//!   16-bit short address in bits 15..0), written once per node; the radio channel of an
//!   unconfigured node: UICR CUSTOMER[1] (11..=26; erased: 15); the management key:
//!   CUSTOMER[2..=5] when the word's flag bit 2 says so (`node_fw::provision`);
//! - radio: the IEEE 802.15.4 radio ([`radio`]);
//! - pins: 16 GPIOs, outputs or inputs as the table uses them ([`gpio`]);
//! - OTA transfer page, frame counter, table slots and boot counter: the last 32 KiB of
//!   the internal flash ([`flash`]);
//! - security: with a management key, the config PAN is secured (`runtime::run_secured`),
//!   AES-128 on the AES-ECB peripheral ([`ecb`]);
//! - log: defmt over RTT (`cargo run --release` flashes a DK with probe-rs and prints it):
//!   the runtime's notes ([`DefmtNotes`]), a panic's location; no `core::fmt` in the image.
//!
//! With the feature `gateway` the image is the serial <-> radio gateway instead
//! ([`gateway`]; a separate build so that the node image does not carry the UART).
#![no_std]
#![no_main]

#[cfg(all(feature = "ecb", not(feature = "gateway")))]
mod ecb;
#[cfg(not(feature = "gateway"))]
mod flash;
#[cfg(feature = "gateway")]
mod gateway;
#[cfg(not(feature = "gateway"))]
mod gpio;
mod mem;
mod radio;

use defmt_rtt as _;
use embassy_executor::Spawner;
use embassy_nrf::config::{Config, HfclkSource};
use embassy_nrf::radio::ieee802154::{Packet, Radio};
use embassy_nrf::{bind_interrupts, peripherals};
use node_fw::provision;

#[cfg(not(feature = "gateway"))]
bind_interrupts!(struct Irqs {
    RADIO => embassy_nrf::radio::InterruptHandler<peripherals::RADIO>;
    GPIOTE => gpio::PortHandler;
});

#[cfg(feature = "gateway")]
bind_interrupts!(struct Irqs {
    RADIO => embassy_nrf::radio::InterruptHandler<peripherals::RADIO>;
    UARTE0 => embassy_nrf::buffered_uarte::InterruptHandler<peripherals::UARTE0>;
});

/// UICR CUSTOMER[0] (the provisioning word), [1] (the channel), [2..=5] (the key): the
/// layout of `node_fw::provision`.
const PROVISION_AT: usize = provision::nrf52840::WORD_AT as usize;
const CHANNEL_AT: usize = provision::nrf52840::CHANNEL_AT as usize;
const KEY_AT: usize = provision::nrf52840::KEY_AT as usize;
const DEFAULT_CHANNEL: u8 = 15;

fn uicr(at: usize) -> u32 {
    // SAFETY: UICR customer words are always readable.
    unsafe { core::ptr::read_volatile(at as *const u32) }
}

/// A panic (none is expected: no data from outside reaches one) halts as panic-probe
/// does: a HardFault, where the probe prints the backtrace (the image has its debug info),
/// so the panic's place is known. The handler does not look at the panic: the message and
/// its location would keep the panic sites' formatting (`core::fmt`, 3.4 KB) in the image.
#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    cortex_m::interrupt::disable();
    defmt::error!("panicked: see the backtrace");
    cortex_m::asm::udf()
}

/// A node that cannot run (no id, a key announced but erased, no frame counter) stays off
/// the air: asleep until reset, its log line already in the RTT buffer. Not an await in
/// `main`: no state of its future per place it stops (flash, docs/boards.md).
fn stay_off() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

/// The runtime's notes as defmt messages: the texts of `runtime::log_note`, formatted on
/// the host that reads the log, so no `core::fmt` is in the image.
#[cfg(not(feature = "gateway"))]
struct DefmtNotes;

/// A flash failure's name.
#[cfg(not(feature = "gateway"))]
fn failure(why: node_fw::runtime::FlashFailure) -> &'static str {
    use embedded_storage::nor_flash::NorFlashErrorKind as Kind;
    use node_fw::slots::SlotError;
    match why {
        SlotError::Geometry => "geometry",
        SlotError::TooLong => "too long",
        SlotError::NotStaged => "not staged",
        SlotError::Flash(Kind::NotAligned) => "flash: not aligned",
        SlotError::Flash(Kind::OutOfBounds) => "flash: out of bounds",
        SlotError::Flash(_) => "flash error",
    }
}

#[cfg(not(feature = "gateway"))]
impl node_fw::runtime::Notes for DefmtNotes {
    fn note(&mut self, addr: u16, note: node_fw::runtime::Note<'_>) {
        use node_fw::runtime::Note;
        match note {
            Note::FlashUnreadable(_) => {
                defmt::warn!("node {=u16:#06x}: flash unreadable: booting unconfigured", addr)
            }
            Note::TrialCutShort { slot } => defmt::warn!(
                "node {=u16:#06x}: a trial was cut short (slot {=usize}): back to the confirmed table",
                addr,
                slot
            ),
            Note::CannotRevoke { slot, why } => defmt::warn!(
                "node {=u16:#06x}: cannot revoke slot {=usize}: {=str}",
                addr,
                slot,
                why.map_or("flash error", failure)
            ),
            Note::MissingPin { pin } => defmt::warn!(
                "node {=u16:#06x}: the stored table uses pin {=u8}, which this board lacks",
                addr,
                pin
            ),
            Note::CannotStage(why) => defmt::warn!(
                "node {=u16:#06x}: cannot stage the pushed table: {=str}",
                addr,
                failure(why)
            ),
            Note::CannotActivate { slot, why } => defmt::warn!(
                "node {=u16:#06x}: cannot activate slot {=usize}: {=str}",
                addr,
                slot,
                failure(why)
            ),
            Note::Switched {
                rollback,
                role,
                generation,
                slot,
            } => defmt::info!(
                "node {=u16:#06x}: {=str} role {=str} generation {=u32} (slot {=usize})",
                addr,
                if rollback { "rolled back to" } else { "activated" },
                role,
                generation,
                slot
            ),
            Note::Boot {
                role,
                generation,
                slot,
            } => defmt::info!(
                "node {=u16:#06x}: boot: role {=str} generation {=u32} from slot {=usize}",
                addr,
                role,
                generation,
                slot
            ),
            Note::BootUnconfigured => defmt::info!("node {=u16:#06x}: boot: unconfigured", addr),
            Note::Staged { generation, slot } => defmt::info!(
                "node {=u16:#06x}: generation {=u32} staged (slot {=usize})",
                addr,
                generation,
                slot
            ),
            Note::Fault { code } => {
                defmt::warn!("node {=u16:#06x}: fault {=u8:#04x}: outputs safe", addr, code)
            }
            Note::FaultCleared => defmt::info!("node {=u16:#06x}: fault cleared", addr),
        }
    }
}

#[embassy_executor::main]
async fn main(_spawner: Spawner) {
    let mut config = Config::default();
    config.hfclk_source = HfclkSource::ExternalXtal;
    let p = embassy_nrf::init(config);

    let Ok(word) = provision::parse_word(uicr(PROVISION_AT)) else {
        defmt::error!(
            "no node id: write UICR CUSTOMER[0] = 0xA500_0000 | address (see docs/boards.md)"
        );
        stay_off()
    };
    let addr = word.addr;
    // The management key (CUSTOMER[2..=5]): the node secures its config PAN with it. An
    // image without frame security (a measurement) reads none.
    let key = if word.has_key() && cfg!(feature = "frame-security") {
        let words = core::array::from_fn(|i| uicr(KEY_AT + 4 * i));
        let Some(key) = provision::ManagementKey::from_words(words) else {
            defmt::error!(
                "node {=u16:#06x}: CUSTOMER[0] announces a key but CUSTOMER[2..=5] are erased",
                addr
            );
            stay_off()
        };
        Some(key)
    } else {
        None
    };
    let channel = match uicr(CHANNEL_AT) as u8 {
        c @ 11..=26 => c,
        _ => DEFAULT_CHANNEL,
    };

    let mut radio = Radio::new(p.RADIO, Irqs);
    radio.set_channel(channel);
    let radio = radio::NrfRadio {
        radio,
        packet: Packet::new(),
    };
    #[cfg(feature = "gateway")]
    {
        // The gateway only relays frames: security is end to end, it needs no key.
        let _ = key;
        defmt::info!("gateway: channel {=u8}, serial 1 Mbaud", channel);
        let mut config = embassy_nrf::uarte::Config::default();
        config.baudrate = embassy_nrf::uarte::Baudrate::Baud1m;
        let rx_buf = cortex_m::singleton!(: [u8; 512] = [0; 512]).expect("once");
        let tx_buf = cortex_m::singleton!(: [u8; 512] = [0; 512]).expect("once");
        let uart = embassy_nrf::buffered_uarte::BufferedUarte::new(
            p.UARTE0,
            p.TIMER1,
            p.PPI_CH0,
            p.PPI_CH1,
            p.PPI_GROUP0,
            p.P0_08,
            p.P0_06,
            Irqs,
            config,
            rx_buf,
            tx_buf,
        );
        let (rx, tx) = uart.split();
        gateway::run(radio, rx, tx).await;
    }
    #[cfg(not(feature = "gateway"))]
    {
        use core::cell::RefCell;

        use embassy_nrf::nvmc::Nvmc;
        #[cfg(feature = "frame-security")]
        use node_fw::frame_counter::FrameCounter;
        use node_fw::runtime::{self, Board};

        use flash::NrfFlash;
        use gpio::{Gpio, GpioInputs, GpioPins};

        let gpio = Gpio::new([
            p.P1_01.into(),
            p.P1_02.into(),
            p.P1_03.into(),
            p.P1_04.into(),
            p.P1_05.into(),
            p.P1_06.into(),
            p.P1_07.into(),
            p.P1_08.into(),
            p.P1_10.into(),
            p.P1_11.into(),
            p.P1_12.into(),
            p.P1_13.into(),
            p.P1_14.into(),
            p.P1_15.into(),
            p.P0_03.into(),
            p.P0_04.into(),
        ]);
        let nvmc = cortex_m::singleton!(: RefCell<Nvmc<'static>> = RefCell::new(Nvmc::new(p.NVMC)))
            .expect("once");
        let flash = NrfFlash::new(nvmc);
        // The boot count reserves the link epochs (`node_fw::epoch`): counted again when
        // this boot has taken most of them.
        let mut boot_counter = flash.boot_counter();
        let (boots, persisted) = boot_counter.count_boot();
        let epoch = node_fw::epoch::of_boot(boots);
        let mut count = || match boot_counter.count_boot() {
            (boots, true) => Some(boots),
            (_, false) => None,
        };
        // A count the NVMC did not take is counted again at once (the next boot would
        // read the previous one and start at this boot's first epoch).
        let boot = runtime::Boot::Counted {
            boots,
            persisted,
            count: &mut count,
        };
        defmt::info!(
            "node {=u16:#06x}: nrf52840, channel {=u8}, boot {=u32}, epoch {=u16}, key {=bool}",
            addr,
            channel,
            boots,
            epoch,
            key.is_some()
        );
        // A keyed node's frame counter. The NVMC blocks: the counter's plain functions
        // (`open`, `next`) complete in place.
        #[cfg(feature = "frame-security")]
        let mut counter = match key {
            Some(_) => match FrameCounter::open(flash.frame_counter()) {
                Ok(c) => {
                    // The counter's value only: the key is never logged.
                    defmt::info!("node {=u16:#06x}: frame counter {=u32}", addr, c.peek());
                    Some(c)
                }
                Err(e) => {
                    // Named, not formatted: no `Debug` of the error (and its flash error)
                    // in the image.
                    let why = match e {
                        node_fw::frame_counter::CounterError::Geometry => "geometry",
                        node_fw::frame_counter::CounterError::Exhausted => "exhausted",
                        node_fw::frame_counter::CounterError::Flash(_) => "flash error",
                    };
                    defmt::error!(
                        "node {=u16:#06x}: frame counter: {=str}: staying off the air",
                        addr,
                        why
                    );
                    stay_off()
                }
            },
            None => None,
        };

        let staging = flash::NrfStaging::new(&flash);
        let board = Board {
            radio,
            outputs: GpioPins(&gpio),
            inputs: GpioInputs::new(&gpio),
            flash,
            pin_mask: runtime::pin_range(gpio::PINS),
        };
        #[cfg(feature = "ecb")]
        ecb::install();
        #[cfg(feature = "frame-security")]
        let (stop, stats) = {
            let mut next = || counter.as_mut().and_then(|c| c.next().ok());
            let security = key.map(|key| runtime::Security {
                key,
                counter: &mut next,
            });
            runtime::run_staged(
                addr,
                boot,
                board,
                &mut (),
                security,
                staging,
                &mut DefmtNotes,
            )
            .await
        };
        // The unsecured node (a measurement: what frame security costs).
        #[cfg(not(feature = "frame-security"))]
        let (stop, stats) =
            runtime::run_staged(addr, boot, board, &mut (), None, staging, &mut DefmtNotes).await;
        defmt::error!(
            "node stopped ({=bool}): {=u32} activations",
            matches!(stop, runtime::Stop::FlashGeometry),
            stats.activations
        );
    }
}
