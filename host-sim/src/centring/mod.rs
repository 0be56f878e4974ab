//! The automatic centring machine of Y-1594 (Feezell 1967), simulated around
//! the real firmware sequence `zslide::centring::Centring`.
//!
//! Each loop tick (10 kHz): the table encoder and index are read
//! ([`table`]), the part's surface under the plunger is found from the true
//! part centre ([`part`]) and converted ([`transducer`]), the tachometers
//! are converted, the firmware computes both motor voltages, and the
//! slides ([`slide`]) are advanced over the tick with the voltages of the
//! *previous* tick (the DAC is written at the end of the handler: one tick
//! of computation delay, as on the board). A fixed-rate loop rather than
//! `sched`: the machine has one periodic interrupt and the index is
//! latched by hardware (count and edge time), so the firmware reads it at
//! the next tick exactly as the board would.

pub mod part;
pub mod slide;
pub mod table;
pub mod transducer;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use zslide::centring::{Centring, Config, Event, Inputs, LoopDesign, Method, State};
use zslide::safety::Fault;
use zslide::spindle::EncoderConfig;
use zslide::units::{SpindleAngle, TableInches};

pub use part::{Lobe, Part};
pub use slide::Mechanics;

pub const TICK_HZ: u32 = 10_000;
const SUB_STEPS: u32 = 4;

/// Everything about one centring run.
#[derive(Clone, Debug)]
pub struct Setup {
    pub method: Method,
    pub design: LoopDesign,
    pub k: f64,
    pub level_in: f64,
    pub max_cycles: u32,
    pub rpm: f64,
    pub part: Part,
    pub mechanics: Mechanics,
    /// Transducer noise, inches rms per sample.
    pub gauge_noise_in: f64,
    pub tach_noise_v: f64,
    pub table_stop_at_s: Option<f64>,
    pub seed: u64,
    /// Give up (and say so) after this much simulated time.
    pub max_time_s: f64,
    /// Trace decimation: one point per this many ticks.
    pub trace_every: u32,
}

impl Setup {
    /// The seed's machine with ideal mechanics and a round part.
    pub fn seed(offset_in: [f64; 2], method: Method, design: LoopDesign) -> Self {
        Self {
            method,
            design,
            k: default_k(method, design),
            level_in: 0.0001,
            max_cycles: 10,
            rpm: 25.0,
            part: Part {
                radius_in: 2.0,
                offset_in,
                lobes: Vec::new(),
            },
            mechanics: Mechanics::default(),
            gauge_noise_in: 0.0,
            // Ripple and noise of a small DC tachometer; it also dithers the
            // converter's 0.76 mV step, which the position integral needs.
            tach_noise_v: 0.002,
            table_stop_at_s: None,
            seed: 1,
            max_time_s: 900.0,
            trace_every: 100,
        }
    }
}

/// The correction ratio K by default. The seed under-corrects (0.95; 0.966
/// reproduces its compensated cycles, docs/CENTRING.md) because four
/// samples and an analog integrator could not be trusted to the last
/// percent. The least-squares fit is good to a few µin with gauge noise and
/// an out-of-round part, and the tachometer integral stops the slide on its
/// target, so the fit corrects in full: one cycle instead of three.
pub fn default_k(method: Method, design: LoopDesign) -> f64 {
    match (method, design) {
        (Method::Lsq | Method::LsqMoving, _) => 1.0,
        (Method::Quadrant, LoopDesign::Critical) => 0.95,
        (Method::Quadrant, LoopDesign::Compensated) => 0.966,
    }
}

