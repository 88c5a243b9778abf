//! Key files: written atomically with mode 0600, refused when group or others may read or
//! write them.
//!
//! The machine secret's file is one line of text:
//!
//! ```text
//! robot-machine-secret v1 <64 lowercase hex digits>
//! ```

use std::fs::File;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

use zeroize::Zeroizing;

use crate::secret::{MachineSecret, SECRET_LEN};

/// The first word of a machine secret's file, and its version.
pub const MACHINE_SECRET_TAG: &str = "robot-machine-secret v1 ";

/// Longer files are not key files (read no further).
const MAX_LEN: u64 = 4096;

/// Why a key file could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum KeyFileError {
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: io::Error },
    #[error(
        "{}: exists; refusing to replace a key (give --force to replace it: what was \
         provisioned from it must then be provisioned again)",
        path.display()
    )]
    Exists { path: PathBuf },
    #[error(
        "{}: mode {mode:04o} lets group or others read or write it; a key file must be \
         readable by its owner only (chmod 600 {})",
        path.display(),
        path.display()
    )]
    Permissions { path: PathBuf, mode: u32 },
    #[error(
        "{}: no such key file (the machine secret is made once, by `config-tool keys new \
         --out {}`)",
        path.display(),
        path.display()
    )]
    Missing { path: PathBuf },
    #[error("{}: not a regular file", path.display())]
    NotAFile { path: PathBuf },
    #[error(
        "{}: owned by user {owner}, not by this user ({me}): whoever owns it may know the key",
        path.display()
    )]
    NotOwned { path: PathBuf, owner: u32, me: u32 },
    #[error("{}:{line}:{col}: {what}", path.display())]
    Format {
        path: PathBuf,
        line: usize,
        col: usize,
        what: String,
    },
    #[error("the operating system's random source failed: {0}")]
    Random(getrandom::Error),
}

fn io_error(path: &Path) -> impl FnOnce(io::Error) -> KeyFileError + '_ {
    move |source| KeyFileError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes `contents` to `path` with mode 0600, atomically (a temporary file in the same
/// directory, synced, then renamed or linked into place): the file is there whole or not
/// at all. An existing file is replaced only with `force`.
pub fn write_secret_file(path: &Path, contents: &[u8], force: bool) -> Result<(), KeyFileError> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match path.symlink_metadata() {
        Ok(_) if !force => {
            return Err(KeyFileError::Exists {
                path: path.to_path_buf(),
            })
        }
        // `--force` replaces a key file (or a link), never a FIFO, a device or a
        // directory (as root, `--out /dev/null --force` replaced the system's).
        Ok(meta) if !(meta.is_file() || meta.is_symlink()) => {
            return Err(KeyFileError::NotAFile {
                path: path.to_path_buf(),
            })
        }
        _ => {}
    }
    if !dir.is_dir() {
        let missing = io::Error::new(
            io::ErrorKind::NotFound,
            format!("no directory {}", dir.display()),
        );
        return Err(io_error(path)(missing));
    }
    // `tempfile` creates the file with mode 0600 (O_EXCL, owner only). Its errors name the
    // temporary file, which the user never asked for: only their kind is kept.
    let mut tmp = tempfile::Builder::new()
        .prefix(".key-")
        .tempfile_in(dir)
        .map_err(|e| io_error(path)(io::Error::from(e.kind())))?;
    set_owner_only(tmp.as_file()).map_err(io_error(path))?;
    tmp.write_all(contents).map_err(io_error(path))?;
    tmp.as_file().sync_all().map_err(io_error(path))?;
    let placed = if force {
        tmp.persist(path).map(drop)
    } else {
        tmp.persist_noclobber(path).map(drop)
    };
    match placed {
        Ok(()) => {}
        Err(e) if e.error.kind() == io::ErrorKind::AlreadyExists => {
            return Err(KeyFileError::Exists {
                path: path.to_path_buf(),
            })
        }
        Err(e) => return Err(io_error(path)(e.error)),
    }
    // The rename is durable once the directory is synced (best effort: not every
    // platform can open a directory).
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

#[cfg(unix)]
fn set_owner_only(f: &File) -> io::Result<()> {
    use std::os::unix::fs::PermissionsExt;
    f.set_permissions(std::fs::Permissions::from_mode(0o600))
}

#[cfg(not(unix))]
fn set_owner_only(_: &File) -> io::Result<()> {
    Ok(())
}

/// Reads a key file: a regular file of at most 4 KiB that neither group nor others may
/// read or write (checked on the opened file), as text.
pub fn read_secret_file(path: &Path) -> Result<Zeroizing<String>, KeyFileError> {
    // Not opened unless it is a regular file (opening a FIFO would wait for a writer).
    let meta = match std::fs::metadata(path) {
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            return Err(KeyFileError::Missing {
                path: path.to_path_buf(),
            })
        }
        other => other.map_err(io_error(path))?,
    };
    if !meta.is_file() {
        return Err(KeyFileError::NotAFile {
            path: path.to_path_buf(),
        });
    }
    let f = File::open(path).map_err(io_error(path))?;
    let meta = f.metadata().map_err(io_error(path))?;
    if !meta.is_file() {
        return Err(KeyFileError::NotAFile {
            path: path.to_path_buf(),
        });
    }
    check_owner_only(path, &meta)?;
    let mut bytes = Zeroizing::new(Vec::with_capacity(MAX_LEN as usize + 1));
    f.take(MAX_LEN + 1)
        .read_to_end(&mut bytes)
        .map_err(io_error(path))?;
    if bytes.len() as u64 > MAX_LEN {
        return Err(format_error(path, "", 0, "longer than a key file (4 KiB)"));
    }
    match std::str::from_utf8(&bytes) {
        Ok(text) => Ok(Zeroizing::new(text.to_string())),
        Err(e) => {
            let before = String::from_utf8_lossy(&bytes[..e.valid_up_to()]).into_owned();
            Err(format_error(path, &before, before.len(), "not UTF-8 text"))
        }
    }
}

