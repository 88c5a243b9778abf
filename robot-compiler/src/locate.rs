//! A structural locator over RON text: records the byte span of every value so that
//! semantic diagnostics can point at `roles[2].actuators[0].name`. ron deserialises the
//! values; this only walks the syntax (tolerantly: it gives up quietly on text ron would
//! reject, which ron reports itself).

use std::ops::Range;

/// A RON value and its byte span.
#[derive(Debug, Clone)]
pub struct Value {
    pub span: Range<usize>,
    pub kind: Kind,
}

/// The shape of a value.
#[derive(Debug, Clone)]
pub enum Kind {
    /// Strings, numbers, chars, unit identifiers.
    Atom,
    /// `Name(a: x, b: y)` or `(a: x)`: named fields, each with its key's span, and where
    /// each name is first ([`Index`]).
    Fields(Vec<(String, Range<usize>, Value)>, Index),
    /// `[x, y]`, `(x, y)`, `Name(x, y)`, `Some(x)`.
    Items(Vec<Value>),
    /// `{ k: v }`: entries with the key as written (strings unquoted), and where each key
    /// is first.
    Map(Vec<(String, Value, Value)>, Index),
}

/// Where each name (of fields, or key of a map) is first: a diagnostic's path is found
/// in one lookup a step, so that many diagnostics on one large map take linear time.
pub type Index = std::collections::HashMap<String, usize>;

/// The index of `names`, the first of each.
fn first<'n>(names: impl Iterator<Item = &'n String>) -> Index {
    let mut index = Index::new();
    for (i, name) in names.enumerate() {
        index.entry(name.clone()).or_insert(i);
    }
    index
}

struct Walker<'a> {
    s: &'a [u8],
    text: &'a str,
    i: usize,
}

/// Parses RON text into its span tree, or `None` if the syntax is broken.
pub fn parse(text: &str) -> Option<Value> {
    let mut p = Walker {
        s: text.as_bytes(),
        text,
        i: 0,
    };
    p.ws();
    // `#![enable(...)]` attributes.
    while p.s.get(p.i) == Some(&b'#') {
        while p.i < p.s.len() && p.s[p.i] != b']' {
            p.i += 1;
        }
        p.i += 1;
        p.ws();
    }
    p.value(0)
}

