//! Nodes as QEMU instances booting the firmware image: the command line, provisioning,
//! and the instruction counts they log (`demo --qemu --icount`).

use std::ffi::OsString;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use node_fw::provision::{self, ManagementKey, Word};

use crate::error::NetError;

/// The emulated board: QEMU's Cortex-M3 machine the `qemu-mps2` image runs on.
pub const QEMU_MACHINE: &str = "mps2-an385";
/// Where the provisioning word goes (`node_fw::provision`, the board's `provision.rs`).
pub const PROVISION_AT: u32 = provision::qemu::WORD_AT;
/// The release image, relative to the repository.
pub const QEMU_ELF: &str = "node-fw/boards/target/thumbv7m-none-eabi/release/qemu-mps2";

/// The provisioning word of node `addr` (address, magic, semihosting on).
pub fn provision_word(addr: u16) -> u32 {
    Word {
        addr,
        flags: provision::FLAG_SEMIHOSTING,
    }
    .encode()
}

/// The `-device` values that write a node's provisioning before its CPU starts: the word
/// (with the key flag when there is a key), then the key's four little-endian words right
/// after it (`node_fw::provision`).
pub fn provision_loaders(word: u32, key: Option<&ManagementKey>) -> Vec<String> {
    let loader =
        |addr: u32, data: u32| format!("loader,addr={addr:#010x},data={data:#010x},data-len=4");
    let Some(key) = key else {
        return vec![loader(PROVISION_AT, word)];
    };
    let word = word | u32::from(provision::FLAG_KEY) << 16;
    let mut loaders = vec![loader(PROVISION_AT, word)];
    for (i, w) in key.words().into_iter().enumerate() {
        loaders.push(loader(provision::qemu::KEY_AT + 4 * i as u32, w));
    }
    loaders
}

/// Where a QEMU node's UART, its radio, goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Uart {
    /// QEMU connects to the medium at this address.
    Medium(SocketAddr),
    /// A socket connected to the medium already, which QEMU inherits as this descriptor.
    Socket(i32),
}

/// QEMU's arguments for one node booting `elf`: its address in the provisioning word (with
/// the key flag when `key_file` names the file QEMU loads the management key from, 16 raw
/// bytes, right after the word: never the key itself, since every local user can read a
/// process's arguments), its UART connected to the medium, its flash slots in `flash`
/// (through semihosting; without it they are erased at every boot).
pub fn qemu_args(
    elf: &Path,
    addr: u16,
    key_file: Option<&Path>,
    uart: Uart,
    flash: Option<&Path>,
    count: Option<&Path>,
) -> Result<Vec<OsString>, NetError> {
    let mut semihosting = OsString::from("enable=on,target=native");
    let mut word = provision_word(addr);
    let mut extra: Vec<OsString> = Vec::new();
    if let Some(dir) = count {
        // A nanosecond of emulated time is one instruction; the firmware logs its busy
        // time and stimuli to the node's log file.
        word |= u32::from(provision::FLAG_COUNT) << 16;
        let log = count_log(dir, addr);
        let mut chardev = OsString::from("file,id=log,path=");
        chardev.push(log.as_os_str());
        extra.extend(["-icount".into(), "shift=0,sleep=on".into()]);
        extra.extend(["-chardev".into(), chardev]);
        semihosting.push(",chardev=log");
    }
    if let Some(f) = flash {
        let text = f.to_str().unwrap_or(",");
        // QEMU splits options at commas and the firmware its command line at spaces.
        if text.contains([',', ' ']) {
            return Err(NetError::FlashPath(f.display().to_string()));
        }
        semihosting.push(",arg=flash=");
        semihosting.push(text);
    }
    let mut args: Vec<OsString> = vec![
        "-M".into(),
        QEMU_MACHINE.into(),
        "-display".into(),
        "none".into(),
        "-monitor".into(),
        "none".into(),
        "-kernel".into(),
        elf.as_os_str().to_owned(),
    ];
    let flag = key_file.map_or(0, |_| u32::from(provision::FLAG_KEY) << 16);
    for loader in provision_loaders(word | flag, None) {
        args.extend(["-device".into(), loader.into()]);
    }
    if let Some(file) = key_file {
        let mut loader = OsString::from("loader,file=");
        loader.push(file.as_os_str());
        loader.push(format!(
            ",addr={:#010x},force-raw=on",
            provision::qemu::KEY_AT
        ));
        args.extend(["-device".into(), loader]);
    }
    args.extend([
        "-chardev".into(),
        match uart {
            Uart::Medium(medium) => format!(
                "socket,id=radio,host={},port={},nodelay=on",
                medium.ip(),
                medium.port()
            ),
            Uart::Socket(fd) => format!("socket,id=radio,fd={fd}"),
        }
        .into(),
        "-serial".into(),
        "chardev:radio".into(),
        "-semihosting-config".into(),
        semihosting,
    ]);
    args.extend(extra);
    Ok(args)
}

