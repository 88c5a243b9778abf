//! `sim`: the robot's compiled blobs, decoded as a node decodes them, run on
//! `node_fw::sim::World` (virtual time, plant models from the RON's travel times), one
//! START press per cycle. Each cycle's actuator steps are compared with the declared
//! sequence (or `expect`).

use std::fmt::{Display, Write};

use config_schema::{DecodeError, Table};
use node_fw::sim::{
    Button, DoubleActing, Driven, Motor, NodeSpec, Plant, SimError, SingleActing, Switch, What,
    World,
};

use robot_compiler::compile::Compiled;
use robot_compiler::interlock::{self, Atom, Interlock};
use robot_compiler::ir::{Step, Valves};
use robot_compiler::model::ActuatorKind;
use robot_compiler::plants::PlantDecl;

/// Why a compiled robot could not be simulated.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SimulationError {
    #[error("the robot has no `start` input to press")]
    NoStart,
    #[error("role {role} has no input {input}")]
    NoStartInput { role: String, input: String },
    /// A compiled blob does not decode as a node decodes it.
    #[error("blob of role {role}: {error}")]
    Blob { role: String, error: DecodeError },
    /// An interlock does not resolve (`check` reports it at its place).
    #[error(transparent)]
    Interlock(#[from] robot_compiler::interlock::NeverError),
    /// A declared plant names a role or pin the compiled robot does not have (`check`
    /// reports it at its place).
    #[error("plant {plant}: no {what}")]
    PlantPin { plant: String, what: String },
    /// The world could not be built, or a run did not finish.
    #[error(transparent)]
    World(#[from] SimError),
}

/// Virtual-time bound of one cycle, for a robot whose declared times are short (see
/// [`cycle_limit_ms`]).
pub const CYCLE_LIMIT_MS: u64 = 600_000;

/// Virtual-time bound of one cycle of `c`: [`CYCLE_LIMIT_MS`], or more for a robot whose
/// declared times need it: each step, and a few more for a fault and the faults it causes,
/// may wait for the longest timer of its tables (watchdogs, dwells, chart timers), the
/// longest stroke of its actuators, or the longest full stroke of its motor plants.
pub fn cycle_limit_ms(c: &Compiled) -> u64 {
    let timers = c.tables.iter().flat_map(|t| t.actions.iter());
    let timers = timers.filter_map(|a| match *a {
        config_schema::Action::StartTimer { ms, .. } => Some(ms),
        _ => None,
    });
    let actuators = c.robot.roles.iter().flat_map(|r| r.actuators.iter());
    let strokes = actuators.flat_map(|a| {
        let (out_ms, back_ms) = a.kind.strokes();
        [out_ms, back_ms]
    });
    // A motor plant's full stroke (`stroke_mm` at `speed_mm_s`), rounded up.
    let motors = c.robot.plants.iter().filter_map(|p| match *p {
        robot_compiler::plants::PlantDecl::Motor {
            stroke_mm,
            speed_mm_s,
            ..
        } if speed_mm_s > 0 => {
            let ms = (u64::from(stroke_mm) * 1000).div_ceil(u64::from(speed_mm_s));
            Some(u32::try_from(ms).unwrap_or(u32::MAX))
        }
        _ => None,
    });
    let longest = u64::from(timers.chain(strokes).chain(motors).max().unwrap_or(0));
    let steps = c.ir.expect.len().max(MANY_STEPS) as u64;
    CYCLE_LIMIT_MS.max(longest.saturating_mul(steps + 4))
}

/// The steps [`cycle_limit_ms`] allows for at least (a robot without a declared sequence).
const MANY_STEPS: usize = 64;

/// What one simulated cycle did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SimulatedCycle {
    pub steps: Vec<Step>,
    pub duration_ms: u64,
    /// Radio publications (one per published event, whatever the number of subscribers).
    pub publications: usize,
    /// Faults, as text (`node VC: ...`).
    pub faults: Vec<String>,
    /// The robot's interlocks (`never:`) that held during the cycle, each the first time:
    /// `at 302 ms: never: "HC.moving && !VC.home" holds`.
    pub interlocks: Vec<String>,
}

