//! Importing IEC 61499-2 basic FB types (`.fbt`): what becomes of a good one, and the
//! exact error, with its line:col in the XML, of each kind of bad one.

use robot_compiler::iec61499::fbt::{import, XmlError};
use robot_compiler::model::{ActionDecl, TransitionDecl};
use robot_compiler::{check, Source};

/// A basic FB `T` with the given interface variables, ECC and algorithms.
fn fbt(vars: &str, ecc: &str, algorithms: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<FBType Name="T">
  <InterfaceList>
    <EventInputs><Event Name="EI"/></EventInputs>
    <EventOutputs><Event Name="EO"/></EventOutputs>
{vars}
  </InterfaceList>
  <BasicFB>
    <ECC>
{ecc}
    </ECC>
{algorithms}
  </BasicFB>
</FBType>
"#
    )
}

const VARS: &str = r#"    <InputVars><VarDeclaration Name="N" Type="INT"/></InputVars>
    <OutputVars><VarDeclaration Name="C" Type="INT" InitialValue="16#10"/></OutputVars>"#;

const ECC: &str = r#"      <ECState Name="START"/>
      <ECState Name="GO"><ECAction Algorithm="A" Output="EO"/></ECState>
      <ECTransition Source="START" Destination="GO" Condition="EI[C &lt; N]"/>
      <ECTransition Source="GO" Destination="START" Condition="1"/>"#;

const ALG: &str = r#"    <Algorithm Name="A"><ST Text="C := C + 1;"/></Algorithm>"#;

/// A robot of one chart of type `T`, imported from `T.fbt` beside it.
const ROBOT: &str = "Robot(name: \"r\", network: (pan_id: 1, channel: 11), \
    nodes: [(name: \"n1\", address: 1)], assign: [(\"A\", \"n1\")], \
    roles: [(name: \"A\", inputs: [(name: \"I\", pin: 0)], \
    charts: [(name: \"t\", type: \"T\", params: {\"N\": 3}, on: {\"EI\": \"I\"})])], \
    fb_types: [\"T.fbt\"])";

fn error(text: &str) -> String {
    let e: XmlError = import(text).expect_err("refused");
    e.to_string()
}

#[test]
fn a_basic_fb_becomes_a_chart_type() {
    let t = import(&fbt(VARS, ECC, ALG)).expect("imports");
    assert_eq!(
        (
            t.name.as_str(),
            t.params.clone(),
            t.inputs.clone(),
            t.outputs.clone()
        ),
        (
            "T",
            vec!["N".to_string()],
            vec!["EI".to_string()],
            vec!["EO".to_string()]
        )
    );
    assert_eq!(
        t.vars
            .iter()
            .map(|v| (v.name.as_str(), v.init.as_str()))
            .collect::<Vec<_>>(),
        [("C", "16")]
    );
    assert_eq!(
        t.states[1].actions,
        [
            ActionDecl::Set("C".to_string(), "int(C + 1)".to_string()),
            ActionDecl::Emit("EO".to_string())
        ]
    );
    let tr = |t: &TransitionDecl| (t.from.clone(), t.to.clone(), t.on.clone(), t.when.clone());
    assert_eq!(
        t.transitions.iter().map(tr).collect::<Vec<_>>(),
        [
            (
                "START".into(),
                "GO".into(),
                Some("EI".into()),
                Some("(C < N)".into())
            ),
            ("GO".into(), "START".into(), None, None),
        ]
    );
}

#[test]
fn every_condition_form_the_tools_write() {
    let with = |cond: &str| {
        let ecc = ECC.replace("EI[C &lt; N]", cond);
        let t = import(&fbt(VARS, &ecc, ALG)).expect("imports");
        (t.transitions[0].on.clone(), t.transitions[0].when.clone())
    };
    let guard = Some("(C < N)".to_string());
    let ei = Some("EI".to_string());
    assert_eq!(with("EI[C &lt; N]"), (ei.clone(), guard.clone()));
    assert_eq!(
        with("EI &amp; C &lt; N"),
        (ei.clone(), guard.clone()),
        "1st edition, FBDK"
    );
    assert_eq!(with("ei AND C &lt; N"), (ei.clone(), guard.clone()));
    assert_eq!(with("[C &lt; N]"), (None, guard.clone()));
    assert_eq!(with("C &lt; N"), (None, guard));
    assert_eq!(with("EI"), (ei, None));
    assert_eq!(with("TRUE"), (None, None));
}

