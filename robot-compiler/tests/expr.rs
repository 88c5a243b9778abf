//! Guard / assignment expressions: text -> bytecode, precedence, precise syntax errors
//! (message and byte span), and the "both guards can hold" test behind the overlap warning.

use config_schema::Op;
use robot_compiler::expr::{bytecode, may_overlap, parse, Operand};

fn ops(text: &str) -> Vec<Op> {
    let resolve = |n: &str| match n {
        "count" => Some(Operand::Var(0)),
        "token" => Some(Operand::Var(1)),
        "END" => Some(Operand::Input(2)),
        "VC.home" => Some(Operand::Input(3)),
        "M" => Some(Operand::Const(3)),
        _ => None,
    };
    bytecode(&parse(text).expect("parses"), &resolve).expect("compiles")
}

fn error(text: &str) -> (String, std::ops::Range<usize>) {
    let e = parse(text).expect_err("syntax error");
    (e.message, e.span)
}

#[test]
fn names_become_variables_inputs_or_parameter_constants() {
    assert_eq!(
        ops("END && count < M"),
        [Op::Input(2), Op::Var(0), Op::Const(3), Op::Lt, Op::And]
    );
    assert_eq!(ops("VC.home"), [Op::Input(3)]);
    assert_eq!(ops("count + 1"), [Op::Var(0), Op::Const(1), Op::Add]);
}

#[test]
fn precedence_not_over_comparison_over_and_over_or() {
    assert_eq!(
        ops("!token || count == 1 && END"),
        [
            Op::Var(1),
            Op::Not,
            Op::Var(0),
            Op::Const(1),
            Op::Eq,
            Op::Input(2),
            Op::And,
            Op::Or
        ]
    );
    assert_eq!(
        ops("(token || END) && true"),
        [Op::Var(1), Op::Input(2), Op::Or, Op::Const(1), Op::And]
    );
    assert_eq!(
        ops("count - 1 - 1 >= -2"),
        [
            Op::Var(0),
            Op::Const(1),
            Op::Sub,
            Op::Const(1),
            Op::Sub,
            Op::Const(0),
            Op::Const(2),
            Op::Sub,
            Op::Ge
        ]
    );
    assert_eq!(ops("false"), [Op::Const(0)]);
}

#[test]
fn syntax_errors_name_the_problem_and_its_span() {
    assert_eq!(
        error("END && && count"),
        (
            "expected a value, a name or `(`, found `&&`".to_string(),
            7..9
        )
    );
    assert_eq!(
        error("(count < 3"),
        (
            "expected `)`, found the end of the expression".to_string(),
            9..10
        )
    );
    assert_eq!(
        error("count = 1"),
        (
            "`=` is not an operator: write `==` to compare".to_string(),
            6..7
        )
    );
    assert_eq!(
        error("count 1"),
        (
            "expected an operator or the end of the expression, found `1`".to_string(),
            6..7
        )
    );
    assert_eq!(
        error("a < b < c"),
        (
            "comparisons do not chain: use `&&` between two comparisons".to_string(),
            6..7
        )
    );
    assert_eq!(
        error("count # 2"),
        ("unexpected character `#`".to_string(), 6..7)
    );
    assert_eq!(error("  "), ("empty expression".to_string(), 0..0));
    assert_eq!(
        error("99999999999"),
        (
            "integer `99999999999` does not fit in 32 bits".to_string(),
            0..11
        )
    );
}

/// -2147483648 is a 32-bit integer, though its magnitude alone is not: it was refused as
/// `2147483648`.
#[test]
fn minus_2147483648_is_an_integer_and_2147483648_is_not() {
    let value = |text: &str| {
        robot_compiler::expr::eval(&parse(text).expect("parses"), &|_| None).expect("constant")
    };
    assert_eq!(value("-2147483648"), i32::MIN);
    assert_eq!(value("- 2147483648 + 1"), i32::MIN + 1);
    assert_eq!(value("-2147483647 - 1"), i32::MIN);
    let big = "integer `2147483648` does not fit in 32 bits".to_string();
    assert_eq!(error("2147483648"), (big.clone(), 0..10));
    assert_eq!(error("-(2147483648)"), (big.clone(), 2..12));
    assert_eq!(error("1 + 2147483648"), (big, 4..14));
}