/// The outcome of a simulation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SimResult {
    pub expect: Vec<Step>,
    pub cycles: Vec<SimulatedCycle>,
    /// Every trace entry, as text (only from [`simulate_traced`]).
    pub trace: Vec<String>,
}

impl SimulatedCycle {
    fn ok(&self, expect: &[Step]) -> bool {
        self.faults.is_empty()
            && self.interlocks.is_empty()
            && (expect.is_empty() || self.steps == expect)
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
                steps_text(&c.steps)
            );
            for f in &c.faults {
                let _ = writeln!(o, "  FAULT {f}");
            }
            for i in &c.interlocks {
                let _ = writeln!(o, "  INTERLOCK {i}");
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
        if bad == 0 && self.expect.is_empty() {
            let _ = writeln!(
                o,
                "ok: {} cycle(s), no fault, no interlock broken",
                self.cycles.len()
            );
        } else if bad == 0 {
            let _ = writeln!(
                o,
                "ok: {} cycle(s), each {} step(s) as declared",
                self.cycles.len(),
                self.expect.len()
            );
        } else {
            let any = |f: &dyn Fn(&SimulatedCycle) -> bool| self.cycles.iter().any(f);
            let (faults, interlocks) = (
                any(&|c| !c.faults.is_empty()),
                any(&|c| !c.interlocks.is_empty()),
            );
            let differ = any(&|c| !self.expect.is_empty() && c.steps != self.expect);
            let n = self.cycles.len();
            if faults || interlocks {
                let why: Vec<&str> = [
                    (faults, "a fault"),
                    (interlocks, "an interlock broken"),
                    (differ, "steps not as declared"),
                ]
                .into_iter()
                .filter_map(|(bad, why)| bad.then_some(why))
                .collect();
                let _ = writeln!(
                    o,
                    "FAILED: {bad} of {n} cycle(s) went wrong: {}",
                    why.join(", ")
                );
            } else {
                let _ = writeln!(
                    o,
                    "FAILED: {bad} of {n} cycle(s) differ from the declared sequence"
                );
            }
        }
        o
    }
}

/// Steps as the CLI prints them: `VC+ GR+ VC-`.
pub fn steps_text(steps: &[Step]) -> String {
    let text: Vec<String> = steps.iter().map(Step::to_string).collect();
    text.join(" ")
}

/// The step of a [`What::Step`] trace entry.
pub fn step_of(what: &What) -> Option<Step> {
    match what {
        What::Step { actuator, plus, .. } => Some(Step {
            actuator: actuator.clone(),
            extend: *plus,
        }),
        _ => None,
    }
}

/// A side-by-side listing of expected and observed steps ([`Step`]s, or their text),
/// marking the differences.
pub fn diff<S: Display>(expect: &[S], observed: &[S]) -> String {
    let text = |s: Option<&S>| s.map_or_else(|| String::from("(none)"), S::to_string);
    let mut o = String::from("  step  expected  observed\n");
    for i in 0..expect.len().max(observed.len()) {
        let (e, s) = (text(expect.get(i)), text(observed.get(i)));
        let mark = if e == s { "" } else { "  <-- differs" };
        let _ = writeln!(o, "  {:>4}  {e:<8}  {s:<8}{mark}", i + 1);
    }
    o
}

/// The plant models of a compiled robot, wired to its tables' pin indices, and the index
/// of the start button.
pub fn plants(c: &Compiled) -> Result<(Vec<Plant>, usize), SimulationError> {
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
    declared(c, &mut plants)?;
    let (sr, name) = c.ir.start.clone().ok_or(SimulationError::NoStart)?;
    let input = c.ir.roles[sr]
        .inputs
        .iter()
        .position(|i| i.name == name)
        .ok_or_else(|| SimulationError::NoStartInput {
            role: c.ir.roles[sr].name.clone(),
            input: name.clone(),
        })?;
    plants.push(Plant::Button(Button::new(&name, sr, input as u8)));
    let button = plants.len() - 1;
    Ok((plants, button))
}

