//! Whole robots through IEC 61499 XML and back: every robot of `robot-configs/` exported
//! (`config-tool export-4diac`) and imported again through its `.sys` and `.fbt` files,
//! compared with the original by its tables or, where the layout differs, by its `sim`
//! run (`robot_analysis::sim`: this test spans the compiler and the simulator, so it
//! lives here rather than with either).

use std::path::Path;

use robot_compiler::iec61499::export::{self, Export};
use robot_compiler::{compile, Compiled, Source};
use test_tables::robots::{compiled, exported, robots};

/// The fields of a robot file that make charts (or bring them), removed from the robot
/// of a round trip: the charts come back through `application` and `fb_types`.
const CHART_FIELDS: [&str; 8] = [
    "chart_types",
    "fb_types",
    "application",
    "sequence",
    "homing",
    "automata",
    "functions",
    "sorting",
];

/// The robot file that brings the export of `src` (its files beside it) back: the
/// original text (nodes, roles' hardware, plants, start, expect, ...) without the fields
/// that make charts and without each role's `charts`, with `fb_types` naming every
/// exported `.fbt` and `application` the `.sys`.
fn reimport_ron(src: &Source, c: &Compiled, e: &Export) -> String {
    let mut paths: Vec<String> = CHART_FIELDS.iter().map(|f| f.to_string()).collect();
    paths.extend((0..c.robot.roles.len()).map(|i| format!("roles[{i}].charts")));
    let mut cuts: Vec<std::ops::Range<usize>> = Vec::new();
    for path in &paths {
        let field = path.rsplit('.').next().unwrap_or(path);
        let key = src.key_span(path);
        if src.slice(key.clone()) != field {
            continue;
        }
        let mut end = src.span(path).end;
        let rest = &src.text[end..];
        let trimmed = rest.trim_start();
        if trimmed.starts_with(',') {
            end += rest.len() - trimmed.len() + 1;
        }
        cuts.push(key.start..end);
    }
    cuts.sort_by_key(|r| std::cmp::Reverse(r.start));
    let mut text = src.text.clone();
    for r in cuts {
        text.replace_range(r, "");
    }
    let close = text.rfind(')').unwrap();
    let types: Vec<String> = (e.files.iter())
        .filter(|(n, _)| n.ends_with(".fbt"))
        .map(|(n, _)| format!("{n:?}"))
        .collect();
    let comma = if text[..close].trim_end().ends_with([',', '(']) {
        ""
    } else {
        ","
    };
    text.insert_str(
        close,
        &format!(
            "{comma}\n    fb_types: [{}],\n    application: (file: {:?}),\n",
            types.join(", "),
            export::sys_file(c)
        ),
    );
    text
}

/// How a re-imported robot compares with the original.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Same {
    /// The same tables, byte for byte.
    Tables,
    /// Other tables, the same `sim` run: per cycle the same actuator steps at the same
    /// virtual times, the same duration, publications and faults ([`SIM_CYCLES`]); and,
    /// for a robot with a `sequence`, the same fault runs ([`fault_runs`]).
    Sim,
}

/// Cycles of the `sim` comparison.
const SIM_CYCLES: usize = 3;

/// A robot's fault runs, for comparing: for each step of `sequence` (the original's: the
/// re-imported robot has none), its actuator stuck at that step (`sim --fault stuck:A@k`), what every node did (each
/// fault and link alarm with its virtual time) and each node's fault and outputs after
/// it. A cycle alone does not show a fault's path: an export that kept one peer of a
/// chart input fed by several (a peer's fault from each of the others) ran the same
/// cycles and stopped only the node that detected a jam.
fn fault_runs(c: &Compiled, sequence: &str) -> Result<Vec<String>, String> {
    let mut out = Vec::new();
    for (k, step) in sequence.split_whitespace().enumerate() {
        let actuator = step.trim_end_matches(['+', '-']);
        let spec = format!("stuck:{actuator}@{}", k + 1);
        let parsed = robot_analysis::inject::parse(&spec).map_err(|e| e.to_string())?;
        let run = robot_analysis::inject::simulate(c, &parsed).map_err(|e| e.to_string())?;
        out.push(format!(
            "{spec}: {:?} then {:?}",
            run.reactions, run.outputs
        ));
    }
    Ok(out)
}

/// A robot's `sim` run, for comparing: per cycle its steps, duration, publications and
/// faults, and every step with its virtual time.
fn sim_run(c: &Compiled) -> Result<(Vec<String>, Vec<String>), String> {
    let r = robot_analysis::sim::simulate_traced(c, SIM_CYCLES).map_err(|e| e.to_string())?;
    let cycles = (r.cycles.iter())
        .map(|x| {
            let steps = robot_analysis::sim::steps_text(&x.steps);
            format!(
                "{steps} in {} ms, {} publications, faults {:?}",
                x.duration_ms, x.publications, x.faults
            )
        })
        .collect();
    let steps = (r.trace.iter())
        .filter(|l| l.contains(" ms  step "))
        .cloned()
        .collect();
    Ok((cycles, steps))
}

/// Compiles the round trip's robot file at a path, from the original's source, compiled
/// robot and export.
type Reimport = dyn Fn(&Path, &Source, &Compiled, &Export) -> Result<Compiled, String>;

