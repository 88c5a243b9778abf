//! The virtual-time world (`node_fw::sim`) through its public API: plants on the pins, the
//! radio (ideal and lossy), run bounds, injected faults, and the trace of each.

use config_schema::{Action, Input, Output, Publication, Subscription, Table, Timer, Transition};
use node_fw::sim::*;
use test_tables::route;

const EXT: u16 = 0b01;
const RET: u16 = 0b10;

/// A cylinder node: input 0 = home switch (rise: event 0), input 1 = end switch (rise:
/// event 1), output 0 = extend solenoid, output 1 = retract solenoid. With `chart`, START
/// (event 2) runs S0 -START-> S1[C+] -end-> S2[C-] -home-> S0.
fn cylinder_table(chart: bool) -> Table {
    let mut t = Table::empty("C");
    for _ in 0..3 {
        t.push_event().unwrap();
    }
    for (pin, rise) in [(0, 0), (1, 1)] {
        t.inputs
            .push(Input {
                pin,
                rise: Some(rise),
                fall: None,
                var: None,
            })
            .unwrap();
    }
    for pin in 10..12 {
        t.outputs.push(Output::safe(pin, false)).unwrap();
    }
    if chart {
        t.start = Some(2);
        let tr = |from, to, trigger| Transition {
            from,
            to,
            trigger: Some(trigger),
            guard: None,
        };
        t.push_chart(
            0,
            3,
            &[
                &[],
                &[Action::Drive {
                    mask: EXT | RET,
                    value: EXT,
                }],
                &[Action::Drive {
                    mask: EXT | RET,
                    value: RET,
                }],
            ],
            &[tr(0, 1, 2), tr(1, 2, 1), tr(2, 0, 0)],
        )
        .unwrap();
        for e in 0..3 {
            route(&mut t, e, 0, e);
        }
    }
    config_schema::validate(&t).unwrap();
    t
}

fn cylinder(node: usize) -> Plant {
    DoubleActing {
        name: "C".into(),
        node,
        extend_out: 0,
        retract_out: 1,
        home_in: Some(0),
        end_in: Some(1),
        extend_ms: 300,
        retract_ms: 600,
    }
    .into()
}

fn at(t_ms: u64, what: What) -> TraceEntry {
    TraceEntry { t_ms, what }
}

fn step(plus: bool) -> What {
    What::Step {
        plant: 0,
        actuator: "C".into(),
        plus,
    }
}

fn input(input: u8, level: bool) -> What {
    What::Input {
        node: 0,
        input,
        level,
    }
}

#[test]
fn the_rod_starts_home_with_its_switch_high_and_no_event() {
    let table = cylinder_table(true);
    let nodes = [NodeSpec {
        addr: 1,
        table: &table,
    }];
    let mut world = World::new(&nodes, vec![cylinder(0)]).unwrap();
    assert_eq!(world.engine(0).inputs(), 0b01);
    assert_eq!(world.states(0), vec![0]);
    assert_eq!(world.position(0), Some(Position::Home));
    assert!(world.is_idle());
    assert!(world.trace().is_empty());
}

#[test]
fn a_motion_drops_the_switch_at_once_and_raises_the_other_after_the_travel_time() {
    let table = cylinder_table(false);
    let nodes = [NodeSpec {
        addr: 1,
        table: &table,
    }];
    let mut world = World::new(&nodes, vec![cylinder(0)]).unwrap();
    world.go(0, true).unwrap();
    assert_eq!(world.position(0), Some(Position::Extending));
    assert_eq!(world.run_until_idle(10_000), Ok(300));
    assert_eq!(
        world.trace(),
        [
            at(
                0,
                What::Go {
                    plant: 0,
                    plus: true
                }
            ),
            at(0, step(true)),
            at(0, input(0, false)),
            at(
                300,
                What::Arrived {
                    plant: 0,
                    end: true
                }
            ),
            at(300, input(1, true)),
        ]
    );
    assert_eq!(world.engine(0).inputs(), 0b10);
    assert_eq!(world.position(0), Some(Position::End));
}

