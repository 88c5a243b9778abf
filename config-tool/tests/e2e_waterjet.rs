//! End to end: `config-tool demo robot-configs/waterjet-transport.ron` on real processes
//! (the medium, three unconfigured node processes, the live plant with the pusher's motor,
//! the belt it moves, the fault contact and the operator's buttons) runs seed 001's fig. 9
//! as the operator would: START, the fault in step 2, RELEASE, the fault cleared, the
//! alarm acknowledged, RESTART and a full transport cycle; every step's motions and
//! function places as `sim` has them, the pusher stopped by the fault contact's own node.
//! The same on QEMU nodes booting the firmware image, at 20 % loss (skipped without the
//! image unless `REQUIRE_QEMU` is set, as CI does once it has built it).
//! `config-tool plant` takes the operator's hand from its standard input (the fault
//! contact, RELEASE, RESTART) and runs the transport's motor.
//! The tests wait for the processes' lines and the nodes' reports (each step waits for
//! events); no sleeps, no timing asserted.

mod cli_support;
mod e2e_support;
use cli_support::{demo, qemu_image, text};

/// The script's lines: each step, its functions, the stop (up to its timing) and the
/// alarm.
fn steps(stdout: &str) -> Vec<String> {
    stdout
        .lines()
        .filter(|l| {
            l.starts_with("step ")
                || l.starts_with("  functions: ")
                || l.starts_with("  stopped by ")
                || l.starts_with("  alarm on ")
                || l.contains("DIFFERENT")
        })
        .map(|l| l.split(';').next().unwrap_or(l).to_string())
        .collect()
}

const FIG9: &[&str] = &[
    "step 1: START: PUSHER clockwise",
    "  functions: Operation: Auto, Transport: Step2, Pusher: Clockwise, FaultDetection: Ok, \
     Belt: Forward",
    "step 2: the fault contact closes: PUSHER stopped",
    "  stopped by node 0x0032 (PUSHER), the fault contact's own node: same node",
    "  functions: Operation: Halted, Transport: ReadyToCut, Pusher: Stopped, FaultDetection: \
     Faulted, Belt: Stopped",
    "step 3: RELEASE pressed: PUSHER counter-clockwise, PUSHER home, PUSHER stopped",
    "  functions: Operation: Releasing, Transport: ReadyToCut, Pusher: Stopped, \
     FaultDetection: Released, Belt: Stopped",
    "step 4: the fault contact opens: nothing moves",
    "  functions: Operation: Releasing, Transport: ReadyToCut, Pusher: Stopped, \
     FaultDetection: Ok, Belt: Stopped",
    "step 5: the alarm acknowledged: nothing moves",
    "  functions: Operation: Releasing, Transport: ReadyToCut, Pusher: Stopped, \
     FaultDetection: Ok, Belt: Stopped",
    "  alarm on CABINET: alarm \"pusher fault\" (FaultDetection.Faulted || \
     FaultDetection.Released) (Fault), acknowledged",
    "step 6: RESTART pressed: PUSHER clockwise, PUSHER at its end, PUSHER stopped, PUSHER \
     counter-clockwise, PUSHER home, PUSHER stopped",
    "  functions: Operation: Auto, Transport: ReadyToCut, Pusher: Stopped, FaultDetection: \
     Ok, Belt: Stopped",
];

fn fig9() -> Vec<String> {
    FIG9.iter().map(|l| l.to_string()).collect()
}

fn assert_fig9(args: &[&str]) -> Vec<String> {
    let out = demo(args);
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stdout}\n{stderr}");
    assert_eq!(steps(&stdout), fig9(), "{stdout}");
    let lines: Vec<String> = stdout.lines().map(str::to_string).collect();
    assert_eq!(
        lines.last().map(String::as_str),
        Some("demo: every step as sim")
    );
    lines
}

#[test]
fn fig_9_on_real_processes_runs_every_step_as_sim() {
    assert_fig9(&["robot-configs/waterjet-transport.ron"]);
}

