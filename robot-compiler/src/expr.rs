//! Guard and assignment expressions: text -> AST -> `config_schema::Op` bytecode.
//!
//! ```text
//! expr  := or
//! or    := and ("||" and)*
//! and   := cmp ("&&" cmp)*
//! cmp   := sum (("==" | "!=" | "<" | "<=" | ">" | ">=") sum)?
//! sum   := prod (("+" | "-") prod)*
//! prod  := unary (("*" | "/" | "%") unary)*
//! unary := "!" unary | "-" unary | atom
//! atom  := INTEGER | "true" | "false" | WIDTH "(" expr ")" | NAME | "(" expr ")"
//! WIDTH := "sint" | "int" | "usint" | "uint"
//! ```
//! Names (letters, digits, `_`, `.`) are variables, inputs or chart parameters. Values
//! are 32-bit and wrap; `/` rounds toward zero and `%` takes the sign of its left side
//! (dividing by zero faults the node); `int(x)` wraps `x` to 16 bits as IEC 61131-3's INT
//! does (`sint`: 8 bits, `usint` and `uint` unsigned).

use std::ops::Range;

use config_schema::limits::MAX_STACK;
use config_schema::Op;

/// A syntax or name error at a byte span of the expression text.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct ExprError {
    pub message: String,
    pub span: Range<usize>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BinOp {
    Or,
    And,
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
    Add,
    Sub,
    Mul,
    Div,
    Rem,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Ast {
    Int(i32),
    Name(String, Range<usize>),
    Not(Box<Ast>),
    Neg(Box<Ast>),
    Bin(BinOp, Box<Ast>, Box<Ast>),
    /// `int(x)` and its kin: `x` wrapped to `bits`, sign-extended if `signed`.
    Wrap {
        bits: u8,
        signed: bool,
        of: Box<Ast>,
    },
}

impl Ast {
    /// This expression with each name `f` answers for replaced by its answer (the rest
    /// kept): how a condition's `F.P` places become reads of a chart's variable.
    pub fn map_names(&self, f: &dyn Fn(&str, &Range<usize>) -> Option<Ast>) -> Ast {
        let again = |a: &Ast| Box::new(a.map_names(f));
        match self {
            Ast::Name(n, span) => f(n, span).unwrap_or_else(|| self.clone()),
            Ast::Int(_) => self.clone(),
            Ast::Not(a) => Ast::Not(again(a)),
            Ast::Neg(a) => Ast::Neg(again(a)),
            Ast::Wrap { bits, signed, of } => Ast::Wrap {
                bits: *bits,
                signed: *signed,
                of: again(of),
            },
            Ast::Bin(op, a, b) => Ast::Bin(*op, again(a), again(b)),
        }
    }
}

/// The integer widths an expression may wrap to: (name, bits, signed).
pub const WIDTHS: [(&str, u8, bool); 4] = [
    ("sint", 8, true),
    ("int", 16, true),
    ("usint", 8, false),
    ("uint", 16, false),
];

/// The name of a width (`int` for 16 bits signed).
pub fn wrap_name(bits: u8, signed: bool) -> &'static str {
    WIDTHS
        .iter()
        .find(|(_, b, s)| *b == bits && *s == signed)
        .map_or("wrap", |(n, _, _)| n)
}

/// The most tokens an expression may have. Every value in a node's expression is an
/// operation of its code (at most `MAX_EXPR_LEN`), so this refuses nothing a table can
/// hold; it bounds the tree's height, so that the walks over it (checks, bytecode, drop)
/// cannot run out of stack on a long chain such as `a && b && ...`.
pub const MAX_TOKENS: usize = 1024;

/// The most parentheses, widths and unary operators an expression may nest: each level is
/// a few frames of the parser's recursion.
pub const MAX_NESTING: usize = 64;

