//! The Z slide, voice-coil motor and the 3150 Hz coil-frame mode as one
//! linear state-space model (chapter 4, eq 4-1..4-11), stepped exactly.
//!
//! # Units (inch system, used throughout the plant)
//! Length in inches, force in lbf, time in s, current in A, voltage in V.
//! Mass is then in lbf·s²/in (1 slug = 1 lbf·s²/ft = 1/12 lbf·s²/in), the
//! back-EMF constant in V·s/in (= V·s/ft ÷ 12) and viscous friction in
//! lbf·s/in (= lbf·s/ft ÷ 12). Poles and transfer-function shapes do not
//! depend on the length unit; eq 4-33 is in ft and checks out unchanged.
//!
//! # State, inputs, outputs
//! `x = [i, v, z, q, q̇]`: coil current (A), slide velocity (in/s), slide
//! position (in, +Z of eq 2-8), modal coordinate of the coil-frame mode as
//! the gauge sees it (in) and its rate. Inputs `u = [e_m, f_ext]`: motor
//! terminal voltage (V) and external force on the slide along +Z (lbf; the
//! cutting force). Outputs `y = [z_gauge, i, v, z]` with `z_gauge = z + q`.
//!
//! ```text
//! L di/dt = e_m − R i − Kb v                        (eq 4-6)
//! M dv/dt = Kf i − B v + f_ext                      (eq 4-1, 4-3)
//! q̈ + 2ζ ωp q̇ + ωp² q = α Kf i                      (coil-frame mode)
//! ```
//! The mode is driven by the motor force only (it is a mode of the motor's
//! armature shell, Fig 4-31). Seen at the gauge, force → z_gauge is
//! `1/(s(Ms+B)) + α/(s² + 2ζωp s + ωp²)`: the sum has a lightly damped zero
//! pair at `ωz = ωp / sqrt(1 + αM)`, below the pole pair, which gives the
//! "upward thrust of nearly 180°" in phase that Fig 4-30 shows near 3100 Hz.
//! `α` is set from the chosen zero frequency, so pole and zero are the
//! documented parameters (`docs/PLANT.md`).

// The f64 functions of `libm` where std's are missing (no_std builds);
// with std the inherent methods are used and the import is idle.
#[allow(unused_imports)]
use num_traits::Float;

/// lbm per slug (standard gravity 32.174 ft/s²).
pub const LBM_PER_SLUG: f64 = 32.174;

pub use crate::statespace::{st, Mats};

/// Physical parameters of slide, motor and mode, inch units (see module doc).
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ZSlideParams {
    /// Motor force constant Kf, lbf/A.
    pub kf_lbf_per_a: f64,
    /// Back-EMF constant Kb, V·s/in.
    pub kb_v_s_per_in: f64,
    /// Coil resistance R, Ω.
    pub r_ohm: f64,
    /// Coil inductance L, H.
    pub l_h: f64,
    /// Moving mass M, lbf·s²/in.
    pub mass_lbf_s2_per_in: f64,
    /// Air-film viscous friction B, lbf·s/in.
    pub b_lbf_s_per_in: f64,
    /// Coil-frame mode: pole pair frequency (Hz), zero pair frequency (Hz,
    /// below the pole), pole damping ratio. `None` = rigid slide.
    pub mode: Option<ModeParams>,
}

/// The structural mode as the gauge sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ModeParams {
    pub pole_hz: f64,
    pub zero_hz: f64,
    pub zeta: f64,
}

impl ModeParams {
    /// Chosen values, see `docs/PLANT.md`: pole at the 3150 Hz of Fig 4-31,
    /// zero 200 Hz below it (an anti-resonance then resonance, which gives
    /// the upward phase thrust of Fig 4-30 and +11 dB peaking that limited
    /// the loop gain well below the Routh limit), damping 2 % (a bolted and
    /// bonded aluminium coil frame; the text calls it lightly damped).
    pub const DISSERTATION: ModeParams = ModeParams {
        pole_hz: 3150.0,
        zero_hz: 2950.0,
        zeta: 0.02,
    };
}

