//! IEC 61499-2 XML out (`config-tool export-4diac`): each chart type of a compiled robot
//! as a basic FB type (`.fbt`, [`fbt`]) and the robot as a system (`.sys`, [`sys`]) that
//! Eclipse 4diac IDE opens: the application's FB network, a device per node, a resource
//! per role, the mapping, and the connections the mapping cuts as PUBLISH / SUBSCRIBE
//! pairs (docs/iec61499-xml.md, "The export").
//!
//! Chart types written in the robot (and imported ones) are exported as they are, with
//! their parameters; a chart no type describes (synthesised, a control function's, an
//! automaton's, a sorting station's) is lifted into one ([`lift`]).

pub mod fbt;
pub mod lift;
pub mod st;
pub mod sys;
pub mod xml;

use std::collections::BTreeMap;

use crate::compile::Compiled;

/// Why a robot cannot be exported.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ExportError {
    #[error("chart type `{ty}`: {message}")]
    Type { ty: String, message: String },
    /// A chart reads another chart's variable into a parameter (a data connection of the
    /// application it came from): the export writes no data connections yet, and the
    /// parameter would come back a constant.
    #[error(
        "chart `{chart}` of role `{role}` reads `{var}` into its parameter `{param}` (a data \
         connection): the export does not write data connections yet"
    )]
    Reads {
        role: String,
        chart: String,
        param: String,
        var: String,
    },
}

/// One chart of the robot as an FB instance of the application.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Instance {
    /// Its role (a resource), by index.
    pub role: usize,
    /// Its chart in the role's IR.
    pub chart: usize,
    /// The FB's name in the application (unique).
    pub name: String,
    /// Its FB type.
    pub ty: String,
    /// Parameter values (the input variables).
    pub params: BTreeMap<String, i32>,
    /// The type's event input for each chart input, by index.
    pub inputs: Vec<String>,
    /// The node events it emits and the type's output event for each.
    pub emits: Vec<(String, String)>,
    /// The service output events its type has (each wired to the role's IO block).
    pub services: Vec<String>,
    /// Whether its type was lifted from the IR (no chart type of the robot describes it).
    pub lifted: bool,
    /// A lifted chart's timers, each with the role's timer event it is (each fed from
    /// the role's IO block, so the charts that share it share it again on import).
    pub timers: Vec<(String, String)>,
}

/// An exported robot: the files to write (name, text), and what they contain.
#[derive(Debug, Clone)]
pub struct Export {
    pub files: Vec<(String, String)>,
    /// The chart types written, in file order (each `NAME.fbt`).
    pub types: Vec<crate::model::ChartType>,
    pub instances: Vec<Instance>,
}

/// The name of the `.sys` file of a robot.
pub fn sys_file(c: &Compiled) -> String {
    format!("{}.sys", fbt::identifier(&c.ir.name))
}