/// Where a counting QEMU node logs.
pub fn count_log(dir: &Path, addr: u16) -> PathBuf {
    dir.join(format!("node-{addr:04x}.log"))
}

/// What a counting node said last.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// Instructions executed while awake (interrupts included).
    pub instructions: u64,
    /// Frames received.
    pub frames: u64,
    /// `Pin` messages received (the plant repeats levels every 200 ms).
    pub pins: u64,
    /// Input level changes among them.
    pub changes: u64,
    /// Instructions inside the node core (MAC, links, OTA, interpreter) for frames, and
    /// the frames.
    pub core_frame: u64,
    pub core_frames: u64,
    /// The same for `Pin` messages (every one goes to the core; repeats raise no event).
    pub core_input: u64,
    pub core_inputs: u64,
    /// The software AES's key schedules and blocks inside the core for frames, and for
    /// `Pin` messages (a changed input's event published, secured).
    pub core_frame_aes: Aes,
    pub core_input_aes: Aes,
}

/// AES work as a node counts it: key schedules computed, blocks encrypted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Aes {
    pub schedules: u64,
    pub blocks: u64,
}

impl Aes {
    fn since(self, before: Aes) -> Aes {
        Aes {
            schedules: self.schedules.saturating_sub(before.schedules),
            blocks: self.blocks.saturating_sub(before.blocks),
        }
    }

    fn add(&mut self, other: Aes) {
        self.schedules += other.schedules;
        self.blocks += other.blocks;
    }

    /// Instructions, at `cost` = (one key schedule, one block) as the node measured.
    fn instructions(self, (schedule, block): (u64, u64)) -> u64 {
        self.schedules * schedule + self.blocks * block
    }
}

/// The last `count:` line of a counting node's log.
pub fn read_counts(dir: &Path, addr: u16) -> Option<Counts> {
    let text = std::fs::read_to_string(count_log(dir, addr)).ok()?;
    let line = text.lines().rev().find(|l| l.contains(" count: "))?;
    let mut words = line.split_whitespace();
    let mut next = |key: &str| -> Option<u64> {
        words.by_ref().find(|w| *w == key)?;
        words.next()?.parse().ok()
    };
    Some(Counts {
        instructions: next("busy_ns")?,
        frames: next("frames")?,
        pins: next("pins")?,
        changes: next("changes")?,
        core_frame: next("core_frame_ns")?,
        core_frames: next("core_frames")?,
        core_input: next("core_input_ns")?,
        core_inputs: next("core_inputs")?,
        core_frame_aes: aes_after(line, "core_frame_aes")?,
        core_input_aes: aes_after(line, "core_input_aes")?,
    })
}

/// The two numbers after `key` in `line`: key schedules, blocks.
fn aes_after(line: &str, key: &str) -> Option<Aes> {
    let mut words = line.split_whitespace().skip_while(|w| *w != key).skip(1);
    let schedules = words.next()?.parse().ok()?;
    let blocks = words.next()?.parse().ok()?;
    Some(Aes { schedules, blocks })
}

/// What securing and opening one frame costs on the emulated Cortex-M3, as a counting node
/// measured it at boot (`security::secure` and `security::open_at`, ENC-MIC-64).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SecurityCost {
    /// Payload bytes.
    pub payload: u64,
    /// Instructions to secure one frame, and to open one.
    pub secure: u64,
    pub open: u64,
}

/// The values after `keys` in `line` (each key's next word), if all are there.
fn values<const N: usize>(line: &str, keys: [&str; N]) -> Option<[u64; N]> {
    let mut words = line.split_whitespace();
    let mut out = [0; N];
    for (key, v) in keys.iter().zip(out.iter_mut()) {
        words.by_ref().find(|w| w == key)?;
        *v = words.next()?.parse().ok()?;
    }
    Some(out)
}

