//! The host board's flash: a file holding the two table slots (NOR semantics: erase sets
//! 0xFF, a write only clears bits, every erase and write is synced before it returns), then
//! one erase page with the boot counter. Without a file, the same flash in RAM.
//!
//! ```text
//! 0              slot 0 (Slots::slot_size() bytes)
//! slot_size      slot 1
//! 2 * slot_size  u32 LE boot counter (0xFFFF_FFFF: never booted), rest of the page 0xFF
//! ```

use std::fs::{File, OpenOptions};
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use embedded_storage::nor_flash::{ErrorType, NorFlashError, NorFlashErrorKind};
use embedded_storage_async::nor_flash::{NorFlash, ReadNorFlash};

use crate::slots::{check_access, Access, Slots};

/// The erase page (as on an nRF52840).
pub const ERASE_SIZE: usize = 4096;
/// The bytes of the two slots: what the runtime's `Slots` see.
pub const SLOTS_BYTES: usize = 2 * Slots::<HostFlash>::slot_size();
/// Where the boot counter is.
pub const COUNTER_AT: usize = SLOTS_BYTES;
/// The size of a flash file.
pub const FILE_SIZE: usize = SLOTS_BYTES + ERASE_SIZE;
/// The size of a frame counter file (`node_fw::frame_counter`: two erase pages), kept
/// beside the flash file ([`counter_path`]).
pub const COUNTER_FILE_SIZE: usize = 2 * ERASE_SIZE;

/// The frame counter file of the flash file at `flash`: `FLASH.counter`.
pub fn counter_path(flash: &Path) -> PathBuf {
    let mut p = flash.as_os_str().to_owned();
    p.push(".counter");
    PathBuf::from(p)
}

/// A flash file's boot counter (a handle on the file of its own: every access seeks first,
/// as the flash's do).
#[derive(Debug)]
pub struct BootCounter(File);

impl BootCounter {
    /// Counts one more boot; returns the new count (1 on the first boot of a file).
    pub fn count(&mut self) -> io::Result<u32> {
        let file = &mut self.0;
        let mut word = [0u8; 4];
        file.seek(SeekFrom::Start(COUNTER_AT as u64))?;
        file.read_exact(&mut word)?;
        let boots = match u32::from_le_bytes(word) {
            u32::MAX => 1,
            n => n.wrapping_add(1).max(1),
        };
        // A 4-byte overwrite in a file: a killed process leaves the old or the new count.
        file.seek(SeekFrom::Start(COUNTER_AT as u64))?;
        file.write_all(&boots.to_le_bytes())?;
        file.sync_data()?;
        Ok(boots)
    }
}

/// Why the host flash failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlashError {
    /// Outside the slots.
    OutOfBounds,
    /// Not aligned to the write or erase size.
    NotAligned,
    /// The file could not be read or written.
    Io(io::ErrorKind),
}

impl From<Access> for FlashError {
    fn from(a: Access) -> Self {
        match a {
            Access::OutOfBounds => FlashError::OutOfBounds,
            Access::NotAligned => FlashError::NotAligned,
        }
    }
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::Io(_) => NorFlashErrorKind::Other,
        }
    }
}

impl std::fmt::Display for FlashError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FlashError::OutOfBounds => f.write_str("an access outside the file"),
            FlashError::NotAligned => f.write_str("an access not aligned to its pages"),
            FlashError::Io(kind) => write!(f, "{kind}"),
        }
    }
}

impl From<io::Error> for FlashError {
    fn from(e: io::Error) -> Self {
        FlashError::Io(e.kind())
    }
}

enum Store {
    Ram(Vec<u8>),
    File(File),
}

/// The two table slots of a host node, in a file or in RAM.
pub struct HostFlash {
    store: Store,
    /// The bytes the `NorFlash` sees: the slots, or the frame counter's two pages.
    capacity: usize,
}