#[test]
fn a_go_toward_the_held_position_changes_nothing() {
    let table = cylinder_table(false);
    let nodes = [NodeSpec {
        addr: 1,
        table: &table,
    }];
    let mut world = World::new(&nodes, vec![cylinder(0)]).unwrap();
    world.go(0, false).unwrap();
    assert_eq!(
        world.trace(),
        [at(
            0,
            What::Go {
                plant: 0,
                plus: false
            }
        )]
    );
    assert!(world.is_idle());
    world.go(0, true).unwrap();
    world.run_until_idle(10_000).unwrap();
    let mark = world.trace().len();
    world.go(0, true).unwrap();
    assert!(world.is_idle());
    assert_eq!(
        world.trace()[mark..],
        [at(
            300,
            What::Go {
                plant: 0,
                plus: true
            }
        )]
    );
    assert_eq!(world.engine(0).inputs(), 0b10);
    assert_eq!(world.position(0), Some(Position::End));
}

#[test]
fn a_reversal_mid_travel_is_a_new_step_and_returns_over_the_covered_stroke() {
    let table = cylinder_table(false);
    let nodes = [NodeSpec {
        addr: 1,
        table: &table,
    }];
    let mut world = World::new(&nodes, vec![cylinder(0)]).unwrap();
    world.go(0, true).unwrap();
    world.run_for(100).unwrap();
    // A third of the stroke out; back at 600 ms per stroke takes 200 ms.
    world.go(0, false).unwrap();
    assert_eq!(world.run_until_idle(10_000), Ok(300));
    assert_eq!(
        world.trace(),
        [
            at(
                0,
                What::Go {
                    plant: 0,
                    plus: true
                }
            ),
            at(0, step(true)),
            at(0, input(0, false)),
            at(
                100,
                What::Go {
                    plant: 0,
                    plus: false
                }
            ),
            at(100, step(false)),
            at(
                300,
                What::Arrived {
                    plant: 0,
                    end: false
                }
            ),
            at(300, input(0, true)),
        ]
    );
    assert_eq!(world.position(0), Some(Position::Home));
    assert_eq!(world.steps(), ["C+", "C-"]);
}

#[test]
fn a_chart_drives_the_cylinder_out_and_back() {
    let table = cylinder_table(true);
    let nodes = [NodeSpec {
        addr: 1,
        table: &table,
    }];
    let mut world = World::new(&nodes, vec![cylinder(0)]).unwrap();
    world.start(0).unwrap();
    assert_eq!(world.run_until_idle(10_000), Ok(900));
    assert_eq!(world.steps(), ["C+", "C-"]);
    assert_eq!(
        world.cycles(),
        [Cycle {
            start_ms: 0,
            end_ms: 900,
            steps: vec!["C+".into(), "C-".into()],
        }]
    );
    let fired: Vec<(u64, u8, u8)> = world
        .trace()
        .iter()
        .filter_map(|e| match e.what {
            What::Fired { from, to, .. } => Some((e.t_ms, from, to)),
            _ => None,
        })
        .collect();
    assert_eq!(fired, [(0, 0, 1), (300, 1, 2), (900, 2, 0)]);
    assert_eq!(world.states(0), vec![0]);
    assert_eq!(world.engine(0).outputs(), RET);
}

#[test]
fn both_solenoids_at_once_is_a_conflict_and_moves_nothing() {
    let mut table = cylinder_table(false);
    table.start = Some(2);
    table
        .push_chart(
            0,
            1,
            &[
                &[],
                &[Action::Drive {
                    mask: EXT | RET,
                    value: EXT | RET,
                }],
            ],
            &[Transition {
                from: 0,
                to: 1,
                trigger: Some(0),
                guard: None,
            }],
        )
        .unwrap();
    table
        .routes
        .push(config_schema::Route {
            event: 2,
            chart: 0,
            input: 0,
        })
        .unwrap();
    config_schema::validate(&table).unwrap();
    let nodes = [NodeSpec {
        addr: 1,
        table: &table,
    }];
    let mut world = World::new(&nodes, vec![cylinder(0)]).unwrap();
    world.start(0).unwrap();
    world.run_until_idle(10_000).unwrap();
    assert_eq!(world.steps(), Vec::<String>::new());
    assert_eq!(
        world.trace().last().map(|e| &e.what),
        Some(&What::Conflict { plant: 0 })
    );
    assert_eq!(world.position(0), Some(Position::Home));
}

