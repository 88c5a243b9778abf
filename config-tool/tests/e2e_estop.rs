//! Issue 14, the emergency stop end to end with real node processes on the medium: the
//! painting robot with an e-stop on VC's node (`tests/fixtures/paint-robot-estop.ron`),
//! pressed during a cycle. Every node faults (VC by its e-stop, the others on its one
//! `estop` publication); the alarms say so and are not acknowledged while the button is
//! pressed; after the release, a reset and the acknowledgement, homing and one exact cycle
//! run. Then the same alarms through the binary: `alarms`, `ack`, `home` and `start` print
//! exactly these lines.

mod e2e_support;

use std::path::{Path, PathBuf};
use std::process::{Command as Process, Output};

use config_schema::alarm::{AlarmLevel, AlarmSource, FAULT_ESTOP, FAULT_ESTOP_PEER};
use config_schema::wire::medium::{Link, Peer};
use config_schema::wire::msg::Command;
use e2e_support::*;
use robot_compiler::{compile, Compiled, Source};
use robot_net::home::HomeEnd;
use robot_net::live_plant::{self, Injection, Jam};

/// The fixture's path from the workspace root.
const FIXTURE: &str = "tests/fixtures/paint-robot-estop.ron";

/// The e-stop input's pin on VC's node (the fixture's `ESTOP`).
const ESTOP_PIN: u8 = 5;

/// A status fault code of a `Fault` action (`node_fw::node::fault_code`).
const ACTION: u8 = 0x80;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The fixture's text with `edit` applied, compiled.
fn estop_robot(name: &str, edit: impl Fn(String) -> String) -> (Compiled, String) {
    let text = std::fs::read_to_string(root().join(FIXTURE)).expect("fixture");
    let text = edit(text);
    let c = compile::compile(&Source::new(name, text.clone()))
        .unwrap_or_else(|d| panic!("{name} does not compile: {d:?}"));
    (c.with_generation(1).expect("re-encodes"), text)
}

/// The e-stop button, wired on the medium like the plant's switches: a plant connection
/// that sets VC's e-stop input; the level is at the node when `set` returns.
struct EStop {
    conn: medium::Conn,
    addr: u16,
}

impl EStop {
    fn wire(medium: std::net::SocketAddr, addr: u16) -> EStop {
        EStop {
            conn: medium::Conn::join(medium, Peer::Plant).expect("the e-stop's wire"),
            addr,
        }
    }

    fn set(&mut self, pressed: bool) {
        (self.conn)
            .send(&Link::Pin {
                addr: self.addr,
                pin: ESTOP_PIN,
                level: pressed,
            })
            .expect("pin");
        self.conn.sync().expect("the level reached the node");
    }
}

/// Each role's e-stop chart (the one the compiler adds to every role).
fn estop_chart(c: &Compiled, role: usize) -> u8 {
    c.ir.roles[role]
        .charts
        .iter()
        .position(|ch| ch.name == "estop")
        .expect("an estop chart") as u8
}

/// Every role's alarms as (source, level, acknowledged, cause persists), in role order.
fn alarm_list(
    reports: &[config_schema::alarm::AlarmReport],
) -> Vec<Vec<(AlarmSource, AlarmLevel, bool, bool)>> {
    reports
        .iter()
        .map(|r| {
            r.alarms
                .iter()
                .map(|a| (a.source, a.level, a.acked, a.persists))
                .collect()
        })
        .collect()
}

/// What every role's alarm list must be after the e-stop: VC's e-stop, every other node's
/// e-stop chart fault; `acked` and `persists` per role.
fn after_estop(
    c: &Compiled,
    state: &[(bool, bool)],
) -> Vec<Vec<(AlarmSource, AlarmLevel, bool, bool)>> {
    (0..c.ir.roles.len())
        .map(|i| {
            let source = if c.ir.roles[i].name == "VC" {
                AlarmSource::EStop
            } else {
                AlarmSource::Chart {
                    chart: estop_chart(c, i),
                    code: ACTION | FAULT_ESTOP_PEER,
                }
            };
            vec![(source, AlarmLevel::Fault, state[i].0, state[i].1)]
        })
        .collect()
}

