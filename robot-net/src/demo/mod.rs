//! The whole machine on the host: the simulated medium, one unconfigured node process per
//! physical node, the plant, and the tool. `demo` pushes the tables over the medium, runs
//! cycles and checks each against the declared sequence, then pushes a reconfiguration to
//! the running nodes. The end-to-end tests drive the same [`Bed`].

mod bed;
mod qemu;
mod report;
mod run;
mod script;
mod station;
mod transport;

pub use bed::{
    node_addrs, remove_key_dirs, targets, Bed, BedFault, Cycle, FaultReport, Homing, MotorPlant,
    Options,
};
pub use qemu::{
    check_elf, check_qemu, count_log, provision_loaders, provision_word, qemu_args, read_counts,
    Counts, Uart, PROVISION_AT, QEMU_ELF, QEMU_MACHINE,
};
pub use report::{
    alarm_text, cycle_line, fault_meaning, fault_text, homed_line, homing_line, push_line,
    push_summary, say,
};
pub use run::{generation_of, load, run, Demo, Verdict};
pub use script::{fig9, functions, simulate as simulate_script, Act, Expected, Moved};
pub use station::{sort, Sorted};
