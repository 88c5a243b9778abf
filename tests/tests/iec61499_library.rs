//! The IEC 61499 event FB library (`robot-compiler/types/iec61499/*.fbt`, basic FB types
//! in the 4diac style) imported into a robot, compiled to a table, and driven on the
//! interpreter by event traces whose expected outputs come from the standard's
//! descriptions (IEC 61499-1, Annex A): after each input event, the output events the
//! chart emitted and the values of its output variables.

use std::collections::BTreeMap;
use std::path::Path;

use node_fw::ecc::{Effects, Engine};
use robot_compiler::ir::ActionIr;
use robot_compiler::{compile, Compiled, Source};

/// A robot with one role running one instance `fb` of library type `ty` (parameters
/// `params`), each event input fed by a role input of its own name (pins 0, 1, ...).
fn robot(ty: &str, params: &[(&str, i32)]) -> Compiled {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("robot-compiler")
        .join("types")
        .join("iec61499");
    robot_in(&dir, ty, params)
}

/// [`robot`], with the type's `.fbt` in `dir`.
fn robot_in(dir: &Path, ty: &str, params: &[(&str, i32)]) -> Compiled {
    let file = format!("{ty}.fbt");
    let text = std::fs::read_to_string(dir.join(&file)).expect("library type");
    let t = robot_compiler::iec61499::fbt::import(&text).expect("imports");
    let inputs: Vec<String> = t
        .inputs
        .iter()
        .enumerate()
        .map(|(pin, e)| format!("(name: \"{e}\", pin: {pin})"))
        .collect();
    let on: Vec<String> = t
        .inputs
        .iter()
        .map(|e| format!("\"{e}\": \"{e}\""))
        .collect();
    let params: Vec<String> = params
        .iter()
        .map(|(p, v)| format!("\"{p}\": {v}"))
        .collect();
    let text = format!(
        "Robot(name: \"lib\", network: (pan_id: 0x0E02, channel: 11), \
         nodes: [(name: \"n1\", address: 0x0001)], assign: [(\"FB\", \"n1\")], \
         roles: [(name: \"FB\", inputs: [{}], charts: [(name: \"fb\", type: \"{ty}\", \
         params: {{{}}}, on: {{{}}})])], fb_types: [\"{file}\"])",
        inputs.join(", "),
        params.join(", "),
        on.join(", ")
    );
    let name = dir.join("lib.ron").to_string_lossy().into_owned();
    compile::compile(&Source::new(&name, text))
        .unwrap_or_else(|d| panic!("{ty} does not compile: {d:#?}"))
}

/// The states a stimulus entered.
#[derive(Default)]
struct Entered(Vec<u8>);

impl Effects for Entered {
    fn fired(&mut self, _chart: u8, _transition: u8, _from: u8, to: u8) {
        self.0.push(to);
    }
}

/// Drives `c`'s chart with `events` (input event names); per event, the output events
/// emitted (`fb.` left out) and the output variables `show` as `NAME=value`.
fn drive(c: &Compiled, events: &[&str], show: &[&str]) -> Vec<String> {
    let role = &c.ir.roles[0];
    let chart = &role.charts[0];
    let table = &c.tables[0];
    let pin: BTreeMap<&str, u8> = role
        .inputs
        .iter()
        .map(|i| (i.name.as_str(), i.pin))
        .collect();
    let var = |name: &str| {
        role.vars
            .iter()
            .position(|(v, _)| v == &format!("fb.{name}"))
            .unwrap_or_else(|| panic!("no var {name}"))
    };
    let mut e = Engine::new(table);
    e.reset(&mut ());
    let mut out = Vec::new();
    for ev in events {
        let p = *pin.get(ev).unwrap_or_else(|| panic!("no input {ev}"));
        let mut entered = Entered::default();
        e.input(p, true, &mut entered);
        e.input(p, false, &mut entered);
        let emitted: Vec<String> = entered
            .0
            .iter()
            .flat_map(|&s| chart.states[usize::from(s)].actions.iter())
            .filter_map(|a| match a {
                ActionIr::Emit(name) => Some(name.trim_start_matches("fb.").to_string()),
                _ => None,
            })
            .collect();
        let vars: Vec<String> = show
            .iter()
            .map(|v| format!("{v}={}", e.var(var(v)).expect("var")))
            .collect();
        out.push(format!("{ev}: [{}] {}", emitted.join(" "), vars.join(" ")));
    }
    out
}

