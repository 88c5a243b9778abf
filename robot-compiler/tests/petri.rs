//! `check`, compilation and the matrix export of control functions (docs/petri-nets.md):
//! one broken robot per kind of problem (tests/fixtures/broken/petri-*), each asserting
//! the exact messages with their line:col; the good robot checks clean and compiles to
//! one chart per function; a function read across the radio becomes a publication with
//! its delay; the matrices are exactly the paper's objects.

use robot_compiler::check::check;
use robot_compiler::petri::{self, check::publication_lines, matrix};
use robot_compiler::Source;

fn fixture(path: &str) -> Source {
    let full = format!("{}/../tests/fixtures/{path}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&full).unwrap_or_else(|e| panic!("{full}: {e}"));
    Source::new(path, text)
}

/// `line:col: severity: message` of every diagnostic of a file.
fn diagnostics(src: &Source) -> Vec<String> {
    check(src)
        .diagnostics
        .iter()
        .map(|d| {
            let (line, col) = d.line_col(src);
            let sev = if d.is_error() { "error" } else { "warning" };
            format!("{line}:{col}: {sev}: {}", d.message)
        })
        .collect()
}

/// (file, every diagnostic as `line:col: severity: message`).
const BROKEN: &[(&str, &[&str])] = &[
    // `check` said ok; the node faulted at the first edge of A (`Cascade`).
    ("petri-cascade.ron", &[
        "9:20: warning: event `A` of role `R` may set off a cascade of 64 events its charts emit, or more (a cycle: charts that react to each other's events): a node that runs that long faults (`Cascade`); `verify` says whether it can",
    ]),
    ("petri-choice.ron", &[
        "32:17: warning: transitions `start` and `skip` of function `Transport` both leave `ReadyToCut` on `START` under conditions that can both hold: the choice rule fires `start`, declared first",
    ]),
    ("petri-dead.ron", &[
        "35:17: warning: transition `never` of function `Transport` can never fire: its condition `FAULT && !FAULT` never holds in `Step2`",
        "36:17: warning: transition `shadowed` of function `Transport` can never fire: `abort`, declared before it, leaves `Step2` on `FAULT` whenever it is enabled (the choice rule takes the first declared)",
    ]),
    ("petri-marking-huge.ron", &[
        "50:30: error: m(0) of function `Pusher` puts 2147483647 tokens in a place: a state machine's place holds 0 or 1 (one entry 1, the others 0)",
    ]),
    ("petri-marking-negative.ron", &[
        "50:33: error: m(0) of function `Pusher` puts -1 tokens in a place: a state machine's place holds 0 or 1 (one entry 1, the others 0)",
    ]),
    ("petri-rest.ron", &[
        "27:20: error: unknown place `Step9`",
    ]),
    ("petri-row.ron", &[
        "46:59: error: row `release` of M of function `Pusher` has 1 entries -1 and 2 entries 1: a state machine's row has exactly one -1 (its precondition) and one 1 (its result)",
    ]),
    // `check` took it; the timed place was left at once (its entry and the timer's expiry
    // one event), and other functions took the expiry for the place's entry.
    ("petri-timer-place.ron", &[
        "26:22: error: timer `Step2` of function `Transport` is named as one of its places: `Transport.Step2` would be both the place's entry and the timer's expiry",
    ]),
    ("petri-two-tokens.ron", &[
        "50:26: error: m(0) of function `Pusher` holds 2 tokens: a state machine holds exactly one (one entry 1, the others 0)",
    ]),
    ("petri-unknown-event.ron", &["31:39: error: function `Pusher` has no place `Forward`"]),
    ("petri-unknown-place.ron", &[
        "30:25: error: function `Pusher` has no place `Stoped`",
        "30:58: error: unknown name `FAUL`: not a place of a function (`FUNCTION.PLACE`) nor an input of role `CELL`",
    ]),
    ("petri-unreachable.ron", &[
        "26:63: warning: place `Cleaning` of function `Transport` is unreachable from its initial place `ReadyToCut`",
        "35:17: warning: transition `cleaned` of function `Transport` can never fire: its place `Cleaning` is unreachable",
    ]),
];

#[test]
fn each_broken_net_gives_exactly_its_diagnostics() {
    for (file, expected) in BROKEN {
        let got = diagnostics(&fixture(&format!("broken/{file}")));
        assert_eq!(got, *expected, "{file}");
    }
}

#[test]
fn every_broken_net_is_in_the_table() {
    let dir = format!("{}/../tests/fixtures/broken", env!("CARGO_MANIFEST_DIR"));
    let mut on_disk: Vec<String> = std::fs::read_dir(dir)
        .expect("fixtures/broken")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|f| f.starts_with("petri-"))
        .collect();
    on_disk.sort();
    let listed: Vec<&str> = BROKEN.iter().map(|(f, _)| *f).collect();
    assert_eq!(on_disk, listed);
}