impl ZSlideParams {
    /// Builds from the dissertation's foot-based numbers.
    /// `kb` in V·s/ft, `mass` in slug, `b` in lbf·s/ft, `tau_e = L/R` in s.
    pub fn from_ft_units(
        kf_lbf_per_a: f64,
        kb_v_s_per_ft: f64,
        r_ohm: f64,
        tau_e_s: f64,
        mass_slug: f64,
        b_lbf_s_per_ft: f64,
    ) -> Self {
        Self {
            kf_lbf_per_a,
            kb_v_s_per_in: kb_v_s_per_ft / 12.0,
            r_ohm,
            l_h: tau_e_s * r_ohm,
            mass_lbf_s2_per_in: mass_slug / 12.0,
            b_lbf_s_per_in: b_lbf_s_per_ft / 12.0,
            mode: None,
        }
    }

    /// Infomag Model 15, the motor the parts were cut with (ch. 4, after the
    /// Model 14 failed): Kf 2.9 lbf/A, Kb 4.002 V·s/ft, R 1.4 Ω, L/R 0.26 ms;
    /// mass 6.25 lbm = 0.1943 slug; B = 51.2 lbf·s/ft (eq 4-32); with the
    /// 3150 Hz mode.
    pub fn model15() -> Self {
        Self {
            mode: Some(ModeParams::DISSERTATION),
            ..Self::from_ft_units(2.9, 4.002, 1.4, 0.26e-3, 6.25 / LBM_PER_SLUG, 51.2)
        }
    }

    /// Infomag Model 14 (first motor): Kf 4.0 lbf/A, Kb 5.52 V·s/ft, R 3.2 Ω.
    /// Eq 4-33/4-34 were formed with these numbers, M = 0.194 slug and
    /// B = 51.2 (which eq 4-32 also derived from Model 14 data). Rigid.
    pub fn model14() -> Self {
        Self::from_ft_units(4.0, 5.52, 3.2, 0.26e-3, 0.194, 51.2)
    }

    /// Without the structural mode (rigid slide), e.g. to compare with the
    /// chapter 4 transfer functions that ignore it.
    pub fn rigid(mut self) -> Self {
        self.mode = None;
        self
    }

    /// Mode input gain α (1/(lbf·s²/in)) that puts the zero pair at the
    /// chosen frequency: `1 + αM = (ωp/ωz)²`.
    pub fn mode_alpha(&self) -> f64 {
        match self.mode {
            Some(m) => ((m.pole_hz / m.zero_hz).powi(2) - 1.0) / self.mass_lbf_s2_per_in,
            None => 0.0,
        }
    }

    /// Continuous state space `x' = A x + B u` (inputs `[e_m, f_ext]`).
    /// `current_held`: the amplifier holds the coil current (current
    /// limit, or zero when disabled/tripped), so the current equation is
    /// frozen (di/dt = 0) and the voltage input has no effect; the
    /// mechanical part is then driven by the held current. The outputs
    /// (`z_gauge = z + q`, `i`, `v`, `z`) are [`ZSlideParams::gauge_sees_mode`]
    /// and the states themselves.
    pub fn continuous(&self, current_held: bool) -> ([[f64; st::N]; st::N], [[f64; 2]; st::N]) {
        let p = self;
        let mut a = [[0.0; st::N]; st::N];
        let mut b = [[0.0; 2]; st::N];
        if !current_held {
            a[st::I][st::I] = -p.r_ohm / p.l_h;
            a[st::I][st::V] = -p.kb_v_s_per_in / p.l_h;
            b[st::I][0] = 1.0 / p.l_h;
        }
        a[st::V][st::I] = p.kf_lbf_per_a / p.mass_lbf_s2_per_in;
        a[st::V][st::V] = -p.b_lbf_s_per_in / p.mass_lbf_s2_per_in;
        b[st::V][1] = 1.0 / p.mass_lbf_s2_per_in;
        a[st::Z][st::V] = 1.0;
        match self.mode {
            Some(m) => {
                let wp = 2.0 * core::f64::consts::PI * m.pole_hz;
                a[st::Q][st::QD] = 1.0;
                a[st::QD][st::Q] = -wp * wp;
                a[st::QD][st::QD] = -2.0 * m.zeta * wp;
                a[st::QD][st::I] = self.mode_alpha() * p.kf_lbf_per_a;
            }
            None => {
                // Keep the modal states decoupled and at rest; a stable
                // diagonal keeps the matrix exponential well conditioned.
                a[st::Q][st::Q] = -1.0;
                a[st::QD][st::QD] = -1.0;
            }
        }
        (a, b)
    }

