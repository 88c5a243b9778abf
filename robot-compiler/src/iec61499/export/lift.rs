//! A chart of the IR that no chart type of the robot describes (synthesised from a
//! sequence, compiled from a control function, an automaton or a sorting table) lifted
//! into a chart type: names made identifiers, guards and assignments decompiled from
//! their bytecode, the levels of the role's inputs and the variables of other charts it
//! reads as BOOL / DINT input variables, the initial state first.

use super::fbt::identifier;
use super::st::decompile;
use crate::ir::{ActionIr, ChartIr, RoleIr};
use crate::model::{ActionDecl, ChartType, StateDecl, TransitionDecl, VarDecl};

/// A lifted chart: its type, the type's name for each chart input (by index), the
/// output name of each node event it emits, the BOOL parameters (input levels), each with
/// the role input it reads, and its timers, each with the role's timer event.
pub struct Lifted {
    pub ty: ChartType,
    pub inputs: Vec<String>,
    pub emits: Vec<(String, String)>,
    pub bools: Vec<String>,
    /// (parameter, role input): the level a BOOL parameter reads.
    pub levels: Vec<(String, String)>,
    /// (the type's timer, the role's timer event it is): the charts of a role that start
    /// one timer share it.
    pub timers: Vec<(String, String)>,
    /// (the type's variable, the role's variable it is), of its own variables.
    pub vars: Vec<(String, String)>,
    /// (DINT parameter, the role's variable it reads): the other charts' variables it
    /// reads.
    pub reads: Vec<(String, String)>,
}

/// A name not yet in `taken` (case-insensitive), from `base`.
fn fresh(base: &str, taken: &mut Vec<String>) -> String {
    let mut name = identifier(base);
    let mut k = 2;
    while taken.iter().any(|t| t.eq_ignore_ascii_case(&name)) {
        name = format!("{}_{k}", identifier(base));
        k += 1;
    }
    taken.push(name.clone());
    name
}

