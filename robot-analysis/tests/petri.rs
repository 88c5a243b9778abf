//! The compiled charts of control functions, run on the node interpreter from their
//! blobs, go through exactly the places the reference modular logic controller
//! (`robot_analysis::petri`, the paper's algebra on the matrices) computes, event by
//! event: on the hand-written net shaped like the paper's Transport / Pusher functions
//! (a scripted cycle, a fault in step 2, and random streams), and on random nets (random
//! state machines, random events and conditions, one written as its matrix).

use node_fw::ecc::Engine;
use proptest::prelude::*;
use robot_analysis::petri::{Controller, Fired, Occurrence};
use robot_analysis::sim::tables;
use robot_compiler::petri::Net;
use robot_compiler::{Compiled, Source};

fn compile(name: &str, text: &str) -> Compiled {
    robot_compiler::compile(&Source::new(name, text)).unwrap_or_else(|d| panic!("{name}: {d:?}"))
}

fn nets(c: &Compiled, text: &str) -> Vec<Net> {
    let src = Source::new("robot.ron", text);
    robot_compiler::petri::load(&c.robot, &src).nets()
}

/// Runs a stream of input toggles (input index into the role's inputs) on the engine
/// of role 0 and on the controller; after each, every function's place must agree.
/// Returns each step's fired rows as `function.row` names.
fn lockstep(c: &Compiled, nets: &[Net], toggles: &[usize]) -> Vec<Vec<String>> {
    let tables = tables(c).expect("blobs decode");
    let mut engine = Engine::new(&tables[0]);
    let mut reference = Controller::new(nets);
    let role = &c.ir.roles[0];
    let mut levels = vec![false; role.inputs.len()];
    let mut trace = Vec::new();
    let agree = |engine: &Engine, reference: &Controller, at: usize| {
        for (f, net) in nets.iter().enumerate() {
            assert_eq!(
                engine.state(f).map(usize::from),
                reference.place(f),
                "function {} after toggle {at} of {toggles:?}",
                net.name
            );
        }
    };
    agree(&engine, &reference, 0);
    for (k, &i) in toggles.iter().enumerate() {
        levels[i] = !levels[i];
        engine.input(i as u8, levels[i], &mut ());
        assert_eq!(engine.fault(), None, "toggle {k} of {toggles:?}");
        let input = &role.inputs[i].name;
        let event = if levels[i] {
            input.clone()
        } else {
            format!("{input}.fall")
        };
        let lv = levels.clone();
        let level = |name: &str| {
            role.inputs
                .iter()
                .position(|x| x.name == name)
                .map(|p| lv[p])
        };
        let fired = reference
            .occur(
                Occurrence::Role {
                    role: role.name.clone(),
                    event,
                },
                &level,
            )
            .expect("the functions settle");
        trace.push(
            fired
                .iter()
                .map(|Fired { function, row }| {
                    format!(
                        "{}.{}",
                        nets[*function].name, nets[*function].transitions[*row].name
                    )
                })
                .collect(),
        );
        agree(&engine, &reference, k + 1);
    }
    trace
}

const TRANSPORT: &str = include_str!("../../tests/fixtures/petri.ron");

/// Inputs of the fixture's role, by name.
fn input(name: &str) -> usize {
    ["START", "FAULT", "RELEASE", "PUSHER_END", "PUSHER_HOME"]
        .iter()
        .position(|n| *n == name)
        .expect(name)
}