#[test]
fn an_estop_mid_cycle_faults_every_node_its_alarm_holds_while_pressed_then_reset_ack_home_and_a_cycle_run(
) {
    // No watchdog within the test's bound: the machine waits on HC's end switch (opened
    // below) for as long as the test needs, so the e-stop comes exactly after HC+.
    let (c, _) = estop_robot("paint-robot-estop.ron", |t| {
        t.replacen("motion_timeout_ms: 2000", "motion_timeout_ms: 600000", 1)
    });
    let mut bed = bring_up(&c, options(medium::Config::default(), None));
    push_and_home(&mut bed, &c);
    assert_running(&mut bed, &c);

    // From the fourth step (HC+) on, HC's end switch stays open: HC extends and the cycle
    // waits there.
    let actuators = live_plant::actuators(&c).expect("actuators");
    let hc = actuators.iter().position(|a| a.name == "HC").expect("HC");
    bed.set_plant_injected(
        actuators.clone(),
        Some(Injection {
            after: 3,
            actuator: hc,
            kind: Jam::SwitchOpen { end: true },
        }),
    )
    .expect("plant");
    bed.press_start(&c).expect("START");
    let seen: Vec<String> = (bed.await_strokes(4).expect("four steps").iter())
        .map(|s| s.to_string())
        .collect();
    assert_eq!(seen.join(" "), "VC+ GR+ VC- HC+");

    // The e-stop on VC's node: every node faults, VC by its e-stop, every other node on
    // the e-stop's publication; the valves go to their fault levels (GR holds its part).
    let vc = addr_of(&c, "VC");
    let mut estop = EStop::wire(bed.medium().addr(), vc);
    estop.set(true);
    let faults: Vec<(String, Option<u8>, u16)> = (c.ir.roles.iter())
        .map(|r| {
            let s = wait_until(&mut bed, r.address, |s| s.fault.is_some());
            (r.name.clone(), s.fault, s.outputs)
        })
        .collect();
    let peer = Some(ACTION | FAULT_ESTOP_PEER);
    assert_eq!(
        faults,
        [
            ("VC".to_string(), Some(ACTION | FAULT_ESTOP), 0),
            ("GR".to_string(), peer, 1),
            ("HC".to_string(), peer, 0),
            ("RC".to_string(), peer, 0),
        ]
    );

    // The alarms: VC's e-stop, the others' e-stop charts; all fault level, latched, their
    // causes persisting. An acknowledgement changes nothing while the button is pressed
    // (and the nodes are faulted); homing is refused.
    let latched = after_estop(&c, &[(false, true); 4]);
    assert_eq!(alarm_list(&bed.alarms(&c, false).unwrap()), latched);
    assert_eq!(alarm_list(&bed.alarms(&c, true).unwrap()), latched);
    assert_eq!(
        bed.home(&c).unwrap().end,
        HomeEnd::Refused(
            "nodes 0x0011 (VC, 0x83), 0x0012 (GR, 0x84), 0x0013 (HC, 0x84), 0x0014 (RC, 0x84) \
             are faulted: reset each (config-tool reset --node 0x0011; config-tool reset \
             --node 0x0012; config-tool reset --node 0x0013; config-tool reset --node \
             0x0014), acknowledge the alarms (config-tool ack), then config-tool home"
                .to_string()
        )
    );

    // Released: VC's alarm no longer persists and is acknowledged; the others stay while
    // their nodes are faulted.
    estop.set(false);
    drop(estop);
    let mut state = [(false, false), (false, true), (false, true), (false, true)];
    assert_eq!(
        alarm_list(&bed.alarms(&c, false).unwrap()),
        after_estop(&c, &state)
    );
    state[0].0 = true;
    assert_eq!(
        alarm_list(&bed.alarms(&c, true).unwrap()),
        after_estop(&c, &state)
    );

    // Reset every node: homing is refused, naming the alarm still latched, until the
    // operator acknowledges it.
    for r in &c.ir.roles {
        bed.command(r.address, Command::Reset).expect("reset");
    }
    assert_not_homed(&mut bed, &c);
    assert_eq!(
        bed.home(&c).unwrap().end,
        HomeEnd::Refused(
            "node 0x0012 (GR) has a fault alarm latched: chart `estop`: stopped by another \
             node's emergency stop (code 0x84): acknowledge it first (config-tool ack)"
                .to_string()
        )
    );
    let acked = bed.alarms(&c, true).unwrap();
    assert_eq!(alarm_list(&acked), after_estop(&c, &[(true, false); 4]));
    assert!(acked.iter().all(|r| r.blocking().is_none()), "{acked:?}");

    // Homing from where the e-stop left the rods: HC back from its end, the gripper
    // released; nothing else moved since the e-stop (the plant saw no other step).
    let homing = bed.home(&c).unwrap();
    assert_eq!(
        homing.end,
        HomeEnd::Homed,
        "{}",
        robot_net::demo::homed_line(&homing)
    );
    assert_eq!(robot_analysis::sim::steps_text(&homing.steps), "HC- GR-");
    // HC's switch works again: one exact cycle.
    bed.set_plant(actuators).expect("plant");
    assert_running(&mut bed, &c);
    let cycle = exact_cycle(&mut bed, &c, 1);
    assert_eq!(robot_analysis::sim::steps_text(&cycle.steps), SEQUENCE_1);
    bed.stop();
}