    /// Whether the gauge sees the modal coordinate (`z_gauge = z + q`).
    pub fn gauge_sees_mode(&self) -> bool {
        self.mode.is_some()
    }

    /// Denominator of eq 4-11, `s² + a1 s + a0` (velocity per volt), for the
    /// rigid motor+slide: `a1 = R/L + B/M`, `a0 = (BR + Kf Kb)/(ML)`.
    pub fn eq4_11_denominator(&self) -> (f64, f64) {
        let p = self;
        let m = p.mass_lbf_s2_per_in;
        (
            p.r_ohm / p.l_h + p.b_lbf_s_per_in / m,
            (p.b_lbf_s_per_in * p.r_ohm + p.kf_lbf_per_a * p.kb_v_s_per_in) / (m * p.l_h),
        )
    }

    /// Numerator of eq 4-11, `Kf/(ML)`, in (in/s)/(V·s²); ×1/12 for ft.
    pub fn eq4_11_numerator(&self) -> f64 {
        self.kf_lbf_per_a / (self.mass_lbf_s2_per_in * self.l_h)
    }
}

/// One discretisation: its step length, its drive model and the matrices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    pub dt_ns: u64,
    pub current_held: bool,
    pub mats: Mats,
}

/// Entries kept: the event spacings of a run plus the power-of-two steps
/// that compose any other spacing.
pub const CACHE_SIZE: usize = 128;
/// Distinct non-power-of-two steps given their own discretisation; beyond
/// this an odd step (an X event or index pulse splitting a loop period at
/// an arbitrary nanosecond) is composed of cached power-of-two steps
/// instead of costing a matrix exponential (exact: the steps of a held
/// input compose).
const ODD_MAX: usize = 32;

/// The slide's state with the two drive models (voltage-driven, current
/// held) and a most-recently-used cache of their discretisations keyed by
/// (step length in ns, model), stepped without allocation.
///
/// With the `std` feature a missing discretisation is computed
/// ([`crate::zoh`]); without it (the QEMU image, which has no matrix
/// exponential) the cache holds what [`ZSlide::preload`] put there, the
/// same code's output generated at build time, and any other step is
/// composed of its power-of-two entries. A step that cannot be composed
/// is counted ([`ZSlide::missing_steps`]) and leaves the state as it was.
#[derive(Clone, Debug)]
pub struct ZSlide {
    pub params: ZSlideParams,
    pub x: [f64; st::N],
    /// Cache keys (step ns, current held), apart from the matrices so the
    /// search walks 16-byte entries.
    keys: [(u64, bool); CACHE_SIZE],
    mats: [Mats; CACHE_SIZE],
    /// Entries in use.
    len: usize,
    /// Entries used last and the one before (a loop period is split in two
    /// steps at the DAC frame, so the usual hits alternate between them).
    mru: usize,
    mru2: usize,
    /// Next entry to replace when full (round robin).
    evict: usize,
    /// Entries whose step is not a power of two.
    odd: usize,
    misses: u64,
    missing: u64,
}

const ZERO_MATS: Mats = Mats {
    phi: [[0.0; st::N]; st::N],
    gamma: [[0.0; 2]; st::N],
};

impl ZSlide {
    pub fn new(params: ZSlideParams) -> Self {
        Self {
            params,
            x: [0.0; st::N],
            keys: [(0, false); CACHE_SIZE],
            mats: [ZERO_MATS; CACHE_SIZE],
            len: 0,
            mru: 0,
            mru2: 0,
            evict: 0,
            odd: 0,
            misses: 0,
            missing: 0,
        }
    }

    /// Puts discretisations into the cache (the QEMU image's, generated at
    /// build time from the same parameters by [`crate::zoh`]). Entries
    /// beyond the cache's capacity are ignored.
    pub fn preload(&mut self, steps: &[Step]) {
        for s in steps {
            self.insert((s.dt_ns, s.current_held), s.mats);
        }
    }

    fn insert(&mut self, key: (u64, bool), m: Mats) -> usize {
        let odd = usize::from(!key.0.is_power_of_two());
        let idx = if self.len < CACHE_SIZE {
            self.len += 1;
            self.len - 1
        } else {
            let p = self.evict;
            self.evict = (self.evict + 1) % CACHE_SIZE;
            if let Some(k) = self.keys.get(p) {
                self.odd -= usize::from(!k.0.is_power_of_two());
            }
            p
        };
        if let (Some(k), Some(slot)) = (self.keys.get_mut(idx), self.mats.get_mut(idx)) {
            *k = key;
            *slot = m;
        }
        self.odd += odd;
        idx
    }