/// The full `.sys` round trip: export `robot`, import its `.sys` (with the exported
/// `.fbt` types beside it) with `import`, and compare with the original: the same tables,
/// or else the same `sim` run ([`sim_run`]); anything else is an error.
pub fn sys_reimport_round_trip(robot: &Path, import: &Reimport) -> Result<Same, String> {
    let (src, c) = compiled(robot);
    let e = exported(&c);
    let dir = std::env::temp_dir().join(format!(
        "sys-round-trip-{}-{}",
        std::process::id(),
        c.ir.name
    ));
    std::fs::create_dir_all(&dir).map_err(|x| x.to_string())?;
    for (name, text) in &e.files {
        std::fs::write(dir.join(name), text).map_err(|x| x.to_string())?;
    }
    let back = import(&dir.join("robot.ron"), &src, &c, &e);
    std::fs::remove_dir_all(&dir).map_err(|x| x.to_string())?;
    let back = back?;
    if back.blobs == c.blobs {
        return Ok(Same::Tables);
    }
    let (want, got) = (sim_run(&c)?, sim_run(&back)?);
    if want.0.len() != SIM_CYCLES || want != got {
        return Err(format!(
            "{}: the re-imported robot's tables and sim run differ: {want:?} / {got:?}",
            c.ir.name
        ));
    }
    // Each role's own events, by kind (the boot event unhomes the machine when a node
    // restarts: it came back only from the first of its sources before).
    let own = |x: &Compiled| -> Vec<[bool; 3]> {
        (x.tables.iter())
            .map(|t| [t.start.is_some(), t.home.is_some(), t.boot.is_some()])
            .collect()
    };
    if own(&c) != own(&back) {
        return Err(format!(
            "{}: the re-imported robot's start, home and boot events differ: {:?} / {:?}",
            c.ir.name,
            own(&c),
            own(&back)
        ));
    }
    let sequence = c.robot.sequence.as_deref().unwrap_or("");
    let (want, got) = (fault_runs(&c, sequence)?, fault_runs(&back, sequence)?);
    match (want.iter().zip(&got)).find(|(w, g)| w != g) {
        None => Ok(Same::Sim),
        Some((w, g)) => Err(format!(
            "{}: the re-imported robot's fault runs differ: {w} / {g}",
            c.ir.name
        )),
    }
}

/// Compiles the round trip's robot file (`reimport_ron`) at `path`; its errors as
/// `check` prints them, the file named `robot.ron`.
fn reimport(path: &Path, src: &Source, c: &Compiled, e: &Export) -> Result<Compiled, String> {
    let again = Source::new(path.display().to_string(), reimport_ron(src, c, e));
    compile(&again).map_err(|d| {
        let msgs: Vec<String> = (d.iter())
            .filter(|x| x.is_error())
            .map(|x| {
                x.short(&again)
                    .replace(&path.display().to_string(), "robot.ron")
            })
            .collect();
        msgs.join("\n")
    })
}

/// Every robot of `robot-configs/`, exported and brought back through its `.sys` (a
/// robot file keeping the original's nodes, roles' hardware, plants, start, expect, with
/// `application` and `fb_types` naming the exported files; `reimport_ron`):
///
/// - paint-robot-paper-charts, paint-robot-counted, paint-robot-4diac: the same tables,
///   byte for byte. Their charts are instances of chart types; the FBs are named
///   `ROLE_chart` and the timers `ROLE_chart.T`, but no name is in a table, and the
///   charts, events, variables and timers come back in the same order.
/// - the sequence robots (paint-robot, -double-dip, -spare-node, -start-on-gr): the same
///   `sim` run and fault runs (`Same::Sim`), other tables. A chart input several peers'
///   events feed (a peer's fault from each other node) comes back from its E_MERGE chain
///   (the export kept only the first peer before: a jam stopped one node). The export's vocabulary brings back what
///   their lifted charts share: the role's timer `VC.watchdog` (one timer again, started
///   by the step and homing charts, its expiry read by the fault chart), the node events
///   `boot` and `home`, the input levels the homing guards read, the step chart's idle
///   state. The tables differ in layout only: a chart type's timer is always a chart
///   input, so the step chart gets an input for its watchdog the synthesised one lacks,
///   and the events come in another order.
/// - the ball sorter: the same `sim` run. Several events feed one chart input (each
///   automaton instance's `Out` into `gate.TOOK`, one transition's `OutSet` into another's
///   `Set`): the export joins them with a chain of E_MERGEs, which the import folds back
///   into the input's sources in route order. The tables differ in layout: the routes of
///   the lifted automaton charts come per chart, not in the automaton's delivery order.
/// - the water-jet transport: the same `sim` run. Its alarm's condition
///   (`FaultDetection.Faulted`) resolves again (the `.seen` chart's variable says `places
///   of FaultDetection: ...`), and a lifted chart reading another chart's variable
///   (`Transport` reads `Operation.state`) reads it again: the input variable says `value
///   of CABINET_Operation.Operation_state`. The tables differ in layout: the role's
///   variables come back per chart, in the charts' order, not in the order the control
///   functions' compilation gave them, and a negative constant comes back as `0 - 1`.
///
#[test]
fn every_robot_round_trips_through_its_sys_or_says_why_not() {
    let mut out = Vec::new();
    for path in robots() {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        out.push((name, sys_reimport_round_trip(&path, &reimport)));
    }
    let want: Vec<(&str, Result<Same, String>)> = vec![
        ("ball-sorter", Ok(Same::Sim)),
        ("paint-robot-4diac", Ok(Same::Tables)),
        ("paint-robot-counted", Ok(Same::Tables)),
        ("paint-robot-double-dip", Ok(Same::Sim)),
        ("paint-robot-paper-charts", Ok(Same::Tables)),
        ("paint-robot-spare-node", Ok(Same::Sim)),
        ("paint-robot-start-on-gr", Ok(Same::Sim)),
        ("paint-robot", Ok(Same::Sim)),
        ("waterjet-transport", Ok(Same::Sim)),
    ];
    let got: Vec<(&str, Result<Same, String>)> =
        out.iter().map(|(n, r)| (n.as_str(), r.clone())).collect();
    assert_eq!(got, want);
}
