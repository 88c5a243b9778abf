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

/// A secured bed with a node process per role of `c` (this binary's `node`) and the
/// plant of `c`, once every node has announced itself; the plant's actuators.
pub fn bed_of(
    c: &robot_compiler::Compiled,
    timeout: std::time::Duration,
) -> (robot_net::demo::Bed, Vec<robot_net::live_plant::Actuator>) {
    use robot_net::demo::{Bed, Options};
    let options = Options {
        medium: medium::Config::default(),
        node_command: vec![env!("CARGO_BIN_EXE_config-tool").into(), "node".into()],
        flash_dir: None,
        timeout,
        secured: true,
    };
    let mut bed = Bed::start(options).expect("bed");
    let addrs: Vec<u16> = c.ir.roles.iter().map(|r| r.address).collect();
    for a in &addrs {
        bed.start_node(*a).expect("node");
    }
    let actuators = robot_net::live_plant::actuators(c).expect("plant");
    bed.set_plant(actuators.clone()).expect("plant");
    bed.wait_for_nodes(&addrs).expect("nodes");
    (bed, actuators)
}