#[derive(Debug, Clone, PartialEq, Eq)]
enum Tok {
    Int(i32),
    /// 2147483648 (2^31): only the operand of a unary minus, which makes it `i32::MIN`.
    MinMagnitude,
    Name(String),
    Sym(&'static str),
    End,
}

/// The error of integer `digits` at `span`, past 32 bits.
fn too_big(digits: &str, span: Range<usize>) -> ExprError {
    ExprError {
        message: format!("integer `{digits}` does not fit in 32 bits"),
        span,
    }
}

fn lex(text: &str) -> Result<Vec<(Tok, Range<usize>)>, ExprError> {
    const SYMS: [&str; 17] = [
        "&&", "||", "==", "!=", "<=", ">=", "<", ">", "!", "+", "-", "*", "/", "%", "(", ")", "=",
    ];
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if out.len() == MAX_TOKENS && !c.is_ascii_whitespace() {
            return Err(ExprError {
                message: format!("an expression of more than {MAX_TOKENS} tokens"),
                span: i..i + 1,
            });
        }
        if c.is_ascii_whitespace() {
            i += 1;
        } else if c.is_ascii_digit() {
            let start = i;
            while i < b.len() && b[i].is_ascii_digit() {
                i += 1;
            }
            let tok = match text[start..i].parse::<u32>() {
                Ok(n) if n <= i32::MAX as u32 => Tok::Int(n as i32),
                Ok(n) if n == 1 << 31 => Tok::MinMagnitude,
                _ => return Err(too_big(&text[start..i], start..i)),
            };
            out.push((tok, start..i));
        } else if c.is_ascii_alphabetic() || c == b'_' {
            let start = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_' || b[i] == b'.') {
                i += 1;
            }
            out.push((Tok::Name(text[start..i].to_string()), start..i));
        } else if let Some(sym) = SYMS.iter().find(|s| text[i..].starts_with(**s)) {
            if *sym == "=" {
                return Err(ExprError {
                    message: String::from("`=` is not an operator: write `==` to compare"),
                    span: i..i + 1,
                });
            }
            out.push((Tok::Sym(sym), i..i + sym.len()));
            i += sym.len();
        } else {
            let ch = text[i..].chars().next().unwrap_or('?');
            return Err(ExprError {
                message: format!("unexpected character `{ch}`"),
                span: i..i + ch.len_utf8(),
            });
        }
    }
    out.push((Tok::End, text.len()..text.len()));
    Ok(out)
}

struct Parser {
    toks: Vec<(Tok, Range<usize>)>,
    at: usize,
    /// Parentheses, widths and unary operators open at this point.
    nesting: usize,
}

impl Parser {
    fn peek(&self) -> &Tok {
        &self.toks[self.at.min(self.toks.len() - 1)].0
    }

    fn span(&self) -> Range<usize> {
        self.toks[self.at.min(self.toks.len() - 1)].1.clone()
    }

    fn eat(&mut self, sym: &'static str) -> bool {
        if *self.peek() == Tok::Sym(sym) {
            self.at += 1;
            true
        } else {
            false
        }
    }

    /// Parses one more level of nesting with `inner`, refused past [`MAX_NESTING`].
    fn nested<T>(
        &mut self,
        span: Range<usize>,
        inner: impl FnOnce(&mut Parser) -> Result<T, ExprError>,
    ) -> Result<T, ExprError> {
        if self.nesting >= MAX_NESTING {
            return Err(ExprError {
                message: format!(
                    "parentheses, widths and unary operators nested more than {MAX_NESTING} deep"
                ),
                span,
            });
        }
        self.nesting += 1;
        let parsed = inner(self);
        self.nesting -= 1;
        parsed
    }

    fn unexpected(&self, wanted: &str) -> ExprError {
        let found = match self.peek() {
            Tok::Int(n) => format!("`{n}`"),
            Tok::MinMagnitude => String::from("`2147483648`"),
            Tok::Name(n) => format!("`{n}`"),
            Tok::Sym(s) => format!("`{s}`"),
            Tok::End => String::from("the end of the expression"),
        };
        let mut span = self.span();
        if span.is_empty() {
            span = span.start.saturating_sub(1)..span.start;
        }
        ExprError {
            message: format!("expected {wanted}, found {found}"),
            span,
        }
    }

