//! A RON file's text, byte offsets <-> line:col, and spans of values by path.

use std::ops::Range;

use crate::locate::{self, Value};

/// One source file: its name (as given on the command line), its text, and the span tree
/// of its values.
#[derive(Debug, Clone)]
pub struct Source {
    pub name: String,
    pub text: String,
    tree: Option<Value>,
}

impl Source {
    pub fn new(name: impl Into<String>, text: impl Into<String>) -> Source {
        let text = text.into();
        let tree = locate::parse(&text);
        Source {
            name: name.into(),
            text,
            tree,
        }
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
        let before = &self.text[..offset];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let col = before[line_start..].chars().count() + 1;
        (line, col)
    }

    /// Byte offset of a 1-based line and column (in characters).
    pub fn offset(&self, line: usize, col: usize) -> usize {
        let mut start = 0;
        for _ in 1..line {
            match self.text[start..].find('\n') {
                Some(i) => start += i + 1,
                None => return self.text.len(),
            }
        }
        let rest = &self.text[start..];
        let line_text = &rest[..rest.find('\n').unwrap_or(rest.len())];
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

    /// The span of the key of a field or map entry at `path` (the value's span if there is
    /// no key).
    pub fn key_span(&self, path: &str) -> Range<usize> {
        match &self.tree {
            Some(tree) => tree.find_key(path),
            None => 0..self.text.len(),
        }
    }

    /// The text of a span.
    pub fn slice(&self, span: Range<usize>) -> &str {
        self.text.get(span).unwrap_or("")
    }
}
