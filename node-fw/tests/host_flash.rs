//! The host board's flash file: created erased, NOR semantics (a write only clears bits),
//! bounds and alignment refused, the boot counter counts across openings, and a table
//! stored through `Slots` is there when the file is opened again.

use std::path::PathBuf;

use config_schema::limits::MAX_BLOB;
use config_schema::{encode, Table};
use embassy_futures::block_on;
use embedded_storage_async::nor_flash::{NorFlash, ReadNorFlash};
use node_fw::epoch::of_boot as epoch_of_boot;
use node_fw::host::flash::{FlashError, HostFlash, OpenError, FILE_SIZE, SLOTS_BYTES};
use node_fw::host::parse_addr;
use node_fw::slots::Slots;

fn path(name: &str) -> PathBuf {
    let p = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("{name}-{}.flash", std::process::id()));
    let _ = std::fs::remove_file(&p);
    p
}

#[test]
fn a_new_file_is_erased_and_writes_only_clear_bits() {
    let p = path("nor");
    let mut f = HostFlash::open(&p).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    assert_eq!(bytes.len(), FILE_SIZE);
    assert!(bytes.iter().all(|&b| b == 0xFF));
    assert_eq!(f.capacity(), SLOTS_BYTES);

    block_on(f.write(8, &[0xF0, 0x0F, 0xFF, 0x00])).unwrap();
    block_on(f.write(8, &[0x3C, 0x3C, 0x3C, 0x3C])).unwrap();
    let mut got = [0u8; 4];
    block_on(f.read(8, &mut got)).unwrap();
    assert_eq!(got, [0x30, 0x0C, 0x3C, 0x00]);
    assert_eq!(block_on(f.write(9, &[0; 4])), Err(FlashError::NotAligned));
    assert_eq!(block_on(f.write(8, &[0; 3])), Err(FlashError::NotAligned));
    let end = SLOTS_BYTES as u32;
    assert_eq!(
        block_on(f.write(end, &[0; 4])),
        Err(FlashError::OutOfBounds)
    );
    assert_eq!(
        block_on(f.read(end - 1, &mut got)),
        Err(FlashError::OutOfBounds)
    );
    assert_eq!(block_on(f.erase(0, 100)), Err(FlashError::NotAligned));
    assert_eq!(block_on(f.erase(4096, 0)), Err(FlashError::OutOfBounds));
    block_on(f.erase(0, 4096)).unwrap();
    block_on(f.read(8, &mut got)).unwrap();
    assert_eq!(got, [0xFF; 4]);
    let _ = std::fs::remove_file(&p);
}

#[test]
fn the_boot_counter_and_the_slots_survive_reopening() {
    let p = path("reopen");
    let mut table = Table::empty("kept");
    table.generation = 9;
    let mut blob = vec![0u8; MAX_BLOB];
    let n = encode(&table, &mut blob).unwrap();
    {
        let mut f = HostFlash::open(&p).unwrap();
        assert_eq!(f.count_boot().unwrap(), Some(1));
        let mut slots = Slots::new(f).unwrap();
        assert_eq!(block_on(slots.load()).unwrap().running, None);
        assert_eq!(block_on(slots.store(None, &blob[..n], 0)).unwrap(), 0);
    }
    let mut f = HostFlash::open(&p).unwrap();
    assert_eq!(f.count_boot().unwrap(), Some(2));
    let mut slots = Slots::new(f).unwrap();
    let loaded = block_on(slots.load()).unwrap().running.unwrap();
    assert_eq!((loaded.slot, loaded.deployed.table), (0, table));
    assert_eq!(HostFlash::ram().count_boot().unwrap(), None);
    let _ = std::fs::remove_file(&p);
}

/// The runtime counts boots on a handle of its own while the slots own the flash (a boot
/// that took most of its link epochs): the slots' reads and writes and the counter's move
/// nothing of each other, and the next boot counts on from it.
#[test]
fn a_boot_counted_on_its_own_handle_is_the_flash_files() {
    let p = path("boot-counter");
    let mut table = Table::empty("kept");
    table.generation = 4;
    let mut blob = vec![0u8; MAX_BLOB];
    let n = encode(&table, &mut blob).unwrap();
    {
        let f = HostFlash::open(&p).unwrap();
        let mut counter = f.boot_counter().unwrap().unwrap();
        assert_eq!(counter.count().unwrap(), 1);
        let mut slots = Slots::new(f).unwrap();
        assert_eq!(block_on(slots.load()).unwrap().running, None);
        assert_eq!(counter.count().unwrap(), 2);
        assert_eq!(block_on(slots.store(None, &blob[..n], 0)).unwrap(), 0);
        assert_eq!(counter.count().unwrap(), 3);
    }
    let mut f = HostFlash::open(&p).unwrap();
    assert_eq!(f.count_boot().unwrap(), Some(4));
    let mut slots = Slots::new(f).unwrap();
    let loaded = block_on(slots.load()).unwrap().running.unwrap();
    assert_eq!((loaded.slot, loaded.deployed.table), (0, table));
    assert!(HostFlash::ram().boot_counter().unwrap().is_none());
    let _ = std::fs::remove_file(&p);
}

