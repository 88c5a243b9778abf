//! The operator's hand on `plant`: a line of standard input drives one of the robot's
//! declared operator inputs (a maintained contact, `FAULT on` / `FAULT off`; a button,
//! `RELEASE`), as `demo` drives them by script.

use std::io::BufRead;

use robot_net::live_motor::{LiveInput, Operate};

/// Longest line taken (an operator's line is a name and a word); a longer one is refused
/// whole, its bytes read and dropped as they come.
pub const MAX_LINE: usize = 128;

/// What the plant prints before it runs: the lines it takes.
pub fn usage(inputs: &[LiveInput]) -> String {
    let one = |i: &LiveInput| match i.press_ms {
        Some(_) => format!("`{}` (a button: pressed)", i.name),
        None => format!("`{0} on` / `{0} off` (a contact: closed / open)", i.name),
    };
    let each: Vec<String> = inputs.iter().map(one).collect();
    format!(
        "operator: type a line to drive an input: {}",
        each.join(", ")
    )
}

/// What `line` asks for (`None`: an empty line), or why it is refused, naming what it
/// could have been.
pub fn parse(inputs: &[LiveInput], line: &str) -> Result<Option<Operate>, String> {
    let mut words = line.split_whitespace();
    let Some(name) = words.next() else {
        return Ok(None);
    };
    let rest: Vec<&str> = words.collect();
    let Some(index) = (inputs.iter()).position(|i| i.name.eq_ignore_ascii_case(name)) else {
        let names: Vec<&str> = inputs.iter().map(|i| i.name.as_str()).collect();
        return Err(format!(
            "no operator input `{name}`: the robot's are {}",
            names.join(", ")
        ));
    };
    let input = &inputs[index];
    match (input.press_ms, rest.as_slice()) {
        (Some(_), []) => Ok(Some(Operate::Press(index))),
        (Some(_), _) => Err(format!(
            "{0} is a button: `{0}` presses it (no `{1}`)",
            input.name,
            rest.join(" ")
        )),
        (None, [level]) => match level.to_ascii_lowercase().as_str() {
            "on" | "close" | "closed" => Ok(Some(Operate::Set(index, true))),
            "off" | "open" => Ok(Some(Operate::Set(index, false))),
            _ => Err(contact(&input.name)),
        },
        (None, _) => Err(contact(&input.name)),
    }
}

fn contact(name: &str) -> String {
    format!("{name} is a contact: `{name} on` closes it, `{name} off` opens it")
}

/// What the plant prints when input `input` went to `level` (`None` for a button let
/// go: its press was said).
pub fn said(input: &LiveInput, level: bool) -> Option<String> {
    match (input.press_ms, level) {
        (Some(_), true) => Some(format!("{} pressed", input.name)),
        (Some(_), false) => None,
        (None, true) => Some(format!("{} closed", input.name)),
        (None, false) => Some(format!("{} open", input.name)),
    }
}

/// One line of `from` of at most [`MAX_LINE`] bytes, without its end (`Ok(None)`: the
/// input ended); a longer one is read to its end and refused.
pub fn next_line(from: &mut impl BufRead) -> std::io::Result<Option<Result<String, String>>> {
    let mut line = Vec::new();
    let mut long = false;
    loop {
        let buf = from.fill_buf()?;
        if buf.is_empty() {
            if line.is_empty() && !long {
                return Ok(None);
            }
            break;
        }
        let (take, end) = match buf.iter().position(|&b| b == b'\n') {
            Some(i) => (i, true),
            None => (buf.len(), false),
        };
        let room = MAX_LINE.saturating_sub(line.len());
        long |= take > room;
        line.extend_from_slice(&buf[..take.min(room)]);
        from.consume(take + usize::from(end));
        if end {
            break;
        }
    }
    if long {
        return Ok(Some(Err(format!("a line over {MAX_LINE} bytes"))));
    }
    Ok(Some(match String::from_utf8(line) {
        Ok(l) => Ok(l),
        Err(_) => Err("a line that is not UTF-8".to_string()),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inputs() -> Vec<LiveInput> {
        let input = |name: &str, pin, press_ms| LiveInput {
            name: name.to_string(),
            addr: 0x31,
            pin,
            press_ms,
        };
        vec![
            input("FAULT", 2, None),
            input("RELEASE", 1, Some(100)),
            input("RESTART", 2, Some(100)),
        ]
    }

    #[test]
    fn a_line_drives_a_contact_or_presses_a_button_and_anything_else_says_why_not() {
        let i = inputs();
        assert_eq!(parse(&i, "FAULT on"), Ok(Some(Operate::Set(0, true))));
        assert_eq!(
            parse(&i, "  fault   OFF "),
            Ok(Some(Operate::Set(0, false)))
        );
        assert_eq!(parse(&i, "FAULT closed"), Ok(Some(Operate::Set(0, true))));
        assert_eq!(parse(&i, "RESTART"), Ok(Some(Operate::Press(2))));
        assert_eq!(parse(&i, "release"), Ok(Some(Operate::Press(1))));
        assert_eq!(parse(&i, "   "), Ok(None));
        assert_eq!(
            parse(&i, "JUMP"),
            Err("no operator input `JUMP`: the robot's are FAULT, RELEASE, RESTART".into())
        );
        assert_eq!(
            parse(&i, "FAULT"),
            Err("FAULT is a contact: `FAULT on` closes it, `FAULT off` opens it".into())
        );
        assert_eq!(
            parse(&i, "FAULT maybe"),
            Err("FAULT is a contact: `FAULT on` closes it, `FAULT off` opens it".into())
        );
        assert_eq!(
            parse(&i, "RELEASE on"),
            Err("RELEASE is a button: `RELEASE` presses it (no `on`)".into())
        );
        assert_eq!(
            usage(&i),
            "operator: type a line to drive an input: `FAULT on` / `FAULT off` (a contact: \
             closed / open), `RELEASE` (a button: pressed), `RESTART` (a button: pressed)"
        );
    }

    #[test]
    fn what_the_plant_says_of_an_input() {
        let i = inputs();
        assert_eq!(said(&i[0], true).as_deref(), Some("FAULT closed"));
        assert_eq!(said(&i[0], false).as_deref(), Some("FAULT open"));
        assert_eq!(said(&i[1], true).as_deref(), Some("RELEASE pressed"));
        assert_eq!(said(&i[1], false), None);
    }

    #[test]
    fn lines_are_bounded_and_an_overlong_or_broken_one_is_refused_whole() {
        let long = "x".repeat(MAX_LINE + 1);
        let text = format!("FAULT on\n{long}\nRELEASE\n\u{ff}\n");
        let mut bytes = text.into_bytes();
        let at = bytes.len() - 2;
        bytes[at] = 0xFF;
        // A small buffer: lines and the limit span several reads.
        let mut from = std::io::BufReader::with_capacity(7, bytes.as_slice());
        let mut got = Vec::new();
        while let Some(l) = next_line(&mut from).expect("reads") {
            got.push(l);
        }
        assert_eq!(
            got,
            [
                Ok("FAULT on".to_string()),
                Err(format!("a line over {MAX_LINE} bytes")),
                Ok("RELEASE".to_string()),
                Err("a line that is not UTF-8".to_string()),
            ]
        );
        let exact = "y".repeat(MAX_LINE);
        let mut from = std::io::BufReader::with_capacity(5, exact.as_bytes());
        assert_eq!(next_line(&mut from).unwrap(), Some(Ok(exact.clone())));
        assert_eq!(next_line(&mut from).unwrap(), None);
    }
}
