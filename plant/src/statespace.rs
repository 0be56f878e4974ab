//! The slide's state vector and the matrices of one exact step: what the
//! model ([`crate::slide`]) and its discretisation ([`crate::zoh`], `std`
//! builds) share.

/// Index of each state in the state vector.
pub mod st {
    pub const I: usize = 0;
    pub const V: usize = 1;
    pub const Z: usize = 2;
    pub const Q: usize = 3;
    pub const QD: usize = 4;
    pub const N: usize = 5;
}

/// `Φ` and `Γ` of one step: `x(t+h) = Φ x(t) + Γ u`, exact for inputs held
/// over the step (zero-order hold), in fixed arrays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mats {
    pub phi: [[f64; st::N]; st::N],
    pub gamma: [[f64; 2]; st::N],
}
