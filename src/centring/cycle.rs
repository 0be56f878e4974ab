//! The centring sequence (Y-1594 ch. II): sample a revolution, test the
//! level, correct both slides by `K` times the off-centre, repeat.
//!
//! ```text
//! WaitTable ──index──▶ Sampling ──estimate──▶ level? ──below──▶ Centred
//!                         ▲                     │above
//!                         └──both slides settled┴─▶ Correcting
//! ```
//! The level detector compares each axis with the bias, as the 1967
//! differential amplifier did: centred when |x| and |y| are both below the
//! level. Refusals ([`Fault`]) open both loops and end the sequence:
//! a reading at the end of the transducer's travel, an estimate larger than
//! the previous one (a cycle made it worse), more than `max_cycles`
//! corrections, a slide that does not settle, and a table that is not
//! turning (no encoder edge within four counts' time at the slowest table
//! speed, an index period outside the speed band, or an index fault).
//!
//! The table angle is the spindle angle estimator of `crate::spindle`
//! (encoder + index): the same concept, a rotary axis turning slowly.

use super::estimate::{Harmonic, OffCentre, Progress, Quadrant};
use super::servo::{LoopDesign, ServoConfig, SlideServo};
use crate::safety::Fault;
use crate::spindle::{EncoderAngle, EncoderConfig};
use crate::trig;
use crate::units::{SpindleAngle, TableInches};

/// Off-centre estimator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// The 1967 four cam switches.
    Quadrant,
    /// Least-squares first harmonic of every tick of a revolution.
    Lsq,
    /// The same fit, revolution after revolution without waiting for the
    /// slides: each reading is corrected by the slides' travel since the
    /// revolution began (integrated tachometers, rotated to the table
    /// angle), so the fit is the off-centre at the revolution's start while
    /// the slides move; the target is renewed after every revolution.
    LsqMoving,
}

/// Sequence configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    pub method: Method,
    pub design: LoopDesign,
    /// Correction ratio K, Q30 (0.95 in the seed's design).
    pub k_q30: i32,
    /// Level detector bias: centred when both axes are below it.
    pub level: TableInches,
    pub max_cycles: u32,
    pub tick_hz: u32,
    /// A correction longer than this is a stuck slide.
    pub max_correction_ticks: u32,
    pub encoder: EncoderConfig,
    /// Nominal radius of the part where the transducer touches it: the
    /// reading is `x cos θ − y sin θ − (x sin θ + y cos θ)²/2R`, and with
    /// `LsqMoving` the second term changes as the slides move. Zero: no
    /// second-order correction.
    pub part_radius: TableInches,
}

/// What the sequence is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    WaitTable,
    Sampling,
    Correcting,
    Centred(OffCentre),
    Refused(Fault),
}

/// Inputs of one loop tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Inputs {
    /// Table encoder count and the timestamp of its last edge.
    pub count: u32,
    pub edge_ticks: u32,
    /// Clock now (the encoder's timestamp clock).
    pub now: u32,
    /// An index since the last tick: the count latched at it and its time.
    pub index: Option<(u32, u32)>,
    /// Transducer reading, converted to inches.
    pub reading: TableInches,
    /// Tachometers of the X′ and Y′ slide motors, µV.
    pub tach_uv: [i32; 2],
}

/// Something the host or a display wants to know about, once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// A revolution was sampled: cycle number (1 = first sample) and the
    /// off-centre measured.
    Measured(u32, OffCentre),
    /// Both slides settled after the correction of this cycle.
    Corrected(u32),
    Refused(Fault),
}

// No allocation in the core: the 5 KB of the harmonic fit's bins are
// reserved in place whichever method is configured.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
enum Estimator {
    Quadrant(Quadrant),
    Lsq(Harmonic),
}

/// The sequence. Owns both slide servos and the table angle.
#[derive(Clone, Debug)]
pub struct Centring {
    cfg: Config,
    angle: EncoderAngle,
    servo: [SlideServo; 2],
    state: State,
    est: Estimator,
    cycle: u32,
    last: Option<OffCentre>,
    last_count: u32,
    last_move: u32,
    stall_ticks: u32,
    correcting_ticks: u32,
    table_angle: SpindleAngle,
    /// Slide positions (integrated tachometers, I2F30 bits) when the
    /// revolution being sampled began (`LsqMoving`).
    rev_start: [i64; 2],
    /// Both slides stayed settled through the revolution being sampled.
    quiet_rev: bool,
    /// Estimated off-centre when the revolution began (`LsqMoving`).
    centre_at_rev_start: [i64; 2],
    /// 1/(2R) in Q30 per inch (0: no second-order term).
    inv_2r_q30: i64,
}

