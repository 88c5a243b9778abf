//! The medium's capture of secured frames, read by Wireshark's IEEE 802.15.4 dissector
//! (`tshark`) with our keys (docs/security.md, "Reading a capture"). Needs `tshark`; CI
//! installs it and sets `REQUIRE_TSHARK=1`, so there a missing tshark fails instead of
//! skipping.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

use config_schema::wire::mac::{Header, FCS};
use config_schema::wire::medium::{Link, Peer};
use config_schema::wire::msg::{Command as Cmd, Message};
use config_schema::wire::security::{ext_addr, secure, AuxRepr};
use medium::{Config, Conn, Medium};

const ROBOT_PAN: u16 = 0xBEEF;
const CONFIG_PAN: u16 = 0xFFFF;
const VC: u16 = 0x0011;
const GR: u16 = 0x0012;
const TOOL: u16 = 0x0100;
/// The link key VC -> GR of a generation whose key index is 4, and the management key.
const LINK_KEY: [u8; 16] = *b"link key VC->GR!";
const MGMT_KEY: [u8; 16] = *b"management of VC";

fn tshark_here() -> bool {
    let have = Command::new("tshark")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !have {
        assert!(
            std::env::var_os("REQUIRE_TSHARK").is_none(),
            "REQUIRE_TSHARK is set but tshark is not installed"
        );
        eprintln!("tshark not installed: skipped");
    }
    have
}

fn message(m: &Message) -> Vec<u8> {
    let mut buf = [0u8; 116];
    let n = m.emit(&mut buf).unwrap();
    buf[..n].to_vec()
}

fn sealed(
    pan_id: u16,
    src: u16,
    dst: u16,
    aux: AuxRepr,
    key: &[u8; 16],
    payload: &[u8],
) -> Vec<u8> {
    let header = Header {
        seq: 1,
        pan_id,
        dst,
        src,
        ack_request: true,
        secured: false,
    };
    let mut psdu = [0u8; 127];
    let n = secure(
        &header,
        &aux,
        key,
        ext_addr(pan_id, src),
        payload,
        &mut psdu,
    )
    .unwrap();
    psdu[..n].to_vec()
}

