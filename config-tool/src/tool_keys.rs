//! The tool's side of frame security (docs/security.md): the machine secret's key file
//! (`--keys FILE`, or `CONFIG_TOOL_KEYS`) and the tool's frame counter, kept in the counter
//! file beside it (`FILE.counter`).
//!
//! The counter is the host node's: a `node_fw::frame_counter::FrameCounter` over a host
//! flash file of two erase pages (`node_fw::host::flash::HostFlash::open_counter`),
//! reserved 1024 ahead, so it is strictly increasing across runs of the tool and power cuts
//! with one write per run and per 1024 frames. Runs with the same key file share it, each frame's counter taken
//! under an exclusive advisory lock (`flock`) on the counter file: the run reads the file
//! again (`FrameCounter::catch_up`) and, if another run reserved above its own
//! reservation since, goes on above that one. Every counter is then above every one
//! handed out before it, by any run (the nodes refuse a counter at or below the last one
//! they took from the tool as a replay), and a panel, a watch or `alarms --watch` can run
//! while other commands are given. A run waits [`LOCK_WAIT`] at most for another to let
//! go (a run holds the lock for one read and, when its reservation is used up, one write).

use std::fs::{File, OpenOptions};
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use node_fw::frame_counter::{CounterError, FrameCounter};
use node_fw::host::flash::{counter_path, FlashError, HostFlash, OpenError, COUNTER_FILE_SIZE};
use robot_keys::{load_machine_secret, KeyFileError, MachineSecret};
use robot_net::radio::CounterSource;

/// How long a run waits for another run's lock on the counter file before it gives up.
pub const LOCK_WAIT: Duration = Duration::from_secs(2);

/// The environment variable that stands for `--keys FILE` when the flag is not given.
pub const KEYS_ENV: &str = "CONFIG_TOOL_KEYS";

/// Where the key file came from: `--keys` or [`KEYS_ENV`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum KeysFrom {
    Flag(PathBuf),
    Env(PathBuf),
}

impl KeysFrom {
    /// `--keys FILE` if given, else a non-empty [`KEYS_ENV`].
    pub fn resolve(flag: Option<&Path>) -> Option<KeysFrom> {
        match flag {
            Some(p) => Some(KeysFrom::Flag(p.to_path_buf())),
            None => std::env::var_os(KEYS_ENV)
                .filter(|v| !v.is_empty())
                .map(|v| KeysFrom::Env(PathBuf::from(v))),
        }
    }

    pub fn path(&self) -> &Path {
        match self {
            KeysFrom::Flag(p) | KeysFrom::Env(p) => p,
        }
    }
}

/// What a secured radio is given: the secret and the counter (shared with other runs of
/// the same key file).
pub struct ToolKeys {
    pub secret: MachineSecret,
    pub counter: CounterSource,
}

/// Why the tool cannot secure its frames.
#[derive(Debug, thiserror::Error)]
pub enum ToolKeyError {
    /// The key file: missing, readable by others, not a secret, ...
    #[error(transparent)]
    Key(#[from] KeyFileError),
    #[error(
        "counter file {}: locked by another config-tool process with the same key file for \
         over {} s (stopped while it held it?)",
        .0.display(),
        LOCK_WAIT.as_secs()
    )]
    Locked(PathBuf),
    #[error("counter file {}: {source}", path.display())]
    Io { path: PathBuf, source: io::Error },
    #[error(
        "counter file {}: {found} bytes, not a frame counter file ({expected} bytes); left \
         unchanged",
        path.display()
    )]
    Size {
        path: PathBuf,
        found: u64,
        expected: u64,
    },
    #[error("counter file {}: {why}", path.display())]
    Unreadable { path: PathBuf, why: String },
    #[error(
        "counter file {}: its directory is writable by others (mode {mode:04o}): they could \
         set the counter back; keep the key file in a directory of this user's",
        path.display()
    )]
    OpenDirectory { path: PathBuf, mode: u32 },
    #[error(
        "counter file {}: owned by user {owner} with mode {mode:04o}: only its owner, this \
         user, may write it (another could set the counter back); fix it or remove it",
        path.display()
    )]
    NotOwnersAlone {
        path: PathBuf,
        owner: u32,
        mode: u32,
    },
}

