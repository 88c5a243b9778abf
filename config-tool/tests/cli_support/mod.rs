//! Shared by the tests that run the `config-tool` binary: a run from the workspace root
//! (where `robot-configs/` is), and its output as text.
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::{Command, Output};

/// `config-tool demo ARGS`, run from the workspace root.
pub fn demo(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .arg("demo")
        .args(args)
        .current_dir(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".."))
        .output()
        .expect("runs")
}

/// Bytes of a process's output as text.
pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}
