//! A chart expression ([`crate::expr::Ast`]) as Structured Text: every operation in
//! parentheses, so the `.fbt` import parses back the same tree (and the same bytecode).
//! Integers are DINT; a BOOL-valued name (an input level) is BOOL.

use crate::expr::{Ast, BinOp};

/// The type of an ST value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Bool,
    Int,
}

/// How a name of the expression is written in ST, and its type.
pub type Names<'a> = &'a dyn Fn(&str) -> Option<(String, Kind)>;

/// `ast` as an ST value of kind `want`. An integer where ST needs a BOOL is compared
/// with 0 (the same truth value); the reverse, and a wrap to a narrower width (which ST
/// writes as a narrower variable's type, not an operator), have no ST form here.
pub fn st(ast: &Ast, want: Kind, names: Names<'_>) -> Result<String, String> {
    // `true` and `false` (1 and 0 in the tables) where ST needs a BOOL: its literals, which
    // the import reads back as 1 and 0 (as `(1 <> 0)` it read back a comparison).
    match (ast, want) {
        (Ast::Int(1), Kind::Bool) => return Ok(String::from("TRUE")),
        (Ast::Int(0), Kind::Bool) => return Ok(String::from("FALSE")),
        _ => {}
    }
    let (text, kind) = value(ast, names)?;
    coerce(text, kind, want)
}

fn coerce(text: String, kind: Kind, want: Kind) -> Result<String, String> {
    match (kind, want) {
        (Kind::Int, Kind::Bool) => Ok(format!("({text} <> 0)")),
        (Kind::Bool, Kind::Int) => Err(format!(
            "`{text}` is a BOOL where ST needs an integer (the tables compute 0 / 1; ST has \
             no implicit conversion)"
        )),
        _ => Ok(text),
    }
}

fn value(ast: &Ast, names: Names<'_>) -> Result<(String, Kind), String> {
    Ok(match ast {
        // In parentheses: a `-` before it (`Neg`) makes `-(-5)`, not `--5` (ST takes one
        // unary operator).
        Ast::Int(n) if *n < 0 => (format!("(-{})", n.unsigned_abs()), Kind::Int),
        Ast::Int(n) => (n.to_string(), Kind::Int),
        Ast::Name(n, _) => names(n).ok_or_else(|| format!("unknown name `{n}`"))?,
        Ast::Not(a) => match value(a, names)? {
            (t, Kind::Bool) => (format!("(NOT {t})"), Kind::Bool),
            (t, Kind::Int) => (format!("({t} = 0)"), Kind::Bool),
        },
        Ast::Neg(a) => (format!("(-{})", st(a, Kind::Int, names)?), Kind::Int),
        Ast::Bin(op @ (BinOp::Or | BinOp::And), a, b) => {
            let word = if *op == BinOp::Or { "OR" } else { "AND" };
            let (a, b) = (st(a, Kind::Bool, names)?, st(b, Kind::Bool, names)?);
            (format!("({a} {word} {b})"), Kind::Bool)
        }
        Ast::Bin(op, a, b) => {
            let (sym, kind) = match op {
                BinOp::Eq => ("=", Kind::Bool),
                BinOp::Ne => ("<>", Kind::Bool),
                BinOp::Lt => ("<", Kind::Bool),
                BinOp::Le => ("<=", Kind::Bool),
                BinOp::Gt => (">", Kind::Bool),
                BinOp::Ge => (">=", Kind::Bool),
                BinOp::Add => ("+", Kind::Int),
                BinOp::Sub => ("-", Kind::Int),
                BinOp::Mul => ("*", Kind::Int),
                BinOp::Div => ("/", Kind::Int),
                BinOp::Rem => ("MOD", Kind::Int),
                // Matched by the arm above.
                BinOp::Or | BinOp::And => ("OR", Kind::Bool),
            };
            let (ta, ka) = value(a, names)?;
            let (tb, kb) = value(b, names)?;
            let same_bools = ka == Kind::Bool && kb == Kind::Bool && kind == Kind::Bool;
            let (ta, tb) = if same_bools && matches!(op, BinOp::Eq | BinOp::Ne) {
                (ta, tb)
            } else {
                (coerce(ta, ka, Kind::Int)?, coerce(tb, kb, Kind::Int)?)
            };
            (format!("({ta} {sym} {tb})"), kind)
        }
        Ast::Wrap { bits, signed, .. } => {
            return Err(format!(
                "`{}(...)` wraps to {bits} bits: ST has no such operator (declare a variable \
                 of that type instead)",
                crate::expr::wrap_name(*bits, *signed)
            ))
        }
    })
}

