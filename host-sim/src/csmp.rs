//! The CSMP loop studies of the dissertation's appendix C, solved exactly.
//!
//! Each appendix C program is a single loop: `ERR = R2 - Z`, a chain of CSMP
//! blocks from `ERR` to the slide velocity `SZ`, and `Z = INTGRL(0., SZ)`.
//! [`Diagram`] holds such a chain; [`Diagram::closed_loop`] turns it into one
//! linear state-space model from the reference `R2` to `Z`, and
//! [`Diagram::simulate`] solves it with the matrix exponential of the system
//! augmented by the input generator (STEP: one constant state; RAMP: two
//! states), so the printed values are the exact solution of the diagram to
//! rounding, not an integration-method artefact.
//!
//! Block conventions (CSMP/360, as the listings of appendix C use them):
//! `LEDLAG(a,b,x)` = (1+as)/(1+bs), `REALPL(ic,p,x)` = 1/(1+ps),
//! `CMPLXPL(ic1,ic2,ζ,ωn,x)` = 1/(s²+2ζωn s+ωn²) (no ωn² on top: the programs
//! multiply by `P2SQ` themselves), `STEP(0.)` = 1 for t ≥ 0, `RAMP(0.)` = t.
//! See `docs/CSMP.md` for each diagram as read from the OCR.

use nalgebra::{DMatrix, DVector, RowDVector};
use std::fmt;

/// One CSMP functional block with its parameters, in the order CSMP takes them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Block {
    /// `y = k x` (the programs' `ERK = KO*ERR`, `GP1 = KP*R1`, `*P2SQ`).
    Gain(f64),
    /// `LEDLAG(a, b, x)`: b y' + y = a x' + x, i.e. (1+as)/(1+bs).
    LedLag { a: f64, b: f64 },
    /// `REALPL(ic, p, x)`: p y' + y = x, y(0) = ic, i.e. 1/(1+ps).
    RealPole { ic: f64, p: f64 },
    /// `CMPLXPL(ic1, ic2, ζ, ωn, x)`: y'' + 2ζωn y' + ωn² y = x,
    /// y(0) = ic1, y'(0) = ic2.
    ComplexPole {
        ic1: f64,
        ic2: f64,
        zeta: f64,
        wn: f64,
    },
    /// `INTGRL(ic, x)`: y' = x, y(0) = ic.
    Integrator { ic: f64 },
}

/// The reference generator `R2` of a study.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Input {
    /// `STEP(0.)`: 1 for t ≥ 0 (so ERR(0) = 1).
    Step,
    /// `RAMP(0.)`: t for t ≥ 0.
    Ramp,
}

/// A CSMP model error: the diagram cannot be turned into a proper linear system.
#[derive(Clone, Debug, PartialEq)]
pub enum CsmpError {
    /// A block parameter is not finite or makes the block improper
    /// (e.g. `LEDLAG` with b = 0 and a ≠ 0, `REALPL` with p = 0).
    BadParameter { block: usize, what: &'static str },
    /// The forward path has a direct feedthrough, so `ERR = R2 - Z` would
    /// be an algebraic loop (CSMP would reject it too).
    AlgebraicLoop,
    /// The study name is not one of appendix C's.
    UnknownStudy(String),
}

impl fmt::Display for CsmpError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CsmpError::BadParameter { block, what } => {
                write!(f, "block {block} of the forward path: {what}")
            }
            CsmpError::AlgebraicLoop => write!(
                f,
                "the forward path ERR -> Z has a direct feedthrough (algebraic loop)"
            ),
            CsmpError::UnknownStudy(s) => write!(
                f,
                "unknown CSMP study {s:?}; valid studies are {}",
                STUDY_NAMES.join(", ")
            ),
        }
    }
}

impl std::error::Error for CsmpError {}

/// A linear single-input single-output state-space model x' = A x + B u,
/// y = C x + D u, with its initial state.
#[derive(Clone, Debug, PartialEq)]
pub struct StateSpace {
    pub a: DMatrix<f64>,
    pub b: DVector<f64>,
    pub c: RowDVector<f64>,
    pub d: f64,
    pub x0: DVector<f64>,
}

impl StateSpace {
    fn static_gain(k: f64) -> Self {
        StateSpace {
            a: DMatrix::zeros(0, 0),
            b: DVector::zeros(0),
            c: RowDVector::zeros(0),
            d: k,
            x0: DVector::zeros(0),
        }
    }

