//! `--controller legacy-analog` with the 1983 command generator
//! (`[errors] gen_*`, `analog1983::generator`): the firmware's legacy
//! coefficient output writes C00..C03 to the quad DAC on the half-mil X
//! events, as the 8080 did; the sine oscillator, driven by the spindle's
//! tachometer and reset by its index, and the multiplier network form the
//! command the 1983 loop follows, in place of the firmware's own.

use crate::analog1983::generator::{command_v, GeneratorLevels, SineGenerator};
use crate::error_levels::ErrorLevels;
use std::cell::Cell;
use std::rc::Rc;

/// Gauge codes per volt of the loop's reference (V = mil).
const CODES_PER_V: f64 = 524_288.0 / 10.0;

/// The generator's levels, if the scenario states one (`gen_calibrated_rpm > 0`).
pub fn levels(l: &ErrorLevels) -> Option<GeneratorLevels> {
    (l.gen_calibrated_rpm > 0.0).then_some(GeneratorLevels {
        tach_rate_error: l.gen_tach_rate_error,
        reset_hold_s: l.gen_reset_hold_us * 1e-6,
        multiplier_offset_v: l.gen_multiplier_offset_mv * 1e-3,
        calibrated_rpm: l.gen_calibrated_rpm,
    })
}

/// The analog command generator run by the cutter at every loop tick.
pub struct AnalogCommand {
    gen: SineGenerator,
    /// The reference the 1983 loop follows, V = mil (the world reads it:
    /// `AnalogDrive::command_v`).
    pub out: Rc<Cell<f64>>,
    /// (time s, spindle turns) at the last tick.
    last: Option<(f64, f64)>,
}

impl AnalogCommand {
    pub fn new(lv: GeneratorLevels, out: Rc<Cell<f64>>) -> Self {
        Self {
            gen: SineGenerator::new(lv),
            out,
            last: None,
        }
    }

    /// One loop tick at `t_s` with the spindle at `spindle_turns` (true,
    /// the index at whole turns), the coefficient DAC at `c_v` (C00..C03,
    /// V); `engaged`: the firmware has a table command (before that the
    /// shop's command generator was switched out of the loop, chapter 5's
    /// activation), `target_code` its offset, gauge codes.
    pub fn tick(
        &mut self,
        t_s: f64,
        spindle_turns: f64,
        c_v: [f64; 4],
        engaged: bool,
        target_code: i32,
    ) {
        match self.last {
            // The machine ran before this stretch: the generator is where
            // it would be, reset at the last index and run at this speed.
            None => {
                self.gen.index();
                let rpm = self.gen.levels().calibrated_rpm;
                let since = spindle_turns - spindle_turns.floor();
                self.gen.advance(since * 60.0 / rpm, rpm);
            }
            Some((t0, u0)) => {
                let (dt, du) = (t_s - t0, spindle_turns - u0);
                if dt > 0.0 {
                    // The tachometer reads the speed over the tick.
                    let rpm = du / dt * 60.0;
                    if spindle_turns.floor() > u0.floor() {
                        let w = (u0.floor() + 1.0 - u0) / du;
                        self.gen.advance(w * dt, rpm);
                        self.gen.index();
                        self.gen.advance((1.0 - w) * dt, rpm);
                    } else {
                        self.gen.advance(dt, rpm);
                    }
                }
            }
        }
        self.last = Some((t_s, spindle_turns));
        let z = if engaged {
            command_v(c_v, self.gen.sine())
        } else {
            0.0
        };
        self.out.set(z + f64::from(target_code) / CODES_PER_V);
    }
}
