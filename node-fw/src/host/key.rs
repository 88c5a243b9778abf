//! The host board's management key: a key file (`--key FILE`, written by `config-tool
//! keys provision --board host --out FILE`), refused if group or others may read or
//! write it, or if it is for another address. Format: [`crate::provision`].

use std::fmt;
use std::io::Read;
use std::path::{Path, PathBuf};

use crate::provision::{parse_node_key, ManagementKey};

/// Longer files are not key files.
const MAX_LEN: u64 = 4096;

/// Why the key file was refused.
#[derive(Debug)]
pub enum KeyError {
    Io(PathBuf, std::io::Error),
    /// Group or others may read or write it (the mode).
    Permissions(PathBuf, u32),
    NotAFile(PathBuf),
    /// FILE:LINE:COL and what is wrong there.
    Format {
        path: PathBuf,
        line: usize,
        col: usize,
        what: String,
    },
    /// The file is for another node (its address, the node's).
    OtherNode(PathBuf, u16, u16),
    /// Another user owns it (its uid, this process's): they may know the key.
    NotOwned(PathBuf, u32, u32),
}

impl fmt::Display for KeyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            KeyError::Io(p, e) => write!(f, "{}: {e}", p.display()),
            KeyError::Permissions(p, mode) => write!(
                f,
                "{0}: mode {mode:04o} lets group or others read or write it; a key file must \
                 be readable by its owner only (chmod 600 {0})",
                p.display()
            ),
            KeyError::NotAFile(p) => write!(f, "{}: not a regular file", p.display()),
            KeyError::Format {
                path,
                line,
                col,
                what,
            } => write!(f, "{}:{line}:{col}: {what}", path.display()),
            KeyError::OtherNode(p, theirs, ours) => write!(
                f,
                "{}: the key of node {theirs:#06x}, not of this node ({ours:#06x})",
                p.display()
            ),
            KeyError::NotOwned(p, owner, me) => write!(
                f,
                "{}: owned by user {owner}, not by this user ({me}): whoever owns it may know \
                 the key",
                p.display()
            ),
        }
    }
}

impl std::error::Error for KeyError {}

/// Reads node `addr`'s management key from `path`.
pub fn load(path: &Path, addr: u16) -> Result<ManagementKey, KeyError> {
    let io = |e| KeyError::Io(path.to_path_buf(), e);
    // Not opened unless it is a regular file (opening a FIFO would wait for a writer).
    if !std::fs::metadata(path).map_err(io)?.is_file() {
        return Err(KeyError::NotAFile(path.to_path_buf()));
    }
    let f = std::fs::File::open(path).map_err(io)?;
    let meta = f.metadata().map_err(io)?;
    if !meta.is_file() {
        return Err(KeyError::NotAFile(path.to_path_buf()));
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::{MetadataExt, PermissionsExt};
        let mode = meta.permissions().mode() & 0o7777;
        if mode & 0o066 != 0 {
            return Err(KeyError::Permissions(path.to_path_buf(), mode));
        }
        // This process's user: the owner of its own `/proc/self` (Linux; elsewhere the
        // owner is not checked).
        if let Ok(me) = std::fs::metadata("/proc/self").map(|m| m.uid()) {
            if meta.uid() != me {
                return Err(KeyError::NotOwned(path.to_path_buf(), meta.uid(), me));
            }
        }
    }
    let mut bytes = Vec::new();
    f.take(MAX_LEN).read_to_end(&mut bytes).map_err(io)?;
    let text = String::from_utf8_lossy(&bytes);
    let result = match parse_node_key(&text) {
        Ok((theirs, _)) if theirs != addr => {
            Err(KeyError::OtherNode(path.to_path_buf(), theirs, addr))
        }
        Ok((_, key)) => Ok(key),
        Err(e) => {
            let before = text.get(..e.at).unwrap_or(&text);
            Err(KeyError::Format {
                path: path.to_path_buf(),
                line: before.matches('\n').count() + 1,
                col: before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1,
                what: e.what.to_string(),
            })
        }
    };
    bytes.fill(0);
    result
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::provision::NodeKeyLine;

    fn file(name: &str, text: &str, mode: u32) -> PathBuf {
        let p = std::env::temp_dir().join(format!("node-fw-key-{}-{name}", std::process::id()));
        std::fs::write(&p, text).unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&p, std::fs::Permissions::from_mode(mode)).unwrap();
        }
        #[cfg(not(unix))]
        let _ = mode;
        p
    }

    fn line(addr: u16) -> String {
        let key = ManagementKey::from_bytes([0x5A; 16]);
        NodeKeyLine { addr, key: &key }.to_string()
    }

    #[test]
    fn a_good_key_file_loads() {
        let p = file("good", &line(0x0011), 0o600);
        assert_eq!(load(&p, 0x0011).unwrap().expose(), &[0x5A; 16]);
    }

    #[test]
    fn another_nodes_key_is_refused() {
        let p = file("other", &line(0x0012), 0o600);
        assert_eq!(
            load(&p, 0x0011).unwrap_err().to_string(),
            format!(
                "{}: the key of node 0x0012, not of this node (0x0011)",
                p.display()
            )
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_key_file_others_may_read_is_refused() {
        let p = file("open", &line(0x0011), 0o644);
        assert_eq!(
            load(&p, 0x0011).unwrap_err().to_string(),
            format!(
                "{0}: mode 0644 lets group or others read or write it; a key file must be \
                 readable by its owner only (chmod 600 {0})",
                p.display()
            )
        );
    }

    /// A key file another user owns is refused, as the machine secret is (whoever owns it
    /// may know the key). It was taken. (Giving a file away takes root: run as root, as
    /// CI does.)
    #[cfg(unix)]
    #[test]
    fn a_key_file_another_user_owns_is_refused() {
        use std::os::unix::fs::MetadataExt;
        let p = file("theirs", &line(0x0011), 0o600);
        if std::fs::metadata("/proc/self").map(|m| m.uid()).ok() != Some(0) {
            return;
        }
        std::os::unix::fs::chown(&p, Some(65534), None).unwrap();
        assert_eq!(
            load(&p, 0x0011).unwrap_err().to_string(),
            format!(
                "{}: owned by user 65534, not by this user (0): whoever owns it may know the key",
                p.display()
            )
        );
    }

    #[test]
    fn a_bad_key_file_names_the_place() {
        let p = file("bad", "robot-node-key v1 0x0011 zz\n", 0o600);
        assert_eq!(
            load(&p, 0x0011).unwrap_err().to_string(),
            format!(
                "{}:1:26: expected a space and 32 hex digits (the 16 key bytes)",
                p.display()
            )
        );
        let missing = std::env::temp_dir().join("node-fw-key-does-not-exist");
        assert!(load(&missing, 0x0011)
            .unwrap_err()
            .to_string()
            .starts_with(&format!("{}: ", missing.display())));
    }
}
