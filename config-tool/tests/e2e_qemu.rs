//! End to end with QEMU nodes: every node a `config-tool qemu-node` booting the `qemu-mps2`
//! image, provisioned with its management key, on a real medium. What the host nodes'
//! tests (`e2e.rs`) show of security, shown of the emulated board's own frame path: its
//! config PAN is secured, an unsecured START moves nothing and is counted, and its frame
//! counter, on its emulated flash, survives a kill (a power cut).
//!
//! The image is built by `cd node-fw/boards/qemu-mps2 && cargo build --release` (or named by
//! `QEMU_ELF`). Without
//! it (or without `qemu-system-arm`) these tests say so and pass, unless `REQUIRE_QEMU` is
//! set (CI sets it once the image is built), where they fail.

mod cli_support;
mod e2e_support;

use std::ffi::OsString;

use config_schema::wire::mac::Frame;
use config_schema::wire::msg::{Command, Message, SecurityCounters};
use config_schema::wire::security::AuxHeader;
use node_fw::node::CONFIG_PAN;
use robot_net::demo::{self, Bed, Options};

use cli_support::qemu_image;
use e2e_support::*;

/// Bed options: secured, every node a QEMU instance, its flash in `flash_dir`.
fn qemu_options(elf: &std::path::Path, flash_dir: &TempDir) -> Options {
    let node_command: Vec<OsString> = vec![
        env!("CARGO_BIN_EXE_config-tool").into(),
        "qemu-node".into(),
        // None outlives a test run that is killed.
        "--end-with-parent".into(),
        "--elf".into(),
        elf.as_os_str().to_owned(),
    ];
    Options {
        medium: medium::Config::default(),
        node_command,
        flash_dir: Some(flash_dir.0.clone()),
        timeout: TIMEOUT,
        secured: true,
    }
}

/// The frame counter of a secured frame from `src` (any PAN), if it is one.
fn counter_from(psdu: &[u8], src: u16) -> Option<u32> {
    match Frame::parse(psdu) {
        Ok(Frame::Data { header, payload }) if header.secured && header.src == src => {
            AuxHeader::new_checked(payload)
                .ok()
                .map(|a| a.frame_counter())
        }
        _ => None,
    }
}

/// Issue 11, on the emulated board: a forged START from 0xBEEF started VC's cylinder. A
/// keyed QEMU node takes the push and the commands of the tool (secured), drops an
/// unsecured START without moving anything, counts it as `not_secured` and nothing else,
/// and runs the next cycle.
#[test]
fn a_keyed_qemu_node_drops_an_unsecured_start_and_counts_it() {
    const HOSTILE: u16 = 0xBEEF;
    let Some(elf) = qemu_image() else { return };
    let dir = TempDir::new("qemu-forged");
    let c = robot("paint-robot.ron", 1);
    let mut bed = bring_up(&c, qemu_options(&elf, &dir));
    push_and_home(&mut bed, &c);
    assert_running(&mut bed, &c);
    let secret = bed.secret().expect("a secured bed").clone();
    let (start_role, _) = c.ir.start.clone().expect("a start input");
    let node = c.ir.roles[start_role].address;
    let at_rest = idle(&c.tables[start_role]);

    let mut raw = RawClient::join(bed.medium().addr(), HOSTILE).keyed(&secret);
    let before = raw.security(node);
    assert!(before.keyed, "the QEMU node has its management key");
    let status_before = raw.status(node);
    let start = payload(&Message::Command {
        id: 0x5A5A,
        command: Command::Start,
    });
    raw.send_psdu(&frame(CONFIG_PAN, node, HOSTILE, 1, &start));
    // Asked on the same connection: the answers come after the forged START.
    let status = raw.status(node);
    assert_eq!(
        status.states.as_slice(),
        at_rest.as_slice(),
        "nothing started"
    );
    assert_eq!(status.outputs, status_before.outputs, "no valve moved");
    let after = raw.security(node);
    assert_eq!(
        after.counters,
        SecurityCounters {
            not_secured: before.counters.not_secured + 1,
            ..before.counters
        }
    );
    exact_cycle(&mut bed, &c, 1);
    bed.stop();
}

