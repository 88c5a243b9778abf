//! `paint-robot-paper-charts.ron` is the hand-built robot of `robot_tests::paper_robot`
//! (the interpreter's robot test) written as RON: compiled, each role's charts, states,
//! transitions and actions are exactly the hand-built ones (event ids aside), and each
//! role publishes the same events to the same number of nodes.

use config_schema::{Action, Table};
use robot_compiler::{compile, Source};
use robot_tests::paper_robot;

/// Actions with event ids blanked (ids are numbered differently by hand).
fn actions(t: &Table) -> Vec<Action> {
    t.actions
        .iter()
        .map(|a| match a {
            Action::Emit(_) => Action::Emit(0),
            other => *other,
        })
        .collect()
}

#[test]
fn the_ron_paper_charts_compile_to_the_hand_built_tables() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../robot-configs/paint-robot-paper-charts.ron"
    );
    let src = Source::new("paper", std::fs::read_to_string(path).expect("config"));
    let compiled = compile(&src).expect("compiles");
    let hand = [
        paper_robot::vc_table(),
        paper_robot::gr_table(),
        paper_robot::hc_table(),
        paper_robot::rc_table(),
    ];
    for ((ours, theirs), role) in compiled.tables.iter().zip(hand).zip(paper_robot::ROLES) {
        let theirs = theirs.expect("hand-built table");
        assert_eq!(ours.header.role.as_str(), role);
        assert_eq!(ours.charts, theirs.charts, "{role}");
        assert_eq!(ours.states, theirs.states, "{role}");
        assert_eq!(ours.transitions, theirs.transitions, "{role}");
        assert_eq!(actions(ours), actions(&theirs), "{role}");
        assert_eq!(ours.timers.len(), theirs.timers.len(), "{role}");
        assert_eq!(ours.outputs.len(), theirs.outputs.len(), "{role}");
        let fanout = |t: &Table| -> Vec<u32> {
            t.publications
                .iter()
                .map(|p| p.subscribers.count_ones())
                .collect()
        };
        let mut a = fanout(ours);
        let mut b = fanout(&theirs);
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b, "{role}");
        assert_eq!(
            ours.subscriptions.len(),
            theirs.subscriptions.len(),
            "{role}"
        );
        assert_eq!(ours.peers.len(), theirs.peers.len(), "{role}");
    }
}
