//! Host simulator of the Z-slide machine.
pub mod cmd;
pub mod coeffgen;
pub mod csmp;
pub mod geometry;
pub mod surface;
pub mod machine;
