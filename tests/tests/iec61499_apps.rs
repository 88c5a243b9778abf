//! Small hand-written IEC 61499 applications (`tests/fixtures/4diac/`) brought by a robot
//! file, compiled and run on the simulator: what the import makes of a data connection
//! within a resource and of an E_MERGE chain, seen in the charts, the routes and the
//! `sim` trace.

use std::path::{Path, PathBuf};

use robot_compiler::{compile, Compiled, Source};

fn fixture(dir: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/4diac")
        .join(dir)
}

/// The robot `text`, as a file `robot.ron` of fixture directory `dir`, compiled.
fn compiled(dir: &str, text: &str) -> Compiled {
    let path = fixture(dir).join("robot.ron");
    let src = Source::new(path.display().to_string(), text);
    compile(&src).unwrap_or_else(|d| {
        let msgs: Vec<String> = d.iter().map(|x| x.short(&src)).collect();
        panic!("{dir}: {}", msgs.join("\n"))
    })
}

/// The trace of `cycles` `sim` cycles.
fn trace(c: &Compiled, cycles: usize) -> Vec<String> {
    let r = robot_analysis::sim::simulate_traced(c, cycles).expect("simulates");
    r.trace
}

const DATA: &str = r#"Robot(name: "dc", network: (pan_id: 1, channel: 11),
    nodes: [(name: "n1", address: 1)],
    start: "START",
    roles: [(name: "A", inputs: [(name: "START", pin: 0)], outputs: [(name: "LAMP", pin: 1)])],
    fb_types: ["Lamp.fbt", "Cnt.fbt"],
    application: (file: "app.sys", on: {"cnt.CU": "START"},
                  actions: {"lamp.ON": Out("LAMP", true), "lamp.OFF": Out("LAMP", false)}),
)"#;

