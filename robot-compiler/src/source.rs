//! A RON file's text, byte offsets <-> line:col, and spans of values by path.

use std::ops::Range;
use std::path::PathBuf;

use crate::locate::{self, Value};

/// The largest file the tool reads as a robot, an FB type, an application or facts: far
/// more than any machine's description; a larger one (or a device such as `/dev/zero`) is
/// refused without being read to its end.
pub const MAX_FILE: u64 = 8 << 20;

/// The bytes of file `path`, or an error if it has more than `limit` (read no further).
pub fn read_at_most(path: &std::path::Path, limit: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let mut bytes = Vec::new();
    std::fs::File::open(path)?
        .take(limit.saturating_add(1))
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("larger than {limit} bytes"),
        ));
    }
    Ok(bytes)
}

/// Why a robot file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The file could not be read.
    #[error("cannot read {}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The bytes are not UTF-8: the first bad byte, its place and offset.
    #[error(
        "{path}:{line}:{col}: error: the file is not UTF-8 text: byte {byte:#04x} at offset {offset}"
    )]
    NotUtf8 {
        /// The file's name as given.
        path: String,
        line: usize,
        col: usize,
        byte: u8,
        offset: usize,
    },
}

/// Bytes between two character-count checkpoints of [`Source`].
const CHECKPOINT: usize = 256;

/// One source file: its name (as given on the command line), its text, and the span tree
/// of its values. Line starts and character-count checkpoints are indexed once, so that
/// [`Source::line_col`] costs O(log lines) whatever the file: diagnostics stay linear.
#[derive(Debug, Clone)]
pub struct Source {
    pub name: String,
    pub text: String,
    tree: Option<Value>,
    /// Byte offset of the start of every line.
    lines: Vec<usize>,
    /// Characters before byte `k * CHECKPOINT`.
    chars: Vec<usize>,
}

/// Whether a byte starts a character (is not a UTF-8 continuation byte).
fn starts_char(b: u8) -> bool {
    b & 0xC0 != 0x80
}

impl Source {
    pub fn new(name: impl Into<String>, text: impl Into<String>) -> Source {
        let text = text.into();
        let tree = locate::parse(&text);
        let bytes = text.as_bytes();
        let lines = std::iter::once(0)
            .chain(newline_ends(bytes))
            .collect::<Vec<_>>();
        let mut chars = Vec::with_capacity(bytes.len() / CHECKPOINT + 1);
        let mut count = 0;
        for block in bytes.chunks(CHECKPOINT) {
            chars.push(count);
            count += block.iter().filter(|b| starts_char(**b)).count();
        }
        chars.push(count);
        Source {
            name: name.into(),
            text,
            tree,
            lines,
            chars,
        }
    }

