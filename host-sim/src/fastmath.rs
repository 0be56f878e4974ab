//! Bit-exact replacements for std float functions that are slow on the
//! baseline x86-64 target; they live with the plant model, whose gauge ADC
//! quantisation uses them too.
pub use zslide_plant::fastmath::{round_i32, round_i64};
