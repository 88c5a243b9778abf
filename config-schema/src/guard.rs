//! Guard and assignment expressions: a tiny stack bytecode with a statically checked
//! stack depth, so evaluating a validated expression can neither underflow nor overflow
//! and costs at most [`MAX_EXPR_LEN`] operations.

use serde::{Deserialize, Serialize};

use crate::limits::{MAX_EXPR_LEN, MAX_STACK};

/// One bytecode operation. Values are `i32`; booleans are `0` (false) and non-zero (true);
/// comparisons and logic push `0` or `1`. Arithmetic wraps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Op {
    /// Push a constant.
    Const(i32),
    /// Push a variable.
    Var(u8),
    /// Push the level of an input (0 or 1).
    Input(u8),
    /// Logical not of the top.
    Not,
    /// Logical and of the two top values.
    And,
    /// Logical or of the two top values.
    Or,
    /// `a == b`.
    Eq,
    /// `a != b`.
    Ne,
    /// `a < b`.
    Lt,
    /// `a <= b`.
    Le,
    /// `a > b`.
    Gt,
    /// `a >= b`.
    Ge,
    /// `a + b` (wrapping).
    Add,
    /// `a - b` (wrapping).
    Sub,
    /// `a * b` (wrapping).
    Mul,
    /// `a / b`, rounded toward zero (`i32::MIN / -1` wraps); dividing by zero is a fault.
    Div,
    /// The remainder of `a / b`, of the sign of `a`; by zero is a fault.
    Rem,
    /// The top truncated to its low `bits` bits (8 or 16), sign-extended if `signed`: the
    /// integer widths of IEC 61131-3 (SINT, INT, USINT, UINT) wrap so.
    Wrap { bits: u8, signed: bool },
}

impl Op {
    /// (values popped, values pushed).
    pub const fn stack_effect(self) -> (usize, usize) {
        match self {
            Op::Const(_) | Op::Var(_) | Op::Input(_) => (0, 1),
            Op::Not | Op::Wrap { .. } => (1, 1),
            _ => (2, 1),
        }
    }
}

/// A reference to an expression: `len` operations of the table's code pool from `start`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Expr {
    pub start: u8,
    pub len: u8,
}

/// Why an expression is not well formed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExprError {
    /// The expression is empty or longer than `MAX_EXPR_LEN`.
    Length(usize),
    /// The expression's range runs past the code pool.
    OutOfCode { end: usize, code_len: usize },
    /// Operation `at` pops more values than the stack holds.
    Underflow { at: usize },
    /// Operation `at` pushes past `MAX_STACK`.
    Overflow { at: usize },
    /// The expression leaves `depth` values instead of exactly one.
    Result { depth: usize },
    /// Operation `at` reads variable `var`, which the table does not have.
    Var { at: usize, var: u8 },
    /// Operation `at` reads input `input`, which the table does not have.
    Input { at: usize, input: u8 },
    /// Operation `at` wraps to a width other than 8 or 16 bits.
    Wrap { at: usize, bits: u8 },
}

/// The widths [`Op::Wrap`] takes.
pub const WRAP_BITS: [u8; 2] = [8, 16];

/// `v` truncated to its low `bits` bits, sign-extended if `signed` (`bits` in
/// [`WRAP_BITS`]; any other width leaves `v` as it is).
pub const fn wrap(v: i32, bits: u8, signed: bool) -> i32 {
    if bits == 0 || bits >= 32 {
        return v;
    }
    let shift = 32 - bits as u32;
    if signed {
        (v << shift) >> shift
    } else {
        ((v as u32) << shift >> shift) as i32
    }
}