#[test]
fn e_ctu_counts_up_to_its_preset_and_resets() {
    let c = robot("E_CTU", &[("PV", 2)]);
    assert_eq!(
        drive(&c, &["CU", "CU", "CU", "R", "CU"], &["CV", "Q"]),
        [
            "CU: [CUO] CV=1 Q=0",
            "CU: [CUO] CV=2 Q=1",
            "CU: [CUO] CV=3 Q=1",
            "R: [RO] CV=0 Q=0",
            "CU: [CUO] CV=1 Q=0",
        ]
    );
}

#[test]
fn e_ctu_stops_counting_at_65535() {
    // The guard CU[CV < 65535]: at the limit a CU is not taken (no CUO, CV stays).
    let c = robot("E_CTU", &[("PV", 65535)]);
    let events = vec!["CU"; 65536];
    let trace = drive(&c, &events, &["CV", "Q"]);
    assert_eq!(trace[65533], "CU: [CUO] CV=65534 Q=0");
    assert_eq!(trace[65534], "CU: [CUO] CV=65535 Q=1");
    assert_eq!(trace[65535], "CU: [] CV=65535 Q=1");
}

#[test]
fn e_ctd_loads_and_counts_down_to_zero() {
    let c = robot("E_CTD", &[("PV", 2)]);
    assert_eq!(
        drive(&c, &["CD", "LD", "CD", "CD", "CD"], &["CV", "Q"]),
        [
            "CD: [] CV=0 Q=0",
            "LD: [LDO] CV=2 Q=0",
            "CD: [CDO] CV=1 Q=0",
            "CD: [CDO] CV=0 Q=1",
            "CD: [] CV=0 Q=1",
        ]
    );
}

#[test]
fn e_ctud_counts_both_ways() {
    let c = robot("E_CTUD", &[("PV", 2)]);
    assert_eq!(
        drive(
            &c,
            &["CU", "CU", "CD", "R", "CD", "LD"],
            &["CV", "QU", "QD"]
        ),
        [
            "CU: [CO] CV=1 QU=0 QD=0",
            "CU: [CO] CV=2 QU=1 QD=0",
            "CD: [CO] CV=1 QU=0 QD=0",
            "R: [RO] CV=0 QU=0 QD=1",
            "CD: [] CV=0 QU=0 QD=1",
            "LD: [LDO] CV=2 QU=1 QD=0",
        ]
    );
}

#[test]
fn the_bistables_emit_only_when_q_changes() {
    for ty in ["E_SR", "E_RS"] {
        let c = robot(ty, &[]);
        assert_eq!(
            drive(&c, &["R", "S", "S", "R", "R", "S"], &["Q"]),
            [
                "R: [] Q=0",
                "S: [EO] Q=1",
                "S: [] Q=1",
                "R: [EO] Q=0",
                "R: [] Q=0",
                "S: [EO] Q=1",
            ],
            "{ty}"
        );
    }
}

#[test]
fn e_t_ff_toggles_on_every_clock() {
    let c = robot("E_T_FF", &[]);
    assert_eq!(
        drive(&c, &["CLK", "CLK", "CLK"], &["Q"]),
        ["CLK: [EO] Q=1", "CLK: [EO] Q=0", "CLK: [EO] Q=1"]
    );
}

#[test]
fn e_d_ff_latches_d_and_says_so_only_on_a_change() {
    let one = robot("E_D_FF", &[("D", 1)]);
    assert_eq!(
        drive(&one, &["CLK", "CLK"], &["Q"]),
        ["CLK: [EO] Q=1", "CLK: [] Q=1"]
    );
    let zero = robot("E_D_FF", &[("D", 0)]);
    assert_eq!(drive(&zero, &["CLK"], &["Q"]), ["CLK: [] Q=0"]);
}

#[test]
fn split_merge_switch_permit_and_demux_route_events() {
    assert_eq!(
        drive(&robot("E_SPLIT", &[]), &["EI"], &[]),
        ["EI: [EO1 EO2] "]
    );
    assert_eq!(
        drive(&robot("E_MERGE", &[]), &["EI1", "EI2"], &[]),
        ["EI1: [EO] ", "EI2: [EO] "]
    );
    assert_eq!(
        drive(&robot("E_SWITCH", &[("G", 0)]), &["EI"], &[]),
        ["EI: [EO0] "]
    );
    assert_eq!(
        drive(&robot("E_SWITCH", &[("G", 1)]), &["EI"], &[]),
        ["EI: [EO1] "]
    );
    assert_eq!(
        drive(&robot("E_PERMIT", &[("PERMIT", 1)]), &["EI"], &[]),
        ["EI: [EO] "]
    );
    assert_eq!(
        drive(&robot("E_PERMIT", &[("PERMIT", 0)]), &["EI"], &[]),
        ["EI: [] "]
    );
    for k in 0..4 {
        assert_eq!(
            drive(&robot("E_DEMUX", &[("K", k)]), &["EI"], &[]),
            [format!("EI: [EO{k}] ")]
        );
    }
    assert_eq!(
        drive(&robot("E_DEMUX", &[("K", 4)]), &["EI"], &[]),
        ["EI: [] "],
        "K beyond the outputs: nothing"
    );
}

