//! One module per command of the acceptance interface.
pub mod accuracy;
pub mod bench;
pub mod center;
pub mod coeffs;
pub mod compensate;
pub mod csmp;
pub mod cut;
pub mod faults;
pub mod parttable;
pub mod plan;
pub mod replay;
pub mod response;
pub mod serve;
pub mod soak;
pub mod trace2vcd;
pub mod track;
pub mod zcmd;
