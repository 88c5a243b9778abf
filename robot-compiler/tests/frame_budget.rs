//! Where the bytes of each paint-robot role's blob go, and whether it fits one frame.
//!
//!     cargo test -p robot-compiler --test frame_budget -- --nocapture
//!
//! prints, per role, the bits of each section of the packed payload (`config_schema::pack`)
//! beside the bytes its postcard encoding (schema 4) took, then a line per role against
//! the data of one `ConfigChunk` (`CHUNK_DATA`, the largest a secured frame carries):
//! `GR 53 B of 88: one frame`. docs/table-format.md ("Size") has the figures.

use std::path::Path;

use config_schema::blob::{HEADER_LEN, TRAILER_LEN};
use config_schema::pack::{self, SECTIONS};
use config_schema::wire::msg::CHUNK_DATA;
use robot_compiler::{compile, Compiled, Source};

fn paint_robot() -> Compiled {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../robot-configs/paint-robot.ron");
    let text = std::fs::read_to_string(&path).expect("read paint-robot.ron");
    compile(&Source::new(path.display().to_string(), text)).expect("paint robot compiles")
}

/// The blob bytes of each paint-robot role, as docs/table-format.md ("Size") gives them
/// (schema 4, postcard: VC 383, GR 192, HC 237, RC 218; schema 5: VC 113, GR 64, HC 78,
/// RC 74).
const BYTES: [(&str, usize); 4] = [("VC", 88), ("GR", 53), ("HC", 63), ("RC", 59)];

#[test]
fn where_the_bytes_of_each_role_go_and_the_frames_it_takes() {
    let c = paint_robot();
    let names: Vec<_> =
        c.ir.roles
            .iter()
            .map(|r| format!("{:>5}", r.name))
            .collect();
    println!("{:<24} {}", "section (bits)", names.join(" "));
    let mut marks = Vec::new();
    for t in &c.tables {
        let mut m = [0usize; SECTIONS.len()];
        let mut buf = [0u8; 4096];
        let n = pack::encode_form(t, &mut buf, Some(&mut m), false).expect("compact");
        assert_eq!(n, m[SECTIONS.len() - 1].div_ceil(8));
        marks.push(m);
    }
    for (i, name) in SECTIONS.iter().enumerate() {
        let cells: Vec<_> = marks
            .iter()
            .map(|m| format!("{:>5}", m[i] - i.checked_sub(1).map_or(0, |p| m[p])))
            .collect();
        println!("{name:<24} {}", cells.join(" "));
    }
    let totals: Vec<_> = marks
        .iter()
        .map(|m| format!("{:>5}", m[SECTIONS.len() - 1]))
        .collect();
    println!("{:<24} {}", "payload", totals.join(" "));
    let mut sizes = Vec::new();
    for ((role, blob), m) in c.ir.roles.iter().zip(&c.blobs).zip(&marks) {
        let payload = m[SECTIONS.len() - 1].div_ceil(8);
        assert_eq!(blob.len(), HEADER_LEN + payload + TRAILER_LEN);
        let frames = blob.len().div_ceil(CHUNK_DATA);
        println!(
            "{} {} B of {CHUNK_DATA}: {} (payload {payload} B, envelope {} B)",
            role.name,
            blob.len(),
            robot_compiler::compile::frames_text(frames),
            HEADER_LEN + TRAILER_LEN
        );
        sizes.push((role.name.as_str(), blob.len()));
    }
    assert_eq!(sizes, BYTES);
    // Every role fits one frame (VC with no byte to spare: docs/table-format.md).
    for (role, bytes) in BYTES {
        assert!(bytes <= CHUNK_DATA, "{role}: {bytes} B");
    }
}
