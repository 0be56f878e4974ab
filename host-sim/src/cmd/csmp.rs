//! `host-sim csmp C-1` .. `csmp C-6`: the appendix C loop studies, solved
//! exactly (matrix exponential) and printed as CSV `t_s,z,err` at the
//! programs' print interval (t = 0, 0.001 .. 0.040 s).

use crate::csmp::{study, Sample, STUDY_NAMES};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Appendix C study: C-1 .. C-6 (case-insensitive).
    pub study: String,
    /// Print a JSON document (study, title, rows) instead of CSV.
    #[arg(long)]
    pub json: bool,
}

/// Digits after the decimal point that print `outdel` multiples exactly.
fn time_decimals(outdel: f64) -> usize {
    (0..=9)
        .find(|&d| {
            let v = outdel * 10f64.powi(d as i32);
            (v - v.round()).abs() < 1e-9 * v.max(1.0)
        })
        .unwrap_or(9)
}

/// The CSV text of a run (header and one row per print time).
pub fn csv(rows: &[Sample], outdel: f64) -> String {
    let dec = time_decimals(outdel);
    let mut out = String::from("t_s,z,err\n");
    for s in rows {
        out.push_str(&format!("{:.dec$},{:.12e},{:.12e}\n", s.t_s, s.z, s.err));
    }
    out
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let st = study(&args.study)
        .map_err(|e| anyhow::anyhow!("{e} (usage: host-sim csmp <{}>)", STUDY_NAMES.join("|")))?;
    let rows = st.diagram.run()?;
    if args.json {
        let doc = serde_json::json!({
            "study": st.name,
            "title": st.title,
            "rows": rows
                .iter()
                .map(|s| serde_json::json!({"t_s": s.t_s, "z": s.z, "err": s.err}))
                .collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        print!("{}", csv(&rows, st.diagram.outdel));
    }
    Ok(())
}
