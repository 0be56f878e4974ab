//! The register map of the STM32H743, read from the source of the `stm32h7`
//! PAC (0.16, which svd2rust generated from ST's SVD with the stm32-rs
//! patches): every peripheral's base address and every register's offset
//! and name, into `$OUT_DIR/regs.rs`. The emulator names each access by it,
//! modelled or not, so an unmodelled access stops the run with the name
//! the reference manual gives.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};

fn pac_dir() -> PathBuf {
    let home = std::env::var("CARGO_HOME")
        .map(PathBuf::from)
        .unwrap_or_else(|_| PathBuf::from(std::env::var("HOME").unwrap()).join(".cargo"));
    let src = home.join("registry/src");
    for index in fs::read_dir(&src).expect("cargo registry") {
        let p = index.unwrap().path().join("stm32h7-0.16.0/src");
        if p.exists() {
            return p;
        }
    }
    panic!(
        "stm32h7-0.16.0 not in {} (a build-dependency fetches it)",
        src.display()
    );
}

/// `0x1c` or `0x04..0x104` at the start of a doc line.
fn offsets(doc: &str) -> Option<(u32, Option<u32>)> {
    let head = doc.split(" - ").next()?;
    let mut parts = head.split("..");
    let a = u32::from_str_radix(parts.next()?.trim_start_matches("0x"), 16).ok()?;
    let b = parts
        .next()
        .and_then(|b| u32::from_str_radix(b.trim_start_matches("0x"), 16).ok());
    Some((a, b))
}

/// Registers of a register-block module file: (offset, name), clusters
/// flattened as `cluster.reg`.
fn block(file: &Path, prefix: &str, base: u32, out: &mut BTreeMap<u32, Vec<String>>) {
    let Ok(text) = fs::read_to_string(file) else {
        return;
    };
    let lines: Vec<&str> = text.lines().collect();
    for (i, l) in lines.iter().enumerate() {
        let Some(doc) = l.trim().strip_prefix("///0x").map(|d| format!("0x{d}")) else {
            continue;
        };
        let Some((off, end)) = offsets(&doc) else {
            continue;
        };
        let Some(f) = lines[i + 1..(i + 4).min(lines.len())]
            .iter()
            .find_map(|l| l.trim().strip_prefix("pub const fn "))
        else {
            continue;
        };
        let name = f.split('(').next().unwrap_or("");
        let args = f.split('(').nth(1).unwrap_or("");
        if args.contains("n: usize") || name.ends_with("_iter") {
            continue; // the array accessor; each element has its own
        }
        let ty = f.rsplit("-> &").next().unwrap_or("").trim_end_matches(" {");
        if doc.contains("Cluster") && end.is_some() {
            let module = ty.to_lowercase();
            let dir = file.parent().unwrap();
            let cluster = [
                dir.join(format!("{module}.rs")),
                dir.join(&module).join("mod.rs"),
            ];
            for c in cluster {
                if c.exists() {
                    block(&c, &format!("{prefix}{name}."), base + off, out);
                    break;
                }
            }
            continue;
        }
        let names = out.entry(base + off).or_default();
        let full = format!("{prefix}{name}");
        if !names.contains(&full) {
            names.push(full);
        }
    }
}

fn main() {
    let pac = pac_dir();
    let device = pac.join("stm32h743/mod.rs");
    println!("cargo:rerun-if-changed={}", device.display());
    let text = fs::read_to_string(&device).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    // module name -> file
    let mut modules = BTreeMap::new();
    for (i, l) in lines.iter().enumerate() {
        if let Some(p) = l.trim().strip_prefix("#[path = \"") {
            let path = p.trim_end_matches("\"]");
            if let Some(m) = lines
                .get(i + 1)
                .and_then(|n| n.trim().strip_prefix("pub mod "))
            {
                modules.insert(
                    m.trim_end_matches(';').to_string(),
                    pac.join("stm32h743").join(path),
                );
            }
        }
    }
    let mut entries = Vec::new();
    for l in &lines {
        let Some(rest) = l.trim().strip_prefix("pub type ") else {
            continue;
        };
        let Some((name, periph)) = rest.split_once(" = crate::Periph<") else {
            continue;
        };
        let Some((module, addr)) = periph.split_once("::RegisterBlock, ") else {
            continue;
        };
        let addr = addr.trim_end_matches(">;").replace('_', "");
        let Ok(base) = u32::from_str_radix(addr.trim_start_matches("0x"), 16) else {
            continue;
        };
        let Some(file) = modules.get(module) else {
            continue;
        };
        let mut regs = BTreeMap::new();
        block(file, "", base, &mut regs);
        for (a, names) in regs {
            entries.push((a, name.to_string(), names.join("|")));
        }
    }
    entries.sort();
    let mut out = String::from("pub static REGS: &[(u32, &str, &str)] = &[\n");
    for (a, p, n) in &entries {
        out.push_str(&format!("    ({a:#010x}, {p:?}, {n:?}),\n"));
    }
    out.push_str("];\n");
    let dest = PathBuf::from(std::env::var("OUT_DIR").unwrap()).join("regs.rs");
    fs::write(dest, out).unwrap();
}