/// One correction cycle (with `LsqMoving`, one revolution: measured at its
/// end, "corrected" at the end of the next one, the slides possibly still
/// moving).
#[derive(Clone, Debug, Serialize)]
pub struct Cycle {
    pub cycle: u32,
    /// What the firmware measured, inches.
    pub measured_x_in: f64,
    pub measured_y_in: f64,
    /// True off-centre (|centre|) when the measurement ended, and after the
    /// slides settled, inches.
    pub residual_before_in: f64,
    pub residual_in: f64,
    /// Simulated time at the end of the measurement and of the correction.
    pub measured_at_s: f64,
    pub corrected_at_s: f64,
    pub correction_s: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct TracePoint {
    pub t_s: f64,
    pub slide_x_in: f64,
    pub slide_y_in: f64,
    pub motor_x_rad_s: f64,
    pub motor_y_rad_s: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct Outcome {
    pub cycles: Vec<Cycle>,
    /// True |centre| at the end, inches.
    pub final_residual_in: f64,
    /// The firmware's last measurement, inches.
    pub final_measured_in: [f64; 2],
    pub centred: bool,
    /// The refusal, readable (`None` when centred).
    pub refusal: Option<String>,
    #[serde(skip)]
    pub fault: Option<Fault>,
    pub time_s: f64,
    pub trace: Vec<TracePoint>,
}

/// Time of loop tick `n`, s. Every use goes through here so that the
/// previous tick's time is bit-identical to what that tick used (`t − dt`
/// can round below it and report one index twice).
fn tick_time(n: u64) -> f64 {
    n as f64 / f64::from(TICK_HZ)
}

fn mag(v: [f64; 2]) -> f64 {
    v[0].hypot(v[1])
}

/// Runs the centring sequence to its end (centred, refused, or out of time).
pub fn run(s: &Setup) -> anyhow::Result<Outcome> {
    anyhow::ensure!(
        (1.0..=25.0).contains(&s.rpm),
        "table speed {} rpm is outside the table's 1-25 rpm",
        s.rpm
    );
    anyhow::ensure!(
        s.k > 0.0 && s.k <= 1.0,
        "correction ratio K = {} is not in (0, 1]",
        s.k
    );
    anyhow::ensure!(
        s.level_in > 0.0 && s.level_in < 0.5,
        "level {} in is not in (0, 0.5)",
        s.level_in
    );
    anyhow::ensure!(
        s.mechanics.free_play_in >= 0.0 && s.mechanics.deflection_in >= 0.0,
        "free play and deflection must not be negative"
    );
    let counts_per_rev = 36_000;
    let cfg = Config {
        method: s.method,
        design: s.design,
        k_q30: (s.k * (1u64 << 30) as f64).round() as i32,
        level: TableInches::from_f64(s.level_in),
        max_cycles: s.max_cycles,
        tick_hz: TICK_HZ,
        max_correction_ticks: 60 * TICK_HZ,
        encoder: EncoderConfig {
            counts_per_rev,
            ticks_per_s: table::CLOCK_HZ,
            min_rpm: 1,
            max_rpm: 26,
            index_tolerance_counts: 2,
            index_angle: SpindleAngle(0),
            edge_stamps: zslide::spindle::EdgeStamps::Captured,
        },
        // The operator enters the part's nominal radius.
        part_radius: TableInches::from_f64(s.part.radius_in),
    };
    let mut fw = Centring::new(cfg)
        .ok_or_else(|| anyhow::anyhow!("centring configuration refused by the firmware"))?;
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    let tbl = table::Table {
        rpm: s.rpm,
        counts_per_rev,
        stop_at_s: s.table_stop_at_s,
        // Start a little before the index so the first one comes soon.
        start_turns: 0.9,
    };
    let probe = transducer::Transducer {
        zero_in: s.part.radius_in,
        noise_in: s.gauge_noise_in,
    };
    let mut slides = [
        slide::Slide::new(TICK_HZ, SUB_STEPS, s.mechanics, s.tach_noise_v),
        slide::Slide::new(TICK_HZ, SUB_STEPS, s.mechanics, s.tach_noise_v),
    ];
    let centre = |sl: &[slide::Slide; 2]| {
        [
            s.part.offset_in[0] + sl[0].position_in(),
            s.part.offset_in[1] + sl[1].position_in(),
        ]
    };
    let mut dac = [0i32; 2];
    let mut cycles: Vec<Cycle> = Vec::new();
    let mut trace = Vec::new();
    let mut last_measured = [f64::NAN; 2];
    let mut n: u64 = 0;
    let fault = loop {
        let t = tick_time(n);
        let enc = tbl.read(t);
        let theta = enc.turns.fract() * std::f64::consts::TAU;
        let c = centre(&slides);
        let reading = probe.read(s.part.surface_x(theta, c), &mut rng);
        let inp = Inputs {
            count: enc.count,
            edge_ticks: enc.edge_ticks,
            now: table::ticks(t),
            index: if n == 0 {
                None
            } else {
                tbl.index_between(tick_time(n - 1), t)
            },
            reading: TableInches::from_f64(reading),
            tach_uv: [slides[0].tach_uv(&mut rng), slides[1].tach_uv(&mut rng)],
        };
        let (out, ev) = fw.tick(&inp);
        match ev {
            Some(Event::Measured(k, d)) => {
                last_measured = [d.x.to_f64(), d.y.to_f64()];
                // `LsqMoving` corrects while it samples: a cycle is one
                // revolution, and it ends at the next measurement.
                if let Some(cy) = cycles.last_mut().filter(|cy| cy.residual_in.is_nan()) {
                    cy.residual_in = mag(c);
                    cy.corrected_at_s = t;
                    cy.correction_s = t - cy.measured_at_s;
                }
                if matches!(fw.state(), State::Correcting | State::Sampling) {
                    cycles.push(Cycle {
                        cycle: k,
                        measured_x_in: last_measured[0],
                        measured_y_in: last_measured[1],
                        residual_before_in: mag(c),
                        residual_in: f64::NAN,
                        measured_at_s: t,
                        corrected_at_s: f64::NAN,
                        correction_s: f64::NAN,
                    });
                }
            }
            Some(Event::Corrected(_)) => {
                if let Some(cy) = cycles.last_mut() {
                    cy.residual_in = mag(c);
                    cy.corrected_at_s = t;
                    cy.correction_s = t - cy.measured_at_s;
                }
            }
            Some(Event::Refused(_)) | None => {}
        }
        if n.is_multiple_of(u64::from(s.trace_every.max(1))) {
            trace.push(TracePoint {
                t_s: t,
                slide_x_in: slides[0].position_in(),
                slide_y_in: slides[1].position_in(),
                motor_x_rad_s: slides[0].motor_rad_s(),
                motor_y_rad_s: slides[1].motor_rad_s(),
            });
        }
        match fw.state() {
            State::Centred(_) => break None,
            State::Refused(f) => break Some(f),
            _ => {}
        }
        if t > s.max_time_s {
            anyhow::bail!(
                "centring did not finish in {} s of simulated time (state {:?})",
                s.max_time_s,
                fw.state()
            );
        }
        for (sl, u) in slides.iter_mut().zip(dac) {
            sl.step(u, &mut rng);
        }
        dac = out;
        n += 1;
    };
    Ok(Outcome {
        final_residual_in: mag(centre(&slides)),
        final_measured_in: last_measured,
        centred: fault.is_none(),
        refusal: fault.map(|f| format!("{f:?}: {}", zslide::safety::Fault::reason(f))),
        fault,
        cycles,
        time_s: tick_time(n),
        trace,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_index_reaches_the_firmware_exactly_once() {
        let tbl = table::Table {
            rpm: 25.0,
            counts_per_rev: 36_000,
            stop_at_s: None,
            start_turns: 0.9,
        };
        // 100 revolutions at 25 rpm.
        let ticks = (100.0 * 2.4 * f64::from(TICK_HZ)) as u64;
        let n_idx = (1..ticks)
            .filter(|&n| tbl.index_between(tick_time(n - 1), tick_time(n)).is_some())
            .count();
        let turns = tbl.read(tick_time(ticks - 1)).turns.floor() as usize;
        assert_eq!(n_idx, turns);
    }
}
