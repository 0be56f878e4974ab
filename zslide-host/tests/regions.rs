//! The regions `zslide` writes, and the checks of a file before it is
//! written (moved from `cargo xtask flash-table/flash-params/param-block`).

use std::fs;
use std::path::PathBuf;

use zslide::params::ParamSource;
use zslide::table::CoeffTable;
use zslide_host::flash::{probe_rs_download, show};
use zslide_host::regions::*;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

fn scratch() -> PathBuf {
    let d = root().join("target/zslide-host-test");
    fs::create_dir_all(&d).unwrap();
    d
}

fn region_of(memory_x: &str, name: &str) -> (u32, u32) {
    let line = memory_x
        .lines()
        .find(|l| l.trim_start().starts_with(name) && l.contains("ORIGIN"))
        .unwrap_or_else(|| panic!("{name} not in memory.x"));
    let origin = line
        .split("ORIGIN = ")
        .nth(1)
        .unwrap()
        .split(',')
        .next()
        .unwrap();
    let len = line.split("LENGTH = ").nth(1).unwrap().trim();
    let origin = u32::from_str_radix(origin.trim().trim_start_matches("0x"), 16).unwrap();
    let len = match len.strip_suffix('K') {
        Some(k) => k.parse::<u32>().unwrap() * 1024,
        None => len.trim_end_matches('M').parse::<u32>().unwrap() * 1024 * 1024,
    };
    (origin, len)
}

/// The addresses this tool writes are the linker's regions.
#[test]
fn the_regions_are_those_of_both_memory_x() {
    for (file, r) in [("memory.x", NUCLEO), ("boards/qemu/memory.x", QEMU)] {
        let text = fs::read_to_string(root().join(file)).unwrap();
        assert_eq!(
            region_of(&text, "ZSCT"),
            (r.table_addr, r.table_len),
            "{file}"
        );
        assert_eq!(
            region_of(&text, "ZSPB"),
            (r.params_addr, r.params_len),
            "{file}"
        );
        assert_eq!(
            region_of(&text, "ZSIB"),
            (r.interruptions_addr, r.interruptions_len),
            "{file}"
        );
        let flash = region_of(&text, "FLASH");
        assert!(
            flash.0 + flash.1 <= r.table_addr.min(r.params_addr).min(r.interruptions_addr),
            "{file}"
        );
        // No two regions overlap.
        let mut spans = [
            (r.table_addr, r.table_len),
            (r.params_addr, r.params_len),
            (r.interruptions_addr, r.interruptions_len),
        ];
        spans.sort();
        for w in spans.windows(2) {
            assert!(w[0].0 + w[0].1 <= w[1].0, "{file}: {spans:x?}");
        }
    }
    // Each NUCLEO region is made of whole 128 KiB sectors; the table is in
    // bank 1 with the image, the parameter store alone in bank 2 (a bank-2
    // erase stalls reads of bank 2 only: `src/board/flash.rs`).
    for a in [
        NUCLEO.table_addr,
        NUCLEO.params_addr,
        NUCLEO.interruptions_addr,
    ] {
        assert_eq!((a - 0x0800_0000) % (128 * 1024), 0);
    }
    // The interruption block's sector ends bank 2 (read at boot only).
    assert_eq!(
        NUCLEO.interruptions_addr + NUCLEO.interruptions_len,
        0x0820_0000
    );
}

// The table in bank 1, the store alone in bank 2 (bank 2 starts at
// 0x0810_0000): checked when the test compiles.
const _: () = assert!(NUCLEO.table_addr + NUCLEO.table_len <= 0x0810_0000);
const _: () = assert!(NUCLEO.params_addr >= 0x0810_0000);

