//! `track`: a spindle-synchronous sinusoidal Z command through the
//! firmware's real command path on the scenario's machine, after settling
//! and learning.
//!
//! The command is a coefficient table of its own, harmonic form, constant
//! over X: `Z = A·(sin kφ − 1)` (C₀ = −A, S_k = A), whose maximum is 0, so
//! the firmware's load-time sign check accepts it like any part. k is the
//! harmonic that puts `freq` at a whole number of cycles per revolution
//! nearest the scenario's speed; the spindle then runs at `60·freq/k` rpm
//! (10 Hz at 300 rpm: k = 2, as the part's dominant C₂ term). Everything
//! else is the scenario's: gauge noise and hum, tachometer or encoder with
//! its errors, spindle ripple, the X slide (held inside the table).
//!
//! The following error is the true slide position (plant) minus the exact
//! command at the *true* spindle angle (the spindle model's, not the
//! firmware's estimate): what the part would see. The gauge error is what
//! the gauge reads minus the same command.

use crate::fwrig::Controller;
use crate::scenario::Scenario;
use serde::Serialize;
use zslide::servo::Phase;
use zslide::table::{Representation, TableHeader};

/// What a `track` run measured.
#[derive(Clone, Debug, Serialize)]
pub struct TrackReport {
    pub following_error_peak_uin: f64,
    pub following_error_rms_uin: f64,
    pub gauge_error_rms_uin: f64,
    pub settle_s: f64,
    pub learning_revs: u32,
    pub faults: Vec<String>,
    pub controller: String,
    pub scenario: String,
    pub freq_hz: f64,
    pub amplitude_in: f64,
    pub harmonic: u32,
    pub rpm: f64,
    pub measured_revs: u32,
    pub simulated_s: f64,
    /// RMS of the firmware's spindle angle minus the true angle at the
    /// handler's read instant (the instant the estimate is for), degrees.
    pub angle_error_rms_deg: f64,
}

/// The run's settings.
#[derive(Clone, Debug)]
pub struct TrackSpec {
    pub freq_hz: f64,
    pub amplitude_in: f64,
    pub controller: Controller,
    /// Revolutions of learning (digital) or settling (analog) before the
    /// measurement, after the engagement.
    pub learn_revs: u32,
    pub measure_revs: u32,
}

/// The harmonic table `Z = A·(sin kφ − 1)` over X 0..8 in.
pub fn sinusoid_table(amplitude_in: f64, k: u32) -> anyhow::Result<Vec<u8>> {
    anyhow::ensure!(
        (1..=15).contains(&k),
        "harmonic {k}: the table holds k = 1..15"
    );
    anyhow::ensure!(
        amplitude_in > 0.0 && amplitude_in <= 0.0045,
        "amplitude {amplitude_in} in: must be in (0, 0.0045] (the command A·(sin kφ − 1) spans 2A inside the gauge's 0.010 in)"
    );
    let terms = 2 * k as usize + 1;
    let q30 = |v: f64| (v * (1u64 << 30) as f64).round() as i32;
    let mut row = vec![0i32; terms];
    row[0] = q30(-amplitude_in);
    row[2 * k as usize] = q30(amplitude_in);
    let geometry = zslide::table::CoeffTable::parse(zslide::DEFAULT_TABLE)
        .map_err(|e| anyhow::anyhow!("default table: {e:?}"))?
        .header()
        .geometry;
    let header = TableHeader {
        representation: Representation::Harmonic,
        terms: terms as u8,
        coeff_frac_bits: 30,
        x_frac_bits: 24,
        node_count: 2,
        x0_raw: 0,
        dx_raw: 8 << 24,
        x_null_raw: 8 << 24,
        geometry,
    };
    let payload: Vec<i32> = row.iter().chain(row.iter()).copied().collect();
    let mut out = vec![0u8; header.image_len()];
    header
        .encode(&payload, &mut out)
        .map_err(|e| anyhow::anyhow!("table encode: {e:?}"))?;
    Ok(out)
}

