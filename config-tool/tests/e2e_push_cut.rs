//! A push whose connection to the medium is lost (a serial gateway unplugged, the medium
//! stopped) says in which phase, what that means for the machine and what to do.

mod e2e_support;

use std::process::{Child, Command, Stdio};

use config_schema::wire::msg::Message;
use e2e_support::*;

/// `config-tool push ROBOT ARGS --medium` to `bed`'s medium, without keys, running.
fn spawn_push(bed: &robot_net::demo::Bed, robot: &std::path::Path, args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .current_dir(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .arg("push")
        .arg(robot)
        .args(args)
        .arg("--medium")
        .arg(bed.medium().addr().to_string())
        .env_remove("CONFIG_TOOL_KEYS")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("push runs")
}

/// It said only `error: the medium closed the connection`, status 1, whether the nodes had
/// switched or not. Cut during the transfer (one node down, so the transfer is still
/// under way), it now says nothing switched and to push again; status 3, a failed push.
/// It names the medium it lost (it named none).
#[test]
fn a_push_cut_off_during_the_transfer_says_nothing_switched() {
    let dir = TempDir::new("push-cut");
    let (paint, c) = unsecured_robot(&dir, "paint-robot.ron");
    let mut opts = options(medium::Config::default(), None);
    opts.secured = false;
    let mut bed = bring_up(&c, opts);
    // RC's node is down: its transfer cannot end before the cut.
    bed.kill_node(addr_of(&c, "RC"));
    let mut monitor = Monitor::join(bed.medium().addr());
    let push = spawn_push(&bed, &paint, &[]);
    // The transfer is under way once a table's first chunk is on the air.
    monitor.until(|_, payload| matches!(Message::parse(payload), Ok(Message::ConfigChunk { .. })));
    let at = bed.medium().addr();
    bed.stop();
    let out = push.wait_with_output().expect("push ends");
    assert_eq!(
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned()
        ),
        (
            Some(3),
            format!(
                "error: the medium at {at} closed the connection during the transfer: nothing \
                 switched (what a node staged, it keeps): push again\n"
            )
        )
    );
}

/// Cut during the switch-over (the machine under way for good, so the nodes are armed and
/// the switch waits for them to rest): it said what that means and to push again, but not
/// where each node stood; now a line per node (staged, not switched) comes first, then the
/// summary. (A faulted machine no longer gets that far: the push names its faulted nodes
/// before arming, `e2e_push`.)
#[test]
fn a_push_cut_off_during_the_switch_over_says_where_each_node_stands() {
    let dir = TempDir::new("push-cut-switch");
    let (bed, _) = under_way_for_good(&dir);
    let (dip, _) = unsecured_robot(&dir, "paint-robot-double-dip.ron");
    let mut monitor = Monitor::join(bed.medium().addr());
    let push = spawn_push(&bed, &dip, &["--generation", "2"]);
    // The switch-over is under way once a node is asked to arm.
    monitor.until(|_, payload| matches!(Message::parse(payload), Ok(Message::Switch { .. })));
    let at = bed.medium().addr();
    bed.stop();
    let out = push.wait_with_output().expect("push ends");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let lines: Vec<&str> = stdout.lines().skip(1).collect();
    assert!(stdout.starts_with("verified: "), "{stdout}");
    assert_eq!(lines.len(), 5, "{stdout}");
    for (line, role) in lines.iter().zip(["VC", "GR", "HC", "RC"]) {
        assert!(
            line.starts_with(&format!("  {role:<6} ")) && line.ends_with("  staged, not switched"),
            "{stdout}"
        );
    }
    assert!(lines[4].starts_with("pushed 4 table(s): "), "{stdout}");
    assert_eq!(
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned()
        ),
        (
            Some(3),
            format!(
                "error: the medium at {at} closed the connection during the switch-over: nodes \
                 may run different generations (`scan` shows each one's): push again to finish \
                 it, or roll back\n"
            )
        )
    );
}