/// Checks that `ops` evaluates to exactly one value without leaving the stack bounds and
/// reads only variables below `vars` and inputs below `inputs`.
pub fn check(ops: &[Op], vars: usize, inputs: usize) -> Result<(), ExprError> {
    if ops.is_empty() || ops.len() > MAX_EXPR_LEN {
        return Err(ExprError::Length(ops.len()));
    }
    let mut depth = 0usize;
    for (at, op) in ops.iter().enumerate() {
        match *op {
            Op::Var(v) if usize::from(v) >= vars => return Err(ExprError::Var { at, var: v }),
            Op::Input(i) if usize::from(i) >= inputs => {
                return Err(ExprError::Input { at, input: i })
            }
            Op::Wrap { bits, .. } if !WRAP_BITS.contains(&bits) => {
                return Err(ExprError::Wrap { at, bits })
            }
            _ => {}
        }
        let (pop, push) = op.stack_effect();
        depth = depth.checked_sub(pop).ok_or(ExprError::Underflow { at })?;
        depth += push;
        if depth > MAX_STACK {
            return Err(ExprError::Overflow { at });
        }
    }
    if depth != 1 {
        return Err(ExprError::Result { depth });
    }
    Ok(())
}

/// `a op b` for a binary operation (`None` for any other, and for a division by zero).
#[inline]
fn binary(op: Op, a: i32, b: i32) -> Option<i32> {
    Some(match op {
        Op::And => i32::from(a != 0 && b != 0),
        Op::Or => i32::from(a != 0 || b != 0),
        Op::Eq => i32::from(a == b),
        Op::Ne => i32::from(a != b),
        Op::Lt => i32::from(a < b),
        Op::Le => i32::from(a <= b),
        Op::Gt => i32::from(a > b),
        Op::Ge => i32::from(a >= b),
        Op::Add => a.wrapping_add(b),
        Op::Sub => a.wrapping_sub(b),
        Op::Mul => a.wrapping_mul(b),
        Op::Div => a.checked_div(b).or((b != 0).then_some(i32::MIN))?,
        Op::Rem => a.checked_rem(b).or((b != 0).then_some(0))?,
        Op::Const(_) | Op::Var(_) | Op::Input(_) | Op::Not | Op::Wrap { .. } => return None,
    })
}

/// Evaluates `ops`. `var` and `input` read the operands. Returns `None` only for an
/// expression that [`check`] would reject (the interpreter turns that into a fault).
///
/// The shapes most guards and assignments have (`v`, `v op c`, `v op w`, `v op c`
/// wrapped: `CV < 65535`, `uint(CV + 1)`, `CV >= PV`) are computed directly, the rest on
/// the stack machine; both give the same value.
#[inline]
pub fn eval(
    ops: &[Op],
    mut var: impl FnMut(u8) -> Option<i32>,
    input: impl FnMut(u8) -> Option<bool>,
) -> Option<i32> {
    match *ops {
        [Op::Const(c)] => Some(c),
        [Op::Var(v)] => var(v),
        [Op::Var(v), Op::Const(c), op] => binary(op, var(v)?, c),
        [Op::Var(a), Op::Var(b), op] => binary(op, var(a)?, var(b)?),
        [Op::Var(v), Op::Const(c), op, Op::Wrap { bits, signed }] => {
            Some(wrap(binary(op, var(v)?, c)?, bits, signed))
        }
        _ => eval_stack(ops, var, input),
    }
}