    /// Reads a robot file: a clear error if it cannot be read, is larger than
    /// [`MAX_FILE`] or is not UTF-8 (at its first bad byte).
    pub fn read(path: &std::path::Path) -> Result<Source, LoadError> {
        let bytes = read_at_most(path, MAX_FILE).map_err(|source| LoadError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Source::from_bytes(path.display().to_string(), bytes)
    }

    /// A file's bytes as a source, or [`LoadError::NotUtf8`] at the first byte that is not
    /// UTF-8.
    pub fn from_bytes(name: impl Into<String>, bytes: Vec<u8>) -> Result<Source, LoadError> {
        let name = name.into();
        let text = utf8(&name, bytes)?;
        Ok(Source::new(name, text))
    }

    /// Characters before byte `offset` (a character boundary).
    fn chars_before(&self, offset: usize) -> usize {
        let k = offset / CHECKPOINT;
        let base = self.chars.get(k).copied().unwrap_or(0);
        let from = k * CHECKPOINT;
        base + self
            .text
            .as_bytes()
            .get(from..offset)
            .map_or(0, |b| b.iter().filter(|b| starts_char(**b)).count())
    }

    /// The 0-based line of a byte offset and the byte offset where that line starts.
    pub fn line_of(&self, offset: usize) -> (usize, usize) {
        let line = self
            .lines
            .partition_point(|&s| s <= offset)
            .saturating_sub(1);
        (line, self.lines.get(line).copied().unwrap_or(0))
    }

    /// The byte offset where 0-based line `line` starts (the end of the text past the
    /// last line).
    pub fn line_start(&self, line: usize) -> usize {
        self.lines.get(line).copied().unwrap_or(self.text.len())
    }

    /// The byte offset where 0-based line `line` ends (before its newline), or the end of
    /// the text.
    pub fn line_end(&self, line: usize) -> usize {
        self.lines
            .get(line + 1)
            .map_or(self.text.len(), |next| next - 1)
    }

    /// The number of lines.
    pub fn line_count(&self) -> usize {
        self.lines.len()
    }

    /// `offset` moved back to a character boundary inside the text.
    pub fn floor(&self, offset: usize) -> usize {
        let mut offset = offset.min(self.text.len());
        while !self.text.is_char_boundary(offset) {
            offset -= 1;
        }
        offset
    }

    /// A span inside the text, on character boundaries.
    pub fn clamp(&self, span: Range<usize>) -> Range<usize> {
        let start = self.floor(span.start);
        start..self.floor(span.end).max(start)
    }

    /// 1-based line and column (in characters) of a byte offset.
    pub fn line_col(&self, offset: usize) -> (usize, usize) {
        let offset = self.floor(offset);
        let (line, start) = self.line_of(offset);
        let col = self.chars_before(offset) - self.chars_before(start);
        (line + 1, col + 1)
    }

    /// Byte offset of a 1-based line and column (in characters).
    pub fn offset(&self, line: usize, col: usize) -> usize {
        let Some(&start) = self.lines.get(line.saturating_sub(1)) else {
            return self.text.len();
        };
        let line_text = self
            .text
            .get(start..self.line_end(line.saturating_sub(1)))
            .unwrap_or("");
        start
            + line_text
                .char_indices()
                .nth(col.saturating_sub(1))
                .map_or(line_text.len(), |(i, _)| i)
    }

    /// The span of the value at `path` (e.g. `roles[2].actuators[0].name`), or of the
    /// deepest existing value on the way there, or of the whole file.
    pub fn span(&self, path: &str) -> Range<usize> {
        match &self.tree {
            Some(tree) => tree.find(path),
            None => 0..self.text.len(),
        }
    }

    /// Whether the file writes a value at `path` (a field left to its default is not).
    pub fn has(&self, path: &str) -> bool {
        self.tree.as_ref().is_some_and(|tree| tree.has(path))
    }

    /// The span of the key of a field or map entry at `path` (the value's span if there is
    /// no key).
    pub fn key_span(&self, path: &str) -> Range<usize> {
        match &self.tree {
            Some(tree) => tree.find_key(path),
            None => 0..self.text.len(),
        }
    }

    /// The span of key `key` (as written, unquoted) of the map at `path`, or of the map if it
    /// has no such key: for keys that are not names (`"vc.GR1"`), which a path cannot name.
    pub fn map_key_span(&self, path: &str, key: &str) -> Range<usize> {
        match &self.tree {
            Some(tree) => tree.find_map_key(path, key),
            None => 0..self.text.len(),
        }
    }

    /// Every key a map of the file has twice: (key, the first's span, the second's).
    pub fn duplicate_keys(&self) -> Vec<(String, Range<usize>, Range<usize>)> {
        let mut out = Vec::new();
        if let Some(tree) = &self.tree {
            tree.duplicate_keys(&mut out);
        }
        out
    }

    /// The text of a span.
    pub fn slice(&self, span: Range<usize>) -> &str {
        self.text.get(span).unwrap_or("")
    }
}

/// `bytes` as text (without a byte order mark), or [`LoadError::NotUtf8`] at the first
/// byte that is not UTF-8 (`name` names the file in the error).
pub fn utf8(name: &str, bytes: Vec<u8>) -> Result<String, LoadError> {
    match String::from_utf8(bytes) {
        // A byte order mark is no part of the text (editors show none; RON takes none).
        Ok(text) => match text.strip_prefix('\u{FEFF}') {
            Some(rest) => Ok(rest.to_string()),
            None => Ok(text),
        },
        Err(e) => {
            let at = e.utf8_error().valid_up_to();
            let bytes = e.as_bytes();
            let valid = std::str::from_utf8(bytes.get(..at).unwrap_or(&[])).unwrap_or("");
            let line = valid.matches('\n').count() + 1;
            let start = valid.rfind('\n').map_or(0, |i| i + 1);
            let col = valid[start..].chars().count() + 1;
            Err(LoadError::NotUtf8 {
                byte: bytes.get(at).copied().unwrap_or(0),
                path: name.to_string(),
                line,
                col,
                offset: at,
            })
        }
    }
}

/// Offsets just after every newline.
fn newline_ends(bytes: &[u8]) -> impl Iterator<Item = usize> + '_ {
    bytes
        .iter()
        .enumerate()
        .filter(|(_, b)| **b == b'\n')
        .map(|(i, _)| i + 1)
}

