//! The flash regions a machinist writes without rebuilding the firmware:
//! the coefficient table (`ZSCT`), the servo parameter block (`ZSPB`) and
//! the part's interruption block (`ZSIB`) of both boards' `memory.x`. Every file is checked with the firmware's
//! own code (parser, sign check, parameter limits) before it is written,
//! and every refusal names the file.

use std::fs;
use std::path::Path;

use zslide::params::{self, ParamSource};
use zslide::servo::ServoDesign;
use zslide::table::interrupt::{self, Interruptions};
use zslide::table::TableIdentity;

use crate::Result;

/// One board's regions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Regions {
    pub table_addr: u32,
    pub table_len: u32,
    pub params_addr: u32,
    pub params_len: u32,
    pub interruptions_addr: u32,
    pub interruptions_len: u32,
}

/// NUCLEO-H743ZI2 (`memory.x` at the root): the table in bank 1 sector 7,
/// the parameter store in bank 2 sectors 5-6, the interruption block in
/// bank 2 sector 7.
pub const NUCLEO: Regions = Regions {
    table_addr: 0x080E_0000,
    table_len: 128 * 1024,
    params_addr: 0x081A_0000,
    params_len: 256 * 1024,
    interruptions_addr: 0x081E_0000,
    interruptions_len: 128 * 1024,
};
/// probe-rs's name for the NUCLEO's chip.
pub const NUCLEO_CHIP: &str = "STM32H743ZITx";

/// QEMU mps2-an386 (`boards/qemu/memory.x`).
pub const QEMU: Regions = Regions {
    table_addr: 0x0030_0000,
    table_len: 512 * 1024,
    params_addr: 0x0038_0000,
    params_len: 4 * 1024,
    interruptions_addr: 0x0038_1000,
    interruptions_len: 4 * 1024,
};

/// The loop rate both boards run (their parameter blocks are checked at it).
pub const LOOP_HZ: u32 = 20_000;

fn read(file: &Path) -> Result<Vec<u8>> {
    fs::read(file).map_err(|e| format!("{}: cannot read: {e}", file.display()))
}

/// What a file that is the other kind is, in words (a `.zspb` handed to
/// the table command is not "cut short").
fn other_kind(bytes: &[u8], want: [u8; 4]) -> Option<&'static str> {
    let magic = bytes.get(0..4)?;
    if magic == want {
        None
    } else if magic == params::MAGIC {
        Some("this is a servo parameter block (ZSPB), not a coefficient table: write it with `zslide params flash`")
    } else if magic == zslide::table::MAGIC {
        Some("this is a coefficient table (ZSCT), not a servo parameter block: write it with `zslide table flash`")
    } else if magic == interrupt::MAGIC {
        Some("this is an interruption block (ZSIB), not a servo parameter block: write it with `zslide table flash`")
    } else {
        None
    }
}

