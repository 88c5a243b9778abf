//! A robot file, whatever its text: `compile` (the RON front end, elaboration, the checks,
//! lowering to tables) returns the tables or diagnostics; never a panic, and never a
//! stack overflow on deep nesting (libFuzzer's timeout catches work that does not end).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    // Files it names (fb_types, an application) are looked for beside a robot that is
    // nowhere: they cannot be read, and say so.
    let src = robot_compiler::Source::new("/nonexistent/fuzz.ron", text);
    let _ = robot_compiler::compile(&src);
});
