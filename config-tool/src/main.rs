//! `config-tool`: `main` parses the command line, `run` calls the one function of the
//! command (`commands`), and the failure sets the exit status (`failure`). The work is in
//! the library crates (docs/architecture.md).

use std::process::ExitCode;

use clap::Parser;

mod cli;
mod commands;
mod failure;

use cli::{Cli, Command};
use commands::{demo, offline, radio};
use failure::Failure;

fn run(command: Command) -> Result<(), Failure> {
    match command {
        Command::Check { robot } => offline::check(&robot),
        Command::Compile {
            robot,
            out,
            generation,
        } => offline::compile(&robot, &out, generation),
        Command::Dump { blob } => offline::dump(&blob),
        Command::Diagram {
            robot,
            role,
            format,
        } => offline::diagram(&robot, &role, format),
        Command::Sim {
            robot,
            cycles,
            trace,
            fault,
            timeline,
        } => offline::sim(&robot, cycles, trace, fault.as_deref(), timeline.as_deref()),
        Command::Verify {
            robot,
            lossy,
            prompt,
            any_delay,
            start_anytime,
            max_states,
        } => offline::verify(
            &robot,
            offline::VerifyFlags {
                lossy,
                prompt,
                any_delay,
                start_anytime,
                max_states,
            },
        ),
        Command::Medium {
            listen,
            loss,
            dup,
            corrupt,
            delay_ms,
            seed,
            pcap,
        } => radio::medium(medium::Config {
            listen,
            loss,
            dup,
            corrupt,
            delay_ms,
            seed,
            pcap,
        }),
        Command::Scan { at } => radio::scan(&at),
        Command::Push {
            robot,
            at,
            role,
            node,
            generation,
            force,
        } => radio::push(
            &robot,
            &at,
            radio::PushFlags {
                role,
                node,
                generation,
                force,
            },
        ),
        Command::Status { at, node } => radio::status(&at, node),
        Command::Start { at, node } => radio::start(&at, node),
        Command::Reset { at, node } => radio::reset(&at, node),
        Command::Plant { robot, at } => radio::plant(&robot, &at),
        Command::Monitor { at, seconds } => {
            radio::monitor(&at, seconds.map(std::time::Duration::from_secs))
        }
        Command::Demo {
            robot,
            cycles,
            loss,
            then,
            no_reconfigure,
            pcap,
            seed,
            qemu,
            elf,
            icount,
            fault,
        } => demo::demo(
            &robot,
            demo::DemoFlags {
                cycles,
                loss,
                then,
                no_reconfigure,
                pcap,
                seed,
                qemu,
                elf,
                icount,
                fault,
            },
        ),
        Command::QemuNode(args) => radio::qemu_node(args),
        Command::Gateway {
            serial,
            baud,
            listen,
        } => radio::gateway(&serial, baud, listen),
        Command::Node(args) => radio::node(args),
    }
}

fn main() -> ExitCode {
    match run(Cli::parse().command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            if !failure.message.is_empty() {
                eprintln!("{}", failure.message);
            }
            ExitCode::from(failure.code)
        }
    }
}