/// The table in `file`, checked as the firmware checks it, and that it
/// fits `regions`.
pub fn check_table_file(file: &Path, regions: &Regions) -> Result<TableIdentity> {
    let bytes = read(file)?;
    if let Some(why) = other_kind(&bytes, zslide::table::MAGIC) {
        return Err(format!("{}: table refused: {why}", file.display()));
    }
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

/// Whether `file` holds an interruption block (its magic), not a table:
/// `zslide table check` / `flash` take both.
pub fn is_interruption_file(file: &Path) -> Result<bool> {
    Ok(read(file)?.get(0..4) == Some(&interrupt::MAGIC[..]))
}

/// The interruption block in `file`, checked as the firmware checks it
/// (`Interruptions::parse`), and that it fits `regions`.
pub fn check_interruptions_file(file: &Path, regions: &Regions) -> Result<Interruptions> {
    let bytes = read(file)?;
    let holes = Interruptions::parse(&bytes)
        .map_err(|e| format!("{}: interruption block refused: {e}", file.display()))?;
    if bytes.len() as u32 > regions.interruptions_len {
        return Err(format!(
            "{}: interruption block refused: {} bytes do not fit the {} KiB interruption region",
            file.display(),
            bytes.len(),
            regions.interruptions_len / 1024
        ));
    }
    Ok(holes)
}

/// The holes of a checked block, one line each: centre radius, angle
/// (degrees of the firmware's spindle angle) and diameter, inches.
pub fn hole_lines(holes: &Interruptions) -> Vec<String> {
    holes
        .holes()
        .iter()
        .enumerate()
        .map(|(k, h)| {
            format!(
                "hole {k}: centre radius {:.4} in, angle {:.3}° (spindle), diameter {:.4} in",
                f64::from(h.centre_radius_uin) * 1e-6,
                f64::from(h.angle.0) * 360.0 / 4_294_967_296.0,
                f64::from(h.diameter_uin) * 1e-6
            )
        })
        .collect()
}

/// The parameter block in `file`, checked as the firmware checks it:
/// where it comes from, and its entries.
pub fn check_params_file(file: &Path, regions: &Regions) -> Result<(ParamSource, Vec<(u16, f64)>)> {
    let bytes = read(file)?;
    if let Some(why) = other_kind(&bytes, params::MAGIC) {
        return Err(format!(
            "{}: parameter block refused: {why}",
            file.display()
        ));
    }
    if bytes.len() as u32 > regions.params_len {
        return Err(format!(
            "{}: parameter block refused: {} bytes do not fit the {} KiB parameter region",
            file.display(),
            bytes.len(),
            regions.params_len / 1024
        ));
    }
    match params::load_region(&bytes, &ServoDesign::brief(LOOP_HZ)) {
        Ok((_, _, ParamSource::BuiltIn)) => Err(format!(
            "{}: parameter block refused: the file is erased (all 0xFF or zero), not a block",
            file.display()
        )),
        Ok((_, _, src)) => Ok((src, block_entries(&bytes))),
        Err(e) => Err(format!("{}: parameter block refused: {e}", file.display())),
    }
}

/// The (id, value) entries of a block `params::load_region` accepted.
fn block_entries(bytes: &[u8]) -> Vec<(u16, f64)> {
    let n = usize::from(u16::from_le_bytes([bytes[6], bytes[7]]));
    bytes[params::HEADER_LEN..params::HEADER_LEN + n * params::ENTRY_LEN]
        .chunks_exact(params::ENTRY_LEN)
        .filter_map(|e| {
            let id = u16::from_le_bytes([e[0], e[1]]);
            let v = f64::from_le_bytes(e[4..12].try_into().ok()?);
            params::by_id(id).map(|_| (id, v))
        })
        .collect()
}

/// `NAME=VALUE` → (parameter id, value), or why not.
pub fn parse_setting(s: &str) -> Result<(u16, f64)> {
    let (name, value) = s
        .split_once('=')
        .ok_or_else(|| format!("{s:?}: expected NAME=VALUE"))?;
    let p = params::by_name(name.trim()).ok_or_else(|| {
        format!("{name:?}: no such servo parameter (`zslide params show` lists them)")
    })?;
    let v: f64 = value
        .trim()
        .parse()
        .map_err(|_| format!("{s:?}: {value:?} is not a number"))?;
    Ok((p.id, v))
}

/// A parameter block of `entries`, checked against the brief's design at
/// the boards' loop rate.
pub fn param_block(entries: &[(u16, f64)]) -> Result<Vec<u8>> {
    let mut out = vec![0u8; params::HEADER_LEN + entries.len() * params::ENTRY_LEN];
    let base = ServoDesign::brief(LOOP_HZ);
    let n = params::encode_block(entries, &base, &mut out).map_err(|e| match e {
        // The design's rule with the values that break it (the block's
        // values on the built-in design), not the rule alone.
        params::ParamError::Design(de) => {
            let mut d = base;
            for &(id, v) in entries {
                if let Some(p) = params::by_id(id) {
                    p.set(&mut d, v);
                }
            }
            format!("parameter block refused: {}", d.refusal(de))
        }
        e => format!("parameter block refused: {e}"),
    })?;
    out.truncate(n);
    Ok(out)
}

/// The NUCLEO's parameter region as `zslide params flash` writes it: the
/// firmware's parameter store (`zslide::store`, which owns the region) on
/// erased flash, holding `block` as its one saved item: what a `zslide
/// params save` of the same parameters leaves on a new board, and what the
/// boot reads first. The block is checked again by the store's save.
pub fn params_store_image(block: &[u8]) -> Result<Vec<u8>> {
    use zslide::store::ram::{Bank2Region, BANK2_REGION_BYTES};
    let mut flash = Box::new(Bank2Region::new());
    zslide::store::Store::new(&mut *flash, 0..BANK2_REGION_BYTES as u32)
        .and_then(|mut s| s.save(block, &ServoDesign::brief(LOOP_HZ)))
        .map_err(|e| format!("the parameter store image: {e}"))?;
    Ok(flash.bytes.to_vec())
}