/// Whether the file of `meta` (at `path`) is a secret's: owned by this user, neither read
/// nor written by others (a file another user owns or may write, they may know or set).
#[cfg(unix)]
fn check_owner_only(path: &Path, meta: &std::fs::Metadata) -> Result<(), KeyFileError> {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let me = rustix::process::geteuid().as_raw();
    if meta.uid() != me {
        return Err(KeyFileError::NotOwned {
            path: path.to_path_buf(),
            owner: meta.uid(),
            me,
        });
    }
    let mode = meta.permissions().mode() & 0o7777;
    if mode & 0o066 != 0 {
        return Err(KeyFileError::Permissions {
            path: path.to_path_buf(),
            mode,
        });
    }
    Ok(())
}

/// [`check_owner_only`] where there are no owners and modes: every file passes.
#[cfg(not(unix))]
fn check_owner_only(_: &Path, _: &std::fs::Metadata) -> Result<(), KeyFileError> {
    Ok(())
}

/// A format error at byte `at` of `text`, as line:col (1-based, col in characters).
fn format_error(path: &Path, text: &str, at: usize, what: &str) -> KeyFileError {
    let before = text.get(..at).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    KeyFileError::Format {
        path: path.to_path_buf(),
        line,
        col,
        what: what.to_string(),
    }
}

/// The text of a machine secret's file.
pub fn machine_secret_text(secret: &MachineSecret) -> Zeroizing<String> {
    let mut text = Zeroizing::new(String::with_capacity(MACHINE_SECRET_TAG.len() + 65));
    text.push_str(MACHINE_SECRET_TAG);
    for b in secret.expose() {
        text.push_str(&format!("{b:02x}"));
    }
    text.push('\n');
    text
}

