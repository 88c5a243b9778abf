//! Guards and assignments lowered once, when a table's [`Index`](super::Index) is built,
//! to one flat five-byte operation each: the shapes nearly every expression has (`c`, `v`,
//! `v op c`, `v op c` wrapped to a narrow integer, `v op w`) are computed in one step; any
//! other expression keeps its place in the table's code pool and runs on the stack machine
//! ([`config_schema::guard::eval`]). Both give the same value for every expression (a test
//! below holds them equal), and the same `None` (a fault) for one that cannot be evaluated.
//!
//! Lowered only when the operands are proven in range at build time (a variable below
//! `MAX_VARS`, a constant in `-65536..=65535`, a binary operation, a wrap of 8 or 16 bits):
//! evaluating a lowered form then reads the engine's variables without a bounds check.

use config_schema::guard::{self, Op};
use config_schema::limits::MAX_VARS;
use config_schema::{Expr, Table};

/// The variable slots: a variable index masked with this is in range (`MAX_VARS` is a
/// power of two).
const VAR_MASK: usize = MAX_VARS - 1;
const _: () = assert!(MAX_VARS.is_power_of_two());

// Shapes: the high nibble of `Calc::code` (the low nibble is the binary operation).
/// No expression: a missing guard (holds).
const TRUE: u8 = 0x00;
/// A constant: `k`, negative when bit 3 of `b` is set.
const CONST: u8 = 0x10;
/// Variable `a`.
const VAR: u8 = 0x20;
/// Variable `a` op constant `k` (negative when bit 3 of `b`), wrapped by `b & 7`.
const VAR_IMM: u8 = 0x30;
/// Variable `a` op variable `b`.
const VAR_VAR: u8 = 0x40;
/// Anything else: `len` = `k[1]` operations from `start` = `k[0]` of the code pool.
const STACK: u8 = 0x50;

/// Bit of `b` that makes the 16-bit immediate negative (`k - 65536`).
const NEG: u8 = 0x08;

/// Wrap codes (`b & 7` of `VAR_IMM`).
const WRAP_NONE: u8 = 0;
const WRAP_U8: u8 = 1;
const WRAP_S8: u8 = 2;
const WRAP_U16: u8 = 3;
const WRAP_S16: u8 = 4;

/// One lowered expression (see the shapes above).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Calc {
    code: u8,
    a: u8,
    b: u8,
    k: [u8; 2],
}

const _: () = assert!(core::mem::size_of::<Calc>() == 5);

/// The binary operations, numbered as the low nibble of `Calc::code`.
fn binary_code(op: Op) -> Option<u8> {
    Some(match op {
        Op::And => 0,
        Op::Or => 1,
        Op::Eq => 2,
        Op::Ne => 3,
        Op::Lt => 4,
        Op::Le => 5,
        Op::Gt => 6,
        Op::Ge => 7,
        Op::Add => 8,
        Op::Sub => 9,
        Op::Mul => 10,
        Op::Div => 11,
        Op::Rem => 12,
        Op::Const(_) | Op::Var(_) | Op::Input(_) | Op::Not | Op::Wrap { .. } => return None,
    })
}

/// `a op b` for the operation numbered `op` ([`binary_code`]): what
/// [`config_schema::guard`] computes (`None`: a division by zero).
#[inline(always)]
fn binary(op: u8, a: i32, b: i32) -> Option<i32> {
    Some(match op {
        0 => i32::from(a != 0 && b != 0),
        1 => i32::from(a != 0 || b != 0),
        2 => i32::from(a == b),
        3 => i32::from(a != b),
        4 => i32::from(a < b),
        5 => i32::from(a <= b),
        6 => i32::from(a > b),
        7 => i32::from(a >= b),
        8 => a.wrapping_add(b),
        9 => a.wrapping_sub(b),
        10 => a.wrapping_mul(b),
        11 => a.checked_div(b).or((b != 0).then_some(i32::MIN))?,
        12 => a.checked_rem(b).or((b != 0).then_some(0))?,
        _ => return None,
    })
}

