//! Power cuts across boots of the QEMU image (`cargo xtask flash-cut`,
//! part of `test`): the image's parameter store (`zslide::store`, the
//! NUCLEO's code) on its NOR flash model (`boards/qemu/src/flash.rs`), the
//! flash kept in a file between QEMU runs.
//!
//! From each starting state of the flash, the image boots and saves a new
//! set over the link (`save`, `powercut.rs` of the image) once uncut, to
//! count its flash operations M; then once for each N in 1..=M with the
//! power cut during operation N (the operation torn, the image stopped
//! there). After every cut the image boots again from what the cut left and
//! must boot the set saved before or the set being saved, all three of its
//! values from the one set (never a mix), from a block (never nothing,
//! once anything was saved); and that boot's own save must work.
//!
//! The starting states: a new board (erased), one save done (the image's
//! own), and two the host prepares with the same store code on the same
//! model (`zslide::store::ram::Bank2Region`), where the image's next save
//! moves on to the next sector (the map erasing the sector it keeps free)
//! from sector 0 and back from sector 1: the operations where a cut hurts
//! most.

use std::fs;
use std::path::{Path, PathBuf};

use zslide::params;
use zslide::servo::ServoDesign;
use zslide::store::ram::{Bank2Region, BANK2_REGION_BYTES};
use zslide::store::{Store, MAX_BLOCK};

use crate::{qemu_elf, run_qemu_elf_at, step, QemuRegions, Result};

/// The image's flash file, in QEMU's working directory (the image's
/// `flash::FILE`).
const FILE: &str = "zspb-flash.bin";

/// A parameter set, in the whole units the image's command line takes:
/// `hum_notch_q`, `following_error_ms`, `following_error_in` in µin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Set {
    q: u32,
    ms: u32,
    fe_uin: u32,
}

/// Set `k`: consecutive sets differ in all three values, so a block mixing
/// two would show.
fn set(k: u32) -> Set {
    Set {
        q: 5 + k % 20,
        ms: 1 + k % 5,
        fe_uin: 1000 + 100 * (k % 30),
    }
}

/// What a boot reported: its parameter source, in the image's words, and
/// the set it runs.
#[derive(Debug)]
struct Boot {
    source: String,
    set: Set,
}

/// One run's findings.
#[derive(Debug, Default)]
struct Run {
    boot: Option<Boot>,
    /// The save's reply came: flash operations since boot.
    saved_ops: Option<u32>,
    /// The power was cut during this operation.
    cut_at: Option<u32>,
    log: Vec<String>,
}

fn number_after(line: &str, key: &str) -> Option<u32> {
    let rest = &line[line.find(key)? + key.len()..];
    let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
    digits.parse().ok()
}

fn parse(lines: Vec<String>) -> Run {
    let mut run = Run::default();
    for l in &lines {
        if let Some(i) = l.find("flash boot: ") {
            let rest = &l[i + "flash boot: ".len()..];
            let source = rest.split(';').next().unwrap_or("").to_string();
            if let (Some(q), Some(ms), Some(fe)) = (
                number_after(rest, "hum_notch_q "),
                number_after(rest, "following_error_ms "),
                number_after(rest, "following_error_in "),
            ) {
                run.boot = Some(Boot {
                    source,
                    set: Set { q, ms, fe_uin: fe },
                });
            }
        }
        if l.contains("saved: block of") {
            run.saved_ops = number_after(l, "; ");
        }
        if l.contains("power cut during flash operation") {
            run.cut_at = number_after(l, "flash operation ");
        }
    }
    run.log = lines;
    run
}

/// Boots the image on `dir`'s flash file and saves `new`, the power cut
/// during operation `cut` if given.
fn run_image(dir: &Path, new: Set, cut: Option<u32>) -> Result<Run> {
    let mut sh = format!(
        "enable=on,target=native,arg=zslide,arg=flash,arg=save,arg=q={},arg=ms={},arg=fe={}",
        new.q, new.ms, new.fe_uin
    );
    if let Some(n) = cut {
        sh.push_str(&format!(",arg=cut={n}"));
    }
    let table = crate::default_table_path();
    let regions = QemuRegions {
        table: Some(&table),
        params: None,
    };
    let (code, lines) = run_qemu_elf_at(&qemu_elf(), &regions, &sh, &[], false, Some(dir))?;
    let run = parse(lines);
    if code != 0 {
        return Err(format!(
            "the image exited with status {code} (save {new:?}, cut {cut:?}):\n  {}",
            run.log.join("\n  ")
        ));
    }
    Ok(run)
}