/// Creates the erased file `path` of `size` bytes whole or not at all: written and synced
/// under a name of its own beside it (`.NAME.creating.PID`), then linked to `path` (which
/// fails if `path` appeared meanwhile: another process created it first, and that one is
/// used). A creation that stops part-way (a kill, a full disk) leaves only the temporary
/// file, never a short flash file. On a file system without hard links (vfat) the file is
/// written in place, as before: a creation cut short there leaves a short file, which the
/// next start refuses by its size.
fn create_erased(path: &Path, size: usize) -> io::Result<()> {
    let erased = |file: &mut File| {
        file.write_all(&vec![0xFF; size])?;
        file.sync_all()
    };
    let name = path
        .file_name()
        .map_or_else(Default::default, |n| n.to_string_lossy());
    let temporary = path.with_file_name(format!(".{name}.creating.{}", std::process::id()));
    let written = (|| {
        let mut file = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&temporary)?;
        erased(&mut file)?;
        std::fs::hard_link(&temporary, path)
    })();
    let _ = std::fs::remove_file(&temporary);
    match written {
        Ok(()) => sync_directory_of(path),
        // Another process created it first: that one is used.
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => Ok(()),
        Err(e)
            if matches!(
                e.kind(),
                io::ErrorKind::Unsupported | io::ErrorKind::PermissionDenied
            ) =>
        {
            let mut file = OpenOptions::new().write(true).create_new(true).open(path)?;
            erased(&mut file)?;
            sync_directory_of(path)
        }
        Err(e) => Err(e),
    }
}

/// Makes the name of a file just created at `path` durable: its directory synced (a
/// power cut soon after could otherwise lose the file's entry though its bytes were
/// synced; a frame counter file lost so starts again at 0: nonces used twice).
pub fn sync_directory_of(path: &Path) -> io::Result<()> {
    #[cfg(unix)]
    {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        File::open(dir)?.sync_all()?;
    }
    #[cfg(not(unix))]
    let _ = path;
    Ok(())
}

/// Why a flash file cannot be used (nothing in it was changed).
#[derive(Debug)]
pub enum OpenError {
    Io(PathBuf, io::Error),
    /// Another process has the file open (a second node on one flash file): locked.
    InUse(PathBuf),
    /// The file exists but is not a node flash file.
    Size {
        path: PathBuf,
        found: u64,
        expected: u64,
    },
    /// The file has a flash file's size, but past the boot count its boot counter's page
    /// holds other data than erased bytes: not a node's flash file.
    Foreign {
        path: PathBuf,
    },
}

impl std::fmt::Display for OpenError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OpenError::Io(path, e) => write!(f, "flash file {}: {e}", path.display()),
            OpenError::InUse(path) => write!(
                f,
                "flash file {} is in use by another node process (two nodes cannot share one \
                 flash)",
                path.display()
            ),
            OpenError::Size {
                path,
                found,
                expected,
            } => write!(
                f,
                "flash file {} is {found} bytes, not a node flash file ({expected} bytes); \
                 left unchanged",
                path.display()
            ),
            OpenError::Foreign { path } => write!(
                f,
                "flash file {}: not a node flash file (its boot counter's page holds other \
                 data); left unchanged",
                path.display()
            ),
        }
    }
}

impl HostFlash {
    /// An erased flash in RAM (lost when the process ends).
    pub fn ram() -> Self {
        HostFlash {
            store: Store::Ram(vec![0xFF; SLOTS_BYTES]),
            capacity: SLOTS_BYTES,
        }
    }

    /// Opens the flash file at `path`, creating it erased if it does not exist.
    /// A file of the size whose boot counter's page is not erased past the count is
    /// refused before anything is written to it ([`OpenError::Foreign`]): every flash
    /// file a node made has it so.
    pub fn open(path: &Path) -> Result<Self, OpenError> {
        let flash = Self::open_sized(path, FILE_SIZE, SLOTS_BYTES, true)?;
        let Store::File(file) = &flash.store else {
            return Ok(flash);
        };
        let mut rest = [0u8; ERASE_SIZE - 4];
        let mut file = file;
        (file.seek(SeekFrom::Start(COUNTER_AT as u64 + 4)))
            .and_then(|_| file.read_exact(&mut rest))
            .map_err(|e| OpenError::Io(path.to_path_buf(), e))?;
        if rest.iter().any(|&b| b != 0xFF) {
            return Err(OpenError::Foreign {
                path: path.to_path_buf(),
            });
        }
        Ok(flash)
    }

    /// Opens the frame counter file at `path` (two erase pages), creating it erased if it
    /// does not exist.
    /// Not locked here: the node's counter file goes with its flash file, which is
    /// (one process per flash file, so per counter file); the tool locks its own, waiting
    /// for another run.
    pub fn open_counter(path: &Path) -> Result<Self, OpenError> {
        Self::open_sized(path, COUNTER_FILE_SIZE, COUNTER_FILE_SIZE, false)
    }