/// Lifts chart `ci` of role `r` into a chart type named `name`.
pub fn lift(r: &RoleIr, ci: usize, name: &str) -> Lifted {
    let c: &ChartIr = &r.charts[ci];
    let mut taken: Vec<String> = Vec::new();
    // Timers this chart starts or cancels are its own; their expiry is the timer's input.
    let mut own_timers: Vec<usize> = Vec::new();
    for a in c.states.iter().flat_map(|s| &s.actions) {
        if let ActionIr::StartTimer { timer, .. } | ActionIr::CancelTimer(timer) = a {
            if !own_timers.contains(timer) {
                own_timers.push(*timer);
            }
        }
    }
    let timer_name: Vec<String> = (r.timers.iter()).map(|t| identifier(&t.name)).collect();
    let routed = |k: usize| {
        r.routes
            .iter()
            .find(|(_, chart, input)| *chart == ci && *input == k)
            .map(|(e, _, _)| e.as_str())
    };
    let mut inputs_of = Vec::new();
    let mut ty_inputs = Vec::new();
    let mut timers = Vec::new();
    for k in 0..c.inputs.len() {
        let own = routed(k).and_then(|e| {
            own_timers
                .iter()
                .find(|t| r.timers.get(**t).is_some_and(|x| x.event == e))
        });
        match own {
            Some(t) => {
                let n = timer_name.get(*t).cloned().unwrap_or_default();
                if !timers.contains(&n) {
                    taken.push(n.clone());
                    timers.push(n.clone());
                }
                inputs_of.push(n);
            }
            None => {
                let n = fresh(&c.inputs[k], &mut taken);
                ty_inputs.push(n.clone());
                inputs_of.push(n);
            }
        }
    }
    for t in &own_timers {
        let n = timer_name.get(*t).cloned().unwrap_or_default();
        if !timers.contains(&n) {
            taken.push(n.clone());
            timers.push(n);
        }
    }
    // Variables: those it sets are its own; others it reads, and input levels, are data
    // inputs (parameters).
    let mut own_vars: Vec<usize> = Vec::new();
    for a in c.states.iter().flat_map(|s| &s.actions) {
        if let ActionIr::Set { var, .. } = a {
            if !own_vars.contains(var) {
                own_vars.push(*var);
            }
        }
    }
    let var_names: Vec<String> = own_vars
        .iter()
        .map(|v| fresh(r.vars.get(*v).map_or("v", |x| x.0.as_str()), &mut taken))
        .collect();
    let mut params: Vec<(String, bool)> = Vec::new();
    let mut read_vars: Vec<(u8, String)> = Vec::new();
    let mut read_inputs: Vec<(u8, String)> = Vec::new();
    let mut ops_all: Vec<&[config_schema::Op]> = Vec::new();
    for a in c.states.iter().flat_map(|s| &s.actions) {
        if let ActionIr::Set { ops, .. } = a {
            ops_all.push(ops);
        }
    }
    for t in &c.transitions {
        if let Some((_, ops)) = &t.guard {
            ops_all.push(ops);
        }
    }
    for op in ops_all.iter().flat_map(|o| o.iter()) {
        match *op {
            config_schema::Op::Var(v)
                if !own_vars.contains(&usize::from(v)) && !read_vars.iter().any(|x| x.0 == v) =>
            {
                let n = fresh(
                    r.vars.get(usize::from(v)).map_or("v", |x| x.0.as_str()),
                    &mut taken,
                );
                params.push((n.clone(), false));
                read_vars.push((v, n));
            }
            config_schema::Op::Input(i) if !read_inputs.iter().any(|x| x.0 == i) => {
                let n = fresh(
                    r.inputs
                        .get(usize::from(i))
                        .map_or("in", |x| x.name.as_str()),
                    &mut taken,
                );
                params.push((n.clone(), true));
                read_inputs.push((i, n));
            }
            _ => {}
        }
    }
    let var = |v: u8| -> String {
        own_vars
            .iter()
            .position(|x| *x == usize::from(v))
            .and_then(|p| var_names.get(p).cloned())
            .or_else(|| read_vars.iter().find(|x| x.0 == v).map(|x| x.1.clone()))
            .unwrap_or_default()
    };
    let input = |i: u8| -> String {
        (read_inputs.iter().find(|x| x.0 == i))
            .map(|x| x.1.clone())
            .unwrap_or_default()
    };
    let text = |ops: &[config_schema::Op]| {
        decompile(ops, &var, &input).map_or_else(|| String::from("0"), |a| print(&a))
    };
    // States, the initial one first.
    let mut order: Vec<usize> = (0..c.states.len()).collect();
    if c.initial < order.len() {
        order.remove(c.initial);
        order.insert(0, c.initial);
    }
    let state_names: Vec<String> = c
        .states
        .iter()
        .map(|s| fresh(&s.name, &mut taken))
        .collect();
    let mut emits: Vec<(String, String)> = Vec::new();
    let mut states = Vec::new();
    for &si in &order {
        let s = &c.states[si];
        let mut actions = Vec::new();
        for a in &s.actions {
            actions.push(match a {
                ActionIr::Set { var: v, ops, .. } => ActionDecl::Set(var(*v as u8), text(ops)),
                ActionIr::Drive { label, .. } => drive(label),
                ActionIr::Emit(e) => {
                    let o = match emits.iter().find(|(x, _)| x == e) {
                        Some((_, o)) => o.clone(),
                        None => {
                            let o = fresh(e, &mut taken);
                            emits.push((e.clone(), o.clone()));
                            o
                        }
                    };
                    ActionDecl::Emit(o)
                }
                ActionIr::StartTimer { timer, ms } => {
                    ActionDecl::StartTimer(timer_name.get(*timer).cloned().unwrap_or_default(), *ms)
                }
                ActionIr::CancelTimer(timer) => {
                    ActionDecl::CancelTimer(timer_name.get(*timer).cloned().unwrap_or_default())
                }
                ActionIr::Fault(code) => ActionDecl::Fault(*code),
            });
        }
        states.push(StateDecl {
            name: state_names[si].clone(),
            actions,
        });
    }
    let transitions = c
        .transitions
        .iter()
        .map(|t| TransitionDecl {
            from: state_names.get(t.from).cloned().unwrap_or_default(),
            to: state_names.get(t.to).cloned().unwrap_or_default(),
            on: t.trigger.and_then(|k| inputs_of.get(k).cloned()),
            when: t.guard.as_ref().map(|(_, ops)| text(ops)),
        })
        .collect();
    let vars = own_vars
        .iter()
        .zip(&var_names)
        .map(|(v, n)| VarDecl {
            name: n.clone(),
            init: r.vars.get(*v).map_or(0, |x| x.1).to_string(),
        })
        .collect();
    let levels = (read_inputs.iter())
        .filter_map(|(i, n)| Some((n.clone(), r.inputs.get(usize::from(*i))?.name.clone())))
        .collect();
    let timer_events = (own_timers.iter())
        .filter_map(|t| {
            let x = r.timers.get(*t)?;
            Some((timer_name.get(*t)?.clone(), x.event.clone()))
        })
        .collect();
    let role_vars = (own_vars.iter().zip(&var_names))
        .filter_map(|(v, n)| Some((n.clone(), r.vars.get(*v)?.0.clone())))
        .collect();
    let reads = (read_vars.iter())
        .filter_map(|(v, n)| Some((n.clone(), r.vars.get(usize::from(*v))?.0.clone())))
        .collect();
    Lifted {
        vars: role_vars,
        reads,
        levels,
        timers: timer_events,
        ty: ChartType {
            name: name.to_string(),
            params: params.iter().map(|p| p.0.clone()).collect(),
            inputs: ty_inputs,
            outputs: emits.iter().map(|e| e.1.clone()).collect(),
            vars,
            timers,
            states,
            transitions,
            idle: (c.idle != c.initial)
                .then(|| state_names.get(c.idle).cloned())
                .flatten(),
            rests: (c.rests.iter())
                .filter_map(|&st| state_names.get(st).cloned())
                .collect(),
            imported: None,
            written: None,
            specializes: None,
        },
        inputs: inputs_of,
        emits,
        bools: params.into_iter().filter(|p| p.1).map(|p| p.0).collect(),
    }
}

