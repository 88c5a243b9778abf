//! `keys new` and `keys provision`: the machine secret's key file, and what to write on a
//! node (docs/security.md). Only `keys provision` prints key material: what to flash.

use std::fmt::Write as _;
use std::path::Path;

use node_fw::provision::{self, ManagementKey, NodeKeyLine, Word};
use robot_keys::{load_machine_secret, management_key, write_machine_secret, write_secret_file};

use crate::cli::Board;
use crate::failure::Failure;
use crate::out::{out, outln};

/// `keys new --out FILE [--force]`.
pub fn new(out: &Path, force: bool) -> Result<(), Failure> {
    write_machine_secret(out, force).map_err(Failure::error)?;
    outln!(
        "wrote a new machine secret to {} (mode 0600): every node's key derives from it; \
         keep it as you keep the machine's root password",
        out.display()
    );
    Ok(())
}

/// `keys provision --keys FILE --node ADDR [--board B] [--out FILE [--force]]`.
pub fn provision(
    keys: &Path,
    node: u16,
    board: Option<Board>,
    out: Option<&Path>,
    force: bool,
) -> Result<(), Failure> {
    if out.is_some() && !matches!(board, None | Some(Board::Host)) {
        return Err(Failure::usage(
            "--out writes the host board's key file: give --board host (or no --board)",
        ));
    }
    if let Some(out) = out {
        // Not even with --force: every node's key derives from the secret.
        super::outputs::not_an_input("--out", out, &[keys.to_path_buf()])?;
    }
    let secret = load_machine_secret(keys).map_err(Failure::error)?;
    let key = ManagementKey::from_bytes(*management_key(&secret, node).expose());
    let boards = match board {
        Some(b) => vec![b],
        None => vec![Board::Host, Board::Qemu, Board::Nrf52840],
    };
    let mut text = String::new();
    for (i, b) in boards.into_iter().enumerate() {
        if i > 0 {
            text.push('\n');
        }
        match b {
            Board::Host => host(&mut text, node, &key, out, force)?,
            Board::Qemu => qemu(&mut text, node, &key),
            Board::Nrf52840 => nrf52840(&mut text, node, &key),
        }
    }
    out!("{text}");
    Ok(())
}

fn host(
    text: &mut String,
    node: u16,
    key: &ManagementKey,
    out: Option<&Path>,
    force: bool,
) -> Result<(), Failure> {
    let line = NodeKeyLine { addr: node, key }.to_string();
    match out {
        Some(path) => {
            write_secret_file(path, line.as_bytes(), force).map_err(Failure::error)?;
            let _ = writeln!(
                text,
                "# node {node:#06x}, host board: wrote its key file {0} (mode 0600); run it with\n\
                 node-host --addr {node:#06x} --key {0} --medium HOST:PORT\n\
                 # or: config-tool node --addr {node:#06x} --key {0} --medium HOST:PORT",
                path.display()
            );
        }
        None => {
            let _ = write!(
                text,
                "# node {node:#06x}, host board: this line is its key file (keep it with mode \
                 0600, or give --out FILE)\n\
                 {line}\
                 # then: node-host --addr {node:#06x} --key FILE --medium HOST:PORT\n"
            );
        }
    }
    Ok(())
}

fn qemu(text: &mut String, node: u16, key: &ManagementKey) {
    let _ = writeln!(
        text,
        "# node {node:#06x}, qemu-mps2: QEMU arguments writing the provisioning word (key flag \
         set) and the key's four words after it\n\
         # (config-tool qemu-node --addr {node:#06x} --key FILE adds the same from the host key file)"
    );
    for loader in
        robot_net::demo::provision_loaders(robot_net::demo::provision_word(node), Some(key))
    {
        let _ = writeln!(text, "-device {loader}");
    }
}

fn nrf52840(text: &mut String, node: u16, key: &ManagementKey) {
    use provision::nrf52840::{KEY_AT, WORD_AT};
    let word = Word {
        addr: node,
        flags: provision::FLAG_KEY,
    }
    .encode();
    let _ = writeln!(
        text,
        "# node {node:#06x}, nrf52840: UICR CUSTOMER[0] (the provisioning word, key flag set) and \
         CUSTOMER[2..=5] (the key); CUSTOMER[1] stays the radio channel\n\
         # (UICR bits only clear: on a node provisioned before, nrfjprog --eraseuicr first, then \
         write the channel again)\n\
         nrfjprog --memwr {WORD_AT:#010X} --val {word:#010X}"
    );
    for (i, w) in key.words().into_iter().enumerate() {
        let at = KEY_AT + 4 * i as u32;
        let _ = writeln!(text, "nrfjprog --memwr {at:#010X} --val {w:#010X}");
    }
    let _ = writeln!(text, "nrfjprog --reset");
}
