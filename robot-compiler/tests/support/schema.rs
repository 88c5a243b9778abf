//! The element structure of IEC 61499-2 (its `LibraryElement.dtd`) for the elements the
//! export writes, as a table: per element its required and optional attributes and its
//! children in order with their multiplicity. [`validate`] applies it to a document
//! parsed with roxmltree; the first violation is an error naming the element and its
//! line:col.

/// How often a child may occur.
#[derive(Clone, Copy)]
pub enum Many {
    /// `?`
    Opt,
    /// `+`
    Plus,
    /// `*`
    Star,
    /// exactly once
    One,
}

pub struct Element {
    pub name: &'static str,
    pub required: &'static [&'static str],
    pub optional: &'static [&'static str],
    /// Children in the order the DTD's sequence has them; a group of alternatives is
    /// written as one entry per alternative with the same position.
    pub children: &'static [(&'static str, Many)],
}

use Many::{One, Opt, Plus, Star};

const XY: &[&str] = &["Comment", "x", "y"];

/// IEC 61499-2 Annex B, the elements of FB types and system configurations used here.
pub const SCHEMA: &[Element] = &[
    Element {
        name: "FBType",
        required: &["Name"],
        optional: &["Comment"],
        children: &[
            ("Identification", Opt),
            ("VersionInfo", Plus),
            ("CompilerInfo", Opt),
            ("InterfaceList", One),
            ("BasicFB", Opt),
            ("Service", Opt),
        ],
    },
    Element {
        name: "Identification",
        required: &[],
        optional: &[
            "Standard",
            "Classification",
            "ApplicationDomain",
            "Function",
            "Type",
            "Description",
        ],
        children: &[],
    },
    Element {
        name: "VersionInfo",
        required: &["Organization", "Version", "Author", "Date"],
        optional: &["Remarks"],
        children: &[],
    },
    Element {
        name: "InterfaceList",
        required: &[],
        optional: &[],
        children: &[
            ("EventInputs", Opt),
            ("EventOutputs", Opt),
            ("InputVars", Opt),
            ("OutputVars", Opt),
        ],
    },
    Element {
        name: "EventInputs",
        required: &[],
        optional: &[],
        children: &[("Event", Plus)],
    },
    Element {
        name: "EventOutputs",
        required: &[],
        optional: &[],
        children: &[("Event", Plus)],
    },
    Element {
        name: "Event",
        required: &["Name"],
        optional: &["Type", "Comment"],
        children: &[("With", Star)],
    },
    Element {
        name: "With",
        required: &["Var"],
        optional: &[],
        children: &[],
    },
    Element {
        name: "InputVars",
        required: &[],
        optional: &[],
        children: &[("VarDeclaration", Plus)],
    },
    Element {
        name: "OutputVars",
        required: &[],
        optional: &[],
        children: &[("VarDeclaration", Plus)],
    },
    Element {
        name: "InternalVars",
        required: &[],
        optional: &[],
        children: &[("VarDeclaration", Plus)],
    },
    Element {
        name: "VarDeclaration",
        required: &["Name", "Type"],
        optional: &["ArraySize", "InitialValue", "Comment"],
        children: &[],
    },
    Element {
        name: "BasicFB",
        required: &[],
        optional: &[],
        children: &[("InternalVars", Opt), ("ECC", Opt), ("Algorithm", Star)],
    },
    Element {
        name: "ECC",
        required: &[],
        optional: &[],
        children: &[("ECState", Plus), ("ECTransition", Star)],
    },
    Element {
        name: "ECState",
        required: &["Name"],
        optional: XY,
        children: &[("ECAction", Star)],
    },
    Element {
        name: "ECAction",
        required: &[],
        optional: &["Algorithm", "Output"],
        children: &[],
    },
    Element {
        name: "ECTransition",
        required: &["Source", "Destination", "Condition"],
        optional: XY,
        children: &[],
    },
    Element {
        name: "Algorithm",
        required: &["Name"],
        optional: &["Comment"],
        children: &[("ST", One)],
    },
    Element {
        name: "ST",
        required: &["Text"],
        optional: &[],
        children: &[],
    },
    Element {
        name: "Service",
        required: &["RightInterface", "LeftInterface"],
        optional: &["Comment"],
        children: &[("ServiceSequence", Star)],
    },
    Element {
        name: "System",
        required: &["Name"],
        optional: &["Comment"],
        children: &[
            ("Identification", Opt),
            ("VersionInfo", Plus),
            ("Application", Star),
            ("Device", Plus),
            ("Mapping", Star),
        ],
    },
    Element {
        name: "Application",
        required: &["Name"],
        optional: &["Comment"],
        children: &[("SubAppNetwork", One)],
    },
    Element {
        name: "SubAppNetwork",
        required: &[],
        optional: &[],
        children: &[
            ("FB", Star),
            ("EventConnections", Opt),
            ("DataConnections", Opt),
        ],
    },
    Element {
        name: "FBNetwork",
        required: &[],
        optional: &[],
        children: &[
            ("FB", Star),
            ("EventConnections", Opt),
            ("DataConnections", Opt),
        ],
    },
    Element {
        name: "FB",
        required: &["Name", "Type"],
        optional: XY,
        children: &[("Parameter", Star)],
    },
    Element {
        name: "Parameter",
        required: &["Name", "Value"],
        optional: &["Comment"],
        children: &[],
    },
    Element {
        name: "EventConnections",
        required: &[],
        optional: &[],
        children: &[("Connection", Plus)],
    },
    Element {
        name: "Connection",
        required: &["Source", "Destination"],
        optional: &["Comment", "dx1", "dx2", "dy"],
        children: &[],
    },
    Element {
        name: "Device",
        required: &["Name", "Type"],
        optional: XY,
        children: &[("Parameter", Star), ("Resource", Star)],
    },
    Element {
        name: "Resource",
        required: &["Name", "Type"],
        optional: XY,
        children: &[("Parameter", Star), ("FBNetwork", Opt)],
    },
    Element {
        name: "Mapping",
        required: &["From", "To"],
        optional: &[],
        children: &[],
    },
];