/// The QEMU node's frame counter is on its emulated flash, persisted in the flash file:
/// killed (a power cut) and booted again, it resumes at the next reservation
/// (`frame_counter::STEP`), above everything it sent, and the tool, which remembers the
/// old counters, takes its frames. Seen on the air: the counters of the node's secured
/// frames, from before the kill to its first answer after the reboot, strictly increase,
/// and the first one at or above `STEP` is `STEP`.
#[test]
fn a_qemu_node_killed_resumes_its_frame_counter_above_everything_it_sent() {
    const NODE: u16 = 0x0011;
    const MARKER: u16 = 0x7E7E;
    const STEP: u32 = node_fw::frame_counter::STEP;
    let Some(elf) = qemu_image() else { return };
    let dir = TempDir::new("qemu-counter");
    let mut bed = Bed::start(qemu_options(&elf, &dir)).expect("bed");
    bed.start_node(NODE).expect("node");
    bed.wait_for_nodes(&[NODE])
        .expect("the node announces itself");
    let mut monitor = Monitor::join(bed.medium().addr());
    bed.command(NODE, Command::Status).expect("status");
    bed.kill_node(NODE);
    bed.start_node(NODE).expect("node again");
    // Resent until answered: the tool opens the answer only above the counter it has seen.
    let s = bed
        .command(NODE, Command::Status)
        .expect("status after the kill");
    assert_eq!((s.generation, s.role.as_str()), (0, ""));
    // The end of what the monitor must have seen: a frame sent after that answer.
    let marker = frame(CONFIG_PAN, MARKER, MARKER, 1, &[0xAA]);
    RawClient::join(bed.medium().addr(), MARKER).send_psdu(&marker);
    let seen = monitor.psdus_until(|p| p == marker.as_slice());
    let counters: Vec<u32> = seen.iter().filter_map(|p| counter_from(p, NODE)).collect();
    assert!(counters.windows(2).all(|w| w[0] < w[1]), "{counters:?}");
    let resumed = counters
        .iter()
        .position(|c| *c >= STEP)
        .unwrap_or_else(|| panic!("no frame after the reboot: {counters:?}"));
    assert!(resumed > 0, "no frame before the kill: {counters:?}");
    assert_eq!(counters[resumed], STEP, "{counters:?}");
    bed.stop();
}

/// Issue 12 on the emulated board: a push on trial while a cycle runs is staged at once
/// and switched at the cycle's end, every node together; the next cycle is the new
/// sequence; then the power goes (every QEMU killed) and every node boots the previous,
/// confirmed generation from its emulated flash and runs it exactly.
#[test]
fn qemu_nodes_switch_at_the_cycle_end_and_a_power_cut_during_the_trial_boots_the_previous_generation(
) {
    let Some(elf) = qemu_image() else { return };
    let flash = TempDir::new("qemu-trial");
    let paint = robot("paint-robot.ron", 1);
    let dip = robot("paint-robot-double-dip.ron", 2);
    let mut bed = bring_up(&paint, qemu_options(&elf, &flash));
    push_and_home(&mut bed, &paint);
    let secret = bed.secret().expect("secured").clone();
    let at = bed.medium().addr();
    let targets = demo::targets(&dip);
    let pusher = std::thread::spawn(move || {
        wait_for_outputs(at, 3);
        let mut radio = second_tool(at, &secret);
        let mut pushed =
            robot_net::push::push(&mut radio, &targets, false, &mut |_, _, _| {}).unwrap();
        robot_net::push::switch_over_as(
            &mut radio,
            &mut pushed,
            2,
            false,
            true,
            std::time::Duration::from_secs(60),
        )
        .unwrap()
    });
    exact_cycle(&mut bed, &paint, 1);
    assert_eq!(pusher.join().unwrap(), node_fw::switch::Verdict::Switched);
    assert_running(&mut bed, &dip);
    exact_cycle(&mut bed, &dip, 1);
    let addrs: Vec<u16> = paint.ir.roles.iter().map(|r| r.address).collect();
    power_cut(&mut bed, &addrs);
    // Booted not homed; the rods are home: homing moves nothing.
    assert_not_homed(&mut bed, &paint);
    assert_eq!(home_ok(&mut bed, &paint), Vec::<String>::new());
    assert_running(&mut bed, &paint);
    exact_cycle(&mut bed, &paint, 2);
    bed.stop();
}

/// Issue 12 on the emulated board: every QEMU node killed mid-cycle and booted again is
/// not homed (a START does nothing), homing runs exactly the steps the rods need, then one
/// START gives an exact cycle (`e2e_homing.rs` on host nodes).
#[test]
fn qemu_nodes_killed_mid_cycle_boot_unhomed_and_homing_then_one_start_gives_an_exact_cycle() {
    let Some(elf) = qemu_image() else { return };
    let flash = TempDir::new("qemu-homing");
    killed_mid_cycle_then_homed(qemu_options(&elf, &flash));
}

