//! The whole machine's signal set as VCD: positions, command, error,
//! current, force, converter codes, X and spindle angle (true and as the
//! firmware has them), handler activity, amplifier enable, fault.
//!
//! Activity bits toggle once per real handler run: `loop_tick` when the
//! firmware's tick counter moved, `x_event` / `index` when the machine's
//! handler counters moved. The X and spindle models' look-ahead wake-ups
//! (scheduler events that run no handler) change nothing.

use super::{SignalKind, VcdRecorder};
use crate::fwrig::FirmwareWorld;
use crate::sched::Scheduler;
use std::cell::RefCell;
use std::io::Write;
use std::rc::Rc;
use zslide::servo::Phase;
use zslide::trace::Signal;

/// Names and kinds of the recorded signals, in order. What the firmware
/// itself knows carries the names of `zslide::trace::Signal`, which a
/// target trace (`host-sim trace2vcd`) uses too, so the two open side by
/// side; the rest is the plant's truth, which only the simulator has.
pub const SIGNALS: [(&str, SignalKind); 19] = [
    ("slide_z_uin", SignalKind::Real),
    ("gauge_z_uin", SignalKind::Real),
    (Signal::Command.name(), SignalKind::Real),
    (Signal::Error.name(), SignalKind::Real),
    ("current_a", SignalKind::Real),
    ("force_lbf", SignalKind::Real),
    (Signal::AdcCode.name(), SignalKind::Int(20)),
    (Signal::DacCode.name(), SignalKind::Int(20)),
    (Signal::AmpEnabled.name(), SignalKind::Bit),
    ("x_true_in", SignalKind::Real),
    (Signal::XFirmware.name(), SignalKind::Real),
    ("spindle_phi_deg", SignalKind::Real),
    (Signal::AngleFirmware.name(), SignalKind::Real),
    (Signal::LoopTick.name(), SignalKind::Bit),
    (Signal::XEvent.name(), SignalKind::Bit),
    (Signal::Index.name(), SignalKind::Bit),
    (Signal::CoeffUpdate.name(), SignalKind::Bit),
    (Signal::Armed.name(), SignalKind::Bit),
    (Signal::Fault.name(), SignalKind::Bit),
];

/// Records the machine's signals over a time window.
pub struct MachineTrace<W: Write> {
    rec: VcdRecorder<W>,
    /// (loop ticks, X events, index events, coefficient generation) at
    /// the last sample.
    seen: (u32, u64, u64, u32),
    toggles: [bool; 4],
    window: (u64, u64),
    error: Option<std::io::Error>,
}

impl<W: Write> MachineTrace<W> {
    /// Header written; samples inside `[t_from, t_to)` ns are recorded.
    pub fn new(out: W, t_from: u64, t_to: u64) -> std::io::Result<Self> {
        Ok(Self {
            rec: VcdRecorder::new(out, "zslide", &SIGNALS)?,
            seen: (0, 0, 0, 0),
            toggles: [false; 4],
            window: (t_from, t_to),
            error: None,
        })
    }

    /// Samples the world at `t` (call after every scheduler event).
    pub fn sample(&mut self, t: u64, w: &FirmwareWorld) {
        let ticks = w.fw.ticks();
        let (xe, ie) = w.stats().map_or((0, 0), |s| (s.x_events, s.index_events));
        let generation = w.fw.shared().coefficient_generation();
        let ran = [
            ticks != self.seen.0,
            xe != self.seen.1,
            ie != self.seen.2,
            generation != self.seen.3,
        ];
        self.seen = (ticks, xe, ie, generation);
        if t < self.window.0 || t >= self.window.1 || self.error.is_some() {
            return;
        }
        for (tg, r) in self.toggles.iter_mut().zip(ran) {
            *tg ^= r;
        }
        // Gauge codes to µin: 2^19 codes = 0.010 in.
        let uin = 0.010e6 / f64::from(1u32 << 19);
        let turn_deg = 360.0 / 4_294_967_296.0;
        let adc = w.rig.adc.state.borrow().code;
        let (x_true, x_fw, phi, phi_fw) = match &w.machine {
            Some(m) => {
                let st = &m.stats;
                let phase = m.spindle.borrow().model().config().index_phase_turns;
                let phi = (m.spindle.borrow_mut().turns_at(t) + phase).rem_euclid(1.0) * 360.0;
                (
                    w.x_true_in(),
                    st.x.map_or(f64::NAN, |x| x.to_f64()),
                    phi,
                    f64::from(st.angle.0) * turn_deg,
                )
            }
            None => (f64::NAN, f64::NAN, f64::NAN, f64::NAN),
        };
        let bit = |b: bool| if b { 1.0 } else { 0.0 };
        let v = [
            w.rig.slide.position_in() * 1e6,
            w.rig.slide.gauge_position_in() * 1e6,
            f64::from(w.fw.command_code()) * uin,
            f64::from(w.fw.command_code() - w.fw.position_code()) * uin,
            w.rig.slide.current_a(),
            w.rig.f_ext,
            f64::from(adc),
            f64::from(w.fw.output_code()),
            bit(w.rig.amp.enabled()),
            x_true,
            x_fw,
            phi,
            phi_fw,
            bit(self.toggles[0]),
            bit(self.toggles[1]),
            bit(self.toggles[2]),
            bit(self.toggles[3]),
            bit(w.fw.servo().phase() != Phase::Disarmed),
            bit(w.fw.fault().is_some()),
        ];
        if let Err(e) = self.rec.sample(t, &v) {
            self.error = Some(e);
        }
    }

    /// Flushes the dump; the first write error, if any.
    pub fn finish(self) -> std::io::Result<()> {
        if let Some(e) = self.error {
            return Err(e);
        }
        self.rec.finish()
    }
}

/// Installs a trace of `[t_from, t_to)` as the scheduler's observer; take
/// it back with [`detach`] after the run.
pub fn attach<W: Write + 'static>(
    s: &mut Scheduler<FirmwareWorld>,
    out: W,
    t_from: u64,
    t_to: u64,
) -> std::io::Result<Rc<RefCell<MachineTrace<W>>>> {
    let tr = Rc::new(RefCell::new(MachineTrace::new(out, t_from, t_to)?));
    let t2 = tr.clone();
    s.on_event = Some(Box::new(move |t, _k, w: &FirmwareWorld| {
        t2.borrow_mut().sample(t, w)
    }));
    Ok(tr)
}

/// Removes the observer and flushes the trace.
pub fn detach<W: Write + 'static>(
    s: &mut Scheduler<FirmwareWorld>,
    tr: Rc<RefCell<MachineTrace<W>>>,
) -> anyhow::Result<()> {
    s.on_event = None;
    match Rc::try_unwrap(tr) {
        Ok(t) => Ok(t.into_inner().finish()?),
        Err(_) => anyhow::bail!("VCD trace still shared"),
    }
}