/// The expression a chart's bytecode computes, as an AST (names from `name_of`: a
/// variable or an input); `None` if the bytecode is not a well-formed expression.
pub fn decompile(
    ops: &[config_schema::Op],
    var: &dyn Fn(u8) -> String,
    input: &dyn Fn(u8) -> String,
) -> Option<Ast> {
    use config_schema::Op;
    let mut stack: Vec<Ast> = Vec::new();
    for op in ops {
        let bin = |o| Some(o);
        let next = match *op {
            Op::Const(c) => Ast::Int(c),
            Op::Var(v) => Ast::Name(var(v), 0..0),
            Op::Input(i) => Ast::Name(input(i), 0..0),
            Op::Not => Ast::Not(Box::new(stack.pop()?)),
            Op::Wrap { bits, signed } => Ast::Wrap {
                bits,
                signed,
                of: Box::new(stack.pop()?),
            },
            other => {
                let o = match other {
                    Op::And => bin(BinOp::And),
                    Op::Or => bin(BinOp::Or),
                    Op::Eq => bin(BinOp::Eq),
                    Op::Ne => bin(BinOp::Ne),
                    Op::Lt => bin(BinOp::Lt),
                    Op::Le => bin(BinOp::Le),
                    Op::Gt => bin(BinOp::Gt),
                    Op::Ge => bin(BinOp::Ge),
                    Op::Add => bin(BinOp::Add),
                    Op::Sub => bin(BinOp::Sub),
                    Op::Mul => bin(BinOp::Mul),
                    Op::Div => bin(BinOp::Div),
                    Op::Rem => bin(BinOp::Rem),
                    _ => None,
                }?;
                let b = stack.pop()?;
                let a = stack.pop()?;
                Ast::Bin(o, Box::new(a), Box::new(b))
            }
        };
        stack.push(next);
    }
    let top = stack.pop()?;
    stack.is_empty().then_some(top)
}

#[cfg(test)]
mod tests {
    use super::{decompile, st, Kind};
    use crate::expr;

    fn names(n: &str) -> Option<(String, Kind)> {
        match n {
            "VC.home" => Some((String::from("VC_home"), Kind::Bool)),
            "n" | "DIPS" => Some((n.to_string(), Kind::Int)),
            _ => None,
        }
    }

    /// Guards and assignments become fully parenthesised ST; an integer used as a
    /// condition is compared with 0; a wrap and an unknown name are errors.
    #[test]
    fn expressions_become_structured_text() {
        let s = |t: &str, k| st(&expr::parse(t).unwrap(), k, &names);
        assert_eq!(
            s("n >= DIPS && !VC.home", Kind::Bool).unwrap(),
            "((n >= DIPS) AND (NOT VC_home))"
        );
        assert_eq!(s("n % 3 + -n", Kind::Int).unwrap(), "((n MOD 3) + (-n))");
        assert_eq!(
            s("n != 0 || !n", Kind::Bool).unwrap(),
            "((n <> 0) OR (n = 0))"
        );
        assert_eq!(s("n", Kind::Bool).unwrap(), "(n <> 0)");
        assert!(s("int(n + 1)", Kind::Int)
            .unwrap_err()
            .contains("wraps to 16 bits"));
        assert_eq!(s("m", Kind::Int).unwrap_err(), "unknown name `m`");
        assert!(s("VC.home + 1", Kind::Int).is_err());
        // A negative literal in parentheses: negated, `-(-5)` (ST takes one unary operator:
        // `--5` was written, which no ST reader takes).
        assert_eq!(s("-(-5)", Kind::Int).unwrap(), "(-(-5))");
        assert_eq!(s("-2147483648", Kind::Int).unwrap(), "(-2147483648)");
        // Read back by the importer: `-(-2147483648)` (its fold wraps).
        let d = crate::iec61499::st::Name {
            name: "D".into(),
            ty: crate::iec61499::st::Ty::of("DINT").unwrap(),
            writable: true,
        };
        let read = |text: &str| {
            crate::iec61499::st::algorithm(&format!("D := {text};"), std::slice::from_ref(&d))
        };
        let minus_min = s("-(-2147483648)", Kind::Int).unwrap();
        assert_eq!(minus_min, "(-(-2147483648))");
        assert!(
            read(&minus_min).is_ok(),
            "read back: {:?}",
            read(&minus_min)
        );
    }

    /// Bytecode decompiles to an expression that compiles to the same bytecode.
    #[test]
    fn bytecode_decompiles_to_the_same_bytecode() {
        let text = "(n + 1) * 2 >= 7 && !VC.home || n == -3";
        let resolve = |n: &str| match n {
            "n" => Some(expr::Operand::Var(4)),
            "VC.home" => Some(expr::Operand::Input(1)),
            _ => None,
        };
        let ops = expr::bytecode(&expr::parse(text).unwrap(), &resolve).unwrap();
        let ast = decompile(&ops, &|_| String::from("n"), &|_| String::from("VC.home")).unwrap();
        assert_eq!(expr::bytecode(&ast, &resolve).unwrap(), ops);
        assert_eq!(
            decompile(&[config_schema::Op::Add], &|_| String::new(), &|_| {
                String::new()
            }),
            None
        );
    }
}
