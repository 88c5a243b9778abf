//! IEC 61499 import, printed: the import time of each type of the event FB library
//! (`.fbt` -> chart type), of an application per 100 FB instances (a generated `.sys` of
//! chained E_CTUs on four devices -> the robot's roles and charts; at 100, 400 and 1600
//! instances, with the ratio to the figure at 100), and the table bytes of
//! each library type (one instance on one node, compiled).
//!
//!     cargo bench -p robot-compiler --bench iec61499

mod support;

use std::hint::black_box;

use support::time;

use robot_compiler::iec61499::{app::LIBRARY, fbt, import_with};
use robot_compiler::{compile, model, Source};

/// A system of `n` E_CTUs, each counting the one before, spread over four devices.
fn chain(n: usize) -> String {
    let mut fbs = String::new();
    let mut conns = String::new();
    let mut maps = String::new();
    for i in 0..n {
        fbs += &format!(
            "      <FB Name=\"c{i}\" Type=\"E_CTU\"><Parameter Name=\"PV\" Value=\"3\"/></FB>\n"
        );
        if i > 0 {
            conns += &format!(
                "        <Connection Source=\"c{}.CUO\" Destination=\"c{i}.CU\"/>\n",
                i - 1
            );
        }
        maps += &format!(
            "  <Mapping From=\"App.c{i}\" To=\"n{}.R{}\"/>\n",
            i % 4,
            i % 4
        );
    }
    let devices: String = (0..4)
        .map(|d| format!("  <Device Name=\"n{d}\"><Resource Name=\"R{d}\"/></Device>\n"))
        .collect();
    format!(
        "<?xml version=\"1.0\"?>\n<System Name=\"S\">\n  <Application Name=\"App\">\n    \
         <SubAppNetwork>\n{fbs}      <EventConnections>\n{conns}      </EventConnections>\n    \
         </SubAppNetwork>\n  </Application>\n{devices}{maps}</System>\n"
    )
}

const ROBOT: &str = "Robot(name: \"b\", network: (pan_id: 1, channel: 11),
    nodes: [(name: \"n0\", address: 1), (name: \"n1\", address: 2), (name: \"n2\", address: 3), (name: \"n3\", address: 4)],
    roles: [], application: (file: \"a.sys\"))";

fn main() {
    println!("import of each library type (.fbt -> chart type):");
    for (name, text) in LIBRARY {
        let s = time(200, || {
            black_box(fbt::import_typed(black_box(text)).expect("imports"));
        });
        println!("  {name:<10} {:>8.1} us", s * 1e6);
    }
    println!("import of an application (.sys -> roles and charts):");
    let src = Source::new("b.ron", ROBOT);
    // Per 100 FB instances, and its ratio to the figure at 100: flat when the import
    // scales linearly.
    let mut at_100 = None;
    for n in [100, 400, 1600] {
        let sys = chain(n).into_bytes();
        let read = |_: &str| Ok(sys.clone());
        let s = time(5, || {
            let mut robot = model::parse(&src).expect("parses");
            let d = import_with(&mut robot, &src, &read);
            assert!(d.is_empty(), "{d:?}");
            black_box(robot);
        });
        let per_100 = s * 1e3 * 100.0 / n as f64;
        let base = *at_100.get_or_insert(per_100);
        println!(
            "  {n:>4} FB instances  {:>8.2} ms  ({per_100:.2} ms per 100 FB instances, {:.2}x the \
             figure at 100)",
            s * 1e3,
            per_100 / base
        );
    }
    println!("table bytes of each library type (one instance on one node):");
    let dir = std::env::temp_dir().join(format!("iec61499-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    for (name, _) in LIBRARY {
        let sys = format!(
            "<System Name=\"S\"><Application Name=\"App\"><SubAppNetwork><FB Name=\"f\" \
             Type=\"{name}\"/></SubAppNetwork></Application><Device Name=\"n0\"><Resource \
             Name=\"R\"/></Device><Mapping From=\"App.f\" To=\"n0.R\"/></System>"
        );
        std::fs::write(dir.join("a.sys"), sys).expect("writes");
        let src = Source::new(dir.join("b.ron").to_string_lossy().as_ref(), ROBOT);
        match compile(&src) {
            Ok(c) => println!("  {name:<10} {:>5} bytes", c.blobs[0].len()),
            Err(d) => println!(
                "  {name:<10} does not compile: {:?}",
                d.first().map(|d| &d.message)
            ),
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