#[test]
fn the_good_nets_check_clean() {
    for file in ["petri.ron", "petri-two-roles.ron"] {
        assert_eq!(diagnostics(&fixture(file)), Vec::<String>::new(), "{file}");
    }
}

/// Names of a role's charts and of each chart's states.
fn charts(c: &robot_compiler::Compiled, role: usize) -> Vec<(String, Vec<String>)> {
    c.ir.roles[role]
        .charts
        .iter()
        .map(|ch| {
            (
                ch.name.clone(),
                ch.states.iter().map(|s| s.name.clone()).collect(),
            )
        })
        .collect()
}

fn names(items: &[&str]) -> Vec<String> {
    items.iter().map(|s| s.to_string()).collect()
}

/// A function's `rest` places are its chart's resting states besides the initial one
/// (`Chart::rests`, a bit each), the initial and places named twice left out; the chart
/// that follows it on another role rests where it does (`other` for places it does not
/// read).
#[test]
fn a_functions_resting_places_are_its_charts_resting_states() {
    let mut src = fixture("petri.ron");
    let text = src.text.replace(
        "initial: \"ReadyToCut\",",
        "initial: \"ReadyToCut\", rest: [\"Step3\", \"ReadyToCut\", \"Step1\", \"Step3\"],",
    );
    src = Source::new("petri.ron", text);
    let c = robot_compiler::compile(&src).expect("compiles");
    let transport = c.ir.roles[0]
        .charts
        .iter()
        .position(|ch| ch.name == "Transport");
    let transport = transport.expect("Transport's chart");
    assert_eq!(c.ir.roles[0].charts[transport].rests, [3, 1]);
    let chart = c.tables[0].charts[transport];
    assert_eq!((chart.idle, chart.rests), (0, 0b1010));
    assert_eq!(
        (0..4).map(|s| chart.rests_in(s)).collect::<Vec<_>>(),
        [true, true, false, true]
    );
    // Across roles: the cell reads only the pusher's `Stopped` (its `Pusher.seen` chart:
    // `Stopped`, `other`), so the pusher resting in `CounterClockwise` rests in `other`.
    let two = fixture("petri-two-roles.ron");
    let text = two.text.replace(
        "name: \"Pusher\",\n            role: \"PUSHER\",",
        "name: \"Pusher\",\n            role: \"PUSHER\",\n            rest: [\"CounterClockwise\"],",
    );
    assert_ne!(text, two.text);
    let c = robot_compiler::compile(&Source::new("two.ron", text)).expect("compiles");
    let rests = |role: usize, chart: &str| {
        let ch = c.ir.roles[role]
            .charts
            .iter()
            .position(|ch| ch.name == chart);
        let ch = ch.unwrap_or_else(|| panic!("{chart}"));
        (
            c.ir.roles[role].charts[ch].states.len(),
            c.tables[role].charts[ch].rests,
        )
    };
    assert_eq!(rests(1, "Pusher"), (3, 0b100));
    assert_eq!(rests(0, "Pusher.seen"), (2, 0b10));
}

/// One chart per function, places -> states in column order, rows -> transitions in row
/// order (the choice rule is the ECC's declaration order), each on its event.
#[test]
fn each_function_compiles_to_one_chart() {
    let c = robot_compiler::compile(&fixture("petri.ron")).expect("compiles");
    assert_eq!(
        charts(&c, 0),
        [
            (
                String::from("Transport"),
                names(&["ReadyToCut", "Step1", "Step2", "Step3"])
            ),
            (
                String::from("Pusher"),
                names(&["Stopped", "Clockwise", "CounterClockwise"])
            ),
        ]
    );
    let role = &c.ir.roles[0];
    let pusher = &role.charts[1];
    let rows: Vec<(usize, usize, &str)> = pusher
        .transitions
        .iter()
        .map(|t| {
            (
                t.from,
                t.to,
                pusher.inputs[t.trigger.expect("event")].as_str(),
            )
        })
        .collect();
    assert_eq!(
        rows,
        [
            (0, 1, "Transport.Step1"),
            (1, 0, "PUSHER_END"),
            (1, 0, "FAULT"),
            (0, 2, "RELEASE"),
            (0, 2, "Transport.Step3"),
            (2, 0, "PUSHER_HOME"),
        ]
    );
    // Transport reads Pusher.Stopped on the same role: Pusher keeps `Pusher.state`.
    assert_eq!(role.vars, [(String::from("Pusher.state"), 0)]);
    let guard = &role.charts[0].transitions[0]
        .guard
        .as_ref()
        .expect("guard")
        .0;
    assert_eq!(guard, "Pusher.Stopped && PUSHER_HOME && !FAULT");
    assert!(role.imports.is_empty());
}

