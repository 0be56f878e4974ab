//! The rotary table (1-25 rpm) and its encoder with index, as the firmware
//! sees them: a count, the hardware timestamp of the count's last edge, and
//! the count latched at each index with its edge time (1 MHz capture clock).

/// Capture clock of the encoder timestamps, Hz.
pub const CLOCK_HZ: u32 = 1_000_000;

#[derive(Clone, Debug)]
pub struct Table {
    pub rpm: f64,
    pub counts_per_rev: u32,
    /// The table stops dead at this time (refusal tests), s.
    pub stop_at_s: Option<f64>,
    /// Angle at t = 0, turns.
    pub start_turns: f64,
}

/// Encoder state at an instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading {
    pub turns: f64,
    pub count: u32,
    pub edge_ticks: u32,
}

impl Table {
    fn turns_at(&self, t: f64) -> f64 {
        let t = self.stop_at_s.map_or(t, |s| t.min(s));
        self.start_turns + self.rpm / 60.0 * t
    }

    /// Time at which the table reached `turns` (it turns at constant speed).
    fn time_of(&self, turns: f64) -> f64 {
        (turns - self.start_turns) * 60.0 / self.rpm
    }

    pub fn read(&self, t: f64) -> Reading {
        let turns = self.turns_at(t);
        let c = (turns * f64::from(self.counts_per_rev)).floor();
        let edge = self.time_of(c / f64::from(self.counts_per_rev)).max(0.0);
        Reading {
            turns,
            count: c as i64 as u32,
            // The edge cannot be timestamped after the instant it is read at
            // (f64 rounding of the edge time could say so).
            edge_ticks: ticks(edge.min(t)),
        }
    }

    /// An index edge in (t0, t1]: the latched count and its edge time.
    pub fn index_between(&self, t0: f64, t1: f64) -> Option<(u32, u32)> {
        let (a, b) = (self.turns_at(t0), self.turns_at(t1));
        let k = b.floor();
        (k > a.floor()).then(|| {
            let c = (k * f64::from(self.counts_per_rev)) as i64 as u32;
            (c, ticks(self.time_of(k)))
        })
    }
}

/// Seconds to capture-clock ticks (nearest), wrapping as the 32-bit counter
/// does.
pub fn ticks(t: f64) -> u32 {
    (t * f64::from(CLOCK_HZ)).round() as i64 as u32
}
