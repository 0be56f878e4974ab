//! Replay of X sweeps through the legacy interface: the simulated
//! interferometer counter chain (dither and ripple-latch glitches included)
//! drives both
//!
//! * a reference model of the 1983 8080 program, written here from the
//!   listing of appendix A and nothing else, and
//! * the firmware's legacy path: `xpos::LegacyX` → `command` (coefficients
//!   and Table 3-1 codes) → `drivers::ad5686` → a quad DAC chip model,
//!
//! and every coefficient update, value and strobe must agree.

use host_sim::machine::xslide::{FeedSegment, XSlide, XSlideConfig};
use std::convert::Infallible;
use zslide::command::CommandGen;
use zslide::drivers::ad5686::Ad5686;
use zslide::hw::XLatchWord;
use zslide::table::{CoeffTable, Geometry, Representation, TableHeader};
use zslide::xpos::legacy_output::LegacyOutput;
use zslide::xpos::{LegacyConfig, LegacyX, XEvent};

/// Table 2-2, as printed (0.1 in grid, X = 0..8 in, C00..C03).
fn table_2_2() -> Vec<[f64; 4]> {
    let text = include_str!("../../tests/table_2_2.csv");
    text.lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|f| f.trim().parse().unwrap()).collect();
            [v[1], v[2], v[3], v[4]]
        })
        .collect()
}

// ---------------------------------------------------------------------------
// Reference: the 8080 program of appendix A.
// ---------------------------------------------------------------------------

/// What the 8080 did at one interrupt: `None` if it returned to NTNO
/// without output (debounce), else the DAC words written before the strobe.
type Output8080 = Option<[Option<f64>; 4]>;

/// State of the 8080 program (appendix A equates DAT0, OLDH, FLG0..3,
/// FLDF0..3, BTNO0..3).
struct Ref8080 {
    table: Vec<[f64; 4]>,
    dat0: Option<u32>,
    oldh: Option<u32>,
    flg: [bool; 4],
    /// Rate of change per update step and the lower end value, per coefficient.
    rate: [f64; 4],
    base: [f64; 4],
}

impl Ref8080 {
    fn new(table: Vec<[f64; 4]>) -> Self {
        Self {
            table,
            dat0: None,
            oldh: None,
            flg: [false; 4],
            rate: [0.0; 4],
            base: [0.0; 4],
        }
    }

    /// BASNO + DFRNC: lower end and (upper − lower)/divisor for interval BN1.
    fn rate_of(&mut self, j: usize, bn1: usize, divisor: f64) {
        let lo = self.table[bn1][j];
        let hi = self.table[bn1 + 1][j];
        self.base[j] = lo;
        self.rate[j] = (hi - lo) / divisor;
        self.flg[j] = false;
    }

    /// NTYS: one interrupt with the latched port contents.
    fn interrupt(&mut self, word: XLatchWord) -> Output8080 {
        let w = word.0;
        // IN P1DA / CMP M / JZ NTNO: the flag byte unchanged → ignore.
        let flags = w & (XLatchWord::HALF_MIL | XLatchWord::MIL_ZERO);
        if self.dat0 == Some(flags) {
            return None;
        }
        self.dat0 = Some(flags);
        let whole_mil = w & XLatchWord::HALF_MIL == 0;
        // DAT0-1: hundredths | thousandths; DAT0-2: units | tenths.
        let ms = (w >> 8) & 0xFF;
        let (dgp0, dgm1) = ((ms >> 4) as usize, (ms & 0xF) as usize);
        let (dgm2, dgm3) = (((w >> 4) & 0xF) as usize, (w & 0xF) as usize);
        // CPI 72H / JM SKP0: 7.2 in and beyond, all coefficients null.
        if ms >= 0x72 {
            return Some([Some(0.0); 4]);
        }
        // SKP0: new interval → rates to recompute (FLG0..3).
        if self.oldh != Some(ms) {
            self.flg = [true; 4];
            self.oldh = Some(ms);
        }
        let bn1 = dgp0 * 10 + dgm1;
        let bn2 = (dgm2 * 10 + dgm3) as f64;
        let mut out = [None; 4];
        // C02 every interrupt: 200 steps per interval, the half-mil count.
        if self.flg[2] {
            self.rate_of(2, bn1, 200.0);
        }
        let n = 2.0 * bn2 + if whole_mil { 0.0 } else { 1.0 };
        out[2] = Some(self.base[2] + n * self.rate[2]);
        if whole_mil {
            // C01 every mil: 100 steps.
            if self.flg[1] {
                self.rate_of(1, bn1, 100.0);
            }
            out[1] = Some(self.base[1] + bn2 * self.rate[1]);
            // C00 and C03 when the mil digit is 0: 10 steps of the hundredths.
            if dgm3 == 0 {
                for j in [0, 3] {
                    if self.flg[j] {
                        self.rate_of(j, bn1, 10.0);
                    }
                    out[j] = Some(self.base[j] + dgm2 as f64 * self.rate[j]);
                }
            }
        }
        Some(out)
    }
}