/// The `security cost: payload` lines of a counting node's log, in order.
pub fn read_security_costs(dir: &Path, addr: u16) -> Vec<SecurityCost> {
    let Ok(text) = std::fs::read_to_string(count_log(dir, addr)) else {
        return Vec::new();
    };
    text.lines()
        .filter(|l| l.contains(" security cost: payload "))
        .filter_map(|line| {
            let [payload, secure, open] = values(line, ["payload", "secure_ns", "open_ns"])?;
            Some(SecurityCost {
                payload,
                secure,
                open,
            })
        })
        .collect()
}

/// The instructions of one AES-128 key schedule and of one block, as the node measured.
pub fn read_aes_cost(dir: &Path, addr: u16) -> Option<(u64, u64)> {
    let text = std::fs::read_to_string(count_log(dir, addr)).ok()?;
    let line = text.lines().find(|l| l.contains(" security cost: aes "))?;
    let [schedule, block] = values(line, ["key_schedule_ns", "block_ns"])?;
    Some((schedule, block))
}

/// The cost of frame security, from the first node of `addrs` that measured it (every node
/// runs the same image).
pub fn security_cost_lines(dir: &Path, addrs: &[u16]) -> Vec<String> {
    let Some((addr, costs)) = addrs
        .iter()
        .map(|a| (*a, read_security_costs(dir, *a)))
        .find(|(_, c)| !c.is_empty())
    else {
        return vec!["frame security: no node measured it".into()];
    };
    let mut lines = vec![
        "frame security (AES-128-CCM*, ENC-MIC-64, software AES, the node's path), instructions per frame:".into(),
    ];
    for c in costs {
        lines.push(format!(
            "  payload {:>3} bytes: secure {:>6}, open {:>6}",
            c.payload, c.secure, c.open
        ));
    }
    if let Some((schedule, block)) = read_aes_cost(dir, addr) {
        lines.push(format!(
            "  of which AES-128 alone: key schedule {schedule:>6} (once per key: the node keeps it), one block {block:>6}"
        ));
    }
    lines
}

/// Checks the image is there (a clear message instead of QEMU's).
pub fn check_elf(elf: &Path) -> Result<(), NetError> {
    if elf.is_file() {
        Ok(())
    } else {
        Err(NetError::NoImage(elf.display().to_string()))
    }
}

/// Checks QEMU runs (a clear message now instead of nodes that never answer).
pub fn check_qemu() -> Result<(), NetError> {
    match std::process::Command::new("qemu-system-arm")
        .arg("--version")
        .stdout(std::process::Stdio::null())
        .status()
    {
        Ok(s) if s.success() => Ok(()),
        Ok(s) => Err(NetError::QemuFailed(s)),
        Err(e) => Err(NetError::NoQemu(e)),
    }
}

/// Every node's counts once they stop changing (the nodes log every second).
pub fn settled_counts(dir: &Path, addrs: &[u16]) -> Vec<Option<Counts>> {
    let read = || -> Vec<Option<Counts>> { addrs.iter().map(|a| read_counts(dir, *a)).collect() };
    let mut last = read();
    for _ in 0..10 {
        std::thread::sleep(Duration::from_millis(1200));
        let now = read();
        if now == last {
            break;
        }
        last = now;
    }
    last
}

/// Instructions per node over `cycles` cycles, per cycle and per stimulus.
/// `aes`: one key schedule's and one block's instructions, as the node measured them (the
/// core's figures then also without the AES).
pub fn count_lines(
    addrs: &[u16],
    before: &[Option<Counts>],
    after: &[Option<Counts>],
    cycles: usize,
    aes: Option<(u64, u64)>,
) -> Vec<String> {
    let mut lines = vec![format!(
        "instructions executed during the {cycles} cycle(s) (QEMU -icount shift=0):"
    )];
    let mut total = Counts::default();
    for ((a, b), e) in addrs.iter().zip(before).zip(after) {
        let (Some(b), Some(e)) = (b, e) else {
            lines.push(format!("  node {a:#06x}: no counts"));
            continue;
        };
        let d = Counts {
            instructions: e.instructions.saturating_sub(b.instructions),
            frames: e.frames.saturating_sub(b.frames),
            pins: e.pins.saturating_sub(b.pins),
            changes: e.changes.saturating_sub(b.changes),
            core_frame: e.core_frame.saturating_sub(b.core_frame),
            core_frames: e.core_frames.saturating_sub(b.core_frames),
            core_input: e.core_input.saturating_sub(b.core_input),
            core_inputs: e.core_inputs.saturating_sub(b.core_inputs),
            core_frame_aes: e.core_frame_aes.since(b.core_frame_aes),
            core_input_aes: e.core_input_aes.since(b.core_input_aes),
        };
        total.instructions += d.instructions;
        total.frames += d.frames;
        total.pins += d.pins;
        total.changes += d.changes;
        total.core_frame += d.core_frame;
        total.core_frames += d.core_frames;
        total.core_input += d.core_input;
        total.core_inputs += d.core_inputs;
        total.core_frame_aes.add(d.core_frame_aes);
        total.core_input_aes.add(d.core_input_aes);
        lines.push(count_line(&format!("node {a:#06x}"), &d, cycles, aes));
    }
    lines.push(count_line("all nodes  ", &total, cycles, aes));
    lines
}

