//! VCD output of chosen simulator signals (positions, command, error, DAC
//! codes, interrupt activity) for GTKWave or PulseView.
//!
//! Signals are declared once (real values, integer codes of a given width,
//! or 1-bit lines) and then sampled with [`VcdRecorder::sample`]; only
//! changes are written. Timescale 1 ns, the simulator's time unit.
//!
//! Viewers: GTKWave (and its `vcd2fst`) reads every signal. libsigrok
//! (PulseView, `sigrok-cli -I vcd`, Debian's 0.5.2) reads only 1-bit
//! wires: it skips `real` variables, but a multi-bit `b…` vector change
//! makes it stop reading the rest of the chunk, losing the 1-bit lines
//! after it. So integer codes are declared `real` and written as exact
//! integers (a 20-bit code is exact in an f64): GTKWave shows them as
//! numbers (or analog), PulseView shows the 1-bit lines of the same file.

use std::io::Write;
use vcd::{IdCode, TimescaleUnit, Value, VarType};

/// Kind of a recorded signal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SignalKind {
    /// A real number (positions in µin, volts, amps).
    Real,
    /// A two's complement integer of `width` bits (DAC/ADC codes),
    /// written as a real-valued variable holding the integer (see the
    /// module doc: libsigrok reads no multi-bit vectors).
    Int(u32),
    /// A single wire (interrupt active, amplifier enabled).
    Bit,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Last {
    None,
    Real(f64),
    Int(i64),
}

pub struct VcdRecorder<W: Write> {
    w: vcd::Writer<W>,
    ids: Vec<(IdCode, SignalKind)>,
    last: Vec<Last>,
    last_t: Option<u64>,
}

impl<W: Write> VcdRecorder<W> {
    /// Writes the header for `signals` (name, kind) in module `scope`.
    pub fn new(out: W, scope: &str, signals: &[(&str, SignalKind)]) -> std::io::Result<Self> {
        let mut w = vcd::Writer::new(out);
        w.timescale(1, TimescaleUnit::NS)?;
        w.add_module(scope)?;
        let mut ids = Vec::new();
        for &(name, kind) in signals {
            let id = match kind {
                SignalKind::Real | SignalKind::Int(_) => {
                    w.add_var(VarType::Real, 64, name, None)?
                }
                SignalKind::Bit => w.add_wire(1, name)?,
            };
            ids.push((id, kind));
        }
        w.upscope()?;
        w.enddefinitions()?;
        Ok(Self {
            w,
            last: vec![Last::None; ids.len()],
            ids,
            last_t: None,
        })
    }

    /// Records the values at `t_ns` (one per signal, in declaration order;
    /// integers and bits as `f64` holding an integer). Unchanged values are
    /// not written.
    pub fn sample(&mut self, t_ns: u64, values: &[f64]) -> std::io::Result<()> {
        let mut stamped = false;
        for (k, (&(id, kind), &v)) in self.ids.iter().zip(values).enumerate() {
            let new = match kind {
                SignalKind::Real => Last::Real(v),
                _ => Last::Int(v as i64),
            };
            // Bit equality, so that an unknown (NaN) value is written once,
            // not at every sample.
            let same = match (self.last[k], new) {
                (Last::Real(a), Last::Real(b)) => a.to_bits() == b.to_bits(),
                (a, b) => a == b,
            };
            if same {
                continue;
            }
            if !stamped && self.last_t != Some(t_ns) {
                self.w.timestamp(t_ns)?;
                self.last_t = Some(t_ns);
            }
            stamped = true;
            match (kind, new) {
                (SignalKind::Real, Last::Real(x)) => self.w.change_real(id, x)?,
                (SignalKind::Bit, Last::Int(b)) => self
                    .w
                    .change_scalar(id, if b != 0 { Value::V1 } else { Value::V0 })?,
                (SignalKind::Int(width), Last::Int(x)) => {
                    // Two's complement of `width` bits, as the converter
                    // holds it; exact in an f64 up to 53 bits.
                    let w = width.clamp(1, 53);
                    let x = (x << (64 - w)) >> (64 - w);
                    self.w.change_real(id, x as f64)?
                }
                _ => {}
            }
            self.last[k] = new;
        }
        Ok(())
    }

    /// Flushes the dump (pass `&mut Vec<u8>` or a buffered file as `W`).
    pub fn finish(mut self) -> std::io::Result<()> {
        self.w.flush()
    }
}

pub mod machine;
pub mod target;
