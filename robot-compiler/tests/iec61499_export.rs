//! The export to IEC 61499-2 XML (`config-tool export-4diac`): every file it writes for
//! the robots of `robot-configs/` meets the element structure of the standard; each
//! chart type comes back through the `.fbt` import; the system's FBs, connections and
//! mapping are the robot's.

mod support;

use std::path::Path;

use robot_compiler::expr::{Ast, BinOp};
use robot_compiler::iec61499::export::{self, lift::print, Export};
use robot_compiler::iec61499::fbt::import;
use robot_compiler::model::{ActionDecl, ChartType};
use robot_compiler::{compile, Source};
use support::schema::validate;
use test_tables::robots::{compiled, exported, robots};

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

/// The schema check finds a required attribute missing, an attribute not allowed, an
/// unknown element, a child not allowed, a child too few times and one out of order,
/// each at its line:col.
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
    let broken = good.replace("<FBType Name=", "<FBType Bogus=\"1\" Name=");
    let row = line_of(&broken, "<FBType ");
    assert_eq!(
        validate(&broken),
        Err(format!(
            "{row}:1: `FBType`: attribute `Bogus` is not allowed"
        ))
    );
    let broken = good.replace("</ECC>", "  <ECState Name=\"LATE\"/>\n    </ECC>");
    let row = line_of(&broken, "<ECC>");
    assert_eq!(
        validate(&broken),
        Err(format!("{row}:5: `ECC`: `ECState` is out of order"))
    );
    let broken = good.replace("<InterfaceList>", "<InterfaceList Comment=\"\">");
    let row = line_of(&broken, "<InterfaceList");
    assert_eq!(
        validate(&broken),
        Err(format!(
            "{row}:3: `InterfaceList`: attribute `Comment` is not allowed"
        ))
    );
    assert_eq!(
        validate(&good.replace("<BasicFB>", "<BasicFB>\n<DataConnections/>")),
        Err(format!(
            "{}:3: `BasicFB`: `DataConnections` is not allowed inside",
            line_of(good, "<BasicFB>")
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
    // Where a type came from is no part of it.
    t.imported = None;
    t.written = None;
    t.specializes = None;
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

/// Robot `src` (compiled: `c`) compiled again with each of its chart types imported from
/// its `.fbt` of export `e` instead (written to a directory of its own, then removed).
fn through_fbt(
    src: &Source,
    c: &robot_compiler::Compiled,
    e: &Export,
) -> Result<robot_compiler::Compiled, Vec<robot_compiler::diag::Diagnostic>> {
    let dir = std::env::temp_dir().join(format!(
        "export-round-trip-{}-{}",
        std::process::id(),
        c.ir.name
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let names: Vec<String> = (c.robot.chart_types.iter())
        .map(|t| format!("{}.fbt", t.name))
        .collect();
    for n in &names {
        std::fs::write(dir.join(n), file(e, n)).unwrap();
    }
    let robot = dir.join("robot.ron");
    let again = Source::new(robot.display().to_string(), with_fb_types(src, &names));
    let back = compile(&again);
    std::fs::remove_dir_all(&dir).unwrap();
    back
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
        let back = through_fbt(&src, &c, &exported(&c));
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

/// A chart type whose guard reads its role's input (`A.home`, which robot-format.md
/// allows) is exported with that level as a BOOL input variable marked `level of A.home`,
/// and comes back through the `.fbt` import to the same tables. The export refused it
/// (`unknown name `A.home``).
#[test]
fn a_chart_type_reading_a_role_input_round_trips_to_the_same_tables() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/small-charts.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("count < M || true"));
    let text = text.replace("count < M || true", "count < M || A.home");
    let src = Source::new("reads-input.ron", text);
    let c = compile(&src).unwrap_or_else(|d| panic!("{d:?}"));
    let e = exported(&c);
    let mover = file(&e, "Mover.fbt");
    assert!(
        mover.contains(
            "<VarDeclaration Name=\"A_home\" Type=\"BOOL\" Comment=\"level of A.home\"/>"
        ),
        "{mover}"
    );
    assert!(mover.contains("OR A_home"), "{mover}");
    let back = through_fbt(&src, &c, &e).unwrap_or_else(|d| panic!("{d:?}"));
    let dumps = |c: &robot_compiler::Compiled| -> Vec<String> {
        let d = |b: &Vec<u8>| robot_compiler::dump::dump(b).unwrap();
        c.blobs.iter().map(d).collect()
    };
    // (Its `when: "true"` came back `1 != 0` while the export wrote `(1 <> 0)`.)
    assert_eq!(dumps(&back), dumps(&c));
    assert_eq!(back.blobs, c.blobs);
}

/// A control function named `IO` on role CABINET: its lifted chart's type and FB are
/// named apart from the role's service FB and type `CABINET_IO`. Both were
/// `CABINET_IO`: the export refused the robot ("two files would be named
/// `CABINET_IO.fbt`"), at no place.
#[test]
fn a_chart_named_like_its_roles_service_fb_is_named_apart() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../robot-configs/waterjet-transport.ron");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("Operation", "IO");
    let src = Source::new("io.ron", text);
    let c = compile(&src).unwrap_or_else(|d| panic!("{d:?}"));
    let e = exported(&c);
    let mut names: Vec<&str> = e.files.iter().map(|(n, _)| n.as_str()).collect();
    names.sort();
    let count = names.len();
    names.dedup();
    assert_eq!(names.len(), count, "{names:?}");
    assert!(names.contains(&"CABINET_IO.fbt") && names.contains(&"CABINET_IO_2.fbt"));
    for (name, text) in &e.files {
        if let Err(e) = validate(text) {
            panic!("{name}:{e}\n{text}");
        }
    }
    let (fbs, _, _, _) = system(file(&e, &export::sys_file(&c)));
    let mut fb_names: Vec<&str> = fbs.iter().map(|(n, _)| n.as_str()).collect();
    fb_names.sort();
    let count = fb_names.len();
    fb_names.dedup();
    assert_eq!(fb_names.len(), count, "{fbs:?}");
    assert!(fbs.contains(&(String::from("CABINET_IO"), String::from("CABINET_IO"))));
    assert!(fbs.contains(&(String::from("CABINET_IO_2"), String::from("CABINET_IO_2"))));
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

/// The exported system is the robot: an FB per chart (of its exported type), the
/// E_MERGEs joining the sources of the inputs several events feed, and a service FB per
/// role, each mapped to the resource of its role on the device of the role's node; every
/// chart input fed by one connection, from as many sources (through the E_MERGEs) as the
/// robot routes to it, each peer's event of one it subscribes from several counted.
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
        let merges: Vec<String> = (fbs.iter())
            .filter(|(_, ty)| ty == "E_MERGE")
            .map(|(n, _)| n.clone())
            .collect();
        want.extend(merges.iter().map(|m| (m.clone(), String::from("E_MERGE"))));
        for ri in 0..c.ir.roles.len() {
            let io = export::sys::io_name(&c, ri);
            want.push((io.clone(), io));
        }
        assert_eq!(fbs, want, "{}", path.display());
        // The chart an E_MERGE's chain ends in.
        let chart_of = |m: &str| -> Option<usize> {
            let mut at = m.to_string();
            for _ in 0..=merges.len() {
                let (_, d) = conns.iter().find(|(s, _)| *s == format!("{at}.EO"))?;
                let fb = d.split_once('.')?.0;
                if !merges.iter().any(|x| x == fb) {
                    return e.instances.iter().find(|i| i.name == fb).map(|i| i.role);
                }
                at = fb.to_string();
            }
            None
        };
        for m in &merges {
            assert!(chart_of(m).is_some(), "{}: {m}", path.display());
        }
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
                        || (merges.contains(name) && chart_of(name) == Some(ri))
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
                // A source per event routed to the input, or one per peer's event it
                // stands for (a peer's fault, subscribed from each other node).
                let routed: usize = r
                    .routes
                    .iter()
                    .filter(|(_, ch, x)| *ch == i.chart && *x == k)
                    .map(|(e, _, _)| {
                        let imports = r.imports.iter().filter(|(_, _, l)| l == e).count();
                        imports.max(1)
                    })
                    .sum();
                let dest = format!("{}.{input}", i.name);
                let direct = conns.iter().filter(|(_, d)| *d == dest).count();
                assert!(direct <= 1, "{}: {dest}", path.display());
                fn sources(conns: &[(String, String)], merges: &[String], d: &str) -> usize {
                    (conns.iter().filter(|(_, x)| x == d))
                        .map(|(s, _)| match s.strip_suffix(".EO") {
                            Some(m) if merges.iter().any(|x| x == m) => {
                                sources(conns, merges, &format!("{m}.EI1"))
                                    + sources(conns, merges, &format!("{m}.EI2"))
                            }
                            _ => 1,
                        })
                        .sum()
                }
                let fed = sources(&conns, &merges, &dest);
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

/// A lifted chart that reads another chart's variable says which, in the export's
/// vocabulary: the water-jet transport's `Transport` reads the operator's place
/// (`Operation.state`) and the places the cabinet has seen of the other nodes' functions
/// (`Pusher.state`, kept by the `Pusher.seen` chart) as input variables `value of` the
/// FB and its variable, which the import reads again instead of a constant.
#[test]
fn a_lifted_chart_reading_another_charts_variable_says_whose() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../robot-configs/waterjet-transport.ron");
    let (_, c) = compiled(&path);
    let e = exported(&c);
    let fbt = file(&e, "CABINET_Transport.fbt");
    let inputs: Vec<&str> = (fbt.lines())
        .skip_while(|l| !l.contains("<InputVars>"))
        .take_while(|l| !l.contains("</InputVars>"))
        .skip(1)
        .map(str::trim)
        .collect();
    assert_eq!(
        inputs,
        [
            "<VarDeclaration Name=\"Operation_state\" Type=\"DINT\" \
             Comment=\"value of CABINET_Operation.Operation_state\"/>",
            "<VarDeclaration Name=\"Pusher_state\" Type=\"DINT\" \
             Comment=\"value of CABINET_Pusher_seen.Pusher_state\"/>",
            "<VarDeclaration Name=\"Belt_state\" Type=\"DINT\" \
             Comment=\"value of CABINET_Belt_seen.Belt_state\"/>",
            "<VarDeclaration Name=\"FaultDetection_state\" Type=\"DINT\" \
             Comment=\"value of CABINET_FaultDetection_seen.FaultDetection_state\"/>",
        ]
    );
}

/// Variables named as IEC 61131-3 keywords (`time`, `step`) are exported renamed, as
/// a clash with another name is (a keyword is no identifier: the ST would not parse),
/// and a character XML 1.0 does not allow (a control character in the robot's name) is
/// not written (the file was not well formed); the tables come back the same.
#[test]
fn keywords_and_characters_xml_forbids_are_not_written_as_they_are() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../robot-configs/paint-robot-counted.ron");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("\"dips", "\"time")
        .replace("\"seen", "\"step")
        .replace("(dips", "(time")
        .replace(" dips ", " time ")
        .replace(" seen ", " step ")
        .replacen("\"paint-robot-counted\"", "\"paint\\u{1}robot\"", 1);
    let c = compile(&Source::new("keywords.ron", text)).unwrap_or_else(|d| panic!("{d:?}"));
    let e = exported(&c);
    for (name, text) in &e.files {
        let opt = roxmltree::ParsingOptions {
            allow_dtd: true,
            ..roxmltree::ParsingOptions::default()
        };
        if let Err(err) = roxmltree::Document::parse_with_options(text, opt) {
            panic!("{name}: {err}\n{text}");
        }
        assert!(!text.contains('\u{1}'), "{name}");
    }
    let all: String = e.files.iter().map(|(_, t)| t.as_str()).collect();
    assert!(all.contains("time_V := (time_V + 1)"), "{all}");
    assert!(all.contains("step_V := (step_V + 1)"), "{all}");
    assert!(!all.contains("time :="), "{all}");
}
