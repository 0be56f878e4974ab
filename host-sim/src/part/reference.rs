//! The exact command a table is measured against (`accuracy`, `zcmd`'s
//! test): the paraboloid its header names, or a part file's surface.

use super::split::{Part, Section};
use crate::surface::Surface;

/// What a table's command should be.
#[derive(Clone, Debug)]
pub enum Reference {
    /// The off-axis paraboloid of the header's geometry (FOREX4).
    Paraboloid(Surface),
    /// A part file's surface and tool.
    Part(Part),
}

/// The reference at one X.
pub enum RefSection<'a> {
    Paraboloid(crate::surface::Section),
    Part(Section, &'a Part),
}

impl Reference {
    /// The paraboloid of a table's header, or the refusal to read a
    /// non-paraboloid header as one.
    pub fn of_header(g: &zslide::table::Geometry) -> anyhow::Result<Self> {
        if super::header_is_not_a_paraboloid(g) {
            anyhow::bail!(
                "the table's header marks a part that is not an off-axis paraboloid (c = S_y = 1 nin): \
                 give its part file (--part FILE.toml) as the reference"
            );
        }
        Ok(Self::Paraboloid(
            Surface::from_table_geometry(g).map_err(|e| anyhow::anyhow!("table geometry: {e}"))?,
        ))
    }

    pub fn at(&self, x: f64) -> anyhow::Result<RefSection<'_>> {
        Ok(match self {
            Self::Paraboloid(s) => RefSection::Paraboloid(
                s.section(x)
                    .map_err(|e| anyhow::anyhow!("surface at X = {x}: {e}"))?,
            ),
            Self::Part(p) => RefSection::Part(
                p.section(x)
                    .map_err(|e| anyhow::anyhow!("part at X = {x}: {e}"))?,
                p,
            ),
        })
    }
}

impl RefSection<'_> {
    /// `Z` at the firmware's angle φ (radians), in (a part's surface is
    /// in the part frame: `super::part_angle`; the paraboloid is the same
    /// in both).
    pub fn z(&self, phi: f64) -> f64 {
        match self {
            Self::Paraboloid(s) => s.z(phi),
            Self::Part(s, p) => s.z(p, super::part_angle(phi)).unwrap_or(f64::NAN),
        }
    }
}