    /// Opens the file at `path` (creating it erased if missing) and, with `lock`, locks it:
    /// a process has it alone for as long as it runs (an exclusive advisory lock, which the
    /// system drops when the process ends, however it ends).
    fn open_sized(
        path: &Path,
        file_size: usize,
        capacity: usize,
        lock: bool,
    ) -> Result<Self, OpenError> {
        let io_err = |e| OpenError::Io(path.to_path_buf(), e);
        let open = || OpenOptions::new().read(true).write(true).open(path);
        let file = match open() {
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                create_erased(path, file_size).map_err(io_err)?;
                open().map_err(io_err)?
            }
            opened => opened.map_err(io_err)?,
        };
        match file.try_lock() {
            _ if !lock => {}
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                return Err(OpenError::InUse(path.to_path_buf()))
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(io_err(e)),
        }
        Self::sized(file, path, file_size, capacity)
    }

    /// The frame counter file open as `file` (at `path`: for what an error says), as
    /// [`HostFlash::open_counter`] opens it: a caller that locked the file reads and writes
    /// the very file it locked, whatever its path names meanwhile.
    pub fn counter_on(file: File, path: &Path) -> Result<Self, OpenError> {
        Self::sized(file, path, COUNTER_FILE_SIZE, COUNTER_FILE_SIZE)
    }

    /// `file` as a flash of `capacity` bytes if it is `file_size` bytes long.
    fn sized(
        file: File,
        path: &Path,
        file_size: usize,
        capacity: usize,
    ) -> Result<Self, OpenError> {
        let found = (file.metadata())
            .map_err(|e| OpenError::Io(path.to_path_buf(), e))?
            .len();
        if found != file_size as u64 {
            return Err(OpenError::Size {
                path: path.to_path_buf(),
                found,
                expected: file_size as u64,
            });
        }
        Ok(HostFlash {
            store: Store::File(file),
            capacity,
        })
    }

    /// Counts this boot: returns the new boot count (1 on the first boot of a file), or
    /// `None` for RAM (which has no previous boot).
    pub fn count_boot(&mut self) -> io::Result<Option<u32>> {
        self.boot_counter()?.map(|mut c| c.count()).transpose()
    }

    /// The boot counter on a handle of its own (the runtime counts a boot to reserve link
    /// epochs while the slots own the flash: `runtime::Boot::Counted`); `None` for RAM.
    pub fn boot_counter(&self) -> io::Result<Option<BootCounter>> {
        match &self.store {
            Store::File(file) => Ok(Some(BootCounter(file.try_clone()?))),
            Store::Ram(_) => Ok(None),
        }
    }

    fn read_at(&mut self, start: usize, bytes: &mut [u8]) -> Result<(), FlashError> {
        match &mut self.store {
            Store::Ram(mem) => {
                let src = mem
                    .get(start..start + bytes.len())
                    .ok_or(FlashError::OutOfBounds)?;
                bytes.copy_from_slice(src);
            }
            Store::File(file) => {
                file.seek(SeekFrom::Start(start as u64))?;
                file.read_exact(bytes)?;
            }
        }
        Ok(())
    }

    fn write_at(&mut self, start: usize, bytes: &[u8]) -> Result<(), FlashError> {
        match &mut self.store {
            Store::Ram(mem) => {
                let dst = mem
                    .get_mut(start..start + bytes.len())
                    .ok_or(FlashError::OutOfBounds)?;
                dst.copy_from_slice(bytes);
            }
            Store::File(file) => {
                file.seek(SeekFrom::Start(start as u64))?;
                file.write_all(bytes)?;
                file.sync_data()?;
            }
        }
        Ok(())
    }
}

impl ErrorType for HostFlash {
    type Error = FlashError;
}

impl ReadNorFlash for HostFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let start = check_access(offset, bytes.len(), Self::READ_SIZE, self.capacity)?;
        self.read_at(start, bytes)
    }

    fn capacity(&self) -> usize {
        self.capacity
    }
}

impl NorFlash for HostFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        let len = to.checked_sub(from).ok_or(FlashError::OutOfBounds)? as usize;
        let start = check_access(from, len, Self::ERASE_SIZE, self.capacity)?;
        self.write_at(start, &vec![0xFF; len])
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let start = check_access(offset, bytes.len(), Self::WRITE_SIZE, self.capacity)?;
        // NOR: programming only clears bits.
        let mut cells = vec![0u8; bytes.len()];
        self.read_at(start, &mut cells)?;
        for (cell, b) in cells.iter_mut().zip(bytes) {
            *cell &= *b;
        }
        self.write_at(start, &cells)
    }
}
