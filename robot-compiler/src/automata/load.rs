//! The robot's `automata:` -> [`Automaton`]s: names resolved to indices, facts parsed,
//! every part's [`Place`] kept for diagnostics. A problem that leaves a reference
//! unresolved (an undeclared state, a colour the robot cannot produce, a duplicate, a
//! bad fact) is an error here and the automaton is left out; what a resolved automaton
//! means is for [`super::check`].

use std::io;
use std::path::{Path, PathBuf};

use super::prolog::{self, Facts};
use super::{
    Automaton, Colour, Place, StateId, StateSet, Transition, TransitionId, MAX_COLOURS, MAX_STATES,
    MAX_TRANSITIONS,
};
use crate::diag::Diagnostic;
use crate::model::{AutomatonDecl, Robot, TransitionKind};
use crate::source::Source;

/// Where each part of one automaton is written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Places {
    /// The automaton's `name`.
    pub name: Place,
    /// Each state's declaration, by [`StateId`].
    pub states: Vec<Place>,
    /// Each transition, by [`TransitionId`].
    pub transitions: Vec<TransitionPlaces>,
    /// Each initial state's declaration.
    pub initial: Vec<Place>,
    /// The `priority` list.
    pub priority: Place,
}

/// Where the parts of one transition are written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TransitionPlaces {
    pub whole: Place,
    pub id: Place,
    pub max: Place,
}

/// A resolved automaton and its places.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Located {
    pub automaton: Automaton,
    pub places: Places,
}

/// Every automaton that resolved, in declaration order, and every problem found.
#[derive(Debug, Clone, Default)]
pub struct Loaded {
    pub automata: Vec<Located>,
    pub diagnostics: Vec<Diagnostic>,
}

/// Resolves the robot's automata, reading `facts_file`s next to the robot file
/// (`src.name`).
pub fn load(robot: &Robot, src: &Source) -> Loaded {
    let dir = facts_dir(src);
    load_with(robot, src, &|name: &str| {
        crate::source::read_at_most(&dir.join(name), crate::source::MAX_FILE)
    })
}

/// [`load`], with `read` giving the bytes of a `facts_file` as the robot names it.
pub fn load_with(
    robot: &Robot,
    src: &Source,
    read: &dyn Fn(&str) -> io::Result<Vec<u8>>,
) -> Loaded {
    let mut out = Loaded::default();
    let mut names: Vec<(&str, usize)> = Vec::new();
    for (i, decl) in robot.automata.iter().enumerate() {
        let path = format!("automata[{i}]");
        if let Some(&(_, first)) = names.iter().find(|(n, _)| *n == decl.name) {
            out.diagnostics.push(crate::check::duplicate(
                src,
                "automaton",
                &decl.name,
                &format!("automata[{first}].name"),
                &format!("{path}.name"),
            ));
            continue;
        }
        names.push((&decl.name, i));
        let mut diags = Vec::new();
        if let Some(located) = resolve(&robot.colours, decl, &path, src, read, &mut diags) {
            if diags.iter().all(|d| !d.is_error()) {
                out.automata.push(located);
            }
        }
        out.diagnostics.append(&mut diags);
    }
    out
}

/// A name, its place, and (for transitions) its other places, as the resolver reads
/// them from RON or from facts.
struct Written {
    states: Vec<(String, Place)>,
    initial: Vec<(String, Place)>,
    transitions: Vec<WrittenTransition>,
}

struct WrittenTransition {
    id: String,
    from: (String, Place),
    to: (String, Place),
    colour: (String, Place),
    max: Option<u32>,
    kind: TransitionKind,
    places: TransitionPlaces,
}