fn count_line(who: &str, d: &Counts, cycles: usize, aes: Option<(u64, u64)>) -> String {
    let per = |n: u64, of: u64| n as f64 / of.max(1) as f64;
    // A stimulus is what the node must react to: a frame, or an input that changed (the
    // plant's repeated levels cost instructions too, but are not events).
    let stimuli = d.frames + d.changes;
    format!(
        "  {who}: {:>9} instructions, {:>8.0} per cycle; {:>4} frames + {:>3} input changes \
         ({:>3} level messages): {:>6.0} per stimulus",
        d.instructions,
        d.instructions as f64 / cycles.max(1) as f64,
        d.frames,
        d.changes,
        d.pins,
        d.instructions as f64 / stimuli.max(1) as f64
    ) + &format!(
        "\n  {:w$}  of which in the node core: {:>6.0} per frame, {:>5.0} per level message",
        "",
        per(d.core_frame, d.core_frames),
        per(d.core_input, d.core_inputs),
        w = who.len()
    ) + &aes.map_or(String::new(), |cost| {
        let (frame, input) = (
            d.core_frame_aes.instructions(cost),
            d.core_input_aes.instructions(cost),
        );
        format!(
            "\n  {:w$}    the core without the AES: {:>6.0} per frame, {:>5.0} per level message \
             (AES: {:.2} schedules and {:.1} blocks per frame)",
            "",
            per(d.core_frame.saturating_sub(frame), d.core_frames),
            per(d.core_input.saturating_sub(input), d.core_inputs),
            per(d.core_frame_aes.schedules, d.core_frames),
            per(d.core_frame_aes.blocks, d.core_frames),
            w = who.len()
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(key: Option<&Path>) -> Vec<String> {
        qemu_args(
            Path::new("qemu-mps2"),
            0x0011,
            key,
            Uart::Medium("127.0.0.1:15400".parse().unwrap()),
            Some(Path::new("node-11.flash")),
            None,
        )
        .unwrap()
        .into_iter()
        .map(|a| a.into_string().unwrap())
        .collect()
    }

    const BASE: [&str; 8] = [
        "-M",
        "mps2-an385",
        "-display",
        "none",
        "-monitor",
        "none",
        "-kernel",
        "qemu-mps2",
    ];
    const TAIL: [&str; 6] = [
        "-chardev",
        "socket,id=radio,host=127.0.0.1,port=15400,nodelay=on",
        "-serial",
        "chardev:radio",
        "-semihosting-config",
        "enable=on,target=native,arg=flash=node-11.flash",
    ];

    #[test]
    fn the_security_costs_are_read_from_the_log() {
        let dir = std::env::temp_dir().join(format!("robot-net-cost-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(
            count_log(&dir, 0x0011),
            "INFO  node 0x0011: qemu-mps2, flash Ram\n\
             INFO  node 0x0011: security cost: payload 4 secure_ns 9000 open_ns 9100\n\
             INFO  node 0x0011: security cost: payload 102 secure_ns 30000 open_ns 30500\n\
             INFO  node 0x0011: security cost: aes key_schedule_ns 7000 block_ns 2000\n\
             INFO  node 0x0011: count: busy_ns 1 frames 0 pins 0 changes 0 core_frame_ns 0 \
             core_frames 0 core_input_ns 0 core_inputs 0 core_frame_aes 0 0 core_input_aes 0 0\n",
        )
        .unwrap();
        let cost = |payload, secure, open| SecurityCost {
            payload,
            secure,
            open,
        };
        assert_eq!(
            read_security_costs(&dir, 0x0011),
            [cost(4, 9000, 9100), cost(102, 30000, 30500)]
        );
        assert_eq!(
            security_cost_lines(&dir, &[0x0012, 0x0011]),
            [
                "frame security (AES-128-CCM*, ENC-MIC-64, software AES, the node's path), instructions per frame:",
                "  payload   4 bytes: secure   9000, open   9100",
                "  payload 102 bytes: secure  30000, open  30500",
                "  of which AES-128 alone: key schedule   7000 (once per key: the node keeps it), one block   2000",
            ]
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A node's count line read back, AES work included; the core's figures printed with
    /// and without the AES (at the node's measured cost), over the difference of two
    /// readings.
    #[test]
    fn the_core_is_counted_with_and_without_the_aes() {
        let dir = std::env::temp_dir().join(format!("robot-net-counts-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(
            count_log(&dir, 0x0011),
            "INFO  node 0x0011: count: busy_ns 900 frames 4 pins 10 changes 2 \
             core_frame_ns 500 core_frames 3 core_input_ns 40 core_inputs 10 \
             core_frame_aes 1 20 core_input_aes 0 1\n\
             INFO  node 0x0011: count: busy_ns 1900000 frames 14 pins 30 changes 4 \
             core_frame_ns 400500 core_frames 13 core_input_ns 3040 core_inputs 30 \
             core_frame_aes 2 90 core_input_aes 0 1\n",
        )
        .unwrap();
        let after = read_counts(&dir, 0x0011).unwrap();
        assert_eq!(
            (after.core_frame_aes, after.core_input_aes),
            (
                Aes {
                    schedules: 2,
                    blocks: 90
                },
                Aes {
                    schedules: 0,
                    blocks: 1
                }
            )
        );
        let before = Counts {
            instructions: 900,
            frames: 4,
            pins: 10,
            changes: 2,
            core_frame: 500,
            core_frames: 3,
            core_input: 40,
            core_inputs: 10,
            core_frame_aes: Aes {
                schedules: 1,
                blocks: 20,
            },
            core_input_aes: Aes {
                schedules: 0,
                blocks: 1,
            },
        };
        // 10 frames: 400,000 instructions in the core, 1 schedule (5,000) and 70 blocks
        // (4,000 each) among them; 20 level messages: 3,000, no block.
        let lines = count_lines(
            &[0x0011],
            &[Some(before)],
            &[Some(after)],
            2,
            Some((5000, 4000)),
        );
        assert_eq!(
            lines[1],
            "  node 0x0011:   1899100 instructions,   949550 per cycle;   10 frames +   2 input \
             changes ( 20 level messages): 158258 per stimulus\n\
             \x20              of which in the node core:  40000 per frame,   150 per level message\n\
             \x20                the core without the AES:  11500 per frame,   150 per level message \
             (AES: 0.10 schedules and 7.0 blocks per frame)"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn without_a_key_the_command_line_is_as_before() {
        let mut want: Vec<&str> = BASE.to_vec();
        want.extend([
            "-device",
            "loader,addr=0x003ff000,data=0xa5010011,data-len=4",
        ]);
        want.extend(TAIL);
        assert_eq!(args(None), want);
    }

    #[test]
    fn a_key_is_loaded_from_its_file_after_the_flagged_word() {
        let mut want: Vec<&str> = BASE.to_vec();
        want.extend([
            "-device",
            "loader,addr=0x003ff000,data=0xa5050011,data-len=4",
            "-device",
            "loader,file=/proc/self/fd/7,addr=0x003ff004,force-raw=on",
        ]);
        want.extend(TAIL);
        assert_eq!(args(Some(Path::new("/proc/self/fd/7"))), want);
    }

    #[test]
    fn the_printed_loaders_carry_the_key_words_the_board_reads_back() {
        let key = ManagementKey::from_bytes(core::array::from_fn(|i| 0x10 + i as u8));
        assert_eq!(
            provision_loaders(0xa501_0011, Some(&key)),
            [
                "loader,addr=0x003ff000,data=0xa5050011,data-len=4",
                "loader,addr=0x003ff004,data=0x13121110,data-len=4",
                "loader,addr=0x003ff008,data=0x17161514,data-len=4",
                "loader,addr=0x003ff00c,data=0x1b1a1918,data-len=4",
                "loader,addr=0x003ff010,data=0x1f1e1d1c,data-len=4",
            ]
        );
        let (word, back) = provision::read(0xa505_0011, || key.words()).unwrap();
        assert_eq!(
            (word.addr, back.map(|k| *k.expose())),
            (0x0011, Some(*key.expose()))
        );
    }
}
