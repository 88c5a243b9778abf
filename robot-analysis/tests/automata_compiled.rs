//! The compiled FB network of a selecting automaton, run on the node interpreter from the
//! compiled blobs, against the reference semantics (`robot_analysis::automata`): fig. 1
//! on the paper's strings, the fig. 2 nondeterministic automaton, and random automata on
//! random colour strings. Each part is one colour event; the trace is, per part, the
//! transitions whose `Out` the network emitted (in order) and how many `EOS` it emitted.

use config_schema::{Action, Table};
use node_fw::ecc::{Effects, Engine};
use proptest::prelude::*;
use robot_analysis::automata::run;
use robot_compiler::automata::{Automaton, Colour};
use robot_compiler::{compile, Compiled, Source};

const FIG1: &str = "state(s0). state(s1).

transition(t1,s0,s1,black,_,ordinary).

transition(t2,s0,s0,orange,999,ordinary).

transition(t3,s1,s1,gray,2,ordinary).

transition(t4,s1,s0,black,_,final).

initial_state(s0).";

/// The nondeterministic automaton of robot-analysis/tests/automata.rs (fig. 2's sets).
const FIG2: &str = "state(s0). state(s1). state(s2).
transition(t1,s0,s0,black,2,ordinary).
transition(t2,s0,s1,black,_,ordinary).
transition(t3,s1,s2,orange,_,final).
transition(t4,s2,s1,black,_,ordinary).
transition(t5,s2,s1,gray,_,final).
initial_state(s0).";

/// A robot with one role `sorter` running the automaton (its facts, as RON text).
fn robot(automaton: &str) -> String {
    format!(
        r#"Robot(
    name: "sorter",
    network: (pan_id: 0x0101, channel: 11),
    nodes: [(name: "n1", address: 0x0001)],
    assign: [("sorter", "n1")],
    roles: [(name: "sorter")],
    colours: ["black", "gray", "orange"],
    automata: [{automaton}],
)"#
    )
}

fn facts(name: &str, facts: &str, priority: &str) -> String {
    format!("(name: \"{name}\", role: \"sorter\", facts: \"{facts}\", deterministic: false, priority: [{priority}])")
}

fn compiled(text: &str) -> Compiled {
    let src = Source::new("sorter.ron", text);
    compile(&src).unwrap_or_else(|d| {
        let msgs: Vec<String> = d.iter().map(|d| d.message.clone()).collect();
        panic!("{text}\n{msgs:#?}")
    })
}

/// The automaton as the compiler resolved it (for the reference semantics).
fn automaton(text: &str) -> Automaton {
    let src = Source::new("sorter.ron", text);
    let robot = robot_compiler::model::parse(&src).expect("parses");
    let loaded = robot_compiler::automata::load(&robot, &src);
    loaded.automata[0].automaton.clone()
}

/// Every event the engine emits, by name, from the `fired` trace: the actions of each
/// state entered.
struct Emitted<'a> {
    table: &'a Table,
    names: &'a [String],
    events: Vec<String>,
}

impl Effects for Emitted<'_> {
    fn fired(&mut self, chart: u8, _transition: u8, _from: u8, to: u8) {
        let state = self.table.chart_states(usize::from(chart)).start + usize::from(to);
        for a in &self.table.actions[self.table.state_actions(state)] {
            if let Action::Emit(e) = a {
                self.events.push(self.names[usize::from(*e)].clone());
            }
        }
    }
}

/// Per part: the transitions whose Out was emitted, in order, and the EOS count.
type Trace = Vec<(Vec<String>, usize)>;

