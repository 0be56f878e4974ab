//! The part's bolt holes as the firmware's interruption block
//! (`zslide::table::interrupt`): centre radius and diameter in µin, the
//! centre's angle in the firmware's spindle angle (the part frame's angle
//! mirrored, `frame`), written by the one encoder and checked by the one
//! parser, so a hole set the firmware would refuse is refused here, in its
//! words, before a pass starts. Filled holes are no interruption: their
//! block is empty.

use super::frame;
use crate::plant::cutting::BoltHoles;
use zslide::table::interrupt::{Hole, Interruptions, HEADER_LEN, HOLE_LEN, MAX_HOLES};
use zslide::units::SpindleAngle;

/// µin of a length in inches, refused (not clipped) outside `u32`.
fn uin(what: &str, v_in: f64) -> anyhow::Result<u32> {
    let u = (v_in * 1e6).round();
    anyhow::ensure!(
        u.is_finite() && (0.0..=f64::from(u32::MAX)).contains(&u),
        "{what} = {v_in} in: not a length the interruption block can carry"
    );
    Ok(u as u32)
}

/// The firmware's binary angle (2³² a turn) of `deg` in its frame.
pub fn spindle_angle(deg: f64) -> SpindleAngle {
    let turns = deg.rem_euclid(360.0) / 360.0;
    SpindleAngle((turns * 4_294_967_296.0).round() as u64 as u32)
}

/// The block of `holes` (part frame), checked as the firmware checks it.
pub fn block_of(holes: &BoltHoles) -> anyhow::Result<Vec<u8>> {
    let list: Vec<Hole> = if holes.filled || holes.count == 0 {
        Vec::new()
    } else {
        anyhow::ensure!(
            holes.count as usize <= MAX_HOLES,
            "cutting.bolt_holes.count = {}: the interruption block carries at most {MAX_HOLES}",
            holes.count
        );
        (0..holes.count)
            .map(|k| {
                let part_deg = holes.phase_deg + 360.0 * f64::from(k) / f64::from(holes.count);
                Ok(Hole {
                    centre_radius_uin: uin(
                        "cutting.bolt_holes.circle_radius_in",
                        holes.circle_radius_in,
                    )?,
                    angle: spindle_angle(frame::command_deg_of_part(part_deg)),
                    diameter_uin: uin("cutting.bolt_holes.diameter_in", holes.diameter_in)?,
                })
            })
            .collect::<anyhow::Result<_>>()?
    };
    let mut out = vec![0u8; HEADER_LEN + list.len() * HOLE_LEN + 4];
    let n = Interruptions::encode(&list, &mut out)
        .ok_or_else(|| anyhow::anyhow!("interruption block: no room for {} holes", list.len()))?;
    out.truncate(n);
    Interruptions::parse(&out)
        .map_err(|e| anyhow::anyhow!("the part's bolt holes are refused: {e}"))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_holes_travel_in_the_firmwares_angle() {
        let b = block_of(&BoltHoles::default()).unwrap();
        let i = Interruptions::parse(&b).unwrap();
        assert_eq!(i.holes().len(), 8);
        let h = i.holes()[0];
        assert_eq!(h.centre_radius_uin, 3_500_000);
        assert_eq!(h.diameter_uin, 750_000);
        // Part 22.5° is the firmware's 180 − 22.5 = 157.5°: 7/16 of a turn.
        assert_eq!(h.angle, SpindleAngle(7 << 28));
        let filled = BoltHoles {
            filled: true,
            ..BoltHoles::default()
        };
        assert!(Interruptions::parse(&block_of(&filled).unwrap())
            .unwrap()
            .is_empty());
    }

    #[test]
    fn a_hole_over_the_axis_is_refused_in_words() {
        let h = BoltHoles {
            circle_radius_in: 0.3,
            diameter_in: 0.75,
            ..BoltHoles::default()
        };
        let e = block_of(&h).unwrap_err().to_string();
        assert!(e.contains("covers the axis"), "{e}");
    }
}
