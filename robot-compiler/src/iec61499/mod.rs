//! IEC 61499-2 XML in: basic FB types (`.fbt`) become chart types of the robot, an
//! application (`.sys`) its roles and charts (docs/iec61499-xml.md). [`fbt`] reads one
//! basic type, [`st`] translates its Structured Text; [`sys`] reads a system, [`composite`]
//! a composite type ([`net`]: the FB networks both have), [`io_fb`] a role's node services
//! type as the export writes it, [`app`] makes the robot of them.
//! Out: [`export`] writes a compiled robot as `.fbt` types and a `.sys`; [`services`] is
//! the naming of the node's services both directions share.

pub mod app;
pub mod composite;
pub mod export;
pub mod fbt;
pub mod io_fb;
pub mod net;
pub mod services;
pub mod st;
pub mod sys;

use std::io;
use std::path::Path;

use crate::diag::Diagnostic;
use crate::model::Robot;
use crate::source::Source;

/// Imports the robot's `fb_types` (files next to the robot file, `src.name`) into its
/// `chart_types`, then its `application`; every problem is an error at its `fb_types` or
/// `application` entry naming the file's line:col. A type with an error is not imported;
/// an application with an error changes nothing.
pub fn import(robot: &mut Robot, src: &Source) -> Vec<Diagnostic> {
    let dir = Path::new(&src.name)
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    import_with(robot, src, &|name: &str| {
        crate::source::read_at_most(&dir.join(name), crate::source::MAX_FILE)
    })
}

/// [`import`], with `read` giving the bytes of a file as the robot names it.
pub fn import_with(
    robot: &mut Robot,
    src: &Source,
    read: &dyn Fn(&str) -> io::Result<Vec<u8>>,
) -> Vec<Diagnostic> {
    let mut diags = Vec::new();
    let mut interfaces = Vec::new();
    let mut composites = Vec::new();
    let mut ios = Vec::new();
    for (i, file) in robot.fb_types.clone().iter().enumerate() {
        let at = src.span(&format!("fb_types[{i}]"));
        let bytes = match read(file) {
            Ok(b) => b,
            Err(e) => {
                diags.push(Diagnostic::error(at, format!("cannot read `{file}`: {e}")));
                continue;
            }
        };
        let text = match utf8_text(file, bytes) {
            Ok(text) => text,
            Err(e) => {
                diags.push(Diagnostic::error(at, e));
                continue;
            }
        };
        if robot.application.is_some() && composite::is_composite(&text) == Some(true) {
            match composite::parse(&text, file) {
                Ok(c) => composites.push(c),
                Err(e) => diags.push(Diagnostic::error(at, e.to_string()).label("imported here")),
            }
            continue;
        }
        if robot.application.is_some() && io_fb::is_io(&text) == Some(true) {
            match io_fb::parse(&text, file) {
                Ok(t) => ios.push(t),
                Err(e) => diags.push(Diagnostic::error(at, e.to_string()).label("imported here")),
            }
            continue;
        }
        match fbt::import_typed(&text) {
            Ok((mut t, mut interface)) => {
                fbt::bind_levels(&mut t, &mut interface);
                interfaces.push((t.name.clone(), interface));
                t.imported = Some(format!("fb_types[{i}]"));
                if let Some(w) = &mut t.written {
                    w.file = file.clone();
                }
                robot.chart_types.push(t);
            }
            Err(e) => {
                diags.push(Diagnostic::error(at, format!("{file}:{e}")).label("imported here"))
            }
        }
    }
    diags.extend(parameters_out_of_type(robot, src, &interfaces));
    if diags.is_empty() {
        if let Some(d) = application(robot, src, read, &interfaces, composites, ios) {
            diags.push(d);
        }
    }
    diags
}

/// The robot file's values of imported types' parameters that their declared types do
/// not hold (a BOOL given 2: `= TRUE` and `= FALSE` then both fail; a UINT given 70000),
/// each at its value. (An application's parameters are checked as they are read.)
fn parameters_out_of_type(
    robot: &Robot,
    src: &Source,
    interfaces: &[(String, fbt::Interface)],
) -> Vec<Diagnostic> {
    let mut diags = Vec::new();
    for (ri, r) in robot.roles.iter().enumerate() {
        for (ci, c) in r.charts.iter().enumerate() {
            let Some((_, iface)) = interfaces.iter().find(|(n, _)| *n == c.type_) else {
                continue;
            };
            for (p, v) in &c.params {
                let Some((_, ty, _)) = iface.inputs.iter().find(|(n, _, _)| n == p) else {
                    continue;
                };
                if let Err(e) = st::literal(&v.to_string(), *ty) {
                    diags.push(Diagnostic::error(
                        src.span(&format!("roles[{ri}].charts[{ci}].params.{p}")),
                        format!(
                            "parameter `{p}` of chart `{}` is {}: {}",
                            c.name,
                            ty.name(),
                            e.message
                        ),
                    ));
                }
            }
        }
    }
    diags
}