/// A cycle, then the paper's fault in step 2: the pusher stops at once, the operator
/// releases it, it returns home, and after the fault is cleared a cycle completes.
#[test]
fn the_transport_net_and_its_charts_go_through_the_same_places() {
    let c = compile("petri.ron", TRANSPORT);
    let nets = nets(&c, TRANSPORT);
    let script = [
        "PUSHER_HOME", // the pusher is home
        "START",       // Transport: Step1; Pusher: Clockwise; Transport: Step2
        "START",       // (released)
        "PUSHER_HOME", // leaves home
        "PUSHER_END",  // Pusher stops at its end; Transport: Step3; Pusher: back
        "PUSHER_END",  // (leaves the end)
        "PUSHER_HOME", // home: Pusher stopped; Transport: ReadyToCut
        "START",       // the next cycle: Step1, Clockwise, Step2
        "START",
        "PUSHER_HOME", // leaves home
        "FAULT",       // fault in step 2: Pusher stops, Transport aborts
        "RELEASE",     // refused while the fault persists
        "RELEASE",
        "FAULT",       // the fault is cleared
        "RELEASE",     // the operator releases the pusher: back home
        "PUSHER_HOME", // home
        "START",       // restart: a full cycle
        "START",
        "PUSHER_HOME",
        "PUSHER_END",
        "PUSHER_END",
        "PUSHER_HOME",
    ];
    let toggles: Vec<usize> = script.iter().map(|n| input(n)).collect();
    let trace = lockstep(&c, &nets, &toggles);
    let expected: [&[&str]; 22] = [
        &[],
        &["Transport.start", "Pusher.cw", "Transport.pushing"],
        &[],
        &[],
        &["Transport.pushed", "Pusher.end", "Pusher.back"],
        &[],
        &["Pusher.home", "Transport.done"],
        &["Transport.start", "Pusher.cw", "Transport.pushing"],
        &[],
        &[],
        &["Transport.abort", "Pusher.fault"],
        &[],
        &[],
        &[],
        &["Pusher.release"],
        &["Pusher.home"],
        &["Transport.start", "Pusher.cw", "Transport.pushing"],
        &[],
        &[],
        &["Transport.pushed", "Pusher.end", "Pusher.back"],
        &[],
        &["Pusher.home", "Transport.done"],
    ];
    let got: Vec<Vec<&str>> = trace
        .iter()
        .map(|s| s.iter().map(String::as_str).collect())
        .collect();
    assert_eq!(got, expected.map(|s| s.to_vec()));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Random streams on the transport net.
    #[test]
    fn the_transport_net_agrees_on_random_streams(toggles in prop::collection::vec(0usize..5, 0..60)) {
        let c = compile("petri.ron", TRANSPORT);
        let nets = nets(&c, TRANSPORT);
        lockstep(&c, &nets, &toggles);
    }
}

/// A random condition over the inputs `A`, `B`, `C` and the places in `places`.
fn condition(places: Vec<String>) -> impl Strategy<Value = Option<String>> {
    let mut atoms: Vec<String> = ["A", "B", "C"].iter().map(|s| s.to_string()).collect();
    atoms.extend(places);
    let atom = prop::sample::select(atoms);
    let literal = (atom, any::<bool>()).prop_map(|(a, neg)| if neg { format!("!{a}") } else { a });
    prop_oneof![
        Just(None),
        literal.clone().prop_map(Some),
        (literal.clone(), literal.clone(), any::<bool>())
            .prop_map(|(a, b, and)| Some(format!("{a} {} {b}", if and { "&&" } else { "||" }))),
        (literal.clone(), literal.clone(), literal)
            .prop_map(|(a, b, c)| Some(format!("({a} && {b}) || {c}"))),
    ]
}

/// One random transition: (from, to != from, event, condition).
type Row = (usize, usize, String, Option<String>);

fn rows(n: usize, events: Vec<String>, reads: Vec<String>) -> impl Strategy<Value = Vec<Row>> {
    let row = (0..n, 1..n, prop::sample::select(events), condition(reads))
        .prop_map(move |(from, d, e, when)| (from, (from + d) % n, e, when));
    prop::collection::vec(row, 1..8)
}

fn places(name: &str, n: usize) -> Vec<String> {
    (0..n).map(|j| format!("{name}.p{j}")).collect()
}

/// Two random functions on one role: F0 on input edges, F1 also on F0's place changes;
/// each reads both functions' places and the inputs. F1 is written as its matrix.
fn random_robot() -> impl Strategy<Value = String> {
    (2usize..5, 2usize..5).prop_flat_map(|(n0, n1)| {
        let inputs: Vec<String> = ["A", "B", "C"]
            .iter()
            .flat_map(|i| [i.to_string(), format!("{i}.fall")])
            .collect();
        let mut e1 = inputs.clone();
        e1.extend(places("F0", n0));
        let reads: Vec<String> = places("F0", n0)
            .into_iter()
            .chain(places("F1", n1))
            .collect();
        (
            rows(n0, inputs, reads.clone()),
            rows(n1, e1, reads),
            0..n0,
            0..n1,
        )
            .prop_map(move |(r0, r1, i0, i1)| robot_text(n0, &r0, i0, n1, &r1, i1))
    })
}

fn when(w: &Option<String>) -> String {
    w.as_ref()
        .map_or(String::new(), |w| format!(", when: \"{w}\""))
}