/// Text after a condition's event that is no guard is refused where it is, whatever its
/// characters (a non-ASCII one there panicked: a slice of three bytes).
#[test]
fn a_condition_with_other_text_after_its_event_is_refused_there() {
    for after in ["éé", "Aé", "x"] {
        let ecc = ECC.replace("EI[C &lt; N]", &format!("EI {after}"));
        let col = ECC
            .lines()
            .nth(2)
            .and_then(|l| l.find("EI["))
            .expect("the condition")
            + 4;
        assert_eq!(
            error(&fbt(VARS, &ecc, ALG)),
            format!("13:{col}: expected `[guard]` or `& guard` after the event `EI`"),
            "{after}"
        );
    }
}

/// An ECC of more states or transitions than a table holds is refused at the first one
/// too many, before anything compares them in pairs.
#[test]
fn an_ecc_past_the_capacities_is_refused_at_the_first_one_too_many() {
    let states: String = (0..100_000)
        .map(|i| format!("<ECState Name=\"S{i}\"/>"))
        .collect();
    let ecc = ECC.replace(
        "<ECState Name=\"START\"/>",
        &format!("<ECState Name=\"START\"/>{states}"),
    );
    let at = 1
        + r#"      <ECState Name="START"/>"#.len()
        + (0..95)
            .map(|i| format!("<ECState Name=\"S{i}\"/>").len())
            .sum::<usize>();
    assert_eq!(
        error(&fbt(VARS, &ecc, ALG)),
        format!("11:{at}: an ECC of more than 96 states: a table holds at most 96 (MAX_STATES)")
    );
    let back = r#"<ECTransition Source="GO" Destination="START" Condition="1"/>"#;
    let ecc = ECC.replace(back, &back.repeat(100_000));
    let at = 7 + back.len() * 127;
    assert_eq!(
        error(&fbt(VARS, &ecc, ALG)),
        format!("14:{at}: an ECC of more than 128 transitions: a table holds at most 128 (MAX_TRANSITIONS)")
    );
}

/// An interface or a choice past the capacities is refused at the first one too many, in
/// linear time: 20,000 event inputs took 6 s (each name compared with every one before
/// it), and an `IF` of 20,000 `ELSIF`s 77 s and 2.8 GB (each arm's guard negating every arm
/// before it), refused only as a chart type of 20,004 states at the robot's `fb_types`.
#[test]
fn an_interface_or_a_choice_past_the_capacities_is_refused_at_the_first_one_too_many() {
    let events: String = (0..100_000)
        .map(|i| format!("<Event Name=\"E{i}\"/>"))
        .collect();
    let text = fbt(VARS, ECC, ALG).replace(
        "<Event Name=\"EI\"/></EventInputs>",
        &format!("<Event Name=\"EI\"/>{events}</EventInputs>"),
    );
    let at = 18
        + r#"<Event Name="EI"/>"#.len()
        + (0..31)
            .map(|i| format!("<Event Name=\"E{i}\"/>").len())
            .sum::<usize>();
    assert_eq!(
        error(&text),
        format!("4:{at}: more than 32 events in `EventInputs`: a table holds at most 32 (MAX_CHART_INPUTS)")
    );
    let vars: String = (0..100_000)
        .map(|i| format!("<VarDeclaration Name=\"V{i}\" Type=\"INT\"/>"))
        .collect();
    let text = fbt(&format!("    <OutputVars>{vars}</OutputVars>"), ECC, ALG);
    let at = 17
        + (0..32)
            .map(|i| format!("<VarDeclaration Name=\"V{i}\" Type=\"INT\"/>").len())
            .sum::<usize>();
    assert_eq!(
        error(&text),
        format!("6:{at}: more than 32 variables: a table holds at most 32 (MAX_VARS)")
    );
    // Parameters (input variables) take no table variable: 40 of them are a type's.
    let params: String = (0..40)
        .map(|i| format!("<VarDeclaration Name=\"P{i}\" Type=\"INT\"/>"))
        .collect();
    let text = fbt(
        &VARS.replace("<InputVars>", &format!("<InputVars>{params}")),
        ECC,
        ALG,
    );
    assert!(import(&text).is_ok());
    let arms = "ELSIF N > 0 THEN C := 1; ".repeat(20_000);
    let alg = format!(
        "    <Algorithm Name=\"A\"><ST Text=\"IF N &gt; 0 THEN C := 1; {arms}END_IF;\"/></Algorithm>"
    );
    assert_eq!(
        error(&fbt(VARS, ECC, &alg)),
        "12:7: state `GO` chooses among so many arms that its chain takes more than 96 states: \
         a table holds at most 96 (MAX_STATES)"
    );
}

