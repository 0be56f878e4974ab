//! `cut --command-sign reversed`: the 1983 first part's mistake (chapter
//! 5: "the sign had been reversed on the Z slide command generator"; the
//! error was "very nearly twice the Z slide command"), and what the
//! digital firmware does with the same mistake (docs/CUT.md).
//!
//! * `legacy-analog`: the 1983 loop follows −Z (its reference negated,
//!   `AnalogDrive::reference_sign`); the part is measured the way chapter
//!   5 re-measured it, against the reversed nominal `Y(X) − Z(X, φ)`, and
//!   the stock it cuts into was left by clean-up passes with the same
//!   mistake (the cutter's `nominal_sign`).
//! * `digital`: the same mistake is a table whose command has the wrong
//!   sign; the firmware's table sign check (`zslide::config`: Z ≤ 0
//!   everywhere, eq 2-14 defines Y as the maximum over φ) refuses it at
//!   load with `Table(SignCheck)` and holds the slide at null.

/// The command generator's sign.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum CommandSign {
    /// As eq 2-15 (the second part).
    #[default]
    Normal,
    /// Reversed (the first part).
    Reversed,
}

impl CommandSign {
    pub fn factor(self) -> f64 {
        match self {
            CommandSign::Normal => 1.0,
            CommandSign::Reversed => -1.0,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            CommandSign::Normal => "normal",
            CommandSign::Reversed => "reversed",
        }
    }
}

/// The default table with every coefficient negated: a valid image (its
/// CRC recomputed) whose command is ≥ 0, the 1983 mistake as a table.
pub fn negated_default_table() -> anyhow::Result<&'static [u8]> {
    use zslide::table::CoeffTable;
    let t = CoeffTable::parse(zslide::DEFAULT_TABLE)
        .map_err(|e| anyhow::anyhow!("default table refused: {e}"))?;
    let h = *t.header();
    let payload: Vec<i32> = (0..t.node_count())
        .flat_map(|n| (0..t.terms()).map(move |c| (n, c)))
        .map(|(n, c)| t.coeff_raw(n, c).saturating_neg())
        .collect();
    let mut out = vec![0u8; h.image_len()];
    h.encode(&payload, &mut out)
        .map_err(|e| anyhow::anyhow!("negated table: {e}"))?;
    // The firmware keeps a `'static` image; one per process is enough.
    static IMAGE: std::sync::OnceLock<&'static [u8]> = std::sync::OnceLock::new();
    Ok(IMAGE.get_or_init(|| Box::leak(out.into_boxed_slice())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_negated_table_parses_and_the_firmware_refuses_it_by_its_sign() {
        let img = negated_default_table().unwrap();
        assert!(zslide::table::CoeffTable::parse(img).is_ok());
        assert_eq!(
            zslide::firmware::config::load_table(img).err(),
            Some(zslide::table::TableError::SignCheck)
        );
    }
}
