//! End to end: `config-tool demo robot-configs/ball-sorter.ron` on real processes (the
//! medium, three unconfigured node processes, the live plant with its ball feed) at 20 %
//! frame loss with a fixed seed sorts the robot's 13 balls into exactly the bins `sim`
//! gives. The test waits for the demo process to end (it ends when the last ball landed,
//! or on the bed's timeout); no sleeps.

use std::path::PathBuf;

mod cli_support;
mod e2e_support;
use cli_support::{demo, text};

/// `    0.743 s  ball   1: gray     bin 3  (as sim)` -> (1, "gray", 3, "as sim").
fn balls(stdout: &str) -> Vec<(usize, String, usize, String)> {
    stdout
        .lines()
        .filter_map(|l| {
            let (_, rest) = l.split_once(" s  ball ")?;
            let (n, rest) = rest.split_once(':')?;
            let mut w = rest.split_whitespace();
            let colour = w.next()?.to_string();
            (w.next()? == "bin").then_some(())?;
            let bin = w.next()?.parse().ok()?;
            let note = rest.split_once('(')?.1.trim_end_matches(')').to_string();
            Some((n.trim().parse().ok()?, colour, bin, note))
        })
        .collect()
}

/// The robot's 13 balls, each with the bin `sim` gives it.
const SORTED: [(&str, usize); 13] = [
    ("gray", 3),
    ("black", 1),
    ("black", 1),
    ("orange", 1),
    ("black", 1),
    ("gray", 2),
    ("black", 2),
    ("black", 2),
    ("orange", 1),
    ("gray", 1),
    ("black", 2),
    ("orange", 1),
    ("gray", 1),
];

#[test]
fn the_station_sorts_its_feed_at_20_percent_loss_into_sims_bins() {
    let out = demo(&[
        "robot-configs/ball-sorter.ron",
        "--loss",
        "0.2",
        "--seed",
        "7",
    ]);
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stdout}\n{stderr}");
    let got = balls(&stdout);
    let want: Vec<(usize, String, usize, String)> = SORTED
        .iter()
        .enumerate()
        .map(|(i, (c, b))| (i + 1, c.to_string(), *b, String::from("as sim")))
        .collect();
    assert_eq!(got, want, "{stdout}");
    let lines: Vec<&str> = stdout.lines().collect();
    assert!(lines.contains(
        &"sorted: bin 1: 8, bin 2: 4, bin 3: 1; sim: bin 1: 8, bin 2: 4, bin 3: 1; every ball \
          in sim's bin"
    ));
    assert_eq!(
        lines.last().copied(),
        Some("demo: every ball sorted into sim's bin")
    );
    // The lossy radio did lose frames (the figure is the medium's, for this seed).
    let medium = (lines.iter())
        .find(|l| l.starts_with("medium: "))
        .expect("the medium's totals");
    assert!(!medium.contains(" 0 lost"), "{medium}");
}

/// The same on QEMU nodes booting the firmware image (`cd node-fw/boards/qemu-mps2 &&
/// cargo build --release`); without the image or `qemu-system-arm` it says so and passes,
/// unless `REQUIRE_QEMU` is set.
#[test]
fn the_station_sorts_its_feed_on_qemu_nodes_into_sims_bins() {
    let elf = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(robot_net::demo::QEMU_ELF);
    if let Err(e) = robot_net::demo::check_elf(&elf).and(robot_net::demo::check_qemu()) {
        assert!(
            std::env::var_os("REQUIRE_QEMU").is_none(),
            "REQUIRE_QEMU is set: {e}"
        );
        eprintln!("skipped: {e}");
        return;
    }
    let elf = elf.to_string_lossy().into_owned();
    let out = demo(&[
        "robot-configs/ball-sorter.ron",
        "--qemu",
        "--elf",
        &elf,
        "--loss",
        "0.2",
        "--seed",
        "7",
    ]);
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stdout}\n{stderr}");
    let bins: Vec<usize> = balls(&stdout).iter().map(|b| b.2).collect();
    assert_eq!(bins, [3, 1, 1, 1, 1, 2, 2, 2, 1, 1, 2, 1, 1], "{stdout}");
    assert!(balls(&stdout).iter().all(|b| b.3 == "as sim"), "{stdout}");
}

/// `config-tool plant` of the station, beside host nodes started and pushed by hand: it
/// fed no ball (it knew only cylinders): START, and nothing happened. Now it feeds the
/// robot's balls as `demo` does, each landing on a line, in the bins `sim` gives.
#[test]
fn the_plant_command_feeds_the_stations_balls() {
    let c = e2e_support::robot("ball-sorter.ron", 1);
    let (mut bed, plant) = e2e_support::pushed_with_plant_process(&c, "ball-sorter.ron");
    bed.press_start(&c).expect("START");
    let mut landed = Vec::new();
    // Landings are stamped on the medium's clock, as the steps are: each after the first
    // push that fed a ball (they were stamped from the plant's start, seconds before).
    let mut first_push = None;
    while landed.len() < 13 {
        let (at, said) = plant.next_timed();
        if said.starts_with("PUSHER+") {
            first_push.get_or_insert(at);
        }
        if said.starts_with("ball ") {
            let pushed = first_push.expect("a push before a landing");
            assert!(
                at >= pushed,
                "{said} at {at} s, the first push at {pushed} s"
            );
            landed.push(said);
        }
    }
    let want: Vec<String> = SORTED
        .iter()
        .enumerate()
        .map(|(i, (c, b))| format!("ball {} ({c}) landed in bin {b}", i + 1))
        .collect();
    assert_eq!(landed, want);
    drop(plant);
    bed.stop();
}
