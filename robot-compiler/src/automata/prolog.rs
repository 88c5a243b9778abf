//! The paper's Prolog facts of a selecting automaton, exactly the forms it uses:
//!
//! ```text
//! state(s0). state(s1).                      % state/1
//! transition(t1,s0,s1,black,_,ordinary).     % transition/6: id, from, to, colour,
//! transition(t2,s0,s0,orange,999,ordinary).  %   max count of a loop or `_`,
//! transition(t4,s1,s0,black,_,final).        %   ordinary or final
//! initial_state(s0).                         % initial_state/1
//! ```
//!
//! Atoms (`[a-z][A-Za-z0-9_]*`), integers, `_`, `%` comments to the end of the line. One
//! pass over the text: the first problem is a [`FactError`] at its byte span.

use std::ops::Range;

use crate::model::TransitionKind;

/// An atom and where it is written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Atom {
    pub text: String,
    /// Byte span in the facts text.
    pub span: Range<usize>,
}

/// A `transition/6` fact.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FactTransition {
    /// The whole fact.
    pub span: Range<usize>,
    pub id: Atom,
    pub from: Atom,
    pub to: Atom,
    pub colour: Atom,
    /// The fifth argument: a count, or `None` for `_`.
    pub max: Option<u32>,
    pub max_span: Range<usize>,
    pub kind: TransitionKind,
}

/// Every fact of a text, in order of appearance.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Facts {
    pub states: Vec<Atom>,
    pub transitions: Vec<FactTransition>,
    pub initial: Vec<Atom>,
}

/// A bad fact: what is wrong, at a byte span of the text.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{kind}")]
pub struct FactError {
    pub span: Range<usize>,
    pub kind: FactErrorKind,
}

/// What is wrong with a fact.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FactErrorKind {
    #[error("unexpected character `{0}` in the facts")]
    Character(char),
    #[error("expected {expected}, found {found}")]
    Expected {
        expected: &'static str,
        found: String,
    },
    #[error("`{0}` is a variable: a fact takes atoms, integers and `_`")]
    Variable(String),
    #[error(
        "unknown fact `{name}/{arity}`: the facts are state/1, transition/6 and initial_state/1"
    )]
    Unknown { name: String, arity: usize },
    #[error("`final_state/1` is not a fact of a selecting automaton: its final transitions end sequences (`final` in transition/6)")]
    FinalState,
    #[error("`{name}` takes {expected}, found {found} argument(s)")]
    Arity {
        name: &'static str,
        expected: &'static str,
        found: usize,
    },
    #[error("argument {position} of `{fact}` must be {expected}, found {found}")]
    Argument {
        fact: &'static str,
        position: usize,
        expected: &'static str,
        found: String,
    },
    #[error("the count `{0}` is too large (at most 4294967295)")]
    TooLarge(String),
}

/// A token's kind.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Tok {
    Atom,
    Var,
    Anon,
    Int,
    Open,
    Close,
    Comma,
    Dot,
    End,
}

struct Lexer<'a> {
    text: &'a str,
    i: usize,
}

impl<'a> Lexer<'a> {
    fn skip_layout(&mut self) {
        let bytes = self.text.as_bytes();
        while let Some(&b) = bytes.get(self.i) {
            if b.is_ascii_whitespace() {
                self.i += 1;
            } else if b == b'%' {
                while bytes.get(self.i).is_some_and(|&b| b != b'\n') {
                    self.i += 1;
                }
            } else {
                break;
            }
        }
    }

