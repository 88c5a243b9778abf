//! Guards and assignments lowered once, when a table's [`Index`](super::Index) is built,
//! to one flat five-byte operation each: the shapes nearly every expression has (`c`, `v`,
//! `v op c`, `v + c` wrapped to a narrow integer, `v op w`) are computed in one step, one
//! operation per shape and binary operator (a super-instruction: `v < c`, `v >= w`,
//! `uint(v + c)`); any
//! other expression keeps its place in the table's code pool and runs on the stack machine
//! ([`config_schema::guard::eval_stack`]). Both give the same value for every expression (a test
//! below holds them equal), and the same `None` (a fault) for one that cannot be evaluated.
//!
//! Lowered only when the operands are proven in range at build time (a variable below
//! `MAX_VARS`, a constant of 24 bits, a binary operation, a wrap of 8 or 16 bits):
//! evaluating a lowered form then reads the engine's variables without a bounds check.

use config_schema::guard::{self, Op};
use config_schema::limits::MAX_VARS;
use config_schema::{Expr, Table};

// A variable index masked with `MAX_VARS - 1` is in range.
const _: () = assert!(MAX_VARS.is_power_of_two());

/// The value of the operation `$code` on `$w` (an `Option<i32>`, `None`: a fault), as one
/// `match` together with the arms `$arms` for other codes (above [`LAST_CODE`]): an
/// entry's walk runs an action or an assignment with one jump.
macro_rules! calc_match {
    ($code:expr, $w:expr, $vars:expr, $inputs:expr, $table:expr, { $($arms:tt)* }) => {{
        let w: &[u8; 4] = $w;
        let vars: &[i32; config_schema::limits::MAX_VARS] = $vars;
        // Each operation reads only its operands (loaded where used); a variable index
        // masked is in range (`MAX_VARS` is a power of two).
        let x = || vars[usize::from(w[0]) & (config_schema::limits::MAX_VARS - 1)];
        let y = || vars[usize::from(w[1]) & (config_schema::limits::MAX_VARS - 1)];
        // Sign-extended from 24 bits: one load, one shift.
        let k = || i32::from_le_bytes(*w) >> 8;
        let b = |v: bool| Some(i32::from(v));
        // Every code is below 64 (a const assertion below): masked, the jump needs no range
        // check.
        // (`$arms` may take codes of its own from those below, as the walk takes 0.)
        #[allow(unreachable_patterns)]
        match $code {
            $($arms)*
            0 => Some(1),
            1 => Some(k()),
            2 => Some(x()),
            4 => Some(i32::from(x().wrapping_add(k()) as u8)),
            5 => Some(i32::from(x().wrapping_add(k()) as i8)),
            6 => Some(i32::from(x().wrapping_add(k()) as u16)),
            7 => Some(i32::from(x().wrapping_add(k()) as i16)),
            16 => b(x() != 0 && k() != 0),
            17 => b(x() != 0 || k() != 0),
            18 => b(x() == k()),
            19 => b(x() != k()),
            20 => b(x() < k()),
            21 => b(x() <= k()),
            22 => b(x() > k()),
            23 => b(x() >= k()),
            24 => Some(x().wrapping_add(k())),
            25 => Some(x().wrapping_sub(k())),
            26 => Some(x().wrapping_mul(k())),
            27 => $crate::ecc::calc::div(x(), k()),
            28 => $crate::ecc::calc::rem(x(), k()),
            32 => b(x() != 0 && y() != 0),
            33 => b(x() != 0 || y() != 0),
            34 => b(x() == y()),
            35 => b(x() != y()),
            36 => b(x() < y()),
            37 => b(x() <= y()),
            38 => b(x() > y()),
            39 => b(x() >= y()),
            40 => Some(x().wrapping_add(y())),
            41 => Some(x().wrapping_sub(y())),
            42 => Some(x().wrapping_mul(y())),
            43 => $crate::ecc::calc::div(x(), y()),
            44 => $crate::ecc::calc::rem(x(), y()),
            _ => $crate::ecc::calc::stack(*w, vars, $inputs, $table),
        }
    }};
}
pub(super) use calc_match;