/// One bit of the sealed payload's second byte flipped, the FCS mended: only the MIC can
/// tell.
fn flipped(mut psdu: Vec<u8>) -> Vec<u8> {
    psdu[16] ^= 0x01;
    let n = psdu.len() - 2;
    let fcs = FCS.checksum(&psdu[..n]);
    psdu[n..].copy_from_slice(&fcs.to_le_bytes());
    psdu
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Puts `frames` on a medium writing a capture and waits until a monitor heard each one
/// (so the capture holds them); returns the capture's path.
fn capture(dir: &Path, frames: &[Vec<u8>]) -> PathBuf {
    let path = dir.join("air.pcap");
    let medium = Medium::start(Config {
        pcap: Some(path.clone()),
        ..Config::default()
    })
    .unwrap();
    let mut monitor = Conn::join(medium.addr(), Peer::Monitor).unwrap();
    let mut radio = Conn::join(medium.addr(), Peer::Tool { addr: TOOL }).unwrap();
    for f in frames {
        radio.send(&Link::Frame(f)).unwrap();
        let until = Instant::now() + Duration::from_secs(5);
        let heard = monitor
            .recv(until, |l| {
                matches!(l, Link::Frame(p) if p == f.as_slice()).then_some(())
            })
            .unwrap();
        assert_eq!(heard, Some(()), "the monitor hears the frame");
    }
    medium.stop();
    path
}

const NO_HEURISTICS: [&str; 8] = [
    "--disable-protocol",
    "lwm",
    "--disable-protocol",
    "6lowpan",
    "--disable-protocol",
    "zbee_nwk",
    "--disable-protocol",
    "zbee_nwk_gp",
];

fn tshark(capture: &Path, options: &[String]) -> Output {
    let mut c = Command::new("tshark");
    c.arg("-r").arg(capture).args(NO_HEURISTICS);
    for o in options {
        c.arg("-o").arg(o);
    }
    c.args(["-T", "fields"]);
    for field in [
        "wpan.dst_pan",
        "wpan.src16",
        "wpan.dst16",
        "wpan.aux_sec.sec_level",
        "wpan.aux_sec.key_id_mode",
        "wpan.aux_sec.key_index",
        "wpan.aux_sec.frame_counter",
        "wpan.key_number",
        "data.data",
        "_ws.expert.message",
    ] {
        c.args(["-e", field]);
    }
    c.output().unwrap()
}

/// tshark, given the link key (its key index) and the static address of the sender
/// (short address, PAN, `ext_addr`), decrypts and verifies a link frame: the payload it
/// shows is the one we sealed, and it names the key that verified it. A bit-flipped copy
/// and a frame under a key index it has no key for are not verified (no key number, a
/// warning). The aux header fields are ours on every frame. Management frames (the config
/// PAN 0xFFFF) cannot be given a static address: tshark refuses the row.
#[test]
fn tshark_decrypts_and_verifies_link_frames_given_the_key_and_the_address() {
    if !tshark_here() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("medium-tshark-sec-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let event = message(&Message::Event {
        epoch: 1,
        seq: 4,
        topic: 2,
    });
    let start = message(&Message::Command {
        id: 3,
        command: Cmd::Start,
    });
    let good = sealed(ROBOT_PAN, VC, GR, AuxRepr::new(4, 100), &LINK_KEY, &event);
    let bad = flipped(sealed(
        ROBOT_PAN,
        VC,
        GR,
        AuxRepr::new(4, 101),
        &LINK_KEY,
        &event,
    ));
    let other = sealed(ROBOT_PAN, VC, GR, AuxRepr::new(5, 102), &LINK_KEY, &event);
    let mgmt = sealed(CONFIG_PAN, TOOL, VC, AuxRepr::new(0, 7), &MGMT_KEY, &start);
    let path = capture(&dir, &[good, bad.clone(), other.clone(), mgmt.clone()]);

    let keys = [
        format!(
            "uat:ieee802154_keys:\"{}\",\"4\",\"No hash\"",
            hex(&LINK_KEY)
        ),
        format!(
            "uat:ieee802154_keys:\"{}\",\"0\",\"No hash\"",
            hex(&MGMT_KEY)
        ),
        "uat:802154_addresses:\"0x0011\",\"0xbeef\",beef00fffe000011".to_string(),
    ];
    let out = tshark(&path, &keys);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    // Unverified frames show their bytes as they are: a bad MIC's CTR-decrypted payload
    // (the flipped bit shows through), the ciphertext of the others.
    let mut garbled = event.clone();
    garbled[1] ^= 0x01;
    let sealed_of = |psdu: &[u8]| hex(&psdu[15..psdu.len() - 10]);
    assert_eq!(
        text.lines().collect::<Vec<_>>(),
        [
            format!(
                "0xbeef\t0x0011\t0x0012\t0x06\t0x01\t0x04\t100\t0\t{}\t",
                hex(&event)
            ),
            format!(
                "0xbeef\t0x0011\t0x0012\t0x06\t0x01\t0x04\t101\t\t{}\t\
                 No encryption key set - can't decrypt",
                hex(&garbled)
            ),
            format!(
                "0xbeef\t0x0011\t0x0012\t0x06\t0x01\t0x05\t102\t\t{}\t\
                 No encryption key set - can't decrypt",
                sealed_of(&other)
            ),
            format!(
                "0xffff\t0x0100\t0x0011\t0x06\t0x01\t0x00\t7\t\t{}\t\
                 No extended source address - can't decrypt",
                sealed_of(&mgmt)
            ),
        ]
    );

    // The config PAN is the broadcast PAN, which tshark's static address table refuses.
    let refused = tshark(
        &path,
        &["uat:802154_addresses:\"0x0100\",\"0xffff\",ffff00fffe000100".to_string()],
    );
    assert!(!refused.status.success());
    assert!(
        String::from_utf8_lossy(&refused.stderr).contains("Invalid PAN identifier"),
        "{}",
        String::from_utf8_lossy(&refused.stderr)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
