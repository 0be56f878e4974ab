//! The flash regions a machinist writes without rebuilding the firmware:
//! the coefficient table (`ZSCT`) and the servo parameter block (`ZSPB`)
//! of both boards' `memory.x`.
//!
//! * `cargo xtask flash-table FILE.zsct` and `cargo xtask flash-params
//!   FILE.zspb`: check the file with the firmware's own code (parser, sign
//!   check, parameter limits), print what it is, and write it to the
//!   NUCLEO's region with `probe-rs download --binary-format bin
//!   --base-address ...` (`--dry-run` prints the command instead).
//! * `cargo xtask param-block --set NAME=VALUE ... --out FILE.zspb`: writes
//!   a parameter block.
//!
//! The QEMU runs of `cargo xtask test` with other tables in the region are
//! `table_checks`.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use zslide::params::{self, ParamSource};
use zslide::servo::ServoDesign;
use zslide::table::TableIdentity;

use crate::Result;

/// One board's regions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Regions {
    pub table_addr: u32,
    pub table_len: u32,
    pub params_addr: u32,
    pub params_len: u32,
}

/// NUCLEO-H743ZI2 (`memory.x` at the root): bank 2 sectors 7 and 6.
pub const NUCLEO: Regions = Regions {
    table_addr: 0x081E_0000,
    table_len: 128 * 1024,
    params_addr: 0x081C_0000,
    params_len: 128 * 1024,
};
/// probe-rs's name for the NUCLEO's chip.
pub const NUCLEO_CHIP: &str = "STM32H743ZITx";

/// QEMU mps2-an386 (`boards/qemu/memory.x`).
pub const QEMU: Regions = Regions {
    table_addr: 0x0030_0000,
    table_len: 512 * 1024,
    params_addr: 0x0038_0000,
    params_len: 4 * 1024,
};

/// The loop rate both boards run (their parameter blocks are checked at it).
pub const LOOP_HZ: u32 = 20_000;

#[derive(clap::Args, Debug)]
pub struct FlashArgs {
    /// The file to write (`host-sim coeffs --config ... --out FILE.zsct`,
    /// or `cargo xtask param-block ... --out FILE.zspb`).
    file: PathBuf,
    /// Print the probe-rs command instead of running it.
    #[arg(long)]
    dry_run: bool,
    /// probe-rs's probe selector (`VID:PID[:SERIAL]`) when several are
    /// connected.
    #[arg(long, value_name = "SEL")]
    probe: Option<String>,
}

#[derive(clap::Args, Debug)]
pub struct ParamBlockArgs {
    /// A parameter and its value (`cargo xtask link params` lists them);
    /// repeat for several.
    #[arg(long = "set", value_name = "NAME=VALUE", required = true)]
    set: Vec<String>,
    /// The block file to write.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
}

/// The table in `file`, checked as the firmware checks it, and that it
/// fits `regions`; every refusal names the file and says what is wrong.
pub fn check_table_file(file: &Path, regions: &Regions) -> Result<TableIdentity> {
    let bytes = fs::read(file).map_err(|e| format!("{}: cannot read: {e}", file.display()))?;
    let table = zslide::firmware::config::check_table(&bytes)
        .map_err(|e| format!("{}: table refused: {e}", file.display()))?;
    let id = table.identity();
    if id.len > regions.table_len {
        return Err(format!(
            "{}: table refused: {} bytes do not fit the {} KiB table region",
            file.display(),
            id.len,
            regions.table_len / 1024
        ));
    }
    Ok(id)
}

/// The parameter block in `file`, checked as the firmware checks it.
pub fn check_params_file(file: &Path, regions: &Regions) -> Result<ParamSource> {
    let bytes = fs::read(file).map_err(|e| format!("{}: cannot read: {e}", file.display()))?;
    if bytes.len() as u32 > regions.params_len {
        return Err(format!(
            "{}: parameter block refused: {} bytes do not fit the parameter region",
            file.display(),
            bytes.len()
        ));
    }
    match params::load_region(&bytes, &ServoDesign::brief(LOOP_HZ)) {
        Ok((_, _, ParamSource::BuiltIn)) => Err(format!(
            "{}: parameter block refused: the file is erased (all 0xFF or zero), not a block",
            file.display()
        )),
        Ok((_, _, src)) => Ok(src),
        Err(e) => Err(format!("{}: parameter block refused: {e}", file.display())),
    }
}

/// The probe-rs command that writes `file` at `addr` on the NUCLEO.
pub fn probe_rs_download(file: &Path, addr: u32, probe: Option<&str>) -> Command {
    let mut cmd = Command::new("probe-rs");
    cmd.args(["download", "--chip", NUCLEO_CHIP]);
    if let Some(p) = probe {
        cmd.args(["--probe", p]);
    }
    cmd.args(["--binary-format", "bin", "--base-address"])
        .arg(format!("{addr:#010x}"))
        .arg(file);
    cmd
}