/// Node A: input 0 (rise: event 0) published as topic 7 to every peer in `peers`; a
/// one-shot timer started by event 1 (START) and cancelled by event 0.
fn publisher_table(peers: &[u16]) -> Table {
    let mut t = Table::empty("A");
    for _ in 0..3 {
        t.push_event().unwrap();
    }
    t.start = Some(1);
    t.inputs
        .push(Input {
            pin: 0,
            rise: Some(0),
            fall: None,
            var: None,
        })
        .unwrap();
    t.timers.push(Timer { event: 2 }).unwrap();
    for p in peers {
        t.peers.push(*p).unwrap();
    }
    t.publications
        .push(Publication {
            event: 0,
            topic: 7,
            subscribers: ((1u16 << peers.len()) - 1) as u8,
        })
        .unwrap();
    let tr = |from, to, trigger| Transition {
        from,
        to,
        trigger: Some(trigger),
        guard: None,
    };
    t.push_chart(
        0,
        2,
        &[
            &[],
            &[Action::StartTimer { timer: 0, ms: 100 }],
            &[Action::CancelTimer(0)],
        ],
        &[tr(0, 1, 1), tr(1, 2, 0)],
    )
    .unwrap();
    route(&mut t, 1, 0, 1);
    route(&mut t, 0, 0, 0);
    config_schema::validate(&t).unwrap();
    t
}

/// Node B: subscribes topic 7 from peer 0 as event 0, routed to a one-state chart that
/// ignores it.
fn subscriber_table(publisher: u16) -> Table {
    let mut t = Table::empty("B");
    t.push_event().unwrap();
    t.peers.push(publisher).unwrap();
    t.subscriptions
        .push(Subscription {
            publisher: 0,
            topic: 7,
            event: 0,
        })
        .unwrap();
    t.push_chart(0, 1, &[&[]], &[]).unwrap();
    route(&mut t, 0, 0, 0);
    config_schema::validate(&t).unwrap();
    t
}

#[test]
fn a_publication_reaches_each_subscriber_after_the_radio_delay() {
    let a = publisher_table(&[0x20, 0x30, 0x40]);
    let b = subscriber_table(0x10);
    let c = subscriber_table(0x99);
    let nodes = [
        NodeSpec {
            addr: 0x10,
            table: &a,
        },
        NodeSpec {
            addr: 0x20,
            table: &b,
        },
        NodeSpec {
            addr: 0x30,
            table: &c,
        },
    ];
    let mut world = World::new(&nodes, vec![Button::new("S", 0, 0).into()]).unwrap();
    world.set_radio_delay(5);
    world.press(0).unwrap();
    assert_eq!(world.run_until_idle(1_000), Ok(50));
    assert_eq!(
        world.trace(),
        [
            at(0, What::Press { button: 0 }),
            at(0, input(0, true)),
            at(
                0,
                What::Publish {
                    node: 0,
                    event: 0,
                    topic: 7,
                    subscribers: 0b111,
                }
            ),
            at(
                0,
                What::Ignored {
                    node: 0,
                    chart: 0,
                    input: 0,
                }
            ),
            // Effects are applied once the engine step is over.
            at(
                0,
                What::NoSuchPeer {
                    node: 0,
                    addr: 0x40
                }
            ),
            at(
                5,
                What::Deliver {
                    from: 0,
                    to: 1,
                    topic: 7,
                    accepted: true,
                }
            ),
            at(
                5,
                What::Ignored {
                    node: 1,
                    chart: 0,
                    input: 0,
                }
            ),
            // Node C knows no peer 0x10: the frame is not for a subscription of its.
            at(
                5,
                What::Deliver {
                    from: 0,
                    to: 2,
                    topic: 7,
                    accepted: false,
                }
            ),
            at(50, input(0, false)),
        ]
    );
}

#[test]
fn a_cancelled_timer_never_expires_and_an_armed_one_does() {
    let a = publisher_table(&[]);
    let nodes = [NodeSpec {
        addr: 0x10,
        table: &a,
    }];
    let mut world = World::new(&nodes, vec![Button::new("S", 0, 0).into()]).unwrap();
    world.start(0).unwrap();
    world.run_for(40).unwrap();
    world.press(0).unwrap();
    assert_eq!(world.run_until_idle(1_000), Ok(90));
    assert!(!world
        .trace()
        .iter()
        .any(|e| matches!(e.what, What::TimerExpired { .. })));
    assert_eq!(world.states(0), vec![2]);

    let mut world = World::new(&nodes, vec![Button::new("S", 0, 0).into()]).unwrap();
    world.start(0).unwrap();
    assert_eq!(world.run_until_idle(1_000), Ok(100));
    assert_eq!(
        world.trace().last(),
        Some(&at(100, What::TimerExpired { node: 0, timer: 0 }))
    );
}

