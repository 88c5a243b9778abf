//! The commands that need no radio: check, compile, dump, diagram, sim, verify.

use std::path::Path;

use robot_analysis::{inject, sim, timeline, verify};
use robot_compiler::compile as pipeline;
use robot_compiler::{check, diagram, dump, Compiled, Diagnostic, Source};

use crate::cli::{Format, SimArgs, VerifyArgs, VerifyHow, VerifyPart};
use crate::commands::outputs;
use crate::failure::Failure;
use crate::out::{err, errln, out, outln};

/// Reads a robot (its errors name the file, and the place of a byte that is not UTF-8).
fn load(path: &Path) -> Result<Source, Failure> {
    Source::read(path).map_err(Failure::from)
}

/// Reads and compiles a robot; on failure every diagnostic is reported.
pub(crate) fn load_compiled(path: &Path) -> Result<(Source, Compiled), Failure> {
    let src = load(path)?;
    match pipeline::compile(&src) {
        Ok(compiled) => Ok((src, compiled)),
        Err(diags) => {
            report(&src, &diags);
            Err(Failure::reported())
        }
    }
}

pub(super) fn report(src: &Source, diags: &[Diagnostic]) {
    use std::io::IsTerminal;
    let color = std::io::stderr().is_terminal();
    err!("{}", robot_compiler::diag::render_all(src, diags, color));
}

pub fn check(robot: &Path) -> Result<(), Failure> {
    let src = load(robot)?;
    let checked = check::check(&src);
    report(&src, &checked.diagnostics);
    if checked.has_errors() {
        return Err(Failure::reported());
    }
    if let Some(line) = checked.ir.as_ref().and_then(pipeline::homing_line) {
        outln!("{line}");
    }
    if let Some(robot) = &checked.robot {
        let nets = robot_compiler::petri::load(robot, &src).nets();
        for line in robot_compiler::petri::check::publication_lines(robot, &nets) {
            outln!("{line}");
        }
    }
    // What the checks let through must also become tables: a robot that does not compile
    // is not ok.
    let compiled = pipeline::lower_checked(&src, checked).map_err(|diags| {
        report(&src, &diags);
        Failure::reported()
    })?;
    for line in pipeline::stimulus_lines(&compiled) {
        outln!("{line}");
    }
    outln!("{}: ok", src.name);
    Ok(())
}

pub fn compile(robot: &Path, out: &Path, generation: Option<u32>) -> Result<(), Failure> {
    let (src, mut compiled) = load_compiled(robot)?;
    if let Some(g) = generation {
        compiled = compiled.with_generation(g).map_err(Failure::error)?;
    }
    report(&src, &compiled.warnings);
    let names: Vec<String> = compiled
        .ir
        .roles
        .iter()
        .map(|r| format!("{}.bin", r.name))
        .collect();
    let inputs = super::outputs::robot_files(robot, &compiled.robot);
    super::outputs::none_an_input("--out", out, names.iter().map(String::as_str), &inputs)?;
    let blobs = compiled.blobs.iter().map(Vec::as_slice);
    super::outputs::write_all(out, names.iter().map(String::as_str).zip(blobs))?;
    for line in pipeline::summary(&compiled) {
        outln!("{line}");
    }
    if compiled.robot.sequence.is_some() {
        let radio = pipeline::radio_events(&compiled.ir);
        outln!("radio publications per cycle: {}", radio.len());
        for (from, event, to) in radio {
            outln!("  {from} -> {to}: {event}");
        }
    }
    if let Some(line) = pipeline::homing_line(&compiled.ir) {
        outln!("{line}");
    }
    Ok(())
}

pub fn dump(blob: &Path) -> Result<(), Failure> {
    let limit = config_schema::limits::MAX_BLOB as u64;
    let bytes = robot_compiler::source::read_at_most(blob, limit)
        .map_err(|e| Failure::error(format!("cannot read {}: {e}", blob.display())))?;
    let text = dump::dump(&bytes)
        .map_err(|e| Failure::error(format!("{}: not a valid table blob: {e}", blob.display())))?;
    out!("{text}");
    Ok(())
}

pub fn diagram(robot: &Path, role: &str, format: Format) -> Result<(), Failure> {
    let (src, compiled) = load_compiled(robot)?;
    super::known_role(robot, &compiled.ir, role)?;
    let automata = robot_compiler::automata::compile::placed(&compiled.robot, &src, role);
    let dot = diagram::dot_with_automata(&compiled.ir, &automata, role).map_err(Failure::error)?;
    match format {
        Format::Dot => out!("{dot}"),
        Format::Svg => out!("{}", diagram::svg(&dot).map_err(Failure::error)?),
    };
    Ok(())
}