    /// Number of states.
    pub fn order(&self) -> usize {
        self.a.nrows()
    }

    /// The realisation of one block, written from its CSMP differential
    /// equation (not from a transfer function), so that initial conditions
    /// mean what they mean in CSMP.
    pub fn of_block(block: &Block, index: usize) -> Result<Self, CsmpError> {
        let bad = |what| Err(CsmpError::BadParameter { block: index, what });
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        match *block {
            Block::Gain(k) => {
                if !finite(&[k]) {
                    return bad("gain is not finite");
                }
                Ok(Self::static_gain(k))
            }
            Block::LedLag { a, b } => {
                if !finite(&[a, b]) {
                    return bad("LEDLAG time constant is not finite");
                }
                if b == 0.0 {
                    if a == 0.0 {
                        return Ok(Self::static_gain(1.0));
                    }
                    return bad("LEDLAG with b = 0 and a != 0 is not proper");
                }
                // CSMP's own form: y = (a/b) x + (1 - a/b) q with b q' + q = x.
                Ok(StateSpace {
                    a: DMatrix::from_element(1, 1, -1.0 / b),
                    b: DVector::from_element(1, 1.0 / b),
                    c: RowDVector::from_element(1, 1.0 - a / b),
                    d: a / b,
                    x0: DVector::zeros(1),
                })
            }
            Block::RealPole { ic, p } => {
                if !finite(&[ic, p]) {
                    return bad("REALPL parameter is not finite");
                }
                if p == 0.0 {
                    return bad("REALPL with p = 0");
                }
                Ok(StateSpace {
                    a: DMatrix::from_element(1, 1, -1.0 / p),
                    b: DVector::from_element(1, 1.0 / p),
                    c: RowDVector::from_element(1, 1.0),
                    d: 0.0,
                    x0: DVector::from_element(1, ic),
                })
            }
            Block::ComplexPole { ic1, ic2, zeta, wn } => {
                if !finite(&[ic1, ic2, zeta, wn]) {
                    return bad("CMPLXPL parameter is not finite");
                }
                Ok(StateSpace {
                    a: DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -wn * wn, -2.0 * zeta * wn]),
                    b: DVector::from_column_slice(&[0.0, 1.0]),
                    c: RowDVector::from_row_slice(&[1.0, 0.0]),
                    d: 0.0,
                    x0: DVector::from_column_slice(&[ic1, ic2]),
                })
            }
            Block::Integrator { ic } => {
                if !finite(&[ic]) {
                    return bad("INTGRL initial condition is not finite");
                }
                Ok(StateSpace {
                    a: DMatrix::zeros(1, 1),
                    b: DVector::from_element(1, 1.0),
                    c: RowDVector::from_element(1, 1.0),
                    d: 0.0,
                    x0: DVector::from_element(1, ic),
                })
            }
        }
    }

    /// `self` followed by `next` (the output of `self` drives `next`).
    pub fn then(&self, next: &StateSpace) -> StateSpace {
        let (n1, n2) = (self.order(), next.order());
        let n = n1 + n2;
        let mut a = DMatrix::zeros(n, n);
        a.view_mut((0, 0), (n1, n1)).copy_from(&self.a);
        a.view_mut((n1, n1), (n2, n2)).copy_from(&next.a);
        a.view_mut((n1, 0), (n2, n1))
            .copy_from(&(&next.b * &self.c));
        let mut b = DVector::zeros(n);
        b.rows_mut(0, n1).copy_from(&self.b);
        b.rows_mut(n1, n2).copy_from(&(&next.b * self.d));
        let mut c = RowDVector::zeros(n);
        c.columns_mut(0, n1).copy_from(&(&self.c * next.d));
        c.columns_mut(n1, n2).copy_from(&next.c);
        let mut x0 = DVector::zeros(n);
        x0.rows_mut(0, n1).copy_from(&self.x0);
        x0.rows_mut(n1, n2).copy_from(&next.x0);
        StateSpace {
            a,
            b,
            c,
            d: self.d * next.d,
            x0,
        }
    }
}

/// One appendix C program: `ERR = R2 - Z`, the forward blocks from `ERR` to
/// `Z` (the last one is `Z = INTGRL(...)`), and its `TIMER` card.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagram {
    pub input: Input,
    pub forward: Vec<Block>,
    /// `FINTIM`, s.
    pub fintim: f64,
    /// `OUTDEL` (print interval), s.
    pub outdel: f64,
}