fn resolve(
    robot_colours: &[String],
    decl: &AutomatonDecl,
    path: &str,
    src: &Source,
    read: &dyn Fn(&str) -> io::Result<Vec<u8>>,
    out: &mut Vec<Diagnostic>,
) -> Option<Located> {
    let here = |field: &str| Place::Robot(src.span(&format!("{path}.{field}")));
    let written_in_ron =
        !decl.states.is_empty() || !decl.transitions.is_empty() || !decl.initial.is_empty();
    let written = match (&decl.facts, &decl.facts_file) {
        (Some(_), Some(_)) => {
            out.push(here("facts_file").error(format!(
                "automaton `{}` has both `facts` and `facts_file`: give one",
                decl.name
            )));
            return None;
        }
        (Some(text), None) if !written_in_ron => {
            let map = InlineMap::new(src, src.span(&format!("{path}.facts")));
            written_from_facts(prolog::parse(text), &|span| map.place(span), out)?
        }
        (None, Some(file)) if !written_in_ron => {
            let at = src.span(&format!("{path}.facts_file"));
            let bytes = match read(file) {
                Ok(bytes) => bytes,
                Err(e) => {
                    out.push(Diagnostic::error(
                        at,
                        format!("cannot read facts file `{file}`: {e}"),
                    ));
                    return None;
                }
            };
            let facts_src = match Source::from_bytes(file.clone(), bytes) {
                Ok(s) => s,
                Err(e) => {
                    out.push(Diagnostic::error(at, e.to_string()));
                    return None;
                }
            };
            let place = |span: std::ops::Range<usize>| {
                let (line, col) = facts_src.line_col(span.start);
                Place::File {
                    name: file.clone(),
                    line,
                    col,
                    at: at.clone(),
                }
            };
            written_from_facts(prolog::parse(&facts_src.text), &place, out)?
        }
        (None, None) => from_ron(decl, path, src),
        _ => {
            out.push(here("states").error(format!(
                "automaton `{}` has facts and also `states`, `initial` or `transitions`: give one or the other",
                decl.name
            )));
            return None;
        }
    };
    build(robot_colours, decl, path, src, written, out)
}

fn from_ron(decl: &AutomatonDecl, path: &str, src: &Source) -> Written {
    let at = |p: String| Place::Robot(src.span(&p));
    Written {
        states: decl
            .states
            .iter()
            .enumerate()
            .map(|(i, s)| (s.clone(), at(format!("{path}.states[{i}]"))))
            .collect(),
        initial: decl
            .initial
            .iter()
            .enumerate()
            .map(|(i, s)| (s.clone(), at(format!("{path}.initial[{i}]"))))
            .collect(),
        transitions: decl
            .transitions
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let p = format!("{path}.transitions[{i}]");
                WrittenTransition {
                    id: t.id.clone(),
                    from: (t.from.clone(), at(format!("{p}.from"))),
                    to: (t.to.clone(), at(format!("{p}.to"))),
                    colour: (t.colour.clone(), at(format!("{p}.colour"))),
                    max: t.max,
                    kind: t.kind,
                    places: TransitionPlaces {
                        whole: at(p.clone()),
                        id: at(format!("{p}.id")),
                        max: at(format!("{p}.max")),
                    },
                }
            })
            .collect(),
    }
}

fn written_from_facts(
    parsed: Result<Facts, prolog::FactError>,
    place: &dyn Fn(std::ops::Range<usize>) -> Place,
    out: &mut Vec<Diagnostic>,
) -> Option<Written> {
    let facts = match parsed {
        Ok(f) => f,
        Err(e) => {
            out.push(place(e.span.clone()).error(e.to_string()));
            return None;
        }
    };
    let atom = |a: &prolog::Atom| (a.text.clone(), place(a.span.clone()));
    Some(Written {
        states: facts.states.iter().map(atom).collect(),
        initial: facts.initial.iter().map(atom).collect(),
        transitions: facts
            .transitions
            .iter()
            .map(|t| WrittenTransition {
                id: t.id.text.clone(),
                from: atom(&t.from),
                to: atom(&t.to),
                colour: atom(&t.colour),
                max: t.max,
                kind: t.kind,
                places: TransitionPlaces {
                    whole: place(t.span.clone()),
                    id: place(t.id.span.clone()),
                    max: place(t.max_span.clone()),
                },
            })
            .collect(),
    })
}

/// Offsets of inline facts -> offsets of the robot file: exact in a raw string and in a
/// plain string without escapes, the string's start otherwise.
struct InlineMap {
    span: std::ops::Range<usize>,
    /// Bytes before the facts' first byte, if offsets map one to one.
    prefix: Option<usize>,
}

impl InlineMap {
    fn new(src: &Source, span: std::ops::Range<usize>) -> InlineMap {
        let text = src.slice(span.clone());
        let prefix = if let Some(raw) = text.strip_prefix('r') {
            Some(1 + raw.bytes().take_while(|&b| b == b'#').count() + 1)
        } else if text.starts_with('"') && !text.contains('\\') {
            Some(1)
        } else {
            None
        };
        InlineMap { span, prefix }
    }