pub fn verify(flags: &VerifyArgs) -> Result<(), Failure> {
    let (src, compiled) = load_compiled(&flags.robot)?;
    let robot = &compiled.robot;
    if flags.how.balls.is_some() && robot.sorting.is_none() {
        return Err(Failure::usage(format!(
            "--balls is a sorting station's: {} has no `sorting:`",
            flags.robot.display()
        )));
    }
    let contacts = robot
        .plants
        .iter()
        .any(|p| matches!(p, robot_compiler::plants::PlantDecl::Switch { .. }));
    if flags.how.faults.is_some() && !contacts {
        return Err(Failure::usage(format!(
            "--faults is for declared fault contacts: {} declares none (`plants: [Switch(...)]`)",
            flags.robot.display()
        )));
    }
    let verified = verification(&src.name, &compiled, flags.how).map_err(Failure::error)?;
    out!("{}", verified.text);
    if verified.ok() {
        Ok(())
    } else {
        Err(Failure::reported())
    }
}

/// A `verify` run: its reports and the text `verify` prints.
pub struct Verification {
    /// The cycle's (not run with `--only homing`: then an empty passing report).
    pub report: verify::Report,
    /// Homing's, if the robot homes and it was run.
    pub homing: Option<verify::HomingReport>,
    pub text: String,
}

impl Verification {
    /// Every exploration run passed.
    pub fn ok(&self) -> bool {
        self.deciding().ok()
    }

    /// The first report that failed (the cycle's, then homing's), else the cycle's.
    pub fn deciding(&self) -> &verify::Report {
        match &self.homing {
            Some(h) if self.report.ok() && !h.ok() => &h.report,
            _ => &self.report,
        }
    }

    /// The one line `push` prints for a robot that passed.
    pub fn passed_line(&self) -> String {
        let r = &self.report;
        let assumed = if r.prompt {
            " (assuming a prompt radio)"
        } else {
            ""
        };
        format!(
            "verified: {} states, {} transitions, every property holds{assumed}",
            r.states, r.transitions
        )
    }
}

/// Explores `compiled` (named `name`) as `verify` does with `how`.
pub fn verification(
    name: &str,
    compiled: &Compiled,
    how: VerifyHow,
) -> Result<Verification, verify::ModelError> {
    let mut text = String::new();
    let declared = compiled.robot.assume_prompt_radio && !how.prompt && !how.any_delay;
    if declared {
        text.push_str(&format!(
            "{name}: assumes a prompt radio (`assume_prompt_radio`); --any-delay explores \
             without it\n"
        ));
    }
    let prompt = (how.prompt || compiled.robot.assume_prompt_radio) && !how.any_delay;
    let balls = how.balls.unwrap_or(verify::DEFAULT_BALLS);
    let model = verify::Model::with_balls(compiled, balls)?;
    let opts = verify::ExploreOptions {
        lossy: how.lossy,
        prompt,
        start_anytime: how.start_anytime,
        max_states: how.max_states,
        faults: how.faults.unwrap_or(verify::DEFAULT_FAULTS),
    };
    let interlocks = model.interlock_count();
    let report = match how.only {
        Some(VerifyPart::Homing) => verify::Report::skipped(opts),
        _ => {
            let r = verify::explore(&model, opts);
            text.push_str(&r.render(name, interlocks));
            r
        }
    };
    let homing = match how.only {
        Some(VerifyPart::Cycle) => None,
        _ => {
            let h = verify::explore_homing(&model, opts);
            match &h {
                Some(h) => text.push_str(&h.render(name, interlocks)),
                None => {
                    // A role that takes HOME without the robot declaring its homing (a
                    // robot brought back from IEC 61499): nothing to prove it against.
                    let takes = (compiled.ir.roles.iter().zip(&compiled.tables))
                        .find(|(_, t)| t.home.is_some())
                        .map(|(r, _)| r.name.as_str());
                    text.push_str(&match takes {
                        Some(role) => format!(
                            "{name}: no homing to prove: role {role} takes the HOME command, \
                             but the robot declares no homing sequence (`homing:`) to prove \
                             it against\n"
                        ),
                        None => format!(
                            "{name}: no homing to prove (its charts take no HOME command)\n"
                        ),
                    })
                }
            }
            h
        }
    };
    Ok(Verification {
        report,
        homing,
        text,
    })
}

/// `sim`'s cycles without `--cycles`.
const DEFAULT_CYCLES: usize = 3;

