//! What can go wrong talking to a machine, typed. The messages carry no `error:` prefix:
//! the binary adds it.

use std::io;
use std::process::ExitStatus;

#[derive(Debug, thiserror::Error)]
pub enum NetError {
    /// A robot that does not load, compile or re-encode (its diagnostics, rendered).
    #[error("{0}")]
    Robot(String),
    /// A robot file that cannot be read.
    #[error(transparent)]
    Load(#[from] robot_compiler::source::LoadError),
    #[error("medium: {0}")]
    Medium(#[source] io::Error),
    /// The medium's capture (`--pcap`) lacks frames: its file could not be written.
    #[error("--pcap: {unwritten} frame(s) not written ({why}): the capture ends early")]
    Pcap { unwritten: u64, why: io::ErrorKind },
    /// The tool's radio (or a command on it) failed.
    #[error("{0}")]
    Radio(#[from] io::Error),
    #[error("no node command")]
    NoNodeCommand,
    #[error("keys of the test bed: {0}")]
    Keys(#[from] robot_keys::KeyFileError),
    #[error("cannot start node {addr:#06x}: {source}")]
    NodeStart { addr: u16, source: io::Error },
    #[error("plant: {0}")]
    Plant(#[source] io::Error),
    #[error("monitor: {0}")]
    Monitor(#[source] io::Error),
    #[error("nodes did not answer: {}", .0.join(", "))]
    Silent(Vec<String>),
    /// A node did not answer `command` in time; `role`: the robot's role it runs, if the
    /// caller knows it.
    #[error(
        "node {addr:#06x}{} did not answer {command}",
        role.as_deref().map(|r| format!(" ({r})")).unwrap_or_default()
    )]
    NoAnswer {
        addr: u16,
        role: Option<String>,
        command: String,
    },
    #[error("the robot has no start input")]
    NoStart,
    #[error("the plant saw {0} of {1} strokes in time")]
    Stalled(usize, usize),
    #[error("the robot has no homing (only a sequence robot is homed)")]
    NoHome,
    /// A `--fault` that does not fit the robot.
    #[error("--fault: {0}")]
    Fault(String),
    #[error(
        "no firmware image at {0}: build it with `cargo build --release` in \
         node-fw/boards/qemu-mps2 (or give --elf)"
    )]
    NoImage(String),
    #[error("qemu-system-arm --version: {0}")]
    QemuFailed(ExitStatus),
    #[error("cannot run qemu-system-arm: {0} (Debian: apt-get install qemu-system-arm)")]
    NoQemu(#[source] io::Error),
    #[error("flash file {0}: a QEMU node's flash path cannot contain a comma or a space")]
    FlashPath(String),
}