    /// The next token and its span.
    fn next(&mut self) -> Result<(Tok, Range<usize>), FactError> {
        self.skip_layout();
        let start = self.i;
        let bytes = self.text.as_bytes();
        let Some(&b) = bytes.get(start) else {
            return Ok((Tok::End, start..start));
        };
        let single = |tok| Ok((tok, start..start + 1));
        self.i += 1;
        match b {
            b'(' => single(Tok::Open),
            b')' => single(Tok::Close),
            b',' => single(Tok::Comma),
            b'.' => single(Tok::Dot),
            b'a'..=b'z' | b'A'..=b'Z' | b'_' | b'0'..=b'9' => {
                let word = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
                while bytes.get(self.i).copied().is_some_and(word) {
                    self.i += 1;
                }
                let span = start..self.i;
                let tok = match b {
                    b'a'..=b'z' => Tok::Atom,
                    b'0'..=b'9' => Tok::Int,
                    b'_' if self.i == start + 1 => Tok::Anon,
                    _ => Tok::Var,
                };
                Ok((tok, span))
            }
            _ => {
                let c = self.text.get(start..).and_then(|s| s.chars().next());
                let c = c.unwrap_or(char::REPLACEMENT_CHARACTER);
                self.i = start + c.len_utf8();
                Err(FactError {
                    span: start..self.i,
                    kind: FactErrorKind::Character(c),
                })
            }
        }
    }
}

/// A fact's argument.
struct Arg {
    tok: Tok,
    span: Range<usize>,
}

/// How a token reads in an error.
fn found(text: &str, tok: &Tok, span: &Range<usize>) -> String {
    match tok {
        Tok::End => String::from("the end of the facts"),
        _ => format!("`{}`", text.get(span.clone()).unwrap_or("")),
    }
}

/// Parses the facts of one automaton.
pub fn parse(text: &str) -> Result<Facts, FactError> {
    let mut lex = Lexer { text, i: 0 };
    let mut facts = Facts::default();
    loop {
        let (tok, name) = lex.next()?;
        match tok {
            Tok::End => return Ok(facts),
            Tok::Atom => {}
            Tok::Var | Tok::Anon => return Err(variable(text, name)),
            _ => return Err(expected(text, "a fact such as `state(s0).`", &tok, name)),
        }
        let (tok, span) = lex.next()?;
        if tok != Tok::Open {
            return Err(expected(text, "`(`", &tok, span));
        }
        let mut args = Vec::new();
        loop {
            let (tok, span) = lex.next()?;
            match tok {
                Tok::Atom | Tok::Int | Tok::Anon => args.push(Arg { tok, span }),
                Tok::Var => return Err(variable(text, span)),
                _ => return Err(expected(text, "an atom, an integer or `_`", &tok, span)),
            }
            let (tok, span) = lex.next()?;
            match tok {
                Tok::Comma => {}
                Tok::Close => break,
                _ => return Err(expected(text, "`,` or `)`", &tok, span)),
            }
        }
        let (tok, span) = lex.next()?;
        if tok != Tok::Dot {
            return Err(expected(text, "`.` after the fact", &tok, span));
        }
        let whole = name.start..span.end;
        fact(text, &mut facts, name, whole, &args)?;
    }
}

fn variable(text: &str, span: Range<usize>) -> FactError {
    FactError {
        kind: FactErrorKind::Variable(text.get(span.clone()).unwrap_or("").to_string()),
        span,
    }
}

fn expected(text: &str, what: &'static str, tok: &Tok, span: Range<usize>) -> FactError {
    FactError {
        kind: FactErrorKind::Expected {
            expected: what,
            found: found(text, tok, &span),
        },
        span,
    }
}