/// One printed line: `t_s,z,err`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub t_s: f64,
    pub z: f64,
    pub err: f64,
}

impl Diagram {
    /// The forward path ERR -> Z as one state-space model.
    pub fn forward_path(&self) -> Result<StateSpace, CsmpError> {
        let mut ss = StateSpace::static_gain(1.0);
        for (i, blk) in self.forward.iter().enumerate() {
            ss = ss.then(&StateSpace::of_block(blk, i)?);
        }
        Ok(ss)
    }

    /// The closed loop R2 -> Z (unity negative feedback `ERR = R2 - Z`).
    pub fn closed_loop(&self) -> Result<StateSpace, CsmpError> {
        let g = self.forward_path()?;
        if g.d != 0.0 {
            return Err(CsmpError::AlgebraicLoop);
        }
        // u = r - C x  =>  x' = (A - B C) x + B r, z = C x.
        let a = &g.a - &g.b * &g.c;
        Ok(StateSpace { a, ..g })
    }

    /// The print times 0, OUTDEL, 2 OUTDEL, .. FINTIM (41 for appendix C).
    pub fn print_times(&self) -> Vec<f64> {
        let n = (self.fintim / self.outdel).round() as usize;
        // k / (1/OUTDEL) rather than k * OUTDEL: 1/0.001 is exactly 1000, so
        // the printed times are the decimal values CSMP printed.
        let per_s = (1.0 / self.outdel).round();
        if (per_s * self.outdel - 1.0).abs() < 1e-12 {
            (0..=n).map(|k| k as f64 / per_s).collect()
        } else {
            (0..=n).map(|k| k as f64 * self.outdel).collect()
        }
    }

    /// The exact response at the given times: `z` and `err = R2 - Z`.
    pub fn simulate(&self, times: &[f64]) -> Result<Vec<Sample>, CsmpError> {
        let cl = self.closed_loop()?;
        let n = cl.order();
        // Augment with the input generator so the input is a state too.
        let m_in = match self.input {
            Input::Step => 1,
            Input::Ramp => 2,
        };
        let na = n + m_in;
        let mut m = DMatrix::zeros(na, na);
        m.view_mut((0, 0), (n, n)).copy_from(&cl.a);
        // r is the first generator state.
        m.view_mut((0, n), (n, 1)).copy_from(&cl.b);
        let mut x0 = DVector::zeros(na);
        x0.rows_mut(0, n).copy_from(&cl.x0);
        match self.input {
            Input::Step => x0[n] = 1.0,
            Input::Ramp => {
                // r' = v, v' = 0, r(0) = 0, v(0) = 1.
                m[(n, n + 1)] = 1.0;
                x0[n + 1] = 1.0;
            }
        }
        // The states span many decades (a CMPLXPL state is ~1/ωn² of its
        // input); balancing first keeps the Padé error relative to each state.
        let (mb, scale) = balance(&m);
        let xb0 = DVector::from_iterator(na, (0..na).map(|i| x0[i] / scale[i]));
        Ok(times
            .iter()
            .map(|&t| {
                let xb = (&mb * t).exp() * &xb0;
                let x = DVector::from_iterator(na, (0..na).map(|i| xb[i] * scale[i]));
                let z = (&cl.c * x.rows(0, n))[(0, 0)];
                let r = x[n];
                Sample {
                    t_s: t,
                    z,
                    err: r - z,
                }
            })
            .collect())
    }

    /// The printed table of the program: the response at [`Self::print_times`].
    pub fn run(&self) -> Result<Vec<Sample>, CsmpError> {
        self.simulate(&self.print_times())
    }
}

