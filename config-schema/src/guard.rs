//! Guard and assignment expressions: a tiny stack bytecode with a statically checked
//! stack depth, so evaluating a validated expression can neither underflow nor overflow
//! and costs at most [`MAX_EXPR_LEN`](crate::limits::MAX_EXPR_LEN) operations.

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
}

impl Op {
    /// (values popped, values pushed).
    pub const fn stack_effect(self) -> (usize, usize) {
        match self {
            Op::Const(_) | Op::Var(_) | Op::Input(_) => (0, 1),
            Op::Not => (1, 1),
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

/// Evaluates `ops`. `var` and `input` read the operands. Returns `None` only for an
/// expression that [`check`] would reject (the interpreter turns that into a fault).
pub fn eval(
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
            binary => {
                let b = *stack.get(depth.checked_sub(1)?)?;
                let a = *stack.get(depth.checked_sub(2)?)?;
                depth -= 2;
                match binary {
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
                    Op::Const(_) | Op::Var(_) | Op::Input(_) | Op::Not => return None,
                }
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
