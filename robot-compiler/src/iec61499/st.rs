//! The Structured Text (IEC 61131-3) of basic FB algorithms and ECC transition
//! conditions, translated into the chart types' own expressions (`crate::expr`).
//!
//! Supported: assignments `NAME := expr;` (and empty statements); expressions with
//! integer and boolean literals (`42`, `16#FF`, `2#1010`, `8#17`, `UINT#5`, `1_000`,
//! `TRUE`, `FALSE`), names, parentheses, unary `-` and `NOT`, `* / MOD`, `+ -`,
//! `= <> < > <= >=`, `AND` / `&`, `XOR`, `OR`; comments `(* *)` and `//`. `NOT`, `AND`,
//! `XOR` and `OR` take BOOL operands (on integers they are bitwise in IEC 61131-3, which
//! the tables cannot compute). Integer arithmetic wraps at its type's width, as
//! IEC 61131-3 has it: an operation on SINT, INT, USINT or UINT values (a literal takes
//! the other side's type) is wrapped to 8 or 16 bits (`int(...)`, `uint(...)` in the
//! chart's expression), and so is a value assigned to a variable of a narrower type;
//! DINT and UDINT compute in 32 bits (UDINT exact below 2^31). `IF` / `ELSIF` / `ELSE`
//! and `CASE` become choices ([`Stmt::If`]); `FOR i := a TO b [BY c] DO ... END_FOR`
//! with constant bounds is unrolled (at most [`MAX_UNROLL`] iterations), `i` read as
//! its value in each. Refused with a message naming the construct: `**`, `WHILE`,
//! `REPEAT`, `EXIT`, `RETURN`, function calls, a FOR bound that is not a constant, and
//! anything else.
//!
//! Names are case-insensitive, as IEC 61131-3 has them: each resolves to its declared
//! spelling. Offsets in errors are byte offsets into the text given.

use std::ops::Range;

/// The type of a value: what the operators accept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ty {
    Bool,
    /// An integer of `bits` (8, 16 or 32), signed or not; a literal has no width yet.
    Int(Option<Width>),
}

/// An integer type's width.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Width {
    pub bits: u8,
    pub signed: bool,
}

impl Ty {
    /// The type of an IEC 61131-3 elementary type name, if the subset has it.
    pub fn of(name: &str) -> Option<Ty> {
        let w = |bits, signed| Some(Ty::Int(Some(Width { bits, signed })));
        match name.to_ascii_uppercase().as_str() {
            "BOOL" => Some(Ty::Bool),
            "SINT" => w(8, true),
            "INT" => w(16, true),
            "DINT" => w(32, true),
            "USINT" => w(8, false),
            "UINT" => w(16, false),
            "UDINT" => w(32, false),
            _ => None,
        }
    }

    fn is_int(self) -> bool {
        matches!(self, Ty::Int(_))
    }

    /// The type's IEC 61131-3 name (`ANY_INT` for a literal's, of no width yet).
    pub fn name(self) -> &'static str {
        match self {
            Ty::Bool => "BOOL",
            Ty::Int(None) => "ANY_INT",
            Ty::Int(Some(Width { bits, signed })) => match (bits, signed) {
                (8, true) => "SINT",
                (16, true) => "INT",
                (8, false) => "USINT",
                (16, false) => "UINT",
                (_, true) => "DINT",
                (_, false) => "UDINT",
            },
        }
    }
}

/// Whether a variable of type `to` holds every value of type `from` (a data connection
/// `from` -> `to` is then an implicit widening IEC 61131-3 allows: BOOL to BOOL, an
/// integer to one at least as wide of the same signedness or a wider signed one).
pub fn holds(to: Ty, from: Ty) -> bool {
    match (to, from) {
        (Ty::Bool, Ty::Bool) => true,
        (Ty::Int(Some(t)), Ty::Int(Some(f))) => match (t.signed, f.signed) {
            (true, true) | (false, false) => t.bits >= f.bits,
            (true, false) => t.bits > f.bits,
            (false, true) => false,
        },
        (Ty::Int(_), Ty::Int(None)) => true,
        (Ty::Int(None), Ty::Int(_)) => true,
        _ => false,
    }
}

/// `inner` (an integer operation of width `w`, unparenthesised) wrapped to `w` if it is
/// narrower than 32 bits, else in parentheses.
fn wrapped(inner: String, w: Option<Width>) -> String {
    match w {
        Some(w) if w.bits < 32 => {
            format!("{}({inner})", crate::expr::wrap_name(w.bits, w.signed))
        }
        _ => format!("({inner})"),
    }
}

/// Whether `text` is an integer literal within width `w`.
fn literal_fits(text: &str, w: Option<Width>) -> bool {
    let Ok(v) = text.parse::<i64>() else {
        return false;
    };
    match w {
        Some(Width { bits, signed: true }) if bits < 32 => {
            (-(1i64 << (bits - 1))..1i64 << (bits - 1)).contains(&v)
        }
        Some(Width {
            bits,
            signed: false,
        }) if bits < 32 => (0..1i64 << bits).contains(&v),
        _ => true,
    }
}

/// The width of an operation on `a` and `b`: the declared one (a literal takes the other
/// side's), the wider if both are declared and of one signedness, else the narrowest
/// signed one that holds both (SINT and USINT: INT; the same either way round).
fn join(a: Option<Width>, b: Option<Width>) -> Option<Width> {
    match (a, b) {
        (Some(x), Some(y)) if x.signed == y.signed => Some(if y.bits > x.bits { y } else { x }),
        (Some(x), Some(y)) => {
            let (signed, unsigned) = if x.signed { (x, y) } else { (y, x) };
            Some(Width {
                bits: signed.bits.max(unsigned.bits * 2).min(32),
                signed: true,
            })
        }
        (Some(x), None) => Some(x),
        (None, y) => y,
    }
}

/// The type of operand `(text, ty)` of an operation whose other operand is of width
/// `other`: a literal that `other` does not hold takes the narrowest type that holds it
/// (of `other`'s signedness if it can: `S * 1000`, S a SINT, is an INT product), as
/// IEC 61131-3 gives an untyped literal the type it needs.
fn literal_width(text: &str, ty: Ty, other: Option<Width>) -> Option<Width> {
    let Ty::Int(w) = ty else {
        return None;
    };
    let (Some(o), None, Ok(v)) = (other, w, text.parse::<i64>()) else {
        return w;
    };
    if literal_fits(text, other) {
        return w;
    }
    [8, 16, 32]
        .into_iter()
        .flat_map(|bits| {
            [
                Width {
                    bits,
                    signed: o.signed,
                },
                Width { bits, signed: true },
            ]
        })
        .find(|&c| (v >= 0 || c.signed) && literal_fits(&v.to_string(), Some(c)))
}

/// A name an algorithm or condition may use.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Name {
    /// As declared.
    pub name: String,
    pub ty: Ty,
    /// Whether an algorithm may assign it (output and internal variables).
    pub writable: bool,
}

/// A translation error at a byte span of the text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StError {
    pub message: String,
    pub span: Range<usize>,
}

