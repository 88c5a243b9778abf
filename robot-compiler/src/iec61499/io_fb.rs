//! A role's node services as an FB type (`ROLE_IO.fbt`, as `export` writes it): an
//! interface-only type marked [`super::services::IO_MARK`] whose event outputs are the
//! role's inputs, switches and timers (each `Comment` the node event it stands for,
//! `VC.home`, or `node event boot` for a node event of its own; the event's name without
//! one) and whose event inputs take the service
//! events of the role's charts. In an application, an FB of such a type stands for the
//! node of the resource it is mapped onto ([`super::app`]).

use std::collections::BTreeMap;

use super::net::{self, child, elements, At, Conn, Fb, Network, SysError, Xml};
use super::services::IO_MARK;

/// An IO type: its name, event inputs, and event outputs with the node events they are.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IoType {
    pub name: String,
    pub events_in: Vec<String>,
    /// (port, node event).
    pub events_out: Vec<(String, String)>,
    /// The ports that are node events of their own (`boot`, `home`:
    /// [`super::services::NODE_EVENTS`]), no pin or timer.
    pub node_events: Vec<String>,
    pub at: At,
}

/// Whether the `.fbt` text is marked as an IO type; `None` if it is not well formed.
pub fn is_io(text: &str) -> Option<bool> {
    let doc = net::parse(text, "").ok()?;
    let root = doc.root_element();
    Some(
        root.tag_name().name() == "FBType"
            && child(root, "Identification")
                .and_then(|i| i.attribute("Classification"))
                .is_some_and(|c| c == IO_MARK),
    )
}

/// Reads an IO type (`file`: its name, for the errors): an `InterfaceList` of events only,
/// no ECC, no network.
pub fn parse(text: &str, file: &str) -> Result<IoType, SysError> {
    let doc = net::parse(text, file)?;
    let lines = net::Lines::of(text);
    let x = Xml {
        doc: &doc,
        file,
        lines: &lines,
    };
    let root = doc.root_element();
    let name = x.attr(root, "Name")?.to_string();
    for n in elements(root) {
        match n.tag_name().name() {
            "Identification" | "VersionInfo" | "CompilerInfo" | "InterfaceList" | "Service"
            | "Attribute" => {}
            other => {
                return Err(x.error(
                    n,
                    format!(
                        "`{name}` is a node services type (`{IO_MARK}`): an interface only, \
                         no `{other}`"
                    ),
                ))
            }
        }
    }
    let mut io = IoType {
        name,
        events_in: Vec::new(),
        events_out: Vec::new(),
        node_events: Vec::new(),
        at: x.at(root),
    };
    let Some(interface) = child(root, "InterfaceList") else {
        return Ok(io);
    };
    for list in elements(interface) {
        let tag = list.tag_name().name();
        for item in elements(list) {
            let n = x.attr(item, "Name")?.to_string();
            match (tag, item.tag_name().name()) {
                ("EventInputs", "Event") => io.events_in.push(n),
                ("EventOutputs", "Event") => {
                    let comment = (item.attribute("Comment").map(str::trim))
                        .filter(|c| !c.is_empty())
                        .map(super::services::io_event);
                    if comment.is_some_and(|(_, node)| node) {
                        io.node_events.push(n.clone());
                    }
                    let event = comment.map_or_else(|| n.clone(), |(e, _)| e.to_string());
                    io.events_out.push((n, event));
                }
                _ => {
                    return Err(x.error(
                        item,
                        format!(
                            "`{}` in `{tag}` of node services type `{}`: it has event inputs \
                             and outputs only",
                            item.tag_name().name(),
                            io.name
                        ),
                    ))
                }
            }
        }
    }
    Ok(io)
}

/// A `PUBLISH_n` or `SUBSCRIBE_n` FB of a resource.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PubSub {
    Publish,
    Subscribe,
}

/// Whether `fb` is a `PUBLISH_n` / `SUBSCRIBE_n` FB (`n` digits), and which.
pub fn pub_sub(fb: &Fb) -> Option<PubSub> {
    let digits = |r: &str| !r.is_empty() && r.bytes().all(|b| b.is_ascii_digit());
    if fb.ty.strip_prefix("PUBLISH_").is_some_and(digits) {
        return Some(PubSub::Publish);
    }
    fb.ty
        .strip_prefix("SUBSCRIBE_")
        .is_some_and(digits)
        .then_some(PubSub::Subscribe)
}

/// The event connections of an application by their source (`FB.EVENT`), in order.
pub type BySource<'n> = BTreeMap<&'n str, Vec<&'n Conn>>;

/// [`BySource`] of `app`.
pub fn by_source(app: &Network) -> BySource<'_> {
    let mut out: BySource<'_> = BTreeMap::new();
    for c in &app.events {
        out.entry(c.source.as_str()).or_default().push(c);
    }
    out
}

/// Checks a `PUBLISH_n` / `SUBSCRIBE_n` FB of resource `resource` is what `export` writes
/// for a connection the mapping cuts: its `ID` the topic `"ROLE/FB.EVENT"` of an
/// application connection from `FB.EVENT` (mapped onto `ROLE`) to an FB on another
/// resource, published on `ROLE`'s resource, subscribed on a resource it reaches. The
/// application's connections are what becomes the robot's links; such FBs add nothing.
pub fn check_pub_sub(
    fb: &Fb,
    kind: PubSub,
    resource: &str,
    by_source: &BySource<'_>,
    mapped: &BTreeMap<String, String>,
) -> Result<(), SysError> {
    let Some(id) = fb.params.iter().find(|p| p.name == "ID") else {
        return Err(fb.at.error(format!(
            "`{}` (`{}`) of resource `{resource}` has no `ID`: a PUBLISH / SUBSCRIBE FB in a \
             resource carries a connection the mapping cuts, its `ID` the topic \
             `\"ROLE/FB.EVENT\"`",
            fb.name, fb.ty
        )));
    };
    let topic = id.value.trim().trim_matches(|c| c == '"' || c == '\'');
    let role_of = |end: &str| end.split_once('.').and_then(|(f, _)| mapped.get(f));
    let carried = topic.split_once('/').is_some_and(|(role, source)| {
        let cut: Vec<&String> = (by_source.get(source).into_iter().flatten())
            .filter(|c| role_of(&c.source).is_some_and(|r| r == role))
            .filter_map(|c| role_of(&c.dest))
            .filter(|r| *r != role)
            .collect();
        match kind {
            PubSub::Publish => role == resource && !cut.is_empty(),
            PubSub::Subscribe => cut.iter().any(|r| *r == resource),
        }
    });
    if carried {
        return Ok(());
    }
    let (verb, way) = match kind {
        PubSub::Publish => ("publishes", "from"),
        PubSub::Subscribe => ("subscribes to", "into"),
    };
    Err(id.at.error(format!(
        "`{}` (`{}`) of resource `{resource}` {verb} `{topic}`, no connection of the \
         application that the mapping cuts {way} this resource: a PUBLISH / SUBSCRIBE FB in \
         a resource may only carry one (`\"ROLE/FB.EVENT\"`); connect the FBs in the \
         application",
        fb.name, fb.ty
    )))
}
