//! The export to IEC 61499-2 XML (`config-tool export-4diac`): every file it writes for
//! the robots of `robot-configs/` meets the element structure of the standard; each
//! chart type comes back through the `.fbt` import; the system's FBs, connections and
//! mapping are the robot's.

mod support;

use std::path::{Path, PathBuf};

use robot_compiler::expr::{Ast, BinOp};
use robot_compiler::iec61499::export::{self, lift::print, Export};
use robot_compiler::iec61499::fbt::import;
use robot_compiler::model::{ActionDecl, ChartType};
use robot_compiler::{compile, Compiled, Source};
use support::schema::validate;

const DATE: &str = "2026-01-01";

fn robots() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../robot-configs");
    let mut out: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "ron"))
        .collect();
    out.sort();
    out
}

fn compiled(path: &Path) -> (Source, Compiled) {
    let src = Source::read(path).unwrap();
    let c = compile(&src).unwrap_or_else(|d| panic!("{}: {d:?}", path.display()));
    (src, c)
}

fn exported(c: &Compiled) -> Export {
    export::export(c, DATE).unwrap_or_else(|e| panic!("{}: {e}", c.ir.name))
}

fn file<'a>(e: &'a Export, name: &str) -> &'a str {
    &e.files.iter().find(|(n, _)| n == name).unwrap().1
}

/// Every `.fbt` and `.sys` written for every robot meets the standard's element
/// structure.
#[test]
fn every_exported_file_meets_the_schema() {
    let mut checked = 0;
    for path in robots() {
        let (_, c) = compiled(&path);
        for (name, text) in &exported(&c).files {
            if let Err(e) = validate(text) {
                panic!("{}: {name}:{e}\n{text}", path.display());
            }
            checked += 1;
        }
    }
    assert!(checked > 80, "{checked} files");
}

/// The schema check finds a required attribute missing, an unknown element and
/// elements out of order, each at its line:col.
#[test]
fn the_schema_refuses_a_broken_file() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../robot-configs/paint-robot-paper-charts.ron");
    let (_, c) = compiled(&path);
    let e = exported(&c);
    let good = file(&e, "Gr.fbt");
    assert_eq!(validate(good), Ok(()));
    let line_of = |text: &str, what: &str| text.lines().position(|l| l.contains(what)).unwrap() + 1;
    let broken = good.replace("<ECState Name=\"S0\" ", "<ECState ");
    let row = line_of(&broken, "<ECState Comment=\"Initial State\"");
    assert_eq!(
        validate(&broken),
        Err(format!(
            "{row}:7: `ECState`: the attribute `Name` is required"
        ))
    );
    let broken = good.replace("<InterfaceList>", "<InterfaceList>\n    <Sockets/>");
    let row = line_of(&broken, "<InterfaceList>");
    assert_eq!(
        validate(&broken),
        Err(format!(
            "{row}:3: `InterfaceList`: `Sockets` is not allowed inside"
        ))
    );
    let broken = good.replace(
        "<ECC>",
        "<ECC>\n      <ECTransition Source=\"S0\" Destination=\"S1\" Condition=\"1\"/>",
    );
    let row = line_of(&broken, "<ECC>");
    assert_eq!(
        validate(&broken),
        Err(format!("{row}:5: `ECC`: `ECState` occurs 0 times"))
    );
    let broken = good.replace("<EventOutputs>", "<EventOutputs>\n<Bogus/>");
    let row = line_of(&broken, "<Bogus/>");
    assert_eq!(
        validate(&broken),
        Err(format!(
            "{}:5: `EventOutputs`: `Bogus` is not allowed inside",
            row - 1
        ))
    );
    assert!(validate("<FBType Name=\"T\">")
        .unwrap_err()
        .starts_with("not well formed: "));
}

/// `x != 0` as `x`: an integer where ST needs a BOOL is exported compared with 0 (the
/// same truth value).
fn truth(a: Ast) -> Ast {
    match a {
        Ast::Bin(BinOp::Ne, x, zero) if *zero == Ast::Int(0) => truth(*x),
        Ast::Bin(op, x, y) => Ast::Bin(op, Box::new(truth(*x)), Box::new(truth(*y))),
        Ast::Not(x) => Ast::Not(Box::new(truth(*x))),
        Ast::Neg(x) => Ast::Neg(Box::new(truth(*x))),
        other => other,
    }
}

