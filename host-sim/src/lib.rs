//! Host simulator of the Z-slide machine.
pub mod analog1983;
pub mod analyser;
pub mod centring;
pub mod chips;
pub mod cmd;
pub mod coeffgen;
pub mod csmp;
pub mod fastmath;
pub mod fwrig;
pub mod geometry;
pub mod machine;
pub mod plant;
pub mod scenario;
pub mod sched;
pub mod surface;
pub mod vcd;