    fn place(&self, at: std::ops::Range<usize>) -> Place {
        match self.prefix {
            Some(p) => {
                let start = self.span.start + p;
                Place::Robot(start + at.start..start + at.end)
            }
            None => Place::Robot(self.span.clone()),
        }
    }
}

/// The colours an automaton reads: its own, else the robot's, else those its transitions
/// name.
fn colours(
    robot_colours: &[String],
    decl: &AutomatonDecl,
    path: &str,
    src: &Source,
    w: &Written,
    out: &mut Vec<Diagnostic>,
) -> Vec<String> {
    if let Some(own) = &decl.colours {
        if !robot_colours.is_empty() {
            for (i, c) in own.iter().enumerate() {
                if !robot_colours.contains(c) {
                    out.push(Diagnostic::error(
                        src.span(&format!("{path}.colours[{i}]")),
                        format!(
                            "colour `{c}` of automaton `{}` is not one of the robot's colours ({}): its sensors cannot produce it",
                            decl.name,
                            robot_colours.join(", ")
                        ),
                    ));
                }
            }
        }
        return own.clone();
    }
    if !robot_colours.is_empty() {
        return robot_colours.to_vec();
    }
    let mut seen: Vec<String> = Vec::new();
    for t in &w.transitions {
        if !seen.contains(&t.colour.0) {
            seen.push(t.colour.0.clone());
        }
    }
    seen
}

fn build(
    robot_colours: &[String],
    decl: &AutomatonDecl,
    path: &str,
    src: &Source,
    w: Written,
    out: &mut Vec<Diagnostic>,
) -> Option<Located> {
    let name = &decl.name;
    let name_place = Place::Robot(src.span(&format!("{path}.name")));
    let errors_before = out.iter().filter(|d| d.is_error()).count();
    let colours = colours(robot_colours, decl, path, src, &w, out);
    let limit = |what: &str, n: usize, max: usize| {
        name_place.error(format!(
            "automaton `{name}` has {n} {what}: at most {max} (over by {}); split it into automata that select parts of the sequences",
            n - max
        ))
    };
    if w.states.len() > MAX_STATES {
        out.push(limit("states", w.states.len(), MAX_STATES));
        return None;
    }
    if w.transitions.len() > MAX_TRANSITIONS {
        out.push(limit("transitions", w.transitions.len(), MAX_TRANSITIONS));
        return None;
    }
    if colours.len() > MAX_COLOURS {
        out.push(limit("colours", colours.len(), MAX_COLOURS));
        return None;
    }
    // States, each once.
    let mut states: Vec<String> = Vec::new();
    let mut state_places = Vec::new();
    for (s, place) in &w.states {
        match states.iter().position(|x| x == s) {
            Some(first) => out.push(place.error(format!(
                "duplicate state `{s}` of automaton `{name}` (first declared at {})",
                state_places
                    .get(first)
                    .map_or(String::new(), |p: &Place| p.line_col(src))
            ))),
            None => {
                states.push(s.clone());
                state_places.push(place.clone());
            }
        }
    }
    let state = |s: &str| states.iter().position(|x| x == s).map(|i| StateId(i as u8));
    let unknown = |(s, place): &(String, Place), what: &str| {
        let is = if what.starts_with("transition") {
            ", which is"
        } else {
            " is"
        };
        place.error(format!(
            "{what} `{s}`{is} not a state of automaton `{name}` (states: {})",
            if states.is_empty() {
                String::from("none declared")
            } else {
                states.join(", ")
            }
        ))
    };
    // Initial states.
    let mut initial = StateSet::EMPTY;
    let mut initial_places = Vec::new();
    for written in &w.initial {
        match state(&written.0) {
            Some(q) => {
                initial = initial.with(q);
                initial_places.push(written.1.clone());
            }
            None => out.push(unknown(written, "initial state")),
        }
    }
    // Transitions: ids once, states declared, colours producible.
    let mut transitions: Vec<Transition> = Vec::new();
    let mut transition_places: Vec<TransitionPlaces> = Vec::new();
    for t in &w.transitions {
        if let Some(first) = transitions.iter().position(|x| x.id == t.id) {
            out.push(t.places.id.error(format!(
                "duplicate transition id `{}` in automaton `{name}` (first declared at {})",
                t.id,
                transition_places
                    .get(first)
                    .map_or(String::new(), |p| p.id.line_col(src))
            )));
            continue;
        }
        let from = state(&t.from.0);
        let to = state(&t.to.0);
        if from.is_none() {
            out.push(unknown(&t.from, &format!("transition `{}` leaves", t.id)));
        }
        if to.is_none() {
            out.push(unknown(&t.to, &format!("transition `{}` goes to", t.id)));
        }
        let colour = colours.iter().position(|c| *c == t.colour.0);
        if colour.is_none() {
            let source = if decl.colours.is_some() {
                format!("automaton `{name}`'s colours")
            } else {
                String::from("the robot's colours")
            };
            out.push(t.colour.1.error(format!(
                "colour `{}` of transition `{}` cannot be produced: it is not one of {source} ({})",
                t.colour.0,
                t.id,
                colours.join(", ")
            )));
        }
        if let (Some(from), Some(to), Some(colour)) = (from, to, colour) {
            transitions.push(Transition {
                id: t.id.clone(),
                from,
                to,
                colour: Colour(colour as u8),
                max: t.max,
                kind: t.kind,
            });
            transition_places.push(t.places.clone());
        }
    }
    // Priority: known ids, each once.
    let mut priority: Vec<TransitionId> = Vec::new();
    for (i, id) in decl.priority.iter().enumerate() {
        let at = Place::Robot(src.span(&format!("{path}.priority[{i}]")));
        match transitions.iter().position(|t| t.id == *id) {
            Some(t) if priority.contains(&TransitionId(t as u8)) => out.push(at.error(format!(
                "transition `{id}` is twice in the priority of automaton `{name}`"
            ))),
            Some(t) => priority.push(TransitionId(t as u8)),
            None => out.push(at.error(format!(
                "priority names `{id}`, which is not a transition of automaton `{name}`"
            ))),
        }
    }
    if out.iter().filter(|d| d.is_error()).count() > errors_before {
        return None;
    }
    Some(Located {
        automaton: Automaton {
            name: name.clone(),
            colours,
            states,
            transitions,
            initial,
            priority,
            deterministic: decl.deterministic,
        },
        places: Places {
            name: name_place,
            states: state_places,
            transitions: transition_places,
            initial: initial_places,
            priority: Place::Robot(src.span(&format!("{path}.priority"))),
        },
    })
}

