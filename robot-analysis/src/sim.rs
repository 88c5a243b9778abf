//! `sim`: the robot's compiled blobs, decoded as a node decodes them, run on
//! `node_fw::sim::World` (virtual time, plant models from the RON's travel times), one
//! START press per cycle. Each cycle's actuator steps are compared with the declared
//! sequence (or `expect`).

use std::fmt::Write;

use config_schema::Table;
use node_fw::sim::{Button, DoubleActing, NodeSpec, Plant, SingleActing, What, World};

use robot_compiler::compile::Compiled;
use robot_compiler::ir::Valves;
use robot_compiler::model::ActuatorKind;

/// Virtual-time bound of one cycle.
pub const CYCLE_LIMIT_MS: u64 = 600_000;

/// What one simulated cycle did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CycleResult {
    pub steps: Vec<String>,
    pub duration_ms: u64,
    /// Radio publications (one per published event, whatever the number of subscribers).
    pub publications: usize,
    /// Faults, as text (`node VC: ...`).
    pub faults: Vec<String>,
}

/// The outcome of a simulation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SimResult {
    pub expect: Vec<String>,
    pub cycles: Vec<CycleResult>,
    /// Every trace entry, as text (only from [`simulate_traced`]).
    pub trace: Vec<String>,
}

impl CycleResult {
    fn ok(&self, expect: &[String]) -> bool {
        self.faults.is_empty() && (expect.is_empty() || self.steps == expect)
    }
}

impl SimResult {
    /// Every cycle produced the expected steps without a fault.
    pub fn ok(&self) -> bool {
        self.cycles.iter().all(|c| c.ok(&self.expect))
    }

    /// Per cycle the observed sequence, time and publications; a diff for a cycle that
    /// differs.
    pub fn report(&self) -> String {
        let mut o = String::new();
        for (i, c) in self.cycles.iter().enumerate() {
            let _ = writeln!(
                o,
                "cycle {:>3}: {:>6} ms  {:>2} publications  {}",
                i + 1,
                c.duration_ms,
                c.publications,
                c.steps.join(" ")
            );
            for f in &c.faults {
                let _ = writeln!(o, "  FAULT {f}");
            }
            if !c.ok(&self.expect) && !self.expect.is_empty() && c.steps != self.expect {
                o.push_str(&diff(&self.expect, &c.steps));
            }
        }
        let bad = self.cycles.iter().filter(|c| !c.ok(&self.expect)).count();
        if self.expect.is_empty() {
            let _ = writeln!(
                o,
                "no expected sequence declared (`expect`): nothing compared"
            );
        }
        if bad == 0 {
            let _ = writeln!(
                o,
                "ok: {} cycle(s), each {} step(s) as declared",
                self.cycles.len(),
                self.expect.len()
            );
        } else {
            let _ = writeln!(
                o,
                "FAILED: {bad} of {} cycle(s) differ from the declared sequence",
                self.cycles.len()
            );
        }
        o
    }
}

/// A side-by-side listing of expected and observed steps, marking the differences.
pub fn diff(expect: &[String], observed: &[String]) -> String {
    let mut o = String::from("  step  expected  observed\n");
    for i in 0..expect.len().max(observed.len()) {
        let e = expect.get(i).map_or("(none)", String::as_str);
        let s = observed.get(i).map_or("(none)", String::as_str);
        let mark = if e == s { "" } else { "  <-- differs" };
        let _ = writeln!(o, "  {:>4}  {e:<8}  {s:<8}{mark}", i + 1);
    }
    o
}

