//! The facing pass's one engagement: the tool feeding in from outside the
//! stock at its rim (`cut::rim_stretch`), the nose's chord growing over
//! the stock by one feed a revolution (`cut::engage`).

use host_sim::cut::run::Entry;
use host_sim::cut::{rim_stretch, run_stretch, Controller, CutSpec, Extras, Holes};

/// The track figure's bound on the loop's following error in air (10 Hz ×
/// 0.004 in, docs/TUNING.md), µin.
const TRACK_PEAK_UIN: f64 = 10.0;

fn spec(k_e_scale: f64) -> CutSpec {
    let mut sc = host_sim::scenario::load("legacy-hw").unwrap();
    sc.cutting.k_e_lbf_per_in *= k_e_scale;
    CutSpec::chapter5(sc, Controller::Digital, None, Some(Holes::Filled), false).unwrap()
}

/// With twice the edge constant the tool stays inside the depth of cut as
/// it meets the stock. The bound of the mechanism: the cutting force only
/// ever pushes the tool out of the part (`part_side = −1`) and the chord
/// grows over `sqrt(2 r_t d)/f ≈ 87` revolutions (the force rises by 1/87
/// of its whole a revolution, far below the loop's bandwidth), so the tool
/// is below the surface by no more than the loop's following error in air:
/// twice the track figure's bound, for the gauge noise and hum the cut adds.
/// Entering the stock with the loop still being referenced (the tool in
/// the stock from the first tick, `Entry::InStock`) breaks it: −111.8 µin.
#[test]
fn the_rim_engagement_with_twice_the_edge_force_stays_inside_the_depth_of_cut() {
    let s = spec(2.0);
    let st = rim_stretch(&s);
    assert!(matches!(st.entry, Entry::Rim(_)), "{:?}", st.entry);
    let r = run_stretch(&s, &st, &Extras::default(), &|_| {}).unwrap();
    assert!(r.faults.is_empty(), "{:?}", r.faults);
    let deepest_uin = r.log.deepest_in * 1e6;
    let depth_uin = s.depth_in * 1e6;
    assert!(deepest_uin.is_finite(), "the stretch must cut");
    assert!(deepest_uin > -depth_uin, "{deepest_uin:.1} µin");
    assert!(
        deepest_uin >= -2.0 * TRACK_PEAK_UIN,
        "{deepest_uin:.1} µin below the surface at the rim"
    );
}