fn show(cmd: &Command) -> String {
    std::iter::once(cmd.get_program())
        .chain(cmd.get_args())
        .map(|a| a.to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join(" ")
}

fn download(args: &FlashArgs, addr: u32) -> Result<u8> {
    let cmd = probe_rs_download(&args.file, addr, args.probe.as_deref());
    if args.dry_run {
        println!("{}", show(&cmd));
        return Ok(0);
    }
    eprintln!("==> {}", show(&cmd));
    let mut cmd = cmd;
    let status = cmd.status().map_err(|e| {
        format!(
            "cannot start probe-rs ({e}): install it with `cargo install probe-rs-tools --locked`"
        )
    })?;
    if status.success() {
        eprintln!("written; reset the board (the firmware reads the region at boot)");
        Ok(0)
    } else {
        Err(format!("probe-rs download failed ({status})"))
    }
}

pub fn flash_table(args: &FlashArgs) -> Result<u8> {
    let id = check_table_file(&args.file, &NUCLEO)?;
    eprintln!("{}: {id}", args.file.display());
    eprintln!(
        "table region of the NUCLEO-H743ZI2: {:#010x} ({} KiB)",
        NUCLEO.table_addr,
        NUCLEO.table_len / 1024
    );
    download(args, NUCLEO.table_addr)
}

pub fn flash_params(args: &FlashArgs) -> Result<u8> {
    let src = check_params_file(&args.file, &NUCLEO)?;
    eprintln!("{}: {src}", args.file.display());
    download(args, NUCLEO.params_addr)
}

/// `NAME=VALUE` → (parameter id, value), or why not.
pub fn parse_setting(s: &str) -> Result<(u16, f64)> {
    let (name, value) = s
        .split_once('=')
        .ok_or_else(|| format!("{s:?}: expected NAME=VALUE"))?;
    let p = params::by_name(name.trim()).ok_or_else(|| {
        format!("{name:?}: no such servo parameter (`cargo xtask link params` lists them)")
    })?;
    let v: f64 = value
        .trim()
        .parse()
        .map_err(|_| format!("{s:?}: {value:?} is not a number"))?;
    Ok((p.id, v))
}

pub fn param_block(args: &ParamBlockArgs) -> Result<u8> {
    let entries = args
        .set
        .iter()
        .map(|s| parse_setting(s))
        .collect::<Result<Vec<_>>>()?;
    let mut out = vec![0u8; params::HEADER_LEN + entries.len() * params::ENTRY_LEN];
    let base = ServoDesign::brief(LOOP_HZ);
    let n = params::encode_block(&entries, &base, &mut out).map_err(|e| match e {
        // The design's rule with the values that break it (the block's
        // values on the built-in design), not the rule alone.
        params::ParamError::Design(de) => {
            let mut d = base;
            for &(id, v) in &entries {
                if let Some(p) = params::by_id(id) {
                    p.set(&mut d, v);
                }
            }
            format!("parameter block refused: {}", d.refusal(de))
        }
        e => format!("parameter block refused: {e}"),
    })?;
    fs::write(&args.out, &out[..n]).map_err(|e| format!("{}: {e}", args.out.display()))?;
    eprintln!(
        "{}: {n} bytes, {} parameters",
        args.out.display(),
        entries.len()
    );
    Ok(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use zslide::table::CoeffTable;

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
            let text = fs::read_to_string(crate::root().join(file)).unwrap();
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
            let flash = region_of(&text, "FLASH");
            assert!(
                flash.0 + flash.1 <= r.table_addr.min(r.params_addr),
                "{file}"
            );
        }
        // Each NUCLEO region is one whole 128 KiB sector of bank 2.
        for a in [NUCLEO.table_addr, NUCLEO.params_addr] {
            assert_eq!((a - 0x0810_0000) % (128 * 1024), 0);
        }
    }

    #[test]
    fn flash_table_checks_the_file_and_builds_the_probe_rs_command() {
        let root = crate::root();
        let good = root.join("tables/default.zsct");
        let id = check_table_file(&good, &NUCLEO).unwrap();
        assert_eq!(id.len, 5204);
        let cmd = probe_rs_download(&good, NUCLEO.table_addr, None);
        assert_eq!(
            show(&cmd),
            format!(
                "probe-rs download --chip STM32H743ZITx --binary-format bin --base-address 0x081e0000 {}",
                good.display()
            )
        );
        let with_probe = probe_rs_download(&good, NUCLEO.params_addr, Some("0483:374e"));
        assert!(show(&with_probe)
            .contains("--probe 0483:374e --binary-format bin --base-address 0x081c0000"));

        let dir = root.join("target/regions-test");
        fs::create_dir_all(&dir).unwrap();
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

    #[test]
    fn param_blocks_are_written_checked_and_refused_in_words() {
        let dir = crate::root().join("target/regions-test");
        fs::create_dir_all(&dir).unwrap();
        let out = dir.join("p.zspb");
        param_block(&ParamBlockArgs {
            set: vec!["following_error_in=0.002".into(), "hum_notch_q = 0".into()],
            out: out.clone(),
        })
        .unwrap();
        assert!(matches!(
            check_params_file(&out, &NUCLEO),
            Ok(ParamSource::Block { entries: 2, .. })
        ));
        let e = param_block(&ParamBlockArgs {
            set: vec!["current_limit_a=9".into()],
            out: dir.join("q.zspb"),
        })
        .unwrap_err();
        assert!(
            e.contains("current_limit_a = 9 A is outside its limits 0.1 .. 8 A"),
            "{e}"
        );
        // Within its own limits (1 .. 1000) but above the built-in fast
        // bandwidth (150 Hz): the relation and both values are named.
        let e = param_block(&ParamBlockArgs {
            set: vec!["bandwidth_hz=160".into()],
            out: dir.join("r.zspb"),
        })
        .unwrap_err();
        assert!(
            e.contains("bandwidth_fast_hz = 150 must be at least bandwidth_hz = 160"),
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
}