/// The chart type's expressions in one spelling (every operation in parentheses, a
/// truth value as itself), for comparing a type with its round trip.
fn normal(t: &ChartType) -> String {
    let n = |text: &str| print(&truth(robot_compiler::expr::parse(text).unwrap()));
    let mut t = t.clone();
    for s in &mut t.states {
        for a in &mut s.actions {
            if let ActionDecl::Set(_, text) = a {
                *text = n(text);
            }
        }
    }
    for tr in &mut t.transitions {
        if let Some(g) = &mut tr.when {
            *g = n(g);
        }
    }
    for v in &mut t.vars {
        v.init = n(&v.init);
    }
    format!("{t:#?}")
}

/// Every chart type of every robot, exported and imported back through the `.fbt`
/// import, is the same chart type: the same interface, variables, states with the same
/// actions (the node's services included) and transitions with the same guards.
#[test]
fn every_chart_type_comes_back_through_the_fbt_import() {
    let mut types = 0;
    for path in robots() {
        let (_, c) = compiled(&path);
        let e = exported(&c);
        for t in &e.types {
            let back = import(file(&e, &format!("{}.fbt", t.name)))
                .unwrap_or_else(|x| panic!("{}: {}: {x}", path.display(), t.name));
            let t = export::fbt::rename_clashing_vars(t);
            assert_eq!(normal(&back), normal(&t), "{}: {}", path.display(), t.name);
            types += 1;
        }
    }
    assert!(types > 60, "{types} types");
}

/// The robot's source with its `chart_types` replaced by `fb_types` naming `files`.
fn with_fb_types(src: &Source, files: &[String]) -> String {
    let span = src.span("chart_types");
    let list: Vec<String> = files.iter().map(|f| format!("{f:?}")).collect();
    format!(
        "{}[], fb_types: [{}]{}",
        &src.text[..span.start],
        list.join(", "),
        &src.text[span.end..]
    )
}

/// A robot whose chart types are written in it, compiled again with each type imported
/// from its exported `.fbt` instead: the same tables, byte for byte (paint-robot-counted,
/// paint-robot-paper-charts and the ball sorter's pusher; the ball sorter's automata and
/// classification chart are generated either way). The robots without chart types
/// (synthesised from a sequence, control functions) have nothing to replace: their
/// lifted charts come back in `every_chart_type_comes_back_through_the_fbt_import`.
#[test]
fn explicit_chart_types_round_trip_to_the_same_tables() {
    let mut robots_done = Vec::new();
    for path in robots() {
        let (src, c) = compiled(&path);
        // A robot that brings a 4diac application has no `chart_types` of its own to
        // replace (its types come with the application).
        if c.robot.chart_types.is_empty() || c.robot.application.is_some() {
            continue;
        }
        let e = exported(&c);
        let dir = std::env::temp_dir().join(format!(
            "export-round-trip-{}-{}",
            std::process::id(),
            c.ir.name
        ));
        std::fs::create_dir_all(&dir).unwrap();
        let names: Vec<String> = c
            .robot
            .chart_types
            .iter()
            .map(|t| format!("{}.fbt", t.name))
            .collect();
        for n in &names {
            std::fs::write(dir.join(n), file(&e, n)).unwrap();
        }
        let robot = dir.join("robot.ron");
        let again = Source::new(robot.display().to_string(), with_fb_types(&src, &names));
        let back = compile(&again);
        std::fs::remove_dir_all(&dir).unwrap();
        let back = back.unwrap_or_else(|d| panic!("{}: {d:?}", path.display()));
        assert_eq!(back.blobs, c.blobs, "{}", path.display());
        robots_done.push(c.ir.name.clone());
    }
    assert_eq!(
        robots_done,
        [
            "ball-sorter",
            "paint-robot-counted",
            "paint-robot-paper-charts"
        ]
    );
}

