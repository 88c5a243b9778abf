//! Importing IEC 61499 applications (`.sys`): the painting robot brought from 4diac files
//! compiles to the paper charts' tables byte for byte; a small application becomes roles,
//! charts and subscriptions; composite FBs flatten; and each kind of bad input is refused
//! with its exact message and place, changing nothing.

use std::collections::BTreeMap;

use robot_compiler::iec61499::import_with;
use robot_compiler::model::{self, Robot};
use robot_compiler::{check, compile, Source};

fn root() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn blobs(file: &str) -> Vec<(String, Vec<u8>)> {
    let src = Source::read(&root().join("robot-configs").join(file)).expect("reads");
    let c = compile(&src).unwrap_or_else(|d| panic!("{file}: {d:?}"));
    c.ir.roles
        .iter()
        .map(|r| r.name.clone())
        .zip(c.blobs.iter().cloned())
        .collect()
}

#[test]
fn the_4diac_painting_robot_compiles_to_the_paper_charts_tables_byte_for_byte() {
    let ours = blobs("paint-robot-4diac.ron");
    assert_eq!(
        ours.iter().map(|(r, _)| r.as_str()).collect::<Vec<_>>(),
        ["VC", "GR", "HC", "RC"]
    );
    assert_eq!(ours, blobs("paint-robot-paper-charts.ron"));
}