fn err<T>(span: Range<usize>, message: impl Into<String>) -> Result<T, StError> {
    Err(StError {
        message: message.into(),
        span,
    })
}

#[derive(Debug, Clone, PartialEq, Eq)]
enum Tok {
    Int(i64),
    /// A typed integer literal (`SINT#100`): of that width, as a variable of it is.
    Typed(i64, Width),
    Word(String),
    Sym(&'static str),
    End,
}

const SYMS: [&str; 19] = [
    ":=", "<>", "<=", ">=", "**", "..", "<", ">", "=", "+", "-", "*", "/", "(", ")", ";", "&", ",",
    ":",
];

fn lex(text: &str) -> Result<Vec<(Tok, Range<usize>)>, StError> {
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        if c.is_ascii_whitespace() {
            i += 1;
            continue;
        }
        if text[i..].starts_with("(*") {
            let Some(end) = text[i + 2..].find("*)") else {
                return err(i..i + 2, "a comment `(*` that is never closed");
            };
            i += end + 4;
            continue;
        }
        if text[i..].starts_with("//") {
            i = text[i..].find('\n').map_or(bytes.len(), |n| i + n);
            continue;
        }
        if c.is_ascii_digit() {
            let start = i;
            while i < bytes.len()
                && (bytes[i].is_ascii_alphanumeric() || bytes[i] == b'_' || bytes[i] == b'#')
            {
                i += 1;
            }
            out.push((Tok::Int(number(&text[start..i], start..i)?), start..i));
            continue;
        }
        if c.is_ascii_alphabetic() || c == b'_' {
            let start = i;
            while i < bytes.len() && (bytes[i].is_ascii_alphanumeric() || bytes[i] == b'_') {
                i += 1;
            }
            // A typed literal: `UINT#5`, `DINT#-5`, `BOOL#TRUE`, `BOOL#0`.
            if i < bytes.len() && bytes[i] == b'#' {
                let name = &text[start..i];
                let Some(ty) = Ty::of(name) else {
                    return err(
                        start..i,
                        format!(
                            "`{name}#`: a typed literal is of BOOL, SINT, INT, DINT, USINT, \
                             UINT or UDINT"
                        ),
                    );
                };
                let neg = bytes.get(i + 1) == Some(&b'-');
                let at = i + 1 + usize::from(neg);
                let mut j = at;
                while j < bytes.len()
                    && (bytes[j].is_ascii_alphanumeric() || bytes[j] == b'_' || bytes[j] == b'#')
                {
                    j += 1;
                }
                let value = &text[at..j];
                let literal = &text[start..j];
                i = j;
                let tok = match (ty, value.to_ascii_uppercase().as_str(), neg) {
                    (Ty::Bool, "TRUE" | "1", false) => Tok::Word(String::from("TRUE")),
                    (Ty::Bool, "FALSE" | "0", false) => Tok::Word(String::from("FALSE")),
                    (Ty::Bool, _, _) => {
                        return err(
                            start..j,
                            format!("`{literal}`: BOOL# takes TRUE, FALSE, 1 or 0"),
                        )
                    }
                    (Ty::Int(w), _, _) => {
                        let magnitude = number(value, at..j)?;
                        let n = if neg { -magnitude } else { magnitude };
                        let unsigned = w.is_some_and(|w| !w.signed);
                        if !literal_fits(&n.to_string(), w) || (unsigned && n < 0) {
                            return err(start..j, format!("`{literal}` does not fit in {name}"));
                        }
                        match w {
                            Some(w) => Tok::Typed(n, w),
                            None => Tok::Int(n),
                        }
                    }
                };
                out.push((tok, start..j));
                continue;
            }
            out.push((Tok::Word(text[start..i].to_string()), start..i));
            continue;
        }
        match SYMS.iter().find(|s| text[i..].starts_with(**s)) {
            Some(s) => {
                out.push((Tok::Sym(s), i..i + s.len()));
                i += s.len();
            }
            None => {
                let ch = text[i..].chars().next().map_or(1, char::len_utf8);
                return err(i..i + ch, format!("unexpected `{}`", &text[i..i + ch]));
            }
        }
    }
    out.push((Tok::End, bytes.len()..bytes.len()));
    Ok(out)
}

/// The magnitude of `-2147483648`: a literal this large is only the operand of a `-`.
const MIN_MAGNITUDE: i64 = 1 << 31;

/// The error of literal `text` at `span`, past 32 bits.
fn too_big<T>(text: &str, span: Range<usize>) -> Result<T, StError> {
    err(
        span,
        format!(
            "`{}` does not fit 32 bits (the tables' integers)",
            short(text)
        ),
    )
}

/// An integer literal's magnitude (at most 2^31, for `-2147483648`): decimal, or `16#`,
/// `8#`, `2#`; `_` separates digits.
fn number(text: &str, span: Range<usize>) -> Result<i64, StError> {
    let digits: String = text.chars().filter(|&c| c != '_').collect();
    let (radix, body) = match digits.split_once('#') {
        Some(("16", b)) => (16, b.to_string()),
        Some(("8", b)) => (8, b.to_string()),
        Some(("2", b)) => (2, b.to_string()),
        Some(_) => return err(span, format!("`{}` is not an integer literal", short(text))),
        None => (10, digits.clone()),
    };
    match i64::from_str_radix(&body, radix) {
        Ok(v) if v <= MIN_MAGNITUDE => Ok(v),
        Ok(_) => too_big(text, span),
        Err(_) => err(span, format!("`{}` is not an integer literal", short(text))),
    }
}

/// Words that start a statement or construct the subset does not have.
const UNSUPPORTED: [&str; 4] = ["WHILE", "REPEAT", "EXIT", "RETURN"];

/// Words that end a statement list (of an `IF` arm, a `CASE` branch or a `FOR` body).
const ENDS: [&str; 6] = ["ELSIF", "ELSE", "END_IF", "END_CASE", "END_FOR", "THEN"];

/// A `FOR` loop is unrolled (its bounds are constants): at most this many iterations.
pub const MAX_UNROLL: i64 = 32;

/// One statement: an assignment in the chart types' syntax, or a choice.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Stmt {
    /// `variable := expression`.
    Assign(String, String),
    /// `IF` / `ELSIF` / `ELSE` (and `CASE`, as its conditions): the first arm whose
    /// condition holds runs, else `otherwise`.
    If {
        arms: Vec<(String, Vec<Stmt>)>,
        otherwise: Vec<Stmt>,
    },
}

struct Parser<'n> {
    toks: Vec<(Tok, Range<usize>)>,
    at: usize,
    names: &'n [Name],
    /// The control variables of the `FOR` loops being unrolled, each with its value in
    /// the iteration being read.
    unrolling: Vec<(String, i64)>,
    /// Parentheses, unary operators and statement bodies open at this point.
    nesting: usize,
    /// Where the outermost expression being read starts (a token index).
    expr_from: usize,
    /// Tokens read again so far by unrolled `FOR` loops.
    unrolled: usize,
}

/// The most tokens unrolled `FOR` loops may read again (nested loops unroll to the product
/// of their counts).
pub const MAX_UNROLLED: usize = 65_536;