/// The wrap code of `Op::Wrap { bits, signed }` (8 or 16 bits only).
fn wrap_code(bits: u8, signed: bool) -> Option<u8> {
    match (bits, signed) {
        (8, false) => Some(WRAP_U8),
        (8, true) => Some(WRAP_S8),
        (16, false) => Some(WRAP_U16),
        (16, true) => Some(WRAP_S16),
        _ => None,
    }
}

#[inline(always)]
fn wrap(v: i32, code: u8) -> i32 {
    match code {
        WRAP_U8 => i32::from(v as u8),
        WRAP_S8 => i32::from(v as i8),
        WRAP_U16 => i32::from(v as u16),
        WRAP_S16 => i32::from(v as i16),
        _ => v,
    }
}

/// (the 16-bit immediate, the `NEG` bit) of `c`, if it is in `-65536..=65535`.
fn immediate(c: i32) -> Option<([u8; 2], u8)> {
    match c {
        0..=65_535 => Some(((c as u16).to_le_bytes(), 0)),
        -65_536..=-1 => Some((((c + 65_536) as u16).to_le_bytes(), NEG)),
        _ => None,
    }
}

/// A variable operand proven in range.
fn var(v: u8) -> Option<u8> {
    (usize::from(v) < MAX_VARS).then_some(v)
}

impl Calc {
    /// A missing guard: holds.
    pub(super) const TRUE: Calc = Calc {
        code: TRUE,
        a: 0,
        b: 0,
        k: [0; 2],
    };

    /// `expr` of `table`, lowered (`None`: a missing guard, which holds).
    pub(super) fn lower(table: &Table, expr: Option<Expr>) -> Calc {
        let Some(expr) = expr else {
            return Calc::TRUE;
        };
        Calc::direct(table.expr(expr)).unwrap_or(Calc {
            code: STACK,
            a: 0,
            b: 0,
            k: [expr.start, expr.len],
        })
    }

    /// The one-step form of `ops`, if it has one of the direct shapes.
    fn direct(ops: &[Op]) -> Option<Calc> {
        let calc = |code, a, b, k| Some(Calc { code, a, b, k });
        match *ops {
            [Op::Const(c)] => {
                let (k, neg) = immediate(c)?;
                calc(CONST, 0, neg, k)
            }
            [Op::Var(v)] => calc(VAR, var(v)?, 0, [0; 2]),
            [Op::Var(v), Op::Const(c), op] => {
                let (k, neg) = immediate(c)?;
                calc(VAR_IMM | binary_code(op)?, var(v)?, neg | WRAP_NONE, k)
            }
            [Op::Var(v), Op::Const(c), op, Op::Wrap { bits, signed }] => {
                let (k, neg) = immediate(c)?;
                let w = wrap_code(bits, signed)?;
                calc(VAR_IMM | binary_code(op)?, var(v)?, neg | w, k)
            }
            [Op::Var(a), Op::Var(b), op] => calc(VAR_VAR | binary_code(op)?, var(a)?, var(b)?, [0; 2]),
            _ => None,
        }
    }

    /// Whether this is a missing guard.
    #[inline(always)]
    pub(super) fn is_true(self) -> bool {
        self.code == TRUE
    }

    #[inline(always)]
    fn imm(self) -> i32 {
        i32::from(u16::from_le_bytes(self.k)) - (i32::from(self.b & NEG) << 13)
    }

    /// The value (`None`: the expression cannot be evaluated, a fault). `vars` are the
    /// engine's variables, `inputs` its input levels; `table` holds the code of the
    /// expressions that run on the stack machine.
    #[inline(always)]
    pub(super) fn eval(self, vars: &[i32; MAX_VARS], inputs: u16, table: &Table) -> Option<i32> {
        let var = |v: u8| vars[usize::from(v) & VAR_MASK];
        let op = self.code & 0x0f;
        match self.code & 0xf0 {
            TRUE => Some(1),
            CONST => Some(self.imm()),
            VAR => Some(var(self.a)),
            VAR_IMM => Some(wrap(binary(op, var(self.a), self.imm())?, self.b & 7)),
            VAR_VAR => binary(op, var(self.a), var(self.b)),
            _ => self.stack(vars, inputs, table),
        }
    }