impl Walker<'_> {
    fn rest(&self) -> &[u8] {
        self.s.get(self.i..).unwrap_or(&[])
    }

    fn ws(&mut self) {
        loop {
            while self.i < self.s.len() && self.s[self.i].is_ascii_whitespace() {
                self.i += 1;
            }
            if self.rest().starts_with(b"//") {
                while self.i < self.s.len() && self.s[self.i] != b'\n' {
                    self.i += 1;
                }
            } else if self.rest().starts_with(b"/*") {
                let mut depth = 0usize;
                while self.i < self.s.len() {
                    if self.s[self.i..].starts_with(b"/*") {
                        depth += 1;
                        self.i += 2;
                    } else if self.s[self.i..].starts_with(b"*/") {
                        depth -= 1;
                        self.i += 2;
                        if depth == 0 {
                            break;
                        }
                    } else {
                        self.i += 1;
                    }
                }
            } else {
                return;
            }
        }
    }

    fn peek(&self) -> Option<u8> {
        self.s.get(self.i).copied()
    }

    fn ident(&mut self) -> Option<Range<usize>> {
        let start = self.i;
        if self.rest().starts_with(b"r#") {
            self.i += 2;
        }
        while self
            .peek()
            .is_some_and(|c| c.is_ascii_alphanumeric() || c == b'_' || c >= 0x80)
        {
            self.i += 1;
        }
        (self.i > start).then_some(start..self.i)
    }

    fn value(&mut self, depth: usize) -> Option<Value> {
        if depth > 128 {
            return None;
        }
        self.ws();
        let start = self.i;
        match self.peek()? {
            b'"' => {
                self.i += 1;
                while let Some(c) = self.peek() {
                    self.i += 1;
                    match c {
                        b'\\' => self.i += 1,
                        b'"' => return Some(self.atom(start)),
                        _ => {}
                    }
                }
                None
            }
            b'\'' => {
                self.i += 1;
                while let Some(c) = self.peek() {
                    self.i += 1;
                    match c {
                        b'\\' => self.i += 1,
                        b'\'' => return Some(self.atom(start)),
                        _ => {}
                    }
                }
                None
            }
            b'r' if self.raw_string_ahead() => {
                self.i += 1;
                let mut hashes = 0;
                while self.peek() == Some(b'#') {
                    hashes += 1;
                    self.i += 1;
                }
                self.i += 1;
                let close: Vec<u8> = std::iter::once(b'"')
                    .chain(std::iter::repeat_n(b'#', hashes))
                    .collect();
                while self.i < self.s.len() {
                    if self.s[self.i..].starts_with(&close) {
                        self.i += close.len();
                        return Some(self.atom(start));
                    }
                    self.i += 1;
                }
                None
            }
            b'[' => {
                self.i += 1;
                let items = self.items(b']', depth)?;
                Some(Value {
                    span: start..self.i,
                    kind: Kind::Items(items),
                })
            }
            b'{' => {
                self.i += 1;
                let mut entries = Vec::new();
                loop {
                    self.ws();
                    if self.peek()? == b'}' {
                        self.i += 1;
                        break;
                    }
                    let key = self.value(depth + 1)?;
                    self.ws();
                    if self.peek()? != b':' {
                        return None;
                    }
                    self.i += 1;
                    let value = self.value(depth + 1)?;
                    let text = self.text[key.span.clone()].trim_matches('"').to_string();
                    entries.push((text, key, value));
                    self.ws();
                    if self.peek()? == b',' {
                        self.i += 1;
                    }
                }
                let index = first(entries.iter().map(|(k, _, _)| k));
                Some(Value {
                    span: start..self.i,
                    kind: Kind::Map(entries, index),
                })
            }
            b'(' => self.parens(start, depth),
            c if c.is_ascii_alphabetic() || c == b'_' => {
                self.ident()?;
                self.after_ident(start, depth)
            }
            _ => {
                // A number (or anything else atomic): up to a delimiter.
                while self.peek().is_some_and(|c| {
                    !matches!(c, b',' | b')' | b']' | b'}' | b':') && !c.is_ascii_whitespace()
                }) {
                    self.i += 1;
                }
                (self.i > start).then(|| self.atom(start))
            }
        }
    }

    fn raw_string_ahead(&self) -> bool {
        let rest = self.s.get(self.i + 1..).unwrap_or(&[]);
        let hashes = rest.iter().take_while(|&&c| c == b'#').count();
        rest.get(hashes) == Some(&b'"')
    }

    fn atom(&self, start: usize) -> Value {
        Value {
            span: start..self.i,
            kind: Kind::Atom,
        }
    }

    fn after_ident(&mut self, start: usize, depth: usize) -> Option<Value> {
        let save = self.i;
        self.ws();
        if self.peek() == Some(b'(') {
            let mut v = self.parens(self.i, depth)?;
            v.span.start = start;
            Some(v)
        } else {
            self.i = save;
            Some(self.atom(start))
        }
    }

    /// `( ... )` after an optional name: named fields or positional items.
    fn parens(&mut self, start: usize, depth: usize) -> Option<Value> {
        self.i += 1;
        self.ws();
        // Named fields if the content starts with `ident :` (and not `::`).
        let save = self.i;
        let named = self.ident().is_some() && {
            self.ws();
            self.peek() == Some(b':')
        };
        self.i = save;
        if !named {
            let items = self.items(b')', depth)?;
            return Some(Value {
                span: start..self.i,
                kind: Kind::Items(items),
            });
        }
        let mut fields = Vec::new();
        loop {
            self.ws();
            if self.peek()? == b')' {
                self.i += 1;
                break;
            }
            let key = self.ident()?;
            self.ws();
            if self.peek()? != b':' {
                return None;
            }
            self.i += 1;
            let value = self.value(depth + 1)?;
            let name = self.text[key.clone()].trim_start_matches("r#").to_string();
            fields.push((name, key, value));
            self.ws();
            if self.peek()? == b',' {
                self.i += 1;
            }
        }
        let index = first(fields.iter().map(|(n, _, _)| n));
        Some(Value {
            span: start..self.i,
            kind: Kind::Fields(fields, index),
        })
    }

    fn items(&mut self, close: u8, depth: usize) -> Option<Vec<Value>> {
        let mut items = Vec::new();
        loop {
            self.ws();
            if self.peek()? == close {
                self.i += 1;
                return Some(items);
            }
            items.push(self.value(depth + 1)?);
            self.ws();
            if self.peek()? == b',' {
                self.i += 1;
            }
        }
    }
}

enum Seg<'p> {
    Field(&'p str),
    Index(usize),
}

fn segments(path: &str) -> Vec<Seg<'_>> {
    let mut out = Vec::new();
    for part in path.split('.').filter(|p| !p.is_empty()) {
        let (name, rest) = part.split_at(part.find('[').unwrap_or(part.len()));
        if !name.is_empty() {
            out.push(Seg::Field(name));
        }
        for index in rest.split('[').filter(|s| !s.is_empty()) {
            if let Ok(i) = index.trim_end_matches(']').parse() {
                out.push(Seg::Index(i));
            }
        }
    }
    out
}

impl Value {
    /// Every key a map has twice (`{"DIPS": 2, "DIPS": 5}`: ron keeps the last silently),
    /// as (key, the first key's span, the second's), in the order of the text.
    pub fn duplicate_keys(&self, out: &mut Vec<(String, Range<usize>, Range<usize>)>) {
        match &self.kind {
            Kind::Atom => {}
            Kind::Fields(fields, _) => fields.iter().for_each(|(_, _, v)| v.duplicate_keys(out)),
            Kind::Items(items) => items.iter().for_each(|v| v.duplicate_keys(out)),
            Kind::Map(entries, _) => {
                let mut seen = std::collections::HashMap::new();
                for (key, k, v) in entries {
                    match seen.get(key.as_str()) {
                        Some(first) => out.push((key.clone(), Range::clone(first), k.span.clone())),
                        None => {
                            seen.insert(key.as_str(), k.span.clone());
                        }
                    }
                    v.duplicate_keys(out);
                }
            }
        }
    }