/// Adds one fact `name(args)` spanning `whole`.
fn fact(
    text: &str,
    facts: &mut Facts,
    name: Range<usize>,
    whole: Range<usize>,
    args: &[Arg],
) -> Result<(), FactError> {
    let word = text.get(name.clone()).unwrap_or("");
    let arity = |name: &'static str, expected: &'static str| FactError {
        span: whole.clone(),
        kind: FactErrorKind::Arity {
            name,
            expected,
            found: args.len(),
        },
    };
    match word {
        "state" | "initial_state" => {
            let (fact, list) = if word == "state" {
                ("state/1", &mut facts.states)
            } else {
                ("initial_state/1", &mut facts.initial)
            };
            let [arg] = args else {
                return Err(arity(
                    if word == "state" {
                        "state"
                    } else {
                        "initial_state"
                    },
                    "1 argument (a state)",
                ));
            };
            list.push(atom(text, fact, 1, "a state (an atom)", arg)?);
            Ok(())
        }
        "transition" => {
            let [id, from, to, colour, max, kind] = args else {
                return Err(arity(
                    "transition",
                    "6 arguments (id, from, to, colour, max count or `_`, ordinary or final)",
                ));
            };
            const F: &str = "transition/6";
            let max_value = match max.tok {
                Tok::Anon => None,
                Tok::Int => {
                    let digits = text.get(max.span.clone()).unwrap_or("");
                    match digits.parse::<u32>() {
                        Ok(n) => Some(n),
                        Err(_) if digits.bytes().all(|b| b.is_ascii_digit()) => {
                            return Err(FactError {
                                span: max.span.clone(),
                                kind: FactErrorKind::TooLarge(digits.to_string()),
                            })
                        }
                        Err(_) => return Err(argument(text, F, 5, "a count or `_`", max)),
                    }
                }
                _ => return Err(argument(text, F, 5, "a count or `_`", max)),
            };
            let kind_atom = atom(text, F, 6, "`ordinary` or `final`", kind)?;
            let kind_value = match kind_atom.text.as_str() {
                "ordinary" => TransitionKind::Ordinary,
                "final" => TransitionKind::Final,
                _ => return Err(argument(text, F, 6, "`ordinary` or `final`", kind)),
            };
            facts.transitions.push(FactTransition {
                span: whole,
                id: atom(text, F, 1, "an id (an atom)", id)?,
                from: atom(text, F, 2, "a state (an atom)", from)?,
                to: atom(text, F, 3, "a state (an atom)", to)?,
                colour: atom(text, F, 4, "a colour (an atom)", colour)?,
                max: max_value,
                max_span: max.span.clone(),
                kind: kind_value,
            });
            Ok(())
        }
        "final_state" if args.len() == 1 => Err(FactError {
            span: whole,
            kind: FactErrorKind::FinalState,
        }),
        _ => Err(FactError {
            span: name,
            kind: FactErrorKind::Unknown {
                name: word.to_string(),
                arity: args.len(),
            },
        }),
    }
}

fn atom(
    text: &str,
    fact: &'static str,
    position: usize,
    expected: &'static str,
    arg: &Arg,
) -> Result<Atom, FactError> {
    if arg.tok != Tok::Atom {
        return Err(argument(text, fact, position, expected, arg));
    }
    Ok(Atom {
        text: text.get(arg.span.clone()).unwrap_or("").to_string(),
        span: arg.span.clone(),
    })
}

