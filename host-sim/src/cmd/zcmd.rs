//! `host-sim zcmd`: the Z command of the firmware's own fixed-point path
//! (`zslide::command`, default table) at given points.
//!
//! Input on stdin: CSV lines `x_in,phi_deg`, no header. X is the tool-centre
//! radius (inches), φ the spindle angle of eq 2-5 in degrees (any real value;
//! it wraps). Output: `x_in,phi_deg,z_in`, the input fields echoed as given,
//! Z in inches with 16 significant digits (Z along +Y_t; ≤ 0 for a correct
//! command; exactly 0 in the null zone X > 7.2 in).
//!
//! A line that is not two finite numbers, or an X below the table (the
//! firmware's X-outside-table fault), stops the run with an error naming the
//! line: nothing is skipped silently.

use super::accuracy::load_table;
use anyhow::{anyhow, bail, Context};
use std::io::{BufRead, BufWriter, Write};
use std::path::PathBuf;
use zslide::command::CommandGen;
use zslide::table::CoeffTable;
use zslide::units::{SpindleAngle, XInches};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Table image to use (default: the firmware's default table).
    #[arg(long)]
    pub table: Option<PathBuf>,
}

/// Parses one input line into (x_in, phi_deg) and their text as given.
pub fn parse_line(line: &str) -> Result<(f64, f64, &str, &str), String> {
    let mut it = line.split(',');
    let (Some(xs), Some(ps), None) = (it.next(), it.next(), it.next()) else {
        return Err(format!("expected two fields `x_in,phi_deg`, got {line:?}"));
    };
    let (xs, ps) = (xs.trim(), ps.trim());
    let num = |s: &str, what: &str| -> Result<f64, String> {
        let v: f64 = s
            .parse()
            .map_err(|_| format!("{what} {s:?} is not a number"))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("{what} {s:?} is not finite"))
        }
    };
    Ok((num(xs, "x_in")?, num(ps, "phi_deg")?, xs, ps))
}

/// Z (inches) of the firmware path at nominal X and φ.
pub fn z_at(gen: &CommandGen, x_in: f64, phi_deg: f64) -> Result<f64, String> {
    if !(-128.0..128.0).contains(&x_in) {
        return Err(format!("x_in = {x_in} is outside the X format (±128 in)"));
    }
    let phi = SpindleAngle::from_degrees(phi_deg.rem_euclid(360.0));
    gen.z(XInches::from_f64(x_in), phi)
        .map(|z| z.to_f64())
        .map_err(|f| format!("x_in = {x_in}: firmware fault {f:?} (below the table's first node)"))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let image = load_table(args.table.as_ref())?;
    let t = CoeffTable::parse(&image).map_err(|e| anyhow!("table refused: {e}"))?;
    let gen = CommandGen::new(t);
    let stdin = std::io::stdin();
    let mut out = BufWriter::new(std::io::stdout().lock());
    for (n, line) in stdin.lock().lines().enumerate() {
        let line = line.with_context(|| format!("reading stdin line {}", n + 1))?;
        let line = line.trim_end_matches('\r');
        let (x, p, xs, ps) = match parse_line(line) {
            Ok(v) => v,
            Err(e) => bail!("stdin line {}: {e}", n + 1),
        };
        let z = z_at(&gen, x, p).map_err(|e| anyhow!("stdin line {}: {e}", n + 1))?;
        writeln!(out, "{xs},{ps},{z:.15e}")?;
    }
    out.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_lines_are_named_errors() {
        assert!(parse_line("1.0,2.0").is_ok());
        assert!(parse_line(" 1.0 , 2.0 ").is_ok());
        for bad in [
            "",
            "1.0",
            "1.0,2.0,3.0",
            "a,1",
            "1,b",
            "nan,1",
            "1,inf",
            "1;2",
        ] {
            assert!(parse_line(bad).is_err(), "{bad:?} accepted");
        }
    }
}