/// The most parentheses, unary operators and `IF` / `CASE` / `FOR` bodies ST text may
/// nest: each level is a few frames of the parser's recursion.
pub const MAX_NESTING: usize = 64;

impl<'n> Parser<'n> {
    fn new(text: &str, names: &'n [Name]) -> Result<Parser<'n>, StError> {
        Ok(Parser {
            toks: lex(text)?,
            at: 0,
            names,
            unrolling: Vec::new(),
            nesting: 0,
            expr_from: 0,
            unrolled: 0,
        })
    }

    /// Reads one more level of nesting with `inner`, refused past [`MAX_NESTING`].
    fn nested<T>(
        &mut self,
        span: Range<usize>,
        inner: impl FnOnce(&mut Self) -> Result<T, StError>,
    ) -> Result<T, StError> {
        if self.nesting >= MAX_NESTING {
            return err(
                span,
                format!(
                    "parentheses, unary operators and statements nested more than \
                     {MAX_NESTING} deep"
                ),
            );
        }
        self.nesting += 1;
        let read = inner(self);
        self.nesting -= 1;
        read
    }

    fn peek(&self) -> &Tok {
        self.toks.get(self.at).map_or(&Tok::End, |(t, _)| t)
    }

    fn span(&self) -> Range<usize> {
        self.toks.get(self.at).map_or(0..0, |(_, s)| s.clone())
    }

    fn bump(&mut self) -> (Tok, Range<usize>) {
        let t = self.toks.get(self.at).cloned().unwrap_or((Tok::End, 0..0));
        self.at += 1;
        t
    }

    fn word(&self, w: &str) -> bool {
        matches!(self.peek(), Tok::Word(x) if x.eq_ignore_ascii_case(w))
    }

    fn sym(&self, s: &str) -> bool {
        matches!(self.peek(), Tok::Sym(x) if *x == s)
    }

    fn resolve(&self, word: &str, span: Range<usize>) -> Result<&Name, StError> {
        match self
            .names
            .iter()
            .find(|n| n.name.eq_ignore_ascii_case(word))
        {
            Some(n) => Ok(n),
            None => err(span, format!("unknown name `{word}`")),
        }
    }

    fn at_word(&self, words: &[&str]) -> bool {
        matches!(self.peek(), Tok::Word(w) if words.iter().any(|k| w.eq_ignore_ascii_case(k)))
    }

    fn expect_word(&mut self, word: &str) -> Result<(), StError> {
        if !self.word(word) {
            return err(self.span(), format!("expected `{word}`"));
        }
        self.bump();
        Ok(())
    }

    /// A `CASE` label starts here: an integer (or `-` integer) followed by `:`, `,` or
    /// `..`.
    fn at_label(&self) -> bool {
        let tok = |k: usize| self.toks.get(self.at + k).map(|(t, _)| t);
        let after = match (tok(0), tok(1)) {
            (Some(Tok::Sym("-")), Some(Tok::Int(_) | Tok::Typed(..))) => tok(2),
            (Some(Tok::Int(_) | Tok::Typed(..)), _) => tok(1),
            _ => return false,
        };
        matches!(after, Some(Tok::Sym(":" | "," | "..")))
    }

    /// Statements until the end of the text, or (`nested`) a word that ends a list or a
    /// `CASE` label.
    fn statements(&mut self, nested: bool) -> Result<Vec<Stmt>, StError> {
        let mut out = Vec::new();
        loop {
            if nested && (self.at_word(&ENDS) || self.at_label()) {
                return Ok(out);
            }
            match self.peek().clone() {
                Tok::End => return Ok(out),
                Tok::Sym(";") => {
                    self.bump();
                }
                Tok::Word(w) if w.eq_ignore_ascii_case("IF") => out.push(self.if_statement()?),
                Tok::Word(w) if w.eq_ignore_ascii_case("CASE") => out.push(self.case_statement()?),
                Tok::Word(w) if w.eq_ignore_ascii_case("FOR") => out.extend(self.for_statement()?),
                Tok::Word(w) if self.at_word(&ENDS) => {
                    return err(
                        self.span(),
                        format!("`{w}` without its `IF`, `CASE` or `FOR`"),
                    );
                }
                Tok::Word(w) => out.push(self.assignment(&w)?),
                _ => return err(self.span(), "expected a statement (`NAME := expression;`)"),
            }
        }
    }

    fn if_statement(&mut self) -> Result<Stmt, StError> {
        let mut arms = Vec::new();
        let mut otherwise = Vec::new();
        let if_span = self.span();
        self.bump(); // IF
        loop {
            let cond = self.bool_expr()?;
            self.expect_word("THEN")?;
            let body = self.nested(if_span.clone(), |p| p.statements(true))?;
            arms.push((cond, body));
            if self.word("ELSIF") {
                self.bump();
                continue;
            }
            if self.word("ELSE") {
                self.bump();
                otherwise = self.nested(if_span.clone(), |p| p.statements(true))?;
            }
            break;
        }
        self.expect_word("END_IF")?;
        Ok(Stmt::If { arms, otherwise })
    }

    fn case_statement(&mut self) -> Result<Stmt, StError> {
        let case_span = self.span();
        self.bump(); // CASE
        let span = self.span();
        let (selector, ty) = self.expr()?;
        if !ty.is_int() {
            return err(span, "CASE selects on an integer");
        }
        self.expect_word("OF")?;
        let mut arms = Vec::new();
        let mut otherwise = Vec::new();
        while self.at_label() {
            let mut alternatives = Vec::new();
            loop {
                let low = self.label()?;
                let alt = if self.sym("..") {
                    self.bump();
                    let high = self.label()?;
                    format!("(({selector} >= {low}) && ({selector} <= {high}))")
                } else {
                    format!("({selector} == {low})")
                };
                alternatives.push(alt);
                if !self.sym(",") {
                    break;
                }
                self.bump();
            }
            if !self.sym(":") {
                return err(self.span(), "expected `:` after the CASE labels");
            }
            self.bump();
            let cond = if alternatives.len() == 1 {
                alternatives.remove(0)
            } else {
                format!("({})", alternatives.join(" || "))
            };
            let body = self.nested(case_span.clone(), |p| p.statements(true))?;
            arms.push((cond, body));
        }
        if !self.at_word(&["ELSE", "END_CASE"]) {
            return err(
                self.span(),
                "a CASE label is an integer literal (or a range `a..b`)",
            );
        }
        if self.word("ELSE") {
            self.bump();
            otherwise = self.nested(case_span, |p| p.statements(true))?;
        }
        self.expect_word("END_CASE")?;
        if arms.is_empty() {
            return err(span, "a CASE without labels");
        }
        Ok(Stmt::If { arms, otherwise })
    }

    /// `FOR i := a TO b [BY c] DO ... END_FOR`, bounds and step constant: unrolled, the
    /// body read once per value of `i` with `i` that value (an integer of `i`'s type),
    /// then `i` assigned the value after the last (as the loop would leave it).
    fn for_statement(&mut self) -> Result<Vec<Stmt>, StError> {
        let for_span = self.span();
        self.bump(); // FOR
        let (name, span) = match self.bump() {
            (Tok::Word(w), span) => (w, span),
            (_, span) => return err(span, "expected the FOR loop's control variable"),
        };
        let var = self.resolve(&name, span.clone())?.clone();
        if !var.ty.is_int() || !var.writable {
            return err(
                span,
                format!(
                    "`{}` cannot count a FOR loop: it must be an integer output or internal \
                     variable",
                    var.name
                ),
            );
        }
        if self.unrolling.iter().any(|(n, _)| *n == var.name) {
            return err(
                span,
                format!("`{}` already counts an outer FOR loop", var.name),
            );
        }
        if !self.sym(":=") {
            return err(self.span(), format!("expected `:=` after `{name}`"));
        }
        self.bump();
        let from = self.constant("FOR loop's start")?;
        self.expect_word("TO")?;
        let to = self.constant("FOR loop's end")?;
        let by = if self.word("BY") {
            self.bump();
            let by_span = self.span();
            match self.constant("FOR loop's step")? {
                0 => return err(by_span, "a FOR loop's step is not 0"),
                by => by,
            }
        } else {
            1
        };
        self.expect_word("DO")?;
        let count = match (to - from).checked_div(by) {
            Some(n) if n >= 0 => n + 1,
            _ => 0,
        };
        if count > MAX_UNROLL {
            return err(
                for_span,
                format!("a FOR loop of {count} iterations (it is unrolled: at most {MAX_UNROLL})"),
            );
        }
        let body = self.at;
        let mut out = Vec::new();
        // An empty loop's body is still read (checked) once, and dropped.
        for k in 0..count.max(1) {
            self.at = body;
            self.unrolling.push((var.name.clone(), from + k * by));
            let stmts = self.nested(for_span.clone(), |p| p.statements(true));
            self.unrolling.pop();
            self.unrolled += self.at.saturating_sub(body);
            if self.unrolled > MAX_UNROLLED {
                return err(
                    for_span,
                    format!("FOR loops unrolled to more than {MAX_UNROLLED} tokens"),
                );
            }
            if k < count {
                out.extend(stmts?);
            } else {
                stmts?;
            }
        }
        self.expect_word("END_FOR")?;
        if self.sym(";") {
            self.bump();
        }
        // Past the last value: wrapped to 32 bits as the node's arithmetic wraps (a DINT
        // counted to its maximum), then to the variable's width.
        let after = i64::from((from + count * by) as i32);
        let after = match var.ty {
            Ty::Int(Some(w)) if !literal_fits(&after.to_string(), Some(w)) => {
                format!("{}({after})", crate::expr::wrap_name(w.bits, w.signed))
            }
            _ => after.to_string(),
        };
        out.push(Stmt::Assign(var.name.clone(), after));
        Ok(out)
    }

    /// An integer constant (a literal, or literals folded): a FOR loop's bound or step.
    fn constant(&mut self, what: &str) -> Result<i64, StError> {
        let span = self.span();
        let (v, ty) = self.expr()?;
        match (ty, v.parse::<i64>()) {
            (Ty::Int(_), Ok(v)) => Ok(v),
            _ => err(span, format!("the {what} must be an integer constant")),
        }
    }

    /// A `CASE` label: an integer literal, `-` allowed.
    fn label(&mut self) -> Result<i64, StError> {
        let neg = self.sym("-");
        if neg {
            self.bump();
        }
        match self.bump() {
            (Tok::Int(v), span) if v == MIN_MAGNITUDE && !neg => too_big(&v.to_string(), span),
            (Tok::Int(v), _) => Ok(if neg { -v } else { v }),
            (Tok::Typed(v, _), _) => Ok(if neg { -v } else { v }),
            (_, span) => err(span, "a CASE label is an integer literal"),
        }
    }

    fn bool_expr(&mut self) -> Result<String, StError> {
        let span = self.span();
        let (v, ty) = self.expr()?;
        if ty != Ty::Bool {
            return err(span, "a condition must be BOOL");
        }
        Ok(v)
    }

    fn assignment(&mut self, w: &str) -> Result<Stmt, StError> {
        let span = self.span();
        if let Some(kw) = UNSUPPORTED.iter().find(|k| w.eq_ignore_ascii_case(k)) {
            return err(
                span,
                format!("`{kw}` is not supported yet (the subset: assignments, IF, CASE, FOR with constant bounds)"),
            );
        }
        let target = self.resolve(w, span.clone())?.clone();
        if self.unrolling.iter().any(|(n, _)| *n == target.name) {
            return err(
                span,
                format!(
                    "`{}` counts the FOR loop: its body may not assign it",
                    target.name
                ),
            );
        }
        self.bump();
        if !self.sym(":=") {
            return err(self.span(), format!("expected `:=` after `{w}`"));
        }
        self.bump();
        if !target.writable {
            return err(
                span,
                format!(
                    "`{}` is an input variable: an algorithm may not assign it",
                    target.name
                ),
            );
        }
        let (value, ty) = self.expr()?;
        let value = match (target.ty, ty) {
            (Ty::Bool, Ty::Bool) => value,
            (Ty::Bool, Ty::Int(_)) => {
                return err(span, format!("`{}` is BOOL: assign it a BOOL", target.name))
            }
            (Ty::Int(_), Ty::Bool) => {
                return err(
                    span,
                    format!("`{}` is an integer: assign it an integer", target.name),
                )
            }
            // Already of the target's width, or wrapped to it here.
            (Ty::Int(to), Ty::Int(from)) if to == from => value,
            // A constant (a literal, or folded) the target holds.
            (Ty::Int(to), Ty::Int(_)) if literal_fits(&value, to) => value,
            (Ty::Int(to), Ty::Int(_)) => match to {
                Some(w) if w.bits < 32 => {
                    format!("{}({value})", crate::expr::wrap_name(w.bits, w.signed))
                }
                _ => value,
            },
        };
        if !self.sym(";") {
            return err(self.span(), "expected `;`");
        }
        self.bump();
        Ok(Stmt::Assign(target.name.clone(), value))
    }

    /// An expression of a statement (a parenthesised one inside it is read by `binary`).
    fn expr(&mut self) -> Result<(String, Ty), StError> {
        self.expr_from = self.at;
        self.binary(0)
    }

    /// Levels, loosest first: OR, XOR, AND, equality, relational, additive,
    /// multiplicative.
    fn binary(&mut self, level: usize) -> Result<(String, Ty), StError> {
        if level == 7 {
            return self.unary();
        }
        let mut left = self.binary(level + 1)?;
        loop {
            let span = self.span();
            let op = match (level, self.peek()) {
                (0, Tok::Word(w)) if w.eq_ignore_ascii_case("OR") => "||",
                (1, Tok::Word(w)) if w.eq_ignore_ascii_case("XOR") => "!=",
                (2, Tok::Word(w)) if w.eq_ignore_ascii_case("AND") => "&&",
                (2, Tok::Sym("&")) => "&&",
                (3, Tok::Sym("=")) => "==",
                (3, Tok::Sym("<>")) => "!=",
                (4, Tok::Sym("<")) => "<",
                (4, Tok::Sym(">")) => ">",
                (4, Tok::Sym("<=")) => "<=",
                (4, Tok::Sym(">=")) => ">=",
                (5, Tok::Sym("+")) => "+",
                (5, Tok::Sym("-")) => "-",
                (6, Tok::Sym("*")) => "*",
                (6, Tok::Sym("/")) => "/",
                (6, Tok::Word(w)) if w.eq_ignore_ascii_case("MOD") => "%",
                (6, Tok::Sym("**")) => {
                    return err(span, "`**` is not supported yet");
                }
                _ => return Ok(left),
            };
            if self.at.saturating_sub(self.expr_from) + 1 >= crate::expr::MAX_TOKENS {
                return err(
                    span,
                    format!(
                        "an expression of more than {} tokens",
                        crate::expr::MAX_TOKENS
                    ),
                );
            }
            self.bump();
            let right_at = self.span();
            let right = self.binary(level + 1)?;
            // A divisor of literals only that is 0 (folded to `0`): every evaluation faults
            // the node.
            if matches!(op, "/" | "%") && right.1 == Ty::Int(None) && right.0 == "0" {
                return err(
                    right_at,
                    "division by zero: this divisor is always 0 (a node evaluating it faults)",
                );
            }
            left = match (level, left.1, right.1) {
                (0..=2, Ty::Bool, Ty::Bool) => (format!("({} {op} {})", left.0, right.0), Ty::Bool),
                (0..=2, _, _) => {
                    return err(
                        span,
                        "AND, OR and XOR take BOOL operands here (on integers they are \
                         bitwise, which the tables cannot compute)",
                    )
                }
                (3, a, b) if a.is_int() == b.is_int() => {
                    (format!("({} {op} {})", left.0, right.0), Ty::Bool)
                }
                (4, Ty::Int(_), Ty::Int(_)) => (format!("({} {op} {})", left.0, right.0), Ty::Bool),
                (3 | 4, _, _) => return err(span, "a comparison of a BOOL with an integer"),
                (_, Ty::Int(None), Ty::Int(None)) if fold(&left.0, op, &right.0).is_some() => {
                    let v = fold(&left.0, op, &right.0).unwrap_or_default();
                    (v.to_string(), Ty::Int(None))
                }
                (_, Ty::Int(a), Ty::Int(b)) => {
                    let w = join(
                        literal_width(&left.0, left.1, b),
                        literal_width(&right.0, right.1, a),
                    );
                    // Constants of a type (`SINT#100 + SINT#100`): folded, wrapped to it.
                    match fold(&left.0, op, &right.0) {
                        Some(v) => (wrap_value(v, w).to_string(), Ty::Int(w)),
                        None => (
                            wrapped(format!("{} {op} {}", left.0, right.0), w),
                            Ty::Int(w),
                        ),
                    }
                }
                _ => return err(span, format!("`{}` takes integer operands", sym_name(op))),
            };
        }
    }

    fn unary(&mut self) -> Result<(String, Ty), StError> {
        let span = self.span();
        if self.sym("-") {
            self.bump();
            // -2147483648 is a 32-bit integer, though 2147483648 is not.
            if let Some((Tok::Int(MIN_MAGNITUDE), _)) = self.toks.get(self.at) {
                self.bump();
                return Ok((i32::MIN.to_string(), Ty::Int(None)));
            }
            let (v, ty) = self.nested(span.clone(), Self::unary)?;
            let Ty::Int(w) = ty else {
                return err(span, "unary `-` takes an integer");
            };
            // Folded as the tables compute it, wrapping: -(-2147483648) is -2147483648
            // (folded unwrapped it was 2147483648, which no table holds).
            if let (None, Some(n)) = (w, v.parse::<i64>().ok().and_then(|n| i32::try_from(n).ok()))
            {
                return Ok((n.wrapping_neg().to_string(), ty));
            }
            return Ok((wrapped(format!("-{v}"), w), ty));
        }
        if self.word("NOT") {
            self.bump();
            let (v, ty) = self.nested(span.clone(), Self::unary)?;
            if ty != Ty::Bool {
                return err(
                    span,
                    "NOT takes a BOOL here (on an integer it is bitwise, which the tables \
                     cannot compute)",
                );
            }
            return Ok((format!("(!{v})"), Ty::Bool));
        }
        self.primary()
    }

    fn primary(&mut self) -> Result<(String, Ty), StError> {
        let (tok, span) = self.bump();
        match tok {
            Tok::Int(v) if v == MIN_MAGNITUDE => too_big(&v.to_string(), span),
            Tok::Int(v) => Ok((v.to_string(), Ty::Int(None))),
            Tok::Typed(v, w) => Ok((v.to_string(), Ty::Int(Some(w)))),
            Tok::Word(w) if w.eq_ignore_ascii_case("TRUE") => Ok((String::from("true"), Ty::Bool)),
            Tok::Word(w) if w.eq_ignore_ascii_case("FALSE") => {
                Ok((String::from("false"), Ty::Bool))
            }
            Tok::Word(w) => {
                if self.sym("(") {
                    return err(
                        span,
                        format!("function calls (`{w}(...)`) are not supported"),
                    );
                }
                let n = self.resolve(&w, span)?;
                if let Some((_, k)) = self.unrolling.iter().find(|(v, _)| *v == n.name) {
                    return Ok((k.to_string(), n.ty));
                }
                Ok((n.name.clone(), n.ty))
            }
            Tok::Sym("(") => {
                let inner = self.nested(span, |p| p.binary(0))?;
                if !self.sym(")") {
                    return err(self.span(), "expected `)`");
                }
                self.bump();
                Ok(inner)
            }
            Tok::End => err(span, "expected an expression, found the end"),
            Tok::Sym(s) => err(span, format!("expected an expression, found `{s}`")),
        }
    }
}

/// `a op b` of two integer literals, computed (as 64-bit: a literal is of any width
/// until it meets a typed value); `None` if either is not a literal, or for a division by
/// zero (left to the node, which faults).
fn fold(a: &str, op: &str, b: &str) -> Option<i64> {
    let (a, b) = (a.parse::<i64>().ok()?, b.parse::<i64>().ok()?);
    let v = match op {
        "+" => a.checked_add(b)?,
        "-" => a.checked_sub(b)?,
        "*" => a.checked_mul(b)?,
        "/" => a.checked_div(b)?,
        "%" => a.checked_rem(b)?,
        _ => return None,
    };
    (i64::from(i32::MIN)..=i64::from(i32::MAX))
        .contains(&v)
        .then_some(v)
}

/// `v` wrapped to width `w` (two's complement), as a variable of it holds it.
fn wrap_value(v: i64, w: Option<Width>) -> i64 {
    match w {
        Some(Width { bits, signed }) if bits < 32 => {
            let m = 1i64 << bits;
            let u = v.rem_euclid(m);
            if signed && u >= m / 2 {
                u - m
            } else {
                u
            }
        }
        _ => v,
    }
}

/// An operator as ST writes it.
fn sym_name(op: &str) -> &str {
    if op == "%" {
        "MOD"
    } else {
        op
    }
}

/// An algorithm's statements, each expression in the chart types' syntax.
pub fn algorithm(text: &str, names: &[Name]) -> Result<Vec<Stmt>, StError> {
    let mut p = Parser::new(text, names)?;
    p.statements(false)
}

/// A BOOL expression (a transition's guard) in the chart types' syntax.
pub fn condition(text: &str, names: &[Name]) -> Result<String, StError> {
    let mut p = Parser::new(text, names)?;
    let span = p.span();
    let (v, ty) = p.expr()?;
    if !matches!(p.peek(), Tok::End) {
        return err(p.span(), "unexpected text after the condition");
    }
    if ty != Ty::Bool {
        return err(span, "a transition condition must be BOOL");
    }
    Ok(v)
}

/// `text` as an error message quotes it: at most 40 characters, then `...`.
fn short(text: &str) -> String {
    match text.char_indices().nth(40) {
        Some((cut, _)) => format!("{}...", &text[..cut]),
        None => text.to_string(),
    }
}

/// An initial value: an integer or boolean literal (`-` allowed), as the chart types'
/// syntax writes it.
pub fn literal(text: &str, ty: Ty) -> Result<String, StError> {
    let toks = lex(text)?;
    let (neg, rest) = match toks.first() {
        Some((Tok::Sym("-"), _)) => (true, &toks[1..]),
        _ => (false, &toks[..]),
    };
    let whole = 0..text.len();
    match (rest, ty) {
        ([(Tok::Int(v) | Tok::Typed(v, _), _), (Tok::End, _)], Ty::Int(w)) => {
            let v = if neg { -*v } else { *v };
            if v == MIN_MAGNITUDE {
                return too_big(text, whole);
            }
            if !literal_fits(&v.to_string(), w) {
                return err(
                    whole,
                    format!("`{}` is out of the variable's range", short(text)),
                );
            }
            Ok(v.to_string())
        }
        ([(Tok::Word(w), _), (Tok::End, _)], Ty::Bool)
            if !neg && w.eq_ignore_ascii_case("TRUE") =>
        {
            Ok(String::from("1"))
        }
        ([(Tok::Word(w), _), (Tok::End, _)], Ty::Bool)
            if !neg && w.eq_ignore_ascii_case("FALSE") =>
        {
            Ok(String::from("0"))
        }
        ([(Tok::Int(v @ (0 | 1)), _), (Tok::End, _)], Ty::Bool) if !neg => Ok(v.to_string()),
        _ => err(
            whole,
            format!("`{}` is not a literal of this variable's type", short(text)),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names() -> Vec<Name> {
        let n = |name: &str, ty, writable| Name {
            name: name.to_string(),
            ty,
            writable,
        };
        vec![
            n("CV", Ty::of("UINT").unwrap(), true),
            n("Q", Ty::Bool, true),
            n("PV", Ty::of("UINT").unwrap(), false),
            n("D", Ty::of("DINT").unwrap(), true),
            n("S", Ty::of("SINT").unwrap(), true),
            n("G", Ty::Bool, false),
        ]
    }

    /// The assignments of a choice-free algorithm.
    fn assigns(text: &str) -> Result<Vec<(String, String)>, StError> {
        Ok(algorithm(text, &names())?
            .into_iter()
            .map(|s| match s {
                Stmt::Assign(v, e) => (v, e),
                other => panic!("a choice: {other:?}"),
            })
            .collect())
    }

    /// -2147483648 is a DINT: written as a literal, a CASE label or an initial value it
    /// was refused (`2147483648` does not fit 32 bits, which only the magnitude alone does
    /// not).
    #[test]
    fn minus_2147483648_is_a_dint_and_2147483648_is_not() {
        let min = i32::MIN.to_string();
        assert_eq!(
            assigns("D := -2147483648;"),
            Ok(vec![("D".into(), min.clone())])
        );
        assert_eq!(
            assigns("D := - 2147483648;"),
            Ok(vec![("D".into(), min.clone())])
        );
        assert_eq!(
            assigns("D := -2147483647 - 1;"),
            Ok(vec![("D".into(), min.clone())])
        );
        assert!(algorithm("CASE D OF -2147483648: D := 1; END_CASE;", &names()).is_ok());
        // Negated again, it wraps as the tables compute (it folded to 2147483648).
        for text in [
            "D := -(-2147483648);",
            "D := - -2147483648;",
            "D := -(-2147483647 - 1);",
        ] {
            assert_eq!(assigns(text), Ok(vec![("D".into(), min.clone())]), "{text}");
        }
        let e = |text: &str| algorithm(text, &names()).unwrap_err();
        let big = "`2147483648` does not fit 32 bits (the tables' integers)";
        assert_eq!(e("D := 2147483648;").message, big);
        assert_eq!(e("D := 2147483648;").span, 5..15);
        assert_eq!(e("D := -(2147483648);").message, big);
        assert_eq!(e("CASE D OF 2147483648: D := 1; END_CASE;").message, big);
        let dint = Ty::of("DINT").unwrap();
        assert_eq!(literal("-2147483648", dint), Ok(min));
        assert_eq!(literal("2147483648", dint).unwrap_err().message, big);
    }

    /// Deep nesting and long expressions are refused at their place instead of running
    /// the parser out of stack.
    #[test]
    fn deep_nesting_and_long_expressions_are_refused_at_their_place() {
        let e = |text: &str| algorithm(text, &names()).unwrap_err();
        let nested = "parentheses, unary operators and statements nested more than 64 deep";
        let parens = |n: usize| format!("CV := {}1{};", "(".repeat(n), ")".repeat(n));
        assert_eq!(assigns(&parens(64)), Ok(vec![("CV".into(), "1".into())]));
        let deep = e(&parens(10_000));
        assert_eq!((deep.message.as_str(), deep.span), (nested, 70..71));
        let nots = format!("Q := {}G;", "NOT ".repeat(65));
        assert_eq!(e(&nots).span, 5 + 64 * 4..5 + 64 * 4 + 3);
        let ifs = |n: usize| format!("{}Q := G;{}", "IF G THEN ".repeat(n), " END_IF;".repeat(n));
        assert!(algorithm(&ifs(64), &names()).is_ok());
        let deep_ifs = e(&ifs(10_000));
        assert_eq!(
            (deep_ifs.message.as_str(), deep_ifs.span),
            (nested, 640..642)
        );
        let deep_case = e(&"CASE CV OF 1: ".repeat(10_000));
        assert_eq!(
            (deep_case.message.as_str(), deep_case.span),
            (nested, 896..900)
        );
        // Nested loops unroll to a product: their reading is bounded too.
        let fors = |vars: &[&str]| {
            let heads: String = vars
                .iter()
                .map(|v| format!("FOR {v} := 1 TO 32 DO "))
                .collect();
            format!("{heads}Q := G;{}", " END_FOR;".repeat(vars.len()))
        };
        assert!(algorithm(&fors(&["D", "CV"]), &names()).is_ok());
        let product = e(&fors(&["D", "CV", "S"]));
        assert_eq!(
            (product.message.as_str(), product.span),
            ("FOR loops unrolled to more than 65536 tokens", 0..3)
        );
        // 512 terms: 1,023 tokens after `:=`; 100,000 are refused at the 1,025th.
        let sum = |n: usize| format!("D := {};", vec!["D"; n].join(" + "));
        assert!(algorithm(&sum(512), &names()).is_ok());
        let long = e(&sum(100_000));
        assert_eq!(long.message, "an expression of more than 1024 tokens");
        assert_eq!(long.span.start, 5 + 512 * 4 - 2, "{long:?}");
    }

    #[test]
    fn assignments_translate_with_declared_spellings() {
        assert_eq!(
            assigns("cv := CV + 1;\n(* compare *) Q := (Cv >= pv); // done"),
            Ok(vec![
                ("CV".to_string(), "uint(CV + 1)".to_string()),
                ("Q".to_string(), "(CV >= PV)".to_string()),
            ])
        );
        assert_eq!(
            assigns("Q := NOT Q AND G XOR TRUE OR FALSE;;"),
            Ok(vec![(
                "Q".to_string(),
                "((((!Q) && G) != true) || false)".to_string()
            )])
        );
        assert_eq!(
            assigns("CV := 16#FF - UINT#2 - 1_000;"),
            Ok(vec![("CV".to_string(), "64789".to_string())])
        );
    }

    #[test]
    fn integer_arithmetic_wraps_at_its_types_width() {
        let one = |text: &str| assigns(text).map(|v| v[0].1.clone());
        // A literal takes the other side's type; an operation on UINT wraps to 16 bits.
        assert_eq!(
            one("CV := CV * 2 / 3 MOD 4;"),
            Ok("uint(uint(uint(CV * 2) / 3) % 4)".into())
        );
        // DINT computes in 32 bits: nothing to wrap.
        assert_eq!(one("D := D * 2 - 1;"), Ok("((D * 2) - 1)".into()));
        // Assigned to a narrower type: wrapped there; a literal in range is not.
        assert_eq!(one("S := D;"), Ok("sint(D)".into()));
        assert_eq!(one("S := -5;"), Ok("-5".into()));
        assert_eq!(
            one("S := 100 + 100;"),
            Ok("sint(200)".into()),
            "folded, then wrapped"
        );
        assert_eq!(one("S := 5;"), Ok("5".into()));
        assert_eq!(one("S := 300;"), Ok("sint(300)".into()));
        // Mixed widths compute in the wider; mixed signedness in the narrowest signed
        // type that holds both (SINT and UINT: DINT), whichever side each is on.
        assert_eq!(one("D := S + CV;"), Ok("(S + CV)".into()));
        assert_eq!(one("D := CV + S;"), Ok("(CV + S)".into()));
        assert_eq!(one("D := S + D;"), Ok("(S + D)".into()));
        // A typed literal is of its type: SINT#100 + SINT#100 wraps to -56.
        assert_eq!(one("D := SINT#100 + SINT#100;"), Ok("-56".into()));
        assert_eq!(one("D := SINT#100 + 100;"), Ok("-56".into()));
        // A literal the other side's type does not hold takes one that holds it: S * 1000
        // is an INT product (it was a SINT one, -48 for S = 2).
        assert_eq!(one("D := S * 1000;"), Ok("int(S * 1000)".into()));
        assert_eq!(one("D := S * 100;"), Ok("sint(S * 100)".into()));
    }

    #[test]
    fn conditions_are_bool() {
        assert_eq!(
            condition("CV < 65535", &names()),
            Ok("(CV < 65535)".to_string())
        );
        assert_eq!(
            condition("CV + 1", &names()),
            Err(StError {
                message: "a transition condition must be BOOL".to_string(),
                span: 0..2
            })
        );
    }

    #[test]
    fn what_the_subset_lacks_is_named_at_its_place() {
        let e = |text: &str| algorithm(text, &names()).unwrap_err();
        assert_eq!(
            e("WHILE G DO CV := 0; END_WHILE;"),
            StError {
                message: "`WHILE` is not supported yet (the subset: assignments, IF, CASE, FOR with constant bounds)"
                    .to_string(),
                span: 0..5
            }
        );
        assert_eq!(
            e("IF CV THEN Q := TRUE; END_IF;").message,
            "a condition must be BOOL"
        );
        assert_eq!(e("IF G THEN Q := TRUE;").message, "expected `END_IF`");
        assert_eq!(e("IF G Q := TRUE; END_IF;").message, "expected `THEN`");
        assert_eq!(
            e("END_IF;").message,
            "`END_IF` without its `IF`, `CASE` or `FOR`"
        );
        assert_eq!(
            e("CASE G OF 1: Q := TRUE; END_CASE;").message,
            "CASE selects on an integer"
        );
        assert_eq!(
            e("CASE CV OF Q: Q := TRUE; END_CASE;").message,
            "a CASE label is an integer literal (or a range `a..b`)"
        );
        assert_eq!(e("CASE CV OF END_CASE;").message, "a CASE without labels");
        assert_eq!(e("CV := CV ** 2;").span, 9..11);
        assert_eq!(e("CV := CV ** 2;").message, "`**` is not supported yet");
        assert_eq!(e("CV := G * 2;").message, "`*` takes integer operands");
        assert_eq!(
            e("Q := G = 2;").message,
            "a comparison of a BOOL with an integer"
        );
        assert_eq!(
            e("PV := 1;").message,
            "`PV` is an input variable: an algorithm may not assign it"
        );
        assert_eq!(e("X := 1;").message, "unknown name `X`");
        assert_eq!(e("Q := 1;").message, "`Q` is BOOL: assign it a BOOL");
        assert_eq!(e("CV := CV + 1").message, "expected `;`");
        assert_eq!(e("CV := CV AND 1;").span, 9..12);
        assert_eq!(e("(* open").message, "a comment `(*` that is never closed");
        assert_eq!(
            e("CV := 99999999999;").message,
            "`99999999999` does not fit 32 bits (the tables' integers)"
        );
        assert_eq!(
            e("CV := ABS(CV);").message,
            "function calls (`ABS(...)`) are not supported"
        );
        // A divisor of literals that is 0: refused at it (it faulted the node at run time).
        let zero = StError {
            message: "division by zero: this divisor is always 0 (a node evaluating it faults)"
                .to_string(),
            span: 11..12,
        };
        assert_eq!(e("CV := CV / 0;"), zero);
        assert_eq!(e("CV := CV MOD (2 - 2);").span, 13..14);
        assert!(algorithm("CV := CV / (3 - 2);", &names()).is_ok());
    }

    /// A typed CASE label, negative too (`-SINT#5`: typed literals lexed apart from plain
    /// ones were refused there).
    #[test]
    fn typed_case_labels_are_labels() {
        assert!(algorithm("CASE S OF -SINT#5: D := 1; END_CASE;", &names()).is_ok());
        assert!(algorithm("CASE S OF 1, -SINT#5, SINT#7: D := 1; END_CASE;", &names()).is_ok());
    }

    #[test]
    fn a_for_loop_with_constant_bounds_is_unrolled() {
        let a = |v: &str, e: &str| (v.to_string(), e.to_string());
        // The control variable reads as its value, of its type (DINT: no wrap), and is
        // left at the value after the last iteration.
        assert_eq!(
            assigns("FOR D := 1 TO 3 DO CV := CV + D; END_FOR; Q := TRUE;"),
            Ok(vec![
                a("CV", "uint((CV + 1))"),
                a("CV", "uint((CV + 2))"),
                a("CV", "uint((CV + 3))"),
                a("D", "4"),
                a("Q", "true"),
            ])
        );
        // A step, downwards; nested loops; the bounds folded from literals (and the
        // body's sums of constants).
        assert_eq!(
            assigns("FOR D := 2 * 3 TO 1 BY -3 DO FOR S := 0 TO 1 DO CV := D + S; END_FOR END_FOR"),
            Ok(vec![
                a("CV", "6"),
                a("CV", "7"),
                a("S", "2"),
                a("CV", "3"),
                a("CV", "4"),
                a("S", "2"),
                a("D", "0"),
            ])
        );
        // A bad initial value is quoted short.
        let long = "7".repeat(200_000);
        let e = literal(&long, Ty::Bool).unwrap_err();
        let quoted = format!("`{}...`", "7".repeat(40));
        assert_eq!(e.message, format!("{quoted} is not an integer literal"));
        let e = literal(&format!("X{long}"), Ty::Bool).unwrap_err();
        let quoted = format!("`X{}...`", "7".repeat(39));
        assert_eq!(
            e.message,
            format!("{quoted} is not a literal of this variable's type")
        );
        // Typed literals: of a type of the subset, within it.
        assert_eq!(
            assigns("D := DINT#-5; S := SINT#-128; CV := UINT#65535; Q := BOOL#1;"),
            Ok(vec![
                a("D", "-5"),
                a("S", "-128"),
                a("CV", "65535"),
                a("Q", "true")
            ])
        );
        let e = |text: &str| algorithm(text, &names()).unwrap_err();
        assert_eq!(
            e("CV := FOO#7;"),
            StError {
                message:
                    "`FOO#`: a typed literal is of BOOL, SINT, INT, DINT, USINT, UINT or UDINT"
                        .into(),
                span: 6..9
            }
        );
        assert_eq!(
            e("Q := BOOL#7;").message,
            "`BOOL#7`: BOOL# takes TRUE, FALSE, 1 or 0"
        );
        assert_eq!(
            e("CV := UINT#70000;").message,
            "`UINT#70000` does not fit in UINT"
        );
        assert_eq!(e("S := SINT#-129;").span, 5..14);
        assert_eq!(
            e("CV := UINT#-1;").message,
            "`UINT#-1` does not fit in UINT"
        );
        // Counted to the top of DINT: left past it, wrapped as the node's arithmetic wraps.
        assert_eq!(
            assigns("FOR D := 2147483600 TO 2147483647 BY 10 DO Q := TRUE; END_FOR;")
                .map(|a| a.last().cloned()),
            Ok(Some(a("D", "-2147483646")))
        );
        // No iteration: the body is checked and dropped; the variable gets the start.
        assert_eq!(
            assigns("FOR D := 5 TO 1 DO CV := 0; END_FOR;"),
            Ok(vec![a("D", "5")])
        );
        // A SINT left past its range wraps as the loop's increment would.
        assert_eq!(
            assigns("FOR S := 120 TO 127 BY 7 DO END_FOR;"),
            Ok(vec![a("S", "sint(134)")])
        );
        let e = |text: &str| algorithm(text, &names()).unwrap_err();
        assert_eq!(
            e("FOR D := 0 TO 32 DO CV := D; END_FOR;"),
            StError {
                message: "a FOR loop of 33 iterations (it is unrolled: at most 32)".into(),
                span: 0..3
            }
        );
        assert_eq!(
            e("FOR D := 0 TO CV DO END_FOR;"),
            StError {
                message: "the FOR loop's end must be an integer constant".into(),
                span: 14..16
            }
        );
        assert_eq!(
            e("FOR D := 0 TO 3 DO D := 1; END_FOR;").message,
            "`D` counts the FOR loop: its body may not assign it"
        );
        assert_eq!(
            e("FOR PV := 0 TO 3 DO END_FOR;").message,
            "`PV` cannot count a FOR loop: it must be an integer output or internal variable"
        );
        assert_eq!(
            e("FOR D := 0 TO 3 BY 0 DO END_FOR;").message,
            "a FOR loop's step is not 0"
        );
        assert_eq!(
            e("FOR D := 0 TO 3 DO CV := 1;").message,
            "expected `END_FOR`"
        );
        assert_eq!(
            e("FOR D := 0 TO 1 DO FOR D := 0 TO 1 DO END_FOR; END_FOR;").message,
            "`D` already counts an outer FOR loop"
        );
    }

    #[test]
    fn if_and_case_become_choices_in_order() {
        let a = |v: &str, e: &str| Stmt::Assign(v.to_string(), e.to_string());
        assert_eq!(
            algorithm(
                "IF CV > 3 THEN Q := TRUE; ELSIF G THEN Q := FALSE; CV := 0; ELSE CV := 1; \
                 END_IF; Q := NOT Q;",
                &names()
            ),
            Ok(vec![
                Stmt::If {
                    arms: vec![
                        ("(CV > 3)".to_string(), vec![a("Q", "true")]),
                        ("G".to_string(), vec![a("Q", "false"), a("CV", "0")]),
                    ],
                    otherwise: vec![a("CV", "1")],
                },
                a("Q", "(!Q)"),
            ])
        );
        assert_eq!(
            algorithm(
                "CASE CV OF 1: Q := TRUE; 2, 3: Q := FALSE; 4..6, -1: CV := 0; ELSE CV := 9; \
                 END_CASE",
                &names()
            ),
            Ok(vec![Stmt::If {
                arms: vec![
                    ("(CV == 1)".to_string(), vec![a("Q", "true")]),
                    (
                        "((CV == 2) || (CV == 3))".to_string(),
                        vec![a("Q", "false")]
                    ),
                    (
                        "(((CV >= 4) && (CV <= 6)) || (CV == -1))".to_string(),
                        vec![a("CV", "0")]
                    ),
                ],
                otherwise: vec![a("CV", "9")],
            }])
        );
    }

    #[test]
    fn literals_of_each_type() {
        assert_eq!(literal("TRUE", Ty::Bool), Ok("1".to_string()));
        assert_eq!(literal("0", Ty::Bool), Ok("0".to_string()));
        assert_eq!(literal("-5", Ty::of("INT").unwrap()), Ok("-5".to_string()));
        assert_eq!(
            literal("16#10", Ty::of("INT").unwrap()),
            Ok("16".to_string())
        );
        assert!(literal("2", Ty::Bool).is_err());
        assert!(literal("TRUE", Ty::of("INT").unwrap()).is_err());
    }
}