fn robot_text(n0: usize, r0: &[Row], i0: usize, n1: usize, r1: &[Row], i1: usize) -> String {
    let places0: Vec<String> = (0..n0).map(|j| format!("\"p{j}\"")).collect();
    let t0: Vec<String> = r0
        .iter()
        .map(|(f, t, e, w)| format!("(on: \"{e}\", from: \"p{f}\", to: \"p{t}\"{})", when(w)))
        .collect();
    let places1: Vec<String> = (0..n1).map(|j| format!("\"p{j}\"")).collect();
    let t1: Vec<String> = r1
        .iter()
        .map(|(f, t, e, w)| {
            let row: Vec<String> = (0..n1)
                .map(|j| (i32::from(j == *t) - i32::from(j == *f)).to_string())
                .collect();
            format!("(on: \"{e}\", row: [{}]{})", row.join(", "), when(w))
        })
        .collect();
    let marking: Vec<String> = (0..n1).map(|j| u8::from(j == i1).to_string()).collect();
    format!(
        r#"Robot(
    name: "random-nets",
    network: (pan_id: 0x0301, channel: 13),
    nodes: [(name: "n1", address: 0x0001)],
    assign: [("R", "n1")],
    roles: [(name: "R", inputs: [(name: "A", pin: 0), (name: "B", pin: 1), (name: "C", pin: 2)])],
    functions: [
        (name: "F0", role: "R", places: [{}], initial: "p{i0}", transitions: [{}]),
        (name: "F1", role: "R", matrix: (places: [{}], rows: [{}], marking: [{}])),
    ],
)"#,
        places0.join(", "),
        t0.join(", "),
        places1.join(", "),
        t1.join(", "),
        marking.join(", "),
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    /// Random nets, random event and condition streams: the charts and the algebra agree
    /// place by place.
    #[test]
    fn random_nets_and_their_charts_go_through_the_same_places(
        text in random_robot(),
        toggles in prop::collection::vec(0usize..3, 0..40),
    ) {
        let c = compile("random.ron", &text);
        let nets = nets(&c, &text);
        prop_assert_eq!(nets.len(), 2);
        lockstep(&c, &nets, &toggles);
    }
}

/// Collects a node's publications (the radio delivers them once its stimulus is done).
#[derive(Default)]
struct Radio(Vec<config_schema::Publication>);

impl node_fw::ecc::Effects for Radio {
    fn publish(&mut self, p: &config_schema::Publication) {
        self.0.push(*p);
    }
}

const TWO_ROLES: &str = include_str!("../../tests/fixtures/petri-two-roles.ron");