impl Centring {
    /// `None` for a configuration that cannot work (see
    /// [`EncoderAngle::new`]; a tick rate of 0; K outside (0, 1]).
    pub fn new(cfg: Config) -> Option<Self> {
        if !(1..=1 << 30).contains(&cfg.k_q30) {
            return None;
        }
        let angle = EncoderAngle::new(cfg.encoder)?;
        let sc = ServoConfig::new(cfg.design, cfg.tick_hz);
        let servo = [SlideServo::new(sc)?, SlideServo::new(sc)?];
        let e = cfg.encoder;
        let rev_ticks = u64::from(e.ticks_per_s) * 60 / u64::from(e.min_rpm);
        let stall_ticks =
            (rev_ticks / u64::from(e.counts_per_rev) * 4).clamp(1, u64::from(u32::MAX / 2)) as u32;
        Some(Self {
            est: Self::estimator(cfg.method),
            cfg,
            angle,
            servo,
            state: State::WaitTable,
            cycle: 0,
            last: None,
            last_count: 0,
            last_move: 0,
            stall_ticks,
            correcting_ticks: 0,
            table_angle: SpindleAngle(0),
            rev_start: [0; 2],
            quiet_rev: true,
            centre_at_rev_start: [0; 2],
            inv_2r_q30: if cfg.part_radius.to_bits() > 0 {
                (1i64 << 59) / i64::from(cfg.part_radius.to_bits())
            } else {
                0
            },
        })
    }

    fn estimator(m: Method) -> Estimator {
        match m {
            Method::Quadrant => Estimator::Quadrant(Quadrant::new()),
            Method::Lsq | Method::LsqMoving => Estimator::Lsq(Harmonic::new()),
        }
    }

    pub fn state(&self) -> State {
        self.state
    }

    /// Table angle of the last tick.
    pub fn table_angle(&self) -> SpindleAngle {
        self.table_angle
    }

    /// Remaining travel of each slide in this correction, I2F30 bits.
    pub fn slide_error_q30(&self) -> [i64; 2] {
        [self.servo[0].error_q30(), self.servo[1].error_q30()]
    }

    fn refuse(&mut self, f: Fault) -> Option<Event> {
        for s in &mut self.servo {
            s.stop();
        }
        self.state = State::Refused(f);
        Some(Event::Refused(f))
    }

    /// One loop tick: motor voltage commands (mV) for X′ and Y′, and an
    /// event if one happened.
    pub fn tick(&mut self, inp: &Inputs) -> ([i32; 2], Option<Event>) {
        if matches!(self.state, State::Centred(_) | State::Refused(_)) {
            return ([0, 0], None);
        }
        let ev = self.sequence(inp);
        let out = [
            self.servo[0].tick(inp.tach_uv[0]),
            self.servo[1].tick(inp.tach_uv[1]),
        ];
        (out, ev)
    }

    fn sequence(&mut self, inp: &Inputs) -> Option<Event> {
        if inp.count != self.last_count {
            self.last_count = inp.count;
            self.last_move = inp.now;
        } else if inp.now.wrapping_sub(self.last_move) > self.stall_ticks {
            return self.refuse(Fault::CentringTableStopped);
        }
        if let Some((c, t)) = inp.index {
            match self.angle.on_index(c, t) {
                Ok(()) => {}
                Err(Fault::SpindleSpeed) => return self.refuse(Fault::CentringTableStopped),
                Err(f) => return self.refuse(f),
            }
        }
        let est = self.angle.tick(inp.count, inp.edge_ticks, inp.now);
        match est.fault {
            None => {}
            Some(Fault::SpindleSpeed) => return self.refuse(Fault::CentringTableStopped),
            Some(f) => return self.refuse(f),
        }
        self.table_angle = est.angle;
        match self.state {
            State::WaitTable => {
                if self.angle.referenced() {
                    self.new_revolution();
                }
                None
            }
            State::Sampling => {
                self.quiet_rev &= self.servo.iter().all(|s| s.settled());
                let moved = self.moved_since_rev_start();
                let reading = if self.cfg.method == Method::LsqMoving {
                    // Take out what the slides did to the reading.
                    let t = trig::sin_cos(est.angle);
                    let c0 = self.centre_at_rev_start;
                    let c1 = [c0[0] + moved[0], c0[1] + moved[1]];
                    let seen = self
                        .reading_model(c1, t)
                        .saturating_sub(self.reading_model(c0, t));
                    let r = i64::from(inp.reading.to_bits()).saturating_sub(seen);
                    TableInches::from_bits(r.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32)
                } else {
                    inp.reading
                };
                let p = match &mut self.est {
                    Estimator::Quadrant(q) => q.sample(est.angle, reading),
                    Estimator::Lsq(h) => h.sample(est.angle, reading),
                };
                match p {
                    Err(f) => self.refuse(f),
                    Ok(Progress::Sampling) => None,
                    Ok(Progress::Done(d)) if self.cfg.method == Method::LsqMoving => {
                        // Off-centre now = at the revolution's start + travel since.
                        let now = |v: TableInches, m: i64| {
                            let b = i64::from(v.to_bits()).saturating_add(m);
                            TableInches::from_bits(
                                b.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
                            )
                        };
                        self.measured(OffCentre {
                            x: now(d.x, moved[0]),
                            y: now(d.y, moved[1]),
                        })
                    }
                    Ok(Progress::Done(d)) => self.measured(d),
                }
            }
            State::Correcting => {
                self.correcting_ticks = self.correcting_ticks.saturating_add(1);
                if self.correcting_ticks > self.cfg.max_correction_ticks {
                    return self.refuse(Fault::CentringSlideTimeout);
                }
                if self.servo.iter().all(|s| s.settled()) {
                    for s in &mut self.servo {
                        s.stop();
                    }
                    self.new_revolution();
                    Some(Event::Corrected(self.cycle))
                } else {
                    None
                }
            }
            State::Centred(_) | State::Refused(_) => None,
        }
    }