/// Checks `text` (an `.fbt` or `.sys`) against [`SCHEMA`]: well formed, the root an
/// `FBType` or a `System`, every element known, its attributes allowed and the required
/// ones present, its children in order and as many as allowed.
pub fn validate(text: &str) -> Result<(), String> {
    let options = roxmltree::ParsingOptions {
        allow_dtd: true,
        ..Default::default()
    };
    let doc = roxmltree::Document::parse_with_options(text, options)
        .map_err(|e| format!("not well formed: {e}"))?;
    let root = doc.root_element();
    if !matches!(root.tag_name().name(), "FBType" | "System") {
        return Err(format!(
            "root `{}` is not FBType or System",
            root.tag_name().name()
        ));
    }
    for n in root.descendants().filter(roxmltree::Node::is_element) {
        let at = doc.text_pos_at(n.range().start);
        let name = n.tag_name().name();
        let here = |m: String| format!("{}:{}: `{name}`: {m}", at.row, at.col);
        let Some(e) = SCHEMA.iter().find(|e| e.name == name) else {
            return Err(here(String::from("not an element of IEC 61499-2 here")));
        };
        for a in n.attributes() {
            if !e.required.contains(&a.name()) && !e.optional.contains(&a.name()) {
                return Err(here(format!("attribute `{}` is not allowed", a.name())));
            }
        }
        for r in e.required {
            if n.attribute(*r).is_none() {
                return Err(here(format!("the attribute `{r}` is required")));
            }
        }
        let mut at_child = 0;
        let mut count = 0;
        for c in n.children().filter(roxmltree::Node::is_element) {
            let cname = c.tag_name().name();
            let Some(pos) = e.children.iter().position(|(k, _)| *k == cname) else {
                return Err(here(format!("`{cname}` is not allowed inside")));
            };
            if pos < at_child {
                return Err(here(format!("`{cname}` is out of order")));
            }
            if pos > at_child {
                check_count(e.children[at_child], count).map_err(&here)?;
                for skipped in &e.children[at_child + 1..pos] {
                    check_count(*skipped, 0).map_err(&here)?;
                }
                at_child = pos;
                count = 0;
            }
            count += 1;
        }
        if let Some(first) = e.children.get(at_child) {
            check_count(*first, count).map_err(&here)?;
            for rest in &e.children[at_child + 1..] {
                check_count(*rest, 0).map_err(&here)?;
            }
        }
    }
    Ok(())
}

fn check_count((name, many): (&str, Many), count: usize) -> Result<(), String> {
    let ok = match many {
        Opt => count <= 1,
        Plus => count >= 1,
        Star => true,
        One => count == 1,
    };
    if ok {
        Ok(())
    } else {
        Err(format!("`{name}` occurs {count} times"))
    }
}