/// Reads the machine secret of `key_file` (refused if others may read it) and opens the
/// tool's frame counter beside it, shared with every other run of the same key file.
pub fn open(key_file: &Path) -> Result<ToolKeys, ToolKeyError> {
    let secret = load_machine_secret(key_file)?;
    // The key file itself, not the name it was reached by: a link to it (or another
    // spelling of its path) gets the same counter file and lock, never a second counter
    // that starts at 0 (a nonce used twice under one key).
    let key_file = &std::fs::canonicalize(key_file).map_err(|source| ToolKeyError::Io {
        path: key_file.to_path_buf(),
        source,
    })?;
    let path = counter_path(key_file);
    let file = lock(&path)?;
    let counter =
        FrameCounter::open(counter_flash(&file, &path)?).map_err(|e| ToolKeyError::Unreadable {
            path: path.clone(),
            why: counter_failure(e),
        })?;
    unlock(&file);
    let mut shared = Shared {
        file,
        path,
        counter,
    };
    Ok(ToolKeys {
        secret,
        counter: Box::new(move || shared.next()),
    })
}

/// The tool's frame counter in its counter file, which other runs write too.
struct Shared {
    /// The counter file, open for its lock.
    file: File,
    path: PathBuf,
    counter: FrameCounter<HostFlash>,
}

impl Shared {
    /// Whether the counter file's path still names the file this run has open.
    fn is_at_path(&self) -> bool {
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            let (Ok(open), Ok(named)) =
                (self.file.metadata(), std::fs::symlink_metadata(&self.path))
            else {
                return false;
            };
            (open.dev(), open.ino()) == (named.dev(), named.ino())
        }
        #[cfg(not(unix))]
        true
    }

    /// A counter above every one handed out before, by this run or any other: taken under
    /// the counter file's lock, after reading the file again. A file replaced since (a
    /// rename over it: a restored copy) is the counter's from then on: its lock is taken
    /// and the counter goes on there above both.
    fn next(&mut self) -> io::Result<u32> {
        let failed = |e: ToolKeyError| io::Error::other(e.to_string());
        hold(&self.file, &self.path).map_err(failed)?;
        let next = self.next_held();
        unlock(&self.file);
        next
    }

    /// [`Shared::next`] under the lock.
    fn next_held(&mut self) -> io::Result<u32> {
        let path = self.path.display();
        let counter_error = |e: CounterError<_>| {
            io::Error::other(format!("counter file {path}: {}", counter_failure(e)))
        };
        if !self.is_at_path() {
            let failed = |e: ToolKeyError| io::Error::other(e.to_string());
            let file = lock(&self.path).map_err(failed)?;
            // The new file's lock is held from here (the old one's goes with it).
            unlock(&std::mem::replace(&mut self.file, file));
            let flash = counter_flash(&self.file, &self.path).map_err(failed)?;
            self.counter.move_to(flash).map_err(counter_error)?;
        }
        (self.counter.catch_up())
            .and_then(|()| self.counter.next())
            .map_err(counter_error)
    }
}

/// What went wrong with the frame counter in a counter file, in the tool's words.
fn counter_failure(e: CounterError<FlashError>) -> String {
    match e {
        CounterError::Exhausted => "used up (2^31 frames): make a new machine secret (`keys \
                                    new`) and provision the nodes again"
            .to_string(),
        CounterError::Flash(e) => e.to_string(),
        CounterError::Geometry => "not two pages".to_string(),
    }
}