#[test]
fn table_files_are_checked_and_the_probe_rs_command_built() {
    let good = root().join("tables/default.zsct");
    let id = check_table_file(&good, &NUCLEO).unwrap();
    assert_eq!(id.len, 5204);
    let cmd = probe_rs_download(&good, NUCLEO.table_addr, None);
    assert_eq!(
        show(&cmd),
        format!(
            "probe-rs download --chip STM32H743ZITx --binary-format bin --base-address 0x080e0000 {}",
            good.display()
        )
    );
    let with_probe = probe_rs_download(&good, NUCLEO.params_addr, Some("0483:374e"));
    assert!(show(&with_probe)
        .contains("--probe 0483:374e --binary-format bin --base-address 0x081a0000"));

    let dir = scratch();
    let e = check_table_file(&dir.join("absent.zsct"), &NUCLEO).unwrap_err();
    assert!(e.contains("absent.zsct: cannot read"), "{e}");
    let mut bytes = fs::read(&good).unwrap();
    bytes[10] = 33;
    let p = dir.join("bad-header.zsct");
    fs::write(&p, &bytes).unwrap();
    let e = check_table_file(&p, &NUCLEO).unwrap_err();
    assert!(
        e.contains("bad-header.zsct: table refused: the header is corrupt"),
        "{e}"
    );
    // A valid image whose command has the wrong sign: the sign check.
    let t = CoeffTable::parse(zslide::DEFAULT_TABLE).unwrap();
    let mut h = *t.header();
    let payload: Vec<i32> = (0..t.node_count())
        .flat_map(|n| (0..t.terms()).map(move |c| (n, c)))
        .map(|(n, c)| -t.coeff_raw(n, c))
        .collect();
    let mut img = vec![0u8; h.image_len()];
    h.encode(&payload, &mut img).unwrap();
    let p = dir.join("negated.zsct");
    fs::write(&p, &img).unwrap();
    let e = check_table_file(&p, &NUCLEO).unwrap_err();
    assert!(
        e.contains("negated.zsct: table refused: the command is positive somewhere"),
        "{e}"
    );
    // Too large for the region.
    h.node_count = 8192;
    h.dx_raw = 1 << 14; // 0.001 in: 8.19 in of grid
    let big: Vec<i32> = vec![0; 8192 * usize::from(h.terms)];
    let mut img = vec![0u8; h.image_len()];
    h.encode(&big, &mut img).unwrap();
    let p = dir.join("big.zsct");
    fs::write(&p, &img).unwrap();
    let e = check_table_file(&p, &NUCLEO).unwrap_err();
    assert!(e.contains("do not fit the 128 KiB table region"), "{e}");
}

/// `table holes` writes the block of a scenario's bolt holes, which
/// `table check` reads as the firmware does (its holes listed); a damaged
/// block is refused in the parser's words, naming the file; `table flash
/// --dry-run` writes a block to the NUCLEO's interruption region.
#[test]
fn interruption_blocks_are_built_checked_and_flashed_to_their_region() {
    use zslide_host::cli::{execute, Cmd, HolesArgs, TableCmd};
    let dir = scratch();
    let out = dir.join("part.zsib");
    let mut link =
        zslide_host::client::Link::new("tcp:127.0.0.1:1", std::time::Duration::from_millis(100));
    let mut said = Vec::new();
    let holes = Cmd::Table {
        cmd: TableCmd::Holes(HolesArgs {
            config: "legacy-hw".into(),
            out: out.clone(),
        }),
    };
    execute(&holes, &mut link, &mut said).unwrap();
    let said = String::from_utf8(said).unwrap();
    // legacy-hw: eight 0.75 in holes on the 3.5 in circle; 12 + 8 × 12 + 4
    // bytes (`zslide::table::interrupt`'s format).
    assert!(said.contains("wrote"), "{said}");
    assert!(said.contains("(112 bytes, 8 holes)"), "{said}");
    assert!(
        said.contains(
            "hole 0: centre radius 3.5000 in, angle 157.500° (spindle), diameter 0.7500 in"
        ),
        "{said}"
    );
    assert!(is_interruption_file(&out).unwrap());
    assert!(!is_interruption_file(&root().join("tables/default.zsct")).unwrap());
    let holes = check_interruptions_file(&out, &NUCLEO).unwrap();
    assert_eq!(holes.holes().len(), 8);

    let mut bytes = fs::read(&out).unwrap();
    bytes[LAST_DIAMETER_BYTE] ^= 1;
    let bad = dir.join("bad.zsib");
    fs::write(&bad, &bytes).unwrap();
    let e = check_interruptions_file(&bad, &NUCLEO).unwrap_err();
    assert!(
        e.contains("bad.zsib: interruption block refused: interruption block CRC mismatch"),
        "{e}"
    );
    let mut said = Vec::new();
    let flash = Cmd::Table {
        cmd: TableCmd::Flash(zslide_host::cli::FlashArgs {
            file: bad,
            dry_run: true,
            probe: None,
        }),
    };
    let e = execute(&flash, &mut link, &mut said).unwrap_err();
    assert!(e.contains("CRC mismatch"), "{e}");
    assert!(said.is_empty(), "nothing written for a refused block");
}

