//! Issue 12, end to end with real processes: a push while the machine runs is staged at
//! once and switched at the machine's next idle point, every node together; a node killed
//! between stage and switch comes back on the old generation with the new one staged, and
//! the switch-over finishes.

mod e2e_support;

use std::time::Duration;

use node_fw::ota::Progress;
use node_fw::switch::{NodeState, Verdict};
use robot_net::push;

use e2e_support::*;

/// Issue 12: a push of the double dip at 1.6 s into a cycle (VC down in the paint pot,
/// holding the part) switched each node the moment its table arrived: the gripper opened
/// over the pot. Now, at 20 % loss: the cycle in progress completes exactly on the old
/// generation (the part is never dropped: no GR- out of turn), every node switches at its
/// end, and the next cycle is exactly the new sequence.
#[test]
fn a_push_during_a_cycle_switches_at_its_end_and_the_next_cycle_is_the_new_sequence() {
    let paint = robot("paint-robot.ron", 1);
    let dip = robot("paint-robot-double-dip.ron", 2);
    let lossy = medium::Config {
        loss: 0.2,
        dup: 0.1,
        delay_ms: (0, 8),
        seed: 12,
        ..medium::Config::default()
    };
    let mut bed = bring_up(&paint, options(lossy, None));
    push_and_home(&mut bed, &paint);
    let secret = bed.secret().expect("secured").clone();
    let at = bed.medium().addr();
    let targets = robot_net::demo::targets(&dip);
    let pusher = std::thread::spawn(move || {
        // VC+ GR+ VC-: the part is held, VC on its way down.
        wait_for_outputs(at, 3);
        let mut radio = second_tool(at, &secret);
        let mut pushed = push::push(&mut radio, &targets, false, &mut |_, _, _| {}).unwrap();
        let staged: Vec<Progress> = pushed.iter().map(|p| p.progress).collect();
        let verdict =
            push::switch_over(&mut radio, &mut pushed, 2, false, Duration::from_secs(60)).unwrap();
        (staged, verdict, pushed)
    });
    // The cycle under way runs to its end on generation 1, exactly.
    exact_cycle(&mut bed, &paint, 1);
    let (staged, verdict, pushed) = pusher.join().unwrap();
    assert!(staged.iter().all(|p| *p == Progress::Done), "{staged:?}");
    assert_eq!(verdict, Verdict::Switched);
    assert!(pushed.iter().all(|p| p.switch == Some(NodeState::Switched)));
    assert_running(&mut bed, &dip);
    for n in 1..=2 {
        exact_cycle(&mut bed, &dip, n);
    }
    bed.stop();
}

/// A node killed between stage and switch boots the old generation with the new one staged
/// (status says so); the switch-over then finishes on every node.
#[test]
fn a_node_killed_between_stage_and_switch_comes_back_staged_and_the_switch_finishes() {
    let flash = TempDir::new("stage-kill");
    let paint = robot("paint-robot.ron", 1);
    let dip = robot("paint-robot-double-dip.ron", 2);
    let mut bed = bring_up(&paint, options(medium::Config::default(), Some(&flash)));
    push_and_home(&mut bed, &paint);
    let mut pushed = bed.stage(&dip, false, &mut |_, _, _| {}).unwrap();
    assert!(pushed.iter().all(|p| p.progress == Progress::Done));
    let gr = addr_of(&paint, "GR");
    let s = status(&mut bed, gr);
    assert_eq!((s.generation, s.staged), (1, 2));
    bed.kill_node(gr);
    bed.start_node(gr).unwrap();
    let s = status(&mut bed, gr);
    assert_eq!(
        (s.generation, s.staged),
        (1, 2),
        "rebooted: old running, new staged"
    );
    // GR's boot told VC: the machine is not homed (at rest: the switch need not wait).
    let vc = addr_of(&paint, "VC");
    wait_until(&mut bed, vc, |s| {
        s.states.first() == Some(&initial(&paint.tables[0])[0])
    });
    let verdict = bed
        .switch_over(&mut pushed, 2, false, Duration::from_secs(30))
        .unwrap();
    assert_eq!(verdict, Verdict::Switched);
    assert_not_homed_node(&mut bed, &dip, "VC");
    let s = status(&mut bed, gr);
    assert_eq!((s.generation, s.staged), (2, 0));
    home_ok(&mut bed, &dip);
    assert_running(&mut bed, &dip);
    exact_cycle(&mut bed, &dip, 1);
    bed.stop();
}

