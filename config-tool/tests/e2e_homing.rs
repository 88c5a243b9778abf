//! Issue 12, homing, end to end with real processes: every node killed mid-cycle and
//! restarted boots its confirmed table unhomed, where a START does nothing and the plant
//! does not move; homing then runs exactly the steps the positions need (a step whose
//! switch already reads home is skipped), and one START gives an exact cycle.

mod e2e_support;

use config_schema::wire::msg::{Command, Status};
use e2e_support::*;
use robot_compiler::Compiled;
use robot_net::demo::Options;

#[test]
fn every_node_killed_mid_cycle_boots_unhomed_and_homing_then_one_start_gives_an_exact_cycle() {
    let flash = TempDir::new("homing-cut");
    killed_mid_cycle_then_homed(options(medium::Config::default(), Some(&flash)));
}

#[test]
fn every_node_killed_mid_cycle_at_20_percent_loss_is_homed_then_runs_an_exact_cycle() {
    let flash = TempDir::new("homing-cut-lossy");
    let lossy = medium::Config {
        loss: 0.2,
        dup: 0.1,
        delay_ms: (0, 8),
        seed: 0x5EED_0012,
        ..medium::Config::default()
    };
    killed_mid_cycle_then_homed(options(lossy, Some(&flash)));
}

/// After a fault, homing is refused until every faulted node is reset; a homing step whose
/// rod is jammed faults on its watchdog, and homing says so.
#[test]
fn homing_is_refused_on_a_faulted_machine_and_a_jammed_homing_step_faults() {
    let c = robot("paint-robot.ron", 1);
    let mut bed = bring_up(&c, options(medium::Config::default(), None));
    push_and_home(&mut bed, &c);
    // VC's rod jams once the plant has seen VC+ GR+: VC- (step 3) does not move.
    jam_after(&mut bed, &c, "VC", 2);
    let cycle = bed.run_cycle(&c, &mut |_, _| {}).unwrap();
    assert_eq!(
        cycle.fault.as_ref().map(|f| (f.role.as_str(), f.code)),
        Some(("VC", Some(0x81))),
        "{}",
        robot_net::demo::cycle_line(1, &cycle)
    );

    // Every node faulted: VC on its watchdog, the others by its fault's publication.
    for r in &c.ir.roles {
        wait_until(&mut bed, r.address, |s| s.fault.is_some());
    }
    let refused = bed.home(&c).unwrap();
    assert_eq!(
        refused.end,
        robot_net::home::HomeEnd::Refused(
            "nodes 0x0011 (VC, 0x81), 0x0012 (GR, 0x82), 0x0013 (HC, 0x82), 0x0014 (RC, 0x82) \
             are faulted: reset each (config-tool reset --node 0x0011; config-tool reset \
             --node 0x0012; config-tool reset --node 0x0013; config-tool reset --node \
             0x0014), acknowledge the alarms (config-tool ack), then config-tool home"
                .to_string()
        )
    );
    for r in &c.ir.roles {
        bed.command(r.address, config_schema::wire::msg::Command::Reset)
            .unwrap();
    }
    assert_not_homed(&mut bed, &c);
    // The watchdog's fault alarm is latched on VC: homing is refused, naming it, until the
    // operator acknowledges it.
    assert_eq!(
        bed.home(&c).unwrap().end,
        robot_net::home::HomeEnd::Refused(
            "node 0x0011 (VC) has a fault alarm latched: chart `fault`: its motion watchdog \
             expired (code 0x81): acknowledge it first (config-tool ack)"
                .to_string()
        )
    );
    let acked = bed.alarms(&c, true).unwrap();
    assert!(acked.iter().all(|r| r.blocking().is_none()), "{acked:?}");
    // Homing commands VC- first: the rod (at its end) is still jammed.
    let homing = bed.home(&c).unwrap();
    let robot_net::home::HomeEnd::Faulted {
        role,
        addr,
        code,
        others,
    } = &homing.end
    else {
        panic!("{}", robot_net::demo::homed_line(&homing));
    };
    assert_eq!((role.as_str(), *addr, *code), ("VC", 0x0011, 0x81));
    // The nodes its fault stopped, each to reset (those it reached by then).
    assert!(
        others.iter().all(|a| [0x0012, 0x0013, 0x0014].contains(a)),
        "{others:?}"
    );
    assert_eq!(robot_analysis::sim::steps_text(&homing.steps), "VC-");
    bed.stop();
}

/// A robot without link keys, RC's node killed and restarted at 20 % loss (it boots its
/// table from flash, not homed): it lost its side of its links while its publishers
/// numbered on. Before, the machine stalled (homing waited out its time with VC moving; a
/// `reset` of HC and VC got it out): the restarted receiver waited for a seq 0 that never
/// came. Now its first event past seq 0 makes it ask the publisher to number the link
/// again: homing runs with no reset, and a START gives an exact cycle.
#[test]
fn an_unsecured_robots_restarted_node_is_homed_without_a_reset_then_runs_an_exact_cycle() {
    let dir = TempDir::new("unsecured-restart");
    let flash = TempDir::new("unsecured-restart-flash");
    let (_, c) = unsecured_robot(&dir, "paint-robot.ron");
    let lossy = medium::Config {
        loss: 0.2,
        dup: 0.1,
        delay_ms: (0, 8),
        seed: 0x5EED_0016,
        ..medium::Config::default()
    };
    let mut opts = options(lossy, Some(&flash));
    opts.secured = false;
    let mut bed = bring_up(&c, opts);
    push_and_home(&mut bed, &c);
    // A cycle: every link numbers past seq 0.
    exact_cycle(&mut bed, &c, 1);
    let rc = addr_of(&c, "RC");
    bed.kill_node(rc);
    bed.start_node(rc).unwrap();
    bed.wait_for_nodes(&[rc]).unwrap();
    // RC's boot event tells the others the machine is not homed any more. The rods are
    // home: homing moves nothing.
    assert_eq!(home_ok(&mut bed, &c), Vec::<String>::new());
    assert_running(&mut bed, &c);
    exact_cycle(&mut bed, &c, 2);
    bed.stop();
}

