//! Shared by the tests that run the `config-tool` binary: a run from the workspace root
//! (where `robot-configs/` is), and its output as text.
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::{Command, Output};

use robot_net::demo;

/// `config-tool demo ARGS`, run from the workspace root.
pub fn demo(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .arg("demo")
        .args(args)
        .current_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".."))
        .output()
        .expect("runs")
}

/// The image (`QEMU_ELF`, else the release build's) and QEMU, if both are there; panics
/// if they are not and `REQUIRE_QEMU` is set.
pub fn qemu_image() -> Option<PathBuf> {
    let elf = std::env::var_os("QEMU_ELF").map_or_else(
        || {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("..")
                .join(demo::QEMU_ELF)
        },
        PathBuf::from,
    );
    let missing = match (demo::check_elf(&elf), demo::check_qemu()) {
        (Ok(()), Ok(())) => return Some(elf),
        (Err(e), _) | (_, Err(e)) => e.to_string(),
    };
    assert!(
        std::env::var_os("REQUIRE_QEMU").is_none(),
        "REQUIRE_QEMU is set: {missing}"
    );
    eprintln!("skipped: {missing}");
    None
}

/// Bytes of a process's output as text.
pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}
