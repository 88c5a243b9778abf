//! A push whose connection to the medium is lost (a serial gateway unplugged, the medium
//! stopped) says in which phase, what that means for the machine and what to do.

mod e2e_support;

use std::process::{Command, Stdio};

use config_schema::wire::msg::Message;
use e2e_support::*;

/// It said only `error: the medium closed the connection`, status 1, whether the nodes had
/// switched or not. Cut during the transfer (one node down, so the transfer is still
/// under way), it now says nothing switched and to push again; status 3, a failed push.
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
    let push = Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .current_dir(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(["push", paint.to_str().expect("utf-8 path"), "--medium"])
        .arg(bed.medium().addr().to_string())
        .env_remove("CONFIG_TOOL_KEYS")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("push runs");
    // The transfer is under way once a table's first chunk is on the air.
    monitor.until(|_, payload| matches!(Message::parse(payload), Ok(Message::ConfigChunk { .. })));
    bed.stop();
    let out = push.wait_with_output().expect("push ends");
    assert_eq!(
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned()
        ),
        (
            Some(3),
            "error: the medium closed the connection during the transfer: nothing switched \
             (what a node staged, it keeps): push again\n"
                .to_string()
        )
    );
}
