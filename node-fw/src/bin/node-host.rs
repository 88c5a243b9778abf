//! `node-host --addr 0x0003 --medium 127.0.0.1:PORT [--flash FILE]`: one generic node on
//! the host, connected to the simulated medium.
use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    match node_fw::host::run(node_fw::host::Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let line = format_args!("node-host: error: {e}\n");
            let _ = std::io::Write::write_fmt(&mut std::io::stderr().lock(), line);
            ExitCode::FAILURE
        }
    }
}
