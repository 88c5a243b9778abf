//! The pieces of IEC 61499-2 XML an application (`.sys`) and a composite FB type share:
//! an FB network (`SubAppNetwork` / `FBNetwork`: `FB`s with `Parameter`s, then
//! `EventConnections` and `DataConnections` of `Connection Source="FB.PORT"
//! Destination="FB.PORT"`), read with every element's file:line:col for the errors.

use roxmltree::{Document, Node, ParsingOptions};

/// A line and column (1-based) of an XML file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pos {
    pub line: u32,
    pub col: u32,
}

/// An error at a place of one of the application's files.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SysError {
    /// The file as the robot (or the application) names it.
    pub file: String,
    pub at: Pos,
    pub message: String,
}

impl std::fmt::Display for SysError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}:{}:{}: {}",
            self.file, self.at.line, self.at.col, self.message
        )
    }
}

/// A place of a named file, to make errors from later.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct At {
    pub file: String,
    pub pos: Pos,
}

impl At {
    /// `FILE:LINE:COL`.
    pub fn place(&self) -> String {
        format!("{}:{}:{}", self.file, self.pos.line, self.pos.col)
    }

    pub fn error(&self, message: impl Into<String>) -> SysError {
        SysError {
            file: self.file.clone(),
            at: self.pos,
            message: message.into(),
        }
    }
}

/// An `FB` instance: its name, its type (the last part of a `::` path), its parameters.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fb {
    pub name: String,
    pub ty: String,
    pub params: Vec<Param>,
    pub at: At,
}

/// A `Parameter`: the value as written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Param {
    pub name: String,
    pub value: String,
    pub at: At,
}

/// A `Connection`, as written (`FB.PORT`, or `PORT` of the enclosing type's interface).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Conn {
    pub source: String,
    pub dest: String,
    pub at: At,
}

/// An FB network.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Network {
    pub fbs: Vec<Fb>,
    pub events: Vec<Conn>,
    pub data: Vec<Conn>,
}

/// Where the lines of a text start, to turn a byte offset into a line and column (as
/// roxmltree's `text_pos_at` counts them: 1-based, columns in characters) without
/// scanning the text from its start, or a long line from its start, each time: a file's
/// every element has its place (a file written on one line took time quadratic in its
/// elements: 18.7 s for 32,000).
pub struct Lines {
    starts: Vec<usize>,
    /// The characters of the text before every [`CHUNK`]th byte.
    chars: Vec<usize>,
}

/// How many bytes apart [`Lines`] keeps its count of characters.
const CHUNK: usize = 256;

impl Lines {
    pub fn of(text: &str) -> Lines {
        let starts = std::iter::once(0).chain(
            (text.bytes().enumerate())
                .filter(|(_, b)| *b == b'\n')
                .map(|(i, _)| i + 1),
        );
        let chars = std::iter::once(0)
            .chain(text.as_bytes().chunks(CHUNK).scan(0, |n, chunk| {
                *n += starts_of_chars(chunk);
                Some(*n)
            }))
            .collect();
        Lines {
            starts: starts.collect(),
            chars,
        }
    }

    /// The characters of `text` before byte `offset` (at most [`CHUNK`] bytes counted).
    fn chars_before(&self, text: &str, offset: usize) -> usize {
        let chunk = offset / CHUNK;
        let counted = self.chars.get(chunk).copied().unwrap_or(0);
        let rest = text.as_bytes().get(chunk * CHUNK..offset).unwrap_or(&[]);
        counted + starts_of_chars(rest)
    }

    /// The line and column of byte `offset` of `text` (the text the lines are of).
    pub fn pos(&self, text: &str, offset: usize) -> Pos {
        let offset = offset.min(text.len());
        let row = self.starts.partition_point(|s| *s <= offset).max(1);
        let start = self.starts.get(row - 1).copied().unwrap_or(0);
        let col = self.chars_before(text, offset) - self.chars_before(text, start) + 1;
        Pos {
            line: u32::try_from(row).unwrap_or(u32::MAX),
            col: u32::try_from(col).unwrap_or(u32::MAX),
        }
    }
}

/// The characters that start in `bytes` of UTF-8 (every byte but a continuation byte).
fn starts_of_chars(bytes: &[u8]) -> usize {
    bytes.iter().filter(|b| (**b & 0xC0) != 0x80).count()
}

/// One XML file being read.
#[derive(Clone, Copy)]
pub struct Xml<'a, 'i> {
    pub doc: &'a Document<'i>,
    pub file: &'a str,
    /// The lines of the document's text.
    pub lines: &'a Lines,
}

/// Parses `text` (DTD allowed, as the tools write one), or an error at the first place
/// that is not well formed.
pub fn parse<'i>(text: &'i str, file: &str) -> Result<Document<'i>, SysError> {
    document(text).map_err(|(at, message)| SysError {
        file: file.to_string(),
        at,
        message,
    })
}