/// Exports a compiled robot; `date` (`YYYY-MM-DD`) goes in every `VersionInfo`.
pub fn export(c: &Compiled, date: &str) -> Result<Export, ExportError> {
    let robot = &c.robot;
    let mut files = Vec::new();
    let mut types: Vec<crate::model::ChartType> = Vec::new();
    for t in &robot.chart_types {
        let t = &fbt::rename_clashing_vars(t);
        // The role inputs its guards read, as BOOL parameters marked with their levels.
        let (written, levels) = fbt::levels_as_params(t);
        let bools: Vec<String> = levels.iter().map(|(p, _)| p.clone()).collect();
        let spec = fbt::FbSpec {
            ty: &written,
            comment: format!("Chart type `{}` of robot {}", t.name, robot.name),
            bools: &bools,
            levels: &levels,
            values: &[],
            places: &[],
            date,
        };
        files.push((format!("{}.fbt", t.name), fbt::write(&spec)?));
        types.push(t.clone());
    }
    // Per role: each variable of the role's pool, the FB of its chart and its name in
    // the FB's type (for the `value of` comments of the lifted charts reading it).
    let mut owners: Vec<BTreeMap<String, (String, String)>> = Vec::new();
    // The lifted charts, written once every FB's name is known: (instance index, its
    // lifted type, the `.fbt` comment).
    let mut lifted: Vec<(usize, lift::Lifted, String)> = Vec::new();
    // Each role's service FB and its type are `ROLE_IO` (`sys::io_name`): a chart's FB or
    // lifted type named so (a chart `IO` of role CABINET) is named apart.
    let ios: Vec<String> = (0..c.ir.roles.len())
        .map(|ri| sys::io_name(c, ri))
        .collect();
    let mut taken: Vec<String> = (types.iter().map(|t| &t.name))
        .chain(&ios)
        .map(|n| n.to_ascii_uppercase())
        .collect();
    let mut fb_names: Vec<String> = ios;
    let mut instances = Vec::new();
    for (ri, r) in c.ir.roles.iter().enumerate() {
        let role = robot.roles.get(ri);
        let mut owner: BTreeMap<String, (String, String)> = BTreeMap::new();
        for (ci, chart) in r.charts.iter().enumerate() {
            let explicit = robot
                .sequence
                .is_none()
                .then(|| role.and_then(|x| x.charts.get(ci)))
                .flatten()
                .filter(|d| d.name == chart.name)
                .and_then(|d| robot.chart_type(&d.type_).map(|(_, t)| (d, t)));
            let mut fb = fbt::identifier(&format!("{}_{}", r.name, chart.name));
            let base = fb.clone();
            let mut k = 2;
            while fb_names.iter().any(|n| n.eq_ignore_ascii_case(&fb)) {
                fb = format!("{base}_{k}");
                k += 1;
            }
            fb_names.push(fb.clone());
            let inst = match explicit {
                Some((d, t)) => {
                    if let Some((param, var)) = d.reads.iter().next() {
                        return Err(ExportError::Reads {
                            role: r.name.clone(),
                            chart: d.name.clone(),
                            param: param.clone(),
                            var: var.clone(),
                        });
                    }
                    let renamed = fbt::rename_clashing_vars(t);
                    for (v, n) in t.vars.iter().zip(&renamed.vars) {
                        owner.insert(
                            format!("{}.{}", d.name, v.name),
                            (fb.clone(), n.name.clone()),
                        );
                    }
                    Instance {
                        role: ri,
                        chart: ci,
                        name: fb,
                        ty: t.name.clone(),
                        params: d.params.clone(),
                        inputs: t.inputs.iter().chain(&t.timers).cloned().collect(),
                        emits: t
                            .outputs
                            .iter()
                            .map(|o| (format!("{}.{o}", d.name), o.clone()))
                            .collect(),
                        services: services_of(t),
                        lifted: false,
                        timers: Vec::new(),
                    }
                }
                None => {
                    let mut name = fbt::identifier(&format!("{}_{}", r.name, chart.name));
                    let base = name.clone();
                    let mut k = 2;
                    while taken.contains(&name.to_ascii_uppercase()) {
                        name = format!("{base}_{k}");
                        k += 1;
                    }
                    taken.push(name.to_ascii_uppercase());
                    let l = lift::lift(r, ci, &name);
                    for (v, role_var) in &l.vars {
                        owner.insert(role_var.clone(), (fb.clone(), v.clone()));
                    }
                    let comment = format!(
                        "Chart `{}` of role {} of robot {}, as the robot compiles it",
                        chart.name, r.name, robot.name
                    );
                    let services = services_of(&l.ty);
                    let inst = Instance {
                        role: ri,
                        chart: ci,
                        name: fb,
                        ty: name,
                        params: BTreeMap::new(),
                        inputs: l.inputs.clone(),
                        emits: l.emits.clone(),
                        services,
                        lifted: true,
                        timers: l.timers.clone(),
                    };
                    lifted.push((instances.len(), l, comment));
                    inst
                }
            };
            instances.push(inst);
        }
        owners.push(owner);
    }
    for (k, l, comment) in lifted {
        let Some(inst) = instances.get(k) else {
            continue;
        };
        let places = places_vars(c, &l.vars);
        let values: Vec<(String, String)> = (l.reads.iter())
            .filter_map(|(p, role_var)| {
                let (fb, var) = owners.get(inst.role)?.get(role_var)?;
                Some((p.clone(), crate::iec61499::services::value_comment(fb, var)))
            })
            .collect();
        let spec = fbt::FbSpec {
            ty: &l.ty,
            comment,
            bools: &l.bools,
            levels: &l.levels,
            values: &values,
            places: &places,
            date,
        };
        files.push((format!("{}.fbt", l.ty.name), fbt::write(&spec)?));
        types.push(l.ty);
    }
    let (ios, sys_text) = sys::write(c, &instances, date);
    files.extend(ios);
    files.push((sys_file(c), sys_text));
    Ok(Export {
        files,
        types,
        instances,
    })
}

/// (variable, comment) of each of `vars` (a lifted type's variable, the role's) that
/// holds a control function's place (`F.state`): the function and its places.
fn places_vars(c: &Compiled, vars: &[(String, String)]) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for (v, role_var) in vars {
        let f = c
            .robot
            .functions
            .iter()
            .find(|f| crate::petri::compile::state_var(&f.name) == *role_var);
        if let Some(f) = f {
            let places = f.matrix.as_ref().map_or(&f.places, |m| &m.places);
            let comment = crate::iec61499::services::places_comment(&f.name, places);
            out.push((v.clone(), comment));
        }
    }
    out
}

/// The service output events of a chart type (after its own outputs).
fn services_of(t: &crate::model::ChartType) -> Vec<String> {
    fbt::output_events(t).split_off(t.outputs.len())
}
