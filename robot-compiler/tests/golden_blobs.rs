//! Every robot of `robot-configs/`, `tests/fixtures/` and `bench/robots/` compiles to the
//! same bytes as the committed golden data `tests/fixtures/blobs.golden`: one line per role
//! (`FILE ROLE BYTES HEX`), or `FILE -` for a robot that does not compile. A change of the
//! front end that keeps behaviour keeps these bytes.
//!
//! A change that means to change the blobs regenerates the file on purpose:
//!
//!     UPDATE_GOLDEN=1 cargo test -p robot-compiler --test golden_blobs
//!
//! and the diff of `tests/fixtures/blobs.golden` shows which blobs changed. CI never sets
//! `UPDATE_GOLDEN`.

use std::path::{Path, PathBuf};

use robot_compiler::{compile, Source};

const GOLDEN: &str = "tests/fixtures/blobs.golden";
const DIRS: &[&str] = &["robot-configs", "tests/fixtures", "bench/robots"];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every `.ron` file under `dir` (relative to the workspace root), recursively.
fn robots(dir: &Path, rel: &str, out: &mut Vec<String>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for path in entries {
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .expect("UTF-8 file name");
        let rel = format!("{rel}/{name}");
        if path.is_dir() {
            robots(&path, &rel, out);
        } else if name.ends_with(".ron") {
            out.push(rel);
        }
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The golden text of the robots as they compile now.
fn current() -> String {
    let mut files = Vec::new();
    for dir in DIRS {
        robots(&root().join(dir), dir, &mut files);
    }
    assert!(
        files.len() > 10,
        "found only {} robots: {files:?}",
        files.len()
    );
    let mut out = String::new();
    for file in files {
        let text = std::fs::read_to_string(root().join(&file)).expect("read robot");
        // Named by its path from here, so that a robot's `facts_file` is found.
        let name = root().join(&file).display().to_string();
        match compile(&Source::new(name, text)) {
            Ok(c) => {
                // Every compiled table takes the compact form, none the wide one.
                for (role, t) in c.ir.roles.iter().zip(&c.tables) {
                    assert!(
                        config_schema::pack::is_compact(t),
                        "{file} {}: not compact",
                        role.name
                    );
                }
                for (role, blob) in c.ir.roles.iter().zip(&c.blobs) {
                    out.push_str(&format!(
                        "{file} {} {} {}\n",
                        role.name,
                        blob.len(),
                        hex(blob)
                    ));
                }
            }
            Err(_) => out.push_str(&format!("{file} -\n")),
        }
    }
    out
}

#[test]
fn every_robot_compiles_to_its_golden_blobs() {
    let now = current();
    let path = root().join(GOLDEN);
    if std::env::var_os("UPDATE_GOLDEN").is_some() {
        std::fs::write(&path, &now).expect("write golden blobs");
        return;
    }
    let golden = std::fs::read_to_string(&path).expect("read tests/fixtures/blobs.golden");
    let (now_lines, golden_lines): (Vec<&str>, Vec<&str>) =
        (now.lines().collect(), golden.lines().collect());
    for i in 0..now_lines.len().max(golden_lines.len()) {
        let (n, g) = (now_lines.get(i).copied(), golden_lines.get(i).copied());
        if n == g {
            continue;
        }
        let (n, g) = (n.unwrap_or("(none)"), g.unwrap_or("(none)"));
        let at = n.bytes().zip(g.bytes()).take_while(|(a, b)| a == b).count();
        let show = |l: &str| {
            l.chars()
                .take(at + 40)
                .skip(at.saturating_sub(40))
                .collect::<String>()
        };
        panic!(
            "line {} of {GOLDEN} differs at column {}:\n  golden: ...{}\n  now:    ...{}\n\
             (regenerate with UPDATE_GOLDEN=1 only if the change of the blobs is meant)",
            i + 1,
            at + 1,
            show(g),
            show(n)
        );
    }
}
