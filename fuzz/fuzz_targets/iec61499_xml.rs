//! IEC 61499 XML, whatever its text: each reader on its own (a basic FB type, a composite
//! type, a node services type, a system), then the whole import as a user meets it: the
//! paint robot of `robot-configs/paint-robot-4diac.ron` compiled with its VC type
//! (`Vc.fbt`, first byte even) or its application (`PaintRobot.sys`, odd) replaced by the
//! text. Never a panic; libFuzzer's timeout catches work that does not end.
#![no_main]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use robot_compiler::iec61499::{composite, fbt, io_fb, sys};

const DIR: &str = "4diac/paint-robot";
const ROBOT: &str = "paint-robot-4diac.ron";
const FILES: [&str; 2] = ["Vc.fbt", "PaintRobot.sys"];

/// A copy of the robot and its XML files in a directory of this process's own: (its
/// directory, the robot's text, the originals of `FILES`).
fn bed() -> &'static (PathBuf, String, [String; 2]) {
    static BED: OnceLock<(PathBuf, String, [String; 2])> = OnceLock::new();
    BED.get_or_init(|| {
        let from = Path::new(env!("CARGO_MANIFEST_DIR")).join("../robot-configs");
        let dir = std::env::temp_dir().join(format!("robot-fuzz-xml-{}", std::process::id()));
        std::fs::create_dir_all(dir.join(DIR)).expect("a directory");
        for f in ["Vc.fbt", "Gr.fbt", "Hc.fbt", "Rc.fbt", "PaintRobot.sys"] {
            std::fs::copy(from.join(DIR).join(f), dir.join(DIR).join(f)).expect("copied");
        }
        let robot = std::fs::read_to_string(from.join(ROBOT)).expect("the robot");
        let original = FILES.map(|f| std::fs::read_to_string(from.join(DIR).join(f)).expect("xml"));
        (dir, robot, original)
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&which, rest)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    let _ = fbt::import_typed(text);
    let _ = composite::parse(text, "fuzz.fbt");
    let _ = io_fb::parse(text, "fuzz.fbt");
    let _ = sys::parse(text, "fuzz.sys");

    let (dir, robot, original) = bed();
    let replaced = usize::from(which & 1);
    for (i, (file, keep)) in FILES.iter().zip(original).enumerate() {
        let body = if i == replaced { text } else { keep.as_str() };
        std::fs::write(dir.join(DIR).join(file), body).expect("written");
    }
    let path = dir.join(ROBOT);
    let src = robot_compiler::Source::new(path.to_string_lossy(), robot.clone());
    let _ = robot_compiler::compile(&src);
});
