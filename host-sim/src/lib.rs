//! Host simulator of the Z-slide machine.
pub mod cmd;
pub mod csmp;
