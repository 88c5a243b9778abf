//! A command's output files, written all or none: `compile`'s blobs, `export-4diac`'s XML.

use std::path::{Path, PathBuf};

use crate::failure::Failure;

/// Writes each `(name, bytes)` into directory `dir` (made if missing), every file or none:
/// a name that is not a plain file name, or a target that exists and is not a file, is
/// refused before anything is written; each file is written to a temporary file beside it
/// first, and the temporary files become the targets only once all of them are written.
/// Returns the paths written, in order.
pub fn write_all<'a>(
    dir: &Path,
    files: impl IntoIterator<Item = (&'a str, &'a [u8])>,
) -> Result<Vec<PathBuf>, Failure> {
    let at =
        |path: &Path, e: &dyn std::fmt::Display| Failure::error(format!("{}: {e}", path.display()));
    let files: Vec<(&str, &[u8])> = files.into_iter().collect();
    if std::fs::metadata(dir).is_ok_and(|m| !m.is_dir()) {
        return Err(at(dir, &"exists and is not a directory: nothing written"));
    }
    for (name, _) in &files {
        let plain = Path::new(name).file_name().and_then(|f| f.to_str()) == Some(*name);
        if !plain {
            return Err(Failure::error(format!(
                "{name:?} is not a file name: nothing written to {}",
                dir.display()
            )));
        }
        let path = dir.join(name);
        if std::fs::symlink_metadata(&path).is_ok_and(|m| !m.is_file()) {
            return Err(at(&path, &"exists and is not a file: nothing written"));
        }
    }
    std::fs::create_dir_all(dir).map_err(|e| at(dir, &e))?;
    let mut staged = Vec::with_capacity(files.len());
    for (name, bytes) in &files {
        let mut tmp = tempfile::Builder::new()
            .prefix(".")
            .suffix(".partial")
            .tempfile_in(dir)
            .map_err(|e| at(dir, &e))?;
        std::io::Write::write_all(&mut tmp, bytes).map_err(|e| at(tmp.path(), &e))?;
        staged.push((tmp, dir.join(name)));
    }
    let mut written = Vec::with_capacity(staged.len());
    for (tmp, path) in staged {
        tmp.persist(&path).map_err(|e| at(&path, &e.error))?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .expect("dir")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn every_file_is_written() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("out");
        let written = write_all(&out, [("A.bin", &b"a"[..]), ("B.bin", &b"bb"[..])]).expect("ok");
        assert_eq!(written, [out.join("A.bin"), out.join("B.bin")]);
        assert_eq!(names(&out), ["A.bin", "B.bin"]);
        assert_eq!(std::fs::read(out.join("B.bin")).expect("B"), b"bb");
        // Written again over the old files.
        write_all(&out, [("A.bin", &b"new"[..])]).expect("ok");
        assert_eq!(std::fs::read(out.join("A.bin")).expect("A"), b"new");
    }

    #[test]
    fn a_target_that_is_a_directory_leaves_every_file_as_it_was() {
        let dir = tempfile::tempdir().expect("tempdir");
        std::fs::write(dir.path().join("A.bin"), b"old").expect("A");
        std::fs::create_dir(dir.path().join("C.bin")).expect("C");
        let files = [
            ("A.bin", &b"new"[..]),
            ("B.bin", &b"b"[..]),
            ("C.bin", &b"c"[..]),
        ];
        let e = write_all(dir.path(), files).expect_err("C.bin is a directory");
        let c = dir.path().join("C.bin");
        let want = format!(
            "error: {}: exists and is not a file: nothing written",
            c.display()
        );
        assert_eq!(e.message, want);
        assert_eq!(names(dir.path()), ["A.bin", "C.bin"]);
        assert_eq!(std::fs::read(dir.path().join("A.bin")).expect("A"), b"old");
        // The directory itself a file.
        let a = dir.path().join("A.bin");
        let e = write_all(&a, [("B.bin", &b"b"[..])]).expect_err("A.bin is a file");
        let want = format!(
            "error: {}: exists and is not a directory: nothing written",
            a.display()
        );
        assert_eq!(e.message, want);
    }

    #[test]
    fn a_name_that_is_a_path_is_refused_before_anything_is_written() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("out");
        for name in ["../A.bin", "/tmp/A.bin", "a/b.bin", "..", ""] {
            let e = write_all(&out, [("ok.bin", &b"1"[..]), (name, &b"2"[..])]).expect_err(name);
            assert_eq!(
                e.message,
                format!(
                    "error: {name:?} is not a file name: nothing written to {}",
                    out.display()
                )
            );
            assert!(!out.exists(), "{name}");
        }
    }
}
