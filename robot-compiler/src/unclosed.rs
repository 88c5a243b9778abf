//! A file cut short: the brackets still open where the RON text ends. ron reports such a
//! file where it stopped (`Expected opening `(` for struct `Role``, at a comment after the
//! last item), which does not say that the file ends; this finds the bracket left open.
//! One pass over the bytes, strings and comments skipped.

/// Where the code ends (the offset after its last byte that is neither white space nor in
/// a comment) and the innermost bracket still open there (its offset and the bracket), if
/// any.
pub fn unclosed(text: &str) -> (usize, Option<(usize, u8)>) {
    let s = text.as_bytes();
    let mut open: Vec<(usize, u8)> = Vec::new();
    let (mut i, mut code_end) = (0, 0);
    while let Some(&b) = s.get(i) {
        match b {
            b'/' if s.get(i + 1) == Some(&b'/') => {
                while s.get(i).is_some_and(|&c| c != b'\n') {
                    i += 1;
                }
                continue;
            }
            b'/' if s.get(i + 1) == Some(&b'*') => {
                i = block_comment_end(s, i);
                continue;
            }
            b'"' => {
                i = string_end(s, i, b'"');
                code_end = i;
                continue;
            }
            // A char: `'('` is no bracket.
            b'\'' => {
                i = string_end(s, i, b'\'');
                code_end = i;
                continue;
            }
            b'(' | b'[' | b'{' => open.push((i, b)),
            b')' | b']' | b'}' => {
                open.pop();
            }
            _ => {}
        }
        if !b.is_ascii_whitespace() {
            code_end = i + 1;
        }
        i += 1;
    }
    (code_end, open.last().copied())
}

/// The offset after the block comment opening at `i` (nested ones included), or the end.
fn block_comment_end(s: &[u8], mut i: usize) -> usize {
    let mut depth = 0usize;
    while i < s.len() {
        if s.get(i..i + 2) == Some(b"/*") {
            depth += 1;
            i += 2;
        } else if s.get(i..i + 2) == Some(b"*/") {
            depth -= 1;
            i += 2;
            if depth == 0 {
                return i;
            }
        } else {
            i += 1;
        }
    }
    s.len()
}

/// The offset after the string (or char) opening at `i` and closed by `quote` (escapes
/// skipped), or the end.
fn string_end(s: &[u8], mut i: usize, quote: u8) -> usize {
    i += 1;
    while let Some(&c) = s.get(i) {
        match c {
            b'\\' => i += 2,
            _ if c == quote => return i + 1,
            _ => i += 1,
        }
    }
    s.len()
}

#[cfg(test)]
mod tests {
    use super::unclosed;

    #[test]
    fn the_innermost_bracket_open_at_the_end_is_found_past_strings_and_comments() {
        let text =
            "Robot(\n  name: \"a ) ] }\", // ) ]\n  roles: [ /* ] */\n    (x: 1),\n  // cut\n";
        let (end, open) = unclosed(text);
        assert_eq!(open, Some((text.find("[ /*").unwrap(), b'[')));
        assert_eq!(
            &text[..end],
            "Robot(\n  name: \"a ) ] }\", // ) ]\n  roles: [ /* ] */\n    (x: 1),"
        );
        assert_eq!(unclosed("R(a: [1, 2])\n// done\n"), (12, None));
        assert_eq!(unclosed(""), (0, None));
        // A char is no bracket.
        assert_eq!(unclosed("R(a: '(', b: ')')"), (17, None));
        // A string cut short runs to the end.
        assert_eq!(unclosed("R(a: \"x\\\""), (9, Some((1, b'('))));
    }
}
