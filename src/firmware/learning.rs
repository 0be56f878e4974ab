//! The learning handler, one priority below the loop tick: it takes the
//! samples the loop tick handed over ([`crate::handoff`]'s learning ring)
//! and runs the spindle-synchronous learning on them (the hum notch on the
//! error, the update, the Q-filter: `servo::repetitive::Learner`) into the
//! shared learned table the loop tick reads its correction from. The
//! learning is the part of the loop that need not finish before the DAC
//! write: the table it writes is read a revolution later. Moving it out of
//! the loop tick keeps the tick's cost the same whether the learning runs
//! or not (`docs/BOARD.md`, interrupt cost). Then it evaluates the command
//! and the learned correction ahead of the next tick (`crate::command::expansion`, `crate::handoff::ahead`).
//!
//! The boards run [`LearnState::run`] after every loop tick (a software-
//! pended interrupt below the tick on the NUCLEO, the machine-event timer
//! on QEMU); `Firmware` runs it right after the tick.

use crate::command::expansion::{rate_step, Expansion};
use crate::command::{Coefficients, CommandGen};
use crate::handoff::ahead::Ahead;
use crate::handoff::Shared;
use crate::servo::edges::{contact_chord_uin, Edges};
use crate::servo::monitor::Monitor;
use crate::servo::{Learner, ServoConfig};
use crate::table::interrupt::Interruptions;
use crate::units::SpindleAngle;

/// State of the learning handler.
#[derive(Clone, Debug)]
pub struct LearnState {
    /// The command and the learned correction evaluated ahead of the next
    /// tick (`crate::command::expansion`, `crate::handoff::ahead`), run after the samples are applied, so that
    /// the correction is the one of the table the tick would have read
    /// (the samples' updates touch only bins a lead behind the angle,
    /// never the four it reads: `servo::repetitive`).
    ahead: AheadState,
    learner: Learner,
    /// Contour monitoring on the same samples (`servo::monitor`).
    monitor: Monitor,
    /// The ring's lost-sample count when last seen.
    lost_seen: u32,
    /// The nose's contact chord into the fresh stock, µin: the part
    /// program's depth of cut (`ServoConfig::depth_of_cut_uin`) under the
    /// table's nose (`Geometry::tool_radius_nin`; 0 without a table),
    /// computed once here, below the tick, for the edges' profile.
    contact_inside_uin: i64,
}

/// Whether a sample may teach the hole edges' step: the loop closed on a
/// live command, nothing freezing the learning.
fn edge_learning(s: &crate::servo::LearnSample) -> bool {
    s.freeze().is_none() && s.angle().is_some()
}

impl LearnState {
    pub(crate) fn new(
        cfg: &ServoConfig,
        gen: Option<CommandGen<'static>>,
        x_published: bool,
    ) -> Self {
        let nose_radius_nin = gen.map_or(0, |g| {
            g.interpolator().table().header().geometry.tool_radius_nin
        });
        let mut ahead = AheadState::new(gen, x_published);
        ahead.edge_feedforward = cfg.edge_feedforward;
        Self {
            ahead,
            learner: Learner::new(cfg),
            monitor: Monitor::new(cfg.monitor),
            lost_seen: 0,
            contact_inside_uin: contact_chord_uin(cfg.depth_of_cut_uin, nose_radius_nin),
        }
    }

    /// Applies every sample the loop tick has handed over since the last
    /// run, oldest first.
    ///
    /// Never inlined, so `cargo xtask isr-cost` can find and count it.
    #[inline(never)]
    pub fn run(&mut self, sh: &Shared) {
        let lost = sh.learn_queue().lost();
        if lost != self.lost_seen {
            // The tick dropped samples while this handler could not run: the
            // ring holds what came after the gap.
            self.lost_seen = lost;
            self.learner.lost_samples();
        }
        while let Some(s) = sh.learn_queue().pop() {
            self.learner.apply(&s, sh.learned());
            let mut over_hole = false;
            if let Some((phi, _)) = s.angle() {
                self.ahead
                    .edges
                    .learn(phi, s.disturbance_q8(), edge_learning(&s));
                over_hole = self.ahead.edges.over_hole(phi);
            }
            if s.requests().clears() {
                sh.lower_monitor();
            }
            if let Some(f) = self.monitor.sample(&s, over_hole) {
                sh.raise(f);
            }
        }
        // After the samples: the learned correction it expands is the
        // table the next tick would have read itself.
        let x_seen = self.ahead.coeff_seen;
        self.ahead.run(sh);
        if self.ahead.coeff_seen != x_seen {
            self.monitor.new_x();
        }
    }