    /// An expression of no direct shape, on the stack machine.
    #[inline(never)]
    fn stack(self, vars: &[i32; MAX_VARS], inputs: u16, table: &Table) -> Option<i32> {
        let [start, len] = self.k;
        guard::eval(
            table.expr(Expr { start, len }),
            |v| vars.get(usize::from(v)).copied(),
            |i| (i < 16).then(|| inputs & (1 << i) != 0),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table_with(ops: &[Op]) -> (Table, Expr) {
        let mut t = Table::empty("t");
        let e = t.push_expr(ops).unwrap();
        (t, e)
    }

    /// Lowered and on the stack machine, every shape gives the same value (or the same
    /// fault) for every binary operation, wrap and constant at and around the edges of
    /// the immediate's range, and the direct shapes are the ones lowered.
    #[test]
    fn lowered_expressions_agree_with_the_stack_machine() {
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
        let constants = [
            i32::MIN,
            -65_537,
            -65_536,
            -65_535,
            -32_768,
            -1,
            0,
            1,
            2,
            255,
            65_535,
            65_536,
            i32::MAX,
        ];
        let wraps = [
            None,
            Some((8, true)),
            Some((8, false)),
            Some((16, true)),
            Some((16, false)),
            Some((12, false)),
        ];
        let mut vars = [0i32; MAX_VARS];
        vars[0] = 7;
        vars[1] = -3;
        vars[2] = 0;
        vars[31] = 70_000;
        let inputs = 0b10;
        let (mut lowered, mut cases) = (0, 0);
        let mut check = |e: &[Op]| {
            let (t, expr) = table_with(e);
            let calc = Calc::lower(&t, Some(expr));
            let stack = guard::eval(
                e,
                |v| vars.get(usize::from(v)).copied(),
                |i| Some(inputs & (1 << i) != 0),
            );
            assert_eq!(calc.eval(&vars, inputs, &t), stack, "{e:?} as {calc:?}");
            lowered += usize::from(calc.code & 0xf0 != STACK);
            cases += 1;
        };
        for op in ops {
            for c in constants {
                for v in [0u8, 1, 2, 31, 32] {
                    check(&[Op::Var(v), Op::Const(c), op]);
                    for (bits, signed) in wraps.iter().flatten().copied() {
                        check(&[Op::Var(v), Op::Const(c), op, Op::Wrap { bits, signed }]);
                    }
                }
            }
            for (a, b) in [(0u8, 1u8), (1, 0), (0, 2), (31, 0), (0, 32)] {
                check(&[Op::Var(a), Op::Var(b), op]);
            }
        }
        for c in constants {
            check(&[Op::Const(c)]);
        }
        for v in [0u8, 31, 32, 200] {
            check(&[Op::Var(v)]);
        }
        check(&[Op::Input(1)]);
        check(&[Op::Var(0), Op::Not]);
        check(&[Op::Const(1), Op::And]);
        check(&[]);
        // Lowered: the 13 binary operations with the 9 constants in range on the 4
        // variables below MAX_VARS, unwrapped or with the 4 wraps, and on the 4 pairs of
        // such variables; the 9 constants and the 2 variables alone.
        assert_eq!(lowered, 13 * 9 * 4 * 5 + 13 * 4 + 9 + 2, "of {cases}");
    }

    #[test]
    fn a_missing_guard_holds_and_an_expression_out_of_the_code_pool_faults() {
        let (t, _) = table_with(&[Op::Const(1)]);
        assert_eq!(Calc::lower(&t, None).eval(&[0; MAX_VARS], 0, &t), Some(1));
        assert!(Calc::lower(&t, None).is_true());
        let outside = Expr { start: 5, len: 3 };
        assert_eq!(Calc::lower(&t, Some(outside)).eval(&[0; MAX_VARS], 0, &t), None);
    }
}
