//! `host-sim part-table PART.toml`: the smallest harmonic table that meets
//! the part file's bound (coeffgen's picker over binary grid steps and up
//! to 15 harmonics), its error split, and the image. Refuses, with the
//! reason, a part no table within the format can hold to the bound.

use crate::part::config::{load_part, LoadedPart};
use crate::part::table::{error_split, generate, PartTable};
use anyhow::{anyhow, Context};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Part file (TOML; docs/PARTS.md).
    pub part: PathBuf,
    /// Write the table image here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Check that this committed image is the one the part gives (exit 1 if not).
    #[arg(long)]
    pub check: Option<PathBuf>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(serde::Serialize)]
pub struct Report {
    pub part: String,
    pub surface: String,
    pub bound_uin: f64,
    pub firmware_allowance_uin: f64,
    pub step_in: f64,
    pub harmonics: usize,
    pub columns: usize,
    pub nodes: usize,
    pub bytes: usize,
    pub x_min_in: f64,
    pub x_null_in: f64,
    pub errors: crate::coeffgen::ErrorSplit,
    pub crc: String,
}

/// The report as text: the part, the table picked, its error split.
pub fn report_text(r: &Report) -> String {
    let e = &r.errors;
    format!(
        "part {}: {}\n\
         table: harmonic, {} harmonics ({} columns), step {} in, {} nodes, X {}..{} in, {} bytes, CRC {}\n\
         error (µin, X {}..{} in, 1440 φ): truncation {:.4}, interpolation {:.4}, quantisation {:.4}, \
         total {:.4} (bound {} less {} for the firmware); Z peak-to-peak {:.6} in\n",
        r.part,
        r.surface,
        r.harmonics,
        r.columns,
        r.step_in,
        r.nodes,
        r.x_min_in,
        r.x_null_in,
        r.bytes,
        r.crc,
        r.x_min_in,
        r.x_null_in,
        e.truncation_uin,
        e.interpolation_uin,
        e.quantization_uin,
        e.total_uin,
        r.bound_uin,
        r.firmware_allowance_uin,
        e.z_peak_to_peak_in
    )
}

/// The table the part file asks for: picked, generated, measured.
pub fn make(lp: &LoadedPart) -> anyhow::Result<(PartTable, Vec<u8>, Report)> {
    let (spec, picked) = lp
        .pick()
        .map_err(|why| anyhow!("part {}: table refused: {why}", lp.name))?;
    let g = generate(&lp.part, &spec).map_err(|e| anyhow!("part {}: {e}", lp.name))?;
    let image = g.image().map_err(|e| anyhow!("part {}: {e}", lp.name))?;
    // The picker measured the same table; measured again densely here.
    let errors = error_split(
        &lp.part,
        &g,
        spec.x_min,
        spec.x_null,
        crate::coeffgen::Sampling {
            per_interval: 8,
            phi: 1440,
        },
    )
    .map_err(|e| anyhow!("part {}: {e}", lp.name))?;
    // The picker's sampling is coarser (it measures every candidate): a
    // table it took can miss the bound between its samples. Only the
    // dense measurement decides.
    let budget = lp.bound_uin - lp.allowance_uin;
    if errors.total_uin.is_nan() || errors.total_uin > budget {
        return Err(anyhow!(
            "part {}: table refused: the table picked ({} harmonics, step {} in) measures {:.4} µin \
             total on the dense check (8 points per interval, 1440 φ; truncation {:.4}, \
             interpolation {:.4}, quantisation {:.4}), above the {budget} µin budget (bound {} µin \
             less the firmware's {} µin); the picker's coarser sampling measured {:.4} µin. Raise \
             bound_uin, or narrow the table's X range",
            lp.name,
            spec.harmonics,
            spec.step,
            errors.total_uin,
            errors.truncation_uin,
            errors.interpolation_uin,
            errors.quantization_uin,
            lp.bound_uin,
            lp.allowance_uin,
            picked.errors.total_uin,
        ));
    }
    let id = zslide::table::CoeffTable::parse(&image)
        .map_err(|e| anyhow!("{e}"))?
        .identity();
    let r = Report {
        part: lp.name.clone(),
        surface: lp.part.sag.describe(),
        bound_uin: lp.bound_uin,
        firmware_allowance_uin: lp.allowance_uin,
        step_in: spec.step,
        harmonics: spec.harmonics,
        columns: picked.columns,
        nodes: g.x.len(),
        bytes: image.len(),
        x_min_in: spec.x_min,
        x_null_in: spec.x_null,
        errors,
        crc: format!("{:#010x}", id.crc),
    };
    Ok((g, image, r))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let lp = load_part(&args.part)?;
    if let Some(out) = &args.out {
        crate::outpath::check_file("--out", out)?;
    }
    let (_, image, r) = make(&lp)?;
    if let Some(out) = &args.out {
        crate::outpath::replace(out, &image)?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        print!("{}", report_text(&r));
    }
    if let Some(c) = &args.check {
        let committed = std::fs::read(c).with_context(|| format!("reading {}", c.display()))?;
        anyhow::ensure!(
            committed == image,
            "{} is not the table part {} gives (regenerate it with --out)",
            c.display(),
            args.part.display()
        );
    }
    Ok(())
}

/// The part and table `cut --part` runs: `table` if given, else the
/// `.zsct` beside the part file, else the table made from the part (said
/// on stderr: which one is used is never silent).
pub fn part_cut(
    path: &std::path::Path,
    table: Option<&PathBuf>,
) -> anyhow::Result<std::sync::Arc<crate::cut::partcut::PartCut>> {
    let lp = load_part(path)?;
    let beside = path.with_extension("zsct");
    let image = match table {
        Some(t) => crate::cmd::accuracy::load_table(Some(t))?,
        None if beside.exists() => {
            eprintln!("part {}: table {}", lp.name, beside.display());
            crate::cmd::accuracy::load_table(Some(&beside))?
        }
        None => {
            eprintln!(
                "part {}: no table given or beside the part file; making one",
                lp.name
            );
            make(&lp)?.1
        }
    };
    Ok(std::sync::Arc::new(crate::cut::partcut::PartCut::new(
        &lp.name, lp.part, image,
    )?))
}