/// The boot in `run` ran `old` (or, on a new board, the built-in design)
/// or `new`, from a whole block.
fn check_boot(run: &Run, old: Option<Set>, new: Set, what: &str) -> Result<()> {
    let Some(b) = &run.boot else {
        return Err(format!("{what}: no boot line:\n  {}", run.log.join("\n  ")));
    };
    let block = b.source.starts_with("Block");
    let ok = match old {
        Some(old) => block && (b.set == old || b.set == new),
        None => (block && b.set == new) || b.source == "BuiltIn",
    };
    if ok {
        Ok(())
    } else {
        Err(format!(
            "{what}: the boot found {} with {:?}; expected the block of {} or of {new:?}",
            b.source,
            b.set,
            old.map_or("nothing (built-in)".to_string(), |o| format!("{o:?}"))
        ))
    }
}

/// Cuts every operation of the save of set `k` from the flash `state`
/// (whose last saved set is `old`); returns (operations, the state after
/// the uncut save).
fn cut_every_operation(
    dir: &Path,
    state: &[u8],
    old: Option<Set>,
    k: u32,
    what: &str,
) -> Result<(u32, Vec<u8>)> {
    let file = dir.join(FILE);
    let put = |bytes: &[u8]| -> Result<()> {
        if bytes.is_empty() {
            match fs::remove_file(&file) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    Err(format!("{}: {e}", file.display()))
                }
                _ => Ok(()),
            }
        } else {
            fs::write(&file, bytes).map_err(|e| format!("{}: {e}", file.display()))
        }
    };
    let new = set(k);
    put(state)?;
    let whole = run_image(dir, new, None)?;
    check_boot(&whole, old, new, &format!("{what}, uncut"))?;
    let Some(ops) = whole.saved_ops else {
        return Err(format!(
            "{what}: the uncut save did not report saved:\n  {}",
            whole.log.join("\n  ")
        ));
    };
    let after = fs::read(&file).map_err(|e| format!("{}: {e}", file.display()))?;
    for n in 1..=ops {
        put(state)?;
        let cut = run_image(dir, new, Some(n))?;
        // Before its cut, this boot found the state unchanged.
        check_boot(
            &cut,
            old,
            old.unwrap_or(new),
            &format!("{what}, before cut {n}"),
        )?;
        if cut.cut_at != Some(n) || cut.saved_ops.is_some() {
            return Err(format!(
                "{what}: cut at operation {n} of {ops}: the image reported cut {:?}, saved {:?}",
                cut.cut_at, cut.saved_ops
            ));
        }
        // The next boot, on what the cut left; its save must work.
        let next = run_image(dir, set(k + 1), None)?;
        check_boot(
            &next,
            old,
            new,
            &format!("{what}, cut at operation {n} of {ops}"),
        )?;
        if next.saved_ops.is_none() {
            return Err(format!(
                "{what}, cut at operation {n} of {ops}: the next boot's save failed:\n  {}",
                next.log.join("\n  ")
            ));
        }
    }
    Ok((ops, after))
}

/// The block the image's save of set `k` writes (`params::design_block`
/// of the built-in design with the set's three values).
fn design_block(k: u32) -> Result<Vec<u8>> {
    let s = set(k);
    let mut d = ServoDesign::brief(zslide_host::regions::LOOP_HZ);
    for (name, v) in [
        ("hum_notch_q", f64::from(s.q)),
        ("following_error_ms", f64::from(s.ms)),
        ("following_error_in", f64::from(s.fe_uin) * 1e-6),
    ] {
        let p = params::by_name(name).ok_or(format!("no parameter {name}"))?;
        d = params::set(&d, p.id, v)
            .map_err(|e| format!("{name} {v}: {e}"))?
            .0;
    }
    let mut out = vec![0u8; MAX_BLOCK];
    let n = params::design_block(&d, &mut out).map_err(|e| e.to_string())?;
    out.truncate(n);
    Ok(out)
}