/// Runs the compiled blob of `c` on an engine, one colour event per part.
fn network_trace(c: &Compiled, a: &Automaton, parts: &[Colour]) -> Trace {
    let table = config_schema::decode(&c.blobs[0]).expect("decodes");
    let names = &c.ir.roles[0].events;
    let mut engine = Engine::new(&table);
    let mut out = Vec::new();
    for &p in parts {
        let event = format!("part.{}", a.colour_name(p));
        let mut fx = Emitted {
            table: &table,
            names,
            events: Vec::new(),
        };
        if let Some(id) = names.iter().position(|n| *n == event) {
            engine.event(id as u8, &mut fx);
        }
        assert_eq!(engine.fault(), None, "the network faulted");
        let prefix = format!("{}.", a.name);
        let outs = fx
            .events
            .iter()
            .filter_map(|e| e.strip_prefix(&prefix)?.strip_suffix(".Out"))
            .map(String::from)
            .collect();
        let eos = fx
            .events
            .iter()
            .filter(|e| **e == format!("{}.EOS", a.name))
            .count();
        out.push((outs, eos));
    }
    out
}

/// The reference semantics' trace, each part's transitions in the network's delivery
/// order (the firing order, loops last).
fn reference_trace(a: &Automaton, parts: &[Colour]) -> Trace {
    let order = robot_compiler::automata::compile::delivery_order(a);
    run(a, parts)
        .iter()
        .map(|s| {
            let fired = order
                .iter()
                .filter(|t| s.fired.contains(t))
                .map(|&t| a.get(t).expect("t").id.clone())
                .collect();
            (fired, s.eos.len())
        })
        .collect()
}

fn colours(a: &Automaton, text: &str) -> Vec<Colour> {
    text.chars()
        .map(|c| {
            let name = match c {
                'B' => "black",
                'G' => "gray",
                'O' => "orange",
                _ => panic!("colour {c}"),
            };
            a.colour(name).expect(name)
        })
        .collect()
}

fn eos_positions(trace: &Trace) -> Vec<usize> {
    (0..trace.len()).filter(|&i| trace[i].1 > 0).collect()
}

/// Fig. 1 compiled: the exact Out / EOS of each part of the paper's strings, equal to the
/// reference's, with EOS where the first layer's tests have them.
#[test]
fn fig1_network_selects_the_papers_strings() {
    let text = robot(&facts("fig1", FIG1, ""));
    let (c, a) = (compiled(&text), automaton(&text));
    let cases: &[(&str, &[usize])] = &[
        ("BB", &[1]),
        ("BGB", &[2]),
        ("OOBGB", &[4]),
        ("OOOBBBBGGB", &[4, 6]),
        ("BG", &[]),
        ("OOGGGG", &[]),
        ("OOOBGG", &[]),
        ("BGGGB", &[4]),
    ];
    for (s, eos) in cases {
        let parts = colours(&a, s);
        let trace = network_trace(&c, &a, &parts);
        assert_eq!(trace, reference_trace(&a, &parts), "{s}");
        assert_eq!(eos_positions(&trace), *eos, "{s}");
    }
    let parts = colours(&a, "OOOBBBBGGB");
    let fired: Vec<String> = network_trace(&c, &a, &parts)
        .into_iter()
        .map(|(t, _)| t.join(","))
        .collect();
    assert_eq!(
        fired,
        ["t2", "t2", "t2", "t1", "t4", "t1", "t4", "", "", "t1"]
    );
}

/// The fig. 2 nondeterministic automaton: several tokens at once; each part's Out / EOS
/// equal the reference's.
#[test]
fn fig2_network_runs_the_online_determinisation() {
    let text = robot(&facts("fig2", FIG2, ""));
    let (c, a) = (compiled(&text), automaton(&text));
    for s in ["BBBOG", "BOG", "OGB", "BBOBGOBBBOOGG", "GOBBBBBOBG"] {
        let parts = colours(&a, s);
        assert_eq!(
            network_trace(&c, &a, &parts),
            reference_trace(&a, &parts),
            "{s}"
        );
    }
    let parts = colours(&a, "BBBOG");
    let fired: Vec<(String, usize)> = network_trace(&c, &a, &parts)
        .into_iter()
        .map(|(t, e)| (t.join(","), e))
        .collect();
    let want = [("t2,t1", 0), ("t2,t1", 0), ("t2", 0), ("t3", 1), ("t5", 1)];
    let want: Vec<(String, usize)> = want.iter().map(|(t, e)| (t.to_string(), *e)).collect();
    assert_eq!(fired, want);
}