/// Table 3-1 code of a coefficient (inches), exactly, as a real number.
fn code_exact(c: f64) -> f64 {
    32768.0 + c * 65536.0 / 0.020
}

// ---------------------------------------------------------------------------
// The quad DAC chip at the level of its frames and LDAC pin.
// ---------------------------------------------------------------------------

#[derive(Default)]
struct QuadDac {
    input: [u16; 4],
    output: [Option<u16>; 4],
    written: [bool; 4],
    strobes: u32,
}

struct Bus<'a>(&'a std::cell::RefCell<QuadDac>);
struct Ldac<'a>(&'a std::cell::RefCell<QuadDac>);

impl embedded_hal::spi::ErrorType for Bus<'_> {
    type Error = Infallible;
}
impl embedded_hal::spi::SpiDevice for Bus<'_> {
    fn transaction(
        &mut self,
        ops: &mut [embedded_hal::spi::Operation<'_, u8>],
    ) -> Result<(), Infallible> {
        let mut d = self.0.borrow_mut();
        for op in ops {
            if let embedded_hal::spi::Operation::Write(b) = op {
                let f = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
                assert_eq!(f >> 20, 0b0001, "write-input-register only");
                for ch in 0..4 {
                    if f >> 16 & (1 << ch) != 0 {
                        d.input[ch] = f as u16;
                        d.written[ch] = true;
                    }
                }
            }
        }
        Ok(())
    }
}
impl embedded_hal::digital::ErrorType for Ldac<'_> {
    type Error = Infallible;
}
impl embedded_hal::digital::OutputPin for Ldac<'_> {
    fn set_low(&mut self) -> Result<(), Infallible> {
        let mut d = self.0.borrow_mut();
        for ch in 0..4 {
            if d.written[ch] {
                d.output[ch] = Some(d.input[ch]);
            }
        }
        d.strobes += 1;
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}

// ---------------------------------------------------------------------------

fn table_image(t: &[[f64; 4]]) -> Vec<u8> {
    let h = TableHeader {
        representation: Representation::SinPower,
        terms: 4,
        coeff_frac_bits: 30,
        x_frac_bits: 24,
        node_count: t.len() as u32,
        x0_raw: 0,
        dx_raw: 1_677_722,       // 0.1 in
        x_null_raw: 120_795_955, // 7.2 in
        geometry: Geometry {
            c_nin: 316_700_000_000,
            s_y_nin: 28_000_000_000,
            tool_radius_nin: 125_000_000,
        },
    };
    let payload: Vec<i32> = t
        .iter()
        .flat_map(|r| r.map(|c| (c * 2f64.powi(30)).round() as i32))
        .collect();
    let mut out = vec![0u8; h.image_len()];
    h.encode(&payload, &mut out).unwrap();
    out
}

struct Tally {
    interrupts: usize,
    ignored: usize,
    stale: usize,
    ties: usize,
    compared: usize,
}

fn replay(cfg: XSlideConfig, until_ns: u64) -> Tally {
    let t22 = table_2_2();
    let img = table_image(&t22);
    let gen = CommandGen::new(CoeffTable::parse(&img).unwrap());
    let mut reference = Ref8080::new(t22);
    let mut core = LegacyX::new(LegacyConfig {
        refresh_all_on_entry: false,
        ..LegacyConfig::new(gen.x_null(), 1_000_000_000)
    });
    let chip = std::cell::RefCell::new(QuadDac::default());
    let mut dac = Ad5686::new(Bus(&chip), Ldac(&chip)).unwrap();
    let mut legacy_out = LegacyOutput::new();

    let mut slide = XSlide::new(cfg);
    let mut events = Vec::new();
    slide.advance(until_ns, 5_000, &mut events);
    let mut tally = Tally {
        interrupts: events.len(),
        ignored: 0,
        stale: events.iter().filter(|e| e.stale).count(),
        ties: 0,
        compared: 0,
    };
    for ev in &events {
        let want = reference.interrupt(ev.word);
        let strobes_before = chip.borrow().strobes;
        let got = core.on_interrupt(ev.word, ev.t_ns as u32).unwrap();
        match (want, got) {
            (None, XEvent::Ignored) => {
                tally.ignored += 1;
                assert_eq!(
                    chip.borrow().strobes,
                    strobes_before,
                    "no strobe when ignored"
                );
            }
            (Some(out), XEvent::Update(u)) => {
                let frame = legacy_out.frame(&gen, &u).unwrap();
                assert_eq!(frame.update, u.update);
                assert_eq!(frame, gen.legacy_frame(&u).unwrap());
                dac.output(&frame.codes, frame.update).unwrap();
                let d = chip.borrow();
                assert_eq!(d.strobes, strobes_before + 1, "one strobe per update");
                for (j, want) in out.iter().enumerate() {
                    assert_eq!(
                        want.is_some(),
                        u.update & (1 << j) != 0,
                        "C0{j} update set differs at {:?}",
                        ev
                    );
                    if let Some(c) = *want {
                        let exact = code_exact(c);
                        let got = f64::from(d.output[j].unwrap());
                        tally.compared += 1;
                        // Equal codes, except where the exact value sits on a
                        // rounding tie: within 0.005 LSB of one, both roundings
                        // are right (the Q30 coefficients and the binary X
                        // differ from the decimal reference by < 0.004 LSB).
                        let tie = (exact - exact.floor() - 0.5).abs() < 0.005;
                        if tie {
                            tally.ties += 1;
                            assert!((got - exact).abs() <= 0.505, "C0{j} at {ev:?}");
                        } else {
                            assert_eq!(got, exact.round(), "C0{j} at {ev:?}: exact {exact}");
                        }
                    }
                }
            }
            (w, g) => panic!("8080 {w:?} vs firmware {g:?} at {ev:?}"),
        }
    }
    tally
}