/// One lowered expression: an operation `code` on its operands `w`: variable `w[0]` and
/// the 24-bit signed immediate `w[1..4]` (little-endian: `w` read as an `i32`, shifted
/// right by 8); for `v op w`, variable `w[1]`; on the stack machine, `w[1]` and `w[2]`
/// are the expression's start and length in the code pool.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
pub(super) struct Calc {
    pub code: u8,
    pub w: [u8; 4],
}

/// The highest operation code (codes above it are free for the actions).
pub(super) const LAST_CODE: u8 = 44;

const _: () = assert!(core::mem::size_of::<Calc>() == 5);

/// The operations: one per shape and binary operation, so that evaluating is one jump.
mod code {
    /// No expression: a missing guard (holds).
    pub const TRUE: u8 = 0;
    /// The immediate.
    pub const CONST: u8 = 1;
    /// Variable `a`.
    pub const VAR: u8 = 2;
    /// Anything else, on the stack machine.
    pub const STACK: u8 = 3;
    const _: () = assert!(super::LAST_CODE == VARS + 12);
    /// `a + imm` wrapped to USINT, SINT, UINT, INT.
    pub const ADD_U8: u8 = 4;
    pub const ADD_S8: u8 = 5;
    pub const ADD_U16: u8 = 6;
    pub const ADD_S16: u8 = 7;
    /// `a op imm`: `IMM + op`, `op` numbered as in [`super::binary_code`].
    pub const IMM: u8 = 16;
    /// `a op w`: `VARS + op`.
    pub const VARS: u8 = 32;
}

/// The binary operations, numbered as added to `code::IMM` and `code::VARS`.
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

/// `a / b` as [`config_schema::guard`] computes it (`None`: by zero).
#[inline(never)]
pub(super) fn div(a: i32, b: i32) -> Option<i32> {
    a.checked_div(b).or((b != 0).then_some(i32::MIN))
}

/// `a % b` as [`config_schema::guard`] computes it (`None`: by zero).
#[inline(never)]
pub(super) fn rem(a: i32, b: i32) -> Option<i32> {
    a.checked_rem(b).or((b != 0).then_some(0))
}

/// The 24-bit immediate of `c`, if it fits.
fn immediate(c: i32) -> Option<[u8; 3]> {
    let [b0, b1, b2, _] = c.to_le_bytes();
    ((-(1 << 23)..1 << 23).contains(&c)).then_some([b0, b1, b2])
}

/// A variable operand proven in range.
fn var(v: u8) -> Option<u8> {
    (usize::from(v) < MAX_VARS).then_some(v)
}

impl Calc {
    /// A missing guard: holds.
    pub(super) const TRUE: Calc = Calc {
        code: code::TRUE,
        w: [0; 4],
    };

    /// `expr` of `table`, lowered (`None`: a missing guard, which holds).
    pub(super) fn lower(table: &Table, expr: Option<Expr>) -> Calc {
        let Some(expr) = expr else {
            return Calc::TRUE;
        };
        Calc::direct(table.expr(expr)).unwrap_or(Calc {
            code: code::STACK,
            w: [0, expr.start, expr.len, 0],
        })
    }

    /// The one-step form of `ops`, if it has one of the direct shapes.
    fn direct(ops: &[Op]) -> Option<Calc> {
        let calc = |code, a, [i0, i1, i2]: [u8; 3]| {
            Some(Calc {
                code,
                w: [a, i0, i1, i2],
            })
        };
        match *ops {
            [Op::Const(c)] => calc(code::CONST, 0, immediate(c)?),
            [Op::Var(v)] => calc(code::VAR, var(v)?, [0; 3]),
            [Op::Var(v), Op::Const(c), op] => {
                calc(code::IMM + binary_code(op)?, var(v)?, immediate(c)?)
            }
            // `v + c` and `v - c` wrapped to a narrow integer: `v + c` (or `v + -c`), then
            // the wrap. Other wrapped operations run on the stack machine.
            [Op::Var(v), Op::Const(c), op, Op::Wrap { bits, signed }] => {
                let c = match op {
                    Op::Add => c,
                    Op::Sub => c.checked_neg()?,
                    _ => return None,
                };
                let code = match (bits, signed) {
                    (8, false) => code::ADD_U8,
                    (8, true) => code::ADD_S8,
                    (16, false) => code::ADD_U16,
                    (16, true) => code::ADD_S16,
                    _ => return None,
                };
                calc(code, var(v)?, immediate(c)?)
            }
            [Op::Var(a), Op::Var(b), op] => {
                calc(code::VARS + binary_code(op)?, var(a)?, [var(b)?, 0, 0])
            }
            _ => None,
        }
    }

