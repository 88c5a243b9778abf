//! Shared by robot-analysis's tests: robots read from the workspace and compiled.
#![allow(dead_code)]

use robot_compiler::{compile, Compiled, Source};

/// A robot file, by its path under the workspace's `tests/` (`fixtures/...`,
/// `../robot-configs/...`).
pub fn load(path: &str) -> Source {
    let full = format!("{}/../tests/{path}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&full).unwrap_or_else(|e| panic!("{full}: {e}"));
    Source::new(path, text)
}

/// Compiles `src`, or panics with every diagnostic.
pub fn build(src: &Source) -> Compiled {
    match compile(src) {
        Ok(c) => c,
        Err(d) => panic!(
            "{}",
            d.iter()
                .map(|d| d.short(src))
                .collect::<Vec<_>>()
                .join("\n")
        ),
    }
}

/// The robot files of `robot-configs/`, by file name, sorted.
pub fn robot_configs() -> Vec<String> {
    let dir = format!("{}/../robot-configs", env!("CARGO_MANIFEST_DIR"));
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .expect("robot-configs")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".ron"))
        .collect();
    files.sort();
    files
}