/// A push with one node down switches no node: the others keep the new table staged and
/// run the old one, and nothing is armed. Found: every node that had staged switched while
/// `push` said "nothing switched", the machine split across two robots.
#[test]
fn a_push_that_a_node_missed_switches_no_node() {
    let paint = robot("paint-robot.ron", 1);
    let dip = robot("paint-robot-double-dip.ron", 2);
    let mut bed = bring_up(&paint, options(medium::Config::default(), None));
    push_and_home(&mut bed, &paint);
    let gr = addr_of(&paint, "GR");
    bed.kill_node(gr);
    let mut pushed = bed.stage(&dip, false, &mut |_, _, _| {}).unwrap();
    let staged: Vec<(u16, Progress)> = pushed.iter().map(|p| (p.addr, p.progress)).collect();
    for (addr, progress) in &staged {
        let want = if *addr == gr {
            Progress::GaveUp
        } else {
            Progress::Done
        };
        assert_eq!(*progress, want, "{addr:#06x}");
    }
    let verdict = bed
        .switch_over(&mut pushed, 2, false, Duration::from_secs(30))
        .unwrap();
    assert_eq!(verdict, Verdict::Aborted);
    assert!(pushed.iter().all(|p| p.switch.is_none()), "{pushed:?}");
    for (addr, _) in staged.iter().filter(|(a, _)| *a != gr) {
        let s = status(&mut bed, *addr);
        assert_eq!((s.generation, s.staged), (1, 2), "{addr:#06x}");
    }
    bed.stop();
}

/// A push of the staged generation with another table replaces the staged one. Found: with
/// the double dip staged as generation 2, a push of the paint robot as generation 2 was
/// answered `Staged` at once, and the switch-over ran the double dip.
#[test]
fn a_push_of_the_staged_generation_with_another_table_replaces_it() {
    let paint = robot("paint-robot.ron", 1);
    let dip = robot("paint-robot-double-dip.ron", 2);
    let paint_2 = robot("paint-robot.ron", 2);
    let mut bed = bring_up(&paint, options(medium::Config::default(), None));
    push_and_home(&mut bed, &paint);
    let staged = bed.stage(&dip, false, &mut |_, _, _| {}).unwrap();
    assert!(staged.iter().all(|p| p.progress == Progress::Done));
    let mut pushed = bed.stage(&paint_2, false, &mut |_, _, _| {}).unwrap();
    assert!(pushed.iter().all(|p| p.progress == Progress::Done));
    // A role whose table differs is sent again; one whose table is the same (GR, HC
    // here) is answered `Staged` at its begin.
    for p in &pushed {
        let role = |c: &robot_compiler::Compiled| {
            let i =
                c.ir.roles
                    .iter()
                    .position(|r| r.name == p.role)
                    .expect("role");
            c.blobs[i].clone()
        };
        let differs = role(&dip) != role(&paint_2);
        assert_eq!(p.stats.frames > 1, differs, "{}: {p:?}", p.role);
    }
    assert!(pushed.iter().any(|p| p.stats.frames > 1));
    let verdict = bed
        .switch_over(&mut pushed, 2, false, Duration::from_secs(30))
        .unwrap();
    assert_eq!(verdict, Verdict::Switched);
    exact_cycle(&mut bed, &paint_2, 1);
    bed.stop();
}

/// Every node's (generation, on trial, previous).
fn where_all(bed: &mut robot_net::demo::Bed, addrs: &[u16]) -> Vec<(u32, bool, u32)> {
    addrs
        .iter()
        .map(|&a| {
            let s = status(bed, a);
            (s.generation, s.trial, s.previous)
        })
        .collect()
}

/// Stages `c` and switches it over on trial.
fn on_trial(bed: &mut robot_net::demo::Bed, c: &robot_compiler::Compiled) {
    let mut pushed = bed.stage(c, false, &mut |_, _, _| {}).unwrap();
    let verdict = push::switch_over_as(
        bed.radio(),
        &mut pushed,
        c.ir.generation,
        false,
        true,
        Duration::from_secs(30),
    )
    .unwrap();
    assert_eq!(verdict, Verdict::Switched);
}