/// A robot of two roles on two nodes, bringing `a.sys`.
const ROBOT: &str = "Robot(name: \"r\", network: (pan_id: 1, channel: 11),
    nodes: [(name: \"n1\", address: 1), (name: \"n2\", address: 2)],
    roles: [(name: \"A\", inputs: [(name: \"PULSE\", pin: 0)]), (name: \"B\", outputs: [(name: \"LAMP\", pin: 1)])],
    fb_types: FBT,
    application: (file: \"a.sys\", on: {\"c.CU\": \"PULSE\"}, actions: ACTIONS))";

/// An up counter on `n1.A` setting a flip-flop on `n2.B`.
const SYS: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<System Name="S">
  <Application Name="App">
    <SubAppNetwork>
      <FB Name="c" Type="iec61499::events::E_CTU"><Parameter Name="PV" Value="UINT#3"/></FB>
      <FB Name="sr" Type="E_SR"/>
      <EventConnections>
        <Connection Source="c.CUO" Destination="sr.S"/>
      </EventConnections>
    </SubAppNetwork>
  </Application>
  <Device Name="n1"><Resource Name="A"/></Device>
  <Device Name="n2"><Resource Name="B"/></Device>
  <Mapping From="App.c" To="n1.A"/>
  <Mapping From="App.sr" To="n2.B"/>
</System>
"#;

/// The robot checked with `files` (`a.sys` and any `.fbt`); the errors as `check` prints
/// them.
fn run(fbt: &str, actions: &str, files: &[(&str, String)]) -> (Robot, Vec<String>) {
    let text = ROBOT.replace("FBT", fbt).replace("ACTIONS", actions);
    let src = Source::new("r.ron", text);
    let mut robot = model::parse(&src).expect("parses");
    let files: BTreeMap<String, Vec<u8>> = files
        .iter()
        .map(|(n, t)| (n.to_string(), t.as_bytes().to_vec()))
        .collect();
    let read = |name: &str| {
        files
            .get(name)
            .cloned()
            .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"))
    };
    let diags = import_with(&mut robot, &src, &read);
    (
        robot,
        diags.iter().map(|d| d.short(&src)).collect::<Vec<_>>(),
    )
}

fn sys_error(sys: &str) -> String {
    let (robot, errors) = run("[]", "{}", &[("a.sys", sys.to_string())]);
    // Nothing half imported: the roles are the robot file's, without charts.
    assert!(
        robot.roles.iter().all(|r| r.charts.is_empty()),
        "{errors:?}"
    );
    assert!(robot.chart_types.is_empty());
    assert_eq!(errors.len(), 1, "{errors:?}");
    errors[0].clone()
}

#[test]
fn an_application_becomes_roles_charts_and_a_subscription_across_the_mapping() {
    let (robot, errors) = run(
        "[]",
        "{\"sr.EO\": Out(\"LAMP\", true)}",
        &[("a.sys", SYS.into())],
    );
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(
        robot.assign,
        [("A".into(), "n1".into()), ("B".into(), "n2".into())]
    );
    let (a, b) = (&robot.roles[0].charts, &robot.roles[1].charts);
    assert_eq!((a.len(), b.len()), (1, 1));
    assert_eq!((a[0].name.as_str(), a[0].type_.as_str()), ("c", "E_CTU"));
    assert_eq!(a[0].params, BTreeMap::from([("PV".to_string(), 3)]));
    assert_eq!(
        a[0].on,
        BTreeMap::from([("CU".to_string(), "PULSE".to_string())])
    );
    // The connection the mapping cuts: B subscribes to A's `c.CUO`.
    assert_eq!((b[0].name.as_str(), b[0].type_.as_str()), ("sr", "E_SR_sr"));
    assert_eq!(
        b[0].on,
        BTreeMap::from([("S".to_string(), "A/c.CUO".to_string())])
    );
    let sr = robot.chart_type("E_SR_sr").expect("the bound copy").1;
    assert!(!sr.outputs.contains(&"EO".to_string()));
    // And it compiles: the whole robot checks.
    let text = ROBOT
        .replace("FBT", "[]")
        .replace("ACTIONS", "{\"sr.EO\": Out(\"LAMP\", true)}");
    let dir = std::env::temp_dir().join(format!("iec61499-sys-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("a.sys"), SYS).unwrap();
    let src = Source::new(dir.join("r.ron").to_string_lossy().as_ref(), text);
    let checked = check::check(&src);
    let _ = std::fs::remove_dir_all(&dir);
    assert!(!checked.has_errors(), "{:?}", checked.diagnostics);
    let ir = checked.ir.expect("elaborated");
    assert_eq!(
        ir.roles[1].imports,
        [("A".to_string(), "c.CUO".to_string(), "A/c.CUO".to_string())]
    );
}

/// A composite `CNT2` around an E_CTU and an E_SR: its interface connected through.
const COMPOSITE: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<FBType Name="CNT2">
  <InterfaceList>
    <EventInputs><Event Name="REQ"/></EventInputs>
    <EventOutputs><Event Name="CNF"/></EventOutputs>
    <InputVars><VarDeclaration Name="N" Type="UINT" InitialValue="2"/></InputVars>
  </InterfaceList>
  <FBNetwork>
    <FB Name="c" Type="E_CTU"/>
    <FB Name="sr" Type="E_SR"/>
    <EventConnections>
      <Connection Source="REQ" Destination="c.CU"/>
      <Connection Source="c.CUO" Destination="sr.S"/>
      <Connection Source="sr.EO" Destination="CNF"/>
    </EventConnections>
    <DataConnections>
      <Connection Source="N" Destination="c.PV"/>
    </DataConnections>
  </FBNetwork>
</FBType>
"#;

/// A chart as the test sees it: name, type, `on` and parameters.
type Chart<'a> = (
    &'a str,
    &'a str,
    Vec<(&'a str, &'a str)>,
    Vec<(&'a str, i32)>,
);

#[test]
fn composite_fbs_are_flattened_into_their_basic_fbs() {
    let sys = SYS
        .replace(
            r#"<FB Name="c" Type="iec61499::events::E_CTU"><Parameter Name="PV" Value="UINT#3"/></FB>"#,
            r#"<FB Name="k" Type="CNT2"><Parameter Name="N" Value="5"/></FB><FB Name="c" Type="E_CTU"/>"#,
        )
        .replace(
            r#"<Connection Source="c.CUO" Destination="sr.S"/>"#,
            r#"<Connection Source="c.CUO" Destination="k.REQ"/><Connection Source="k.CNF" Destination="sr.S"/>"#,
        )
        .replace(
            r#"<Mapping From="App.c" To="n1.A"/>"#,
            r#"<Mapping From="App.c" To="n1.A"/><Mapping From="App.k" To="n1.A"/>"#,
        );
    let (robot, errors) = run(
        "[\"CNT2.fbt\"]",
        "{}",
        &[("a.sys", sys), ("CNT2.fbt", COMPOSITE.into())],
    );
    assert!(errors.is_empty(), "{errors:?}");
    let charts: Vec<Chart<'_>> = robot
        .roles
        .iter()
        .flat_map(|r| &r.charts)
        .map(|c| {
            (
                c.name.as_str(),
                c.type_.as_str(),
                c.on.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect(),
                c.params.iter().map(|(k, v)| (k.as_str(), *v)).collect(),
            )
        })
        .collect();
    assert_eq!(
        charts,
        [
            ("k.c", "E_CTU", vec![("CU", "c.CUO")], vec![("PV", 5)]),
            ("k.sr", "E_SR", vec![("S", "k.c.CUO")], vec![]),
            ("c", "E_CTU", vec![("CU", "PULSE")], vec![("PV", 0)]),
            ("sr", "E_SR", vec![("S", "A/k.sr.EO")], vec![]),
        ]
    );
}

#[test]
fn a_sys_that_is_not_well_formed_is_refused_at_its_place() {
    assert_eq!(
        sys_error(&SYS.replace("<FB Name=\"sr\" Type=\"E_SR\"/>", "<FB Name=\"sr\" Type=\"E_SR\">")),
        "r.ron:5:25: error: a.sys:10:5: not well-formed XML: expected 'FB' tag, not 'SubAppNetwork' at 10:5"
    );
}

#[test]
fn an_unknown_element_is_refused_at_its_place() {
    assert_eq!(
        sys_error(&SYS.replace(
            "<EventConnections>",
            "<Frobnicate/>\n      <EventConnections>"
        )),
        "r.ron:5:25: error: a.sys:7:7: unknown element `Frobnicate` in `SubAppNetwork`"
    );
}

/// A scratch directory (`tag`) with the 4diac paint robot's files, each as `edit` makes
/// it: the directory and the robot file's text (to write there as `r.ron`).
fn paint_4diac_copy(tag: &str, edit: impl Fn(&str) -> String) -> (std::path::PathBuf, String) {
    let dir = std::env::temp_dir().join(format!("{tag}-{}", std::process::id()));
    let types = dir.join("4diac/paint-robot");
    std::fs::create_dir_all(&types).expect("dir");
    let configs = root().join("robot-configs");
    for entry in std::fs::read_dir(configs.join("4diac/paint-robot")).expect("4diac files") {
        let path = entry.expect("entry").path();
        let text = edit(&std::fs::read_to_string(&path).expect("reads"));
        std::fs::write(types.join(path.file_name().expect("name")), text).expect("writes");
    }
    let robot = std::fs::read_to_string(configs.join("paint-robot-4diac.ron")).expect("robot");
    (dir, robot)
}

/// `check` of `robot` written to `dir` as `r.ron` (beside the files it names): its
/// diagnostics, each `r.ron:LINE:COL: severity: message`.
fn check_r_ron(dir: &std::path::Path, robot: &str) -> Vec<String> {
    std::fs::write(dir.join("r.ron"), robot).expect("writes");
    let src = Source::read(&dir.join("r.ron")).expect("reads");
    (check::check(&src).diagnostics.iter())
        .map(|d| d.short(&src).replace(&*src.name, "r.ron"))
        .collect()
}

/// `check` of a robot whose application fails to import reports that failure alone, not
/// what follows from it (a robot without behaviour, its roles on no node).
#[test]
fn a_failed_import_is_the_only_error_check_reports() {
    let (dir, robot) = paint_4diac_copy("sys-import", |text| {
        text.replace("Source=\"gr.GR1\"", "Source=\"gr.ZZ\"")
    });
    assert_eq!(
        check_r_ron(&dir, &robot),
        ["r.ron:52:15: error: 4diac/paint-robot/PaintRobot.sys:19:9: `gr.ZZ`: `gr` (of type `Gr`) \
          has no event output `ZZ`"]
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A TIME literal gives each unit once, the larger first (IEC 61131-3): `T#150ms150ms`
/// was read as 300 ms, `T#1ms1h` as an hour and a millisecond. A parameter given twice
/// was taken at its first value, unsaid. Both are refused at their place in the file.
#[test]
fn a_time_with_a_unit_twice_and_a_parameter_given_twice_are_refused_at_their_place() {
    let dt = "<Parameter Name=\"DT\" Value=\"T#150ms\"/>";
    for (edit, error) in [
        (
            "<Parameter Name=\"DT\" Value=\"T#150ms150ms\"/>".to_string(),
            "4diac/paint-robot/PaintRobot.sys:14:9: E_DELAY `T` needs its `DT` as a TIME in \
             whole milliseconds (`T#150ms`)",
        ),
        (
            "<Parameter Name=\"DT\" Value=\"T#1ms1h\"/>".to_string(),
            "4diac/paint-robot/PaintRobot.sys:14:9: E_DELAY `T` needs its `DT` as a TIME in \
             whole milliseconds (`T#150ms`)",
        ),
        (
            format!("{dt}\n        <Parameter Name=\"DT\" Value=\"T#300ms\"/>"),
            "4diac/paint-robot/PaintRobot.sys:15:9: parameter `DT` of FB `T` is given twice",
        ),
    ] {
        let (dir, robot) = paint_4diac_copy("sys-params", |text| {
            match text.contains("PaintRobot") && text.contains(dt) {
                true => text.replacen(dt, &edit, 1),
                false => text.to_string(),
            }
        });
        assert_eq!(
            check_r_ron(&dir, &robot),
            [format!("r.ron:52:15: error: {error}")],
            "{edit}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// Warnings about a chart type read from an `.fbt` file pointed at its `fb_types` entry
/// and said nothing of where in the file (the overlap's other transition "at 49:44", the
/// entry again), and the unreachable state was warned twice (for the type an FB
/// instance's own actions made of it too): now each names the state's or transition's
/// line and column in the file, once.
#[test]
fn warnings_on_an_imported_chart_name_their_place_in_its_fbt_file() {
    let (dir, robot) = paint_4diac_copy("sys-written", |text| {
        if !text.contains("<FBType Name=\"Gr\"") {
            return text.to_string();
        }
        let s3 = "<ECState Name=\"S3\" Comment=\"\" x=\"2700\" y=\"400\"/>";
        let t =
            "<ECTransition Source=\"S3\" Destination=\"S4\" Condition=\"VC1\" x=\"0\" y=\"0\"/>";
        assert!(text.contains(s3) && text.contains(t));
        (text.replace(s3, &format!("{s3}\n      <ECState Name=\"S9\"/>")))
            .replace(t, &format!("{t}\n      {t}"))
    });
    assert_eq!(
        check_r_ron(&dir, &robot),
        [
            "r.ron:49:44: warning: 4diac/paint-robot/Gr.fbt:33:7: state `S9` of chart type `Gr` \
             is unreachable from its initial state `S0`",
            "r.ron:49:44: warning: 4diac/paint-robot/Gr.fbt:42:7: transitions `S3 -> S4` and \
             `S3 -> S4` leave `S3` on `VC1` and both guards can hold: the first declared wins",
        ]
    );
    let src = Source::read(&dir.join("r.ron")).expect("reads");
    let labels: Vec<String> = (check::check(&src).diagnostics.into_iter())
        .map(|d| d.label)
        .collect();
    assert_eq!(
        labels,
        [
            "no transition leads here",
            "overlaps the transition at 4diac/paint-robot/Gr.fbt:41:7"
        ]
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// An action of `application.actions` naming an actuator or output its FB's role lacks
/// was reported at `Robot(`, the first line of the file: now at its key, naming the
/// role's actuators (or outputs).
#[test]
fn an_action_naming_what_its_role_lacks_is_refused_at_its_key() {
    let (dir, robot) = paint_4diac_copy("sys-action", str::to_string);
    for (from, to, want) in [
        (
            "\"vc.VC_EXT\": Extend(\"VC\")",
            "\"vc.VC_EXT\": Extend(\"VX\")",
            "r.ron:68:13: error: `vc.VC_EXT`: no actuator `VX` (role `VC`'s actuators are VC)",
        ),
        (
            "\"gr.OPEN\": Retract(\"GR\")",
            "\"gr.OPEN\": Out(\"LAMP\", true)",
            "r.ron:71:13: error: `gr.OPEN`: no output `LAMP` (role `GR` has no outputs)",
        ),
    ] {
        assert!(robot.contains(from), "{from}");
        assert_eq!(check_r_ron(&dir, &robot.replace(from, to)), [want]);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_connection_to_a_missing_fb_or_port_is_refused_at_its_place() {
    assert_eq!(
        sys_error(&SYS.replace("Destination=\"sr.S\"", "Destination=\"sx.S\"")),
        "r.ron:5:25: error: a.sys:8:9: `sx.S`: no FB `sx` in this network"
    );
    assert_eq!(
        sys_error(&SYS.replace("Source=\"c.CUO\"", "Source=\"c.CUX\"")),
        "r.ron:5:25: error: a.sys:8:9: `c.CUX`: `c` (of type `E_CTU`) has no event output `CUX`"
    );
}

#[test]
fn an_unmapped_fb_is_refused_at_its_place() {
    assert_eq!(
        sys_error(&SYS.replace("<Mapping From=\"App.sr\" To=\"n2.B\"/>", "")),
        "r.ron:5:25: error: a.sys:6:7: FB `sr` is mapped to no resource (no `Mapping \
         From=\"App.sr\"`)"
    );
}

#[test]
fn an_unknown_or_service_fb_type_is_refused_at_its_place() {
    assert_eq!(
        sys_error(&SYS.replace("Type=\"E_SR\"", "Type=\"E_NOPE\"")),
        "r.ron:5:25: error: a.sys:6:7: FB `sr` is of type `E_NOPE`: no basic or composite FB \
         type of that name in the robot's `fb_types`, its `chart_types` or the library"
    );
    assert_eq!(
        sys_error(&SYS.replace("Type=\"E_SR\"", "Type=\"iec61499::events::E_CYCLE\"")),
        "r.ron:5:25: error: a.sys:6:7: FB `sr` is of type `E_CYCLE`, a service FB: not \
         supported (only basic and composite FB types, and E_DELAY)"
    );
}

#[test]
fn adapters_fan_in_and_data_connections_across_resources_are_refused_at_their_place() {
    assert_eq!(
        sys_error(&SYS.replace(
            "<EventConnections>",
            "<AdapterConnections><Connection Source=\"c.P\" Destination=\"sr.S\"/></AdapterConnections>\n      <EventConnections>"
        )),
        "r.ron:5:25: error: a.sys:7:27: adapter connections are not supported"
    );
    assert_eq!(
        sys_error(&SYS.replace(
            "</EventConnections>",
            "  <Connection Source=\"c.RO\" Destination=\"sr.S\"/>\n      </EventConnections>"
        )),
        "r.ron:5:25: error: a.sys:9:9: `sr.S` has a second event connection: join its \
         sources with an E_MERGE"
    );
    assert_eq!(
        sys_error(&SYS.replace(
            "</EventConnections>",
            "</EventConnections>\n      <DataConnections><Connection Source=\"sr.Q\" Destination=\"c.PV\"/></DataConnections>"
        ).replace("<Parameter Name=\"PV\" Value=\"UINT#3\"/>", "")),
        "r.ron:5:25: error: a.sys:10:24: data connection `sr.Q` -> `c.PV` crosses resources \
         (`sr` is on `B`, `c` on `A`): events between nodes carry no data; map both FBs onto \
         one resource, or give `PV` a parameter"
    );
}

#[test]
fn a_device_that_is_no_node_and_a_bad_binding_are_refused() {
    assert_eq!(
        sys_error(
            &SYS.replace("Device Name=\"n2\"", "Device Name=\"n9\"")
                .replace("To=\"n2.B\"", "To=\"n9.B\"")
        ),
        "r.ron:5:25: error: a.sys:13:3: device `n9` is no node of the robot: add it to the \
         robot file's `nodes` with its 802.15.4 short address"
    );
    let (robot, errors) = run(
        "[]",
        "{\"sr.NOPE\": Extend(\"X\")}",
        &[("a.sys", SYS.into())],
    );
    assert_eq!(
        errors,
        ["r.ron:5:67: error: `sr.NOPE`: `E_SR` has no event output `NOPE`"]
    );
    assert!(robot.roles.iter().all(|r| r.charts.is_empty()));
}

/// Role A's node services FB type, as `export-4diac` writes one: its input `PULSE` as an
/// event output (the `Comment` names the node event), an event input for services.
const A_IO: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<FBType Name="A_IO">
  <Identification Standard="61499-2" Classification="ecc-nodes services"/>
  <InterfaceList>
    <EventInputs><Event Name="c_FAULT_1" Type="Event" Comment=""/></EventInputs>
    <EventOutputs><Event Name="PULSE_IN" Type="Event" Comment="PULSE"/></EventOutputs>
  </InterfaceList>
  <Service RightInterface="RESOURCE" LeftInterface="A_IO"/>
</FBType>
"#;

/// `SYS` with A's node services FB feeding `c.CU`, and the cut connection rendered in
/// the resources as `export-4diac` does (`EXTRA` goes into the application network,
/// `TOPIC` is the PUBLISH's `ID`).
const SYS_IO: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<System Name="S">
  <Application Name="App">
    <SubAppNetwork>
      <FB Name="c" Type="E_CTU"><Parameter Name="PV" Value="UINT#3"/></FB>
      <FB Name="sr" Type="E_SR"/>
      <FB Name="A_IO" Type="A_IO"/>
      <EventConnections>
        <Connection Source="c.CUO" Destination="sr.S"/>
        <Connection Source="A_IO.PULSE_IN" Destination="c.CU"/>EXTRA
      </EventConnections>
    </SubAppNetwork>
  </Application>
  <Device Name="n_1"><Resource Name="A"><FBNetwork>
    <FB Name="c" Type="E_CTU"/><FB Name="A_IO" Type="A_IO"/>
    <FB Name="PUBLISH_1" Type="PUBLISH_0"><Parameter Name="ID" Value="&quot;TOPIC&quot;"/></FB>
  </FBNetwork></Resource></Device>
  <Device Name="n2"><Resource Name="B"><FBNetwork>
    <FB Name="sr" Type="E_SR"/>
    <FB Name="SUBSCRIBE_1" Type="SUBSCRIBE_0"><Parameter Name="ID" Value="&quot;A/c.CUO&quot;"/></FB>
  </FBNetwork></Resource></Device>
  <Mapping From="App.c" To="n_1.A"/>
  <Mapping From="App.sr" To="n2.B"/>
  <Mapping From="App.A_IO" To="n_1.A.A_IO"/>
</System>
"#;

/// The robot of `ROBOT` with node `n1` named `n-1` (a device `n_1` stands for it) and no
/// `on` (A's node services FB feeds `c.CU`), checked with `SYS_IO`'s `EXTRA` and `TOPIC`.
fn run_io(extra: &str, id: &str) -> (Robot, Vec<String>) {
    let text = ROBOT
        .replace("\"n1\"", "\"n-1\"")
        .replace("FBT", "[\"A_IO.fbt\"]")
        .replace("on: {\"c.CU\": \"PULSE\"}, ", "")
        .replace("ACTIONS", "{\"sr.EO\": Out(\"LAMP\", true)}");
    let src = Source::new("r.ron", text);
    let mut robot = model::parse(&src).expect("parses");
    let sys = SYS_IO.replace("EXTRA", extra).replace("TOPIC", id);
    let read = |name: &str| match name {
        "a.sys" => Ok(sys.as_bytes().to_vec()),
        "A_IO.fbt" => Ok(A_IO.as_bytes().to_vec()),
        _ => Err(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            "no such file",
        )),
    };
    let diags = import_with(&mut robot, &src, &read);
    (robot, diags.iter().map(|d| d.short(&src)).collect())
}

/// A node services FB (`ROLE_IO`, as `export-4diac` writes it) stands for its resource's
/// node: its output feeds `c.CU` with the node event its `Comment` names; the PUBLISH /
/// SUBSCRIBE pair the export writes for a cut connection is accepted; the device `n_1`
/// is the node `n-1`.
#[test]
fn a_node_services_fb_feeds_its_roles_events_and_export_pub_sub_pairs_are_accepted() {
    let (robot, errors) = run_io("", "A/c.CUO");
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(
        robot.assign,
        [("A".into(), "n-1".into()), ("B".into(), "n2".into())]
    );
    let (a, b) = (&robot.roles[0].charts, &robot.roles[1].charts);
    assert_eq!(
        (a.len(), a[0].name.as_str(), b.len(), b[0].name.as_str()),
        (1, "c", 1, "sr")
    );
    assert_eq!(
        a[0].on,
        BTreeMap::from([("CU".to_string(), "PULSE".to_string())])
    );
    assert_eq!(
        b[0].on,
        BTreeMap::from([("S".to_string(), "A/c.CUO".to_string())])
    );
}

/// A PUBLISH in a resource carrying no cut connection, a chart's own output into a node
/// services FB, two node services FBs joined, a node services FB into a timer of another
/// role: each refused at its place, nothing imported.
#[test]
fn misused_node_services_fbs_and_stray_pub_sub_fbs_are_refused_at_their_place() {
    let cases = [
        (
            "",
            "A/c.CV",
            "r.ron:5:25: error: a.sys:16:43: `PUBLISH_1` (`PUBLISH_0`) of resource `A` publishes \
             `A/c.CV`, no connection of the application that the mapping cuts from this \
             resource: a PUBLISH / SUBSCRIBE FB in a resource may only carry one \
             (`\"ROLE/FB.EVENT\"`); connect the FBs in the application",
        ),
        (
            "<Connection Source=\"sr.EO\" Destination=\"A_IO.c_FAULT_1\"/>",
            "A/c.CUO",
            "r.ron:5:25: error: a.sys:10:64: `A_IO.c_FAULT_1` takes the node services of its \
             resource's charts (`EXTEND_A`, `START_T_150`, ... of a type marked `ecc-nodes \
             chart`): `sr.EO` is none",
        ),
        (
            "<Connection Source=\"A_IO.PULSE_IN\" Destination=\"A_IO.c_FAULT_1\"/>",
            "A/c.CUO",
            "r.ron:5:25: error: a.sys:10:64: `A_IO.PULSE_IN` -> `A_IO.c_FAULT_1` joins two node \
             services FBs",
        ),
    ];
    for (extra, id, want) in cases {
        let (robot, errors) = run_io(extra, id);
        assert_eq!(errors, [want.to_string()], "{extra}");
        assert!(robot.roles.iter().all(|r| r.charts.is_empty()));
    }
}

/// A chart type as the export marks it, whose input variable `N` reads the value of
/// `SOURCE` (`value of FB.VAR`).
const READER: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<FBType Name="Rd">
  <Identification Standard="61499-2" Classification="ecc-nodes chart"/>
  <InterfaceList>
    <EventInputs><Event Name="REQ"/></EventInputs>
    <EventOutputs><Event Name="HIGH"/></EventOutputs>
    <InputVars><VarDeclaration Name="N" Type="DINT" Comment="value of SOURCE"/></InputVars>
  </InterfaceList>
  <BasicFB>
    <ECC>
      <ECState Name="S0"/>
      <ECState Name="S1"><ECAction Output="HIGH"/></ECState>
      <ECTransition Source="S0" Destination="S1" Condition="REQ[N &gt; 1]"/>
      <ECTransition Source="S1" Destination="S0" Condition="1"/>
    </ECC>
  </BasicFB>
</FBType>
"#;

/// `sys` with `rd` (of `READER`) on resource A beside the counter `c`.
fn with_reader(sys: &str) -> String {
    sys.replace(
        r#"<FB Name="sr" Type="E_SR"/>"#,
        r#"<FB Name="sr" Type="E_SR"/><FB Name="rd" Type="Rd"/>"#,
    )
    .replace(
        r#"<Mapping From="App.c" To="n1.A"/>"#,
        r#"<Mapping From="App.c" To="n1.A"/><Mapping From="App.rd" To="n1.A"/>"#,
    )
}

/// `rd` (of `READER`) on resource A beside the counter `c`, and `sr` on B.
fn reader(source: &str) -> (Robot, Vec<String>) {
    let sys = with_reader(SYS);
    run(
        "[\"Rd.fbt\"]",
        "{}",
        &[("a.sys", sys), ("Rd.fbt", READER.replace("SOURCE", source))],
    )
}

#[test]
fn an_input_variable_reading_another_fbs_variable_reads_it_on_its_resource() {
    let (robot, errors) = reader("c.CV");
    assert!(errors.is_empty(), "{errors:?}");
    let rd = &robot.roles[0].charts[1];
    assert_eq!(rd.name, "rd");
    assert!(rd.params.is_empty());
    assert_eq!(
        rd.reads,
        BTreeMap::from([("N".to_string(), "c.CV".to_string())])
    );
    assert_eq!(
        reader("nope.CV").1,
        [
            "r.ron:5:25: error: a.sys:6:34: input `N` of `rd` (of type `Rd`) reads `nope.CV` \
          (its `Comment`): no basic FB `nope` on its resource `A`"
        ]
    );
    assert_eq!(
        reader("sr.Q").1,
        [
            "r.ron:5:25: error: a.sys:6:34: input `N` of `rd` (of type `Rd`) reads `sr.Q` (its \
          `Comment`): no basic FB `sr` on its resource `A`"
        ]
    );
    assert_eq!(
        reader("c.XV").1,
        [
            "r.ron:5:25: error: a.sys:6:34: input `N` of `rd` (of type `Rd`) reads `c.XV` (its \
          `Comment`): `c` (of type `E_CTU`) has no variable `XV`"
        ]
    );
}

/// A data connection reaches through a composite's output: `k.CV` (the composite's
/// output, its inner `c.CV` connected to it) into the counter `c` beside it on resource
/// A: `c` reads `k.c.CV` for its `PV`.
#[test]
fn a_data_connection_through_a_composites_output_reads_the_inner_fbs_variable() {
    let composite = COMPOSITE
        .replace(
            "</InputVars>",
            "</InputVars>\n    <OutputVars><VarDeclaration Name=\"CV\" Type=\"UINT\"/></OutputVars>",
        )
        .replace(
            "<Connection Source=\"N\" Destination=\"c.PV\"/>",
            "<Connection Source=\"N\" Destination=\"c.PV\"/>\n      <Connection Source=\"c.CV\" Destination=\"CV\"/>",
        );
    let sys = SYS
        .replace(
            r#"<FB Name="c" Type="iec61499::events::E_CTU"><Parameter Name="PV" Value="UINT#3"/></FB>"#,
            r#"<FB Name="k" Type="CNT2"/><FB Name="c" Type="E_CTU"/>"#,
        )
        .replace(
            "</EventConnections>",
            "</EventConnections>\n      <DataConnections><Connection Source=\"k.CV\" Destination=\"c.PV\"/></DataConnections>",
        )
        .replace(
            r#"<Mapping From="App.c" To="n1.A"/>"#,
            r#"<Mapping From="App.c" To="n1.A"/><Mapping From="App.k" To="n1.A"/>"#,
        );
    let (robot, errors) = run(
        "[\"CNT2.fbt\"]",
        "{}",
        &[("a.sys", sys), ("CNT2.fbt", composite)],
    );
    assert!(errors.is_empty(), "{errors:?}");
    type Reads<'a> = (&'a str, Vec<(&'a str, i32)>, Vec<(&'a str, &'a str)>);
    let charts: Vec<Reads<'_>> = (robot.roles.iter())
        .flat_map(|r| &r.charts)
        .map(|c| {
            (
                c.name.as_str(),
                c.params.iter().map(|(k, v)| (k.as_str(), *v)).collect(),
                c.reads
                    .iter()
                    .map(|(k, v)| (k.as_str(), v.as_str()))
                    .collect(),
            )
        })
        .collect();
    assert_eq!(
        charts,
        [
            ("k.c", vec![("PV", 2)], vec![]),
            ("k.sr", vec![], vec![]),
            ("c", vec![], vec![("PV", "k.c.CV")]),
            ("sr", vec![], vec![]),
        ]
    );
}

/// Two charts of one role, `b` (declared first) of a type guarding on its parameter `N`,
/// `a` of a type with a variable `v`.
const POOL: &str = r#"Robot(name: "p", network: (pan_id: 1, channel: 11),
    nodes: [(name: "n1", address: 1)], assign: [("A", "n1")],
    roles: [(name: "A", inputs: [(name: "GO", pin: 0)], charts: [
        (name: "b", type: "Reader", on: {"GO": "GO"}),
        (name: "a", type: "Holder"),
    ])],
    chart_types: [
        (name: "Reader", params: ["N"], inputs: ["GO"],
         states: [(name: "S0"), (name: "S1")],
         transitions: [(from: "S0", to: "S1", on: "GO", when: "N > 1")]),
        (name: "Holder", vars: [(name: "w", init: "7"), (name: "v", init: "5")],
         states: [(name: "S0")]),
    ],
)"#;

/// A parameter an instance reads from another chart's variable
/// ([`model::ChartInstance::reads`], as an application brings it) is that variable in
/// the role's pool, though its chart comes later; one naming no variable of the role,
/// or no parameter, is an error.
#[test]
fn a_parameter_read_from_another_charts_variable_is_that_variable() {
    let src = Source::new("p.ron", POOL);
    let with = |param: &str, var: &str| {
        let mut robot = model::parse(&src).expect("parses");
        robot.roles[0].charts[0]
            .reads
            .insert(param.to_string(), var.to_string());
        robot_compiler::elab::elaborate(&robot, &src)
            .map_err(|d| d.iter().map(|x| x.message.clone()).collect::<Vec<String>>())
    };
    let ir = with("N", "a.v").expect("elaborates");
    let r = &ir.roles[0];
    assert_eq!(r.vars, [("a.w".to_string(), 7), ("a.v".to_string(), 5)]);
    let guard = r.charts[0].transitions[0].guard.clone().expect("a guard");
    assert_eq!(
        guard.1,
        [
            config_schema::Op::Var(1),
            config_schema::Op::Const(1),
            config_schema::Op::Gt
        ]
    );
    assert_eq!(
        with("N", "a.x").err(),
        Some(vec![String::from(
            "parameter `N` of chart `b` reads `a.x`: no chart of role `A` has that variable"
        )])
    );
    assert_eq!(
        with("M", "a.v").err(),
        Some(vec![
            String::from(
                "chart type `Reader` has no parameter `M` (chart `b` reads `a.v` into it)"
            ),
            String::from("parameter `N` of chart type `Reader` has no value"),
            String::from("unknown name `N`: not a variable, input or parameter of this chart"),
        ])
    );
}

/// What `check` says of the robot bringing `files` (`a.sys` and the `.fbt`s `fbt` lists),
/// one line each.
fn checked(fbt: &str, files: &[(&str, String)]) -> Vec<String> {
    let text = ROBOT.replace("FBT", fbt).replace("ACTIONS", "{}");
    let dir = std::env::temp_dir().join(format!(
        "iec61499-sys-checked-{}-{}",
        std::process::id(),
        files.len()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, text) in files {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let checked = check_r_ron(&dir, &text);
    let _ = std::fs::remove_dir_all(&dir);
    checked
}

/// A problem of a chart the application declares is reported where the application
/// declares it (its `FB` element, or the connection into the input), as an error in its
/// XML is: at the robot file's `application`, the place in the `.sys` first.
#[test]
fn a_problem_of_an_application_chart_names_its_place_in_the_application() {
    assert_eq!(
        checked("[]", &[("a.sys", SYS.into())]),
        [
            "r.ron:5:25: warning: a.sys:5:7: chart `c` publishes `RO` but nobody uses it",
            "r.ron:5:25: warning: a.sys:5:7: input `R` of chart `c` is connected to no event",
            "r.ron:5:25: warning: a.sys:6:7: chart `sr` publishes `EO` but nobody uses it",
            "r.ron:5:25: warning: a.sys:6:7: input `R` of chart `sr` is connected to no event",
        ]
    );
    // `rd` (on A) never emits `HIGH`, which resets `sr` (on B): the connection is where
    // the application subscribes to nothing.
    let sys = with_reader(SYS).replace(
        r#"<Connection Source="c.CUO" Destination="sr.S"/>"#,
        "<Connection Source=\"c.CUO\" Destination=\"sr.S\"/>\n        \
         <Connection Source=\"c.RO\" Destination=\"rd.REQ\"/>\n        \
         <Connection Source=\"rd.HIGH\" Destination=\"sr.R\"/>",
    );
    let never = READER
        .replace("SOURCE", "c.CV")
        .replace(r#"<ECAction Output="HIGH"/>"#, "");
    assert_eq!(
        checked("[\"Rd.fbt\"]", &[("a.sys", sys), ("Rd.fbt", never)]),
        [
            "r.ron:5:25: error: a.sys:10:9: `A/rd.HIGH` is subscribed here but nobody \
             publishes it: no state of chart `rd` emits `HIGH`",
            "r.ron:5:25: warning: a.sys:5:7: input `R` of chart `c` is connected to no event",
            "r.ron:5:25: warning: a.sys:6:7: chart `sr` publishes `EO` but nobody uses it",
        ]
    );
}

/// An unknown event given in the robot file's `application.on` is named at its key there
/// (the whole role block was underlined, far from it).
#[test]
fn an_unknown_event_of_application_on_is_named_at_its_key() {
    let text = ROBOT
        .replace("FBT", "[]")
        .replace("ACTIONS", "{}")
        .replace("\"c.CU\": \"PULSE\"", "\"c.CU\": \"PLUSE\"");
    let dir = std::env::temp_dir().join(format!("iec61499-sys-on-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("a.sys"), SYS).unwrap();
    let path = dir.join("r.ron").to_string_lossy().into_owned();
    let src = Source::new(&path, text);
    let checked = check::check(&src);
    let _ = std::fs::remove_dir_all(&dir);
    let errors: Vec<String> = (checked.diagnostics.iter())
        .filter(|d| d.is_error())
        .map(|d| d.short(&src).replace(&format!("{path}:"), "r.ron:"))
        .collect();
    assert_eq!(
        errors,
        ["r.ron:5:39: error: unknown event `PLUSE` of role `A`"]
    );
}