/// The directory a robot file's `facts_file`s are read from.
pub fn facts_dir(src: &Source) -> PathBuf {
    Path::new(&src.name)
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default()
}

/// One automaton from the paper's facts alone (no robot): resolved and checked, or every
/// error as `line:col: error: message` (places in `text`). For tests and tools that
/// bring an automaton written for the paper's tools.
pub fn from_facts(name: &str, text: &str) -> Result<Located, Vec<String>> {
    let mut hashes = String::from("#");
    while text.contains(&format!("\"{hashes}")) {
        hashes.push('#');
    }
    let prefix = format!("(name: {name:?}, facts: r{hashes}\"");
    let src = Source::new(name, format!("{prefix}{text}\"{hashes})"));
    let facts_src = Source::new(name, text);
    let short = |diags: &[Diagnostic]| -> Vec<String> {
        diags
            .iter()
            .filter(|d| d.is_error())
            .map(|d| {
                let (line, col) = facts_src.line_col(d.span.start.saturating_sub(prefix.len()));
                format!("{line}:{col}: error: {}", d.message)
            })
            .collect()
    };
    let decl: AutomatonDecl = ron::Options::default()
        .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
        .from_str(&src.text)
        .map_err(|e| vec![e.to_string()])?;
    let mut diags = Vec::new();
    let no_file = |_: &str| Err(io::Error::from(io::ErrorKind::NotFound));
    let located = resolve(&[], &decl, "", &src, &no_file, &mut diags);
    if let Some(l) = &located {
        super::check::check_one(l, &mut diags);
    }
    match located {
        Some(l) if short(&diags).is_empty() => Ok(l),
        _ => Err(short(&diags)),
    }
}
