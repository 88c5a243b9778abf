//! The allowed range of the integer field at a position of RON text: ron reports "Integer
//! is out of bounds" without saying which field or which range, so the field is found by
//! reading back from the number to its key (`address: 0x10000`), its map (`params:
//! {"N": ...}`) or the action it is an argument of (`Fault(300)`).

/// The field name (as written) and its allowed range, for a number at byte `offset`.
pub fn integer_field(text: &str, offset: usize) -> Option<(String, &'static str)> {
    let b = text.as_bytes();
    let mut i = offset.min(b.len());
    // Back to the start of the number.
    while i > 0 && (b[i - 1].is_ascii_alphanumeric() || matches!(b[i - 1], b'_' | b'-' | b'+')) {
        i -= 1;
    }
    let skip_ws = |mut i: usize| {
        while i > 0 && b[i - 1].is_ascii_whitespace() {
            i -= 1;
        }
        i
    };
    i = skip_ws(i);
    match b.get(i.checked_sub(1)?)? {
        b':' => {
            let end = skip_ws(i - 1);
            if b.get(end.checked_sub(1)?) == Some(&b'"') {
                // A map entry `"N": 5`: chart parameters are the only integer maps.
                return Some((String::from("params"), range("params")?));
            }
            let mut start = end;
            while start > 0 && (b[start - 1].is_ascii_alphanumeric() || b[start - 1] == b'_') {
                start -= 1;
            }
            let name = text.get(start..end)?;
            Some((name.to_string(), range(name)?))
        }
        b'(' | b',' => {
            // A positional argument: back to the `(` that opens it, then the name before.
            let mut depth = 0usize;
            let mut j = i;
            while j > 0 {
                j -= 1;
                match b[j] {
                    b')' | b']' | b'}' => depth += 1,
                    b'(' | b'[' | b'{' if depth > 0 => depth -= 1,
                    b'(' => break,
                    b'[' | b'{' => return None,
                    _ => {}
                }
            }
            let end = skip_ws(j);
            let mut start = end;
            while start > 0 && (b[start - 1].is_ascii_alphanumeric() || b[start - 1] == b'_') {
                start -= 1;
            }
            let name = text.get(start..end)?;
            Some((name.to_string(), range(name)?))
        }
        _ => None,
    }
}

/// The range of an integer field of the robot format (`model`).
fn range(field: &str) -> Option<&'static str> {
    Some(match field {
        "channel" | "extend" | "retract" | "home" | "end" | "valve" | "pin" | "Fault" => "0..=255",
        "pan_id" | "address" => "0..=65535",
        "generation" | "motion_timeout_ms" | "out_ms" | "back_ms" | "dwell_ms" | "timeout_ms"
        | "StartTimer" => "0..=4294967295",
        "params" => "-2147483648..=2147483647",
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::integer_field;

    fn at(text: &str, number: &str) -> Option<(String, &'static str)> {
        integer_field(text, text.find(number).expect("number") + 1)
    }

    #[test]
    fn fields_maps_and_action_arguments() {
        assert_eq!(
            at("(name: \"n\", address: 0x10000)", "0x10000"),
            Some((String::from("address"), "0..=65535"))
        );
        assert_eq!(
            at("kind: SingleActing(valve: 300, dwell_ms: 1)", "300"),
            Some((String::from("valve"), "0..=255"))
        );
        assert_eq!(
            at("params: {\"N\": 9999999999}", "9999999999"),
            Some((String::from("params"), "-2147483648..=2147483647"))
        );
        assert_eq!(
            at("actions: [Fault(300)]", "300"),
            Some((String::from("Fault"), "0..=255"))
        );
        assert_eq!(
            at("actions: [StartTimer(\"T\", 99999999999)]", "99999999999"),
            Some((String::from("StartTimer"), "0..=4294967295"))
        );
        assert_eq!(at("x: [300]", "300"), None);
        assert_eq!(at("unknown: 300", "300"), None);
    }
}