/// Runs `track` on `sc`.
pub fn run(sc: &Scenario, spec: &TrackSpec) -> anyhow::Result<TrackReport> {
    anyhow::ensure!(
        spec.freq_hz > 0.0 && spec.freq_hz <= 200.0,
        "--freq {}: must be in (0, 200] Hz",
        spec.freq_hz
    );
    let rps0 = sc.file.spindle.rpm / 60.0;
    let k = (spec.freq_hz / rps0).round().max(1.0) as u32;
    let rpm = spec.freq_hz * 60.0 / f64::from(k);
    anyhow::ensure!(
        rpm >= f64::from(sc.file.spindle.min_rpm) && rpm <= f64::from(sc.file.spindle.max_rpm),
        "--freq {} Hz needs {rpm:.1} rpm (k = {k}), outside the scenario's {}..{} rpm",
        spec.freq_hz,
        sc.file.spindle.min_rpm,
        sc.file.spindle.max_rpm
    );
    // One image per run: the firmware takes a 'static table, as from flash.
    let table: &'static [u8] = Box::leak(sinusoid_table(spec.amplitude_in, k)?.into_boxed_slice());
    let mut machine = sc.machine.clone();
    machine.spindle.rpm0 = rpm;
    let (mut w, mut s) = crate::fwrig::firmware_with(sc.rig.clone(), sc.loop_hz, sc.servo);
    w.attach_machine_with_table(&machine, table);
    crate::fwrig::add_machine_sources(&w, &mut s);
    spec.controller.attach(&mut w, &mut s);
    let tick_ns = 1_000_000_000 / u64::from(sc.loop_hz);
    let rev_ns = (60.0e9 / rpm) as u64;
    let index_phase = sc.machine.spindle.index_phase_turns;
    // Engagement: the first index (angle known), the sign check and the
    // approach to the moving command.
    let mut t = 0u64;
    let limit = 5_000_000_000u64;
    let mut settle_ns = 0;
    loop {
        t += tick_ns;
        s.run_until(&mut w, t);
        let engaged = match spec.controller {
            Controller::Digital => w.fw.servo().phase() == Phase::Engaged,
            Controller::LegacyAnalog => w.fw.table_code() != 0,
        };
        if engaged && settle_ns == 0 {
            settle_ns = t;
        }
        if settle_ns != 0 || w.fw.fault().is_some() || t > limit {
            break;
        }
    }
    let learn_end = t + u64::from(spec.learn_revs) * rev_ns;
    s.run_until(&mut w, learn_end);
    let learning_revs = match spec.controller {
        Controller::Digital => w.fw.learning().revolutions(),
        Controller::LegacyAnalog => 0,
    };
    let end = learn_end + u64::from(spec.measure_revs) * rev_ns;
    let (mut s2, mut g2, mut peak, mut n) = (0.0, 0.0, 0.0f64, 0.0);
    let mut a2 = 0.0;
    let a = spec.amplitude_in;
    let mut t = learn_end;
    while t < end && w.fw.fault().is_none() {
        t += tick_ns;
        s.run_until(&mut w, t);
        let (turns, read_turns) = {
            let m = w.machine.as_ref().expect("a machine is attached");
            let mut sp = m.spindle.borrow_mut();
            // The firmware's angle is for the handler's read instant (read
            // in time order: the link forgets what lies behind a read).
            let now = sp.turns_at(t);
            let read = sp.turns_at(t + w.rig.handler_entry_ns);
            (now + index_phase, read + index_phase)
        };
        let z_cmd = a * ((std::f64::consts::TAU * f64::from(k) * turns).sin() - 1.0);
        if let Some(st) = w.stats() {
            let fw_turns = f64::from(st.angle.0) / 4_294_967_296.0;
            let d = (fw_turns - read_turns).rem_euclid(1.0);
            let d = if d > 0.5 { d - 1.0 } else { d };
            a2 += (d * 360.0) * (d * 360.0);
        }
        let e = w.rig.slide.position_in() - z_cmd;
        let g = f64::from(w.fw.position_code()) * 0.010 / 524_288.0 - z_cmd;
        s2 += e * e;
        g2 += g * g;
        peak = peak.max(e.abs());
        n += 1.0;
    }
    let faults =
        w.fw.fault()
            .map(|f| vec![format!("{f:?}: {}", f.reason())])
            .unwrap_or_default();
    let n = f64::max(n, 1.0);
    Ok(TrackReport {
        following_error_peak_uin: peak * 1e6,
        following_error_rms_uin: (s2 / n).sqrt() * 1e6,
        gauge_error_rms_uin: (g2 / n).sqrt() * 1e6,
        settle_s: settle_ns as f64 * 1e-9,
        learning_revs,
        faults,
        controller: spec.controller.name().into(),
        scenario: sc.file.name.clone(),
        freq_hz: spec.freq_hz,
        amplitude_in: spec.amplitude_in,
        harmonic: k,
        rpm,
        measured_revs: spec.measure_revs,
        simulated_s: t as f64 * 1e-9,
        angle_error_rms_deg: (a2 / n).sqrt(),
    })
}