#[test]
fn bad_xml_is_refused_with_its_place() {
    assert_eq!(
        error("<FBType Name=\"T\">\n  <InterfaceList>\n</FBType>"),
        "3:1: not well-formed XML: expected 'InterfaceList' tag, not 'FBType' at 3:1"
    );
    assert_eq!(
        error("<ResourceType Name=\"R\"/>"),
        "1:1: `ResourceType` is not a function block type (`FBType`)"
    );
    let composite = fbt(VARS, ECC, ALG).replace("<BasicFB>", "<FBNetwork/>\n  <BasicFB>");
    assert_eq!(
        error(&composite),
        "9:3: `T` is a FBNetwork FB type: only basic FB types (`BasicFB`) are supported"
    );
    let real = fbt(
        &VARS.replace("Name=\"C\" Type=\"INT\"", "Name=\"C\" Type=\"REAL\""),
        ECC,
        ALG,
    );
    assert_eq!(
        error(&real),
        "7:17: `C` is of type REAL: supported are BOOL, SINT, INT, DINT, USINT, UINT and UDINT"
    );
    let missing = fbt(
        VARS,
        &ECC.replace("Destination=\"GO\"", "Destination=\"GOO\""),
        ALG,
    );
    assert_eq!(error(&missing), "13:49: no state `GOO`");
    let st = fbt(VARS, ECC, &ALG.replace("C := C + 1;", "C := C + ;"));
    assert_eq!(error(&st), "16:44: expected an expression, found `;`");
    let ld = fbt(
        VARS,
        ECC,
        &ALG.replace("<ST Text=\"C := C + 1;\"/>", "<LD/>"),
    );
    assert_eq!(
        error(&ld),
        "16:25: algorithm `A` is in LD: only Structured Text (`ST`) is supported"
    );
    let cond = fbt(VARS, &ECC.replace("EI[C &lt; N]", "EI[C + N]"), ALG);
    assert_eq!(error(&cond), "13:67: a transition condition must be BOOL");
    let unknown = fbt(VARS, &ECC.replace("EI[C &lt; N]", "EJ[C]"), ALG);
    assert_eq!(
        error(&unknown),
        "13:64: `EJ` is not an event input of this FB type"
    );
    // An `InternalVars` in the interface (its place is the `BasicFB`) was dropped unsaid:
    // the only error was a later `unknown name` where a variable of it was used.
    let misplaced = fbt(
        &format!(
            "{VARS}\n    <InternalVars><VarDeclaration Name=\"X\" Type=\"INT\"/></InternalVars>"
        ),
        ECC,
        ALG,
    );
    assert_eq!(
        error(&misplaced),
        "8:5: unknown element `InternalVars` in `InterfaceList`"
    );
}

