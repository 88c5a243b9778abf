//! One function per command.

pub mod alarms;
pub mod demo;
pub mod export;
pub mod keys;
pub mod matrix;
pub mod offline;
pub mod outputs;
pub mod panel;
pub mod radio;

/// Prints a server's start-up lines (where it listens) for the operator, ignoring an
/// output closed under it (a pipe whose reader went away): a server goes on serving.
pub fn announce(lines: &[String]) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    for line in lines {
        let _ = writeln!(out, "{line}");
    }
    let _ = out.flush();
}