#[cfg(test)]
mod tests {
    use super::Source;

    #[test]
    fn line_col_and_offset_agree_on_multibyte_text() {
        let text = format!("ab\n{}é x\n\nlast", "ü".repeat(300));
        let src = Source::new("t", text.clone());
        for (offset, _) in text.char_indices() {
            let (line, col) = src.line_col(offset);
            let before = &text[..offset];
            let want_line = before.matches('\n').count() + 1;
            let start = before.rfind('\n').map_or(0, |i| i + 1);
            assert_eq!(
                (line, col),
                (want_line, before[start..].chars().count() + 1)
            );
            assert_eq!(src.offset(line, col), offset);
        }
        assert_eq!(src.line_col(text.len()), (4, 5));
        assert_eq!(src.offset(9, 1), text.len());
        assert_eq!(src.line_count(), 4);
    }

    #[test]
    fn bytes_that_are_not_utf8_are_an_error_at_their_place() {
        let bytes = b"Robot(\n  name: \"\xc3\xa9\xff\",\n)".to_vec();
        assert_eq!(
            Source::from_bytes("r.ron", bytes)
                .map(|s| s.text)
                .unwrap_err()
                .to_string(),
            "r.ron:2:11: error: the file is not UTF-8 text: byte 0xff at offset 18"
        );
        let ok = Source::from_bytes("r.ron", b"ok".to_vec()).expect("utf-8");
        assert_eq!(ok.text, "ok");
    }

    /// A byte order mark is dropped: a robot saved with one reads as without it.
    #[test]
    fn a_byte_order_mark_is_no_part_of_the_text() {
        let bom = Source::from_bytes("r.ron", b"\xef\xbb\xbfRobot(\n)".to_vec()).expect("utf-8");
        assert_eq!(bom.text, "Robot(\n)");
        assert_eq!(bom.line_col(bom.text.find(')').expect(")")), (2, 1));
    }

    /// A file that cannot be read is an error naming it, with the I/O error as its source.
    #[test]
    fn a_file_that_cannot_be_read_is_an_error_naming_it() {
        let path = std::env::temp_dir().join("robot-compiler-no-such-dir/robot.ron");
        let e = Source::read(&path).expect_err("no such file");
        let want = format!("cannot read {}: ", path.display());
        assert!(e.to_string().starts_with(&want), "{e}");
        match e {
            super::LoadError::Read { path: p, source } => {
                assert_eq!(p, path);
                assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
            }
            other => panic!("not a read error: {other}"),
        }
    }
}
