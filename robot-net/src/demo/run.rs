//! The demo as an operator runs it: start the bed, push, home, run the cycles, report
//! each, push the reconfiguration; say how it ended.

use std::io::{self, Write};
use std::path::Path;
use std::time::Instant;

use node_fw::ota::Progress;
use robot_compiler::{compile, Compiled, Source};

use super::bed::{self, Bed, BedFault};
use super::{qemu, report as demo_report};
use crate::error::NetError;
use crate::{home, live_plant};

/// How a demo ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Every cycle matched its declared sequence.
    Matched,
    PushFailed,
    Mismatch,
    Faulted,
}

/// Reads and compiles a robot; on failure the errors, rendered.
pub fn load(path: &Path) -> Result<Compiled, NetError> {
    let src = Source::read(path)?;
    compile::compile(&src).map_err(|diags| {
        let errors: Vec<robot_compiler::Diagnostic> =
            diags.into_iter().filter(|d| d.is_error()).collect();
        NetError::Robot(format!(
            "{}{}: does not compile",
            robot_compiler::diag::render_all(&src, &errors, false),
            src.name
        ))
    })
}

/// The generation to push: the robot's, at least 1 (an unconfigured node runs 0).
pub fn generation_of(c: Compiled, generation: Option<u32>) -> Result<Compiled, NetError> {
    let g = generation.unwrap_or(c.ir.generation).max(1);
    c.with_generation(g)
        .map_err(|e| NetError::Robot(e.to_string()))
}

/// What `demo` runs.
pub struct Demo<'a> {
    pub robot: &'a Path,
    /// The robot pushed afterwards to the running nodes (one cycle).
    pub then: Option<&'a Path>,
    pub cycles: usize,
    /// A fault injected into the first robot's run.
    pub fault: Option<robot_analysis::inject::FaultSpec>,
    /// Where counting QEMU nodes log (`--icount`).
    pub count_dir: Option<&'a Path>,
}

/// Where a `--fault` goes on the test bed: the plant's injection, or the bed's fault to
/// inject after so many steps.
type Placed = (Option<live_plant::Injection>, Option<(usize, BedFault)>);

fn place_fault(
    c: &Compiled,
    actuators: &[live_plant::Actuator],
    spec: &robot_analysis::inject::FaultSpec,
) -> Result<Placed, NetError> {
    use robot_analysis::inject::FaultKind;
    let after = (spec.cycle - 1) * c.ir.expect.len() + (spec.step - 1);
    let actuator = |name: &str| {
        actuators
            .iter()
            .position(|a| a.name == name)
            .ok_or_else(|| NetError::Fault(format!("the robot has no actuator {name}")))
    };
    let address = |role: &str| {
        c.ir.roles
            .iter()
            .find(|r| r.name == role)
            .map(|r| r.address)
            .ok_or_else(|| NetError::Fault(format!("the robot has no role {role}")))
    };
    match &spec.kind {
        FaultKind::Stuck(name) => Ok((
            Some(live_plant::Injection {
                after,
                actuator: actuator(name)?,
                kind: live_plant::Jam::Stuck,
            }),
            None,
        )),
        FaultKind::Switch(target) => {
            let (name, end) = match target.rsplit_once('.') {
                Some((n, "end")) => (n, true),
                Some((n, "home")) => (n, false),
                _ => {
                    return Err(NetError::Fault(format!(
                        "`{target}`: a switch is ACT.end or ACT.home"
                    )))
                }
            };
            Ok((
                Some(live_plant::Injection {
                    after,
                    actuator: actuator(name)?,
                    kind: live_plant::Jam::SwitchOpen { end },
                }),
                None,
            ))
        }
        FaultKind::Stop(role) => Ok((None, Some((after, BedFault::Stop(address(role)?))))),
        FaultKind::Link(from, to) => {
            let fault = BedFault::Cut {
                from: address(from)?,
                to: address(to)?,
            };
            Ok((None, Some((after, fault))))
        }
    }
}

