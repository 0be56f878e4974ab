//! Host simulator of the Z-slide machine.
pub mod analog1983;
pub mod analyser;
pub mod chips;
pub mod cmd;
pub mod plant;
pub mod sched;
pub mod vcd;
