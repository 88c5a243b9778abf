//! `config-tool keys`: the machine secret's file (mode 0600, never replaced without
//! --force, refused when others may read it) and the exact provisioning output.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn tool(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_config-tool"))
        .args(args)
        .output()
        .expect("runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[cfg(unix)]
fn mode(p: &Path) -> u32 {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(p).unwrap().permissions().mode() & 0o777
}

#[cfg(unix)]
fn chmod(p: &Path, m: u32) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(p, std::fs::Permissions::from_mode(m)).unwrap();
}

/// The machine secret 00 01 02 .. 1f, in a file of mode 0600.
fn fixed_secret(dir: &Path) -> PathBuf {
    let p = dir.join("machine.key");
    let hex: String = (0u8..32).map(|b| format!("{b:02x}")).collect();
    std::fs::write(&p, format!("robot-machine-secret v1 {hex}\n")).unwrap();
    #[cfg(unix)]
    chmod(&p, 0o600);
    p
}

#[test]
fn keys_new_writes_a_secret_only_its_owner_can_read_and_never_replaces_it_silently() {
    let dir = scratch("keys-new");
    let key = dir.join("machine.key");
    let out = tool(&["keys", "new", "--out", s(&key)]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(
        text(&out.stdout),
        format!(
            "wrote a new machine secret to {} (mode 0600): every node's key derives from it; \
             keep it as you keep the machine's root password\n",
            key.display()
        )
    );
    #[cfg(unix)]
    assert_eq!(mode(&key), 0o600);
    let first = std::fs::read_to_string(&key).unwrap();
    assert!(first.starts_with("robot-machine-secret v1 "));
    assert_eq!(first.len(), 24 + 64 + 1);
    // The secret is in the file, never on the terminal.
    assert!(!text(&out.stdout).contains(&first[24..88]));

    let again = tool(&["keys", "new", "--out", s(&key)]);
    assert_eq!(again.status.code(), Some(1));
    assert_eq!(
        text(&again.stderr),
        format!(
            "error: {}: exists; refusing to replace a key (give --force to replace it: what \
             was provisioned from it must then be provisioned again)\n",
            key.display()
        )
    );
    assert_eq!(std::fs::read_to_string(&key).unwrap(), first);

    let forced = tool(&["keys", "new", "--out", s(&key), "--force"]);
    assert!(forced.status.success());
    assert_ne!(std::fs::read_to_string(&key).unwrap(), first);
    #[cfg(unix)]
    assert_eq!(mode(&key), 0o600);
    // No temporary file left beside it.
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
}

#[cfg(unix)]
#[test]
fn a_key_file_others_may_read_is_refused_naming_the_file_and_its_mode() {
    let dir = scratch("keys-mode");
    let key = fixed_secret(&dir);
    chmod(&key, 0o644);
    let out = tool(&["keys", "provision", "--keys", s(&key), "--node", "0x0011"]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(text(&out.stdout), "");
    assert_eq!(
        text(&out.stderr),
        format!(
            "error: {0}: mode 0644 lets group or others read or write it; a key file must be \
             readable by its owner only (chmod 600 {0})\n",
            key.display()
        )
    );
    chmod(&key, 0o660);
    let out = tool(&["keys", "provision", "--keys", s(&key), "--node", "0x0011"]);
    assert!(text(&out.stderr).contains("mode 0660 lets group or others"));
}

#[test]
fn a_file_that_is_not_a_secret_names_the_place() {
    let dir = scratch("keys-format");
    let key = dir.join("machine.key");
    std::fs::write(&key, "robot-machine-secret v1 0011zz\n").unwrap();
    #[cfg(unix)]
    chmod(&key, 0o600);
    let out = tool(&["keys", "provision", "--keys", s(&key), "--node", "3"]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        text(&out.stderr),
        format!(
            "error: {}:1:29: expected 64 hex digits (the 32 bytes of the secret)\n",
            key.display()
        )
    );
}

/// Node 0x0011's management key from the secret 00..1f is a65fc7a6fd940aa8567e4224a6c1ce5e
/// (HKDF-SHA256, cross-checked against an independent HKDF in robot-keys' tests); as LE
/// words a6c75fa6 a80a94fd 24427e56 5ecec1a6.
#[test]
fn provision_prints_exactly_what_to_write_on_each_board() {
    let dir = scratch("keys-provision");
    let key = fixed_secret(&dir);
    let run = |board: &str| {
        let out = tool(&[
            "keys",
            "provision",
            "--keys",
            s(&key),
            "--node",
            "0x0011",
            "--board",
            board,
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        text(&out.stdout)
    };
    assert_eq!(
        run("qemu"),
        "# node 0x0011, qemu-mps2: QEMU arguments writing the provisioning word (key flag set) \
         and the key's four words after it\n\
         # (config-tool qemu-node --addr 0x0011 --key FILE adds the same from the host key file)\n\
         -device loader,addr=0x003ff000,data=0xa5050011,data-len=4\n\
         -device loader,addr=0x003ff004,data=0xa6c75fa6,data-len=4\n\
         -device loader,addr=0x003ff008,data=0xa80a94fd,data-len=4\n\
         -device loader,addr=0x003ff00c,data=0x24427e56,data-len=4\n\
         -device loader,addr=0x003ff010,data=0x5ecec1a6,data-len=4\n"
    );
    assert_eq!(
        run("nrf52840"),
        "# node 0x0011, nrf52840: UICR CUSTOMER[0] (the provisioning word, key flag set) and \
         CUSTOMER[2..=5] (the key); CUSTOMER[1] stays the radio channel\n\
         # (UICR bits only clear: on a node provisioned before, nrfjprog --eraseuicr first, \
         then write the channel again)\n\
         nrfjprog --memwr 0x10001080 --val 0xA5040011\n\
         nrfjprog --memwr 0x10001088 --val 0xA6C75FA6\n\
         nrfjprog --memwr 0x1000108C --val 0xA80A94FD\n\
         nrfjprog --memwr 0x10001090 --val 0x24427E56\n\
         nrfjprog --memwr 0x10001094 --val 0x5ECEC1A6\n\
         nrfjprog --reset\n"
    );
    let host = "# node 0x0011, host board: this line is its key file (keep it with mode 0600, \
                or give --out FILE)\n\
                robot-node-key v1 0x0011 a65fc7a6fd940aa8567e4224a6c1ce5e\n\
                # then: node-host --addr 0x0011 --key FILE --medium HOST:PORT\n";
    assert_eq!(run("host"), host);
    // Without --board: every board, one after the other.
    let all = tool(&["keys", "provision", "--keys", s(&key), "--node", "0x0011"]);
    assert_eq!(
        text(&all.stdout),
        format!("{host}\n{}\n{}", run("qemu"), run("nrf52840"))
    );
}

#[test]
fn provision_writes_the_host_key_file_that_node_host_reads() {
    let dir = scratch("keys-host");
    let key = fixed_secret(&dir);
    let node_key = dir.join("node-11.key");
    let out = tool(&[
        "keys",
        "provision",
        "--keys",
        s(&key),
        "--node",
        "0x0011",
        "--board",
        "host",
        "--out",
        s(&node_key),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(
        text(&out.stdout),
        format!(
            "# node 0x0011, host board: wrote its key file {0} (mode 0600); run it with\n\
             node-host --addr 0x0011 --key {0} --medium HOST:PORT\n\
             # or: config-tool node --addr 0x0011 --key {0} --medium HOST:PORT\n",
            node_key.display()
        )
    );
    #[cfg(unix)]
    assert_eq!(mode(&node_key), 0o600);
    assert_eq!(
        std::fs::read_to_string(&node_key).unwrap(),
        "robot-node-key v1 0x0011 a65fc7a6fd940aa8567e4224a6c1ce5e\n"
    );
    // The node's own reader takes it, for this address only.
    let k = node_fw::host::key::load(&node_key, 0x0011).unwrap();
    assert_eq!(
        k.expose(),
        &[
            0xa6, 0x5f, 0xc7, 0xa6, 0xfd, 0x94, 0x0a, 0xa8, 0x56, 0x7e, 0x42, 0x24, 0xa6, 0xc1,
            0xce, 0x5e
        ]
    );
    assert!(node_fw::host::key::load(&node_key, 0x0012).is_err());
    // Never replaced without --force.
    let again = tool(&[
        "keys",
        "provision",
        "--keys",
        s(&key),
        "--node",
        "0x0011",
        "--board",
        "host",
        "--out",
        s(&node_key),
    ]);
    assert_eq!(again.status.code(), Some(1));
    assert!(text(&again.stderr).contains("exists; refusing to replace a key"));
    // --out is the host board's.
    let qemu = tool(&[
        "keys",
        "provision",
        "--keys",
        s(&key),
        "--node",
        "0x0011",
        "--board",
        "qemu",
        "--out",
        s(&dir.join("x")),
    ]);
    assert_eq!(
        text(&qemu.stderr),
        "error: --out writes the host board's key file: give --board host (or no --board)\n"
    );
}

#[test]
fn the_host_node_refuses_another_nodes_key_file_at_start() {
    let dir = scratch("keys-node");
    let key = fixed_secret(&dir);
    let node_key = dir.join("node-12.key");
    let out = tool(&[
        "keys",
        "provision",
        "--keys",
        s(&key),
        "--node",
        "0x0012",
        "--board",
        "host",
        "--out",
        s(&node_key),
    ]);
    assert!(out.status.success());
    // Port 1: the key is checked before the medium is reached.
    let node = tool(&[
        "node",
        "--addr",
        "0x0011",
        "--medium",
        "127.0.0.1:1",
        "--key",
        s(&node_key),
    ]);
    assert_eq!(node.status.code(), Some(1));
    assert_eq!(
        text(&node.stderr),
        format!(
            "node: key file: {}: the key of node 0x0012, not of this node (0x0011)\n",
            node_key.display()
        )
    );
}

/// `provision --out` naming the machine secret (the hint said `give --force`, and then
/// the secret every node key derives from was replaced by one node's key): refused, with
/// --force too, by any name for it, before anything is written (status 2).
#[test]
fn provision_never_writes_over_the_machine_secret() {
    let dir = scratch("provision-over-secret");
    let secret = fixed_secret(&dir);
    let before = std::fs::read(&secret).unwrap();
    let link = dir.join("link.key");
    std::os::unix::fs::symlink(&secret, &link).unwrap();
    for out in [secret.clone(), link, dir.join(".").join("machine.key")] {
        for force in [false, true] {
            let mut args = vec!["keys", "provision", "--keys", s(&secret), "--node", "0x11"];
            args.extend(["--board", "host", "--out", s(&out)]);
            if force {
                args.push("--force");
            }
            let o = tool(&args);
            assert_eq!(o.status.code(), Some(2), "{out:?} {force}");
            assert_eq!(
                text(&o.stderr),
                format!(
                    "error: --out {}: that is {}, which this command reads: it would be \
                     overwritten\n",
                    out.display(),
                    secret.display()
                )
            );
            assert_eq!(std::fs::read(&secret).unwrap(), before);
        }
    }
}

/// `provision --out` with a board other than the host (whose key file it writes) is a
/// command line that contradicts itself: status 2, as every such refusal (it was 1).
#[test]
fn provision_out_for_another_board_is_a_usage_error() {
    let dir = scratch("provision-out-board");
    let secret = fixed_secret(&dir);
    let out = dir.join("node.key");
    let o = tool(&[
        "keys",
        "provision",
        "--keys",
        s(&secret),
        "--node",
        "0x11",
        "--board",
        "qemu",
        "--out",
        s(&out),
    ]);
    assert_eq!(
        (o.status.code(), text(&o.stderr)),
        (
            Some(2),
            "error: --out writes the host board's key file: give --board host (or no \
             --board)\n"
                .to_string()
        )
    );
    assert!(!out.exists());
}
