//! A composite FB type (`.fbt`: `FBType` with an `FBNetwork`): its interface and its
//! network, which [`super::app`] flattens into the instances of the basic FB types inside.

use super::net::{self, child, elements, At, Network, SysError, Xml};

/// A composite FB type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Composite {
    pub name: String,
    pub events_in: Vec<String>,
    pub events_out: Vec<String>,
    /// Input variables and their `InitialValue`s, as written.
    pub inputs: Vec<(String, Option<String>)>,
    pub outputs: Vec<String>,
    pub net: Network,
    pub at: At,
}

/// Whether the `.fbt` text is a composite FB type (has an `FBNetwork`); `None` if it is
/// not well formed (the basic import says why).
pub fn is_composite(text: &str) -> Option<bool> {
    let doc = net::parse(text, "").ok()?;
    let root = doc.root_element();
    Some(root.tag_name().name() == "FBType" && child(root, "FBNetwork").is_some())
}

/// Reads a composite FB type (`file`: its name, for the errors).
pub fn parse(text: &str, file: &str) -> Result<Composite, SysError> {
    let doc = net::parse(text, file)?;
    let lines = net::Lines::of(text);
    let x = Xml {
        doc: &doc,
        file,
        lines: &lines,
    };
    let root = doc.root_element();
    let name = x.attr(root, "Name")?.to_string();
    let Some(network) = child(root, "FBNetwork") else {
        return Err(x.error(root, format!("`{name}` has no `FBNetwork`")));
    };
    let interface = child(root, "InterfaceList")
        .ok_or_else(|| x.error(root, format!("`{name}` has no `InterfaceList`")))?;
    let mut c = Composite {
        name,
        events_in: Vec::new(),
        events_out: Vec::new(),
        inputs: Vec::new(),
        outputs: Vec::new(),
        net: x.network(network)?,
        at: x.at(root),
    };
    for list in elements(interface) {
        let tag = list.tag_name().name();
        for item in elements(list) {
            let n = x.attr(item, "Name")?.to_string();
            match (tag, item.tag_name().name()) {
                ("EventInputs", "Event") => c.events_in.push(n),
                ("EventOutputs", "Event") => c.events_out.push(n),
                ("InputVars", "VarDeclaration") => c.inputs.push((
                    n,
                    item.attribute("InitialValue")
                        .filter(|v| !v.trim().is_empty())
                        .map(str::to_string),
                )),
                ("OutputVars", "VarDeclaration") => c.outputs.push(n),
                ("Sockets" | "Plugs", _) => {
                    return Err(x.error(item, "adapters (sockets and plugs) are not supported"))
                }
                _ => return Err(x.unknown(item, list)),
            }
        }
    }
    Ok(c)
}