#[test]
fn runs_are_bounded_by_their_time_limit() {
    let table = cylinder_table(false);
    let nodes = [NodeSpec {
        addr: 1,
        table: &table,
    }];
    let mut world = World::new(&nodes, vec![cylinder(0)]).unwrap();
    world.go(0, true).unwrap();
    assert_eq!(
        world.run_until_idle(299),
        Err(SimError::NotIdle {
            limit_ms: 299,
            now_ms: 0,
            next_ms: 300
        })
    );
    assert_eq!(
        world.run_until_idle(0).map_err(|e| e.to_string()),
        Err(String::from(
            "not idle by the time limit (0 ms): the last event at 0 ms, the next one due at \
             300 ms"
        ))
    );
    assert_eq!(world.run_until_idle(300), Ok(300));
}

#[test]
fn the_same_calls_give_the_same_trace() {
    let table = cylinder_table(true);
    let nodes = [NodeSpec {
        addr: 1,
        table: &table,
    }];
    let run = || {
        let mut world = World::new(&nodes, vec![cylinder(0)]).unwrap();
        for _ in 0..3 {
            world.start(0).unwrap();
            world.run_for(450).unwrap();
            world.go(0, true).unwrap();
            world.run_until_idle(10_000).unwrap();
        }
        world.take_trace()
    };
    let first = run();
    assert!(first.len() > 20);
    assert_eq!(first, run());
}

#[test]
fn bad_wiring_is_refused() {
    let table = cylinder_table(false);
    let nodes = [NodeSpec {
        addr: 1,
        table: &table,
    }];
    let bad_out = DoubleActing {
        name: "X".into(),
        node: 0,
        extend_out: 0,
        retract_out: 2,
        home_in: None,
        end_in: None,
        extend_ms: 1,
        retract_ms: 1,
    };
    assert_eq!(
        World::new(&nodes, vec![bad_out.into()]).err(),
        Some(SimError::NoSuchOutput {
            plant: "X".into(),
            node: 0,
            output: 2
        })
    );
    assert_eq!(
        World::new(&nodes, vec![cylinder(0), Button::new("S", 0, 1).into()]).err(),
        Some(SimError::PinShared {
            plant: "S".into(),
            node: 0,
            pin: 1,
            output: false
        })
    );
    assert_eq!(
        World::new(&nodes, vec![cylinder(1)]).err(),
        Some(SimError::NoSuchNode {
            plant: "C".into(),
            node: 1
        })
    );
    let twice = [nodes[0], nodes[0]];
    assert_eq!(
        World::new(&twice, vec![]).err(),
        Some(SimError::DuplicateAddress { addr: 1 })
    );
    let mut world = World::new(&nodes, vec![cylinder(0)]).unwrap();
    assert_eq!(
        world.press(0),
        Err(SimError::NoSuchPlant {
            plant: 0,
            want: "a button"
        })
    );
}

