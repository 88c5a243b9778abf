//! The element structure of IEC 61499-2 (its `LibraryElement.dtd`) for the elements the
//! export writes, as a table: per element its required and optional attributes and its
//! children in order with their multiplicity. [`validate`] applies it to a document
//! parsed with roxmltree; the first violation is an error naming the element and its
//! line:col.

/// How often a child may occur.
#[derive(Clone, Copy)]
enum Many {
    /// `?`
    Opt,
    /// `+`
    Plus,
    /// `*`
    Star,
    /// exactly once
    One,
}

/// IEC 61499-2 Annex B, the elements of FB types and system configurations used here, a
/// row each as the DTD declares them: the element, its required attributes, its optional
/// ones (`?name`), then after `:` its children in the order of the DTD's sequence, each
/// with its multiplicity (`?`, `+`, `*`, none: exactly once).
const SCHEMA: &[&str] = &[
    "FBType Name ?Comment : Identification? VersionInfo+ CompilerInfo? InterfaceList BasicFB? \
     Service?",
    "Identification ?Standard ?Classification ?ApplicationDomain ?Function ?Type ?Description",
    "VersionInfo Organization Version Author Date ?Remarks",
    "InterfaceList : EventInputs? EventOutputs? InputVars? OutputVars?",
    "EventInputs : Event+",
    "EventOutputs : Event+",
    "Event Name ?Type ?Comment : With*",
    "With Var",
    "InputVars : VarDeclaration+",
    "OutputVars : VarDeclaration+",
    "InternalVars : VarDeclaration+",
    "VarDeclaration Name Type ?ArraySize ?InitialValue ?Comment",
    "BasicFB : InternalVars? ECC? Algorithm*",
    "ECC : ECState+ ECTransition*",
    "ECState Name ?Comment ?x ?y : ECAction*",
    "ECAction ?Algorithm ?Output",
    "ECTransition Source Destination Condition ?Comment ?x ?y",
    "Algorithm Name ?Comment : ST",
    "ST Text",
    "Service RightInterface LeftInterface ?Comment : ServiceSequence*",
    "System Name ?Comment : Identification? VersionInfo+ Application* Device+ Mapping*",
    "Application Name ?Comment : SubAppNetwork",
    "SubAppNetwork : FB* EventConnections? DataConnections?",
    "FBNetwork : FB* EventConnections? DataConnections?",
    "FB Name Type ?Comment ?x ?y : Parameter*",
    "Parameter Name Value ?Comment",
    "EventConnections : Connection+",
    "Connection Source Destination ?Comment ?dx1 ?dx2 ?dy",
    "Device Name Type ?Comment ?x ?y : Parameter* Resource*",
    "Resource Name Type ?Comment ?x ?y : Parameter* FBNetwork?",
    "Mapping From To",
];

/// One row of [`SCHEMA`], read.
struct Element<'s> {
    required: Vec<&'s str>,
    optional: Vec<&'s str>,
    children: Vec<(&'s str, Many)>,
}

/// The row of element `name`, if [`SCHEMA`] has one.
fn element(name: &str) -> Option<Element<'static>> {
    let row = SCHEMA
        .iter()
        .find(|r| r.split_whitespace().next() == Some(name))?;
    let (attrs, children) = row.split_once(':').unwrap_or((row, ""));
    let attrs: Vec<&str> = attrs.split_whitespace().skip(1).collect();
    let children = children
        .split_whitespace()
        .map(|c| match c.strip_suffix(['?', '+', '*']) {
            Some(n) if c.ends_with('?') => (n, Many::Opt),
            Some(n) if c.ends_with('+') => (n, Many::Plus),
            Some(n) => (n, Many::Star),
            None => (c, Many::One),
        });
    Some(Element {
        required: attrs
            .iter()
            .filter(|a| !a.starts_with('?'))
            .copied()
            .collect(),
        optional: attrs.iter().filter_map(|a| a.strip_prefix('?')).collect(),
        children: children.collect(),
    })
}

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
        let Some(e) = element(name) else {
            return Err(here(String::from("not an element of IEC 61499-2 here")));
        };
        for a in n.attributes() {
            if !e.required.contains(&a.name()) && !e.optional.contains(&a.name()) {
                return Err(here(format!("attribute `{}` is not allowed", a.name())));
            }
        }
        for r in &e.required {
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
        Many::Opt => count <= 1,
        Many::Plus => count >= 1,
        Many::Star => true,
        Many::One => count == 1,
    };
    if ok {
        Ok(())
    } else {
        Err(format!("`{name}` occurs {count} times"))
    }
}
