//! A small XML writer: elements with attributes in the order given, two-space indents,
//! every attribute value escaped (`&`, `<`, `>`, `"`, and line breaks and tabs as
//! character references, so a value survives a parser's attribute normalisation).

/// The text of one XML document being written.
pub struct Writer {
    out: String,
    open: Vec<&'static str>,
}

/// `value` escaped for a double-quoted attribute.
pub fn escape(value: &str) -> String {
    let mut s = String::with_capacity(value.len());
    for c in value.chars() {
        match c {
            '&' => s.push_str("&amp;"),
            '<' => s.push_str("&lt;"),
            '>' => s.push_str("&gt;"),
            '"' => s.push_str("&quot;"),
            '\n' => s.push_str("&#10;"),
            '\r' => s.push_str("&#13;"),
            '\t' => s.push_str("&#9;"),
            // Not a character of XML 1.0, even as a reference (only a comment, from a
            // name, can hold one): the replacement character.
            '\u{0}'..='\u{1F}' | '\u{FFFE}' | '\u{FFFF}' => s.push('\u{FFFD}'),
            c => s.push(c),
        }
    }
    s
}

impl Writer {
    /// A document of root `root` with the DTD 4diac IDE and FBDK name
    /// (`LibraryElement.dtd`).
    pub fn new(root: &str) -> Writer {
        Writer {
            out: format!(
                "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!DOCTYPE {root} SYSTEM \
                 \"http://www.holobloc.com/xml/LibraryElement.dtd\">\n"
            ),
            open: Vec::new(),
        }
    }

    fn tag(&mut self, name: &str, attrs: &[(&str, &str)]) {
        for _ in 0..self.open.len() {
            self.out.push_str("  ");
        }
        self.out.push('<');
        self.out.push_str(name);
        for (k, v) in attrs {
            self.out.push(' ');
            self.out.push_str(k);
            self.out.push_str("=\"");
            self.out.push_str(&escape(v));
            self.out.push('"');
        }
    }

    /// Opens `name`: what follows until [`Writer::close`] is inside it.
    pub fn open(&mut self, name: &'static str, attrs: &[(&str, &str)]) {
        self.tag(name, attrs);
        self.out.push_str(">\n");
        self.open.push(name);
    }

    /// An empty element.
    pub fn empty(&mut self, name: &str, attrs: &[(&str, &str)]) {
        self.tag(name, attrs);
        self.out.push_str("/>\n");
    }

    /// Closes the innermost open element.
    pub fn close(&mut self) {
        if let Some(name) = self.open.pop() {
            for _ in 0..self.open.len() {
                self.out.push_str("  ");
            }
            self.out.push_str("</");
            self.out.push_str(name);
            self.out.push_str(">\n");
        }
    }

    /// The document, every element closed.
    pub fn finish(mut self) -> String {
        while !self.open.is_empty() {
            self.close();
        }
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::{escape, Writer};

    /// Attribute values are escaped; elements nest and close in order.
    #[test]
    fn writes_escaped_nested_elements() {
        assert_eq!(
            escape("a<b && c>\"d\"\n"),
            "a&lt;b &amp;&amp; c&gt;&quot;d&quot;&#10;"
        );
        let mut w = Writer::new("FBType");
        w.open("FBType", &[("Name", "T")]);
        w.empty("Event", &[("Name", "E"), ("Comment", "x < 1")]);
        let text = w.finish();
        assert_eq!(
            text,
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!DOCTYPE FBType SYSTEM \
             \"http://www.holobloc.com/xml/LibraryElement.dtd\">\n<FBType Name=\"T\">\n  \
             <Event Name=\"E\" Comment=\"x &lt; 1\"/>\n</FBType>\n"
        );
        let doc = roxmltree::Document::parse_with_options(
            &text,
            roxmltree::ParsingOptions {
                allow_dtd: true,
                ..Default::default()
            },
        )
        .unwrap();
        let e = doc.descendants().find(|n| n.has_tag_name("Event")).unwrap();
        assert_eq!(e.attribute("Comment"), Some("x < 1"));
    }
}