/// Trial and rollback, as MCUboot does for images: a generation switched on trial is
/// left by a power cut (every node boots the previous one) or by `rollback`; once
/// confirmed it stays across a power cut.
#[test]
fn a_trial_is_left_by_a_power_cut_or_a_rollback_and_stays_once_confirmed() {
    let flash = TempDir::new("trial");
    let paint = robot("paint-robot.ron", 1);
    let mut bed = bring_up(&paint, options(medium::Config::default(), Some(&flash)));
    let addrs: Vec<u16> = paint.ir.roles.iter().map(|r| r.address).collect();
    push_and_home(&mut bed, &paint);
    let n = addrs.len();

    // On trial, then the power goes: generation 1 again.
    on_trial(&mut bed, &robot("paint-robot-double-dip.ron", 2));
    assert_eq!(where_all(&mut bed, &addrs), vec![(2, true, 1); n]);
    power_cut(&mut bed, &addrs);
    assert_eq!(where_all(&mut bed, &addrs), vec![(1, false, 0); n]);
    // Booted: not homed (the rods are home: homing moves nothing).
    assert_not_homed(&mut bed, &paint);
    assert_eq!(home_ok(&mut bed, &paint), Vec::<String>::new());
    exact_cycle(&mut bed, &paint, 1);

    // On trial, then rolled back on demand: generation 1 again, at once an exact cycle.
    on_trial(&mut bed, &robot("paint-robot-double-dip.ron", 3));
    assert_eq!(where_all(&mut bed, &addrs), vec![(3, true, 1); n]);
    let (verdict, _) =
        push::rollback(bed.radio(), &addrs, 1, false, Duration::from_secs(30)).unwrap();
    assert_eq!(verdict, Verdict::Switched);
    assert_eq!(where_all(&mut bed, &addrs), vec![(1, false, 0); n]);
    exact_cycle(&mut bed, &paint, 2);

    // On trial and confirmed: it stays across a power cut.
    let dip = robot("paint-robot-double-dip.ron", 4);
    on_trial(&mut bed, &dip);
    let answers = push::confirm(bed.radio(), &addrs, 4, Duration::from_secs(10)).unwrap();
    assert!(answers
        .iter()
        .all(|a| a.1 == Some(config_schema::wire::msg::ConfigReply::Confirmed)));
    assert_eq!(where_all(&mut bed, &addrs), vec![(4, false, 1); n]);
    power_cut(&mut bed, &addrs);
    assert_eq!(where_all(&mut bed, &addrs), vec![(4, false, 1); n]);
    assert_not_homed(&mut bed, &dip);
    assert_eq!(home_ok(&mut bed, &dip), Vec::<String>::new());
    exact_cycle(&mut bed, &dip, 1);
    bed.stop();
}

/// A node that lost power between cycles and booted again from its flash: its peers kept
/// numbering their links to it, and its fresh receivers, waiting for seq 0, dropped every
/// event (the next cycle stalled). Its greeting now tells each peer to number again. Its
/// boot makes the machine not homed (its gripper let go): a START moves nothing until
/// HOME.
#[test]
fn a_node_that_rebooted_between_cycles_takes_part_in_the_next_cycle() {
    let flash = TempDir::new("reboot-one");
    let paint = robot("paint-robot.ron", 1);
    let mut bed = bring_up(&paint, options(medium::Config::default(), Some(&flash)));
    push_and_home(&mut bed, &paint);
    exact_cycle(&mut bed, &paint, 1);
    let gr = addr_of(&paint, "GR");
    power_cut(&mut bed, &[gr]);
    let vc = addr_of(&paint, "VC");
    wait_until(&mut bed, vc, |s| {
        s.states.first() == Some(&initial(&paint.tables[0])[0])
    });
    assert_not_homed_node(&mut bed, &paint, "VC");
    home_ok(&mut bed, &paint);
    assert_running(&mut bed, &paint);
    for n in 2..=3 {
        exact_cycle(&mut bed, &paint, n);
    }
    bed.stop();
}

/// A second tool, in a thread, watching the trial of `addrs` (back to generation 1 unless
/// confirmed) for `window`, asking every 200 ms; `wait`: how long a rollback waits for the
/// idle point.
fn watch_from_a_second_tool(
    bed: &robot_net::demo::Bed,
    addrs: &[u16],
    window: push::TrialWindow,
    wait: Duration,
) -> std::thread::JoinHandle<push::TrialEnd> {
    let secret = bed.secret().expect("secured").clone();
    let at = bed.medium().addr();
    let watched = addrs.to_vec();
    std::thread::spawn(move || {
        let mut radio = second_tool(at, &secret);
        let every = Duration::from_millis(200);
        let mut ids = push::Ids::default();
        push::watch_trial_for(
            &mut radio,
            &mut ids,
            (&watched, 1),
            window,
            (every, wait),
            &|| false,
        )
        .unwrap()
    })
}