/// A node that answers every `topic_in` from its peer with a publication of `topic_out`
/// back to it; with `starts`, START sends the first one.
fn ping_table(peer: u16, topic_in: u8, topic_out: u8, starts: bool) -> Table {
    let mut t = Table::empty("P");
    for _ in 0..3 {
        t.push_event().unwrap();
    }
    t.peers.push(peer).unwrap();
    t.subscriptions
        .push(Subscription {
            publisher: 0,
            topic: topic_in,
            event: 0,
        })
        .unwrap();
    t.publications
        .push(Publication {
            event: 1,
            topic: topic_out,
            subscribers: 1,
        })
        .unwrap();
    t.push_chart(
        0,
        1,
        &[&[Action::Emit(1)]],
        &[Transition {
            from: 0,
            to: 0,
            trigger: Some(0),
            guard: None,
        }],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    if starts {
        t.start = Some(2);
        route(&mut t, 2, 0, 0);
    }
    config_schema::validate(&t).unwrap();
    t
}

#[test]
fn an_endless_exchange_between_nodes_is_stopped_by_the_run_bounds() {
    let a = ping_table(0x20, 1, 2, true);
    let b = ping_table(0x10, 2, 1, false);
    let nodes = [
        NodeSpec {
            addr: 0x10,
            table: &a,
        },
        NodeSpec {
            addr: 0x20,
            table: &b,
        },
    ];
    // With the radio's delay, virtual time advances: the time limit stops it.
    let mut world = World::new(&nodes, vec![]).unwrap();
    world.start(0).unwrap();
    assert_eq!(
        world.run_until_idle(9),
        Err(SimError::NotIdle {
            limit_ms: 9,
            now_ms: 8,
            next_ms: 10
        })
    );
    let deliveries = |w: &World<'_>| {
        w.trace()
            .iter()
            .filter(|e| matches!(e.what, What::Deliver { accepted: true, .. }))
            .count()
    };
    assert_eq!(deliveries(&world), 4);
    // With no delay it never leaves t = 0: the event limit stops it.
    let mut world = World::new(&nodes, vec![]).unwrap();
    world.set_radio_delay(0);
    world.set_run_event_limit(100);
    world.start(0).unwrap();
    assert_eq!(
        world.run_until_idle(1_000),
        Err(SimError::Runaway {
            now_ms: 0,
            events: 100
        })
    );
    assert_eq!(deliveries(&world), 99);
}

#[test]
fn a_single_acting_valve_follows_its_output_and_ignores_a_zero_length_pulse() {
    let mut t = Table::empty("G");
    t.push_event().unwrap();
    t.start = Some(0);
    t.outputs.push(Output::safe(0, false)).unwrap();
    let (on, off) = (
        Action::Drive { mask: 1, value: 1 },
        Action::Drive { mask: 1, value: 0 },
    );
    let tr = |from, to| Transition {
        from,
        to,
        trigger: Some(0),
        guard: None,
    };
    // START: a pulse within one step, then close, then open.
    t.push_chart(
        0,
        1,
        &[&[off], &[on, off], &[on]],
        &[tr(0, 1), tr(1, 2), tr(2, 0)],
    )
    .unwrap();
    route(&mut t, 0, 0, 0);
    config_schema::validate(&t).unwrap();
    let nodes = [NodeSpec { addr: 1, table: &t }];
    let gripper = SingleActing {
        name: "GR".into(),
        node: 0,
        out: 0,
        home_in: None,
        end_in: None,
        extend_ms: 80,
        retract_ms: 40,
    };
    let mut world = World::new(&nodes, vec![gripper.into()]).unwrap();
    world.start(0).unwrap();
    world.run_until_idle(1_000).unwrap();
    assert_eq!(world.steps(), Vec::<String>::new());
    assert_eq!(world.position(0), Some(Position::Home));
    world.start(0).unwrap();
    world.run_for(10).unwrap();
    assert_eq!(world.position(0), Some(Position::Extending));
    assert_eq!(world.run_until_idle(1_000), Ok(80));
    assert_eq!(world.position(0), Some(Position::End));
    world.start(0).unwrap();
    assert_eq!(world.run_until_idle(1_000), Ok(120));
    assert_eq!(world.position(0), Some(Position::Home));
    assert_eq!(world.steps(), ["GR+", "GR-"]);
    assert_eq!(
        world
            .trace()
            .iter()
            .filter_map(|e| match e.what {
                What::Arrived { end, .. } => Some((e.t_ms, end)),
                _ => None,
            })
            .collect::<Vec<_>>(),
        [(80, true), (120, false)]
    );
}

#[test]
fn a_jammed_cylinder_moves_nothing_and_says_so() {
    let table = cylinder_table(false);
    let nodes = [NodeSpec {
        addr: 1,
        table: &table,
    }];
    let mut world = World::new(&nodes, vec![cylinder(0)]).unwrap();
    world.jam(0).unwrap();
    world.go(0, true).unwrap();
    assert_eq!(world.run_until_idle(10_000), Ok(0));
    assert_eq!(
        world.trace(),
        [
            at(
                0,
                What::Injected {
                    fault: "C jammed".into()
                }
            ),
            at(
                0,
                What::Go {
                    plant: 0,
                    plus: true
                }
            ),
            at(
                0,
                What::Jammed {
                    plant: 0,
                    plus: true
                }
            ),
        ]
    );
    assert_eq!(world.position(0), Some(Position::Home));
    assert_eq!(
        world.jam(5),
        Err(SimError::NoSuchPlant {
            plant: 5,
            want: "an actuator"
        })
    );
}

