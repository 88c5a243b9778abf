//! The `config-tool` command line. The work is in the library; this parses arguments,
//! prints, and sets the exit status.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use robot_analysis::{inject, sim, timeline, verify};
use robot_compiler::{check, compile, diagram, dump, Diagnostic, Source};

mod netcmd;

#[derive(Parser)]
#[command(
    name = "config-tool",
    version,
    about = "Check, compile, dump, draw and simulate RON robot descriptions"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Parse and validate a robot: every problem, with file:line:col.
    Check { robot: PathBuf },
    /// Compile a robot to one table blob per role (`DIR/ROLE.bin`).
    Compile {
        robot: PathBuf,
        #[arg(long)]
        out: PathBuf,
        /// Deployment generation written into every blob (default: the robot's
        /// `generation`, or 0).
        #[arg(long)]
        generation: Option<u32>,
    },
    /// Print a table blob in readable form.
    Dump { blob: PathBuf },
    /// Print a role's charts as Graphviz DOT (or SVG through `dot`).
    Diagram {
        robot: PathBuf,
        #[arg(long)]
        role: String,
        #[arg(long, value_enum, default_value = "dot")]
        format: Format,
    },
    /// Run the compiled blobs on the host interpreter with plant models, on virtual time.
    Sim {
        robot: PathBuf,
        #[arg(long, default_value_t = 3)]
        cycles: usize,
        /// Print every trace entry.
        #[arg(long)]
        trace: bool,
        /// Inject a fault: stuck:ACT, switch:ACT.end|ACT.home, stop:ROLE or
        /// link:FROM->TO, then @STEP or @CYCLE.STEP (injected just before that step).
        #[arg(long)]
        fault: Option<String>,
        /// Write a time diagram of the run (SVG): actuator positions, chart states, events.
        #[arg(long)]
        timeline: Option<PathBuf>,
    },
    /// Explore every reachable state of the machine (charts, plant, radio) and check
    /// deadlock freedom, sequence conformance, interlocks and no double actuation.
    Verify {
        robot: PathBuf,
        /// A delivery may also fail after the link's retries (link alarm).
        #[arg(long)]
        lossy: bool,
        /// Assume the radio is faster than any motion or timer: nothing arrives or
        /// expires while a publication is in flight (also when the robot declares
        /// `assume_prompt_radio`).
        #[arg(long)]
        prompt: bool,
        /// Explore any radio delay, even if the robot declares `assume_prompt_radio`.
        #[arg(long, conflicts_with = "prompt")]
        any_delay: bool,
        /// The operator may press START at any time, not only when the machine is idle.
        #[arg(long)]
        start_anytime: bool,
        /// Stop (inconclusive) beyond this many states.
        #[arg(long, default_value_t = 2_000_000)]
        max_states: usize,
    },
    /// The radio: medium, scan, push, status, start, reset, monitor, demo.
    #[command(flatten)]
    Net(crate::netcmd::NetCommand),
}

#[derive(Clone, Copy, ValueEnum)]
enum Format {
    Dot,
    Svg,
}

fn load(path: &Path) -> Result<Source, String> {
    Source::read(path)
}

/// Reads and compiles a robot; on failure every diagnostic is reported.
fn load_compiled(path: &Path) -> Result<(Source, compile::Compiled), String> {
    let src = load(path)?;
    match compile::compile(&src) {
        Ok(compiled) => Ok((src, compiled)),
        Err(diags) => {
            report(&src, &diags);
            Err(String::new())
        }
    }
}

fn report(src: &Source, diags: &[Diagnostic]) {
    use std::io::IsTerminal;
    let color = std::io::stderr().is_terminal();
    eprint!("{}", robot_compiler::diag::render_all(src, diags, color));
}

