//! The hardware the core needs, as traits. Boards implement them with timers
//! and GPIO; `host-sim` implements them against the plant model. Converter
//! chips are not here: their drivers (`drivers`) are generic over
//! embedded-hal 1.0 `SpiDevice` and `OutputPin`.

/// A free-running up-counter used for timestamps, wrapping at 2³².
///
/// Its rate is a board constant given to the consumers (`ticks_per_s`); the
/// core never assumes one. Differences of two readings are taken with
/// `wrapping_sub`, so wrap-around is harmless for intervals under 2³² ticks.
pub trait Clock {
    fn now_ticks(&mut self) -> u32;
}

/// One reading of an incremental encoder (spindle encoder, or the X
/// interferometer's quadrature count).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct EncoderSample {
    /// Accumulated count, wrapping. Up is the positive sense of the axis.
    pub count: u32,
    /// Clock ticks ([`Clock`]) at the most recent count edge, captured by
    /// hardware: the basis of 1/T interpolation between counts.
    pub edge_ticks: u32,
}

/// An incremental encoder read by polling from the loop tick.
pub trait Encoder {
    fn sample(&mut self) -> EncoderSample;
}

/// The legacy X interface of appendix A: the lines the 8080 read when the
/// half-mil interrupt fired. The board latches them at the interrupt edge.
///
/// Bit layout of [`XLatchWord`] (matches the 1983 latch, four BCD digits of
/// the interferometer's "d.dddd" display without the ten-thousandths digit):
///
/// | bits | meaning |
/// |---|---|
/// | 0..4 | thousandths digit (BCD) |
/// | 4..8 | hundredths digit (BCD) |
/// | 8..12 | tenths digit (BCD) |
/// | 12..16 | units digit (BCD) |
/// | 16 | half-mil flag: ten-thousandths digit is 5 |
/// | 17 | mil-zero flag: thousandths digit is 0 |
/// | 18..32 | zero |
pub trait XLatch {
    fn read(&mut self) -> XLatchWord;
}

/// Raw latched word of the legacy X interface; see [`XLatch`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct XLatchWord(pub u32);

impl XLatchWord {
    pub const HALF_MIL: u32 = 1 << 16;
    pub const MIL_ZERO: u32 = 1 << 17;
}

/// The legacy spindle tachometer: 5 V at 300 rpm (chapter 3), read by an ADC.
pub trait Tachometer {
    /// Tachometer voltage in millivolts, signed (positive = forward rotation).
    fn millivolts(&mut self) -> i32;
}

/// A converter did not answer, or answered with a frame that cannot be right.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct BusError;

/// One gauge conversion, as the ADC delivered it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct GaugeSample {
    /// 20-bit two's complement code, `2^19` = +10 V = +0.010 in at 1 V/mil.
    pub code: i32,
    /// The converter flagged its input as over range.
    pub overrange: bool,
}

/// The capacitance-gauge ADC, read once per loop tick (the conversion itself
/// is started by hardware on the loop timer, so its instant has no jitter).
pub trait GaugeAdc {
    fn read(&mut self) -> Result<GaugeSample, BusError>;
}

/// The DAC in front of the power amplifier.
pub trait AmplifierDac {
    /// Sets the output: 20-bit two's complement code, `2^19` = +10 V.
    fn write(&mut self, code: i32) -> Result<(), BusError>;
    /// Clamps the output to ground (the converter's own safe state).
    fn clamp_to_ground(&mut self) -> Result<(), BusError>;
    /// Releases that clamp at zero volts (the code is zeroed first, so the
    /// release cannot step the output), verified where the converter can
    /// be read back. After it, [`Self::write`] drives the output again.
    fn release_clamp(&mut self) -> Result<(), BusError>;
}

/// The quad coefficient DAC of the legacy coefficient-output mode (C00..C03
/// on channels A..D, Table 3-1 codes), with its simultaneous update.
pub trait CoefficientDac {
    /// Writes the channels in `update` (bit j = C0j), then one strobe that
    /// puts all four on the outputs at once.
    fn output(&mut self, codes: &[u16; 4], update: u8) -> Result<(), BusError>;
}
