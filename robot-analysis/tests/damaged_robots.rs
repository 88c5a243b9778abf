//! Damaged robot files through the whole offline pipeline: `check` never panics, and what
//! checks clean compiles and simulates.

use robot_compiler::check::check;
use robot_compiler::Source;

mod robustness {
    use super::*;
    use proptest::prelude::*;

    fn config(which: usize) -> String {
        let name = ["paint-robot-paper-charts.ron", "paint-robot.ron"][which % 2];
        std::fs::read_to_string(format!(
            "{}/../robot-configs/{name}",
            env!("CARGO_MANIFEST_DIR")
        ))
        .expect("config")
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

        /// Damaged robot files (a range cut out, text spliced in) never panic `check` or
        /// the rendering of its diagnostics, and an error always comes with a position
        /// inside the file; a damaged file that checks clean compiles and simulates.
        #[test]
        fn check_never_panics_on_damaged_files(
            which in 0usize..2,
            cut in 0usize..6000,
            len in 0usize..40,
            insert in "[ -~éü\"\\\\(){}\\[\\],:+\n]{0,12}",
        ) {
            let text = config(which);
            let mut at = cut.min(text.len());
            while !text.is_char_boundary(at) { at -= 1; }
            let mut end = (at + len).min(text.len());
            while !text.is_char_boundary(end) { end -= 1; }
            let damaged = format!("{}{}{}", &text[..at], insert, &text[end..]);
            let src = Source::new("damaged.ron", damaged);
            let diags = check(&src).diagnostics;
            for d in &diags {
                let (line, col) = d.line_col(&src);
                prop_assert!(line >= 1 && col >= 1);
                prop_assert!(!d.render(&src, false).is_empty());
            }
            // What checks clean also compiles, and simulates (maybe to a fault or a diff).
            if !diags.iter().any(|d| d.is_error()) {
                let compiled = robot_compiler::compile(&src);
                prop_assert!(compiled.is_ok());
                if let Ok(c) = compiled {
                    let _ = robot_analysis::sim::simulate(&c, 2);
                }
            }
        }
    }
}