/// The worst table the time budget allows (`config_schema::cost`): one input routed to a
/// chart whose state 0 has as many transitions on it, each with a 31-operation guard that
/// never holds, as `validate` lets through. On a counting QEMU node (`-icount shift=0`: an
/// instruction a nanosecond) the rise of that input costs, inside `NodeCore`, no more than
/// the bound: the weights are an upper bound of the real work. Prints both.
#[test]
fn the_worst_table_the_budget_allows_costs_at_most_its_bound_on_qemu() {
    use config_schema::cost::{worst_stimulus, STIMULUS_BUDGET};
    use config_schema::wire::medium::{Link, Peer};
    use config_schema::{Input, Op, Route, Table, Transition};
    use robot_net::push;

    let Some(elf) = qemu_image() else {
        return;
    };
    const NODE: u16 = 0x0021;
    const PIN: u8 = 3;
    let table = |transitions: usize| {
        let mut t = Table::empty("worst");
        t.generation = 1;
        let rise = t.push_event().unwrap();
        t.inputs
            .push(Input {
                pin: PIN,
                rise: Some(rise),
                fall: None,
                var: None,
            })
            .unwrap();
        let mut ops = vec![Op::Const(0)];
        for _ in 0..15 {
            ops.extend([Op::Input(0), Op::And]);
        }
        let never = t.push_expr(&ops).unwrap();
        let tr: Vec<Transition> = (0..transitions)
            .map(|_| Transition {
                from: 0,
                to: 1,
                trigger: Some(0),
                guard: Some(never),
            })
            .collect();
        t.push_chart(0, 1, &[&[], &[]], &tr).unwrap();
        t.routes
            .push(Route {
                event: rise,
                chart: 0,
                input: 0,
            })
            .unwrap();
        t
    };
    let n = (1..=config_schema::limits::MAX_TRANSITIONS)
        .rev()
        .find(|&n| config_schema::validate(&table(n)).is_ok())
        .expect("some table fits");
    let t = table(n);
    let bound = worst_stimulus(&t).cost;
    assert!(
        bound <= STIMULUS_BUDGET && bound > STIMULUS_BUDGET * 9 / 10,
        "{n}: {bound}"
    );

    let count = TempDir::new("worst-count");
    let medium = medium::Medium::start(medium::Config::default()).expect("medium");
    let at = medium.addr();
    let mut node = std::process::Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(["qemu-node", "--addr", &format!("{NODE:#06x}"), "--medium"])
        .arg(at.to_string())
        .arg("--elf")
        .arg(&elf)
        .arg("--count")
        .arg(&count.0)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("qemu-node");
    let mut radio = robot_net::radio::ToolRadio::connect(at, 0x0100).expect("tool");
    let targets = [push::Target {
        role: String::from("worst"),
        addr: NODE,
        blob: robot_compiler::compile::encode(&t).expect("encodes"),
        generation: 1,
    }];
    let mut pushed = push::push(&mut radio, &targets, false, &mut |_, _, _| {}).expect("push");
    let verdict = push::switch_over(
        &mut radio,
        &mut pushed,
        1,
        true,
        std::time::Duration::from_secs(30),
    )
    .expect("switch");
    assert_eq!(verdict, node_fw::switch::Verdict::Switched);
    // Counts of the node's input changes so far, as it logs them (every second).
    let inputs = |want: u64| {
        let end = std::time::Instant::now() + TIMEOUT;
        loop {
            if let Some(c) = demo::read_counts(&count.0, NODE).filter(|c| c.core_inputs >= want) {
                return c;
            }
            assert!(
                std::time::Instant::now() < end,
                "no count of {want} input(s)"
            );
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
    };
    let before = inputs(0);
    let mut plant = medium::Conn::join(at, Peer::Plant).expect("plant");
    plant
        .send(&Link::Pin {
            addr: NODE,
            pin: PIN,
            level: true,
        })
        .expect("pin");
    let after = inputs(before.core_inputs + 1);
    let measured =
        (after.core_input - before.core_input) / (after.core_inputs - before.core_inputs);
    eprintln!(
        "worst table the budget allows: {n} transitions, bound {bound} instructions, measured \
         {measured} on QEMU ({:.2} of the bound)",
        measured as f64 / bound as f64
    );
    assert!(measured <= bound, "measured {measured} > bound {bound}");
    let _ = node.kill();
    let _ = node.wait();
    medium.stop();
}

/// A demo of QEMU nodes stopped by its supervisor (SIGTERM) leaves no QEMU running (each
/// ends with its parent: `qemu-node --end-with-parent`) and no key behind, status 130.
/// Issue: its five QEMU processes ran on for good.
#[cfg(target_os = "linux")]
#[test]
fn an_interrupted_qemu_demo_leaves_no_qemu_running() {
    let Some(elf) = qemu_image() else { return };
    let elf = elf.to_str().expect("a text path").to_string();
    let ended = cli_support::interrupt_demo(&[
        "robot-configs/paint-robot.ron",
        "--qemu",
        "--elf",
        &elf,
        "--cycles",
        "50",
    ]);
    assert_eq!(ended, cli_support::Interrupted::cleanly());
}

/// A QEMU node started by hand (no `--end-with-parent`) ends when its medium stops, as a
/// host node does, says why, and leaves no QEMU running. Found: it ran on for good, its
/// UART talking to no one.
#[cfg(target_os = "linux")]
#[test]
fn a_qemu_node_started_by_hand_ends_when_its_medium_stops() {
    let Some(elf) = qemu_image() else { return };
    let elf = elf.to_str().expect("a text path").to_string();
    let gone =
        cli_support::node_after_its_medium_stops(&["qemu-node", "--addr", "0x0031", "--elf", &elf]);
    assert!(
        gone.status.is_some_and(|s| s.success()),
        "{:?}",
        gone.status
    );
    assert!(
        gone.said
            .contains("the medium closed the connection: the node stops"),
        "{}",
        gone.said
    );
    assert_eq!(gone.started, 1, "QEMU, a child of qemu-node");
    assert_eq!(gone.left, 0, "QEMU processes left running");
}