    /// Whether this is a missing guard.
    #[inline(always)]
    pub(super) fn is_true(&self) -> bool {
        self.code == code::TRUE
    }

    /// Whether this guard holds whatever the variables and inputs are, and cannot fault:
    /// a missing guard or a non-zero constant.
    pub(super) fn always_holds(&self) -> bool {
        self.is_true() || (self.code == code::CONST && i32::from_le_bytes(self.w) >> 8 != 0)
    }

    /// The value (`None`: the expression cannot be evaluated, a fault). `vars` are the
    /// engine's variables, `inputs` its input levels; `table` holds the code of the
    /// expressions that run on the stack machine.
    #[inline(always)]
    pub(super) fn eval(&self, vars: &[i32; MAX_VARS], inputs: u16, table: &Table) -> Option<i32> {
        Calc::run(self.code, &self.w, vars, inputs, table)
    }

    /// [`Calc::eval`] of the operation `code` on `w`.
    #[inline(always)]
    pub(super) fn run(
        code: u8,
        w: &[u8; 4],
        vars: &[i32; MAX_VARS],
        inputs: u16,
        table: &Table,
    ) -> Option<i32> {
        calc_match!(code, w, vars, inputs, table, {})
    }
}

// The codes the `match` above spells as numbers.
const _: () = assert!(
    code::TRUE == 0
        && code::CONST == 1
        && code::VAR == 2
        && code::STACK == 3
        && code::ADD_U8 == 4
        && code::ADD_S16 == 7
        && code::IMM == 16
        && code::VARS == 32
        && LAST_CODE == 44
);
// The codes above `LAST_CODE` (the actions') stay below 64 too.
const _: () = assert!(LAST_CODE + 16 < 64);

/// An expression of no direct shape, on the stack machine. Its operands by value: the
/// walk then keeps no copy of an operation's operands in memory for this rare call.
#[inline(never)]
pub(super) fn stack(w: [u8; 4], vars: &[i32; MAX_VARS], inputs: u16, table: &Table) -> Option<i32> {
    let [_, start, len, _] = w;
    guard::eval_stack(
        table.expr(Expr { start, len }),
        |v| vars.get(usize::from(v)).copied(),
        |i| (i < 16).then(|| inputs & (1 << i) != 0),
    )
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
            -(1 << 23) - 1,
            -(1 << 23),
            -65_536,
            -32_768,
            -1,
            0,
            1,
            2,
            255,
            65_535,
            (1 << 23) - 1,
            1 << 23,
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
            lowered += usize::from(calc.code != code::STACK);
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
        // Lowered: the 13 binary operations with the 10 constants of 24 bits on the 4
        // variables below MAX_VARS, and on the 4 pairs of such variables; `v + c` and
        // `v - c` with the 4 wraps, 10 constants each (`v - c` lowered as `v + -c`: not
        // for c = -2^23, but for c = 2^23); the 10 constants and the 2 variables alone.
        assert_eq!(
            lowered,
            13 * 10 * 4 + 13 * 4 + 2 * 10 * 4 * 4 + 10 + 2,
            "of {cases}"
        );
    }

    #[test]
    fn a_missing_guard_holds_and_an_expression_out_of_the_code_pool_faults() {
        let (t, _) = table_with(&[Op::Const(1)]);
        assert_eq!(Calc::lower(&t, None).eval(&[0; MAX_VARS], 0, &t), Some(1));
        assert!(Calc::lower(&t, None).is_true());
        let outside = Expr { start: 5, len: 3 };
        assert_eq!(
            Calc::lower(&t, Some(outside)).eval(&[0; MAX_VARS], 0, &t),
            None
        );
    }
}