#[test]
fn a_file_of_another_size_is_refused_untouched() {
    let p = path("foreign");
    std::fs::write(&p, vec![7u8; 100]).unwrap();
    match HostFlash::open(&p) {
        Err(OpenError::Size { found: 100, .. }) => {}
        other => panic!("{:?}", other.err()),
    }
    assert_eq!(std::fs::read(&p).unwrap(), vec![7u8; 100]);
    let _ = std::fs::remove_file(&p);
}

/// Only the size told a flash file: any other file of 20,480 bytes was taken for one, and
/// the node's first boot wrote its boot count into it (a table pushed erased its pages).
/// Past the count, the boot counter's page of a flash file is erased: a file whose page
/// holds anything else there is refused, unchanged.
#[test]
fn a_file_of_the_size_that_is_not_a_flash_file_is_refused_untouched() {
    let p = path("foreign-sized");
    let text: Vec<u8> = (b"notes of a shift\n".iter().copied().cycle())
        .take(FILE_SIZE)
        .collect();
    std::fs::write(&p, &text).unwrap();
    let said = match HostFlash::open(&p) {
        Err(e @ OpenError::Foreign { .. }) => e.to_string(),
        other => panic!("{:?}", other.err()),
    };
    assert_eq!(
        said,
        format!(
            "flash file {}: not a node flash file (its boot counter's page holds other data); \
             left unchanged",
            p.display()
        )
    );
    assert_eq!(std::fs::read(&p).unwrap(), text);
    // One byte off in the erased part is enough.
    let mut flash = vec![0xFF; FILE_SIZE];
    flash[FILE_SIZE - 1] = 0xFE;
    std::fs::write(&p, &flash).unwrap();
    assert!(matches!(
        HostFlash::open(&p),
        Err(OpenError::Foreign { .. })
    ));
    assert_eq!(std::fs::read(&p).unwrap(), flash);
    // A node's own file, booted and holding a table, opens.
    flash[FILE_SIZE - 1] = 0xFF;
    flash[SLOTS_BYTES..SLOTS_BYTES + 4].copy_from_slice(&7u32.to_le_bytes());
    flash[..64].fill(0x12);
    std::fs::write(&p, &flash).unwrap();
    assert!(HostFlash::open(&p).is_ok());
    let _ = std::fs::remove_file(&p);
}

#[test]
fn epochs_of_consecutive_boots_are_newer_with_room_for_tables() {
    for boots in [1u32, 2, 255, 256, 257, 65_535, 65_536] {
        let (a, b) = (epoch_of_boot(boots), epoch_of_boot(boots + 1));
        // b is after a in serial order, with 255 installs of room between them.
        assert_eq!(b.wrapping_sub(a), 256, "boot {boots}");
    }
}

#[test]
fn addresses_parse_in_hex_or_decimal() {
    assert_eq!(parse_addr("0x0003"), Ok(3));
    assert_eq!(parse_addr("0X1f"), Ok(0x1F));
    assert_eq!(parse_addr("42"), Ok(42));
    assert!(parse_addr("0xFFFE").unwrap_err().contains("reserved"));
    assert_eq!(
        parse_addr("0x0100"),
        Err("0x0100 is not a node address (it is config-tool's own)".to_string())
    );
    assert!(parse_addr("65536")
        .unwrap_err()
        .contains("not a 16-bit address"));
    assert!(parse_addr("").is_err());
}

/// A flash file another node process has open is refused (`InUse`), untouched: two nodes
/// on one file (a typo in a start loop) both took it, one staged its table over the
/// other's confirmed one, and that one booted the other's role after a power cut; and two
/// processes counted the same frame counters in the counter file beside it (nonces used
/// twice under one key), which goes with the flash file. Once the first is closed, the
/// file opens again.
#[test]
fn a_flash_file_in_use_by_another_node_is_refused() {
    let p = path("in-use");
    let first = HostFlash::open(&p).unwrap();
    let before = std::fs::read(&p).unwrap();
    match HostFlash::open(&p) {
        Err(e @ OpenError::InUse(_)) => assert_eq!(
            e.to_string(),
            format!(
                "flash file {} is in use by another node process (two nodes cannot share \
                 one flash)",
                p.display()
            )
        ),
        other => panic!("{:?}", other.err()),
    }
    assert_eq!(std::fs::read(&p).unwrap(), before);
    drop(first);
    assert!(HostFlash::open(&p).is_ok());
    let _ = std::fs::remove_file(&p);
}

/// A creation that did not finish (a full disk: here a file size limit of 8 KiB on the
/// node process) leaves no flash file where the node looks: the file appears whole or not
/// at all, so the next start creates it. A short one was left, and every later start
/// stopped at it ("is 8192 bytes, not a node flash file").
#[test]
fn a_creation_that_did_not_finish_leaves_no_flash_file() {
    let dir =
        PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("creating-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("n.flash");
    // The node stops at its flash file, before it looks for the medium.
    let run = std::process::Command::new("bash")
        .arg("-c")
        .arg("ulimit -f 8; trap '' XFSZ; exec \"$0\" --addr 0x0011 --medium 127.0.0.1:9 --flash \"$1\"")
        .arg(env!("CARGO_BIN_EXE_node-host"))
        .arg(&p)
        .output()
        .unwrap();
    assert_eq!(
        run.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(!p.exists(), "a short flash file was left");
    let f = HostFlash::open(&p).unwrap();
    assert_eq!(std::fs::read(&p).unwrap().len(), FILE_SIZE);
    drop(f);
    let _ = std::fs::remove_dir_all(&dir);
}