/// A trial the tool watches: a node that faults during it sends every node back to the
/// previous generation at once; a window that ends unconfirmed sends them back at the idle
/// point.
#[test]
fn a_watched_trial_rolls_back_on_a_fault_or_when_its_window_ends_unconfirmed() {
    let flash = TempDir::new("watched");
    let paint = robot("paint-robot.ron", 1);
    let dip = robot("paint-robot-double-dip.ron", 2);
    let mut bed = bring_up(&paint, options(medium::Config::default(), Some(&flash)));
    let addrs: Vec<u16> = paint.ir.roles.iter().map(|r| r.address).collect();
    push_and_home(&mut bed, &paint);

    // Expired: nobody confirms within 1 s.
    on_trial(&mut bed, &dip);
    let mut ids = push::Ids::default();
    let end = push::watch_trial(
        bed.radio(),
        &mut ids,
        &addrs,
        1,
        Duration::from_secs(1),
        Duration::from_millis(200),
        Duration::from_secs(30),
    )
    .unwrap();
    assert_eq!(
        end,
        push::TrialEnd::Expired {
            rolled_back: Verdict::Switched
        }
    );
    assert_running(&mut bed, &paint);

    // Faulted: VC's rod jams after the first step of a cycle on the trial generation.
    let dip3 = robot("paint-robot-double-dip.ron", 3);
    on_trial(&mut bed, &dip3);
    let actuators = robot_net::live_plant::actuators(&dip3).unwrap();
    let vc = actuators.iter().position(|a| a.name == "VC").unwrap();
    bed.set_plant_injected(
        actuators.clone(),
        Some(robot_net::live_plant::Injection {
            after: 1,
            actuator: vc,
            kind: robot_net::live_plant::Jam::Stuck,
        }),
    )
    .unwrap();
    let window = push::TrialWindow {
        time: Some(Duration::from_secs(60)),
        cycles: None,
    };
    let watcher = watch_from_a_second_tool(&bed, &addrs, window, Duration::from_secs(30));
    let (start_role, _) = dip3.ir.start.clone().unwrap();
    bed.command(
        dip3.ir.roles[start_role].address,
        config_schema::wire::msg::Command::Start,
    )
    .unwrap();
    // The watch ends when it sees the fault (the motion watchdog) and has rolled back.
    let end = watcher.join().unwrap();
    assert!(
        matches!(
            end,
            push::TrialEnd::Faulted {
                rolled_back: Verdict::Switched,
                ..
            }
        ),
        "{end:?}"
    );
    // Every node back on generation 1 at once (the machine stopped, faulted): in its
    // initial states, not homed, not faulted. (The jammed rod: no cycle is run here.)
    assert_not_homed(&mut bed, &paint);
    assert_eq!(
        where_all(&mut bed, &addrs),
        vec![(1, false, 0); addrs.len()]
    );
    bed.stop();
}

/// A trial window counted in cycles: the machine runs two cycles on the trial generation,
/// nobody confirms, and after the second every node goes back to the previous generation
/// at the idle point (homed: the next cycle is the old sequence at once).
#[test]
fn a_trial_watched_for_two_cycles_rolls_back_after_the_second() {
    let flash = TempDir::new("cycles");
    let paint = robot("paint-robot.ron", 1);
    let dip = robot("paint-robot-double-dip.ron", 2);
    let mut bed = bring_up(&paint, options(medium::Config::default(), Some(&flash)));
    let addrs: Vec<u16> = paint.ir.roles.iter().map(|r| r.address).collect();
    push_and_home(&mut bed, &paint);
    on_trial(&mut bed, &dip);
    let window = push::TrialWindow {
        time: None,
        cycles: Some(2),
    };
    let watcher = watch_from_a_second_tool(&bed, &addrs, window, Duration::from_secs(60));
    for n in 1..=2 {
        exact_cycle(&mut bed, &dip, n);
    }
    assert_eq!(
        watcher.join().unwrap(),
        push::TrialEnd::Expired {
            rolled_back: Verdict::Switched
        }
    );
    assert_running(&mut bed, &paint);
    exact_cycle(&mut bed, &paint, 1);
    bed.stop();
}
