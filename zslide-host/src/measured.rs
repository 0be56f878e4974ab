//! One point of a measured frequency response, as `zslide identify`
//! measures it and the fits (`crate::fit`, `crate::process`) read it.

use nalgebra::Complex;

/// One measured frequency.
#[derive(Clone, Copy, Debug)]
pub struct Measured {
    pub f_hz: f64,
    pub h: Complex<f64>,
    /// H1 coherence over the windows (1: no noise).
    pub coherence: f64,
    /// Relative standard deviation of `h` (the windows' spread / √n).
    pub rel_sigma: f64,
    pub amplitude_v: f64,
}
