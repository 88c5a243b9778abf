//! The paper's robot on the interpreter, on virtual time (`node_fw::sim`): four hand-built
//! tables, pushed through encode -> decode as a node would receive them, four engines, the
//! radio and the plant models.

use config_schema::{decode, Table};
use node_fw::sim::{Position, TraceEntry, What, World};
use robot_tests::paper_robot::*;

/// Virtual-time bound of one cycle run.
const LIMIT_MS: u64 = 60_000;

/// Cycle time by hand, with travel VC 250 ms, HC 1200 ms, RC 300 ms, GR dwell 150 ms and
/// the 2 ms radio: VC+ 0..250, GR+ at 252, GR1 at 402 -> 404, VC- 404..654, VC0 -> 656,
/// HC+ 656..1856, HC1 -> 1858, VC+ ..2108, VC- ..2358, VC0 -> 2360, RC+ ..2660, RC- ..2960,
/// RC0 -> 2962, HC- ..4162, HC0 -> 4164, VC+ ..4414, VC1 -> 4416, GR- + dwell ..4566,
/// GR0 -> 4568, VC- ..4818, VC0 reaches HC and RC at 4820.
const CYCLE_MS: u64 = 4820;

/// The four tables as a node gets them: encoded, then decoded (and checked equal).
fn decoded() -> [Table; 4] {
    let tables = tables().expect("the robot fits the table limits");
    tables.map(test_tables::load)
}

fn actuators() -> [usize; 4] {
    [VC_PLANT, GR_PLANT, HC_PLANT, RC_PLANT]
}

fn assert_at_rest(world: &World<'_>, when: &str) {
    for (node, role) in ROLES.iter().enumerate() {
        assert_eq!(world.states(node), [0], "{when}: {role} state");
        assert_eq!(world.engine(node).fault(), None, "{when}: {role} fault");
    }
    for plant in actuators() {
        assert_eq!(
            world.position(plant),
            Some(Position::Home),
            "{when}: {} position",
            world.plants()[plant].name()
        );
    }
    // Extend solenoids off, the gripper open.
    for node in [VC, HC, RC] {
        assert_eq!(
            world.engine(node).outputs() & EXT,
            0,
            "{when}: {}",
            ROLES[node]
        );
    }
    assert_eq!(world.engine(GR).outputs(), 0, "{when}: GR");
}

fn ignored(trace: &[TraceEntry]) -> Vec<(usize, u8)> {
    trace
        .iter()
        .filter_map(|e| match e.what {
            What::Ignored { node, input, .. } => Some((node, input)),
            _ => None,
        })
        .collect()
}

#[test]
fn ten_cycles_run_sequence_1_exactly_on_the_decoded_tables() {
    let tables = decoded();
    let mut world = world(&tables).unwrap();
    for cycle in 0..10 {
        let mark = world.trace().len();
        let c = world.run_cycle(START_BUTTON, LIMIT_MS).unwrap();
        assert_eq!(c.steps, SEQUENCE, "cycle {cycle}");
        assert_eq!(c.start_ms, cycle * CYCLE_MS, "cycle {cycle}");
        assert_eq!(c.duration_ms(), CYCLE_MS, "cycle {cycle}");
        assert_at_rest(&world, &format!("end of cycle {cycle}"));
        // The bistable valves' retract solenoids stay energised after the last motion.
        for node in [VC, HC, RC] {
            assert_eq!(world.engine(node).outputs(), RET, "cycle {cycle}");
        }

        let trace = &world.trace()[mark..];
        // The recurring position events reach VC in states that do not expect them:
        // its own VC1 in S1 and S5, its own VC0 in S2 and S4. Nothing else is ignored.
        assert_eq!(
            ignored(trace),
            [(VC, vc::VC1), (VC, vc::VC0), (VC, vc::VC0), (VC, vc::VC1)],
            "cycle {cycle}"
        );
        let publications: Vec<(usize, u8)> = trace
            .iter()
            .filter_map(|e| match e.what {
                What::Publish { node, topic, .. } => Some((node, topic)),
                _ => None,
            })
            .collect();
        assert_eq!(
            publications,
            [
                (VC, topic::VC1),
                (GR, topic::GR1),
                (VC, topic::VC0),
                (HC, topic::HC1),
                (VC, topic::VC1),
                (VC, topic::VC0),
                (RC, topic::RC0),
                (HC, topic::HC0),
                (VC, topic::VC1),
                (GR, topic::GR0),
                (VC, topic::VC0),
            ],
            "cycle {cycle}"
        );
        let deliveries: Vec<(usize, usize, bool)> = trace
            .iter()
            .filter_map(|e| match e.what {
                What::Deliver {
                    from, to, accepted, ..
                } => Some((from, to, accepted)),
                _ => None,
            })
            .collect();
        assert_eq!(deliveries.len(), 14, "cycle {cycle}");
        assert!(deliveries.iter().all(|d| d.2), "cycle {cycle}");
        assert!(
            !trace
                .iter()
                .any(|e| matches!(e.what, What::Fault { .. } | What::Conflict { .. })),
            "cycle {cycle}"
        );
    }
    // Nothing but sequence (1), ten times.
    assert_eq!(world.steps(), SEQUENCE.repeat(10));
}