#[test]
fn fig_9_at_20_percent_loss_runs_every_step_as_sim() {
    let lines = assert_fig9(&[
        "robot-configs/waterjet-transport.ron",
        "--loss",
        "0.2",
        "--seed",
        "7",
    ]);
    // The lossy radio did lose frames (the figure is the medium's, for this seed).
    let medium = (lines.iter())
        .find(|l| l.starts_with("medium: "))
        .expect("the medium's totals");
    assert!(!medium.contains(" 0 lost"), "{medium}");
}

#[test]
fn fig_9_on_qemu_nodes_at_20_percent_loss_runs_every_step_as_sim() {
    let Some(elf) = qemu_image() else { return };
    let elf = elf.to_string_lossy().into_owned();
    let lines = assert_fig9(&[
        "robot-configs/waterjet-transport.ron",
        "--qemu",
        "--elf",
        &elf,
        "--loss",
        "0.2",
        "--seed",
        "7",
    ]);
    let medium = (lines.iter())
        .find(|l| l.starts_with("medium: "))
        .expect("the medium's totals");
    assert!(!medium.contains(" 0 lost"), "{medium}");
}

/// The pusher's motions in one transport cycle, as `plant` says them.
const TRANSPORT: [&str; 6] = [
    "PUSHER clockwise",
    "PUSHER at its end",
    "PUSHER stopped",
    "PUSHER counter-clockwise",
    "PUSHER home",
    "PUSHER stopped",
];

/// `config-tool plant` of the transport, beside host nodes started and pushed by hand:
/// it knew only cylinders and printed nothing, the pusher's motor output driven for ever
/// and no sensor ever changing. Now its motor runs as in `demo`: START, and a whole
/// transport cycle, each motion on a line.
#[test]
fn the_plant_command_runs_the_transports_motor() {
    let c = e2e_support::robot("waterjet-transport.ron", 1);
    let (mut bed, plant) = e2e_support::pushed_with_plant_process(&c, "waterjet-transport.ron");
    bed.press_start(&c).expect("START");
    let motions: Vec<String> = (0..6).map(|_| plant.next_said()).collect();
    assert_eq!(motions, TRANSPORT);
    drop(plant);
    bed.stop();
}

/// Waits until the functions `want` names are at those places (the statuses asked again
/// and again, at most the test's timeout).
fn places(bed: &mut robot_net::demo::Bed, c: &robot_compiler::Compiled, want: &[(&str, &str)]) {
    let end = std::time::Instant::now() + e2e_support::TIMEOUT;
    loop {
        let statuses = bed.statuses(c).expect("statuses");
        let states: Vec<Option<Vec<u8>>> =
            statuses.iter().map(|s| Some(s.states.to_vec())).collect();
        let got = robot_net::demo::functions(c, &states);
        if want
            .iter()
            .all(|w| got.iter().any(|g| (g.0.as_str(), g.1.as_str()) == *w))
        {
            return;
        }
        assert!(std::time::Instant::now() < end, "never {want:?}: {got:?}");
    }
}

