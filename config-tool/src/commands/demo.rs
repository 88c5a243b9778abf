//! `demo`: the whole machine on this host (the work is `robot_net::demo::run`); this turns
//! the flags into the bed's options and the verdict into the exit status.

use std::io;
use std::path::{Path, PathBuf};
use std::time::Duration;

use robot_net::demo::{self, Demo};

use crate::cli::DemoArgs;
use crate::commands::outputs;
use crate::failure::Failure;

pub fn demo(flags: DemoArgs) -> Result<(), Failure> {
    let robot = flags.robot.as_path();
    let fault = flags
        .fault
        .as_deref()
        .map(robot_analysis::inject::parse)
        .transpose()
        .map_err(Failure::usage)?;
    let loaded = demo::load(robot)?;
    refuse_unused(&flags, &loaded, fault.is_some())?;
    if let Some(spec) = &fault {
        // A target or step the robot lacks, said before anything runs (status 2).
        robot_analysis::inject::simulate(&loaded, spec)
            .map_err(super::offline::injection_failure)?;
        // The node that takes START stopped before a cycle's first step takes no START: the
        // demo would wait a minute for its answer and report no fault.
        let given = flags.fault.as_deref().unwrap_or_default();
        let starts = loaded
            .ir
            .start
            .as_ref()
            .map(|(r, _)| loaded.ir.roles[*r].name.as_str());
        if let robot_analysis::inject::FaultKind::Stop(role) = &spec.kind {
            if spec.step == 1 && Some(role.as_str()) == starts {
                return Err(Failure::usage(format!(
                    "--fault {given}: role {role}'s node takes START: stopped before step 1, \
                     it takes no START and nothing moves (sim: not detected); stop it before a \
                     later step"
                )));
            }
        }
        // A fault in a cycle the demo does not run would never be injected.
        let cycles = flags.cycles.unwrap_or(3);
        if spec.cycle > cycles {
            return Err(Failure::usage(format!(
                "--fault {given}: its cycle {} is after the last the demo runs ({cycles}: \
                 --cycles {} or more runs it)",
                spec.cycle, spec.cycle
            )));
        }
    }
    // The robot pushed afterwards: --then's, refused on nodes the demo does not start; else
    // the double dip beside the robot, if there is one and it fits them; none with
    // --no-reconfigure (clap refuses it with --then), nor for a station (it pushes nothing
    // after its run; `refuse_unused` refused its --then).
    let station = loaded.robot.sorting.is_some() || !loaded.robot.functions.is_empty();
    let then = match &flags.then {
        Some(t) => {
            same_nodes(robot, &loaded, t)?;
            Some(t.clone())
        }
        None if flags.no_reconfigure || station => None,
        None => {
            let p = robot.with_file_name("paint-robot-double-dip.ron");
            let fits = p.exists() && p != robot && same_nodes(robot, &loaded, &p).is_ok();
            fits.then_some(p)
        }
    };
    if let Some(out) = &flags.pcap {
        // What the demo reads: both robots and what they import, and the image.
        let mut inputs = outputs::robot_files(robot, &loaded.robot);
        if let Some(then) = &then {
            match demo::load(then) {
                Ok(c) => inputs.extend(outputs::robot_files(then, &c.robot)),
                Err(_) => inputs.push(then.clone()),
            }
        }
        inputs.push(flags.elf.clone());
        outputs::not_an_input("--pcap", out, &inputs)?;
    }
    let count_dir = if flags.icount {
        let dir = std::env::temp_dir().join(format!("config-tool-icount-{}", std::process::id()));
        std::fs::create_dir_all(&dir)
            .map_err(|e| Failure::error(format!("{}: {e}", dir.display())))?;
        Some(dir)
    } else {
        None
    };
    interrupted_cleans_up(count_dir.clone())?;
    let options = demo::Options {
        medium: medium::Config {
            loss: flags.loss,
            dup: flags.loss / 2.0,
            delay_ms: if flags.loss > 0.0 { (0, 8) } else { (0, 0) },
            seed: flags.seed,
            pcap: flags.pcap,
            ..medium::Config::default()
        },
        node_command: node_command(flags.qemu, &flags.elf, count_dir.as_deref())?,
        flash_dir: None,
        timeout: Duration::from_secs(60),
        // Host and QEMU nodes alike: every node gets its management key, unless the robot
        // says `security: Off` (which `check` warns about).
        secured: loaded.robot.security == robot_compiler::model::Security::On,
    };
    let verdict = demo::run(
        &Demo {
            robot,
            then: then.as_deref(),
            cycles: flags.cycles.unwrap_or(3),
            fault,
            count_dir: count_dir.as_deref(),
        },
        options,
        &mut io::stdout(),
    );
    if let Some(dir) = &count_dir {
        let _ = std::fs::remove_dir_all(dir);
    }
    Failure::of_verdict(verdict?)
}