    /// Contour monitoring's state.
    pub fn monitor(&self) -> &Monitor {
        &self.monitor
    }

    /// The evaluation ahead of the tick (the coefficients it holds).
    pub fn ahead(&self) -> &AheadState {
        &self.ahead
    }

    /// The learning's state (why it is frozen, revolutions learned).
    pub fn learner(&self) -> &Learner {
        &self.learner
    }

    /// The part's interruptions (a checked block: `Firmware::set_interruptions`).
    pub(crate) fn set_interruptions(&mut self, holes: Interruptions) {
        self.ahead.edges = Edges::new(holes, self.contact_inside_uin);
    }
}

/// State of the evaluation ahead of the tick (runs in the learning
/// handler, below the tick and, on the NUCLEO, below the X handlers).
#[derive(Clone, Debug)]
pub struct AheadState {
    gen: Option<CommandGen<'static>>,
    /// An X source publishes coefficients.
    x_published: bool,
    coeffs: Coefficients,
    coeff_seen: u32,
    /// The tick's angle request last evaluated.
    request_seen: u32,
    /// Expansions published (the hand-off's generation).
    published: u32,
    /// The hole edges' anticipation (`crate::servo::edges`): its profile
    /// follows the coefficients' X, its expectation goes with the command
    /// ahead.
    edges: Edges,
    /// Whether the edges' expectation is handed to the tick
    /// (`ServoConfig::edge_feedforward`; the step is learned either way).
    edge_feedforward: bool,
}

impl AheadState {
    pub(crate) fn new(gen: Option<CommandGen<'static>>, x_published: bool) -> Self {
        Self {
            gen,
            x_published,
            coeffs: Coefficients::NULL,
            coeff_seen: 0,
            request_seen: 0,
            published: 0,
            edges: Edges::new(Interruptions::NONE, 0),
            edge_feedforward: true,
        }
    }

    /// Takes a new coefficient set, evaluates the command at the angle the
    /// next tick is predicted to read (this tick's angle plus its step) and
    /// publishes it; nothing when the tick posted no new angle.
    #[inline(never)]
    pub fn run(&mut self, sh: &Shared) {
        if self.x_published {
            // A set overwritten while copied (an X handler preempting this
            // one, on the NUCLEO) is taken again: the next read finds the
            // newer set complete unless X events come microseconds apart.
            for _ in 0..3 {
                if let Ok(x) = sh
                    .coefficients()
                    .take(&mut self.coeff_seen, &mut self.coeffs)
                {
                    if let Some(x) = x {
                        self.edges.set_x(x);
                    }
                    break;
                }
            }
        }
        self.edges.refresh_step();
        let Some((tick, phi, dphi, alpha_q4)) = sh.ahead().request() else {
            return;
        };
        if tick == self.request_seen {
            return;
        }
        self.request_seen = tick;
        // The next tick predicted: this one's angle plus its step, the
        // same step and Δ²φ.
        let at = SpindleAngle(phi.wrapping_add(dphi as u32));
        let expansion = match &self.gen {
            Some(g) if !self.coeffs.null => Some(Expansion::direct(
                g,
                &self.coeffs,
                at,
                rate_step(dphi),
                alpha_q4,
            )),
            _ => None,
        };
        let correction = sh.learned().ahead(at, dphi);
        let edge_q8 = if self.edge_feedforward {
            self.edges
                .expected_q8(SpindleAngle(at.0.wrapping_add((dphi / 2) as u32)))
        } else {
            0
        };
        self.published = self.published.wrapping_add(1);
        sh.ahead().publish(
            self.published,
            &Ahead {
                tick: tick.wrapping_add(1),
                expansion,
                correction,
                edge_q8,
            },
        );
    }

    /// The coefficients this handler evaluates (the last set taken).
    pub fn coefficients(&self) -> &Coefficients {
        &self.coeffs
    }

    /// The hole edges' anticipation (its learned step).
    pub fn edges(&self) -> &Edges {
        &self.edges
    }
}