/// The robot's declared plants (`plants`), in order, after those already in `plants`.
fn declared(c: &Compiled, plants: &mut Vec<Plant>) -> Result<(), SimulationError> {
    let base = plants.len();
    for p in &c.robot.plants {
        let missing = |what: String| SimulationError::PlantPin {
            plant: p.name().to_string(),
            what,
        };
        let node = (c.ir.roles.iter())
            .position(|r| r.name == p.role())
            .ok_or_else(|| missing(format!("role {}", p.role())))?;
        let role = &c.ir.roles[node];
        let input = |name: &str| {
            (role.inputs.iter())
                .position(|i| i.name == name)
                .map(|i| i as u8)
                .ok_or_else(|| missing(format!("input {name} on role {}", role.name)))
        };
        let output = |name: &str| {
            (role.outputs.iter())
                .position(|o| o.name == name)
                .map(|o| o as u8)
                .ok_or_else(|| missing(format!("output {name} on role {}", role.name)))
        };
        let opt = |name: &Option<String>| name.as_deref().map(input).transpose();
        let name = p.name().to_string();
        plants.push(match p {
            PlantDecl::Motor {
                cw,
                ccw,
                home,
                end,
                stroke_mm,
                speed_mm_s,
                ..
            } => Plant::Motor(Motor {
                name,
                node,
                cw_out: output(cw)?,
                ccw_out: output(ccw)?,
                home_in: opt(home)?,
                end_in: opt(end)?,
                stroke_mm: *stroke_mm,
                speed_mm_s: *speed_mm_s,
            }),
            PlantDecl::Driven {
                motor, home, end, ..
            } => Plant::Driven(Driven {
                name,
                node,
                motor: (c.robot.plants.iter())
                    .position(|q| matches!(q, PlantDecl::Motor { name, .. } if name == motor))
                    .map(|m| base + m)
                    .ok_or_else(|| missing(format!("motor {motor}")))?,
                home_in: opt(home)?,
                end_in: opt(end)?,
            }),
            PlantDecl::Switch { input: i, .. } => Plant::Switch(Switch {
                name,
                node,
                input: input(i)?,
            }),
            PlantDecl::Button { input: i, .. } => {
                Plant::Button(Button::new(&name, node, input(i)?))
            }
        });
    }
    Ok(())
}

/// The most cycles one simulation runs (`sim --cycles`, a fault's cycle): its report
/// keeps every cycle.
pub const MAX_CYCLES: usize = 10_000;

/// Runs `cycles` cycles of the compiled robot from its blobs.
pub fn simulate(c: &Compiled, cycles: usize) -> Result<SimResult, SimulationError> {
    run(c, cycles, false)
}

/// [`simulate`], keeping every trace entry as text in [`SimResult::trace`].
pub fn simulate_traced(c: &Compiled, cycles: usize) -> Result<SimResult, SimulationError> {
    run(c, cycles, true)
}

/// The robot's blobs decoded as a node decodes them, in role order.
pub fn tables(c: &Compiled) -> Result<Vec<Table>, SimulationError> {
    c.blobs
        .iter()
        .zip(&c.ir.roles)
        .map(|(b, r)| {
            config_schema::decode(b).map_err(|error| SimulationError::Blob {
                role: r.name.clone(),
                error,
            })
        })
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
pub fn world<'t>(c: &Compiled, tables: &'t [Table]) -> Result<(World<'t>, usize), SimulationError> {
    let specs = node_specs(c, tables);
    let (plants, button) = plants(c)?;
    let world = World::new(&specs, plants)?;
    Ok((world, button))
}