#[test]
fn unknown_names_are_reported_at_their_span() {
    let e = bytecode(&parse("count < MAX").expect("parses"), &|n| {
        (n == "count").then_some(Operand::Var(0))
    })
    .expect_err("unknown");
    assert_eq!(
        e.message,
        "unknown name `MAX`: not a variable, input or parameter of this chart"
    );
    assert_eq!(e.span, 8..11);
}

#[test]
fn overlap_is_found_when_both_guards_can_hold_and_not_otherwise() {
    let none = |_: &str| None;
    let g = |t: &str| parse(t).expect("parses");
    assert!(!may_overlap(&g("count < 3"), &g("count >= 3"), &none));
    assert!(may_overlap(&g("count < 3"), &g("count > 1"), &none));
    assert!(!may_overlap(&g("END && !token"), &g("token"), &none));
    assert!(may_overlap(&g("END"), &g("token"), &none));
    // Parameters are fixed per instance: `count < M` and `count > 5` overlap only if M > 6.
    let m3 = |n: &str| (n == "M").then_some(3);
    let m9 = |n: &str| (n == "M").then_some(9);
    assert!(!may_overlap(&g("count < M"), &g("count > 5"), &m3));
    assert!(may_overlap(&g("count < M"), &g("count > 5"), &m9));
}

/// Deep nesting and long chains are refused where they pass the limits, with the place,
/// instead of running the parser (or a walk over the tree) out of stack.
#[test]
fn deep_nesting_and_long_chains_are_refused_at_their_place() {
    let deep = |n: usize| format!("{}count{}", "(".repeat(n), ")".repeat(n));
    assert_eq!(ops(&deep(64)), [Op::Var(0)]);
    assert_eq!(
        error(&deep(100)),
        (
            String::from("parentheses, widths and unary operators nested more than 64 deep"),
            64..65
        )
    );
    assert_eq!(
        error(&format!("{}count", "!".repeat(65))).1,
        64..65,
        "unary operators nest"
    );
    assert_eq!(error(&format!("{}count", "- ".repeat(65))).1, 128..129);
    let wraps = format!("{}count{}", "int(".repeat(65), ")".repeat(65));
    assert_eq!(error(&wraps).1, 256..259, "widths nest");
    // 512 names and 511 `&&`: the most tokens an expression has.
    let chain = |n: usize| vec!["END"; n].join(" && ");
    assert!(parse(&chain(512)).is_ok());
    let long = chain(100_000);
    let (message, span) = error(&long);
    assert_eq!(message, "an expression of more than 1024 tokens");
    assert_eq!(&long[span.clone()], "E", "the 1025th token: {span:?}");
    assert_eq!(span.start, 512 * "END && ".len());
}

/// A divisor of literals only that is 0 faults every node that evaluates it: refused at
/// the divisor (`1 / 0` passed `check` and faulted the node in `sim`); one that reads a
/// variable, or is not 0, is taken.
#[test]
fn a_divisor_that_is_always_zero_is_refused_at_it() {
    let zero = (
        "division by zero: this divisor is always 0 (a node evaluating it faults)".to_string(),
        4..5,
    );
    assert_eq!(error("1 / 0"), zero);
    assert_eq!(error("1 % 0"), zero);
    assert_eq!(error("count / (2 - 2) + 1").1, 8..15);
    assert_eq!(ops("count / (3 - 2)").len(), 5);
    assert_eq!(ops("1 / count").len(), 3);
    assert_eq!(ops("0 / 1").len(), 3);
}