/// (flash operations, erases) of saving set `k` on `flash`, which it
/// changes.
fn save_on(flash: &mut Bank2Region, k: u32) -> Result<(u32, u32)> {
    let base = ServoDesign::brief(zslide_host::regions::LOOP_HZ);
    let (ops, erases) = (flash.ops, flash.erases);
    let block = design_block(k)?;
    Store::new(&mut *flash, 0..BANK2_REGION_BYTES as u32)
        .and_then(|mut s| s.save(&block, &base))
        .map_err(|e| format!("host store, save {k}: {e}"))?;
    Ok((flash.ops - ops, flash.erases - erases))
}

/// From `flash` (last set `k`), saves until the image's next save would
/// take more operations than a save inside a sector does: the move to the
/// next sector (with the map's erase of the sector it keeps free). Returns
/// the last set saved and that next save's erases.
fn fill_until_move(flash: &mut Bank2Region, mut k: u32) -> Result<(u32, u32)> {
    let mut inside = None;
    for _ in 0..4 * BANK2_REGION_BYTES / MAX_BLOCK {
        let mut trial = flash.clone();
        let (ops, erases) = save_on(&mut trial, k + 1)?;
        if ops > *inside.get_or_insert(ops) {
            return Ok((k, erases));
        }
        save_on(flash, k + 1)?;
        k += 1;
    }
    Err(format!(
        "the host store never moved to the next sector in {k} saves"
    ))
}

/// Runs the check; returns the summary line.
pub fn check() -> Result<String> {
    step("QEMU parameter store: a power cut at every flash operation, across boots");
    let dir: PathBuf = crate::target_dir().join("qemu-flash-cut");
    // The host fills sector 0 to one save short of the move to sector 1,
    // then sector 1 to one short of the move back to sector 0.
    let mut flash = Box::new(Bank2Region::new());
    save_on(&mut flash, 100)?;
    let mut k = 100;
    let mut moves = Vec::new();
    for what in ["move to sector 1", "move back to sector 0"] {
        let erases;
        (k, erases) = fill_until_move(&mut flash, k)?;
        let what = format!("save {} ({what}, {erases} sector erase)", k - 99);
        moves.push((what, flash.bytes.to_vec(), k));
        save_on(&mut flash, k + 1)?;
        k += 1;
    }
    // Each starting state in a directory (and a thread) of its own: the
    // QEMU runs are the cost.
    let results: Vec<Result<String>> = std::thread::scope(|scope| {
        let dir = &dir;
        let mut jobs = vec![scope.spawn(move || {
            // A new board; then the state its first save left.
            let d = dir.join("new");
            fs::create_dir_all(&d).map_err(|e| format!("{}: {e}", d.display()))?;
            let what = "first save on erased flash";
            let (ops, first) = cut_every_operation(&d, &[], None, 1, what)?;
            let mut line = format!("{what}: {ops} operations cut");
            let what = "second save";
            let (ops, _) = cut_every_operation(&d, &first, Some(set(1)), 2, what)?;
            line.push_str(&format!("; {what}: {ops} operations cut"));
            Ok(line)
        })];
        for (i, (what, state, k)) in moves.iter().enumerate() {
            jobs.push(scope.spawn(move || {
                let d = dir.join(format!("move{i}"));
                fs::create_dir_all(&d).map_err(|e| format!("{}: {e}", d.display()))?;
                let (ops, _) = cut_every_operation(&d, state, Some(set(*k)), k + 1, what)?;
                Ok(format!("{what}: {ops} operations cut"))
            }));
        }
        jobs.into_iter()
            .map(|j| {
                j.join()
                    .unwrap_or_else(|_| Err("a power-cut job panicked".into()))
            })
            .collect()
    });
    let lines = results.into_iter().collect::<Result<Vec<_>>>()?;
    for l in &lines {
        eprintln!("  {l}");
    }
    let cuts: u32 = lines
        .iter()
        .flat_map(|l| l.split("; "))
        .filter_map(|l| number_after(l, ": "))
        .sum();
    Ok(format!(
        "{cuts} power cuts, one at every flash operation of four saves ({}); every boot after a cut ran the set saved before or the new one, whole, and its own save worked",
        lines.join("; ")
    ))
}

/// `cargo xtask flash-cut`: [`check`] with the image built first.
pub fn run() -> Result<u8> {
    crate::tools::require_for_qemu_log()?;
    crate::images::build_qemu()?;
    eprintln!("QEMU power cuts: {}", check()?);
    Ok(0)
}