fn run(c: &Compiled, cycles: usize, keep_trace: bool) -> Result<SimResult, SimulationError> {
    let tables = tables(c)?;
    let (mut world, button) = world(c, &tables)?;
    let mut result = SimResult {
        expect: c.ir.expect.clone(),
        cycles: Vec::new(),
        trace: Vec::new(),
    };
    let watch = Interlocks::of(c, &world)?;
    let limit_ms = cycle_limit_ms(c);
    for _ in 0..cycles {
        let mark = world.trace().len();
        let mut broken: Vec<(u64, usize)> = Vec::new();
        let cycle = world.run_cycle_watched(button, limit_ms, &mut |w| {
            for i in watch.holding(w) {
                if broken.iter().all(|&(_, b)| b != i) {
                    broken.push((w.now(), i));
                }
            }
        })?;
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
        let r = SimulatedCycle {
            steps: entries.iter().filter_map(|e| step_of(&e.what)).collect(),
            duration_ms,
            publications,
            faults,
            interlocks: broken
                .iter()
                .map(|&(t, i)| format!("at {t} ms: never: \"{}\" holds", watch.list[i].text))
                .collect(),
        };
        let stop = !r.ok(&result.expect);
        result.cycles.push(r);
        if stop {
            break;
        }
    }
    Ok(result)
}

/// The robot's interlocks (`never:`), read on a simulated world.
struct Interlocks {
    list: Vec<Interlock>,
    /// The world's plant of each actuator an interlock names (by the IR's index).
    plants: Vec<Option<usize>>,
}

impl Interlocks {
    fn of(c: &Compiled, world: &World<'_>) -> Result<Interlocks, SimulationError> {
        let list = interlock::interlocks(&c.robot, &c.ir)?;
        let plants = interlock::actuator_names(&c.ir)
            .iter()
            .map(|name| world.plant_by_name(name))
            .collect();
        Ok(Interlocks { list, plants })
    }

    /// The interlocks that hold in `world` now, by index.
    fn holding<'a>(&'a self, world: &'a World<'_>) -> impl Iterator<Item = usize> + 'a {
        let read = move |a: Atom| match a {
            Atom::Position { plant, mask } => {
                let at = self.plants.get(plant).copied().flatten();
                at.and_then(|p| world.position(p))
                    .is_some_and(|pos| crate::verify::rod_mask(pos) & mask != 0)
            }
            Atom::Chart { role, chart, state } => {
                role < world.node_count()
                    && world.engine(role).state(chart).map(usize::from) == Some(state)
            }
            Atom::Fault { role } => {
                role < world.node_count() && world.engine(role).fault().is_some()
            }
            Atom::Const(v) => v,
        };
        (0..self.list.len()).filter(move |&i| self.list[i].holds(&read))
    }
}

#[cfg(test)]
mod tests {
    use super::{diff, step_of, steps_text};
    use node_fw::sim::What;
    use robot_compiler::ir::Step;

    fn step(actuator: &str, extend: bool) -> Step {
        Step {
            actuator: actuator.to_string(),
            extend,
        }
    }

    #[test]
    fn a_diff_of_steps_reads_as_the_diff_of_their_text() {
        let expect = [step("VC", true), step("GR", true)];
        let observed = [step("VC", true), step("GR", false), step("VC", false)];
        let text = "  step  expected  observed\n     1  VC+       VC+     \n     2  GR+       GR-       <-- differs\n     3  (none)    VC-       <-- differs\n";
        assert_eq!(diff(&expect, &observed), text);
        let as_text = |s: &[Step]| s.iter().map(Step::to_string).collect::<Vec<_>>();
        assert_eq!(diff(&as_text(&expect), &as_text(&observed)), text);
    }

    #[test]
    fn steps_print_as_the_sequence_is_written() {
        assert_eq!(
            steps_text(&[step("VC", true), step("GR", false)]),
            "VC+ GR-"
        );
        assert_eq!(steps_text(&[]), "");
        let what = What::Step {
            plant: 3,
            actuator: String::from("HC"),
            plus: false,
        };
        assert_eq!(step_of(&what), Some(step("HC", false)));
        assert_eq!(step_of(&What::Reset { node: 0 }), None);
    }
}