/// The transport ran once: after it the cabinet's `Operation` stayed in `Auto` (the mode
/// the operator selected), which was neither its initial nor its idle place, so `start`
/// refused `moving`, `status` said moving, and a push waited for an idle point that never
/// came. `Auto` is a resting place of `Operation` now: `start` runs the transport again
/// and again, and a push switches over between two transports.
#[test]
fn the_tools_start_runs_the_transport_again_and_a_push_switches_between_transports() {
    let dir = e2e_support::TempDir::new("waterjet-again");
    let (robot, c) = e2e_support::unsecured_robot(&dir, "waterjet-transport.ron");
    let robot = robot.to_str().expect("utf-8 path");
    let (mut bed, plant) = e2e_support::pushed_with_plant(&c, "waterjet-transport.ron", false);
    let m = bed.medium().addr().to_string();
    for _ in 0..2 {
        let (code, _, err) = e2e_support::run_tool(&["start", robot, "--medium", &m]);
        assert_eq!((code, err.as_str()), (Some(0), ""));
        let motions: Vec<String> = (0..6).map(|_| plant.next_said()).collect();
        assert_eq!(motions, TRANSPORT);
        places(
            &mut bed,
            &c,
            &[
                ("Operation", "Auto"),
                ("Transport", "ReadyToCut"),
                ("Belt", "Stopped"),
            ],
        );
    }
    let (code, out, err) = e2e_support::run_tool(&[
        "push",
        robot,
        "--medium",
        &m,
        "--generation",
        "2",
        "--wait",
        "20",
    ]);
    assert_eq!((code, err.as_str()), (Some(0), ""), "{out}");
    drop(plant);
    bed.stop();
}

/// `plant` with the operator at its standard input, at rest: the fault contact closed
/// halts the machine and latches the cabinet's alarm; opened, then RELEASE, the fault
/// detection is back to `Ok` and the alarm's cause gone; acknowledged, RESTART runs a full
/// transport cycle. A line it cannot take is refused on standard error, naming the
/// robot's inputs, and the plant goes on. Each step waits for the places the nodes report.
#[test]
fn the_plant_commands_operator_drives_the_fault_contact_and_the_buttons() {
    use robot_net::demo::Bed;
    let c = e2e_support::robot("waterjet-transport.ron", 1);
    let (mut bed, mut plant) = e2e_support::pushed_with_plant_process(&c, "waterjet-transport.ron");
    let places = |bed: &mut Bed, want: &[(&str, &str)]| places(bed, &c, want);
    // The cabinet's (the role of `start`) alarms: (persists, acknowledged) each.
    let cabinet = c.ir.start.as_ref().map_or(0, |s| s.0);
    let alarms = |bed: &mut Bed, ack: bool| -> Vec<(bool, bool)> {
        let reports = bed.alarms(&c, ack).expect("alarm reports");
        (reports.get(cabinet).iter().flat_map(|r| r.alarms.iter()))
            .map(|a| (a.persists, a.acked))
            .collect()
    };
    // Waits until the cabinet reports `want` (what it learns from the pusher's node
    // comes over the radio).
    let alarms_until = |bed: &mut Bed, want: &[(bool, bool)]| {
        let end = std::time::Instant::now() + e2e_support::TIMEOUT;
        loop {
            let got = alarms(bed, false);
            if got == want {
                return;
            }
            assert!(std::time::Instant::now() < end, "never {want:?}: {got:?}");
        }
    };
    plant.type_line("JUMP");
    assert_eq!(
        plant.next_error(),
        "plant: refused: no operator input `JUMP`: the robot's are FAULT, RELEASE, RESTART"
    );
    plant.type_line("FAULT on");
    assert_eq!(plant.next_said(), "FAULT closed");
    places(
        &mut bed,
        &[("FaultDetection", "Faulted"), ("Operation", "Halted")],
    );
    alarms_until(&mut bed, &[(true, false)]);
    plant.type_line("FAULT off");
    assert_eq!(plant.next_said(), "FAULT open");
    places(&mut bed, &[("FaultDetection", "Cleared")]);
    plant.type_line("RELEASE");
    assert_eq!(plant.next_said(), "RELEASE pressed");
    places(
        &mut bed,
        &[("FaultDetection", "Ok"), ("Operation", "Releasing")],
    );
    alarms_until(&mut bed, &[(false, false)]);
    assert_eq!(alarms(&mut bed, true), [(false, true)]);
    plant.type_line("RESTART");
    assert_eq!(plant.next_said(), "RESTART pressed");
    let motions: Vec<String> = (0..6).map(|_| plant.next_said()).collect();
    assert_eq!(motions, TRANSPORT);
    drop(plant);
    bed.stop();
}