pub fn sim(args: &SimArgs) -> Result<(), Failure> {
    let (trace, timeline) = (args.trace, args.timeline.as_deref());
    let cycles = args.cycles.unwrap_or(DEFAULT_CYCLES);
    let (_, compiled) = load_compiled(&args.robot)?;
    if let Some(out) = &args.timeline {
        let inputs = outputs::robot_files(&args.robot, &compiled.robot);
        outputs::not_an_input("--timeline", out, &inputs)?;
    }
    if compiled.robot.sorting.is_some() {
        return sim_station(&compiled, args);
    }
    if args.feed.is_some() || args.random.is_some() {
        return Err(Failure::usage(format!(
            "--feed and --random are a sorting station's: {} has no `sorting:`",
            args.robot.display()
        )));
    }
    if args.fault.is_some() && args.cycles.is_some() {
        return Err(Failure::usage(
            "--fault runs up to the fault's cycle (`@CYCLE.STEP`): it takes no --cycles",
        ));
    }
    if let Some(spec) = &args.fault {
        return sim_fault(&compiled, spec, trace, timeline);
    }
    let result = if trace || timeline.is_some() {
        sim::simulate_traced(&compiled, cycles)
    } else {
        sim::simulate(&compiled, cycles)
    }
    .map_err(Failure::error)?;
    if trace {
        for line in &result.trace {
            outln!("{line}");
        }
    }
    if let Some(path) = timeline {
        let entries = timeline::run(&compiled, cycles).map_err(Failure::error)?;
        write_timeline(&compiled, &entries, path)?;
    }
    out!("{}", result.report());
    if result.ok() {
        Ok(())
    } else {
        Err(Failure::reported())
    }
}

/// Why a fault could not be injected: a target or step the robot does not have is a bad
/// argument (status 2), as an unknown `--role` is; the simulation's own failures are not.
pub fn injection_failure(e: inject::InjectError) -> Failure {
    match e {
        inject::InjectError::Simulation(_) | inject::InjectError::World(_) => Failure::error(e),
        _ => Failure::usage(e),
    }
}

/// `sim` of a sorting station: the whole feed, one line per ball.
fn sim_station(compiled: &Compiled, args: &SimArgs) -> Result<(), Failure> {
    use robot_analysis::sorter;
    if args.fault.is_some() || args.cycles.is_some() {
        return Err(Failure::usage(format!(
            "a sorting station's `sim` takes no {}: it runs its feed (--feed, --random, \
             --trace, --timeline)",
            if args.fault.is_some() {
                "--fault"
            } else {
                "--cycles"
            }
        )));
    }
    if args.feed.as_deref().is_some_and(|f| f.trim().is_empty()) {
        return Err(Failure::usage(
            "--feed names no ball: give their colours, front first (`--feed \"B G O\"`)",
        ));
    }
    let feed = match (&args.feed, args.random, &compiled.robot.sorting) {
        (Some(text), _, Some(s)) => Some(sorter::parse_feed(s, text).map_err(Failure::usage)?),
        (None, Some(n), Some(s)) => Some(sorter::random_feed(s, usize::from(n), args.seed)),
        _ => None,
    };
    let run = sorter::simulate(compiled, feed.as_deref()).map_err(Failure::error)?;
    if args.trace {
        for line in &run.trace {
            outln!("{line}");
        }
    }
    if let Some(path) = &args.timeline {
        let svg = timeline::station::svg(compiled, &run).map_err(Failure::error)?;
        std::fs::write(path, svg)
            .map_err(|e| Failure::error(format!("{}: {e}", path.display())))?;
        errln!("timeline: {}", path.display());
    }
    out!("{}", run.report());
    if run.ok() {
        Ok(())
    } else {
        Err(Failure::reported())
    }
}

/// `sim --fault`: succeeds if the fault was detected and nothing moved afterwards.
fn sim_fault(
    compiled: &Compiled,
    spec: &str,
    trace: bool,
    timeline: Option<&Path>,
) -> Result<(), Failure> {
    let spec = inject::parse(spec).map_err(Failure::usage)?;
    let run = inject::simulate(compiled, &spec).map_err(injection_failure)?;
    if trace {
        for e in &run.trace {
            outln!("{e}");
        }
    }
    if let Some(path) = timeline {
        write_timeline(compiled, &run.trace, path)?;
    }
    out!("{}", run.report());
    if run.stopped_safely() {
        Ok(())
    } else {
        Err(Failure::reported())
    }
}

fn write_timeline(
    compiled: &Compiled,
    trace: &[node_fw::sim::TraceEntry],
    path: &Path,
) -> Result<(), Failure> {
    let svg = timeline::svg(compiled, trace).map_err(Failure::error)?;
    std::fs::write(path, svg).map_err(|e| Failure::error(format!("{}: {e}", path.display())))?;
    errln!("timeline: {}", path.display());
    Ok(())
}