    fn new_revolution(&mut self) {
        self.state = State::Sampling;
        self.est = Self::estimator(self.cfg.method);
        self.rev_start = [self.servo[0].position_q30(), self.servo[1].position_q30()];
        self.quiet_rev = true;
    }

    /// The reading's dependence on the part centre `c` (I2F30 bits):
    /// `cx cos θ − cy sin θ − (cx sin θ + cy cos θ)²/2R`.
    fn reading_model(&self, c: [i64; 2], t: trig::SinCos) -> i64 {
        let (s, co) = (i64::from(t.sin), i64::from(t.cos));
        let along = (c[0] * co - c[1] * s) >> trig::FRAC_BITS;
        let across = (c[0] * s + c[1] * co) >> trig::FRAC_BITS;
        // across² is ≤ 0.25 in² (2⁵⁸ in Q60); times 1/2R in Q30 fits i128.
        let sq = ((i128::from(across) * i128::from(across)) >> 30) * i128::from(self.inv_2r_q30);
        along.saturating_sub((sq >> 30) as i64)
    }

    fn moved_since_rev_start(&self) -> [i64; 2] {
        [
            self.servo[0]
                .position_q30()
                .saturating_sub(self.rev_start[0]),
            self.servo[1]
                .position_q30()
                .saturating_sub(self.rev_start[1]),
        ]
    }

    /// End of a sampled revolution: level detector, worse-check, correction.
    fn measured(&mut self, d: OffCentre) -> Option<Event> {
        self.cycle = self.cycle.saturating_add(1);
        let worse = self
            .last
            .is_some_and(|p| d.max_abs_bits() > p.max_abs_bits());
        self.last = Some(d);
        let level = i64::from(self.cfg.level.to_bits());
        // Centred only on a revolution with the slides at rest throughout:
        // nothing moved under the measurement, and nothing moves after it.
        // (A fit during motion is good to a few % of the motion: the
        // transducer's second-order geometry, c²/2R, changes with it.)
        let below = d.max_abs_bits() < level;
        if below && self.quiet_rev {
            for s in &mut self.servo {
                s.stop();
            }
            self.state = State::Centred(d);
            // The measurement is reported with the verdict.
            return Some(Event::Measured(self.cycle, d));
        }
        if worse && !below {
            self.refuse(Fault::CentringWorse);
            return Some(Event::Measured(self.cycle, d));
        }
        if self.cycle > self.cfg.max_cycles {
            self.refuse(Fault::CentringNoConvergence);
            return Some(Event::Measured(self.cycle, d));
        }
        let k = i64::from(self.cfg.k_q30);
        let travel = |v: TableInches| {
            TableInches::from_bits(((i64::from(v.to_bits()) * k) >> 30).saturating_neg() as i32)
        };
        if self.cfg.method == Method::LsqMoving {
            // Keep going: renew the targets (unless the part is already
            // within the level, measured in motion: then let the slides
            // finish) and sample the next revolution.
            if !below {
                self.servo[0].retarget(travel(d.x));
                self.servo[1].retarget(travel(d.y));
            }
            self.new_revolution();
            self.centre_at_rev_start = [i64::from(d.x.to_bits()), i64::from(d.y.to_bits())];
        } else {
            self.servo[0].start(travel(d.x));
            self.servo[1].start(travel(d.y));
            self.correcting_ticks = 0;
            self.state = State::Correcting;
        }
        Some(Event::Measured(self.cycle, d))
    }
}