/// A sorting station runs its feed once and a robot with control functions its
/// operator's script: `--cycles`, `--fault` and `--then` would be ignored (said nothing,
/// and ended `every ball sorted`), so they are refused (status 2), as `sim` refuses them.
fn refuse_unused(
    flags: &DemoArgs,
    c: &robot_compiler::Compiled,
    fault: bool,
) -> Result<(), Failure> {
    let what = if c.robot.sorting.is_some() {
        "a sorting station's `demo` runs its feed once"
    } else if !c.robot.functions.is_empty() {
        "a robot with control functions runs its operator's script"
    } else {
        return Ok(());
    };
    let given = [
        (flags.cycles.is_some(), "--cycles"),
        (fault, "--fault"),
        (flags.then.is_some(), "--then"),
    ];
    match given.iter().find(|g| g.0) {
        Some((_, flag)) => Err(Failure::usage(format!(
            "{what}: it takes no {flag} ({})",
            flags.robot.display()
        ))),
        None => Ok(()),
    }
}

/// The robot pushed afterwards runs on the first robot's nodes (the demo starts those):
/// one with a node of its own is refused before anything runs (it failed its push after
/// the first robot's whole run).
fn same_nodes(robot: &Path, c: &robot_compiler::Compiled, then: &Path) -> Result<(), Failure> {
    let next = demo::load(then)?;
    let ours: Vec<u16> = demo::node_addrs(c);
    match next.ir.roles.iter().find(|r| !ours.contains(&r.address)) {
        Some(r) => Err(Failure::usage(format!(
            "--then {}: its role {} is on node {:#06x}, which is not one of {}'s nodes (the \
             demo pushes it to those)",
            then.display(),
            r.name,
            r.address,
            robot.display()
        ))),
        None => Ok(()),
    }
}

/// An interrupted demo (Ctrl-C, SIGTERM, its terminal closed) ends without the bed's
/// machine secret and node keys (nor `count_dir`) left in the temporary directory (its
/// node processes end as its medium closes), status 130.
fn interrupted_cleans_up(count_dir: Option<PathBuf>) -> Result<(), Failure> {
    ctrlc::set_handler(move || {
        demo::remove_key_dirs();
        if let Some(dir) = &count_dir {
            let _ = std::fs::remove_dir_all(dir);
        }
        crate::out::errln!("demo: interrupted");
        std::process::exit(130);
    })
    .map_err(|e| Failure::error(format!("cannot take the interrupt: {e}")))
}

/// How the bed starts one node: this binary's `node`, or its `qemu-node` booting `elf`.
fn node_command(
    qemu: bool,
    elf: &Path,
    count_dir: Option<&Path>,
) -> Result<Vec<std::ffi::OsString>, Failure> {
    let exe = std::env::current_exe().map_err(Failure::error)?;
    if !qemu {
        return Ok(vec![exe.into_os_string(), "node".into()]);
    }
    demo::check_elf(elf)?;
    demo::check_qemu()?;
    let elf = std::path::absolute(elf).map_err(Failure::error)?;
    let mut cmd = vec![
        exe.into_os_string(),
        "qemu-node".into(),
        // None outlives an interrupted demo.
        "--end-with-parent".into(),
        "--elf".into(),
        elf.into_os_string(),
    ];
    if let Some(dir) = count_dir {
        cmd.extend(["--count".into(), dir.as_os_str().to_owned()]);
    }
    Ok(cmd)
}
