//! A command's output files, written all or none: `compile`'s blobs, `export-4diac`'s XML;
//! and an output file that is one of the command's inputs, refused before anything runs.

use std::path::{Path, PathBuf};

use crate::failure::Failure;

/// Refuses output file `out` (`what`: its flag) if it is one of `inputs`, however named
/// (the same file: a link, `./`, another path to it): it would be overwritten with what
/// the command made of it. Looks at the files' metadata only (opens nothing: a named pipe
/// to write to stays as it was).
pub fn not_an_input(what: &str, out: &Path, inputs: &[PathBuf]) -> Result<(), Failure> {
    let Ok(target) = std::fs::metadata(out) else {
        // Nothing there yet: no input is it.
        return Ok(());
    };
    match inputs
        .iter()
        .find(|input| std::fs::metadata(input).is_ok_and(|m| same_file(&m, &target, input, out)))
    {
        Some(input) => Err(Failure::usage(format!(
            "{what} {}: that is {}, which this command reads: it would be overwritten",
            out.display(),
            input.display()
        ))),
        None => Ok(()),
    }
}

/// [`not_an_input`] for each file `names` would write into directory `dir` (`what`: the
/// directory's flag).
pub fn none_an_input<'a>(
    what: &str,
    dir: &Path,
    names: impl IntoIterator<Item = &'a str>,
    inputs: &[PathBuf],
) -> Result<(), Failure> {
    names
        .into_iter()
        .try_for_each(|name| not_an_input(what, &dir.join(name), inputs))
}

/// Whether two files' metadata are of the same file (`a` at `a_path`, `b` at `b_path`).
#[cfg(unix)]
fn same_file(a: &std::fs::Metadata, b: &std::fs::Metadata, _: &Path, _: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    (a.dev(), a.ino()) == (b.dev(), b.ino())
}

#[cfg(not(unix))]
fn same_file(_: &std::fs::Metadata, _: &std::fs::Metadata, a_path: &Path, b_path: &Path) -> bool {
    matches!(
        (std::fs::canonicalize(a_path), std::fs::canonicalize(b_path)),
        (Ok(a), Ok(b)) if a == b
    )
}

/// The robot file at `path` and every file compiling it reads
/// ([`robot_compiler::model::Robot::imports`]).
pub fn robot_files(path: &Path, robot: &robot_compiler::model::Robot) -> Vec<PathBuf> {
    std::iter::once(path.to_path_buf())
        .chain(robot.imports(path))
        .collect()
}

/// Bytes of the longest file name the common file systems take (ext4, XFS, APFS, NTFS
/// in UTF-16 units, which a name of this many bytes never exceeds).
pub const MAX_FILE_NAME: usize = 255;

/// Writes each `(name, bytes)` into directory `dir` (made if missing), every file or none:
/// a name that is not a plain file name or comes twice, or a target that exists and is not
/// a file, is refused before anything is written; each file is written to a temporary
/// file beside it first (with the mode `fs::write` would give it: an existing target's,
/// else 0666 less the umask), and the temporary files become the targets only once all of
/// them are written. Returns the paths written, in order.
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
    let mut names = std::collections::HashSet::new();
    for (name, _) in &files {
        if !names.insert(*name) {
            return Err(Failure::error(format!(
                "two files named {name:?}: nothing written to {}",
                dir.display()
            )));
        }
        let plain = Path::new(name).file_name().and_then(|f| f.to_str()) == Some(*name);
        // Longer than a file system takes: it would fail part-way, the files before it
        // already in place.
        if !plain || name.len() > MAX_FILE_NAME {
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
        let path = dir.join(name);
        let mut builder = tempfile::Builder::new();
        builder.prefix(".").suffix(".partial");
        // 0666 less the umask, as `fs::write` creates a file (tempfile's own is 0600).
        #[cfg(unix)]
        builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
        let mut tmp = builder.tempfile_in(dir).map_err(|e| at(dir, &e))?;
        if let Ok(existing) = std::fs::metadata(&path) {
            // Created with the umask applied; an existing target keeps its own mode.
            std::fs::set_permissions(tmp.path(), existing.permissions())
                .map_err(|e| at(tmp.path(), &e))?;
        }
        std::io::Write::write_all(&mut tmp, bytes).map_err(|e| at(tmp.path(), &e))?;
        staged.push((tmp, path));
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

    /// The files get the mode `fs::write` gives: 0666 less the umask when new, an existing
    /// file's own when replaced.
    #[cfg(unix)]
    #[test]
    fn files_get_the_mode_a_plain_write_gives() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().expect("tempdir");
        let mode = |name: &str| {
            let m = std::fs::metadata(dir.path().join(name)).expect("written");
            m.permissions().mode() & 0o777
        };
        std::fs::write(dir.path().join("plain.bin"), b"p").expect("plain");
        std::fs::write(dir.path().join("kept.bin"), b"k").expect("kept");
        let kept = std::fs::Permissions::from_mode(0o640);
        std::fs::set_permissions(dir.path().join("kept.bin"), kept).expect("chmod");
        write_all(
            dir.path(),
            [("new.bin", &b"n"[..]), ("kept.bin", &b"k2"[..])],
        )
        .expect("ok");
        assert_eq!(mode("new.bin"), mode("plain.bin"));
        assert_eq!(mode("kept.bin"), 0o640);
    }

    #[test]
    fn a_name_given_twice_is_refused_before_anything_is_written() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("out");
        let e = write_all(
            &out,
            [("VC_IO.fbt", &b"type"[..]), ("VC_IO.fbt", &b"io"[..])],
        )
        .expect_err("twice");
        let want = format!(
            "error: two files named \"VC_IO.fbt\": nothing written to {}",
            out.display()
        );
        assert_eq!(e.message, want);
        assert!(!out.exists());
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