/// The `.sys` of a robot, parsed: (application FBs as (name, type), application
/// connections as (source, destination), mapping as (from, to), resources as
/// (device, resource)).
#[allow(clippy::type_complexity)]
fn system(
    text: &str,
) -> (
    Vec<(String, String)>,
    Vec<(String, String)>,
    Vec<(String, String)>,
    Vec<(String, String)>,
) {
    let options = roxmltree::ParsingOptions {
        allow_dtd: true,
        ..Default::default()
    };
    let doc = roxmltree::Document::parse_with_options(text, options).unwrap();
    let a = |n: roxmltree::Node, k: &str| n.attribute(k).unwrap().to_string();
    let app = doc
        .descendants()
        .find(|n| n.has_tag_name("Application"))
        .unwrap();
    let fbs = app
        .descendants()
        .filter(|n| n.has_tag_name("FB"))
        .map(|n| (a(n, "Name"), a(n, "Type")))
        .collect();
    let conns = app
        .descendants()
        .filter(|n| n.has_tag_name("Connection"))
        .map(|n| (a(n, "Source"), a(n, "Destination")))
        .collect();
    let mapping = doc
        .descendants()
        .filter(|n| n.has_tag_name("Mapping"))
        .map(|n| (a(n, "From"), a(n, "To")))
        .collect();
    let resources = doc
        .descendants()
        .filter(|n| n.has_tag_name("Resource"))
        .map(|n| (a(n.parent().unwrap(), "Name"), a(n, "Name")))
        .collect();
    (fbs, conns, mapping, resources)
}

/// The exported system is the robot: an FB per chart (of its exported type) and a
/// service FB per role, each mapped to the resource of its role on the device of the
/// role's node; every chart input fed by as many connections as the robot routes to it.
/// The paper's charts: exactly the connections the paper draws, the cut ones as
/// PUBLISH / SUBSCRIBE pairs on the resources.
#[test]
fn the_system_has_the_robots_instances_connections_and_mapping() {
    for path in robots() {
        let (_, c) = compiled(&path);
        let e = exported(&c);
        let (fbs, conns, mapping, resources) = system(file(&e, &export::sys_file(&c)));
        let app = format!("{}App", export::fbt::identifier(&c.ir.name));
        let mut want: Vec<(String, String)> = e
            .instances
            .iter()
            .map(|i| (i.name.clone(), i.ty.clone()))
            .collect();
        for ri in 0..c.ir.roles.len() {
            let io = export::sys::io_name(&c, ri);
            want.push((io.clone(), io));
        }
        assert_eq!(fbs, want, "{}", path.display());
        let mut want_mapping = Vec::new();
        let mut want_resources = Vec::new();
        for node in &c.robot.nodes {
            for (ri, r) in c.ir.roles.iter().enumerate() {
                if !c
                    .robot
                    .assign
                    .iter()
                    .any(|(role, n)| *role == r.name && *n == node.name)
                {
                    continue;
                }
                want_resources.push((node.name.replace('-', "_"), r.name.clone()));
                for (name, _) in fbs.iter().filter(|(name, _)| {
                    e.instances.iter().any(|i| i.role == ri && &i.name == name)
                        || *name == export::sys::io_name(&c, ri)
                }) {
                    want_mapping.push((
                        format!("{app}.{name}"),
                        format!("{}.{}.{name}", node.name.replace('-', "_"), r.name),
                    ));
                }
            }
        }
        assert_eq!(resources, want_resources, "{}", path.display());
        assert_eq!(mapping, want_mapping, "{}", path.display());
        for i in &e.instances {
            let r = &c.ir.roles[i.role];
            for (k, input) in i.inputs.iter().enumerate() {
                let routed = r
                    .routes
                    .iter()
                    .filter(|(_, ch, x)| *ch == i.chart && *x == k)
                    .count();
                let dest = format!("{}.{input}", i.name);
                let fed = conns.iter().filter(|(_, d)| *d == dest).count();
                assert_eq!(fed, routed, "{}: {dest}", path.display());
            }
        }
    }
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../robot-configs/paint-robot-paper-charts.ron");
    let (_, c) = compiled(&path);
    let e = exported(&c);
    let sys = file(&e, &export::sys_file(&c));
    let (_, conns, _, _) = system(sys);
    let charts: Vec<String> = conns
        .iter()
        .filter(|(s, d)| !s.contains("_IO.") && !d.contains("_IO."))
        .map(|(s, d)| format!("{s} -> {d}"))
        .collect();
    assert_eq!(
        charts,
        ["GR_gr.GR1 -> VC_vc.GR1", "GR_gr.GR0 -> VC_vc.GR0",]
    );
    let from_io: Vec<String> = conns
        .iter()
        .filter(|(s, _)| s.contains("_IO."))
        .map(|(s, d)| format!("{s} -> {d}"))
        .collect();
    assert_eq!(
        from_io,
        [
            "VC_IO.START -> VC_vc.START",
            "VC_IO.VC_home -> VC_vc.VC0",
            "VC_IO.VC_end -> VC_vc.VC1",
            "HC_IO.HC_end -> VC_vc.HC1",
            "HC_IO.HC_home -> VC_vc.HC0",
            "VC_IO.VC_end -> GR_gr.VC1",
            "GR_IO.gr_T -> GR_gr.T",
            "VC_IO.VC_home -> HC_hc.VC0",
            "RC_IO.RC_home -> HC_hc.RC0",
            "VC_IO.VC_home -> RC_rc.VC0",
            "RC_IO.RC_end -> RC_rc.RC1",
        ]
    );
    // Seven topics cross nodes (GR's two outputs, HC's two switches, VC's two, RC's home
    // switch), each published once; VC subscribes to four, GR to one, HC to two, RC to
    // one.
    assert_eq!(sys.matches("Type=\"PUBLISH_0\"").count(), 7, "{sys}");
    assert_eq!(sys.matches("Type=\"SUBSCRIBE_0\"").count(), 8, "{sys}");
}

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
    /// virtual times, the same duration, publications and faults ([`SIM_CYCLES`]).
    Sim,
}

