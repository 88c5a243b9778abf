//! The robots of `robot-configs/`, for the tests that go through every one of them (the
//! IEC 61499 export tests of robot-compiler, the round trip of robot-tests): their files,
//! each compiled, each exported (feature `robots`).

use std::path::{Path, PathBuf};

use robot_compiler::iec61499::export::{self, Export};
use robot_compiler::{compile, Compiled, Source};

/// The date the tests' exports write in every `VersionInfo`.
pub const DATE: &str = "2026-01-01";

/// Every robot file (`.ron`) of `robot-configs/`, sorted.
pub fn robots() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../robot-configs");
    let mut out: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "ron"))
        .collect();
    out.sort();
    out
}

/// The robot file at `path`, read and compiled (it must compile).
pub fn compiled(path: &Path) -> (Source, Compiled) {
    let src = Source::read(path).unwrap();
    let c = compile(&src).unwrap_or_else(|d| panic!("{}: {d:?}", path.display()));
    (src, c)
}

/// The compiled robot exported to IEC 61499-2 XML (it must export), dated [`DATE`].
pub fn exported(c: &Compiled) -> Export {
    export::export(c, DATE).unwrap_or_else(|e| panic!("{}: {e}", c.ir.name))
}