#[test]
fn downward_sweep_through_the_null_zone_edge_and_two_nodes() {
    // 7.25 in → 6.95 in at 0.5 in/min with 6 µin of 300 Hz vibration (its
    // velocity, 11 000 µin/s, exceeds the feed's: the counter reverses).
    let t = replay(
        XSlideConfig {
            x0_in: 7.25,
            feed: vec![FeedSegment {
                t_start_s: 0.0,
                feed_in_per_min: -0.5,
            }],
            vibration_uin: 6.0,
            vibration_hz: 300.0,
            ripple_prob: 0.2,
            seed: 83,
            ..XSlideConfig::default()
        },
        36_000_000_000,
    );
    assert!(
        t.interrupts > 600 && t.ignored > 10,
        "{}/{}",
        t.interrupts,
        t.ignored
    );
    assert!(
        t.ties * 20 < t.compared,
        "ties {} of {}",
        t.ties,
        t.compared
    );
}

#[test]
fn upward_sweep_with_reversals_and_ripple_glitches() {
    // 0.95 → 1.25 in, with two reversals of 3 mil, ripple latches 20 %.
    let t = replay(
        XSlideConfig {
            x0_in: 0.95,
            feed: vec![
                FeedSegment {
                    t_start_s: 0.0,
                    feed_in_per_min: 2.0,
                },
                FeedSegment {
                    t_start_s: 3.0,
                    feed_in_per_min: -0.5,
                },
                FeedSegment {
                    t_start_s: 3.36,
                    feed_in_per_min: 2.0,
                },
                FeedSegment {
                    t_start_s: 6.0,
                    feed_in_per_min: -0.5,
                },
                FeedSegment {
                    t_start_s: 6.36,
                    feed_in_per_min: 2.0,
                },
            ],
            vibration_uin: 15.0,
            vibration_hz: 250.0,
            ripple_prob: 0.2,
            seed: 1983,
            ..XSlideConfig::default()
        },
        9_500_000_000,
    );
    assert!(
        t.interrupts > 600 && t.ignored > 10 && t.stale > 5,
        "{} {} {}",
        t.interrupts,
        t.ignored,
        t.stale
    );
    assert!(
        t.ties * 20 < t.compared,
        "ties {} of {}",
        t.ties,
        t.compared
    );
}

/// With re-sync on (the firmware's default), leaving the null zone refreshes
/// all four coefficients at once, where the 8080 left C00, C01, C03 at zero
/// for up to 10 mil of travel.
#[test]
fn resync_refreshes_everything_on_leaving_the_null_zone() {
    let img = table_image(&table_2_2());
    let gen = CommandGen::new(CoeffTable::parse(&img).unwrap());
    let mut core = LegacyX::new(LegacyConfig::new(gen.x_null(), 1_000_000_000));
    let mut slide = XSlide::new(XSlideConfig {
        x0_in: 7.2004,
        feed: vec![FeedSegment {
            t_start_s: 0.0,
            feed_in_per_min: -1.0,
        }],
        ..XSlideConfig::default()
    });
    let mut ev = Vec::new();
    slide.advance(90_000_000, 5_000, &mut ev);
    let masks: Vec<(u32, u8, bool)> = ev
        .iter()
        .map(
            |e| match core.on_interrupt(e.word, e.t_ns as u32).unwrap() {
                XEvent::Update(u) => (u.half_mils, u.update, u.null),
                XEvent::Ignored => panic!("no dither here"),
            },
        )
        .collect();
    // 7.2000 (null, all), 7.1995 (leaving: all), 7.1990 (C02 + C01).
    assert_eq!(
        masks,
        [
            (14400, 0b1111, true),
            (14399, 0b1111, false),
            (14398, 0b0110, false)
        ]
    );
}
