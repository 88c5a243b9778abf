//! The reference semantics of selecting automata on the paper's examples: fig. 1 (its
//! Prolog facts, verbatim) and a nondeterministic automaton whose on-line determinisation
//! has the active sets of fig. 2. Exact EOS positions, fired transitions and active sets.

use robot_analysis::automata::{eos_positions, run, Config, Step};
use robot_compiler::automata::{from_facts, Automaton, Colour};

/// The facts of fig. 1 as the paper prints them.
const FIG1: &str = "state(s0). state(s1).

transition(t1,s0,s1,black,_,ordinary).

transition(t2,s0,s0,orange,999,ordinary).

transition(t3,s1,s1,gray,2,ordinary).

transition(t4,s1,s0,black,_,final).

initial_state(s0).";

/// A nondeterministic automaton (our reconstruction: the paper's figure is not in its
/// text) that, from {s0}, reaches exactly the active sets fig. 2 names: {s0,s1},
/// {s0,s2}, {s1}, {s2}. From {s0} only black parts start a sequence; once the active
/// set has changed, a sequence may start with orange or gray.
const FIG2: &str = "state(s0). state(s1). state(s2).
transition(t1,s0,s0,black,2,ordinary).   % keeps s0 active for 2 blacks
transition(t2,s0,s1,black,_,ordinary).
transition(t3,s1,s2,orange,_,final).
transition(t4,s2,s1,black,_,ordinary).
transition(t5,s2,s1,gray,_,final).
initial_state(s0).";

fn automaton(name: &str, facts: &str) -> Automaton {
    from_facts(name, facts)
        .unwrap_or_else(|e| panic!("{name}: {e:?}"))
        .automaton
}

/// `B`, `G`, `O` -> the automaton's colours.
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

/// Each step as `fired -> active [EOS t]`, e.g. `t1 -> {s1}`, `- -> {s0}` if ignored.
fn trace(a: &Automaton, steps: &[Step]) -> Vec<String> {
    steps
        .iter()
        .map(|s| {
            let fired: Vec<&str> = s
                .fired
                .iter()
                .map(|&t| a.get(t).expect("t").id.as_str())
                .collect();
            let fired = if fired.is_empty() {
                String::from("-")
            } else {
                fired.join(",")
            };
            let eos: Vec<&str> = s
                .eos
                .iter()
                .map(|&t| a.get(t).expect("t").id.as_str())
                .collect();
            let eos = if eos.is_empty() {
                String::new()
            } else {
                format!(" EOS {}", eos.join(","))
            };
            format!("{fired} -> {}{eos}", s.active.show(a))
        })
        .collect()
}

#[test]
fn fig_1_selects_from_the_strings_the_paper_says_at_exact_places() {
    let a = automaton("fig1", FIG1);
    assert_eq!(a.colours, ["black", "orange", "gray"]);
    let cases: &[(&str, &[usize])] = &[
        ("BB", &[1]),
        ("BGB", &[2]),
        ("OOBGB", &[4]),
        ("OOOBBBBGGB", &[4, 6]),
    ];
    for (input, eos) in cases {
        let steps = run(&a, &colours(&a, input));
        assert_eq!(eos_positions(&steps), *eos, "{input}");
    }
    let steps = run(&a, &colours(&a, "OOOBBBBGGB"));
    assert_eq!(
        trace(&a, &steps),
        [
            "t2 -> {s0}",
            "t2 -> {s0}",
            "t2 -> {s0}",
            "t1 -> {s1}",
            "t4 -> {s0} EOS t4",
            "t1 -> {s1}",
            "t4 -> {s0} EOS t4",
            "- -> {s0}",
            "- -> {s0}",
            "t1 -> {s1}",
        ]
    );
}

