//! `config-tool`: `main` parses the command line, `run` calls the one function of the
//! command (`commands`), and the failure sets the exit status (`failure`). The work is in
//! the library crates (docs/architecture.md).

use std::process::ExitCode;

use clap::Parser;

mod cli;
mod commands;
mod failure;
mod out;
mod tool_keys;

use cli::{Cli, Command, KeysCommand};
use commands::{demo, keys, offline, radio};
use failure::Failure;
use out::errln;

fn run(command: Command) -> Result<(), Failure> {
    match command {
        Command::Check { robot } => offline::check(&robot),
        Command::Compile {
            robot,
            out,
            generation,
        } => offline::compile(&robot, &out, generation),
        Command::Export4diac { robot, out } => commands::export::export(&robot, &out),
        Command::Dump { blob } => offline::dump(&blob),
        Command::Matrix {
            robot,
            function,
            csv,
        } => commands::matrix::matrix(&robot, function.as_deref(), csv),
        Command::Diagram {
            robot,
            role,
            format,
        } => offline::diagram(&robot, &role, format),
        Command::Sim(args) => offline::sim(&args),
        Command::Verify(args) => offline::verify(&args),
        Command::Medium(args) => radio::medium(args.config()),
        Command::Scan { robot, at, keys } => radio::scan(robot.as_deref(), &at, &keys),
        Command::Push(args) => radio::push(&args),
        Command::Confirm(args) => radio::confirm(&args),
        Command::Rollback(args) => radio::rollback(&args),
        Command::Status {
            robot,
            at,
            node,
            keys,
        } => radio::status(robot.as_deref(), &at, node, &keys),
        Command::Start {
            robot,
            at,
            node,
            keys,
        } => radio::start(robot.as_deref(), &at, node, &keys),
        Command::Home(args) => radio::home(&args),
        Command::Reset { at, node, keys } => radio::reset(&at, node, &keys),
        Command::Alarms {
            robot,
            at,
            watch,
            keys,
        } => radio::alarms(&robot, &at, &keys, watch),
        Command::Ack { robot, at, keys } => radio::ack(&robot, &at, &keys),
        Command::Plant { robot, at } => radio::plant(&robot, &at),
        Command::Panel {
            robot,
            at,
            listen,
            keys,
        } => commands::panel::panel(&robot, &at, listen, &keys),
        Command::Monitor {
            at,
            seconds,
            keys,
            generation,
        } => radio::monitor(
            &at,
            seconds.map(std::time::Duration::from_secs),
            keys.as_deref(),
            generation,
        ),
        Command::Demo(args) => demo::demo(args),
        Command::QemuNode(args) => radio::qemu_node(args),
        Command::Gateway {
            serial,
            baud,
            listen,
        } => radio::gateway(&serial, baud, listen),
        Command::Keys { command } => match command {
            KeysCommand::New { out, force } => keys::new(&out, force),
            KeysCommand::Provision {
                keys: file,
                node,
                board,
                out,
                force,
            } => keys::provision(&file, node, board, out.as_deref(), force),
        },
        Command::Node(args) => radio::node(args),
    }
}

fn main() -> ExitCode {
    let done = run(Cli::parse().command);
    out::flush();
    // Its work done, a command whose output could not be written fails (a reader that
    // went away is no failure: `out`).
    let done = done.and_then(|()| out::failed().map_or(Ok(()), |e| Err(Failure::error(e))));
    match done {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            if !failure.message.is_empty() {
                errln!("{}", failure.message);
            }
            ExitCode::from(failure.code)
        }
    }
}