/// The demo: pushes, runs the cycles, reports each; says how it ended.
pub fn run(demo: &Demo, options: bed::Options, out: &mut dyn Write) -> Result<Verdict, NetError> {
    let c = generation_of(load(demo.robot)?, None)?;
    if c.robot.sorting.is_some() {
        // A sorting station: its feed, once (no cycles, no reconfiguration).
        return super::station::run(&c, options, out);
    }
    if !c.robot.functions.is_empty() {
        // Control functions: the operator's script of fig. 9, step by step against sim.
        return super::transport::run(&c, options, out);
    }
    let next = match demo.then {
        Some(p) => Some(generation_of(load(p)?, Some(c.ir.generation + 1))?),
        None => None,
    };
    let first_actuators = live_plant::actuators(&c)?;
    let placed = demo
        .fault
        .as_ref()
        .map(|f| place_fault(&c, &first_actuators, f))
        .transpose()?;
    let addrs = bed::node_addrs(&c);
    let mut bed = bring_up(options, &addrs, first_actuators, out)?;
    let runs = [(demo.robot, &c, demo.cycles)].into_iter().chain(
        next.as_ref()
            .map(|n| (demo.then.unwrap_or(demo.robot), n, 1)),
    );
    let mut verdict = Verdict::Matched;
    for (i, (label, robot, cycles)) in runs.enumerate() {
        let first = i == 0;
        if !push_robot(&mut bed, label, robot, out)? {
            verdict = Verdict::PushFailed;
            break;
        }
        let activated = Instant::now();
        let (injection, fault) = match (&placed, first) {
            (Some(p), true) => *p,
            _ => (None, None),
        };
        bed.set_plant_injected(live_plant::actuators(robot)?, injection)?;
        bed.watch(robot)?;
        if let Some((after, fault)) = fault {
            bed.inject_after(after, fault);
        }
        if let Some(spec) = demo.fault.as_ref().filter(|_| first) {
            demo_report::say(out, &format!("fault to inject: {spec}"));
        }
        if !home_robot(&mut bed, robot, out)? {
            verdict = Verdict::Faulted;
            break;
        }
        let count_dir = demo.count_dir.filter(|_| first);
        verdict = run_cycles(&mut bed, robot, cycles, activated, count_dir, &addrs, out)?;
        if verdict != Verdict::Matched {
            break;
        }
    }
    finish(bed, verdict, out)?;
    Ok(verdict)
}

/// Starts the bed: the medium, one unconfigured node per address, the plant; says what
/// announced itself.
pub(super) fn bring_up(
    options: bed::Options,
    addrs: &[u16],
    actuators: Vec<live_plant::Actuator>,
    out: &mut dyn Write,
) -> Result<Bed, NetError> {
    let mut bed = Bed::start(options)?;
    demo_report::say(
        out,
        &format!(
            "medium on {}; starting {} unconfigured node(s)",
            bed.medium().addr(),
            addrs.len()
        ),
    );
    for a in addrs {
        bed.start_node(*a)?;
    }
    bed.set_plant(actuators)?;
    for (addr, a) in &bed.wait_for_nodes(addrs)? {
        let role = if a.role.is_empty() {
            "unconfigured"
        } else {
            a.role.as_str()
        };
        demo_report::say(
            out,
            &format!("  node {addr:#06x}: firmware {}, {role}", a.firmware),
        );
    }
    Ok(bed)
}

/// Pushes every role of `robot`; says how each push went. `false` if one failed.
pub(super) fn push_robot(
    bed: &mut Bed,
    label: &Path,
    robot: &Compiled,
    out: &mut dyn Write,
) -> Result<bool, NetError> {
    demo_report::say(
        out,
        &format!(
            "pushing {} (generation {})",
            label.display(),
            robot.ir.generation
        ),
    );
    let pushed = bed.push(robot, false, &mut |_, _, _| {})?;
    for o in &pushed {
        demo_report::say(out, &demo_report::push_line(o));
    }
    let mut ok = true;
    for o in pushed.iter().filter(|o| o.progress != Progress::Done) {
        demo_report::say(
            out,
            &format!(
                "push FAILED: role {} at node {:#06x}: {}",
                o.role,
                o.addr,
                o.verdict()
            ),
        );
        ok = false;
    }
    Ok(ok)
}

/// Homes `robot` when a node is not homed (the first push to unconfigured nodes; a push
/// at the idle point leaves the machine homed); says what happened. `false` if homing
/// did not end with every chart idle.
fn home_robot(bed: &mut Bed, robot: &Compiled, out: &mut dyn Write) -> Result<bool, NetError> {
    let before = bed.statuses(robot)?;
    let nodes = home::nodes(robot, &before);
    if nodes.iter().all(|n| n.standing == home::Standing::Homed) {
        demo_report::say(out, "homed already: the tables switched at the idle point");
        return Ok(true);
    }
    let homing = bed.home_from(robot, &before, &mut || {
        demo_report::say(out, &demo_report::homing_line(robot))
    })?;
    demo_report::say(out, &demo_report::homed_line(&homing));
    Ok(homing.end == home::HomeEnd::Homed)
}