/// Parses a machine secret's file (`path` names it in errors).
pub fn parse_machine_secret(path: &Path, text: &str) -> Result<MachineSecret, KeyFileError> {
    let err = |at: usize, what: &str| format_error(path, text, at, what);
    let Some(rest) = text.strip_prefix(MACHINE_SECRET_TAG) else {
        return Err(err(
            0,
            "not a machine secret (expected `robot-machine-secret v1 ` and 64 hex digits; \
             `config-tool keys new` writes one)",
        ));
    };
    let start = MACHINE_SECRET_TAG.len();
    let mut bytes = Zeroizing::new([0u8; SECRET_LEN]);
    let digits = rest.as_bytes();
    for (i, b) in bytes.iter_mut().enumerate() {
        let (Some(hi), Some(lo)) = (
            digits.get(2 * i).and_then(|d| hex_digit(*d)),
            digits.get(2 * i + 1).and_then(|d| hex_digit(*d)),
        ) else {
            let bad = (2 * i..2 * i + 2)
                .find(|j| digits.get(*j).and_then(|d| hex_digit(*d)).is_none())
                .unwrap_or(2 * i);
            return Err(err(
                start + bad,
                "expected 64 hex digits (the 32 bytes of the secret)",
            ));
        };
        *b = hi << 4 | lo;
    }
    let tail = &rest[2 * SECRET_LEN..];
    if !(tail.is_empty() || tail == "\n" || tail == "\r\n") {
        return Err(err(
            start + 2 * SECRET_LEN,
            "expected the end of the line after 64 hex digits",
        ));
    }
    Ok(MachineSecret::from_bytes(*bytes))
}

fn hex_digit(d: u8) -> Option<u8> {
    match d {
        b'0'..=b'9' => Some(d - b'0'),
        b'a'..=b'f' => Some(d - b'a' + 10),
        b'A'..=b'F' => Some(d - b'A' + 10),
        _ => None,
    }
}

/// `keys new`: a fresh machine secret from the OS, written to `path` (mode 0600;
/// an existing file only replaced with `force`).
pub fn write_machine_secret(path: &Path, force: bool) -> Result<(), KeyFileError> {
    let secret = MachineSecret::generate().map_err(KeyFileError::Random)?;
    write_secret_file(path, machine_secret_text(&secret).as_bytes(), force)
}

