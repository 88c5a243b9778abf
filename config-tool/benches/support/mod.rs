//! What the benchmarks of config-tool share.

use robot_compiler::{compile, Source};

/// `robot-configs/paint-robot.ron`, compiled, generation 1.
pub fn paint_robot() -> robot_compiler::Compiled {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../robot-configs/paint-robot.ron"
    );
    let src = Source::new(
        "paint-robot.ron",
        std::fs::read_to_string(path).expect("robot"),
    );
    compile::compile(&src)
        .expect("paint robot compiles")
        .with_generation(1)
        .expect("generation")
}
