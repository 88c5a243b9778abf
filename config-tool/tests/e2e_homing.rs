//! Issue 12, homing, end to end with real processes: every node killed mid-cycle and
//! restarted boots its confirmed table unhomed, where a START does nothing and the plant
//! does not move; homing then runs exactly the steps the positions need (a step whose
//! switch already reads home is skipped), and one START gives an exact cycle.

mod e2e_support;

use e2e_support::*;

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