/// The counter file `file` locked by [`lock`] (at `path`, checked and made whole) as the
/// flash of its `FrameCounter`, what is wrong with it in the tool's words. The very file
/// locked, on a handle of its own: opened by its path again, it could be another file
/// renamed over it in between, not locked.
fn counter_flash(file: &File, path: &Path) -> Result<HostFlash, ToolKeyError> {
    let file = file.try_clone().map_err(|source| ToolKeyError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    HostFlash::counter_on(file, path).map_err(|e| match e {
        OpenError::Size {
            found, expected, ..
        } => ToolKeyError::Size {
            path: path.to_path_buf(),
            found,
            expected,
        },
        OpenError::Io(_, source) => ToolKeyError::Io {
            path: path.to_path_buf(),
            source,
        },
        // (`Foreign` is a node flash file's: a counter file is read by its `FrameCounter`.)
        OpenError::InUse(_) | OpenError::Foreign { .. } => ToolKeyError::Unreadable {
            path: path.to_path_buf(),
            why: e.to_string(),
        },
    })
}

/// Opens (creating, mode 0600) and locks the counter file (until [`unlock`]); a file just
/// created, or left shorter by a cut while it was being created (still blank), is made two
/// erased pages.
/// Whoever may write it may set the counter back (a nonce used twice): it must be a
/// regular file (not a link), written by this user alone, in a directory others (not the
/// group) cannot write to (unless sticky: they cannot then replace this user's files).
fn lock(path: &Path) -> Result<File, ToolKeyError> {
    let io_err = |source| ToolKeyError::Io {
        path: path.to_path_buf(),
        source,
    };
    #[cfg(unix)]
    if let Some(dir) = path.parent() {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(dir).map_err(io_err)?.permissions().mode();
        // Others (not the group: umask 002 and a group of one's own are common) may
        // replace files in it, unless it is sticky.
        if mode & 0o002 != 0 && mode & 0o1000 == 0 {
            return Err(ToolKeyError::OpenDirectory {
                path: path.to_path_buf(),
                mode: mode & 0o7777,
            });
        }
    }
    let mut options = OpenOptions::new();
    options.read(true).write(true).create(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.mode(0o600);
        options.custom_flags(rustix::fs::OFlags::NOFOLLOW.bits() as i32);
    }
    let mut file = options.open(path).map_err(io_err)?;
    let meta = file.metadata().map_err(io_err)?;
    if !meta.is_file() {
        return Err(KeyFileError::NotAFile {
            path: path.to_path_buf(),
        }
        .into());
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::{MetadataExt, PermissionsExt};
        let me = rustix::process::geteuid().as_raw();
        let mode = meta.permissions().mode() & 0o7777;
        if meta.uid() != me || mode & 0o022 != 0 {
            return Err(ToolKeyError::NotOwnersAlone {
                path: path.to_path_buf(),
                owner: meta.uid(),
                mode,
            });
        }
    }
    hold(&file, path)?;
    let len = file.metadata().map_err(io_err)?.len();
    if len < COUNTER_FILE_SIZE as u64 {
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes).map_err(io_err)?;
        // Anything but erased bytes is left for the size check to refuse.
        if bytes.iter().all(|b| *b == 0xFF) {
            file.seek(SeekFrom::Start(0)).map_err(io_err)?;
            file.write_all(&[0xFF; COUNTER_FILE_SIZE]).map_err(io_err)?;
            file.sync_all().map_err(io_err)?;
            // Just created (or cut short while it was): its name made durable too, or a
            // power cut could lose the file and the next run start at 0 again.
            node_fw::host::flash::sync_directory_of(path).map_err(io_err)?;
        }
    }
    Ok(file)
}

/// Takes the exclusive lock of the counter file `file` (at `path`), waiting for another run
/// to let go for [`LOCK_WAIT`] at most.
fn hold(file: &File, path: &Path) -> Result<(), ToolKeyError> {
    #[cfg(unix)]
    {
        use rustix::fs::{flock, FlockOperation};
        let until = Instant::now() + LOCK_WAIT;
        loop {
            match flock(file, FlockOperation::NonBlockingLockExclusive) {
                Ok(()) => break,
                Err(e) if e == rustix::io::Errno::WOULDBLOCK => {
                    if Instant::now() >= until {
                        return Err(ToolKeyError::Locked(path.to_path_buf()));
                    }
                    std::thread::sleep(Duration::from_millis(1));
                }
                Err(e) => {
                    return Err(ToolKeyError::Io {
                        path: path.to_path_buf(),
                        source: e.into(),
                    })
                }
            }
        }
    }
    let _ = (file, path);
    Ok(())
}