/// A data connection into a variable that does not hold every value of its source is
/// refused at the connection (a BOOL given the counter's DINT held 2, and neither
/// `N = TRUE` nor `N = FALSE` held: the machine stalled), as 4diac refuses it; so is a
/// robot file's value of an imported type's parameter its type does not hold.
#[test]
fn a_value_a_variable_cannot_hold_is_refused_where_it_comes_from() {
    let dir = std::env::temp_dir().join(format!("iec-types-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for f in ["Cnt.fbt", "app.sys", "Lamp.fbt"] {
        std::fs::copy(fixture("data-connection").join(f), dir.join(f)).unwrap();
    }
    let errors = |lamp_n: &str, robot: &str| {
        let mut lamp = std::fs::read_to_string(fixture("data-connection").join("Lamp.fbt"))
            .unwrap()
            .replace(
                "Name=\"N\" Type=\"DINT\"",
                &format!("Name=\"N\" Type=\"{lamp_n}\""),
            );
        if lamp_n == "BOOL" {
            lamp = lamp
                .replace("REQ[N &gt;= 2]", "REQ[N = TRUE]")
                .replace("REQ[N &lt; 2]", "REQ[N = FALSE]");
        }
        std::fs::write(dir.join("Lamp.fbt"), lamp).unwrap();
        let src = Source::new(dir.join("robot.ron").display().to_string(), robot);
        let d = compile(&src).err().unwrap_or_default();
        d.iter().map(|x| x.short(&src)).collect::<Vec<_>>()
    };
    let sys = std::fs::read_to_string(dir.join("app.sys")).unwrap();
    let (line, col) = sys
        .lines()
        .enumerate()
        .find_map(|(i, l)| {
            l.find("<Connection Source=\"cnt.CV\"")
                .map(|c| (i + 1, c + 1))
        })
        .expect("the data connection");
    let refused = errors("BOOL", DATA);
    assert_eq!(refused.len(), 1, "{refused:?}");
    assert!(
        refused[0].contains(&format!(
            "app.sys:{line}:{col}: data connection `cnt.CV` -> `lamp.N`: `CV` is DINT and `N` \
             BOOL, which does not hold every value of it"
        )),
        "{refused:?}"
    );
    assert_eq!(errors("UINT", DATA).len(), 1, "DINT into UINT");
    assert!(errors("DINT", DATA).is_empty());
    // A robot file's parameter value of an imported type.
    let ron = r#"Robot(name: "p", network: (pan_id: 1, channel: 11),
    nodes: [(name: "n1", address: 1)], assign: [("A", "n1")], start: "START",
    roles: [(name: "A", inputs: [(name: "START", pin: 0)],
             charts: [(name: "lamp", type: "Lamp", params: {"N": 2}, on: {"REQ": "START"})])],
    fb_types: ["Lamp.fbt"])"#;
    let refused = errors("BOOL", ron);
    assert_eq!(refused.len(), 1, "{refused:?}");
    assert!(
        refused[0].ends_with(
            "parameter `N` of chart `lamp` is BOOL: `2` is not a literal of this variable's type"
        ),
        "{refused:?}"
    );
    let fine = errors("USINT", ron);
    assert!(fine.is_empty(), "{fine:?}");
    let big = ron.replace("\"N\": 2", "\"N\": 70000");
    assert!(errors("UINT", &big)[0].ends_with(
        "parameter `N` of chart `lamp` is UINT: `70000` is out of the variable's range"
    ));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `lamp` (declared first) reads `cnt.CV` by a data connection on their resource: the
/// lamp's parameter `N` is the counter's variable, so the first press (count 1) darkens
/// it and the second (count 2) lights it (a constant 0 never would).
#[test]
fn a_data_connection_within_a_resource_reads_the_sources_variable() {
    let c = compiled("data-connection", DATA);
    let charts: Vec<(&str, Vec<(&str, &str)>)> = (c.robot.roles[0].charts.iter())
        .map(|x| {
            let reads = x.reads.iter().map(|(k, v)| (k.as_str(), v.as_str()));
            (x.name.as_str(), reads.collect())
        })
        .collect();
    assert_eq!(charts, [("lamp", vec![("N", "cnt.CV")]), ("cnt", vec![])]);
    assert!(c.robot.roles[0].charts[0].params.is_empty());
    // What the export cannot write yet, it refuses (rather than a constant coming back).
    assert_eq!(
        robot_compiler::iec61499::export::export(&c, "2026-01-01")
            .err()
            .map(|e| e.to_string()),
        Some(String::from(
            "chart `lamp` of role `A` reads `cnt.CV` into its parameter `N` (a data \
             connection): the export does not write data connections yet"
        ))
    );
    assert_eq!(
        trace(&c, 3),
        [
            "       0 ms  press button #0",
            "       0 ms  node 0 input 0 = 1",
            "       0 ms  node 0 chart 1: S0 -> S1 (transition 4)",
            "       0 ms  node 0 chart 1: S1 -> S0 (transition 5)",
            "       0 ms  node 0 chart 0: S0 -> S2 (transition 1)",
            "       0 ms  node 0 chart 0: S2 -> S0 (transition 3)",
            "      50 ms  node 0 input 0 = 0",
            "      50 ms  press button #0",
            "      50 ms  node 0 input 0 = 1",
            "      50 ms  node 0 chart 1: S0 -> S1 (transition 4)",
            "      50 ms  node 0 chart 1: S1 -> S0 (transition 5)",
            "      50 ms  node 0 chart 0: S0 -> S1 (transition 0)",
            "      50 ms  node 0 output 0 = 1",
            "      50 ms  node 0 chart 0: S1 -> S0 (transition 2)",
            "     100 ms  node 0 input 0 = 0",
            "     100 ms  press button #0",
            "     100 ms  node 0 input 0 = 1",
            "     100 ms  node 0 chart 1: S0 -> S1 (transition 4)",
            "     100 ms  node 0 chart 1: S1 -> S0 (transition 5)",
            "     100 ms  node 0 chart 0: S0 -> S1 (transition 0)",
            "     100 ms  node 0 chart 0: S1 -> S0 (transition 2)",
            "     150 ms  node 0 input 0 = 0",
        ]
    );
}

const MERGE: &str = r#"Robot(name: "merge", network: (pan_id: 1, channel: 11),
    nodes: [(name: "n1", address: 1)],
    start: "START",
    roles: [(name: "A", inputs: [(name: "START", pin: 0)])],
    application: (file: "app.sys", on: {"a.CU": "START", "b.CU": "START.fall", "c.CU": "START"}),
)"#;