/// A random automaton as RON: states s0..s{n}, transitions of three colours, loops with
/// caps, some final; the priority `check` suggests when it has conflicts.
fn random_automaton(
    states: usize,
    initial: &[bool],
    ts: &[(usize, usize, usize, u32, bool)],
) -> Option<String> {
    let names = ["black", "gray", "orange"];
    let state_list: Vec<String> = (0..states).map(|i| format!("\"s{i}\"")).collect();
    let mut init: Vec<String> = (0..states)
        .filter(|&i| initial.get(i).copied().unwrap_or(false))
        .map(|i| format!("\"s{i}\""))
        .collect();
    if init.is_empty() {
        init.push(String::from("\"s0\""));
    }
    let mut trans = Vec::new();
    for (k, &(from, to, colour, max, fin)) in ts.iter().enumerate() {
        let (from, to) = (from % states, to % states);
        let max = if from == to {
            format!(", max: {}", 1 + max % 3)
        } else {
            String::new()
        };
        let kind = if fin { ", kind: Final" } else { "" };
        trans.push(format!(
            "(id: \"t{k}\", from: \"s{from}\", to: \"s{to}\", colour: \"{}\"{max}{kind})",
            names[colour % 3]
        ));
    }
    let decl = format!(
        "(name: \"rnd\", role: \"sorter\", deterministic: false, states: [{}], initial: [{}], transitions: [{}], priority: [PRIORITY])",
        state_list.join(", "),
        init.join(", "),
        trans.join(", ")
    );
    // The priority the checker suggests, if it finds conflicts.
    let text = robot(&decl.replace("PRIORITY", ""));
    let a = automaton(&text);
    let conflicts = robot_compiler::automata::check::find_conflicts(&a).ok()?;
    let priority = if conflicts.is_empty() {
        String::new()
    } else {
        let order = robot_compiler::automata::check::suggest_priority(&conflicts)?;
        order
            .iter()
            .map(|&t| format!("\"{}\"", a.get(t).expect("t").id))
            .collect::<Vec<_>>()
            .join(", ")
    };
    Some(robot(&decl.replace("PRIORITY", &priority)))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Random automata (deterministic or not, loops with caps, several final transitions,
    /// conflicts resolved by the suggested priority) on random strings: the compiled
    /// network's trace is the reference's.
    #[test]
    fn compiled_network_equals_the_reference(
        states in 1usize..5,
        initial in proptest::collection::vec(any::<bool>(), 4),
        ts in proptest::collection::vec((0usize..4, 0usize..4, 0usize..3, 0u32..3, any::<bool>()), 1..=8),
        input in proptest::collection::vec(0u8..3, 0..24),
    ) {
        let Some(text) = random_automaton(states, &initial, &ts) else {
            return Ok(()); // conflicts in a cycle: no order resolves them
        };
        let src = Source::new("sorter.ron", text.as_str());
        let Ok(c) = compile(&src) else {
            // Only a network that queues too much for one node, or whose worst stimulus is
            // over the time budget (`config_schema::cost`), is refused.
            let d = compile(&src).err().unwrap_or_default();
            prop_assert!(d.iter().filter(|d| d.is_error()).all(|d| d.message.contains("EVENT_QUEUE") || d.message.contains("cannot be compiled to a token network") || d.message.contains("over the budget of 64000")), "{d:#?}");
            return Ok(());
        };
        let a = automaton(&text);
        let parts: Vec<Colour> = input.iter().map(|&i| a.colour(["black", "gray", "orange"][usize::from(i)]).expect("colour")).collect();
        prop_assert_eq!(network_trace(&c, &a, &parts), reference_trace(&a, &parts));
    }
}