fn argument(
    text: &str,
    fact: &'static str,
    position: usize,
    expected: &'static str,
    arg: &Arg,
) -> FactError {
    FactError {
        span: arg.span.clone(),
        kind: FactErrorKind::Argument {
            fact,
            position,
            expected,
            found: found(text, &arg.tok, &arg.span),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fig. 1 of the paper, as the paper writes it.
    const FIG1: &str = "state(s0). state(s1).
transition(t1,s0,s1,black,_,ordinary).
transition(t2,s0,s0,orange,999,ordinary).
transition(t3,s1,s1,gray,2,ordinary).
transition(t4,s1,s0,black,_,final).
initial_state(s0).
";

    fn names(atoms: &[Atom]) -> Vec<&str> {
        atoms.iter().map(|a| a.text.as_str()).collect()
    }

    #[test]
    fn the_facts_of_fig_1_parse() {
        let facts = parse(FIG1).expect("parses");
        assert_eq!(names(&facts.states), ["s0", "s1"]);
        assert_eq!(names(&facts.initial), ["s0"]);
        let t: Vec<_> = facts
            .transitions
            .iter()
            .map(|t| {
                (
                    t.id.text.as_str(),
                    t.from.text.as_str(),
                    t.to.text.as_str(),
                    t.colour.text.as_str(),
                    t.max,
                    t.kind,
                )
            })
            .collect();
        use TransitionKind::*;
        assert_eq!(
            t,
            [
                ("t1", "s0", "s1", "black", None, Ordinary),
                ("t2", "s0", "s0", "orange", Some(999), Ordinary),
                ("t3", "s1", "s1", "gray", Some(2), Ordinary),
                ("t4", "s1", "s0", "black", None, Final),
            ]
        );
        let t2 = &facts.transitions[1];
        assert_eq!(
            &FIG1[t2.span.clone()],
            "transition(t2,s0,s0,orange,999,ordinary)."
        );
        assert_eq!(&FIG1[t2.max_span.clone()], "999");
    }

    #[test]
    fn comments_and_layout_are_skipped() {
        let facts = parse("% fig. 1\n  state( s0 ) .% s0\n\tinitial_state(s0).%").expect("ok");
        assert_eq!(names(&facts.states), ["s0"]);
        assert_eq!(names(&facts.initial), ["s0"]);
        assert_eq!(parse("").expect("empty"), Facts::default());
    }

    /// Each bad fact: the exact message and the exact text it points at.
    #[test]
    fn bad_facts_are_errors_at_their_place() {
        let cases: &[(&str, &str, &str)] = &[
            ("state(s0)", "expected `.` after the fact, found the end of the facts", ""),
            ("state(s0) state(s1).", "expected `.` after the fact, found `state`", "state"),
            ("state(S0).", "`S0` is a variable: a fact takes atoms, integers and `_`", "S0"),
            ("state(s0,s1).", "`state` takes 1 argument (a state), found 2 argument(s)", "state(s0,s1)."),
            ("transition(t1,s0,s1,black,_).", "`transition` takes 6 arguments (id, from, to, colour, max count or `_`, ordinary or final), found 5 argument(s)", "transition(t1,s0,s1,black,_)."),
            ("transition(t1,s0,s1,black,x,ordinary).", "argument 5 of `transition/6` must be a count or `_`, found `x`", "x"),
            ("transition(t1,s0,s1,black,_,fnal).", "argument 6 of `transition/6` must be `ordinary` or `final`, found `fnal`", "fnal"),
            ("transition(1,s0,s1,black,_,final).", "argument 1 of `transition/6` must be an id (an atom), found `1`", "1"),
            ("transition(t1,s0,s1,black,99999999999,final).", "the count `99999999999` is too large (at most 4294967295)", "99999999999"),
            ("transition(t1,s0,s1,black,2x,final).", "argument 5 of `transition/6` must be a count or `_`, found `2x`", "2x"),
            ("edge(s0,s1).", "unknown fact `edge/2`: the facts are state/1, transition/6 and initial_state/1", "edge"),
            ("final_state(s1).", "`final_state/1` is not a fact of a selecting automaton: its final transitions end sequences (`final` in transition/6)", "final_state(s1)."),
            ("state(s0).\nstate('s1').", "unexpected character `'` in the facts", "'"),
            ("state(é).", "unexpected character `é` in the facts", "é"),
            ("state().", "expected an atom, an integer or `_`, found `)`", ")"),
            ("(s0).", "expected a fact such as `state(s0).`, found `(`", "("),
            ("state s0.", "expected `(`, found `s0`", "s0"),
            ("state(s0 s1).", "expected `,` or `)`, found `s1`", "s1"),
        ];
        for (text, message, at) in cases {
            let e = parse(text).expect_err(text);
            assert_eq!(e.to_string(), *message, "{text}");
            assert_eq!(&text[e.span.clone()], *at, "{text}");
        }
    }

    proptest::proptest! {
        /// Any bytes: a result, never a panic, and an error's span inside the text.
        #[test]
        fn any_text_parses_or_fails_cleanly(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..200)) {
            let text = String::from_utf8_lossy(&bytes);
            if let Err(e) = parse(&text) {
                proptest::prop_assert!(e.span.start <= e.span.end && e.span.end <= text.len());
                proptest::prop_assert!(text.is_char_boundary(e.span.start) && text.is_char_boundary(e.span.end));
            }
        }

        /// Text made of the facts' own tokens, shuffled: the same.
        #[test]
        fn fact_like_text_parses_or_fails_cleanly(parts in proptest::collection::vec(
            proptest::sample::select(vec!["state", "transition", "initial_state", "(", ")", ",", ".", "_", "s0", "X", "12", "99999999999", "final", " ", "\n", "%c\n", "é"]), 0..60)) {
            let text: String = parts.concat();
            if let Err(e) = parse(&text) {
                proptest::prop_assert!(e.span.end <= text.len());
            }
        }
    }
}