/// Lets go of the counter file's lock ([`hold`]).
fn unlock(file: &File) {
    #[cfg(unix)]
    let _ = rustix::fs::flock(file, rustix::fs::FlockOperation::Unlock);
    let _ = file;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key_file(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("tool-keys-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("machine.key");
        robot_keys::write_machine_secret(&p, false).unwrap();
        p
    }

    /// A counter used up says so and what to do, in words (the flash's errors were in
    /// their debug form, and a counter that could not be opened said only "unreadable").
    #[test]
    fn a_counter_used_up_says_what_to_do() {
        let key = key_file("used-up");
        let path = counter_path(&std::fs::canonicalize(&key).unwrap());
        let flash = HostFlash::open_counter(&path).unwrap();
        let limit = node_fw::frame_counter::LIMIT;
        let mut c = FrameCounter::open_with_step(flash, limit).unwrap();
        assert_eq!(c.next(), Ok(0), "the whole counter reserved");
        drop(c);
        let mut keys = open(&key).unwrap();
        let e = (keys.counter)().expect_err("used up");
        assert_eq!(
            e.to_string(),
            format!(
                "counter file {}: used up (2^31 frames): make a new machine secret (`keys \
                 new`) and provision the nodes again",
                path.display()
            )
        );
        assert_eq!(
            counter_failure(CounterError::Flash(FlashError::Io(
                io::ErrorKind::StorageFull
            ))),
            "no storage space"
        );
    }

    /// Runs with one key file at once (a panel, and a command given meanwhile) share its
    /// counter: each counter is above every one handed out before it, by either run (a
    /// node takes no counter at or below the last one it took from the tool), and a later
    /// run resumes above both. Before, the second run was refused while the first ran.
    #[test]
    fn runs_with_one_key_file_share_the_counter() {
        let key = key_file("runs");
        let mut first = open(&key).unwrap();
        let next = |keys: &mut ToolKeys| (keys.counter)().unwrap();
        let mut sent: Vec<u32> = (0..3).map(|_| next(&mut first)).collect();
        let mut second = open(&key).unwrap();
        sent.push(next(&mut second));
        sent.push(next(&mut second));
        sent.push(next(&mut first));
        sent.push(next(&mut second));
        const STEP: u32 = node_fw::frame_counter::STEP;
        // Each catching up skips what the other reserved and did not use, then reserves a
        // counter at a time: two runs that take turns skip no more.
        assert_eq!(sent, [0, 1, 2, STEP, STEP + 1, 2 * STEP, 2 * STEP + 1]);
        drop((first, second));
        let mut third = open(&key).unwrap();
        assert_eq!(next(&mut third), 2 * STEP + 2);
        assert_eq!(
            std::fs::metadata(counter_path(&key)).unwrap().len(),
            COUNTER_FILE_SIZE as u64
        );
    }

    /// The counter file set back under a running run, to a copy taken earlier: written
    /// over in place, or renamed over it (a restored backup, a synced copy). Either way
    /// the run's next frame writes its reservation into the file that is there now, and a
    /// later run starts above everything the first handed out. Renamed over it, the run
    /// went on with the file it had open, and the later run started inside what it had
    /// handed out (counters, so nonces, used twice).
    #[test]
    fn a_counter_file_set_back_under_a_run_is_caught_up() {
        for replaced in [false, true] {
            let key = key_file(if replaced { "renamed" } else { "in-place" });
            let path = counter_path(&key);
            let copy = path.with_extension("copy");
            let mut a = open(&key).unwrap();
            assert_eq!((a.counter)().ok(), Some(0));
            std::fs::copy(&path, &copy).unwrap();
            let sent: Vec<u32> = (0..1500).map(|_| (a.counter)().unwrap()).collect();
            assert_eq!(sent.last(), Some(&1500));
            if replaced {
                std::fs::rename(&copy, &path).unwrap();
            } else {
                std::fs::copy(&copy, &path).unwrap();
            }
            assert_eq!((a.counter)().ok(), Some(1501), "replaced: {replaced}");
            let mut later = open(&key).unwrap();
            assert_eq!((later.counter)().ok(), Some(2048), "replaced: {replaced}");
        }
    }

    /// A run that holds the counter file's lock for longer than [`LOCK_WAIT`] (stopped
    /// while it held it): another run's next frame is not sent, and says why.
    #[cfg(unix)]
    #[test]
    fn a_counter_file_locked_for_long_stops_the_frame_and_says_why() {
        let key = key_file("held");
        let mut keys = open(&key).unwrap();
        let other = File::open(counter_path(&key)).unwrap();
        rustix::fs::flock(&other, rustix::fs::FlockOperation::LockExclusive).unwrap();
        let err = (keys.counter)().expect_err("locked");
        assert_eq!(
            err.to_string(),
            format!(
                "counter file {}.counter: locked by another config-tool process with the same \
                 key file for over 2 s (stopped while it held it?)",
                key.display()
            )
        );
        drop(other);
        assert_eq!((keys.counter)().ok(), Some(0));
    }

    #[test]
    fn a_blank_counter_file_cut_short_is_completed_and_anything_else_refused() {
        let key = key_file("short");
        let path = counter_path(&key);
        std::fs::write(&path, [0xFF; 100]).unwrap();
        let mut keys = open(&key).unwrap();
        assert_eq!((keys.counter)().ok(), Some(0));
        drop(keys);
        std::fs::write(&path, b"hello").unwrap();
        let e = open(&key).err().expect("refused");
        assert_eq!(
            e.to_string(),
            format!(
                "counter file {}: 5 bytes, not a frame counter file (8192 bytes); left \
                 unchanged",
                path.display()
            )
        );
        assert_eq!(std::fs::read(&path).unwrap(), b"hello");
    }

    /// A key file reached through a link (or another spelling of its path) has the one
    /// counter file and lock of the file it names: a second counter beside the link
    /// started at 0 again (frame counters, so nonces, used twice under one key).
    #[cfg(unix)]
    #[test]
    fn a_key_file_reached_through_a_link_shares_its_counter_and_lock() {
        let key = key_file("link");
        let link = key.with_file_name("link.key");
        std::os::unix::fs::symlink(&key, &link).unwrap();
        let mut first = open(&key).unwrap();
        assert_eq!((first.counter)().ok(), Some(0));
        let mut second = open(&link).unwrap();
        assert_eq!((second.counter)().ok(), Some(node_fw::frame_counter::STEP));
        assert_eq!(
            (first.counter)().ok(),
            Some(2 * node_fw::frame_counter::STEP)
        );
        assert!(!counter_path(&link).exists());
    }

    /// A counter file another may write (or in a directory others may write to) is
    /// refused: they could set it back. It was opened and used as it was.
    #[cfg(unix)]
    #[test]
    fn a_counter_file_others_may_write_is_refused() {
        use std::os::unix::fs::PermissionsExt;
        let key = key_file("open");
        let path = counter_path(&key);
        drop(open(&key).unwrap());
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o666)).unwrap();
        let e = open(&key).err().expect("refused");
        assert!(
            matches!(e, ToolKeyError::NotOwnersAlone { mode: 0o666, .. }),
            "{e}"
        );
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
        let dir = key.parent().unwrap();
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o777)).unwrap();
        let e = open(&key).err().expect("refused");
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o700)).unwrap();
        assert!(
            matches!(e, ToolKeyError::OpenDirectory { mode: 0o777, .. }),
            "{e}"
        );
        assert!(open(&key).is_ok());
    }
}