#[test]
fn a_robot_names_the_file_and_its_place_and_imports_nothing_of_a_bad_type() {
    let dir = std::env::temp_dir().join(format!("iec61499-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("T.fbt"),
        fbt(
            VARS,
            ECC,
            &ALG.replace("C := C + 1;", "WHILE C &gt; 0 DO C := 0; END_WHILE;"),
        ),
    )
    .unwrap();
    let src = Source::new(
        dir.join("r.ron").to_string_lossy().as_ref(),
        ROBOT.to_string(),
    );
    let checked = check::check(&src);
    let errors: Vec<String> = checked
        .diagnostics
        .iter()
        .filter(|d| d.is_error())
        .map(|d| d.short(&src).replace(&*src.name, "r.ron"))
        .collect();
    assert_eq!(
        errors[0],
        "r.ron:1:244: error: T.fbt:16:35: `WHILE` is not supported yet (the subset: \
         assignments, IF, CASE, FOR with constant bounds)"
    );
    // Nothing of it was imported, and nothing was compiled.
    assert_eq!(errors.len(), 1, "{errors:#?}");
    assert!(checked.robot.expect("parsed").chart_types.is_empty());
    assert!(checked.ir.is_none());

    // A file that is not UTF-8: the place of its first bad byte.
    let mut latin1 = fbt(VARS, ECC, ALG).into_bytes();
    let at = latin1
        .windows(5)
        .position(|w| w == b"START")
        .expect("START");
    latin1[at + 1] = 0xC4; // `SÄART` in ISO-8859-1
    std::fs::write(dir.join("T.fbt"), latin1).unwrap();
    let checked = check::check(&src);
    let first = checked.diagnostics.first().expect("an error");
    assert_eq!(
        first.short(&src).replace(&*src.name, "r.ron"),
        "r.ron:1:244: error: `T.fbt` is not UTF-8 text: byte 0xc4 at 11:23 (offset 393)"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A diagnostic about an imported type points at the `fb_types` entry that brought it,
/// and names the place in the file (a state an `IF` made a chain of: all of its states
/// at its `ECState`).
#[test]
fn a_warning_about_an_imported_type_points_at_its_import() {
    let dir = std::env::temp_dir().join(format!("iec61499-warn-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let lost = ECC.replace(
        "<ECState Name=\"START\"/>",
        "<ECState Name=\"START\"/><ECState Name=\"LOST\"/>\n      \
         <ECState Name=\"GONE\"><ECAction Algorithm=\"B\"/></ECState>",
    );
    let alg = format!(
        "{ALG}\n    <Algorithm Name=\"B\"><ST Text=\"IF C &gt; 1 THEN C := 0; END_IF;\"/></Algorithm>"
    );
    std::fs::write(dir.join("T.fbt"), fbt(VARS, &lost, &alg)).unwrap();
    let src = Source::new(
        dir.join("r.ron").to_string_lossy().as_ref(),
        ROBOT.to_string(),
    );
    let lost: Vec<String> = check::check(&src)
        .diagnostics
        .iter()
        .filter(|d| d.message.contains("unreachable"))
        .map(|d| d.short(&src).replace(&*src.name, "r.ron"))
        .collect();
    let said = |at: &str, state: &str| {
        format!(
            "r.ron:1:244: warning: T.fbt:{at}: state `{state}` of chart type `T` is unreachable \
             from its initial state `START`"
        )
    };
    assert_eq!(
        lost,
        [
            said("11:30", "LOST"),
            said("12:7", "GONE.0"),
            said("12:7", "GONE.2"),
            said("12:7", "GONE"),
        ]
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A type imported twice (the same file listed twice in `fb_types`) is a duplicate chart
/// type at the second entry. Found: it was at the robot's first byte (`Robot(`), as the
/// imported types have no `chart_types[..]` of their own.
#[test]
fn a_type_imported_twice_is_named_at_its_second_import() {
    let dir = std::env::temp_dir().join(format!("iec61499-twice-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("T.fbt"), fbt(VARS, ECC, ALG)).unwrap();
    let twice = ROBOT.replace("fb_types: [\"T.fbt\"]", "fb_types: [\"T.fbt\", \"T.fbt\"]");
    let src = Source::new(dir.join("r.ron").to_string_lossy().as_ref(), twice);
    let errors: Vec<String> = check::check(&src)
        .diagnostics
        .iter()
        .filter(|d| d.is_error())
        .map(|d| d.short(&src).replace(&*src.name, "r.ron"))
        .collect();
    assert_eq!(errors, ["r.ron:1:253: error: duplicate chart type `T`"]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// An element of more attributes than any IEC 61499 element has is refused at the first
/// one too many, before the XML parser (whose check of duplicate attributes is quadratic)
/// reads it; `=` in comments, CDATA and quoted values is no attribute.
#[test]
fn an_element_of_too_many_attributes_is_refused_before_parsing() {
    let text = fbt(VARS, ECC, ALG);
    let attributes: String = (0..100_000).map(|i| format!(" a{i}=\"x\"")).collect();
    let many = text.replacen(
        "<FBType Name=\"T\"",
        &format!("<FBType Name=\"T\"{attributes}"),
        1,
    );
    let col = "<FBType Name=\"T\"".len()
        + (0..255)
            .map(|i| format!(" a{i}=\"x\"").len())
            .sum::<usize>()
        + " a255".len()
        + 1;
    assert_eq!(
        error(&many),
        format!("2:{col}: an element of more than 256 attributes")
    );
    let equals = "=".repeat(100_000);
    let harmless = text
        .replacen(
            "<FBType Name=\"T\"",
            &format!("<!-- {equals} --><FBType Name=\"T\" Comment=\"{equals}\""),
            1,
        )
        .replacen(
            "C := C + 1;",
            &format!("C := C + 1; (* {} *)", "&#61;".repeat(10)),
            1,
        );
    assert!(import(&harmless).is_ok(), "{:?}", import(&harmless).err());
    // Nor through declared entities, which the scan would not see: a DOCTYPE's internal
    // subset is refused (a DTD named by its system id, as 4diac writes, is read).
    let attributes: String = (0..20_000).map(|i| format!(" a{i}='1'")).collect();
    let entity = format!(
        "<?xml version='1.0'?>\n<!DOCTYPE FBType [\n<!ENTITY e \"<b{attributes}/>\">\n]>\n\
         <FBType Name='X'>&e;&e;&e;&e;</FBType>"
    );
    assert_eq!(
        error(&entity),
        "2:1: a DOCTYPE with an internal subset (declarations): not taken"
    );
    // A `>` in a quoted literal before the subset does not end the DOCTYPE.
    let quoted = entity.replacen("FBType [", "FBType SYSTEM \"x>y\" [", 1);
    assert_eq!(
        error(&quoted),
        "2:1: a DOCTYPE with an internal subset (declarations): not taken"
    );
    let system = format!(
        "<?xml version=\"1.0\"?>\n<!DOCTYPE FBType SYSTEM \"LibraryElement.dtd\">\n{}",
        text.trim_start_matches("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n")
    );
    assert!(import(&system).is_ok(), "{:?}", import(&system).err());
}

/// XML that ends too early is refused at its end, where the parser found it out.
#[test]
fn truncated_xml_is_refused_at_its_end() {
    let text = fbt(VARS, ECC, ALG);
    let end = |cut: &str| {
        (
            cut.lines().count(),
            cut.lines().last().map_or(0, str::len) + 1,
        )
    };
    let cut = &text[..text.find("<ECTransition").expect("a transition")];
    let (line, col) = end(cut);
    assert_eq!(
        error(cut),
        format!("{line}:{col}: not well-formed XML: the root node was opened but never closed")
    );
    let cut = &text[..text.find("C := C").expect("an algorithm") + 2];
    let (line, col) = end(cut);
    assert_eq!(
        error(cut),
        format!("{line}:{col}: not well-formed XML: unexpected end of stream")
    );
    assert_eq!(
        error("  \n  "),
        "2:3: not well-formed XML: the document does not have a root node"
    );
}

/// An error in Structured Text written as the `ST` element's text is placed where it is
/// in the file, after a CDATA section's start, whitespace before it and character
/// references (it was off by the 9 characters of `<![CDATA[`, by 3 for each `&lt;`).
#[test]
fn an_error_in_st_element_text_is_placed_exactly() {
    let cases = [
        "    <Algorithm Name=\"A\"><ST>\n      <![CDATA[C := 1; C := C + ;]]></ST></Algorithm>",
        "    <Algorithm Name=\"A\"><ST>IF C &lt; 2 THEN C := C + ; END_IF;</ST></Algorithm>",
        "    <Algorithm Name=\"A\"><ST Text=\"IF C &lt; 2 THEN C := C + ; END_IF;\"/></Algorithm>",
        "    <Algorithm Name=\"A\"><ST>C := 1;<![CDATA[ IF C < 2 THEN]]> C := C + ; END_IF;</ST></Algorithm>",
    ];
    for alg in cases {
        let text = fbt(VARS, ECC, alg);
        let (line, col) = text
            .lines()
            .enumerate()
            .find_map(|(i, l)| l.find("+ ;").map(|c| (i + 1, c + 3)))
            .expect("the error's place");
        let e = error(&text);
        assert!(
            e.starts_with(&format!("{line}:{col}: ")),
            "{e}, not at {line}:{col}, in {alg}"
        );
    }
}