    fn binary(
        &mut self,
        ops: &[(&'static str, BinOp)],
        next: fn(&mut Parser) -> Result<Ast, ExprError>,
        chain: bool,
    ) -> Result<Ast, ExprError> {
        let mut left = next(self)?;
        loop {
            let Some(&(_, op)) = ops.iter().find(|(s, _)| self.eat(s)) else {
                return Ok(left);
            };
            let start = self.span().start;
            let right = next(self)?;
            // A divisor of literals only that is 0: every evaluation faults the node.
            if matches!(op, BinOp::Div | BinOp::Rem) && eval(&right, &|_| None) == Some(0) {
                let end = (self.at.checked_sub(1))
                    .and_then(|i| self.toks.get(i))
                    .map_or(start, |t| t.1.end);
                return Err(ExprError {
                    message: String::from(
                        "division by zero: this divisor is always 0 (a node evaluating it \
                         faults)",
                    ),
                    span: start..end.max(start),
                });
            }
            left = Ast::Bin(op, Box::new(left), Box::new(right));
            if !chain {
                if ops.iter().any(|(s, _)| *self.peek() == Tok::Sym(s)) {
                    return Err(ExprError {
                        message: String::from(
                            "comparisons do not chain: use `&&` between two comparisons",
                        ),
                        span: self.span(),
                    });
                }
                return Ok(left);
            }
        }
    }

    fn or(&mut self) -> Result<Ast, ExprError> {
        self.binary(&[("||", BinOp::Or)], Parser::and, true)
    }

    fn and(&mut self) -> Result<Ast, ExprError> {
        self.binary(&[("&&", BinOp::And)], Parser::cmp, true)
    }

    fn cmp(&mut self) -> Result<Ast, ExprError> {
        self.binary(
            &[
                ("==", BinOp::Eq),
                ("!=", BinOp::Ne),
                ("<=", BinOp::Le),
                (">=", BinOp::Ge),
                ("<", BinOp::Lt),
                (">", BinOp::Gt),
            ],
            Parser::sum,
            false,
        )
    }

    fn sum(&mut self) -> Result<Ast, ExprError> {
        self.binary(&[("+", BinOp::Add), ("-", BinOp::Sub)], Parser::prod, true)
    }

    fn prod(&mut self) -> Result<Ast, ExprError> {
        self.binary(
            &[("*", BinOp::Mul), ("/", BinOp::Div), ("%", BinOp::Rem)],
            Parser::unary,
            true,
        )
    }

    fn unary(&mut self) -> Result<Ast, ExprError> {
        let span = self.span();
        if self.eat("!") {
            let of = self.nested(span, Parser::unary)?;
            return Ok(Ast::Not(Box::new(of)));
        }
        if self.eat("-") {
            // -2147483648 is a 32-bit integer, though 2147483648 is not.
            if *self.peek() == Tok::MinMagnitude {
                self.at += 1;
                return Ok(Ast::Int(i32::MIN));
            }
            let of = self.nested(span, Parser::unary)?;
            return Ok(Ast::Neg(Box::new(of)));
        }
        self.atom()
    }

    fn atom(&mut self) -> Result<Ast, ExprError> {
        let span = self.span();
        match self.peek().clone() {
            Tok::Int(n) => {
                self.at += 1;
                Ok(Ast::Int(n))
            }
            Tok::MinMagnitude => Err(too_big("2147483648", span)),
            Tok::Name(n) if n == "true" => {
                self.at += 1;
                Ok(Ast::Int(1))
            }
            Tok::Name(n) if n == "false" => {
                self.at += 1;
                Ok(Ast::Int(0))
            }
            Tok::Name(n) => {
                self.at += 1;
                if let Some(&(_, bits, signed)) = WIDTHS.iter().find(|(w, _, _)| *w == n) {
                    if self.eat("(") {
                        let of = self.nested(span, Parser::or)?;
                        if !self.eat(")") {
                            return Err(self.unexpected("`)`"));
                        }
                        return Ok(Ast::Wrap {
                            bits,
                            signed,
                            of: Box::new(of),
                        });
                    }
                }
                Ok(Ast::Name(n, span))
            }
            Tok::Sym("(") => {
                self.at += 1;
                let inner = self.nested(span, Parser::or)?;
                if !self.eat(")") {
                    return Err(self.unexpected("`)`"));
                }
                Ok(inner)
            }
            _ => Err(self.unexpected("a value, a name or `(`")),
        }
    }
}

/// Parses expression text.
pub fn parse(text: &str) -> Result<Ast, ExprError> {
    let toks = lex(text)?;
    let mut p = Parser {
        toks,
        at: 0,
        nesting: 0,
    };
    if *p.peek() == Tok::End {
        return Err(ExprError {
            message: String::from("empty expression"),
            span: 0..0,
        });
    }
    let ast = p.or()?;
    if *p.peek() != Tok::End {
        return Err(p.unexpected("an operator or the end of the expression"));
    }
    Ok(ast)
}

/// What a name stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Operand {
    Var(u8),
    Input(u8),
    Const(i32),
}

/// Compiles an AST to bytecode; `resolve` gives the meaning of each name.
pub fn bytecode(
    ast: &Ast,
    resolve: &dyn Fn(&str) -> Option<Operand>,
) -> Result<Vec<Op>, ExprError> {
    let mut ops = Vec::new();
    emit(ast, resolve, &mut ops)?;
    let deepest = deepest(&ops);
    if deepest > MAX_STACK {
        // A node refuses the table (`config_schema::guard::check`): said here, at the
        // expression's start, and not as a table that does not validate.
        return Err(ExprError {
            message: format!(
                "this expression needs {deepest} values on the stack at once, a node \
                 evaluates on {MAX_STACK}: nest it to the left (`(a + b) + c` needs 2, \
                 `a + (b + c)` 3) or name a part of it in a variable"
            ),
            span: 0..0,
        });
    }
    Ok(ops)
}

/// The most values `ops` hold on the stack at once (0 for ops that underflow it, which
/// `emit` never writes).
fn deepest(ops: &[Op]) -> usize {
    let mut depth = 0usize;
    let mut most = 0;
    for op in ops {
        let (pop, push) = op.stack_effect();
        depth = depth.saturating_sub(pop) + push;
        most = most.max(depth);
    }
    most
}

fn emit(
    ast: &Ast,
    resolve: &dyn Fn(&str) -> Option<Operand>,
    ops: &mut Vec<Op>,
) -> Result<(), ExprError> {
    match ast {
        Ast::Int(n) => ops.push(Op::Const(*n)),
        Ast::Name(n, span) => ops.push(match resolve(n) {
            Some(Operand::Var(v)) => Op::Var(v),
            Some(Operand::Input(i)) => Op::Input(i),
            Some(Operand::Const(c)) => Op::Const(c),
            None => {
                return Err(ExprError {
                    message: format!(
                        "unknown name `{n}`: not a variable, input or parameter of this chart"
                    ),
                    span: span.clone(),
                })
            }
        }),
        Ast::Not(a) => {
            emit(a, resolve, ops)?;
            ops.push(Op::Not);
        }
        Ast::Neg(a) => {
            ops.push(Op::Const(0));
            emit(a, resolve, ops)?;
            ops.push(Op::Sub);
        }
        Ast::Bin(op, a, b) => {
            emit(a, resolve, ops)?;
            emit(b, resolve, ops)?;
            ops.push(match op {
                BinOp::Or => Op::Or,
                BinOp::And => Op::And,
                BinOp::Eq => Op::Eq,
                BinOp::Ne => Op::Ne,
                BinOp::Lt => Op::Lt,
                BinOp::Le => Op::Le,
                BinOp::Gt => Op::Gt,
                BinOp::Ge => Op::Ge,
                BinOp::Add => Op::Add,
                BinOp::Sub => Op::Sub,
                BinOp::Mul => Op::Mul,
                BinOp::Div => Op::Div,
                BinOp::Rem => Op::Rem,
            });
        }
        Ast::Wrap { bits, signed, of } => {
            emit(of, resolve, ops)?;
            ops.push(Op::Wrap {
                bits: *bits,
                signed: *signed,
            });
        }
    }
    Ok(())
}

/// Evaluates an AST with `value` giving each name's value (`None`: unknown name).
pub fn eval(ast: &Ast, value: &dyn Fn(&str) -> Option<i32>) -> Option<i32> {
    Some(match ast {
        Ast::Int(n) => *n,
        Ast::Name(n, _) => value(n)?,
        Ast::Not(a) => i32::from(eval(a, value)? == 0),
        Ast::Neg(a) => 0i32.wrapping_sub(eval(a, value)?),
        Ast::Bin(op, a, b) => {
            let (a, b) = (eval(a, value)?, eval(b, value)?);
            match op {
                BinOp::Or => i32::from(a != 0 || b != 0),
                BinOp::And => i32::from(a != 0 && b != 0),
                BinOp::Eq => i32::from(a == b),
                BinOp::Ne => i32::from(a != b),
                BinOp::Lt => i32::from(a < b),
                BinOp::Le => i32::from(a <= b),
                BinOp::Gt => i32::from(a > b),
                BinOp::Ge => i32::from(a >= b),
                BinOp::Add => a.wrapping_add(b),
                BinOp::Sub => a.wrapping_sub(b),
                BinOp::Mul => a.wrapping_mul(b),
                BinOp::Div => a.checked_div(b).or((b != 0).then_some(i32::MIN))?,
                BinOp::Rem => a.checked_rem(b).or((b != 0).then_some(0))?,
            }
        }
        Ast::Wrap { bits, signed, of } => {
            config_schema::guard::wrap(eval(of, value)?, *bits, *signed)
        }
    })
}

/// Every name an AST reads, in order of first use.
pub fn names(ast: &Ast, out: &mut Vec<String>) {
    let mut seen: std::collections::BTreeSet<String> = out.iter().cloned().collect();
    collect_names(ast, &mut seen, out);
}

fn collect_names(ast: &Ast, seen: &mut std::collections::BTreeSet<String>, out: &mut Vec<String>) {
    match ast {
        Ast::Int(_) => {}
        Ast::Name(n, _) => {
            if seen.insert(n.clone()) {
                out.push(n.clone());
            }
        }
        Ast::Not(a) | Ast::Neg(a) | Ast::Wrap { of: a, .. } => collect_names(a, seen, out),
        Ast::Bin(_, a, b) => {
            collect_names(a, seen, out);
            collect_names(b, seen, out);
        }
    }
}

fn constants(ast: &Ast, out: &mut Vec<i32>) {
    match ast {
        Ast::Int(n) => out.push(*n),
        Ast::Name(..) => {}
        Ast::Not(a) | Ast::Neg(a) | Ast::Wrap { of: a, .. } => constants(a, out),
        Ast::Bin(_, a, b) => {
            constants(a, out);
            constants(b, out);
        }
    }
}

/// Whether two guards can both be true for some values of their names: tried over the
/// constants they mention, their neighbours, 0 and 1 (exhaustive for up to 4 names).
/// `fixed` gives the names whose value is known (parameters).
pub fn may_overlap(a: &Ast, b: &Ast, fixed: &dyn Fn(&str) -> Option<i32>) -> bool {
    let mut free = Vec::new();
    names(a, &mut free);
    names(b, &mut free);
    free.retain(|n| fixed(n).is_none());
    let mut consts = vec![0, 1];
    constants(a, &mut consts);
    constants(b, &mut consts);
    let mut candidates: Vec<i32> = Vec::new();
    for c in consts
        .iter()
        .chain([fixed_values(a, b, fixed)].iter().flatten())
    {
        for d in [-1, 0, 1] {
            let v = c.wrapping_add(d);
            if !candidates.contains(&v) {
                candidates.push(v);
            }
        }
    }
    if free.len() > 4 {
        return true;
    }
    let mut idx = vec![0usize; free.len()];
    loop {
        let value = |n: &str| {
            fixed(n).or_else(|| free.iter().position(|f| f == n).map(|i| candidates[idx[i]]))
        };
        if eval(a, &value).is_some_and(|v| v != 0) && eval(b, &value).is_some_and(|v| v != 0) {
            return true;
        }
        // Next combination.
        let mut k = 0;
        loop {
            if k == idx.len() {
                return false;
            }
            idx[k] += 1;
            if idx[k] < candidates.len() {
                break;
            }
            idx[k] = 0;
            k += 1;
        }
    }
}

fn fixed_values(a: &Ast, b: &Ast, fixed: &dyn Fn(&str) -> Option<i32>) -> Vec<i32> {
    let mut all = Vec::new();
    names(a, &mut all);
    names(b, &mut all);
    all.iter().filter_map(|n| fixed(n)).collect()
}