/// The plant models of a compiled robot, wired to its tables' pin indices, and the index
/// of the start button.
pub fn plants(c: &Compiled) -> Result<(Vec<Plant>, usize), String> {
    let mut plants = Vec::new();
    for (ri, (role, r)) in c.robot.roles.iter().zip(&c.ir.roles).enumerate() {
        for a in &role.actuators {
            // Only the actuators the tables drive (a sequence declares those that move).
            let Some(w) = r.actuator(&a.name) else {
                continue;
            };
            let home_in = w.home.map(|i| i.0 as u8);
            let end_in = w.end.map(|i| i.0 as u8);
            match a.kind {
                ActuatorKind::DoubleActing {
                    out_ms, back_ms, ..
                } => {
                    let Valves::Double { extend, retract } = w.valves else {
                        continue;
                    };
                    let (e, rt) = (extend.0 as u8, retract.0 as u8);
                    plants.push(Plant::DoubleActing(DoubleActing {
                        name: a.name.clone(),
                        node: ri,
                        extend_out: e,
                        retract_out: rt,
                        home_in,
                        end_in,
                        extend_ms: u64::from(out_ms),
                        retract_ms: u64::from(back_ms),
                    }));
                }
                ActuatorKind::SingleActing {
                    out_ms, back_ms, ..
                } => {
                    let Valves::Single { valve } = w.valves else {
                        continue;
                    };
                    let v = valve.0 as u8;
                    plants.push(Plant::SingleActing(SingleActing {
                        name: a.name.clone(),
                        node: ri,
                        out: v,
                        home_in,
                        end_in,
                        extend_ms: u64::from(out_ms),
                        retract_ms: u64::from(back_ms),
                    }));
                }
            }
        }
    }
    let (sr, name) =
        c.ir.start
            .clone()
            .ok_or("the robot has no `start` input to press")?;
    let input = c.ir.roles[sr]
        .inputs
        .iter()
        .position(|i| i.name == name)
        .ok_or_else(|| format!("role {} has no input {name}", c.ir.roles[sr].name))?;
    plants.push(Plant::Button(Button::new(&name, sr, input as u8)));
    let button = plants.len() - 1;
    Ok((plants, button))
}

/// Runs `cycles` cycles of the compiled robot from its blobs.
pub fn simulate(c: &Compiled, cycles: usize) -> Result<SimResult, String> {
    run(c, cycles, false)
}

/// [`simulate`], keeping every trace entry as text in [`SimResult::trace`].
pub fn simulate_traced(c: &Compiled, cycles: usize) -> Result<SimResult, String> {
    run(c, cycles, true)
}

/// The robot's blobs decoded as a node decodes them, in role order.
pub fn tables(c: &Compiled) -> Result<Vec<Table>, String> {
    c.blobs
        .iter()
        .zip(&c.ir.roles)
        .map(|(b, r)| config_schema::decode(b).map_err(|e| format!("blob of role {}: {e}", r.name)))
        .collect()
}

/// Every role's node running its table of `tables` (in role order) at its address.
pub fn node_specs<'t>(c: &Compiled, tables: &'t [Table]) -> Vec<NodeSpec<'t>> {
    tables
        .iter()
        .zip(&c.ir.roles)
        .map(|(t, r)| NodeSpec {
            addr: r.address,
            table: t,
        })
        .collect()
}

/// A world running `tables` (from [`tables`]) with the robot's plants, and the index of
/// its start button.
pub fn world<'t>(c: &Compiled, tables: &'t [Table]) -> Result<(World<'t>, usize), String> {
    let specs = node_specs(c, tables);
    let (plants, button) = plants(c)?;
    let world = World::new(&specs, plants).map_err(|e| e.to_string())?;
    Ok((world, button))
}

fn run(c: &Compiled, cycles: usize, keep_trace: bool) -> Result<SimResult, String> {
    let tables = tables(c)?;
    let (mut world, button) = world(c, &tables)?;
    let expect: Vec<String> = c.ir.expect.iter().map(|s| s.to_string()).collect();
    let mut result = SimResult {
        expect,
        cycles: Vec::new(),
        trace: Vec::new(),
    };
    for _ in 0..cycles {
        let mark = world.trace().len();
        let cycle = world
            .run_cycle(button, CYCLE_LIMIT_MS)
            .map_err(|e| e.to_string())?;
        let entries = &world.trace()[mark..];
        let publications = entries
            .iter()
            .filter(|e| matches!(e.what, What::Publish { .. }))
            .count();
        let faults = entries
            .iter()
            .filter_map(|e| match &e.what {
                What::Fault { node, fault } => Some(format!(
                    "at {} ms: role {} faulted: {fault:?}",
                    e.t_ms, c.ir.roles[*node].name
                )),
                _ => None,
            })
            .collect();
        if keep_trace {
            result.trace.extend(entries.iter().map(|e| e.to_string()));
        }
        let duration_ms = cycle.duration_ms();
        let r = CycleResult {
            steps: cycle.steps,
            duration_ms,
            publications,
            faults,
        };
        let stop = !r.ok(&result.expect);
        result.cycles.push(r);
        if stop {
            break;
        }
    }
    Ok(result)
}