/// Reads the machine secret from its key file (mode checked first).
pub fn load_machine_secret(path: &Path) -> Result<MachineSecret, KeyFileError> {
    let text = read_secret_file(path)?;
    parse_machine_secret(path, &text)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("robot-keys-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
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

    #[test]
    fn a_missing_key_file_says_how_to_make_one() {
        let p = dir("missing").join("machine.key");
        let e = load_machine_secret(&p).unwrap_err();
        assert!(matches!(e, KeyFileError::Missing { .. }), "{e:?}");
        assert_eq!(
            e.to_string(),
            format!(
                "{0}: no such key file (the machine secret is made once, by `config-tool keys \
                 new --out {0}`)",
                p.display()
            )
        );
    }

    #[test]
    fn a_new_secret_is_written_owner_only_and_reads_back() {
        let d = dir("new");
        let p = d.join("machine.key");
        write_machine_secret(&p, false).unwrap();
        #[cfg(unix)]
        assert_eq!(mode(&p), 0o600);
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.starts_with(MACHINE_SECRET_TAG) && text.ends_with('\n'));
        assert_eq!(text.len(), MACHINE_SECRET_TAG.len() + 65);
        let s = load_machine_secret(&p).unwrap();
        assert_eq!(machine_secret_text(&s).as_str(), text);
        // Only the file is left: no temporary beside it.
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
    }

    /// A key file in a directory that does not exist: said so, without the name of the
    /// temporary file the write would have used (it said `... at path "nodir/.key-QaHBWk"`).
    #[test]
    fn a_key_file_in_a_missing_directory_says_so() {
        let p = dir("nodir").join("not-there").join("machine.key");
        let e = write_machine_secret(&p, false).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!(
                "{}: no directory {}",
                p.display(),
                p.parent().unwrap().display()
            )
        );
    }

    /// `--force` replaces a key file, not whatever else has the name: a FIFO stays.
    #[cfg(unix)]
    #[test]
    fn force_replaces_no_fifo() {
        use std::os::unix::fs::FileTypeExt;
        let p = dir("fifo").join("pipe");
        let made = std::process::Command::new("mkfifo")
            .arg(&p)
            .status()
            .unwrap();
        assert!(made.success());
        let e = write_machine_secret(&p, true).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("{}: not a regular file", p.display())
        );
        assert!(std::fs::symlink_metadata(&p).unwrap().file_type().is_fifo());
    }

    #[test]
    fn an_existing_file_is_replaced_only_with_force() {
        let d = dir("force");
        let p = d.join("machine.key");
        write_machine_secret(&p, false).unwrap();
        let first = std::fs::read_to_string(&p).unwrap();
        let e = write_machine_secret(&p, false).unwrap_err();
        assert!(matches!(e, KeyFileError::Exists { .. }), "{e}");
        assert_eq!(std::fs::read_to_string(&p).unwrap(), first);
        write_machine_secret(&p, true).unwrap();
        assert_ne!(std::fs::read_to_string(&p).unwrap(), first);
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_is_refused_at_once_not_waited_on() {
        let d = dir("fifo");
        let p = d.join("machine.key");
        let made = std::process::Command::new("mkfifo")
            .arg(&p)
            .status()
            .unwrap();
        assert!(made.success());
        let e = load_machine_secret(&p).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("{}: not a regular file", p.display())
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_file_others_may_read_or_write_is_refused() {
        let d = dir("mode");
        let p = d.join("machine.key");
        write_machine_secret(&p, false).unwrap();
        for m in [0o644, 0o640, 0o604, 0o620, 0o602, 0o666] {
            chmod(&p, m);
            let e = load_machine_secret(&p).unwrap_err();
            assert_eq!(
                e.to_string(),
                format!(
                    "{0}: mode {m:04o} lets group or others read or write it; a key file \
                     must be readable by its owner only (chmod 600 {0})",
                    p.display()
                )
            );
        }
        for m in [0o600, 0o400, 0o700] {
            chmod(&p, m);
            load_machine_secret(&p).unwrap();
        }
    }

    #[test]
    fn bad_files_name_the_place() {
        let p = Path::new("m.key");
        let e = |t: &str| parse_machine_secret(p, t).unwrap_err().to_string();
        assert!(e("hello\n").starts_with("m.key:1:1: not a machine secret"));
        let good = format!("{MACHINE_SECRET_TAG}{}", "ab".repeat(32));
        assert!(parse_machine_secret(p, &good).is_ok());
        assert!(parse_machine_secret(p, &format!("{good}\r\n")).is_ok());
        let short = format!("{MACHINE_SECRET_TAG}{}\n", "ab".repeat(31));
        assert_eq!(
            e(&short),
            "m.key:1:87: expected 64 hex digits (the 32 bytes of the secret)"
        );
        let bad = format!("{MACHINE_SECRET_TAG}ab{}", "x".repeat(62));
        assert_eq!(
            e(&bad),
            "m.key:1:27: expected 64 hex digits (the 32 bytes of the secret)"
        );
        assert_eq!(
            e(&format!("{good}\nmore")),
            "m.key:1:89: expected the end of the line after 64 hex digits"
        );
        // Not a char boundary inside the digits: still an error, no panic.
        let utf = format!("{MACHINE_SECRET_TAG}{}é", "ab".repeat(31));
        assert!(e(&utf).starts_with("m.key:1:87: expected 64 hex digits"));
    }

    #[test]
    fn a_long_or_binary_file_is_refused() {
        let d = dir("long");
        let p = d.join("k");
        write_secret_file(&p, &[b'a'; 5000], false).unwrap();
        assert!(read_secret_file(&p)
            .unwrap_err()
            .to_string()
            .ends_with("k:1:1: longer than a key file (4 KiB)"));
        let q = d.join("b");
        write_secret_file(&q, b"ab\n\xff", false).unwrap();
        assert!(read_secret_file(&q)
            .unwrap_err()
            .to_string()
            .ends_with("b:2:1: not UTF-8 text"));
    }
}
