//! An IEC 61499-2 system configuration (`.sys`, as Eclipse 4diac IDE writes it) read into
//! its parts: the `Application`'s FB network, the `Device`s with their `Resource`s, and
//! the `Mapping`s of the application's FBs onto resources. What it becomes is
//! [`super::app`]'s business.

use super::net::{self, child, elements, At, Fb, Network, SysError, Xml};

/// A system: one application, the devices, the mapping.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct System {
    /// The application's name (the first part of a mapping's `From`).
    pub app: String,
    pub net: Network,
    pub devices: Vec<Device>,
    pub mapping: Vec<Mapping>,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Device {
    pub name: String,
    pub resources: Vec<Resource>,
    pub at: At,
}

/// A resource and the FB network 4diac keeps in it (the mapped FBs' copies, and the
/// `E_RESTART` it puts in every new resource).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Resource {
    pub name: String,
    pub net: Network,
    pub at: At,
}

/// `Mapping From="APP.FB" To="DEVICE.RESOURCE"` (or `.RESOURCE.FB`, as 4diac 2 writes).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Mapping {
    pub fb: String,
    pub device: String,
    pub resource: String,
    pub at: At,
}

/// Reads the `.sys` text (`file`: its name, for the errors).
pub fn parse(text: &str, file: &str) -> Result<System, SysError> {
    let doc = net::parse(text, file)?;
    let lines = net::Lines::of(text);
    let x = Xml {
        doc: &doc,
        file,
        lines: &lines,
    };
    let root = doc.root_element();
    if root.tag_name().name() != "System" {
        return Err(x.error(
            root,
            format!(
                "`{}` is not a system configuration (`System`)",
                root.tag_name().name()
            ),
        ));
    }
    let mut app: Option<(String, Network)> = None;
    let mut devices = Vec::new();
    let mut maps = Vec::new();
    for n in elements(root) {
        match n.tag_name().name() {
            "Application" => {
                if app.is_some() {
                    return Err(x.error(n, "a second `Application`: one system, one application"));
                }
                let name = x.attr(n, "Name")?.to_string();
                let mut network = None;
                for c in elements(n) {
                    match c.tag_name().name() {
                        "SubAppNetwork" | "FBNetwork" if network.is_none() => {
                            network = Some(x.network(c)?)
                        }
                        "Attribute" | "Comment" => {}
                        _ => return Err(x.unknown(c, n)),
                    }
                }
                app = Some((name, network.unwrap_or_default()));
            }
            "Device" => devices.push(device(&x, n)?),
            "Mapping" => maps.push(n),
            "Identification" | "VersionInfo" | "Segment" | "Link" | "Attribute" => {}
            _ => return Err(x.unknown(n, root)),
        }
    }
    let Some((app, net)) = app else {
        return Err(x.error(root, "the system has no `Application`"));
    };
    let mut mapping = Vec::new();
    for n in maps {
        let from = x.attr(n, "From")?;
        let to = x.attr(n, "To")?;
        let Some((_, fb)) = from.split_once('.').filter(|(a, _)| *a == app) else {
            return Err(x.error(
                n,
                format!("`From=\"{from}\"` names no FB of the application `{app}` (`{app}.FB`)"),
            ));
        };
        let mut parts = to.splitn(3, '.');
        let (Some(device), Some(resource)) = (parts.next(), parts.next()) else {
            return Err(x.error(
                n,
                format!("`To=\"{to}\"` names no resource (`DEVICE.RESOURCE`)"),
            ));
        };
        mapping.push(Mapping {
            fb: fb.to_string(),
            device: device.to_string(),
            resource: resource.to_string(),
            at: x.at(n),
        });
    }
    Ok(System {
        app,
        net,
        devices,
        mapping,
    })
}

fn device(x: &Xml<'_, '_>, n: roxmltree::Node<'_, '_>) -> Result<Device, SysError> {
    let name = x.attr(n, "Name")?.to_string();
    let mut resources = Vec::new();
    for r in elements(n) {
        match r.tag_name().name() {
            "Resource" => {
                for c in elements(r) {
                    if !matches!(c.tag_name().name(), "FBNetwork" | "Parameter" | "Attribute") {
                        return Err(x.unknown(c, r));
                    }
                }
                resources.push(Resource {
                    name: x.attr(r, "Name")?.to_string(),
                    net: match child(r, "FBNetwork") {
                        Some(c) => x.network(c)?,
                        None => Network::default(),
                    },
                    at: x.at(r),
                });
            }
            "Parameter" | "Attribute" => {}
            _ => return Err(x.unknown(r, n)),
        }
    }
    Ok(Device {
        name,
        resources,
        at: x.at(n),
    })
}

/// Whether `fb` is what 4diac puts into every new resource and the import leaves alone:
/// an `E_RESTART` that nothing connects.
pub fn idle_restart(fb: &Fb, net: &Network) -> bool {
    let named = |c: &str| c.split_once('.').is_some_and(|(f, _)| f == fb.name);
    fb.ty == "E_RESTART"
        && !net
            .events
            .iter()
            .chain(&net.data)
            .any(|c| named(&c.source) || named(&c.dest))
}