#[test]
fn a_broken_switch_never_rises() {
    let table = cylinder_table(false);
    let nodes = [NodeSpec {
        addr: 1,
        table: &table,
    }];
    let mut world = World::new(&nodes, vec![cylinder(0)]).unwrap();
    world.break_switch(0, 1).unwrap();
    world.go(0, true).unwrap();
    assert_eq!(world.run_until_idle(10_000), Ok(300));
    assert_eq!(world.position(0), Some(Position::End));
    // The rod arrived, the end switch stayed low (and the home switch fell).
    assert_eq!(world.engine(0).inputs(), 0b00);
    assert!(!world.trace().contains(&at(300, input(1, true))));
}

#[test]
fn a_cut_link_or_a_stopped_node_raises_the_link_alarm_after_the_retries() {
    assert_eq!(link_alarm_ms(), 30 + 60 + 6 * 120);
    let a = publisher_table(&[0x20, 0x30]);
    let b = subscriber_table(0x10);
    let c = subscriber_table(0x10);
    let nodes = [
        NodeSpec {
            addr: 0x10,
            table: &a,
        },
        NodeSpec {
            addr: 0x20,
            table: &b,
        },
        NodeSpec {
            addr: 0x30,
            table: &c,
        },
    ];
    let mut world = World::new(&nodes, vec![Button::new("S", 0, 0).into()]).unwrap();
    world.cut_link(0, 1).unwrap();
    world.stop_node(2).unwrap();
    world.press(0).unwrap();
    assert_eq!(world.run_until_idle(10_000), Ok(810));
    let alarms: Vec<&TraceEntry> = world
        .trace()
        .iter()
        .filter(|e| matches!(e.what, What::LinkAlarm { .. }))
        .collect();
    assert_eq!(
        alarms,
        [
            &at(810, What::LinkAlarm { node: 0, peer: 1 }),
            &at(810, What::LinkAlarm { node: 0, peer: 2 }),
        ]
    );
    assert!(!world
        .trace()
        .iter()
        .any(|e| matches!(e.what, What::Deliver { .. })));
}

/// A publisher (node 0, a button on input 0 publishes topic 7) and its subscriber.
fn pub_sub() -> (Table, Table) {
    (publisher_table(&[0x20]), subscriber_table(0x10))
}

fn pub_sub_world<'t>(a: &'t Table, b: &'t Table) -> World<'t> {
    let nodes = [
        NodeSpec {
            addr: 0x10,
            table: a,
        },
        NodeSpec {
            addr: 0x20,
            table: b,
        },
    ];
    World::new(&nodes, vec![Button::new("S", 0, 0).into()]).unwrap()
}

fn link_trouble(world: &World<'_>) -> Vec<TraceEntry> {
    world
        .trace()
        .iter()
        .filter(|e| matches!(e.what, What::LinkAlarm { .. } | What::LinkBroken { .. }))
        .cloned()
        .collect()
}

#[test]
fn a_lossy_radio_delivers_every_publication_exactly_once() {
    let (a, b) = pub_sub();
    let mut world = pub_sub_world(&a, &b);
    world.set_loss(0.3, 7);
    for _ in 0..20 {
        world.press(0).unwrap();
        world.run_for(70).unwrap();
    }
    world.run_until_idle(60_000).unwrap();
    let delivered = world
        .trace()
        .iter()
        .filter(|e| {
            matches!(
                e.what,
                What::Deliver {
                    from: 0,
                    to: 1,
                    topic: 7,
                    accepted: true
                }
            )
        })
        .count();
    assert_eq!(delivered, 20);
    let (sent, lost) = world.frames();
    assert!(lost > 0 && lost < sent, "{lost} of {sent} frames lost");
    assert_eq!(link_trouble(&world), []);
}