/// The same scenario with the pusher on a node of its own: Transport reads Pusher's
/// places through its published place changes (the `Pusher.seen` chart), one hop later.
/// Once every publication has arrived (a radio without loss, in order), both nodes are
/// where the controller is after each input change; both nodes sense the shared sensors,
/// so an edge is an occurrence on each role at once (`occur_all`): the pusher at its end
/// stops on its own node before Transport's Step3 arrives and sends it back.
#[test]
fn across_the_radio_the_charts_reach_the_controllers_places() {
    let c = compile("petri-two-roles.ron", TWO_ROLES);
    let nets = nets(&c, TWO_ROLES);
    let tables = tables(&c).expect("blobs decode");
    let mut engines: Vec<Engine> = tables.iter().map(Engine::new).collect();
    let mut reference = Controller::new(&nets);
    let names = ["START", "FAULT", "RELEASE", "PUSHER_END", "PUSHER_HOME"];
    let mut levels = [false; 5];
    // (role, chart) of each function: Transport after CELL's `Pusher.seen`.
    let charts = [(0, 1), (1, 0)];
    let script = [
        "PUSHER_HOME",
        "START",
        "START",
        "PUSHER_HOME",
        "PUSHER_END",
        "PUSHER_END",
        "PUSHER_HOME",
        "START",
        "START",
        "PUSHER_HOME",
        "FAULT",
        "RELEASE",
        "RELEASE",
        "FAULT",
        "RELEASE",
        "PUSHER_HOME",
        "START",
        "START",
        "PUSHER_HOME",
        "PUSHER_END",
        "PUSHER_END",
        "PUSHER_HOME",
    ];
    let mut hops = 0;
    for (k, name) in script.iter().enumerate() {
        let i = names.iter().position(|n| n == name).expect("input");
        levels[i] = !levels[i];
        let mut pending: Vec<(usize, config_schema::Publication)> = Vec::new();
        for (ri, role) in c.ir.roles.iter().enumerate() {
            if let Some(pin) = role.inputs.iter().position(|x| x.name == *name) {
                let mut radio = Radio::default();
                engines[ri].input(pin as u8, levels[i], &mut radio);
                pending.extend(radio.0.into_iter().map(|p| (ri, p)));
            }
        }
        while !pending.is_empty() {
            let (from, p) = pending.remove(0);
            hops += 1;
            let address = c.ir.roles[from].address;
            for (ri, engine) in engines.iter_mut().enumerate() {
                let Some(peer) = tables[ri].peers.iter().position(|&a| a == address) else {
                    continue;
                };
                let mut radio = Radio::default();
                engine.remote(peer as u8, p.topic, &mut radio);
                pending.extend(radio.0.into_iter().map(|q| (ri, q)));
            }
        }
        let lv = levels;
        let level = |n: &str| names.iter().position(|x| *x == n).map(|p| lv[p]);
        let event = if levels[i] {
            name.to_string()
        } else {
            format!("{name}.fall")
        };
        // The edge happens on every role that senses it, at once.
        let sensed: Vec<Occurrence> = (c.ir.roles.iter())
            .filter(|r| r.inputs.iter().any(|x| x.name == *name))
            .map(|r| Occurrence::Role {
                role: r.name.clone(),
                event: event.clone(),
            })
            .collect();
        reference
            .occur_all(sensed, &level)
            .expect("the functions settle");
        for (f, (ri, ci)) in charts.iter().enumerate() {
            assert_eq!(engines[*ri].fault(), None);
            assert_eq!(
                engines[*ri].state(*ci).map(usize::from),
                reference.place(f),
                "{} after step {k} ({name})",
                nets[f].name
            );
        }
    }
    // A cycle crosses the radio 6 times (Step1, Clockwise, Step3, Stopped at the end,
    // CounterClockwise, Stopped at home); the faulted one 5 (Step1, Clockwise, Stopped
    // on the fault, CounterClockwise on the release, Stopped at home): 6 + 6 + 5.
    assert_eq!(hops, 17);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    /// Damaged function declarations (a range cut out, text spliced in) never panic
    /// `check`, the matrix export or the compilation, every error has a place in the
    /// file, and what checks clean compiles.
    #[test]
    fn damaged_nets_never_panic(
        which in 0usize..2,
        cut in 0usize..4000,
        len in 0usize..30,
        insert in "[ -~\"(){}\\[\\],:.!&|\\-1\n]{0,10}",
    ) {
        let text = [TRANSPORT, TWO_ROLES][which];
        let mut at = cut.min(text.len());
        while !text.is_char_boundary(at) { at -= 1; }
        let mut end = (at + len).min(text.len());
        while !text.is_char_boundary(end) { end -= 1; }
        let damaged = format!("{}{}{}", &text[..at], insert, &text[end..]);
        let src = Source::new("damaged.ron", damaged);
        let checked = robot_compiler::check::check(&src);
        for d in &checked.diagnostics {
            let (line, col) = d.line_col(&src);
            prop_assert!(line >= 1 && col >= 1);
        }
        if let Some(robot) = &checked.robot {
            for n in robot_compiler::petri::load(robot, &src).nets() {
                let _ = (robot_compiler::petri::matrix::text(&n), robot_compiler::petri::matrix::csv(&n));
            }
        }
        if !checked.has_errors() {
            prop_assert!(robot_compiler::compile(&src).is_ok());
        }
    }
}

/// Two functions that enter places on each other's entries: the reference controller
/// stops past `MAX_CASCADE` place changes, as a node faults there (it never returned).
#[test]
fn the_reference_controller_stops_an_endless_cascade_where_a_node_faults() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/fixtures/broken/petri-cascade.ron"
    );
    let text = std::fs::read_to_string(path).unwrap();
    let c = compile("petri-cascade.ron", &text);
    let nets = nets(&c, &text);
    let mut reference = Controller::new(&nets);
    let edge = Occurrence::Role {
        role: String::from("R"),
        event: String::from("A"),
    };
    assert_eq!(
        reference.occur(edge, &|_| Some(true)),
        Err(robot_analysis::petri::Endless)
    );
}