#[test]
fn a_go_toward_the_held_position_changes_nothing() {
    let tables = decoded();
    let mut world = world(&tables).unwrap();
    // At rest: every actuator is home; a GO home changes nothing.
    for plant in actuators() {
        let mark = world.trace().len();
        world.go(plant, false).unwrap();
        assert_eq!(
            world.trace()[mark..],
            [TraceEntry {
                t_ms: 0,
                what: What::Go { plant, plus: false }
            }]
        );
        assert!(world.is_idle());
    }
    // In the cycle, VC reaches its end at 250 ms; drive its extend again there.
    world.press(START_BUTTON).unwrap();
    while world.position(VC_PLANT) != Some(Position::End) {
        assert!(world.step().is_some(), "VC never reached its end");
    }
    assert_eq!(world.now(), 250);
    let inputs = world.engine(VC).inputs();
    let mark = world.trace().len();
    world.go(VC_PLANT, true).unwrap();
    assert_eq!(
        world.trace()[mark..],
        [TraceEntry {
            t_ms: 250,
            what: What::Go {
                plant: VC_PLANT,
                plus: true
            }
        }]
    );
    assert_eq!(world.position(VC_PLANT), Some(Position::End));
    assert_eq!(world.engine(VC).inputs(), inputs);
    // The cycle goes on exactly as before: no extra step, edge or event came of it.
    world.run_until_idle(LIMIT_MS).unwrap();
    assert_eq!(world.steps(), SEQUENCE);
    assert_eq!(world.now(), CYCLE_MS);
    assert_at_rest(&world, "after the cycle");

    // The opposite GO does move (so the check above can fail).
    let mark = world.trace().len();
    world.go(VC_PLANT, true).unwrap();
    assert_eq!(world.position(VC_PLANT), Some(Position::Extending));
    assert_eq!(
        world.trace()[mark + 1].what,
        What::Step {
            plant: VC_PLANT,
            actuator: "VC".into(),
            plus: true
        }
    );
}

#[test]
fn events_in_a_state_that_does_not_expect_them_are_ignored() {
    let tables = decoded();
    let mut world = world(&tables).unwrap();
    // At rest, stray frames: the completion events VC waits for later in the cycle, RC0 at
    // HC, and VC1 at HC (which does not even subscribe to it).
    let strays = [
        (GR, VC, topic::GR1, true, Some(vc::GR1)),
        (HC, VC, topic::HC1, true, Some(vc::HC1)),
        (HC, VC, topic::HC0, true, Some(vc::HC0)),
        (GR, VC, topic::GR0, true, Some(vc::GR0)),
        (RC, HC, topic::RC0, true, Some(hc::RC0)),
        (VC, HC, topic::VC1, false, None),
    ];
    let mark = world.trace().len();
    for (from, to, topic, _, _) in strays {
        world.inject(from, to, topic).unwrap();
    }
    world.run_until_idle(LIMIT_MS).unwrap();
    let mut expected = Vec::new();
    for (from, to, topic, accepted, input) in strays {
        expected.push(What::Deliver {
            from,
            to,
            topic,
            accepted,
        });
        if let Some(input) = input {
            expected.push(What::Ignored {
                node: to,
                chart: 0,
                input,
            });
        }
    }
    let got: Vec<What> = world.trace()[mark..]
        .iter()
        .map(|e| e.what.clone())
        .collect();
    assert_eq!(got, expected);
    assert_at_rest(&world, "after the strays");

    // Mid-cycle: VC waits for HC1 in S2, HC is moving out in S1. A stray GR0 to VC and a
    // stray RC0 to HC change nothing; the cycle completes exactly.
    world.press(START_BUTTON).unwrap();
    while world.states(VC) != [2] || world.states(HC) != [1] {
        assert!(world.step().is_some(), "never reached VC S2 / HC S1");
    }
    let mark = world.trace().len();
    world.inject(GR, VC, topic::GR0).unwrap();
    world.inject(RC, HC, topic::RC0).unwrap();
    world.run_for(0).unwrap();
    assert_eq!(
        ignored(&world.trace()[mark..]),
        [(VC, vc::GR0), (HC, hc::RC0)]
    );
    assert_eq!((world.states(VC), world.states(HC)), (vec![2], vec![1]));
    world.run_until_idle(LIMIT_MS).unwrap();
    assert_eq!(world.steps(), SEQUENCE);
    assert_at_rest(&world, "after the cycle");
}

#[test]
fn start_during_a_cycle_is_ignored() {
    let tables = decoded();
    let mut world = world(&tables).unwrap();
    world.press(START_BUTTON).unwrap();
    world.run_for(1000).unwrap();
    let mark = world.trace().len();
    world.press(START_BUTTON).unwrap();
    world.step();
    assert_eq!(ignored(&world.trace()[mark..]), [(VC, vc::START)]);
    world.run_until_idle(LIMIT_MS).unwrap();
    assert_eq!(world.steps(), SEQUENCE);
    assert_at_rest(&world, "after the cycle");
}

/// Encoded blob sizes (envelope included) measured when these tables were written, in node
/// order. The target is one IEEE 802.15.4 frame payload (about 100 bytes); VC, with seven
/// events, seven routes and four subscriptions, is over it. A table may shrink; growing
/// past these fails here. (Schema 2 added two bytes per output: fault and home levels;
/// schema 3 two per table, its HOME and boot events, and one per chart, its idle state;
/// schema 4 four per table, its safety declarations, none here.)
const BLOB_BUDGET: [usize; 4] = [173, 116, 115, 109];

#[test]
fn every_table_survives_encode_decode_within_its_size_budget() {
    let tables = tables().unwrap();
    for (t, budget) in tables.iter().zip(BLOB_BUDGET) {
        config_schema::validate(t).unwrap();
        let blob = test_tables::blob(t);
        let len = blob.len();
        assert_eq!(decode(&blob).as_ref(), Ok(t), "{}", t.header.role);
        assert!(
            len <= budget,
            "{}: {len} bytes, over its {budget}-byte budget",
            t.header.role
        );
    }
}
