//! `cargo xtask size`: flash and RAM use of every image, as percentages of
//! the regions their `memory.x` defines.

use std::fs;

use crate::images::{build_board, build_qemu};
use crate::tools::{require, Tool};
use crate::{board_elf, centre_elf, elf, qemu_elf, root, step, Result};

pub fn run() -> Result<u8> {
    require(&[Tool::Target, Tool::FlipLink])?;
    build_board()?;
    build_qemu()?;
    print_sizes()?;
    Ok(0)
}

/// LENGTH of region `name` in a linker `memory.x`, bytes (`1792K`, `3M`,
/// or a number): the percentages of `size` are of the region the image is
/// linked into, read from the file that defines it.
fn region_len(memory_x: &std::path::Path, name: &str) -> Result<u64> {
    let text = fs::read_to_string(memory_x).map_err(|e| format!("{}: {e}", memory_x.display()))?;
    let line = text
        .lines()
        .find(|l| l.split(':').next().is_some_and(|n| n.trim() == name))
        .ok_or_else(|| format!("{}: no {name} region", memory_x.display()))?;
    let len = line
        .split("LENGTH")
        .nth(1)
        .and_then(|r| r.split('=').nth(1))
        .map(str::trim)
        .ok_or_else(|| format!("{}: {name} has no LENGTH", memory_x.display()))?;
    let (num, unit) = match len.chars().last() {
        Some('K') => (&len[..len.len() - 1], 1024),
        Some('M') => (&len[..len.len() - 1], 1024 * 1024),
        _ => (len, 1),
    };
    let n: u64 = if let Some(h) = num.strip_prefix("0x") {
        u64::from_str_radix(h, 16).map_err(|e| e.to_string())?
    } else {
        num.parse()
            .map_err(|e| format!("{}: {name} LENGTH {len}: {e}", memory_x.display()))?
    };
    Ok(n * unit)
}

pub fn print_sizes() -> Result<()> {
    step("image sizes");
    let board = root().join("memory.x");
    let qemu = root().join("boards/qemu/memory.x");
    for (name, path, memory_x) in [
        ("NUCLEO-H743ZI2 (zslide-fw)", board_elf(), &board),
        ("NUCLEO-H743ZI2 (zslide-centre)", centre_elf(), &board),
        ("QEMU mps2-an386 (zslide-qemu)", qemu_elf(), &qemu),
    ] {
        let flash_total = region_len(memory_x, "FLASH")?;
        let ram_total = region_len(memory_x, "RAM")?;
        let s = elf::sizes(&path)?;
        eprintln!(
            "{name}: flash {} B ({:.2} % of the {} KiB FLASH region), static RAM {} B ({:.2} % of {} KiB)  \
             [text+rodata {} B, data {} B, bss+uninit {} B]",
            s.flash(),
            100.0 * s.flash() as f64 / flash_total as f64,
            flash_total / 1024,
            s.ram(),
            100.0 * s.ram() as f64 / ram_total as f64,
            ram_total / 1024,
            s.text,
            s.data,
            s.bss
        );
    }
    Ok(())
}