/// Runs `n` cycles of `robot`, each step printed as it happens (stderr) and each cycle's
/// verdict (`out`); with `count_dir`, the instructions the QEMU nodes executed.
fn run_cycles(
    bed: &mut Bed,
    robot: &Compiled,
    n: usize,
    activated: Instant,
    count_dir: Option<&Path>,
    addrs: &[u16],
    out: &mut dyn Write,
) -> Result<Verdict, NetError> {
    let expect: Vec<String> = robot.ir.expect.iter().map(|s| s.to_string()).collect();
    demo_report::say(out, &format!("sequence: {}", expect.join(" ")));
    let counted = count_dir.map(|dir| (dir, qemu::settled_counts(dir, addrs)));
    let mut first_motion = None;
    for i in 1..=n {
        let cycle = bed.run_cycle(robot, &mut |s, at| {
            if s.moved {
                first_motion.get_or_insert_with(|| activated.elapsed());
            }
            let jammed = if s.moved { "" } else { "  (jammed: no motion)" };
            let _ = writeln!(io::stderr(), "  {:>7.3} s  {s}{jammed}", at.as_secs_f64());
        })?;
        demo_report::say(out, &demo_report::cycle_line(i, &cycle));
        if let (1, Some(t), None) = (i, first_motion, &counted) {
            demo_report::say(
                out,
                &format!(
                    "first motion of the cycle {:.1} ms after the last table was activated \
                     (homing, if it ran, and START included)",
                    t.as_secs_f64() * 1e3
                ),
            );
        }
        if !cycle.ok() {
            return Ok(if cycle.fault.is_some() {
                Verdict::Faulted
            } else {
                Verdict::Mismatch
            });
        }
    }
    if let Some((dir, before)) = counted {
        let after = qemu::settled_counts(dir, addrs);
        let aes = addrs.iter().find_map(|a| qemu::read_aes_cost(dir, *a));
        for line in qemu::count_lines(addrs, &before, &after, n, aes) {
            demo_report::say(out, &line);
        }
        for line in qemu::security_cost_lines(dir, addrs) {
            demo_report::say(out, &line);
        }
    }
    Ok(Verdict::Matched)
}

/// The medium's totals and the verdict in words; stops the bed.
fn finish(bed: Bed, verdict: Verdict, out: &mut dyn Write) -> Result<(), NetError> {
    finish_as(
        bed,
        verdict,
        "demo: every cycle matched",
        "demo: FAILED (sequence mismatch)",
        out,
    )
}

/// [`finish`] of a sorting station's demo.
pub(super) fn finish_with(bed: Bed, verdict: Verdict, out: &mut dyn Write) -> Result<(), NetError> {
    finish_as(
        bed,
        verdict,
        "demo: every ball sorted into sim's bin",
        "demo: FAILED (bins differ from sim's)",
        out,
    )
}

/// [`finish`], saying `matched` or `mismatch` for those verdicts; an error if the
/// medium's capture (`--pcap`) could not be written whole.
pub(super) fn finish_as(
    bed: Bed,
    verdict: Verdict,
    matched: &str,
    mismatch: &str,
    out: &mut dyn Write,
) -> Result<(), NetError> {
    let s = bed.medium().stats();
    demo_report::say(
        out,
        &format!(
            "medium: {} frames, {:.1} ms airtime, {} lost, {} duplicated",
            s.frames,
            s.airtime_us as f64 / 1e3,
            s.lost,
            s.duplicated
        ),
    );
    bed.stop();
    demo_report::say(
        out,
        match verdict {
            Verdict::Matched => matched,
            Verdict::PushFailed => "demo: FAILED (push)",
            Verdict::Mismatch => mismatch,
            Verdict::Faulted => "demo: FAULTED",
        },
    );
    // A capture cut short fails a demo that passed; one that failed keeps its verdict's
    // status, the capture said beside it.
    let pcap = match (s.pcap_unwritten, s.pcap_error) {
        (0, _) => return Ok(()),
        (unwritten, why) => NetError::Pcap {
            unwritten,
            why: why.unwrap_or(std::io::ErrorKind::Other),
        },
    };
    if verdict == Verdict::Matched {
        return Err(pcap);
    }
    demo_report::say(out, &format!("demo: {pcap}"));
    Ok(())
}
