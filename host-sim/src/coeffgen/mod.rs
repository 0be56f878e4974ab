//! Coefficient generator: replaces FOREX4 (appendix B-1) and the EPROM burn.
//!
//! From the exact surface ([`crate::surface`]) it computes, at each node of a
//! uniform X grid, the series coefficients of `Z(X, φ)` in φ, quantises them
//! to the firmware's fixed point and writes the table image through the one
//! encoder, [`zslide::table::TableHeader::encode`]. It also measures what the
//! firmware's approximation of the command costs, split into truncation
//! (terms), interpolation (grid) and quantisation, and picks the smallest
//! table that meets a bound. The maths and the budget are in
//! `docs/COEFFICIENTS.md`.
//!
//! # Fourier expansion
//!
//! `Z(X, ·)` is smooth and 2π-periodic, so the equispaced trapezoid rule (a
//! DFT) converges geometrically: with [`FOURIER_SAMPLES`] samples the aliasing
//! error is below 1e-18 in for any harmonic this format can hold. FOREX4's
//! FORIF used 721 samples with π = 3.141593, which left ~1e-9 in of noise.
//!
//! `Z` depends on φ only through `sin φ` (eq 2-15 has `sin φ` and
//! `cos²φ = 1 − sin²φ`), so it is symmetric under `φ → π − φ`: `C_k = 0` for
//! odd k and `S_k = 0` for even k, exactly. They are returned as exact zeros.
//! With `s = sin φ`, `cos 2mφ = (−1)^m T_2m(s)` and
//! `sin (2m+1)φ = (−1)^m T_2m+1(s)` (Chebyshev polynomials), so the harmonic
//! series truncated after harmonic `N−1` *is* the degree `N−1` Chebyshev
//! expansion of `Z` in `s`; re-expanded in powers of `s` it is the N-term
//! sin-power form, eq 2-19..2-23 for N = 4. Both forms truncated at the same
//! degree are the same function, and linear interpolation of the columns
//! commutes with that change of basis, so they have the same truncation and
//! interpolation error; they differ only in table size and firmware work.

//! The folder: the series of one section ([`fit`]), the table's
//! specification ([`spec`]), the quantised table ([`generate`]), its error
//! budget ([`budget`]) and the smallest table within a bound ([`pick`]).

pub mod budget;
pub mod fit;
pub mod generate;
pub mod pick;
pub mod spec;

pub use budget::{
    error_split, interpolate, quantization_bound_uin, split_of, ErrorSplit, Sampling,
    SectionSource, TableColumns,
};
pub use fit::{
    columns_of, eval_columns, eval_sin_power, harmonics, harmonics_with, Harmonics, FOURIER_SAMPLES,
};
pub(crate) use generate::{check_coefficient_range, check_sign};
pub use generate::{generate, Generated};
pub use pick::{pick, pick_smallest, PickResult, BINARY_STEPS, CANDIDATE_STEPS};
pub use spec::{SpecError, TableSpec};