/// [`eval`] on the stack machine, whatever the expression's shape (the same value: a test
/// holds them equal). For an interpreter that computes the direct shapes itself.
pub fn eval_stack(
    ops: &[Op],
    mut var: impl FnMut(u8) -> Option<i32>,
    mut input: impl FnMut(u8) -> Option<bool>,
) -> Option<i32> {
    let mut stack = [0i32; MAX_STACK];
    let mut depth = 0usize;
    for op in ops.iter().take(MAX_EXPR_LEN) {
        let value = match *op {
            Op::Const(c) => c,
            Op::Var(v) => var(v)?,
            Op::Input(i) => i32::from(input(i)?),
            Op::Not => {
                let a = *stack.get(depth.checked_sub(1)?)?;
                depth -= 1;
                i32::from(a == 0)
            }
            Op::Wrap { bits, signed } => {
                let a = *stack.get(depth.checked_sub(1)?)?;
                depth -= 1;
                wrap(a, bits, signed)
            }
            binary => {
                let b = *stack.get(depth.checked_sub(1)?)?;
                let a = *stack.get(depth.checked_sub(2)?)?;
                depth -= 2;
                self::binary(binary, a, b)?
            }
        };
        *stack.get_mut(depth)? = value;
        depth += 1;
    }
    if depth == 1 {
        Some(stack[0])
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(ops: &[Op]) -> Option<i32> {
        check(ops, 0, 0).ok()?;
        eval(ops, |_| None, |_| None)
    }

    fn bin(a: i32, b: i32, op: Op) -> Option<i32> {
        run(&[Op::Const(a), Op::Const(b), op])
    }

    /// The shapes computed directly give what the stack machine gives, for every binary
    /// operation and wrap, on values at and around the edges (and a division by zero is
    /// `None` either way).
    #[test]
    fn the_direct_shapes_agree_with_the_stack_machine() {
        let ops = [
            Op::And,
            Op::Or,
            Op::Eq,
            Op::Ne,
            Op::Lt,
            Op::Le,
            Op::Gt,
            Op::Ge,
            Op::Add,
            Op::Sub,
            Op::Mul,
            Op::Div,
            Op::Rem,
            Op::Not,
        ];
        let values = [i32::MIN, -65_536, -1, 0, 1, 2, 255, 65_535, i32::MAX];
        let vars = [7, -3];
        let var = |v: u8| vars.get(usize::from(v)).copied();
        let input = |_| Some(false);
        let mut shapes = 0;
        for op in ops {
            for c in values {
                for wrap in [None, Some((8, true)), Some((16, false))] {
                    let (bits, signed) = wrap.unwrap_or((8, false));
                    let full = [Op::Var(0), Op::Const(c), op, Op::Wrap { bits, signed }];
                    let e = &full[..if wrap.is_some() { 4 } else { 3 }];
                    assert_eq!(eval(e, var, input), eval_stack(e, var, input), "{e:?}");
                    shapes += 1;
                }
            }
            let e = [Op::Var(0), Op::Var(1), op];
            assert_eq!(eval(&e, var, input), eval_stack(&e, var, input), "{e:?}");
        }
        for e in [&[Op::Var(1)][..], &[Op::Const(5)], &[Op::Var(9)]] {
            assert_eq!(eval(e, var, input), eval_stack(e, var, input), "{e:?}");
        }
        assert_eq!(eval(&[Op::Var(0), Op::Const(0), Op::Div], var, input), None);
        assert_eq!(shapes, 14 * 9 * 3);
    }

    #[test]
    fn multiplication_and_division_as_iec_61131_3_integers() {
        assert_eq!(bin(6, 7, Op::Mul), Some(42));
        assert_eq!(bin(i32::MAX, 2, Op::Mul), Some(-2), "wraps");
        assert_eq!(bin(-7, 2, Op::Div), Some(-3), "toward zero");
        assert_eq!(bin(-7, 2, Op::Rem), Some(-1), "the sign of the left side");
        assert_eq!(bin(7, -2, Op::Rem), Some(1));
        assert_eq!(bin(i32::MIN, -1, Op::Div), Some(i32::MIN), "wraps");
        assert_eq!(bin(i32::MIN, -1, Op::Rem), Some(0));
        assert_eq!(bin(1, 0, Op::Div), None, "a fault");
        assert_eq!(bin(1, 0, Op::Rem), None, "a fault");
    }

    #[test]
    fn wrapping_to_the_narrow_integer_types() {
        let w = |v, bits, signed| run(&[Op::Const(v), Op::Wrap { bits, signed }]);
        assert_eq!(w(65_536 + 4_464, 16, false), Some(4_464), "UINT");
        assert_eq!(w(-1, 16, false), Some(65_535), "UINT");
        assert_eq!(w(40_000, 16, true), Some(-25_536), "INT");
        assert_eq!(w(32_767, 16, true), Some(32_767), "INT");
        assert_eq!(w(200, 8, true), Some(-56), "SINT");
        assert_eq!(w(-1, 8, false), Some(255), "USINT");
        assert_eq!(
            check(
                &[
                    Op::Const(1),
                    Op::Wrap {
                        bits: 12,
                        signed: false
                    }
                ],
                0,
                0
            ),
            Err(ExprError::Wrap { at: 1, bits: 12 })
        );
    }
}