/// Cycles of the `sim` comparison.
const SIM_CYCLES: usize = 3;

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
    if want.0.len() == SIM_CYCLES && want == got {
        return Ok(Same::Sim);
    }
    Err(format!(
        "{}: the re-imported robot's tables and sim run differ: {want:?} / {got:?}",
        c.ir.name
    ))
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
///   `sim` run (`Same::Sim`), other tables. The export's vocabulary brings back what
///   their lifted charts share: the role's timer `VC.watchdog` (one timer again, started
///   by the step and homing charts, its expiry read by the fault chart), the node events
///   `boot` and `home`, the input levels the homing guards read, the step chart's idle
///   state. The tables differ in layout only: a chart type's timer is always a chart
///   input, so the step chart gets an input for its watchdog the synthesised one lacks,
///   and the events come in another order.
/// - the water-jet transport: its alarm's condition names the places of the control
///   functions (`FaultDetection.Faulted`), which are gone once the functions come back as
///   lifted charts.
/// - the ball sorter: two events feed one chart input (`GATE1_gate.TOOK`, taken from
///   either automaton's accepting chart); the export writes two connections, which the
///   import refuses as it refuses every fan-in (an E_MERGE would say it), and with the
///   application refused the robot has no charts.
///
#[test]
fn every_robot_round_trips_through_its_sys_or_says_why_not() {
    let mut out = Vec::new();
    for path in robots() {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        out.push((name, sys_reimport_round_trip(&path, &reimport)));
    }
    let want: Vec<(&str, Result<Same, String>)> = vec![
        (
            "ball-sorter",
            Err(String::from(
                "robot.ron:32:1: error: the robot has no behaviour
robot.ron:86:25: error: ball_sorter.sys:45:9: `GATE1_gate.TOOK` has a second event \
                 connection: join its sources with an E_MERGE",
            )),
        ),
        ("paint-robot-4diac", Ok(Same::Tables)),
        ("paint-robot-counted", Ok(Same::Tables)),
        ("paint-robot-double-dip", Ok(Same::Sim)),
        ("paint-robot-paper-charts", Ok(Same::Tables)),
        ("paint-robot-spare-node", Ok(Same::Sim)),
        ("paint-robot-start-on-gr", Ok(Same::Sim)),
        ("paint-robot", Ok(Same::Sim)),
        (
            "waterjet-transport",
            Err(String::from(
                "robot.ron:71:22: error: alarm `pusher fault`: `FaultDetection.Faulted` is \
                 neither a function's place (`F.P`) nor an input of role `CABINET`
robot.ron:71:48: error: alarm `pusher fault`: `FaultDetection.Released` is neither a \
                 function's place (`F.P`) nor an input of role `CABINET`",
            )),
        ),
    ];
    let got: Vec<(&str, Result<Same, String>)> =
        out.iter().map(|(n, r)| (n.as_str(), r.clone())).collect();
    assert_eq!(got, want);
}
