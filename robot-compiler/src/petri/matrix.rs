//! The paper's objects of one control function, for people (`config-tool matrix`) and
//! as CSV (`--csv`): the incidence matrix M (rows = transitions, columns = places), its
//! precondition part F, the initial marking m(0), and by row the event vector x (each
//! row's event) and the condition vector u (each row's condition, `true` if none).

use super::Net;

/// A table of cells with a header row, right-aligned columns after the first.
fn table(header: &[String], rows: &[Vec<String>]) -> String {
    let cols = header.len();
    let width = |c: usize| {
        rows.iter()
            .filter_map(|r| r.get(c))
            .chain(header.get(c))
            .map(|s| s.chars().count())
            .max()
            .unwrap_or(0)
    };
    let widths: Vec<usize> = (0..cols).map(width).collect();
    let line = |r: &[String]| {
        let cells: Vec<String> = r
            .iter()
            .enumerate()
            .map(|(c, s)| match c {
                0 => format!("{s:<w$}", w = widths[0]),
                _ => format!("{s:>w$}", w = widths[c]),
            })
            .collect();
        format!("  {}", cells.join("  ").trim_end())
    };
    let mut out = vec![line(header)];
    out.extend(rows.iter().map(|r| line(r)));
    out.join("\n")
}

fn header(net: &Net, first: &str) -> Vec<String> {
    std::iter::once(first.to_string())
        .chain(net.places.iter().cloned())
        .collect()
}

/// The condition of row `k` as u shows it.
fn condition(net: &Net, k: usize) -> &str {
    net.transitions
        .get(k)
        .and_then(|t| t.when.as_ref())
        .map_or("true", |(text, _)| text.as_str())
}

/// M, F, m(0), x and u of one function as readable tables.
pub fn text(net: &Net) -> String {
    let m = net.incidence();
    let f = net.precondition();
    let rows = |cells: &dyn Fn(usize) -> Vec<String>| -> Vec<Vec<String>> {
        net.transitions
            .iter()
            .enumerate()
            .map(|(k, t)| std::iter::once(t.name.clone()).chain(cells(k)).collect())
            .collect()
    };
    let m_rows = rows(&|k| m[k].iter().map(|e| e.to_string()).collect());
    let f_rows = rows(&|k| f[k].iter().map(|&e| u8::from(e).to_string()).collect());
    let m0 = vec![std::iter::once(String::new())
        .chain(net.initial_marking().iter().map(|e| e.to_string()))
        .collect()];
    let xu: Vec<Vec<String>> = net
        .transitions
        .iter()
        .enumerate()
        .map(|(k, t)| vec![t.name.clone(), t.on.clone(), condition(net, k).to_string()])
        .collect();
    let xu_header = ["row", "x (event)", "u (condition)"].map(String::from);
    format!(
        "function {} on role {}: {} places, {} transitions\n\nM (rows: transitions, columns: places; -1 precondition, 1 result)\n{}\n\nF (precondition part of M)\n{}\n\nm(0) (initial marking)\n{}\n\nx (events) and u (conditions), by row of M\n{}\n",
        net.name,
        net.role,
        net.places.len(),
        net.transitions.len(),
        table(&header(net, "M"), &m_rows),
        table(&header(net, "F"), &f_rows),
        table(&header(net, "m(0)"), &m0),
        left_aligned(&xu_header, &xu),
    )
}

/// A table of cells with a header row, every column left-aligned.
fn left_aligned(header: &[String], rows: &[Vec<String>]) -> String {
    let widths: Vec<usize> = (0..header.len())
        .map(|c| {
            rows.iter()
                .chain(std::iter::once(&header.to_vec()))
                .filter_map(|r| r.get(c))
                .map(|s| s.chars().count())
                .max()
                .unwrap_or(0)
        })
        .collect();
    let line = |r: &[String]| {
        let cells: Vec<String> = r
            .iter()
            .enumerate()
            .map(|(c, s)| format!("{s:<w$}", w = widths[c]))
            .collect();
        format!("  {}", cells.join("  ").trim_end())
    };
    let mut out = vec![line(header)];
    out.extend(rows.iter().map(|r| line(r)));
    out.join("\n")
}

/// A CSV field, quoted if it must be (RFC 4180).
fn field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The same objects as CSV: `object,row,x,u,PLACE...`; a row of M and one of F per
/// transition (x its event, u its condition), then m(0).
pub fn csv(net: &Net) -> String {
    let mut lines = Vec::new();
    let head: Vec<String> = ["function", "object", "row", "x", "u"]
        .iter()
        .map(|s| s.to_string())
        .chain(net.places.iter().map(|p| field(p)))
        .collect();
    lines.push(head.join(","));
    let m = net.incidence();
    let f = net.precondition();
    for (object, cells) in [
        (
            "M",
            m.iter()
                .map(|r| r.iter().map(|e| e.to_string()).collect::<Vec<_>>())
                .collect::<Vec<_>>(),
        ),
        (
            "F",
            f.iter()
                .map(|r| r.iter().map(|&e| u8::from(e).to_string()).collect())
                .collect(),
        ),
    ] {
        for (k, (t, row)) in net.transitions.iter().zip(cells).enumerate() {
            let mut l = vec![
                field(&net.name),
                object.to_string(),
                field(&t.name),
                field(&t.on),
                field(condition(net, k)),
            ];
            l.extend(row);
            lines.push(l.join(","));
        }
    }
    let mut l = vec![
        field(&net.name),
        String::from("m(0)"),
        String::new(),
        String::new(),
        String::new(),
    ];
    l.extend(net.initial_marking().iter().map(|e| e.to_string()));
    lines.push(l.join(","));
    lines.join("\n") + "\n"
}

#[cfg(test)]
mod tests {
    /// A CSV field with a comma, a quote or a line break is quoted (RFC 4180).
    #[test]
    fn csv_fields_are_quoted_when_they_must_be() {
        assert_eq!(super::field("A && B"), "A && B");
        assert_eq!(super::field("A, B"), "\"A, B\"");
        assert_eq!(super::field("say \"x\""), "\"say \"\"x\"\"\"");
    }
}
