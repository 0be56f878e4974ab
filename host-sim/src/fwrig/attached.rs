//! The X slide and spindle attached to a world, as the firmware's
//! handlers see them, and what the handlers saw.

use crate::machine::hw::{
    SharedSpindle, SimSpindleEncoder, SimTachometer, SimXLatch, SimXQuadrature, XHalfMilLink,
};
use std::cell::RefCell;
use std::rc::Rc;
use zslide::safety::Fault;
use zslide::spindle::{EncoderAngle, TachAngle};
use zslide::units::{SpindleAngle, XInches};
use zslide::xpos::CountX;

/// What the X and spindle handlers saw (for tests and reports).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MachineStats {
    pub x_events: u64,
    pub x_accepted: u64,
    pub x_ignored: u64,
    pub x_faults: u64,
    /// Interrupts whose latch caught a ripple (model truth).
    pub x_stale: u64,
    pub index_events: u64,
    pub index_faults: u64,
    /// Last X the firmware knows.
    pub x: Option<XInches>,
    /// Spindle angle at the last loop tick.
    pub angle: SpindleAngle,
    pub referenced: bool,
    /// Last fault raised by an X or spindle handler.
    pub last_fault: Option<Fault>,
}

impl Machine {
    /// True X at `t_s` (feed profile, without vibration and jitter), in.
    pub fn x_true_in(&self, t_s: f64) -> f64 {
        match &self.x {
            XState::Legacy { link, .. } => link.borrow().model().nominal_x(t_s),
            XState::Count { enc, .. } => enc.model().nominal_x(t_s),
        }
    }
}

pub(super) enum XState {
    Legacy {
        link: Rc<RefCell<XHalfMilLink>>,
        latch: SimXLatch,
    },
    Count {
        enc: Box<SimXQuadrature>,
        decoder: CountX,
    },
}

pub(super) enum AngleState {
    Encoder {
        dev: SimSpindleEncoder,
        est: EncoderAngle,
    },
    Tach {
        dev: SimTachometer,
        est: TachAngle,
    },
}

/// X slide and spindle as the firmware sees them.
pub struct Machine {
    pub(super) x: XState,
    pub(super) angle: AngleState,
    pub spindle: SharedSpindle,
    pub stats: MachineStats,
    /// Run the monitor copy of the firmware's angle estimator (the
    /// stats' `angle`, `referenced` and index faults; on by default). A
    /// run that reads none of them turns it off: it costs as much as the
    /// firmware's own estimator (≈ 170 instructions a tick with an
    /// encoder).
    pub monitor: bool,
}
