//! The provisioning word: written once per node, the way a factory programs a node id
//! (QEMU: `-device loader,addr=0x003ff000,data=0xA5010003,data-len=4`; on the nRF52840 the
//! same word lives in UICR CUSTOMER[0]). Every node boots the same image.
//!
//! ```text
//! bits 31..24  0xA5     magic: the word was written
//! bits 23..16  flags    bit 0: the emulator has semihosting (flash file, clock, log)
//!                       bit 1: count busy time and stimuli, logged every second (for
//!                       `-icount shift=0`, where a nanosecond is an instruction)
//! bits 15..0   address  the node's 16-bit short address
//! ```

/// Where the word is (outside the linker's FLASH region: see memory.x).
pub const ADDR: usize = 0x003F_F000;
pub const MAGIC: u32 = 0xA5;
pub const FLAG_SEMIHOSTING: u8 = 1;
pub const FLAG_COUNT: u8 = 2;

#[derive(Debug, Clone, Copy)]
pub struct Provision {
    pub addr: u16,
    pub flags: u8,
}

/// The word, if it was written and names a usable address.
pub fn read() -> Option<Provision> {
    // SAFETY: a word of emulated SSRAM that nothing else uses.
    let word = unsafe { core::ptr::read_volatile(ADDR as *const u32) };
    let addr = word as u16;
    (word >> 24 == MAGIC && addr < 0xFFFE).then_some(Provision {
        addr,
        flags: (word >> 16) as u8,
    })
}