#[test]
fn the_edge_detectors_fire_once_per_edge() {
    // QI is the instance's (a parameter): TRUE at every EI is one rising edge, at the
    // first; FALSE at every EI never falls (QI was FALSE before the first).
    assert_eq!(
        drive(&robot("E_R_TRIG", &[("QI", 1)]), &["EI", "EI"], &[]),
        ["EI: [EO] ", "EI: [] "]
    );
    assert_eq!(
        drive(&robot("E_R_TRIG", &[("QI", 0)]), &["EI", "EI"], &[]),
        ["EI: [] ", "EI: [] "]
    );
    assert_eq!(
        drive(&robot("E_F_TRIG", &[("QI", 0)]), &["EI", "EI"], &[]),
        ["EI: [] ", "EI: [] "]
    );
}

#[test]
fn integer_arithmetic_wraps_at_the_declared_width_on_the_node() {
    // An INT that steps by 10000 and a USINT that steps by 100: IEC 61131-3 wraps them at
    // 16 and 8 bits; MOD and / as the standard rounds them.
    let dir = std::env::temp_dir().join(format!("iec61499-wrap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let fbt = r#"<?xml version="1.0" encoding="UTF-8"?>
<FBType Name="STEP">
  <InterfaceList>
    <EventInputs><Event Name="EI"/></EventInputs>
    <EventOutputs><Event Name="EO"/></EventOutputs>
    <OutputVars>
      <VarDeclaration Name="I" Type="INT"/>
      <VarDeclaration Name="U" Type="USINT"/>
      <VarDeclaration Name="M" Type="DINT"/>
    </OutputVars>
  </InterfaceList>
  <BasicFB>
    <ECC>
      <ECState Name="START"/>
      <ECState Name="STEP"><ECAction Algorithm="STEP" Output="EO"/></ECState>
      <ECTransition Source="START" Destination="STEP" Condition="EI"/>
      <ECTransition Source="STEP" Destination="START" Condition="1"/>
    </ECC>
    <Algorithm Name="STEP"><ST><![CDATA[I := I + 10000;
U := U + 100;
M := I MOD 7 + I / 1000;]]></ST></Algorithm>
  </BasicFB>
</FBType>
"#;
    std::fs::write(dir.join("STEP.fbt"), fbt).expect("write");
    let c = robot_in(&dir, "STEP", &[]);
    let trace = drive(&c, &["EI"; 4], &["I", "U", "M"]);
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(
        trace,
        [
            "EI: [EO] I=10000 U=100 M=14",
            "EI: [EO] I=20000 U=200 M=21",
            "EI: [EO] I=30000 U=44 M=35",
            // 40000 wraps to -25536 (= 7 * -3648: MOD 0); -25536 / 1000 rounds toward
            // zero: -25.
            "EI: [EO] I=-25536 U=144 M=-25",
        ]
    );
}

#[test]
fn a_for_loop_with_constant_bounds_runs_unrolled_on_the_node() {
    // Sums 1..4 (and, nested, a 2 x 3 grid with a downward step) into DINTs per event;
    // the control variables are left past their last value, as the loop leaves them.
    let dir = std::env::temp_dir().join(format!("iec61499-for-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let fbt = r#"<?xml version="1.0" encoding="UTF-8"?>
<FBType Name="SUMS">
  <InterfaceList>
    <EventInputs><Event Name="EI"/></EventInputs>
    <EventOutputs><Event Name="EO"/></EventOutputs>
    <OutputVars>
      <VarDeclaration Name="SUM" Type="DINT"/>
      <VarDeclaration Name="GRID" Type="DINT"/>
    </OutputVars>
  </InterfaceList>
  <BasicFB>
    <InternalVars>
      <VarDeclaration Name="I" Type="INT"/>
      <VarDeclaration Name="J" Type="INT"/>
    </InternalVars>
    <ECC>
      <ECState Name="START"/>
      <ECState Name="RUN"><ECAction Algorithm="RUN" Output="EO"/></ECState>
      <ECTransition Source="START" Destination="RUN" Condition="EI"/>
      <ECTransition Source="RUN" Destination="START" Condition="1"/>
    </ECC>
    <Algorithm Name="RUN"><ST><![CDATA[FOR I := 1 TO 4 DO
  SUM := SUM + I;
END_FOR;
FOR I := 20 TO 10 BY -10 DO
  FOR J := 1 TO 3 DO GRID := GRID + I * J; END_FOR;
END_FOR;]]></ST></Algorithm>
  </BasicFB>
</FBType>
"#;
    std::fs::write(dir.join("SUMS.fbt"), fbt).expect("write");
    let c = robot_in(&dir, "SUMS", &[]);
    let trace = drive(&c, &["EI"; 2], &["SUM", "GRID"]);
    let _ = std::fs::remove_dir_all(&dir);
    // 1 + 2 + 3 + 4 = 10 per event; (20 + 10) * (1 + 2 + 3) = 180 per event.
    assert_eq!(
        trace,
        ["EI: [EO] SUM=10 GRID=180", "EI: [EO] SUM=20 GRID=360"]
    );
}

#[test]
fn if_and_case_choose_on_the_node_and_the_ecc_rests_in_its_state() {
    let dir = std::env::temp_dir().join(format!("iec61499-if-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let fbt = r#"<?xml version="1.0" encoding="UTF-8"?>
<FBType Name="PICK">
  <InterfaceList>
    <EventInputs><Event Name="CU"/><Event Name="K"/></EventInputs>
    <EventOutputs><Event Name="EO"/></EventOutputs>
    <InputVars><VarDeclaration Name="PV" Type="INT"/></InputVars>
    <OutputVars>
      <VarDeclaration Name="CV" Type="INT"/>
      <VarDeclaration Name="Q" Type="BOOL"/>
      <VarDeclaration Name="Y" Type="INT"/>
    </OutputVars>
  </InterfaceList>
  <BasicFB>
    <ECC>
      <ECState Name="START"/>
      <ECState Name="CU"><ECAction Algorithm="CU" Output="EO"/></ECState>
      <ECState Name="K"><ECAction Algorithm="K"/></ECState>
      <ECTransition Source="START" Destination="CU" Condition="CU"/>
      <ECTransition Source="CU" Destination="START" Condition="1"/>
      <ECTransition Source="START" Destination="K" Condition="K"/>
      <ECTransition Source="K" Destination="START" Condition="1"/>
    </ECC>
    <Algorithm Name="CU"><ST><![CDATA[
IF CV < PV THEN
  CV := CV + 1;
  Q := FALSE;
ELSE
  Q := TRUE;
END_IF;]]></ST></Algorithm>
    <Algorithm Name="K"><ST><![CDATA[
CASE CV OF
  0: Y := 10;
  1, 2: Y := 20;
ELSE
  IF Q THEN Y := 40; ELSE Y := 30; END_IF;
END_CASE;]]></ST></Algorithm>
  </BasicFB>
</FBType>
"#;
    std::fs::write(dir.join("PICK.fbt"), fbt).expect("write");
    let c = robot_in(&dir, "PICK", &[("PV", 3)]);
    let _ = std::fs::remove_dir_all(&dir);
    let trace = drive(
        &c,
        &["K", "CU", "K", "CU", "CU", "K", "CU", "K"],
        &["CV", "Q", "Y"],
    );
    assert_eq!(
        trace,
        [
            "K: [] CV=0 Q=0 Y=10",
            "CU: [EO] CV=1 Q=0 Y=10",
            "K: [] CV=1 Q=0 Y=20",
            "CU: [EO] CV=2 Q=0 Y=20",
            "CU: [EO] CV=3 Q=0 Y=20",
            "K: [] CV=3 Q=0 Y=30",
            "CU: [EO] CV=3 Q=1 Y=30",
            "K: [] CV=3 Q=1 Y=40",
        ]
    );
    // Between stimuli the chart rests in START, as the ECC does (the chains of CU and K
    // ran within their stimulus).
    let chart = &c.ir.roles[0].charts[0];
    assert_eq!(chart.states[0].name, "START");
    assert!(chart.states.iter().any(|s| s.name == "CU.0"));
}