/// The chain `a.CUO`, `b.CUO` -> `m1`, `m1.EO`, `c.CUO` -> `m2`, `m2.EO` -> `total.CU`
/// (its connections not in chain order in the file) is folded: no E_MERGE chart is
/// left, and `total.CU` has the three sources in the chain's order (`EI1` before
/// `EI2`, depth first), one route each; a press counts three times: `a` and `c` on
/// START's rise, `b` on its fall.
#[test]
fn an_e_merge_chain_is_folded_into_its_inputs_sources() {
    let c = compiled("merge", MERGE);
    let charts: Vec<String> = (c.robot.roles[0].charts.iter())
        .map(|x| format!("{} {} {:?} {:?}", x.name, x.type_, x.on, x.more))
        .collect();
    assert_eq!(
        charts,
        [
            "a E_CTU {\"CU\": \"START\"} {}",
            "b E_CTU {\"CU\": \"START.fall\"} {}",
            "c E_CTU {\"CU\": \"START\"} {}",
            "total E_CTU {\"CU\": \"a.CUO\"} {\"CU\": [\"b.CUO\", \"c.CUO\"]}",
        ]
    );
    let routes: Vec<(&str, usize, usize)> = (c.ir.roles[0].routes.iter())
        .map(|(e, ch, i)| (e.as_str(), *ch, *i))
        .collect();
    assert_eq!(
        routes,
        [
            ("START", 0, 0),
            ("START.fall", 1, 0),
            ("START", 2, 0),
            ("a.CUO", 3, 0),
            ("b.CUO", 3, 0),
            ("c.CUO", 3, 0),
        ]
    );
    let table = config_schema::decode(&c.blobs[0]).expect("decodes");
    let routes: Vec<(u8, u8, u8)> = (table.routes.iter())
        .map(|r| (r.event, r.chart, r.input))
        .collect();
    assert_eq!(
        routes,
        [
            (0, 0, 0),
            (1, 1, 0),
            (0, 2, 0),
            (2, 3, 0),
            (4, 3, 0),
            (6, 3, 0)
        ]
    );
    assert_eq!(
        trace(&c, 2),
        [
            "       0 ms  press button #0",
            "       0 ms  node 0 input 0 = 1",
            "       0 ms  node 0 chart 0: S0 -> S1 (transition 0)",
            "       0 ms  node 0 chart 0: S1 -> S0 (transition 2)",
            "       0 ms  node 0 chart 2: S0 -> S1 (transition 8)",
            "       0 ms  node 0 chart 2: S1 -> S0 (transition 10)",
            "       0 ms  node 0 chart 3: S0 -> S1 (transition 12)",
            "       0 ms  node 0 chart 3: S1 -> S0 (transition 14)",
            "       0 ms  node 0 chart 3: S0 -> S1 (transition 12)",
            "       0 ms  node 0 chart 3: S1 -> S0 (transition 14)",
            "      50 ms  node 0 input 0 = 0",
            "      50 ms  node 0 chart 1: S0 -> S1 (transition 4)",
            "      50 ms  node 0 chart 1: S1 -> S0 (transition 6)",
            "      50 ms  node 0 chart 3: S0 -> S1 (transition 12)",
            "      50 ms  node 0 chart 3: S1 -> S0 (transition 14)",
            "      50 ms  press button #0",
            "      50 ms  node 0 input 0 = 1",
            "      50 ms  node 0 chart 0: S0 -> S1 (transition 0)",
            "      50 ms  node 0 chart 0: S1 -> S0 (transition 2)",
            "      50 ms  node 0 chart 2: S0 -> S1 (transition 8)",
            "      50 ms  node 0 chart 2: S1 -> S0 (transition 10)",
            "      50 ms  node 0 chart 3: S0 -> S1 (transition 12)",
            "      50 ms  node 0 chart 3: S1 -> S0 (transition 14)",
            "      50 ms  node 0 chart 3: S0 -> S1 (transition 12)",
            "      50 ms  node 0 chart 3: S1 -> S0 (transition 14)",
            "     100 ms  node 0 input 0 = 0",
            "     100 ms  node 0 chart 1: S0 -> S1 (transition 4)",
            "     100 ms  node 0 chart 1: S1 -> S0 (transition 6)",
            "     100 ms  node 0 chart 3: S0 -> S1 (transition 12)",
            "     100 ms  node 0 chart 3: S1 -> S0 (transition 14)",
        ]
    );
}