    /// `Some(x)` and single-item wrappers are transparent to paths.
    fn unwrap_some(&self) -> &Value {
        match &self.kind {
            Kind::Items(items) if items.len() == 1 => items[0].unwrap_some(),
            _ => self,
        }
    }

    fn step(&self, seg: &Seg) -> Option<(Option<Range<usize>>, &Value)> {
        match (seg, &self.kind) {
            (Seg::Field(name), Kind::Fields(fields, index)) => (index.get(*name))
                .and_then(|&i| fields.get(i))
                .map(|(_, k, v)| (Some(k.clone()), v)),
            (Seg::Field(name), Kind::Map(entries, index)) => (index.get(*name))
                .and_then(|&i| entries.get(i))
                .map(|(_, k, v)| (Some(k.span.clone()), v)),
            (Seg::Index(i), Kind::Items(items)) => items.get(*i).map(|v| (None, v)),
            (Seg::Index(i), Kind::Map(entries, _)) => {
                entries.get(*i).map(|(_, k, v)| (Some(k.span.clone()), v))
            }
            (Seg::Field(_), Kind::Items(items)) if items.len() == 1 => items[0].step(seg),
            _ => None,
        }
    }

    /// The key and value at `path`, or `None` and the deepest existing ancestor; and
    /// whether the whole path was found.
    fn reach(&self, path: &str) -> (Option<Range<usize>>, &Value, bool) {
        let mut at = self;
        let mut key = None;
        for seg in segments(path) {
            match at.step(&seg).or_else(|| at.unwrap_some().step(&seg)) {
                Some((k, v)) => {
                    key = k;
                    at = v;
                }
                None => return (None, at, false),
            }
        }
        (key, at, true)
    }

    fn walk(&self, path: &str) -> (Option<Range<usize>>, &Value) {
        let (key, at, _) = self.reach(path);
        (key, at)
    }

    /// Whether the file has a value at `path` (not a default).
    pub fn has(&self, path: &str) -> bool {
        self.reach(path).2
    }

    /// The span of the value at `path` (or of its deepest existing ancestor).
    pub fn find(&self, path: &str) -> Range<usize> {
        self.walk(path).1.span.clone()
    }

    /// The span of key `key` of the map at `path` (or of the value at `path`).
    pub fn find_map_key(&self, path: &str, key: &str) -> Range<usize> {
        let (_, v) = self.walk(path);
        match &v.kind {
            Kind::Map(entries, index) => (index.get(key))
                .and_then(|&i| entries.get(i))
                .map_or_else(|| v.span.clone(), |(_, k, _)| k.span.clone()),
            _ => v.span.clone(),
        }
    }

    /// The span of the key naming the value at `path` (or the value's span).
    pub fn find_key(&self, path: &str) -> Range<usize> {
        let (key, v) = self.walk(path);
        key.unwrap_or_else(|| v.span.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::parse;

    fn at<'a>(text: &'a str, path: &str) -> &'a str {
        let tree = parse(text).expect("parses");
        &text[tree.find(path)]
    }

    #[test]
    fn spans_of_fields_items_maps_and_wrappers() {
        let text = r##"// comment (with parens)
Robot(
    name: "x", /* block /* nested */ */
    list: [(a: 1, b: Some("two")), Kind(c: [3, 4])],
    map: {"k": r#"raw "quoted""#, "m": 'c'},
    r#type: -5,
)"##;
        assert_eq!(at(text, "name"), "\"x\"");
        assert_eq!(at(text, "list[0].a"), "1");
        assert_eq!(at(text, "list[0].b"), "Some(\"two\")");
        assert_eq!(at(text, "list[1].c[1]"), "4");
        assert_eq!(at(text, "list[1]"), "Kind(c: [3, 4])");
        assert_eq!(at(text, "map.k"), "r#\"raw \"quoted\"\"#");
        assert_eq!(at(text, "map.m"), "'c'");
        assert_eq!(at(text, "type"), "-5");
        // A path that goes too deep stops at the deepest value that exists.
        assert_eq!(at(text, "list[0].zzz"), "(a: 1, b: Some(\"two\"))");
        let tree = parse(text).expect("parses");
        assert_eq!(&text[tree.find_key("map.m")], "\"m\"");
        assert_eq!(&text[tree.find_key("list[0].b")], "b");
    }

    #[test]
    fn broken_syntax_gives_no_tree() {
        assert!(parse("Robot(name: \"x\"").is_none());
        assert!(parse("[1, 2").is_none());
        assert!(parse("{\"a\" 1}").is_none());
    }
}