/// A secured robot, GR's node alone loses power mid-cycle (the machine under way, the
/// gripper holding the part): before, every other node waited for an event that had
/// passed, `moving` for ever, and `home` refused until every node was reset by hand. Now
/// the restarted node's greeting tells its peers: each one under way stops in a fault
/// (`0x86`, outputs at their fault levels), a node at rest stays at rest; the operator's
/// reset of the faulted nodes, acknowledging their alarms, homing and a START give an
/// exact cycle.
#[test]
fn one_node_cut_mid_cycle_faults_the_nodes_under_way_then_reset_and_homing_give_an_exact_cycle() {
    let flash = TempDir::new("one-cut");
    let c = robot("paint-robot.ron", 1);
    one_node_cut_mid_cycle(&c, options(medium::Config::default(), Some(&flash)));
}

/// As above, on a robot without link keys at 20 % loss: the restarted node's boot notice
/// (a challenge in clear, sent a few times) tells its peers.
#[test]
fn an_unsecured_robots_one_node_cut_mid_cycle_at_20_percent_loss_faults_the_nodes_under_way() {
    let dir = TempDir::new("one-cut-unsecured");
    let flash = TempDir::new("one-cut-unsecured-flash");
    let (_, c) = unsecured_robot(&dir, "paint-robot.ron");
    let lossy = medium::Config {
        loss: 0.2,
        dup: 0.1,
        delay_ms: (0, 8),
        seed: 0x5EED_0041,
        ..medium::Config::default()
    };
    let mut opts = options(lossy, Some(&flash));
    opts.secured = false;
    one_node_cut_mid_cycle(&c, opts);
}

/// Push, home, START; once the plant has seen `VC+ GR+ VC- HC+ VC+`, GR's node loses
/// power and boots again: VC (in the middle of its chart until the cycle's last step) is
/// faulted `0x86`, GR not homed and not faulted, every other node faulted `0x86` or at
/// rest; then reset, acknowledge, home, an exact cycle.
fn one_node_cut_mid_cycle(c: &Compiled, options: Options) {
    let mut bed = bring_up(c, options);
    push_and_home(&mut bed, c);
    bed.press_start(c).expect("START");
    let seen: Vec<String> = (bed.await_strokes(5).expect("five steps").iter())
        .map(|s| s.to_string())
        .collect();
    assert_eq!(seen.join(" "), "VC+ GR+ VC- HC+ VC+");
    let gr = addr_of(c, "GR");
    power_cut(&mut bed, &[gr]);

    let restarted = 0x80 | config_schema::alarm::FAULT_PEER_RESTART;
    let vc = wait_until(&mut bed, addr_of(c, "VC"), |s| s.fault.is_some());
    assert_eq!(vc.fault, Some(restarted), "VC: {vc:?}");
    let mut faulted = Vec::new();
    for (r, t) in c.ir.roles.iter().zip(&c.tables) {
        let rests = |s: &Status| {
            (t.charts.iter().zip(&s.states)).all(|(ch, &at)| at == ch.idle || at == ch.initial)
        };
        let s = wait_until(&mut bed, r.address, |s| s.fault.is_some() || rests(s));
        if r.address == gr {
            assert_eq!(
                (s.fault, s.states),
                (None, initial(t).into_iter().collect())
            );
        } else if s.fault.is_some() {
            assert_eq!(s.fault, Some(restarted), "{}: {s:?}", r.name);
            faulted.push(r.address);
        }
    }
    assert!(faulted.contains(&addr_of(c, "VC")), "{faulted:?}");
    for &a in &faulted {
        bed.command(a, Command::Reset).expect("reset");
    }
    // The faults' alarms stay latched until the operator acknowledges them.
    let refused = bed.home(c).unwrap().end;
    assert_eq!(
        refused,
        robot_net::home::HomeEnd::Refused(
            "node 0x0011 (VC) has a fault alarm latched: a peer restarted (a power cut?) while \
             this node was under way (code 0x86): acknowledge it first (config-tool ack)"
                .to_string()
        )
    );
    let acked = bed.alarms(c, true).unwrap();
    assert!(acked.iter().all(|r| r.blocking().is_none()), "{acked:?}");
    home_ok(&mut bed, c);
    assert_running(&mut bed, c);
    exact_cycle(&mut bed, c, 2);
    bed.stop();
}

/// GR's node loses power for good while the gripper holds the part: its monostable valve
/// drops with the power, and the plant sees the gripper open (`GR-`) at once. Before, the
/// plant kept the dead node's last levels: the gripper held the part until the node
/// booted again.
#[test]
fn a_dead_nodes_valves_drop_with_its_power() {
    let c = robot("paint-robot.ron", 1);
    let mut bed = bring_up(&c, options(medium::Config::default(), None));
    push_and_home(&mut bed, &c);
    bed.press_start(&c).expect("START");
    let seen: Vec<String> = (bed.await_strokes(2).expect("two steps").iter())
        .map(|s| s.to_string())
        .collect();
    assert_eq!(seen.join(" "), "VC+ GR+");
    bed.kill_node(addr_of(&c, "GR"));
    let dropped = bed.await_strokes(1).expect("the gripper opens");
    assert_eq!(dropped[0].to_string(), "GR-");
    bed.stop();
}
