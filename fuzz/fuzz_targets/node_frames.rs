//! Frames from the air, whatever their bytes, into a node's core (`NodeCore`): a node
//! running the paint robot's VC table with no link keys (its events in clear), and an
//! unconfigured node without a management key (what a node is before its first push),
//! whose board stages, activates and confirms whatever the core asks for, as a real
//! board's flash does. Interleaved with the clock going on and input edges. Never a
//! panic; every frame and tick returns (libFuzzer's timeout catches one that does not).
//!
//! The input, read as commands: `0 len bytes` a frame (MPDU) to the running node, `1 len
//! bytes` to the unconfigured one, `2 ms` the clock on by `ms`, `3 pin` an input edge
//! on the running node (bit 7: the level).
#![no_main]

use std::sync::OnceLock;

use config_schema::link_keys::{decode_deployment, Deployment};
use config_schema::Table;
use libfuzzer_sys::fuzz_target;
use node_fw::node::{FlashRequest, Io, NodeCore};

/// A board that keeps nothing of what is sent.
struct Board;

impl Io for Board {
    fn transmit(&mut self, _psdu: &[u8]) {}
    fn set_pin(&mut self, _pin: u8, _level: bool) {}
    fn next_frame_counter(&mut self) -> Option<u32> {
        Some(1)
    }
}

/// The paint robot's VC role: (its address, its table).
fn vc() -> &'static (u16, Table) {
    static VC: OnceLock<(u16, Table)> = OnceLock::new();
    VC.get_or_init(|| {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../robot-configs/paint-robot.ron"
        );
        let text = std::fs::read_to_string(path).expect("paint-robot.ron");
        let c = robot_compiler::compile(&robot_compiler::Source::new(path, text))
            .expect("paint-robot.ron compiles");
        let i = c.ir.roles.iter().position(|r| r.name == "VC").expect("VC");
        (c.ir.roles[i].address, c.tables[i].clone())
    })
}

/// An unconfigured node and the flash its board keeps: (staged, running, previous).
struct Fresh {
    core: NodeCore,
    staged: Option<Vec<u8>>,
    running: Option<Vec<u8>>,
    previous: Option<Vec<u8>>,
}

impl Fresh {
    /// Serves what the core asks of its flash, as a board does.
    fn flash(&mut self, now: u64) {
        let deployed = |b: &Option<Vec<u8>>| -> Option<Deployment> {
            b.as_deref().and_then(|b| decode_deployment(b).ok())
        };
        // Each request answered moves the core on; a bound, not a pace.
        for _ in 0..4 {
            match self.core.flash_request() {
                None => return,
                Some(FlashRequest::Stage(blob)) => {
                    self.staged = Some(blob.to_vec());
                    self.core.staged(true, &mut Board);
                }
                Some(FlashRequest::Activate { .. }) => {
                    let d = deployed(&self.staged);
                    if d.is_some() {
                        self.previous = self.running.take();
                        self.running = self.staged.take();
                    }
                    self.core.activated(d, now, &mut Board);
                }
                Some(FlashRequest::Rollback) => {
                    let d = deployed(&self.previous);
                    if d.is_some() {
                        self.running = self.previous.take();
                    }
                    self.core.activated(d, now, &mut Board);
                }
                Some(FlashRequest::Confirm) => self.core.confirmed(true, &mut Board),
                // No boot counter: the count fails (asked again at the next epoch).
                Some(FlashRequest::CountBoot) => {
                    self.core.boot_counted(None);
                }
            }
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let (addr, table) = vc();
    let mut running = NodeCore::new(*addr, u64::MAX, Some(table.clone()), 1);
    let mut fresh = Fresh {
        core: NodeCore::new(*addr, u64::MAX, None, 1),
        staged: None,
        running: None,
        previous: None,
    };
    running.boot(&mut Board);
    fresh.core.boot(&mut Board);
    let mut now = 0u64;
    let mut bytes = data.iter().copied();
    while let Some(kind) = bytes.next() {
        match kind & 3 {
            0 | 1 => {
                let Some(len) = bytes.next() else { return };
                let frame: Vec<u8> = bytes.by_ref().take(usize::from(len & 0x7F)).collect();
                if kind & 3 == 0 {
                    running.receive_mpdu(&frame, now, &mut Board);
                } else {
                    fresh.core.receive_mpdu(&frame, now, &mut Board);
                    fresh.flash(now);
                }
            }
            2 => {
                now += u64::from(bytes.next().unwrap_or(1)) * 7;
                running.poll(now, &mut Board);
                fresh.core.poll(now, &mut Board);
                fresh.flash(now);
            }
            _ => {
                let pin = bytes.next().unwrap_or(0);
                running.input(pin & 0x3F, pin & 0x80 != 0, now, &mut Board);
            }
        }
    }
});
