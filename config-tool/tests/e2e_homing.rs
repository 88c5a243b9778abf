//! Issue 12, homing, end to end with real processes: every node killed mid-cycle and
//! restarted boots its confirmed table unhomed, where a START does nothing and the plant
//! does not move; homing then runs exactly the steps the positions need (a step whose
//! switch already reads home is skipped), and one START gives an exact cycle.

mod e2e_support;

use e2e_support::*;

/// Push, home, START; once the plant has seen `VC+ GR+ VC- HC+ VC+` (HC+ completed, VC on
/// its way down into the pot) every node process is killed and restarted.
fn killed_mid_cycle_then_homed(medium: medium::Config, tag: &str) {
    let flash = TempDir::new(tag);
    let c = robot("paint-robot.ron", 1);
    let addrs: Vec<u16> = c.ir.roles.iter().map(|r| r.address).collect();
    let mut bed = bring_up(&c, options(medium, Some(&flash)));
    push_and_home(&mut bed, &c);
    assert_running(&mut bed, &c);

    bed.press_start(&c).expect("START");
    let seen: Vec<String> = bed
        .await_strokes(5)
        .expect("five steps")
        .iter()
        .map(|s| s.to_string())
        .collect();
    assert_eq!(seen.join(" "), "VC+ GR+ VC- HC+ VC+");
    power_cut(&mut bed, &addrs);
    // The gripper's monostable valve dropped with the power (a boot cannot hold it): the
    // part is released; the cylinders' valves go off and their rods stay where they are.
    let booted = bed.await_strokes(1).expect("the gripper drops");
    assert_eq!(booted[0].to_string(), "GR-");

    // Booted from flash: generation 1, every chart initial (not homed).
    assert_not_homed(&mut bed, &c);
    let (start_role, _) = c.ir.start.clone().unwrap();
    let before = status(&mut bed, c.ir.roles[start_role].address);
    let after = bed.press_start(&c).expect("START");
    assert_eq!(
        (after.states.as_slice(), after.outputs, after.fault),
        (before.states.as_slice(), before.outputs, None),
        "a START on a machine not homed does nothing"
    );

    // Homing (VC- HC- RC- GR-) from where the power cut left the rods, and nothing else
    // since the boot (no START motion): VC (down, or on its way) and HC (at its end) go
    // home, RC's home switch reads home (skipped), GR- runs its dwell on a valve that is
    // off already (the plant sees no change).
    assert_eq!(
        robot_analysis::sim::steps_text(&c.ir.homing),
        "VC- HC- RC- GR-"
    );
    let homing = home_ok(&mut bed, &c);
    assert_eq!(homing.join(" "), "VC- HC-");
    assert_running(&mut bed, &c);
    let cycle = exact_cycle(&mut bed, &c, 1);
    assert_eq!(robot_analysis::sim::steps_text(&cycle.steps), SEQUENCE_1);
    bed.stop();
}

#[test]
fn every_node_killed_mid_cycle_boots_unhomed_and_homing_then_one_start_gives_an_exact_cycle() {
    killed_mid_cycle_then_homed(medium::Config::default(), "homing-cut");
}

#[test]
fn every_node_killed_mid_cycle_at_20_percent_loss_is_homed_then_runs_an_exact_cycle() {
    killed_mid_cycle_then_homed(
        medium::Config {
            loss: 0.2,
            dup: 0.1,
            delay_ms: (0, 8),
            seed: 0x5EED_0012,
            ..medium::Config::default()
        },
        "homing-cut-lossy",
    );
}