/// Diagonal balancing by powers of two (the LAPACK `gebal` scaling step, no
/// permutation): returns `B = D⁻¹ M D` and the diagonal of `D`, so that
/// `exp(M t) = D exp(B t) D⁻¹` exactly (powers of two scale without rounding).
pub fn balance(m: &DMatrix<f64>) -> (DMatrix<f64>, Vec<f64>) {
    let n = m.nrows();
    let mut b = m.clone();
    let mut d = vec![1.0f64; n];
    let radix = 2.0f64;
    loop {
        let mut converged = true;
        for i in 0..n {
            let c: f64 = (0..n).filter(|&j| j != i).map(|j| b[(j, i)].abs()).sum();
            let r: f64 = (0..n).filter(|&j| j != i).map(|j| b[(i, j)].abs()).sum();
            if c == 0.0 || r == 0.0 {
                continue;
            }
            let s = c + r;
            let mut f = 1.0;
            let (mut cc, mut rr) = (c, r);
            while cc < rr / radix {
                cc *= radix;
                rr /= radix;
                f *= radix;
            }
            while cc >= rr * radix {
                cc /= radix;
                rr *= radix;
                f /= radix;
            }
            if cc + rr < 0.95 * s {
                converged = false;
                d[i] *= f;
                // B <- D_i⁻¹ B D_i: column i times f, row i divided by f.
                for j in 0..n {
                    b[(j, i)] *= f;
                    b[(i, j)] /= f;
                }
            }
        }
        if converged {
            return (b, d);
        }
    }
}

/// The appendix C studies, in order.
pub const STUDY_NAMES: [&str; 6] = ["C-1", "C-2", "C-3", "C-4", "C-5", "C-6"];

/// One appendix C study: its name, title and diagram.
#[derive(Clone, Debug, PartialEq)]
pub struct Study {
    pub name: &'static str,
    pub title: &'static str,
    pub diagram: Diagram,
}

/// `TIMER FINTIM=.040,OUTDEL=.001` of every appendix C program.
const FINTIM: f64 = 0.040;
const OUTDEL: f64 = 0.001;

/// C-1/C-2, first lag-compensated system (fig 4-13): closed velocity loop of
/// eq 4-38 under a lag compensator (corners 2.9 and 290 rad/s) and 38 dB.
fn first_lag(input: Input) -> Diagram {
    const K1: f64 = 419.14;
    const P1: f64 = 0.75988;
    const P2: f64 = 2663.668;
    const W1: f64 = 290.0;
    const W2: f64 = 2.9;
    const KO: f64 = 79.432;
    let p2sq = P2 * P2;
    Diagram {
        input,
        forward: vec![
            Block::Gain(KO), // ERK=KO*ERR
            Block::LedLag {
                a: 1.0 / W1,
                b: 1.0 / W2,
            }, // R1
            Block::ComplexPole {
                ic1: 0.0,
                ic2: 0.0,
                zeta: P1,
                wn: P2,
            }, // SZ1
            Block::Gain(K1 * p2sq), // SZ=K1*SZ1*P2SQ
            Block::Integrator { ic: 0.0 }, // Z
        ],
        fintim: FINTIM,
        outdel: OUTDEL,
    }
}

/// C-3/C-4, lead-lag compensated system without velocity feedback
/// (fig 4-15): eq 4-40 compensator, eq 4-39 plant, KO = 7.5 as run.
fn lead_lag(input: Input) -> Diagram {
    const P1: f64 = 302.5;
    const P2: f64 = 3808.0;
    const KP: f64 = 2582.0;
    const W1: f64 = 35.0;
    const W2: f64 = 1.0;
    const W3: f64 = 100.0;
    const W4: f64 = 3500.0;
    const KO: f64 = 7.5;
    Diagram {
        input,
        forward: vec![
            Block::Gain(KO), // ERK=ERR*KO
            Block::LedLag {
                a: 1.0 / W1,
                b: 1.0 / W2,
            }, // EGO1
            Block::LedLag {
                a: 1.0 / W3,
                b: 1.0 / W4,
            }, // R1
            Block::Gain(KP), // GP1=KP*R1
            Block::RealPole {
                ic: 0.0,
                p: 1.0 / P1,
            }, // GP2
            Block::RealPole {
                ic: 0.0,
                p: 1.0 / P2,
            }, // SZ
            Block::Integrator { ic: 0.0 }, // Z
        ],
        fintim: FINTIM,
        outdel: OUTDEL,
    }
}

/// C-5/C-6, final lag-compensated system: eq 4-45 compensator (KO = 6 is
/// the text's 12·Ko with Ko = 0.5) on the measured velocity loop of eq 4-44.
fn final_lag(input: Input) -> Diagram {
    const P1: f64 = 1162.4;
    const P2: f64 = 7634.1;
    const KP: f64 = 674.0;
    const W1: f64 = 4.16667;
    const W2: f64 = 0.378788;
    const W3: f64 = 3030.3;
    const KO: f64 = 6.0;
    Diagram {
        input,
        forward: vec![
            Block::Gain(KO), // ERK=ERR*KO
            Block::LedLag {
                a: 1.0 / W1,
                b: 1.0 / W2,
            }, // R11
            Block::RealPole {
                ic: 0.0,
                p: 1.0 / W3,
            }, // R1
            Block::Gain(KP), // GP1=KP*R1
            Block::RealPole {
                ic: 0.0,
                p: 1.0 / P1,
            }, // GP2
            Block::RealPole {
                ic: 0.0,
                p: 1.0 / P2,
            }, // SZ
            Block::Integrator { ic: 0.0 }, // Z
        ],
        fintim: FINTIM,
        outdel: OUTDEL,
    }
}