/// A byte of the last hole's diameter in a block of eight.
const LAST_DIAMETER_BYTE: usize = 12 + 7 * 12 + 8;

/// A parameter block handed to the table command (and the reverse) is
/// named for what it is, not "cut short".
#[test]
fn a_file_of_the_other_kind_is_named_for_what_it_is() {
    let dir = scratch();
    let block = dir.join("kind.zspb");
    fs::write(&block, param_block(&[(1, 40.0)]).unwrap()).unwrap();
    let e = check_table_file(&block, &NUCLEO).unwrap_err();
    assert!(
        e.contains("kind.zspb: table refused: this is a servo parameter block (ZSPB), not a coefficient table: write it with `zslide params flash`"),
        "{e}"
    );
    let table = root().join("tables/default.zsct");
    let e = check_params_file(&table, &NUCLEO).unwrap_err();
    assert!(
        e.contains("default.zsct: parameter block refused: this is a coefficient table (ZSCT)"),
        "{e}"
    );
}

#[test]
fn param_blocks_are_written_checked_and_refused_in_words() {
    let dir = scratch();
    let out = dir.join("p.zspb");
    let entries: Vec<(u16, f64)> = ["following_error_in=0.002", "hum_notch_q = 0"]
        .iter()
        .map(|s| parse_setting(s).unwrap())
        .collect();
    fs::write(&out, param_block(&entries).unwrap()).unwrap();
    let (src, got) = check_params_file(&out, &NUCLEO).unwrap();
    assert!(matches!(src, ParamSource::Block { entries: 2, .. }));
    assert_eq!(got, entries);
    let e = param_block(&[parse_setting("current_limit_a=9").unwrap()]).unwrap_err();
    assert!(
        e.contains("current_limit_a = 9 A is outside its limits 0.1 .. 8 A"),
        "{e}"
    );
    assert!(parse_setting("bandwith_hz=3")
        .unwrap_err()
        .contains("no such servo parameter"));
    assert!(parse_setting("bandwidth_hz")
        .unwrap_err()
        .contains("NAME=VALUE"));
    let mut bytes = fs::read(&out).unwrap();
    bytes[20] ^= 1;
    fs::write(dir.join("r.zspb"), &bytes).unwrap();
    let e = check_params_file(&dir.join("r.zspb"), &NUCLEO).unwrap_err();
    assert!(
        e.contains("r.zspb: parameter block refused: the parameter block is corrupt"),
        "{e}"
    );
}

/// `params flash` writes the NUCLEO's region as the firmware's store
/// holding the block: the board's boot (`store::boot::at_boot_owned`, the
/// store's block first) runs the block's values. A bare block at the
/// region's start, as `params flash` wrote before the store owned the
/// region, still boots (not dropped unseen); the first save over it
/// starts the store afresh.
#[test]
fn the_parameter_region_is_written_as_a_store_the_boot_reads() {
    use zslide::store::ram::{Bank2Region, BANK2_REGION_BYTES};
    use zslide::store::{boot, Store};
    let entries = [parse_setting("following_error_ms=7").unwrap()];
    let block = param_block(&entries).unwrap();
    let image = params_store_image(&block).unwrap();
    assert_eq!(image.len() as u32, NUCLEO.params_len);
    let base = zslide::servo::ServoDesign::brief(LOOP_HZ);
    let ms = zslide::params::by_name("following_error_ms").unwrap();
    let crc = u32::from_le_bytes(block[12..16].try_into().unwrap());
    let mut bare = vec![0xFF; BANK2_REGION_BYTES];
    bare[..block.len()].copy_from_slice(&block);
    for (what, bytes) in [("store image", &image), ("bare block", &bare)] {
        let mut flash = Box::new(Bank2Region::with_image(bytes));
        let mut s = Store::new(&mut *flash, 0..BANK2_REGION_BYTES as u32).unwrap();
        let (d, _, src) = boot::at_boot_owned(&mut s, &base).unwrap();
        assert_eq!(ms.get(&d), 7.0, "{what}");
        assert_eq!(src, ParamSource::Block { entries: 1, crc }, "{what}");
        let other = param_block(&[parse_setting("following_error_ms=9").unwrap()]).unwrap();
        s.save(&other, &base).unwrap();
        let (d, _, _) = boot::at_boot_owned(&mut s, &base).unwrap();
        assert_eq!(ms.get(&d), 9.0, "{what}, saved over");
    }
}