/// The action a `Drive` label says: `VC+`, `VC-`, `LAMP=1`.
fn drive(label: &str) -> ActionDecl {
    if let Some((o, v)) = label.rsplit_once('=') {
        return ActionDecl::Out(o.to_string(), v == "1");
    }
    match label.strip_suffix('+') {
        Some(a) => ActionDecl::Extend(a.to_string()),
        None => ActionDecl::Retract(label.trim_end_matches('-').to_string()),
    }
}

/// An AST in the chart types' own syntax, every operation in parentheses.
pub fn print(a: &crate::expr::Ast) -> String {
    use crate::expr::{Ast, BinOp};
    match a {
        Ast::Int(n) => n.to_string(),
        Ast::Name(n, _) => n.clone(),
        Ast::Not(x) => format!("(!{})", print(x)),
        Ast::Neg(x) => format!("(-{})", print(x)),
        Ast::Bin(op, x, y) => {
            let sym = match op {
                BinOp::Or => "||",
                BinOp::And => "&&",
                BinOp::Eq => "==",
                BinOp::Ne => "!=",
                BinOp::Lt => "<",
                BinOp::Le => "<=",
                BinOp::Gt => ">",
                BinOp::Ge => ">=",
                BinOp::Add => "+",
                BinOp::Sub => "-",
                BinOp::Mul => "*",
                BinOp::Div => "/",
                BinOp::Rem => "%",
            };
            format!("({} {sym} {})", print(x), print(y))
        }
        Ast::Wrap { bits, signed, of } => {
            format!("{}({})", crate::expr::wrap_name(*bits, *signed), print(of))
        }
    }
}