/// The study named `name` (`C-1` .. `C-6`; case-insensitive, the hyphen
/// optional).
pub fn study(name: &str) -> Result<Study, CsmpError> {
    let key: String = name
        .trim()
        .chars()
        .filter(|c| *c != '-')
        .collect::<String>()
        .to_ascii_uppercase();
    let (name, title, diagram) = match key.as_str() {
        "C1" => (
            "C-1",
            "Step input to first lag-compensated system",
            first_lag(Input::Step),
        ),
        "C2" => (
            "C-2",
            "Ramp input to first lag-compensated system",
            first_lag(Input::Ramp),
        ),
        "C3" => (
            "C-3",
            "Step input to lead-lag compensated system (no velocity feedback)",
            lead_lag(Input::Step),
        ),
        "C4" => (
            "C-4",
            "Ramp input to lead-lag compensated system (no velocity feedback)",
            lead_lag(Input::Ramp),
        ),
        "C5" => (
            "C-5",
            "Step input to final lag compensated system",
            final_lag(Input::Step),
        ),
        "C6" => (
            "C-6",
            "Ramp input to final lag compensated system",
            final_lag(Input::Ramp),
        ),
        _ => return Err(CsmpError::UnknownStudy(name.to_string())),
    };
    Ok(Study {
        name,
        title,
        diagram,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn balancing_is_an_exact_similarity() {
        let m = DMatrix::from_row_slice(3, 3, &[0.0, 1.0, 0.0, -7e6, -4e3, 3e9, 0.0, 0.0, -2.0]);
        let (b, d) = balance(&m);
        for i in 0..3 {
            for j in 0..3 {
                assert_eq!(b[(i, j)], m[(i, j)] * d[j] / d[i]);
            }
            assert_eq!(d[i], 2f64.powi(d[i].log2().round() as i32));
        }
    }

    #[test]
    fn ledlag_with_b_zero_is_rejected() {
        let d = Diagram {
            input: Input::Step,
            forward: vec![
                Block::LedLag { a: 1.0, b: 0.0 },
                Block::Integrator { ic: 0.0 },
            ],
            fintim: 0.04,
            outdel: 0.001,
        };
        assert!(matches!(
            d.closed_loop(),
            Err(CsmpError::BadParameter { block: 0, .. })
        ));
    }

    #[test]
    fn feedthrough_is_an_algebraic_loop() {
        let d = Diagram {
            input: Input::Step,
            forward: vec![Block::Gain(2.0)],
            fintim: 0.04,
            outdel: 0.001,
        };
        assert_eq!(d.closed_loop(), Err(CsmpError::AlgebraicLoop));
    }

    #[test]
    fn integrator_loop_is_first_order_lag() {
        // Z/R = k/(s+k): step z = 1 - e^{-kt}; ramp z = t - (1 - e^{-kt})/k.
        let k = 250.0;
        for input in [Input::Step, Input::Ramp] {
            let d = Diagram {
                input,
                forward: vec![Block::Gain(k), Block::Integrator { ic: 0.0 }],
                fintim: 0.04,
                outdel: 0.001,
            };
            for s in d.run().unwrap() {
                let e = (-k * s.t_s).exp();
                let want = match input {
                    Input::Step => 1.0 - e,
                    Input::Ramp => s.t_s - (1.0 - e) / k,
                };
                assert!((s.z - want).abs() < 1e-14, "{input:?} {s:?} {want}");
            }
        }
    }

    #[test]
    fn names_are_case_insensitive_and_unknown_names_list_the_valid_ones() {
        assert_eq!(study("c-3").unwrap().name, "C-3");
        assert_eq!(study("C6").unwrap().name, "C-6");
        let e = study("C-7").unwrap_err().to_string();
        for n in STUDY_NAMES {
            assert!(e.contains(n), "{e}");
        }
    }
}