/// Brings the robot's `application`, if it has one: the error that kept it out.
fn application(
    robot: &mut Robot,
    src: &Source,
    read: &dyn Fn(&str) -> io::Result<Vec<u8>>,
    interfaces: &[(String, fbt::Interface)],
    composites: Vec<composite::Composite>,
    ios: Vec<io_fb::IoType>,
) -> Option<Diagnostic> {
    let decl = robot.application.clone()?;
    let at = src.span(crate::model::APPLICATION_FILE);
    let file = &decl.file;
    let text = match read(file) {
        Ok(bytes) => match utf8_text(file, bytes) {
            Ok(t) => t,
            Err(e) => return Some(Diagnostic::error(at, e)),
        },
        Err(e) => return Some(Diagnostic::error(at, format!("cannot read `{file}`: {e}"))),
    };
    let xml =
        |e: net::SysError| Diagnostic::error(at.clone(), e.to_string()).label("imported here");
    let system = match sys::parse(&text, file) {
        Ok(s) => s,
        Err(e) => return Some(xml(e)),
    };
    let mut types = app::Types::of(robot, interfaces);
    types.composites = composites;
    types.ios = ios;
    match app::bring(robot, &decl, &system, &mut types) {
        Ok(b) => {
            robot.roles = b.roles;
            robot.assign = b.assign;
            robot
                .chart_types
                .extend(b.chart_types.into_iter().map(|mut t| {
                    t.imported
                        .get_or_insert_with(|| String::from(crate::model::APPLICATION_FILE));
                    t
                }));
            robot.places = b.places;
            None
        }
        Err(app::AppError::Xml(e)) => Some(xml(e)),
        Err(app::AppError::Ron { path, key, message }) => {
            let at = match key {
                Some(key) => src.map_key_span(&path, &key),
                None => src.span(&path),
            };
            Some(Diagnostic::error(at, message))
        }
    }
}

/// Where an XML parse error of `text` is: the place roxmltree gives, or for an error only
/// found at the end (the text ended inside an element, or holds none) the end of the
/// text, where roxmltree says 1:1.
pub(crate) fn xml_error_at(text: &str, e: &roxmltree::Error) -> net::Pos {
    use roxmltree::Error::{NoRootNode, UnclosedRootNode, UnexpectedEndOfStream};
    if matches!(e, UnexpectedEndOfStream | UnclosedRootNode | NoRootNode) {
        return net::Lines::of(text).pos(text, text.len());
    }
    let p = e.pos();
    net::Pos {
        line: p.row,
        col: p.col,
    }
}

/// `bytes` of `file` as text, or why not: the place of the first byte that is not UTF-8.
pub(crate) fn utf8_text(file: &str, bytes: Vec<u8>) -> Result<String, String> {
    crate::source::utf8(file, bytes).map_err(|e| match e {
        crate::source::LoadError::NotUtf8 {
            byte,
            line,
            col,
            offset,
            ..
        } => format!(
            "`{file}` is not UTF-8 text: byte {byte:#04x} at {line}:{col} (offset {offset})"
        ),
        other => other.to_string(),
    })
}

/// The most attributes one XML element may have: roxmltree compares each attribute with
/// the element's others, so an element of many takes time quadratic in their number
/// (40,000 took 1.5 s). IEC 61499 elements have a handful.
pub const MAX_ATTRIBUTES: usize = 256;

/// What the XML parser is not given, found by a linear scan of `text` (comments, CDATA,
/// processing instructions, end tags and quoted values skipped): the place and why of the
/// first attribute past [`MAX_ATTRIBUTES`] of one element, or of a `DOCTYPE` with an
/// internal subset (declared entities would bring elements this scan does not see; IEC
/// 61499 files name their DTD only).
pub(crate) fn refused_xml(text: &str) -> Option<(net::Pos, String)> {
    let b = text.as_bytes();
    let place = |i: usize| net::Lines::of(text).pos(text, i);
    let find = |from: usize, what: &str| {
        text.get(from..)
            .and_then(|rest| rest.find(what))
            .map_or(b.len(), |k| from + k + what.len())
    };
    let mut i = 0;
    while let Some(k) = b
        .get(i..)
        .and_then(|rest| rest.iter().position(|&c| c == b'<'))
    {
        i += k + 1;
        let rest = text.get(i..).unwrap_or("");
        if rest.starts_with("!--") {
            i = find(i, "-->");
        } else if rest.starts_with("![CDATA[") {
            i = find(i, "]]>");
        } else if rest.starts_with('?') {
            i = find(i, "?>");
        } else if rest.starts_with("!DOCTYPE") {
            // Its end or its subset's `[`, whichever comes first outside the quoted
            // literals (`SYSTEM "x>y"` does not end it).
            let mut quote = None;
            let stop = b.get(i..).and_then(|d| {
                d.iter().position(|&c| match quote {
                    Some(q) => {
                        if c == q {
                            quote = None;
                        }
                        false
                    }
                    None if c == b'"' || c == b'\'' => {
                        quote = Some(c);
                        false
                    }
                    None => c == b'>' || c == b'[',
                })
            });
            let Some(k) = stop else {
                break;
            };
            if b.get(i + k) == Some(&b'[') {
                let why = "a DOCTYPE with an internal subset (declarations): not taken";
                return Some((place(i - 1), why.to_string()));
            }
            i += k + 1;
        } else if rest.starts_with('!') || rest.starts_with('/') {
            i = find(i, ">");
        } else {
            let mut attributes = 0;
            while let Some(&c) = b.get(i) {
                match c {
                    b'>' => break,
                    b'"' | b'\'' => {
                        i += 1;
                        i += b
                            .get(i..)
                            .and_then(|v| v.iter().position(|&q| q == c))
                            .unwrap_or(b.len());
                    }
                    b'=' => {
                        attributes += 1;
                        if attributes > MAX_ATTRIBUTES {
                            let why =
                                format!("an element of more than {MAX_ATTRIBUTES} attributes");
                            return Some((place(i), why));
                        }
                    }
                    _ => {}
                }
                i += 1;
            }
        }
    }
    None
}