#[test]
fn a_lossy_link_raises_its_alarm_after_the_retries_and_breaks_when_its_queue_overflows() {
    let (a, b) = pub_sub();
    let mut world = pub_sub_world(&a, &b);
    world.set_loss(1.0, 1);
    // One publication every 60 ms, none acknowledged: the 17th overflows the queue of 16.
    for _ in 0..17 {
        world.press(0).unwrap();
        world.run_for(60).unwrap();
    }
    assert_eq!(node_fw::link::QUEUE, 16);
    assert_eq!(
        link_trouble(&world),
        [
            at(810, What::LinkAlarm { node: 0, peer: 1 }),
            at(960, What::LinkBroken { node: 0, peer: 1 }),
        ]
    );
    assert!(!world
        .trace()
        .iter()
        .any(|e| matches!(e.what, What::Deliver { .. })));
}

/// The cylinder node's chart driving a motor (output 0 clockwise, 1 counter-clockwise,
/// 300 mm at 150 mm/s) that moves a belt whose sensors are on node 1; a fault contact on
/// node 2. Out 2 s, back 2 s; the belt's sensors switch with the motor's, on its node;
/// at home the motor stalls (still commanded counter-clockwise).
#[test]
fn a_motor_moves_its_carriage_and_what_it_drives_at_its_speed() {
    let (chart, plain) = (cylinder_table(true), cylinder_table(false));
    let nodes = [
        NodeSpec {
            addr: 1,
            table: &chart,
        },
        NodeSpec {
            addr: 2,
            table: &plain,
        },
        NodeSpec {
            addr: 3,
            table: &plain,
        },
    ];
    let motor = Motor {
        name: "M".into(),
        node: 0,
        cw_out: 0,
        ccw_out: 1,
        home_in: Some(0),
        end_in: Some(1),
        stroke_mm: 300,
        speed_mm_s: 150,
    };
    let belt = Driven {
        name: "B".into(),
        node: 1,
        motor: 0,
        home_in: Some(0),
        end_in: Some(1),
    };
    let contact = Switch {
        name: "F".into(),
        node: 2,
        input: 1,
    };
    let mut world = World::new(&nodes, vec![motor.into(), belt.into(), contact.into()]).unwrap();
    // Both home sensors read high at power-up, no edge.
    assert_eq!(world.engine(0).inputs(), 0b01);
    assert_eq!(world.engine(1).inputs(), 0b01);
    world.start(0).unwrap();
    world.run_for(1000).unwrap();
    assert_eq!(world.run(0), Some(Run::Clockwise));
    assert_eq!(
        (world.carriage_um(0), world.carriage_um(1)),
        (Some(150_000), Some(150_000))
    );
    assert_eq!(world.run_until_idle(10_000), Ok(4000));
    assert_eq!(world.run(0), Some(Run::CounterClockwise));
    assert_eq!(world.carriage_um(1), Some(0));
    world.set_switch(2, true).unwrap();
    world.run_until_idle(10).unwrap();
    assert_eq!(world.engine(2).inputs(), 0b10);
    let motion: Vec<String> = world
        .trace()
        .iter()
        .filter(|e| {
            !matches!(
                e.what,
                What::Fired { .. } | What::Output { .. } | What::Start { .. }
            )
        })
        .map(|e| e.to_string())
        .collect();
    let want = [
        "       0 ms  plant #0 runs clockwise at 0.000 mm",
        "       0 ms  step M+",
        "       0 ms  node 0 input 0 = 0",
        "       0 ms  node 1 input 0 = 0",
        "    2000 ms  plant #0 at end",
        "    2000 ms  node 0 input 1 = 1",
        // The chart reverses on the end sensor, in that engine step.
        "    2000 ms  plant #0 runs counter-clockwise at 300.000 mm",
        "    2000 ms  step M-",
        "    2000 ms  node 1 input 1 = 1",
        "    2000 ms  node 0 input 1 = 0",
        "    2000 ms  node 1 input 1 = 0",
        "    4000 ms  plant #0 at home",
        "    4000 ms  node 0 input 0 = 1",
        "    4000 ms  node 1 input 0 = 1",
        "    4000 ms  switch plant #2 set to 1",
        "    4000 ms  node 2 input 1 = 1",
    ];
    assert_eq!(motion, want);
    assert_eq!(
        World::new(
            &nodes,
            vec![Driven {
                name: "B".into(),
                node: 1,
                motor: 0,
                home_in: None,
                end_in: None,
            }
            .into()]
        )
        .err(),
        Some(SimError::NoSuchPlant {
            plant: 0,
            want: "a motor"
        })
    );
}
