//! The light test cut of a served machine (`host-sim serve --cut-depth`):
//! the tool engaged in solid stock at the slide's null position, as when
//! the operator faces a little stock at a fixed Z before a pass, so that
//! `zslide identify --in-cut` can measure the slide's response with the
//! part on it.
//!
//! The stock's top stands the depth of cut `d` from the tool's null
//! position (the carriage at z = 0, where the loop holds the gauge at its
//! null code), on the stock's side (`CuttingParams::part_side`). With the
//! tool at z the depth into the stock is `d_f = d + part_side · z`, and the
//! force on the slide is the force model's steady thrust,
//! `−part_side · thrust(d_f, f)` (`CuttingParams::thrust_lbf`, `f` the feed
//! per revolution), with the scenario's broadband chip-formation noise
//! (`errors.cut_force_noise_lbf`, white per loop tick) while the tool is in
//! the stock. Its slope against the depth, `k_t·f + k_e·√(r_t / (2d))`
//! (`sensitivity::stiffness_lbf_per_in`), is the spring the loop meets.
//!
//! What it leaves out, against `cut::engage`: the open bolt holes (the
//! test cut is on solid stock) and the nose's rear contact with the
//! previous revolution's surface (a facing cut at a fixed Z has the same
//! surface every revolution, so the contact is the steady `f/2`).
//!
//! Disarmed, the slide floats: the force pushes it out of the stock until
//! the tool only touches it; arming brings the tool back in to the depth.

use crate::fwrig::{Machine, TickHook};
use crate::plant::cutting::CuttingParams;
use crate::plant::Rig;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::Distribution;
use zslide::firmware::Firmware;

/// The test cut's depth and feed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TestCut {
    /// Depth of cut at the null position, in.
    pub depth_in: f64,
    /// Feed per spindle revolution, in.
    pub feed_per_rev_in: f64,
}

impl TestCut {
    /// The deepest test cut served, in: ten times chapter 5's finishing
    /// depth (0.0003 in), well inside the following-error limit.
    pub const MAX_DEPTH_IN: f64 = 0.003;
    /// The largest feed per revolution, in: chapter 5's roughing feed
    /// (667 µin/rev) with room.
    pub const MAX_FEED_IN: f64 = 0.001;

    /// Refuses a depth or feed outside (0, max].
    pub fn check(&self) -> anyhow::Result<()> {
        anyhow::ensure!(
            self.depth_in > 0.0 && self.depth_in <= Self::MAX_DEPTH_IN,
            "--cut-depth {} uin: must be in (0, {}] uin",
            self.depth_in * 1e6,
            Self::MAX_DEPTH_IN * 1e6
        );
        anyhow::ensure!(
            self.feed_per_rev_in > 0.0 && self.feed_per_rev_in <= Self::MAX_FEED_IN,
            "--cut-feed {} uin/rev: must be in (0, {}] uin/rev",
            self.feed_per_rev_in * 1e6,
            Self::MAX_FEED_IN * 1e6
        );
        Ok(())
    }
}

/// The cut's force, set before every loop tick.
pub struct TestCutHook {
    cut: TestCut,
    cutting: CuttingParams,
    noise_lbf: f64,
    rng: ChaCha8Rng,
}

impl TestCutHook {
    /// The cut `cut` in the scenario's force model `cutting`, with the
    /// chip's force noise of RMS `noise_lbf`, its stream from `seed`.
    pub fn new(cut: TestCut, cutting: CuttingParams, noise_lbf: f64, seed: u64) -> Self {
        Self {
            cut,
            cutting,
            noise_lbf,
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x5445_5354_4355_5400),
        }
    }

    /// The depth into the stock with the carriage at `z_in`, in (≤ 0: out
    /// of it).
    pub fn depth_at(&self, z_in: f64) -> f64 {
        self.cut.depth_in + self.cutting.part_side * z_in
    }

    /// The force on the slide along +Z with the carriage at `z_in`, lbf,
    /// without the noise.
    pub fn force_lbf(&self, z_in: f64) -> f64 {
        -self.cutting.part_side
            * self
                .cutting
                .thrust_lbf(self.depth_at(z_in), self.cut.feed_per_rev_in)
    }
}

impl TickHook for TestCutHook {
    fn before_tick(&mut self, rig: &mut Rig, _m: &Machine, _fw: &Firmware) {
        // The tool rides on the carriage, not on the coil frame the gauge
        // also sees.
        let z = rig.slide.position_in();
        let mut f = self.force_lbf(z);
        if self.depth_at(z) > 0.0 && self.noise_lbf > 0.0 {
            let w: f64 = rand_distr::StandardNormal.sample(&mut self.rng);
            f -= self.cutting.part_side * self.noise_lbf * w;
        }
        rig.set_force_lbf(f);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_force_falls_to_zero_as_the_tool_leaves_the_stock_and_its_slope_is_the_models() {
        let c = CuttingParams::default();
        let cut = TestCut {
            depth_in: 300e-6,
            feed_per_rev_in: 100e-6,
        };
        let h = TestCutHook::new(cut, c.clone(), 0.0, 1);
        // part_side −1: the stock lies toward −Z and pushes the slide +Z.
        assert!(h.force_lbf(0.0) > 1.0);
        assert_eq!(h.force_lbf(cut.depth_in + 1e-9), 0.0);
        let dz = 1e-7;
        let slope = -(h.force_lbf(dz) - h.force_lbf(-dz)) / (2.0 * dz);
        // k_t·f + k_e·√(r_t/(2d)) written out from the model's constants.
        let want = 2.0e5 * 100e-6 + 150.0 * (0.125f64 / (2.0 * 300e-6)).sqrt();
        assert!((slope / want - 1.0).abs() < 1e-4, "{slope} vs {want}");
    }
}