    /// The discretisation for a missing key, when this build can compute one.
    #[cfg(feature = "std")]
    fn discretise(&mut self, key: (u64, bool)) -> Option<Mats> {
        self.misses += 1;
        let (a, b) = self.params.continuous(key.1);
        Some(crate::zoh::zoh(&a, &b, key.0 as f64 * 1e-9))
    }
    #[cfg(not(feature = "std"))]
    fn discretise(&mut self, _key: (u64, bool)) -> Option<Mats> {
        None
    }

    /// Advances `dt_ns` with the inputs held. `current_held`: see
    /// [`ZSlideParams::continuous`].
    pub fn step(&mut self, dt_ns: u64, e_m: f64, f_ext: f64, current_held: bool) {
        if dt_ns == 0 {
            return;
        }
        let key = (dt_ns, current_held);
        let used = &self.keys[..self.len.min(CACHE_SIZE)];
        let idx = if used.get(self.mru) == Some(&key) {
            self.mru
        } else if used.get(self.mru2) == Some(&key) {
            self.mru2
        } else if let Some(p) = used.iter().position(|k| *k == key) {
            p
        } else if !dt_ns.is_power_of_two() && (self.odd >= ODD_MAX || cfg!(not(feature = "std"))) {
            self.step_binary(dt_ns, e_m, f_ext, current_held);
            return;
        } else if let Some(m) = self.discretise(key) {
            self.insert(key, m)
        } else {
            self.missing += 1;
            return;
        };
        if idx != self.mru {
            self.mru2 = self.mru;
            self.mru = idx;
        }
        if let Some(m) = self.mats.get(idx) {
            apply_fixed(&mut self.x, m, [e_m, f_ext]);
        }
    }

    /// Advances `dt_ns` as a sum of power-of-two steps (at most 64, each
    /// cached): for the odd remainders of limit and trip instants, so they
    /// never cost a matrix exponential after the first time.
    pub fn step_binary(&mut self, dt_ns: u64, e_m: f64, f_ext: f64, current_held: bool) {
        for k in (0..64).rev() {
            let h = 1u64 << k;
            if dt_ns & h != 0 {
                self.step(h, e_m, f_ext, current_held);
            }
        }
    }

    /// Advances an arbitrary (non-cached) interval; for the rare crossing
    /// searches of the amplifier's current limit.
    #[cfg(feature = "std")]
    pub fn step_uncached(&mut self, dt_s: f64, e_m: f64, f_ext: f64, current_held: bool) {
        if dt_s <= 0.0 {
            return;
        }
        let (a, b) = self.params.continuous(current_held);
        let m = crate::zoh::zoh(&a, &b, dt_s);
        apply_fixed(&mut self.x, &m, [e_m, f_ext]);
    }

    /// Position the gauge sees (slide plus coil-frame mode), in.
    pub fn gauge_position_in(&self) -> f64 {
        if self.params.mode.is_some() {
            self.x[st::Z] + self.x[st::Q]
        } else {
            self.x[st::Z]
        }
    }
    pub fn current_a(&self) -> f64 {
        self.x[st::I]
    }
    pub fn velocity_in_s(&self) -> f64 {
        self.x[st::V]
    }
    pub fn position_in(&self) -> f64 {
        self.x[st::Z]
    }
    /// Number of matrix exponentials computed so far (cache misses).
    pub fn expm_count(&self) -> u64 {
        self.misses
    }
    /// Steps that could not be taken: neither cached nor computable nor
    /// composable (a build without `std` whose preloaded table lacks a
    /// power of two). Zero in every correct run.
    pub fn missing_steps(&self) -> u64 {
        self.missing
    }
}

#[inline]
fn apply_fixed(x: &mut [f64; st::N], m: &Mats, u: [f64; 2]) {
    let mut nx = [0.0; st::N];
    for ((out, p), g) in nx.iter_mut().zip(&m.phi).zip(&m.gamma) {
        *out = g[0] * u[0]
            + g[1] * u[1]
            + p[0] * x[0]
            + p[1] * x[1]
            + p[2] * x[2]
            + p[3] * x[3]
            + p[4] * x[4];
    }
    *x = nx;
}
