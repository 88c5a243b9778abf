//! A node's running table has an identity on the air (its blob's CRC-32, in `Status` and
//! `Announce`): the tool tells "runs this robot's table" by it, not by the role's name and
//! chart count, so a robot whose roles and charts look like another's is not taken for it.

mod e2e_support;

use e2e_support::*;

/// With the double dip running (the paint robot's roles, the same chart count, VC's and
/// RC's tables different), `start paint-robot.ron` started the double dip, exit 0; and
/// `status` said `homed` of VC. Now the first node whose table is not the robot's is
/// named, nothing is sent (exit 6); the nodes whose tables are the same in both robots
/// (GR, HC) are the robot's.
#[test]
fn a_robot_with_the_same_roles_and_charts_is_not_taken_for_the_running_one() {
    let dir = TempDir::new("identity");
    let (paint, _) = unsecured_robot(&dir, "paint-robot.ron");
    let (dip_file, dip) = unsecured_robot(&dir, "paint-robot-double-dip.ron");
    let dip_file = dip_file.to_str().expect("utf-8 path");
    let paint = paint.to_str().expect("utf-8 path");
    let mut opts = options(medium::Config::default(), None);
    opts.secured = false;
    let mut bed = bring_up(&dip, opts);
    push_and_home(&mut bed, &dip);
    let medium = bed.medium().addr().to_string();
    let m = medium.as_str();

    // Both refused before anything is sent (`home` printed its `homing:` line before the
    // refusal, as if HOME had gone out).
    for (command, what) in [("start", "START"), ("home", "HOME")] {
        assert_eq!(
            run_tool(&[command, paint, "--medium", m]),
            (
                Some(6),
                String::new(),
                format!(
                    "error: nodes 0x0011 (VC), 0x0014 (RC) do not run this robot's table \
                     (another robot's, or this file changed since its push): check the file, \
                     or push it; {what} was not sent\n"
                )
            )
        );
    }
    let homing = |node: &str| {
        let (code, out, err) = run_tool(&["status", paint, "--medium", m, "--node", node]);
        assert_eq!((code, err.as_str()), (Some(0), ""), "{out}");
        out.lines().last().unwrap_or_default().to_string()
    };
    assert_eq!(homing("0x0011"), "  homing: not running this robot's table");
    assert_eq!(homing("0x0012"), "  homing: homed");
    let (code, found, err) = run_tool(&["scan", paint, "--medium", m]);
    assert_eq!((code, err.as_str()), (Some(0), ""), "{found}");
    assert!(
        found.contains("0x0011  firmware 1  generation 1  VC  not running this robot's table\n")
            && found.contains("0x0012  firmware 1  generation 1  GR  homed\n"),
        "{found}"
    );
    // A push of the paint robot at the running generation is refused by every node (a
    // table is replaced by a newer generation only) but GR's and HC's, whose tables are
    // the double dip's: they run them already; the summary counts the others not staged
    // (it said `pushed 4 table(s)`).
    let (code, out, err) = run_tool(&["push", paint, "--medium", m]);
    assert_eq!(
        (code, err.as_str()),
        (
            Some(3),
            "error: not every node staged its table: nothing switched; a node runs \
             generation 1: push with --generation 2\n"
        ),
        "{out}"
    );
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 6, "{out}");
    for line in &lines[1..5] {
        let want = if line.contains("  GR  ") || line.contains("  HC  ") {
            "runs this table already"
        } else {
            "refused: generation not newer than the running 1"
        };
        assert!(line.ends_with(want), "{out}");
    }
    assert!(
        lines[5].starts_with("staged 0 of 4 table(s), 2 run theirs already (2 not: above): "),
        "{out}"
    );

    // Nothing moved: the machine is at rest, and its next cycle is the double dip's,
    // exactly.
    assert_running(&mut bed, &dip);
    exact_cycle(&mut bed, &dip, 1);

    // The double dip on trial as generation 2: `confirm` with the paint robot confirmed
    // it (exit 0); it now names the node whose trial is another table, and confirms
    // nothing. With the double dip, it confirms.
    let (code, out, err) = run_tool(&[
        "push",
        dip_file,
        "--medium",
        m,
        "--generation",
        "2",
        "--trial",
    ]);
    assert_eq!((code, err.as_str()), (Some(0), ""), "{out}");
    assert_eq!(
        run_tool(&["confirm", paint, "--medium", m]),
        (
            Some(6),
            String::new(),
            "error: node 0x0011 (VC) runs generation 2 on trial, not this robot's table: \
             nothing confirmed (confirm with the robot that was pushed)\n"
                .to_string()
        )
    );
    let (code, out, err) = run_tool(&["confirm", dip_file, "--medium", m]);
    assert_eq!((code, err.as_str()), (Some(0), ""), "{out}");
    assert_eq!(
        out.lines()
            .filter(|l| l.ends_with("generation 2  confirmed"))
            .count(),
        4,
        "{out}"
    );

    // One role pushed: only its node switched (it said `every node runs the new
    // generation` with the others on generation 2).
    let (code, out, err) = run_tool(&[
        "push",
        dip_file,
        "--medium",
        m,
        "--generation",
        "3",
        "--role",
        "VC",
    ]);
    assert_eq!((code, err.as_str()), (Some(0), ""), "{out}");
    assert_eq!(
        out.lines().last(),
        Some("switched: VC's node runs generation 3 (the robot's other nodes run theirs)"),
        "{out}"
    );
    bed.stop();
}