fn run(command: Command) -> Result<(), String> {
    match command {
        Command::Check { robot } => {
            let src = load(&robot)?;
            let diags = check::check(&src).diagnostics;
            report(&src, &diags);
            if diags.iter().any(Diagnostic::is_error) {
                return Err(String::new());
            }
            println!("{}: ok", src.name);
            Ok(())
        }
        Command::Compile {
            robot,
            out,
            generation,
        } => {
            let (src, mut compiled) = load_compiled(&robot)?;
            if let Some(g) = generation {
                compiled = compiled
                    .with_generation(g)
                    .map_err(|e| format!("error: {e}"))?;
            }
            report(&src, &compiled.warnings);
            std::fs::create_dir_all(&out).map_err(|e| format!("error: {}: {e}", out.display()))?;
            for (role, blob) in compiled.ir.roles.iter().zip(&compiled.blobs) {
                let path = out.join(format!("{}.bin", role.name));
                std::fs::write(&path, blob)
                    .map_err(|e| format!("error: {}: {e}", path.display()))?;
            }
            for line in compile::summary(&compiled) {
                println!("{line}");
            }
            if compiled.robot.sequence.is_some() {
                let radio = compile::radio_events(&compiled.ir);
                println!("radio publications per cycle: {}", radio.len());
                for (from, event, to) in radio {
                    println!("  {from} -> {to}: {event}");
                }
            }
            Ok(())
        }
        Command::Dump { blob } => {
            let bytes = std::fs::read(&blob)
                .map_err(|e| format!("error: cannot read {}: {e}", blob.display()))?;
            let text = dump::dump(&bytes)
                .map_err(|e| format!("error: {}: not a valid table blob: {e}", blob.display()))?;
            print!("{text}");
            Ok(())
        }
        Command::Diagram {
            robot,
            role,
            format,
        } => {
            let (_, compiled) = load_compiled(&robot)?;
            let dot = diagram::dot(&compiled.ir, &role).map_err(|e| format!("error: {e}"))?;
            match format {
                Format::Dot => print!("{dot}"),
                Format::Svg => print!("{}", diagram::svg(&dot).map_err(|e| format!("error: {e}"))?),
            }
            Ok(())
        }
        // `main` runs them itself, for their exit statuses.
        Command::Net(cmd) => crate::netcmd::run(cmd).map_err(|f| f.message),
        Command::Verify {
            robot,
            lossy,
            prompt,
            any_delay,
            start_anytime,
            max_states,
        } => {
            let (src, compiled) = load_compiled(&robot)?;
            let declared = compiled.robot.assume_prompt_radio && !prompt && !any_delay;
            if declared {
                println!(
                    "{}: assumes a prompt radio (`assume_prompt_radio`); --any-delay explores without it",
                    src.name
                );
            }
            let prompt = (prompt || compiled.robot.assume_prompt_radio) && !any_delay;
            let model = verify::Model::new(&compiled).map_err(|e| format!("error: {e}"))?;
            let result = verify::explore(
                &model,
                verify::ExploreOptions {
                    lossy,
                    prompt,
                    start_anytime,
                    max_states,
                },
            );
            print!("{}", result.render(&src.name, model.interlock_count()));
            if result.ok() {
                Ok(())
            } else {
                Err(String::new())
            }
        }
        Command::Sim {
            robot,
            cycles,
            trace,
            fault,
            timeline,
        } => {
            let (_, compiled) = load_compiled(&robot)?;
            if let Some(spec) = fault {
                let spec = inject::parse(&spec).map_err(|e| format!("error: {e}"))?;
                let run = inject::simulate(&compiled, &spec).map_err(|e| format!("error: {e}"))?;
                if trace {
                    for e in &run.trace {
                        println!("{e}");
                    }
                }
                if let Some(path) = timeline {
                    write_timeline(&compiled, &run.trace, &path)?;
                }
                print!("{}", run.report());
                return if run.stopped_safely() {
                    Ok(())
                } else {
                    Err(String::new())
                };
            }
            let result = if trace || timeline.is_some() {
                sim::simulate_traced(&compiled, cycles)
            } else {
                sim::simulate(&compiled, cycles)
            }
            .map_err(|e| format!("error: {e}"))?;
            if trace {
                for line in &result.trace {
                    println!("{line}");
                }
            }
            if let Some(path) = timeline {
                let entries =
                    timeline::run(&compiled, cycles).map_err(|e| format!("error: {e}"))?;
                write_timeline(&compiled, &entries, &path)?;
            }
            print!("{}", result.report());
            if result.ok() {
                Ok(())
            } else {
                Err(String::new())
            }
        }
    }
}

fn write_timeline(
    compiled: &robot_compiler::Compiled,
    trace: &[node_fw::sim::TraceEntry],
    path: &Path,
) -> Result<(), String> {
    let svg = timeline::svg(compiled, trace).map_err(|e| format!("error: {e}"))?;
    std::fs::write(path, svg).map_err(|e| format!("error: {}: {e}", path.display()))?;
    eprintln!("timeline: {}", path.display());
    Ok(())
}

fn main() -> ExitCode {
    let result = match Cli::parse().command {
        Command::Net(cmd) => crate::netcmd::run(cmd),
        command => run(command).map_err(crate::netcmd::Failure::from),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            if !failure.message.is_empty() {
                eprintln!("{}", failure.message);
            }
            ExitCode::from(failure.code)
        }
    }
}
