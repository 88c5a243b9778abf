//! A node that does not answer (dead, out of range) does not hide what the others say.

mod e2e_support;

use e2e_support::*;

/// With RC's node dead, `alarms` and `ack` printed only `node 0x0014 did not answer`
/// (status 1): the alarms of the nodes that answered, exactly when the operator needs
/// them, were not shown, and nothing was acknowledged. Now the answering nodes' alarms
/// are shown (and acknowledged), the silent node is named on its own line, status 1.
#[test]
fn a_silent_node_does_not_hide_the_others_alarms() {
    let dir = TempDir::new("silent-node");
    let (paint, c) = unsecured_robot(&dir, "paint-robot.ron");
    let paint = paint.to_str().expect("utf-8 path");
    let mut opts = options(medium::Config::default(), None);
    opts.secured = false;
    let mut bed = bring_up(&c, opts);
    push_and_home(&mut bed, &c);
    bed.kill_node(addr_of(&c, "RC"));
    let medium = bed.medium().addr().to_string();
    let m = medium.as_str();

    let silent = "0x0014 RC        did not answer: its alarms are unknown\n";
    let (code, out, err) = run_tool(&["alarms", paint, "--medium", m]);
    assert_eq!((code, out.as_str()), (Some(1), silent), "{err}");
    assert!(
        err.starts_with("error: node 0x0014 (RC) did not answer (asked "),
        "{err}"
    );
    let (code, out, err) = run_tool(&["ack", paint, "--medium", m]);
    assert_eq!(
        (code, out),
        (
            Some(1),
            format!("acknowledged: 0 alarm(s) on 3 node(s)\n{silent}")
        ),
        "{err}"
    );
    // `home` and `start` name the silent node's role (they said only its address), how
    // often it was asked, and that nothing was sent (they said neither).
    for (command, what) in [("home", "HOME"), ("start", "START")] {
        let (code, out, err) = run_tool(&[command, paint, "--medium", m]);
        assert_eq!((code, out.as_str()), (Some(1), ""), "{command}: {err}");
        let asked = err
            .strip_prefix("error: node 0x0014 (RC) did not answer Status (asked ")
            .and_then(|r| r.strip_suffix(&format!(" times in 5 s): {what} was not sent\n")))
            .and_then(|n| n.parse::<u32>().ok());
        assert!(asked.is_some_and(|n| n > 1), "{command}: {err}");
    }
    // START to one node without the robot is unchecked: the node acknowledges it, which
    // does not say it started anything (it said `started`).
    assert_eq!(
        run_tool(&["start", "--node", "0x0012", "--medium", m]),
        (
            Some(0),
            "0x0012: START acknowledged (unchecked without the robot: a node not homed, under \
             way or faulted ignores it)\n"
                .to_string(),
            String::new()
        )
    );
    bed.stop();
}