/// Across roles: Transport reads Pusher's places through Pusher's published state
/// changes (only those it reads), kept by a `Pusher.seen` chart; `check` says so, with
/// the delay of one radio hop.
#[test]
fn a_place_read_across_the_radio_is_a_publication_with_its_delay() {
    let src = fixture("petri-two-roles.ron");
    let c = robot_compiler::compile(&src).expect("compiles");
    assert_eq!(
        charts(&c, 0),
        [
            (String::from("Pusher.seen"), names(&["Stopped", "other"])),
            (
                String::from("Transport"),
                names(&["ReadyToCut", "Step1", "Step2", "Step3"])
            ),
        ]
    );
    assert_eq!(
        charts(&c, 1),
        [(
            String::from("Pusher"),
            names(&["Stopped", "Clockwise", "CounterClockwise"])
        )]
    );
    let imports: Vec<&str> = c.ir.roles[0]
        .imports
        .iter()
        .map(|(_, _, l)| l.as_str())
        .collect();
    assert_eq!(
        imports,
        [
            "PUSHER/Pusher.Stopped",
            "PUSHER/Pusher.Clockwise",
            "PUSHER/Pusher.CounterClockwise"
        ]
    );
    let nets = petri::load(&c.robot, &src).nets();
    assert_eq!(
        publication_lines(&c.robot, &nets),
        [
            "function Transport (role CELL) publishes Transport.Step1, Transport.Step3 to role PUSHER (events Transport.Step1, Transport.Step3): one radio hop later: 2.47 ms of airtime (at most 8.2 ms on host processes)",
            "function Pusher (role PUSHER) publishes Pusher.Stopped, Pusher.Clockwise, Pusher.CounterClockwise to role CELL (conditions read Pusher.Stopped; events Pusher.Stopped, Pusher.Clockwise): one radio hop later: 2.47 ms of airtime (at most 8.2 ms on host processes)",
        ]
    );
    // On one role nothing crosses the radio.
    let one = fixture("petri.ron");
    let c = robot_compiler::compile(&one).expect("compiles");
    assert!(publication_lines(&c.robot, &petri::load(&c.robot, &one).nets()).is_empty());
}

const PUSHER_MATRIX: &str = "function Pusher on role CELL: 3 places, 6 transitions

M (rows: transitions, columns: places; -1 precondition, 1 result)
  M        Stopped  Clockwise  CounterClockwise
  cw            -1          1                 0
  end            1         -1                 0
  fault          1         -1                 0
  release       -1          0                 1
  back          -1          0                 1
  home           1          0                -1

F (precondition part of M)
  F        Stopped  Clockwise  CounterClockwise
  cw             1          0                 0
  end            0          1                 0
  fault          0          1                 0
  release        1          0                 0
  back           1          0                 0
  home           0          0                 1

m(0) (initial marking)
  m(0)  Stopped  Clockwise  CounterClockwise
              1          0                 0

x (events) and u (conditions), by row of M
  row      x (event)        u (condition)
  cw       Transport.Step1  !FAULT
  end      PUSHER_END       true
  fault    FAULT            true
  release  RELEASE          !PUSHER_HOME && !FAULT
  back     Transport.Step3  true
  home     PUSHER_HOME      true
";

const TRANSPORT_CSV: &str = "function,object,row,x,u,ReadyToCut,Step1,Step2,Step3
Transport,M,start,START,Pusher.Stopped && PUSHER_HOME && !FAULT,-1,1,0,0
Transport,M,pushing,Pusher.Clockwise,true,0,-1,1,0
Transport,M,pushed,PUSHER_END,!FAULT,0,0,-1,1
Transport,M,done,Pusher.Stopped,PUSHER_HOME,1,0,0,-1
Transport,M,abort,FAULT,true,1,0,-1,0
Transport,F,start,START,Pusher.Stopped && PUSHER_HOME && !FAULT,1,0,0,0
Transport,F,pushing,Pusher.Clockwise,true,0,1,0,0
Transport,F,pushed,PUSHER_END,!FAULT,0,0,1,0
Transport,F,done,Pusher.Stopped,PUSHER_HOME,0,0,0,1
Transport,F,abort,FAULT,true,0,0,1,0
Transport,m(0),,,,1,0,0,0
";

/// The matrix export: M, F, m(0), x and u with names on rows and columns; the same as
/// CSV. The matrix form (Pusher) and the place form (Transport) give the same objects.
#[test]
fn the_matrices_are_the_papers_objects() {
    let src = fixture("petri.ron");
    let robot = robot_compiler::model::parse(&src).expect("parses");
    let loaded = petri::load(&robot, &src);
    assert!(loaded.diagnostics.is_empty());
    let nets = loaded.nets();
    assert_eq!(matrix::text(&nets[1]), PUSHER_MATRIX);
    assert_eq!(matrix::csv(&nets[0]), TRANSPORT_CSV);
    assert_eq!(nets[1].incidence()[3], [-1, 0, 1]);
    assert_eq!(nets[0].initial_marking(), [1, 0, 0, 0]);
}