#[test]
fn fig_1_cannot_select_from_the_strings_the_paper_says() {
    let a = automaton("fig1", FIG1);
    for input in ["BG", "OOGGGG", "OOOBGG"] {
        let steps = run(&a, &colours(&a, input));
        assert_eq!(eos_positions(&steps), Vec::<usize>::new(), "{input}");
    }
    // Gray parts in s0 fire nothing: ignored.
    let steps = run(&a, &colours(&a, "OOGGGG"));
    assert_eq!(
        trace(&a, &steps),
        [
            "t2 -> {s0}",
            "t2 -> {s0}",
            "- -> {s0}",
            "- -> {s0}",
            "- -> {s0}",
            "- -> {s0}"
        ]
    );
}

/// The loop t3 accepts at most 2 grays in one visit of s1: the 3rd is ignored (the state
/// stays active, the final black still selects); a new visit counts again from 0.
#[test]
fn a_loop_takes_at_most_its_cap_in_a_row_then_ignores_its_colour() {
    let a = automaton("fig1", FIG1);
    let steps = run(&a, &colours(&a, "BGGGBBGGB"));
    assert_eq!(
        trace(&a, &steps),
        [
            "t1 -> {s1}",
            "t3 -> {s1}",
            "t3 -> {s1}",
            "- -> {s1}",
            "t4 -> {s0} EOS t4",
            "t1 -> {s1}",
            "t3 -> {s1}",
            "t3 -> {s1}",
            "t4 -> {s0} EOS t4",
        ]
    );
    let mut config = Config::initial(&a);
    for c in colours(&a, "BGG") {
        config.step(&a, c);
    }
    assert_eq!(config.counts, [0, 0, 2, 0]);
}

#[test]
fn fig_2_runs_as_its_on_line_determinisation() {
    let a = automaton("fig2", FIG2);
    // Every active set reachable from {s0} on any string (breadth-first over the exact
    // configurations, counts included).
    let mut seen = vec![Config::initial(&a)];
    let mut i = 0;
    while let Some(config) = seen.get(i).cloned() {
        for c in 0..a.colours.len() as u8 {
            let mut next = config.clone();
            next.step(&a, Colour(c));
            if !seen.contains(&next) {
                seen.push(next);
            }
        }
        i += 1;
    }
    let mut sets: Vec<String> = seen.iter().map(|c| c.active.show(&a)).collect();
    sets.sort();
    sets.dedup();
    assert_eq!(sets, ["{s0,s1}", "{s0,s2}", "{s0}", "{s1}", "{s2}"]);

    // Selects: exact steps and active sets.
    let steps = run(&a, &colours(&a, "BO"));
    assert_eq!(
        trace(&a, &steps),
        ["t1,t2 -> {s0,s1}", "t3 -> {s0,s2} EOS t3"]
    );
    let steps = run(&a, &colours(&a, "BBBOG"));
    assert_eq!(
        trace(&a, &steps),
        [
            "t1,t2 -> {s0,s1}",
            "t1,t2 -> {s0,s1}",
            "t2 -> {s1}",
            "t3 -> {s2} EOS t3",
            "t5 -> {s1} EOS t5",
        ]
    );
    // Once the set is {s1} or {s2}, a sequence starts with orange or gray.
    let steps = run(&a, &colours(&a, "BBBOGOG"));
    assert_eq!(eos_positions(&steps), [3, 4, 5, 6]);
    let steps = run(&a, &colours(&a, "BOBG"));
    assert_eq!(
        trace(&a, &steps),
        [
            "t1,t2 -> {s0,s1}",
            "t3 -> {s0,s2} EOS t3",
            "t1,t2,t4 -> {s0,s1}",
            "- -> {s0,s1}",
        ]
    );

    // Does not select: from {s0} orange and gray are ignored; blacks alone end nothing.
    for input in ["", "OOGG", "GOGO", "BBBB", "BGG"] {
        let steps = run(&a, &colours(&a, input));
        assert_eq!(eos_positions(&steps), Vec::<usize>::new(), "{input}");
    }
    let steps = run(&a, &colours(&a, "OGBBBB"));
    assert_eq!(
        trace(&a, &steps),
        [
            "- -> {s0}",
            "- -> {s0}",
            "t1,t2 -> {s0,s1}",
            "t1,t2 -> {s0,s1}",
            "t2 -> {s1}",
            "- -> {s1}",
        ]
    );
}