/// `text` parsed as IEC 61499 XML (a DTD named, as the tools write one), or the place and
/// why not: what the parser is not given (the module's `refused_xml`: too many attributes,
/// a DTD's internal subset), or the first place that is not well formed (at the end of the
/// text for what only the end shows).
pub fn document(text: &str) -> Result<Document<'_>, (Pos, String)> {
    if let Some((at, message)) = super::refused_xml(text) {
        return Err((at, message));
    }
    let options = ParsingOptions {
        allow_dtd: true,
        ..ParsingOptions::default()
    };
    Document::parse_with_options(text, options).map_err(|e| {
        (
            super::xml_error_at(text, &e),
            format!("not well-formed XML: {e}"),
        )
    })
}

impl<'a, 'i> Xml<'a, 'i> {
    pub fn at(&self, n: Node<'a, 'i>) -> At {
        At {
            file: self.file.to_string(),
            pos: self.lines.pos(self.doc.input_text(), n.range().start),
        }
    }

    pub fn error(&self, n: Node<'a, 'i>, message: impl Into<String>) -> SysError {
        self.at(n).error(message)
    }

    /// An attribute's value, or an error at the element.
    pub fn attr(&self, n: Node<'a, 'i>, name: &str) -> Result<&'a str, SysError> {
        n.attribute(name).ok_or_else(|| {
            self.error(
                n,
                format!("`{}` needs the attribute `{name}`", n.tag_name().name()),
            )
        })
    }

    /// An error for an element that has no place here.
    pub fn unknown(&self, n: Node<'a, 'i>, parent: Node<'a, 'i>) -> SysError {
        self.error(
            n,
            format!(
                "unknown element `{}` in `{}`",
                n.tag_name().name(),
                parent.tag_name().name()
            ),
        )
    }

    /// The FB network `n` (`SubAppNetwork` or `FBNetwork`).
    pub fn network(&self, n: Node<'a, 'i>) -> Result<Network, SysError> {
        let mut net = Network::default();
        for c in elements(n) {
            match c.tag_name().name() {
                "FB" => net.fbs.push(self.fb(c)?),
                "EventConnections" => net.events.extend(self.connections(c)?),
                "DataConnections" => net.data.extend(self.connections(c)?),
                "AdapterConnections" => {
                    if let Some(first) = elements(c).next() {
                        return Err(self.error(first, "adapter connections are not supported"));
                    }
                }
                "SubApp" => {
                    let name = c.attribute("Name").unwrap_or("");
                    return Err(self.error(
                        c,
                        format!(
                            "`{name}` is a subapplication: not supported (make it a composite \
                             FB type, `.fbt` with an `FBNetwork`)"
                        ),
                    ));
                }
                "Attribute" | "Comment" => {}
                _ => return Err(self.unknown(c, n)),
            }
        }
        Ok(net)
    }

    fn fb(&self, n: Node<'a, 'i>) -> Result<Fb, SysError> {
        let name = self.attr(n, "Name")?.to_string();
        let ty = self.attr(n, "Type")?;
        let ty = ty.rsplit("::").next().unwrap_or(ty).to_string();
        let mut params: Vec<Param> = Vec::new();
        let mut given = std::collections::HashSet::new();
        for p in elements(n) {
            match p.tag_name().name() {
                "Parameter" => {
                    let param = self.attr(p, "Name")?;
                    // The first would win unsaid: refused, as any name declared twice.
                    if !given.insert(param) {
                        let what = format!("parameter `{param}` of FB `{name}` is given twice");
                        return Err(self.error(p, what));
                    }
                    params.push(Param {
                        name: param.to_string(),
                        value: self.attr(p, "Value")?.to_string(),
                        at: self.at(p),
                    });
                }
                "Attribute" => {}
                _ => return Err(self.unknown(p, n)),
            }
        }
        Ok(Fb {
            name,
            ty,
            params,
            at: self.at(n),
        })
    }

    fn connections(&self, n: Node<'a, 'i>) -> Result<Vec<Conn>, SysError> {
        let mut out = Vec::new();
        for c in elements(n) {
            if c.tag_name().name() != "Connection" {
                return Err(self.unknown(c, n));
            }
            out.push(Conn {
                source: self.attr(c, "Source")?.to_string(),
                dest: self.attr(c, "Destination")?.to_string(),
                at: self.at(c),
            });
        }
        Ok(out)
    }
}

/// Element children of `n` (comments and text skipped).
pub fn elements<'a, 'i>(n: Node<'a, 'i>) -> impl Iterator<Item = Node<'a, 'i>> {
    n.children().filter(Node::is_element)
}

pub fn child<'a, 'i>(n: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    elements(n).find(|c| c.tag_name().name() == name)
}

#[cfg(test)]
mod tests {
    use super::Lines;

    /// Lines and columns as roxmltree counts them, at every offset of a text with
    /// several lines, an empty one and characters of more than one byte.
    #[test]
    fn lines_give_roxmltree_positions() {
        let long = format!("<d x=\"{}\"/>", "aé€😀".repeat(200));
        let text = format!("<a>\n  <b é=\"ü\"/>\n\n<c/>{long}\n{long}{long}</a>");
        let doc = roxmltree::Document::parse(&text).expect("parses");
        let lines = Lines::of(&text);
        for (offset, _) in text.char_indices().chain([(text.len(), ' ')]) {
            let want = doc.text_pos_at(offset);
            let got = lines.pos(&text, offset);
            assert_eq!((got.line, got.col), (want.row, want.col), "at {offset}");
        }
    }
}