/// Runs the tool at the workspace root (without keys).
fn tool(args: &[&str]) -> Output {
    Process::new(env!("CARGO_BIN_EXE_config-tool"))
        .current_dir(root())
        .args(args)
        .env_remove("CONFIG_TOOL_KEYS")
        .output()
        .expect("runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// `(exit status, stdout, stderr)`, the wall times of `alarms` lines (`HH:MM:SS.mmm UTC`)
/// as `T`, each checked to be one.
fn run(args: &[&str]) -> (Option<i32>, String, String) {
    let out = tool(args);
    let stdout = text(&out.stdout)
        .lines()
        .map(|l| match l.find(" UTC ") {
            Some(at) if at >= 12 => {
                let clock = &l[at - 12..at];
                let digits: String = clock.chars().filter(char::is_ascii_digit).collect();
                assert_eq!(
                    (digits.len(), &clock[2..3], &clock[5..6], &clock[8..9]),
                    (9, ":", ":", "."),
                    "{l}"
                );
                format!("{}T{}\n", &l[..at - 12], &l[at..])
            }
            _ => format!("{l}\n"),
        })
        .collect();
    (out.status.code(), stdout, text(&out.stderr))
}

#[test]
fn alarms_and_ack_print_the_estop_and_what_stayed_then_the_acknowledged_alarms() {
    // The binary's frames are unsecured: the bed's radio holds the tool's counters.
    let dir = TempDir::new("estop-cli");
    let (c, robot_text) = estop_robot("paint-robot-estop.ron", |t| {
        t.replacen(
            "    network: (pan_id: 0x1234, channel: 15),\n",
            "    network: (pan_id: 0x1234, channel: 15),\n    security: Off,\n",
            1,
        )
    });
    let file = dir.0.join("paint-robot-estop.ron");
    std::fs::write(&file, robot_text).expect("robot file");
    let robot = file.to_str().expect("utf-8 path");
    let mut opts = options(medium::Config::default(), None);
    opts.secured = false;
    let mut bed = bring_up(&c, opts);
    push_and_home(&mut bed, &c);
    let medium = bed.medium().addr().to_string();
    let m = medium.as_str();

    let (status, out, err) = run(&["alarms", robot, "--medium", m]);
    assert_eq!(
        (status, out.as_str(), err.as_str()),
        (Some(0), "no alarms\n", "")
    );

    // The e-stop, at rest: every node faults.
    let mut estop = EStop::wire(bed.medium().addr(), addr_of(&c, "VC"));
    estop.set(true);
    for r in &c.ir.roles {
        wait_until(&mut bed, r.address, |s| s.fault.is_some());
    }
    let listed = "\
fault    T UTC  0x0011 VC        emergency stop `ESTOP` pressed  [latched, cause persists]
fault    T UTC  0x0012 GR        chart `estop`: stopped by another node's emergency stop (code 0x84)  [latched, cause persists]
fault    T UTC  0x0013 HC        chart `estop`: stopped by another node's emergency stop (code 0x84)  [latched, cause persists]
fault    T UTC  0x0014 RC        chart `estop`: stopped by another node's emergency stop (code 0x84)  [latched, cause persists]
";
    assert_eq!(
        run(&["alarms", robot, "--medium", m]),
        (Some(0), listed.into(), "".into())
    );
    let stayed = "\
acknowledged: 0 alarm(s) on 4 node(s)
stayed: 0x0011 VC: emergency stop `ESTOP` pressed (its cause persists)
stayed: 0x0012 GR: chart `estop`: stopped by another node's emergency stop (code 0x84) (its cause persists)
stayed: 0x0013 HC: chart `estop`: stopped by another node's emergency stop (code 0x84) (its cause persists)
stayed: 0x0014 RC: chart `estop`: stopped by another node's emergency stop (code 0x84) (its cause persists)
";
    assert_eq!(
        run(&["ack", robot, "--medium", m]),
        (
            Some(6),
            stayed.into(),
            "error: node 0x0011 (VC) has a fault alarm latched: emergency stop `ESTOP` pressed \
             (its cause persists: the emergency stop is pressed; release it, then ack again): \
             the machine cannot restart\n"
                .into()
        )
    );

    // Released and reset: the alarms no longer persist; home and start are refused until
    // they are acknowledged.
    estop.set(false);
    drop(estop);
    for r in &c.ir.roles {
        let node = format!("{:#06x}", r.address);
        let (status, out, _) = run(&["reset", "--medium", m, "--node", &node]);
        assert_eq!(
            (status, out),
            (
                Some(0),
                format!("{node}: reset; no link needed re-establishing\n")
            )
        );
    }
    let released = listed.replace("[latched, cause persists]", "[latched]");
    assert_eq!(
        run(&["alarms", robot, "--medium", m]),
        (Some(0), released, "".into())
    );
    assert_eq!(
        run(&["home", robot, "--medium", m]).2,
        "error: node 0x0011 (VC) has a fault alarm latched: emergency stop `ESTOP` pressed: \
         acknowledge it first (config-tool ack); HOME was not sent\n"
    );
    assert_eq!(
        run(&["ack", robot, "--medium", m]),
        (
            Some(0),
            "acknowledged: 4 alarm(s) on 4 node(s)\n".into(),
            "".into()
        )
    );
    // A second `ack` acknowledges nothing new (it counted the four again).
    assert_eq!(
        run(&["ack", robot, "--medium", m]),
        (
            Some(0),
            "acknowledged: 0 alarm(s) on 4 node(s) (4 acknowledged before)\n".into(),
            "".into()
        )
    );
    let acknowledged = listed.replace("[latched, cause persists]", "[acknowledged]");
    assert_eq!(
        run(&["alarms", robot, "--medium", m]),
        (Some(0), acknowledged, "".into())
    );
    let (status, out, err) = run(&["home", robot, "--medium", m]);
    assert_eq!(status, Some(0), "{out}{err}");
    assert_eq!(
        run(&["start", robot, "--medium", m]),
        (Some(0), "0x0011: started\n".into(), "".into())
    );
    bed.stop();
}
