//! The full inertia tensor `J` in the sensor frame, with a known rotor momentum as an input.
//!
//! # Model
//!
//! Euler's equation of a rigid body carrying rotors of known angular momentum `h(t)` (rotor
//! inertia times speed along the rotor axis, summed over rotors), torque-free:
//!
//! ```text
//! J w' + w x (J w + h) = 0                                                      (T1)
//! ```
//!
//! is linear in the six entries `j = (Jxx, Jyy, Jzz, Jxy, Jxz, Jyz)`. Integrated from the
//! start `t0` of a stretch of data to every later sample `t` it needs no derivative of the
//! gyro:
//!
//! ```text
//! J w(t) + h(t) + integral_t0^t w x (J w + h) dt = c                            (T2)
//! ```
//!
//! with `c = J w(t0) + h(t0)` the body-frame angular momentum at `t0`, an unknown constant per
//! stretch (the intercept). `w x J w` is linear in `j` with coefficients that are integrals of
//! the six products `w_a w_b`, so (T2) reads, per sample and per axis `r`:
//!
//! ```text
//! P_r(t) . j - c_r = y_r(t),      y(t) = -(h(t) + integral w x h dt)            (T3)
//! P_x = (wx, -Qyz, Qyz, wy - Qxz, wz + Qxy, Qyy - Qzz)
//! P_y = (Qxz, wy, -Qxz, wx + Qyz, Qzz - Qxx, wz - Qxy)
//! P_z = (-Qxy, Qxy, wz, Qxx - Qyy, wx - Qyz, wy + Qxz)
//! Q_ab(t) = integral_t0^t w_a w_b dt   (trapezoid with the Euler-Maclaurin end correction)
//! ```
//!
//! # Estimator
//!
//! One information matrix over all three axes and all six entries (a joint least-squares fit,
//! not three filters). Per sample the estimator adds the outer products of the rows (T3),
//! kept per axis so that a weight per axis can be applied later; the intercept `c` of a stretch
//! is eliminated exactly (Schur complement of its block, which is diagonal) when the stretch
//! closes. The three axes' rows are weighted equally: the residual of (T3) is `J n(t)` plus the
//! integrals' noise, which mixes all three axes into every row (weighting each axis by the
//! white part alone, `1 / (J J^T)_rr`, made the reported standard deviation several times too
//! small). A stretch closes at a gap, a saturated or bad
//! sample, an external [`TensorEstimator::end_stretch`] (release, catch), or when the integral's
//! own noise, which grows like `sigma^2 sum dt^2 |w|^2`, reaches
//! [`TensorSettings::stretch_noise`] times the white noise (the integral's noise is correlated
//! from sample to sample; a new stretch starts it afresh).
//!
//! Solutions (all from the same information, [`TensorEstimator::estimate`]):
//! - with a rotor momentum that carries information, `J` in kg m^2 from `Lambda j = eta`;
//! - always, `J` up to scale, normalised to trace 1: the equations without `h` under
//!   `Jxx + Jyy + Jzz = 1` (five free entries);
//! - the principal-axis model (products of inertia zero) is used instead of the full tensor
//!   when a Wald test finds the three products of inertia jointly insignificant
//!   (chi-square with 3 degrees of freedom below [`TensorSettings::products_chi2`]);
//! - standard deviations from the inverse information times the residual variance per
//!   equation, floored at the gyro noise;
//! - principal moments and axes ([`crate::symmetric::eigen_symmetric3`]), the paper's ratios
//!   `a1 = (A2 - A3)/A1, ...` with the principal moments assigned to the sensor axes they lie
//!   closest to, and their standard deviations by first-order propagation
//!   (`d lambda_i = v_i^T dJ v_i`).

// Loop indices below are bounded by the fixed array sizes; the link-time no-panic check
// (scripts/check-no-panic.sh) proves no bounds check survives in the firmware build.
#![allow(
    clippy::indexing_slicing,
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord
)]

use crate::status::{SampleStatus, Status};
use crate::symmetric::{cholesky, cholesky_inverse, cholesky_solve, eigen_symmetric3, sqrt, Sym};

/// Samples summed in `f32` before they are added to the stretch's sums (two-level summation
/// keeps the rounding error of long stretches near that of `BLOCK + n / BLOCK` additions).
const BLOCK: u16 = 64;

/// Tuning of [`TensorEstimator`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TensorSettings {
    /// Gyro white noise per sample, rad/s: the floor of the residual's standard deviation.
    /// Must be finite and `> 0`.
    pub noise_std: f32,
    /// Gyro full scale, rad/s: a sample with any component at or beyond it is saturated and
    /// ends the stretch (a clipped rate breaks the integral). `INFINITY` for none.
    pub full_scale: f32,
    /// Rates above this (rad/s) are not physical for a thrown or tumbling vehicle: the data
    /// are taken to be in the wrong unit (deg/s) and the estimate is never trusted.
    pub max_plausible_rate: f32,
    /// Longest time step still integrated, s; a longer one starts a new stretch.
    pub max_dt: f32,
    /// Ratio of the integral's noise to the gyro's white noise at which a stretch is closed
    /// and a new one started (see the module docs). `> 0`.
    pub stretch_noise: f32,
    /// Largest standard deviation of every `a_i` (and relative standard deviation of every
    /// principal moment) for [`Status::Converged`].
    pub tolerance: f32,
    /// Fewest samples used before any estimate is given.
    pub min_samples: u32,
    /// Chi-square (3 degrees of freedom) below which the products of inertia are taken as zero
    /// (21.11: 0.01 % false-alarm rate). `0` forces the full tensor, `INFINITY` the
    /// principal-axis model. The two errors cost differently: a false alarm on a principal body
    /// makes the pipeline report the full tensor's `a`, several times less precise than the
    /// principal-axis ratio fit's (one such flight, an `a` many bounds off, shows in a scenario's
    /// RMS error; at 0.01 % they are rare enough that the RMS stays the constrained maximum
    /// likelihood's own, `scripts/bench-estimators.sh`), while products just below the threshold
    /// are at most 4.6 of their standard deviations.
    pub products_chi2: f32,
    /// Residual standard deviation over the gyro noise beyond which the model does not describe
    /// the data (wrong time step, contact, thrust): [`Status::ModelMismatch`].
    pub mismatch_ratio: f32,
    /// Least [`TensorEstimate::excitation`] for an estimate to be given at all (below it:
    /// [`Status::NoExcitation`]). Pure gyro noise gives about 1.
    pub min_excitation: f32,
    /// Quantum of the rotor momentum as it is read, kg m^2/s: the rotor inertia times the
    /// speed telemetry's step (DShot eRPM: 100 eRPM, `100 / (poles / 2) * 2 pi / 60` rad/s).
    /// The output-error fit's absolute tensor then fits the reading's constant error over each
    /// steady run of the speed as an offset of the momentum ((F7) of
    /// `tensor_fit`) and counts its error elsewhere (along the ramps) in the
    /// covariance ((F8)). `0` takes the momentum as exact.
    pub momentum_resolution: f32,
}

impl TensorSettings {
    /// Defaults: `noise_std = 2e-3 rad/s`, no full scale, 75 rad/s plausible (beyond the widest MEMS gyro range, 4000 deg/s = 70 rad/s), `max_dt = 0.1 s`,
    /// `stretch_noise = 1`, `tolerance = 0.01`, 200 samples, `products_chi2 = 21.11`,
    /// `mismatch_ratio = 30`, `min_excitation = 100`, `momentum_resolution = 0`.
    pub const fn new() -> Self {
        TensorSettings {
            noise_std: 2e-3,
            full_scale: f32::INFINITY,
            max_plausible_rate: 75.0,
            max_dt: 0.1,
            stretch_noise: 1.0,
            tolerance: 0.01,
            min_samples: 200,
            products_chi2: 21.11,
            mismatch_ratio: 30.0,
            min_excitation: 100.0,
            momentum_resolution: 0.0,
        }
    }

    /// Settings for a gyro sampled at `rate_hz` with white noise `noise_std` (rad/s per
    /// sample): the longest step is ten sample periods (a satellite's 1 Hz gyro included; a
    /// step that turns the body by more than [`MAX_STEP_TURN_RAD`] is a gap too, whatever the
    /// rate, so a log whose time unit is wrong still shows its gaps); at least 50 ms of
    /// samples (20 to 200) before an estimate; everything else is rate-independent. Invalid
    /// inputs give settings that [`TensorEstimator::new`] refuses.
    pub fn for_rate(rate_hz: f32, noise_std: f32) -> Self {
        let mut s = Self::new();
        s.noise_std = noise_std;
        s.max_dt = 10.0 / rate_hz;
        // 50 ms of samples, between 20 and 200: a 0.85 s toss at 100 Hz has 85.
        let n = rate_hz * 0.05;
        s.min_samples = if n >= 200.0 {
            200
        } else if n >= 20.0 {
            n as u32
        } else {
            20
        };
        s
    }

    /// True when every field is usable.
    pub fn is_valid(&self) -> bool {
        let pos = |x: f32| x.is_finite() && x > 0.0;
        pos(self.noise_std)
            && !self.full_scale.is_nan()
            && self.full_scale > 0.0
            && !self.max_plausible_rate.is_nan()
            && self.max_plausible_rate > 0.0
            && pos(self.max_dt)
            && pos(self.stretch_noise)
            && pos(self.tolerance)
            && !self.products_chi2.is_nan()
            && self.products_chi2 >= 0.0
            && pos(self.mismatch_ratio)
            && pos(self.min_excitation)
            && self.momentum_resolution.is_finite()
            && self.momentum_resolution >= 0.0
    }
}

impl Default for TensorSettings {
    fn default() -> Self {
        Self::new()
    }
}

/// The output-error fit's residual over the gyro's noise up to which the fit is taken to
/// explain the data to the noise: beyond it the estimate is at most
/// [`Status::ModelMismatch`] (with an exact momentum: a rotor read in steps leaves its
/// reading's error too, see [`TensorSettings::momentum_resolution`]). A fit of the right model
/// leaves the noise itself, up to
/// the noise estimate's own error (a few tens of percent on short or slow logs); a gyro that
/// truncates its readings or whose bias walks leaves half as much again.
pub const OUTPUT_ERROR_FIT_RATIO: f32 = 1.5;

/// The most a body may turn between two samples, rad (`|w|_1 dt`), for the step to be
/// integrated: a longer step is a gap ([`Status::UnitsLookWrong`] when more than a tenth
/// of the steps are). A time unit read wrong (ms as s) turns a thrown body by radians per
/// step; a satellite's 1 Hz gyro at 0.5 rad/s turns it by half of one.
pub const MAX_STEP_TURN_RAD: f32 = 1.0;

/// Which model the estimate uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TensorModel {
    /// Six entries, products of inertia included.
    Full,
    /// Products of inertia fixed at zero (sensor axes taken as principal axes).
    Principal,
}

/// What [`TensorEstimator::estimate`] reports. Tensors are 3x3, rows and columns in the
/// sensor's axis order.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TensorEstimate {
    /// Why the estimate is or is not to be trusted.
    pub status: Status,
    /// Model used.
    pub model: TensorModel,
    /// `J` in kg m^2 when the rotor momentum determines the scale (relative standard
    /// deviation of the trace below 10 %), else `None`.
    pub tensor: Option<[[f32; 3]; 3]>,
    /// Standard deviation of each entry of [`TensorEstimate::tensor`].
    pub tensor_std: Option<[[f32; 3]; 3]>,
    /// Covariance of the entries `(Jxx, Jyy, Jzz, Jxy, Jxz, Jyz)` of
    /// [`TensorEstimate::tensor`], (kg m^2)^2: what a function of several entries (a principal
    /// moment, a difference of two bodies) needs, since their errors are correlated (the
    /// rotor momentum fixes one scale for all of them).
    pub tensor_cov: Option<[[f32; 6]; 6]>,
    /// `J / trace(J)`, `None` before there is information.
    pub normalized: Option<[[f32; 3]; 3]>,
    /// Standard deviation of each entry of [`TensorEstimate::normalized`].
    pub normalized_std: Option<[[f32; 3]; 3]>,
    /// Principal moments, ascending (kg m^2 when `tensor` is given, else normalised).
    pub principal_moments: Option<[f32; 3]>,
    /// Unit principal axes in the sensor frame, `principal_axes[i]` for moment `i`.
    pub principal_axes: Option<[[f32; 3]; 3]>,
    /// The paper's `a = ((A2-A3)/A1, (A3-A1)/A2, (A1-A2)/A3)`, `A_k` the principal moment
    /// closest to sensor axis `k`.
    pub a: Option<[f32; 3]>,
    /// Standard deviation of each `a_i`.
    pub std_a: Option<[f32; 3]>,
    /// Residual standard deviation per equation over the gyro noise (about 1 when the model
    /// fits to the noise).
    pub residual_ratio: f32,
    /// Excitation: the information per equation about the least determined entry over the
    /// gyro noise variance, `1 / (sigma^2 m max_i (Lambda^-1)_ii)` for `m` equations. Motion
    /// much larger than the noise gives thousands; a still gyro gives about 1.
    pub excitation: f32,
    /// Samples used.
    pub samples: u32,
    /// Stretches closed so far (plus the open one).
    pub stretches: u32,
    /// Which estimator gave the tensor.
    pub method: TensorMethod,
    /// Where the standard deviations come from, and so whether they count what the residual
    /// shows.
    pub uncertainty: Uncertainty,
    /// The tensor determines a rigid body's inertia: every principal moment more than three
    /// of its standard deviations above zero, and `l0 + l1 - l2` (ascending) not below minus
    /// three of its own, the test of [`Status::PhysicallyImpossible`] made whatever the
    /// status says (a residual beyond the noise says `ModelMismatch` first). False before
    /// there is a tensor.
    pub determined: bool,
}

/// Where a [`TensorEstimate`]'s standard deviations come from. With the status it says how
/// far the estimate is to be used: `Converged` with [`Uncertainty::Noise`] fits to the gyro's
/// noise; `ModelMismatch` with [`Uncertainty::Residual`] fits to its stated uncertainty (the
/// model lacks an effect, and the standard deviations count the error it leaves); any other
/// `ModelMismatch` is indicative only.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Uncertainty {
    /// The gyro's white noise: the residual is the noise's, and the covariance is the inverse
    /// information times its variance (the Cramer-Rao bound of white noise).
    Noise,
    /// The residual actually seen, its level and its correlation: the output-error fit's
    /// covariance inflated by the sandwich of its scores ((F10) of [`crate::TensorFit`]),
    /// multiple shooting's over its segments ((F11)), never below the walk of the output's
    /// ((F14)).
    Residual,
    /// An error the standard deviations do not count: the per-sample equation error scaled by
    /// its residual's level alone (a coloured residual claims more information than the
    /// flight holds), or a model error another test found (a torque, a body that is not
    /// rigid, a gyro bias the model lacks).
    Unaccounted,
}

impl Uncertainty {
    /// Whether an estimate of status `status` and this uncertainty is to be used with its
    /// standard deviations: `Converged`, or `ModelMismatch` with [`Uncertainty::Residual`].
    ///
    /// ```
    /// use identifier_core::{Status, Uncertainty};
    /// // A flight the model does not explain, its covariance from the residual seen.
    /// assert!(Uncertainty::Residual.usable(Status::ModelMismatch));
    /// // The same status where the standard deviations do not count the mismatch.
    /// assert!(!Uncertainty::Unaccounted.usable(Status::ModelMismatch));
    /// assert!(!Uncertainty::Noise.usable(Status::ModelMismatch));
    /// // Whatever the uncertainty, a clipped throw or one still converging is not.
    /// assert!(!Uncertainty::Residual.usable(Status::Saturated));
    /// assert!(!Uncertainty::Residual.usable(Status::Converging));
    /// assert!(Uncertainty::Noise.usable(Status::Converged));
    /// ```
    pub const fn usable(self, status: Status) -> bool {
        matches!(
            (status, self),
            (Status::Converged, _) | (Status::ModelMismatch, Uncertainty::Residual)
        )
    }
}

impl TensorEstimate {
    /// Whether the tensor is to be used with its standard deviations:
    /// [`Uncertainty::usable`] of its status, and a rigid body's inertia determined
    /// ([`TensorEstimate::determined`]: a fit that does not fit to the noise can follow a
    /// hand's motion to a tensor its standard deviations say nothing about).
    pub fn usable(&self) -> bool {
        self.uncertainty.usable(self.status) && self.determined
    }
}

/// Which estimator gave a [`TensorEstimate`]'s tensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TensorMethod {
    /// [`TensorEstimator`]: Euler's equation integrated per stretch, least squares, updated
    /// with every sample.
    EquationError,
    /// [`crate::TensorFit`]: the trajectory fitted to the gyro once a flight has ended
    /// (efficient for white gyro noise), described by [`TensorEstimator::with_tensor`].
    OutputError,
}

/// Counters for diagnosis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TensorCounters {
    /// Samples added to the sums.
    pub used: u32,
    /// Samples refused as non-finite.
    pub non_finite: u32,
    /// Samples at or beyond the full scale.
    pub saturated: u32,
    /// Samples with a zero, negative or non-finite time step.
    pub bad_dt: u32,
    /// Gaps longer than `max_dt`.
    pub gaps: u32,
    /// Samples faster than the plausible rate.
    pub implausible: u32,
}

/// Entries kept of one axis's row (T3): in every row one entry is exactly minus another (x:
/// Jyy's coefficient `-Qyz` is minus Jzz's `Qyz`; y: Jzz's `-Qxz` minus Jxx's; z: Jxx's `-Qxy`
/// minus Jyy's), so only five are summed per sample, which takes the outer product from 21
/// to 15 multiply-adds per axis. [`RowSums::expanded`] gives back the six-entry sums; negation
/// is exact in floating point, so they are, to the bit, the sums of the six-entry rows.
const KEPT: usize = 5;

/// Per axis and per entry `i` of the six-entry row: which kept entry it is and whether it is
/// negated (see [`KEPT`]).
const EXPAND: [[(usize, bool); 6]; 3] = [
    [
        (0, false),
        (1, true),
        (1, false),
        (2, false),
        (3, false),
        (4, false),
    ],
    [
        (0, false),
        (1, false),
        (0, true),
        (2, false),
        (3, false),
        (4, false),
    ],
    [
        (0, true),
        (0, false),
        (1, false),
        (2, false),
        (3, false),
        (4, false),
    ],
];

/// Position of `(i, j)`, `i <= j`, in an upper triangle of order `n` stored by rows.
const fn upper(n: usize, i: usize, j: usize) -> usize {
    i * n - i * (i + 1) / 2 + j
}

/// Sums of one axis's rows (T3) over samples, relative to the stretch's first row
/// (`dP = P - P0`, `dy = y - y0`: the intercept absorbs the shift and the sums stay small),
/// over the [`KEPT`] entries of the row.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct RowSums {
    pp: [f32; 15],
    p: [f32; KEPT],
    py: [f32; KEPT],
    y: f32,
    yy: f32,
}

/// The sums of the six-entry rows of one axis, from [`RowSums::expanded`].
struct FullRowSums {
    pp: [f32; 21],
    p: [f32; 6],
    py: [f32; 6],
    y: f32,
    yy: f32,
}

impl RowSums {
    const ZERO: RowSums = RowSums {
        pp: [0.0; 15],
        p: [0.0; KEPT],
        py: [0.0; KEPT],
        y: 0.0,
        yy: 0.0,
    };

    /// Adds one row: `pp += d d^T` (upper triangle by rows), `p += d`, `py += d dy`, `y += dy`,
    /// `yy += dy^2`. Written out term by term: this runs three times per sample, and the
    /// firmware's link-time optimisation (at opt-level "s") does not unroll the loops it was
    /// written as (the tensor step cost 1 149 instructions there against 732 at opt-level 3).
    #[inline(always)]
    fn add(&mut self, d: &[f32; KEPT], dy: f32) {
        let [d0, d1, d2, d3, d4] = *d;
        let [p00, p01, p02, p03, p04, p11, p12, p13, p14, p22, p23, p24, p33, p34, p44] =
            &mut self.pp;
        *p00 += d0 * d0;
        *p01 += d0 * d1;
        *p02 += d0 * d2;
        *p03 += d0 * d3;
        *p04 += d0 * d4;
        *p11 += d1 * d1;
        *p12 += d1 * d2;
        *p13 += d1 * d3;
        *p14 += d1 * d4;
        *p22 += d2 * d2;
        *p23 += d2 * d3;
        *p24 += d2 * d4;
        *p33 += d3 * d3;
        *p34 += d3 * d4;
        *p44 += d4 * d4;
        let [s0, s1, s2, s3, s4] = &mut self.p;
        *s0 += d0;
        *s1 += d1;
        *s2 += d2;
        *s3 += d3;
        *s4 += d4;
        let [y0, y1, y2, y3, y4] = &mut self.py;
        *y0 += d0 * dy;
        *y1 += d1 * dy;
        *y2 += d2 * dy;
        *y3 += d3 * dy;
        *y4 += d4 * dy;
        self.y += dy;
        self.yy += dy * dy;
    }

    fn absorb(&mut self, o: &RowSums) {
        for (a, b) in self.pp.iter_mut().zip(o.pp.iter()) {
            *a += b;
        }
        for (a, b) in self.p.iter_mut().zip(o.p.iter()) {
            *a += b;
        }
        for (a, b) in self.py.iter_mut().zip(o.py.iter()) {
            *a += b;
        }
        self.y += o.y;
        self.yy += o.yy;
    }

    /// The sums of axis `axis`'s six-entry rows: entry `i` is kept entry `k` or its negative
    /// ([`EXPAND`]), so `sum P_i P_j = s_i s_j sum d_k d_l` with signs `s = +-1`.
    fn expanded(&self, axis: usize) -> FullRowSums {
        let (vec, outer) = match axis {
            0 => (&EXPAND[0], &EXPAND_OUTER[0]),
            1 => (&EXPAND[1], &EXPAND_OUTER[1]),
            _ => (&EXPAND[2], &EXPAND_OUTER[2]),
        };
        let pick = |v: &[f32], (k, neg): (usize, bool)| {
            let x = v.get(k).copied().unwrap_or(0.0);
            if neg {
                -x
            } else {
                x
            }
        };
        FullRowSums {
            pp: outer.map(|m| pick(&self.pp, m)),
            p: vec.map(|m| pick(&self.p, m)),
            py: vec.map(|m| pick(&self.py, m)),
            y: self.y,
            yy: self.yy,
        }
    }
}

/// [`EXPAND`] for the upper triangle of the outer product: per axis and per entry `(i, j)`,
/// `i <= j`, of the six-entry triangle, the entry of the kept triangle and whether it is negated.
const EXPAND_OUTER: [[(usize, bool); 21]; 3] = [
    expand_outer(&EXPAND[0]),
    expand_outer(&EXPAND[1]),
    expand_outer(&EXPAND[2]),
];

const fn expand_outer(map: &[(usize, bool); 6]) -> [(usize, bool); 21] {
    let mut out = [(0, false); 21];
    let mut i = 0;
    while i < 6 {
        let mut j = i;
        while j < 6 {
            let ((ki, ni), (kj, nj)) = (map[i], map[j]);
            let (lo, hi) = if ki <= kj { (ki, kj) } else { (kj, ki) };
            out[upper(6, i, j)] = (upper(KEPT, lo, hi), ni != nj);
            j += 1;
        }
        i += 1;
    }
    out
}

/// Normal equations `Lambda j = eta` with `yy = sum w y^2` and the number of equations.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Normal {
    lam: [f32; 21],
    eta: [f32; 6],
    yy: f32,
    equations: u32,
}

impl Normal {
    const ZERO: Normal = Normal {
        lam: [0.0; 21],
        eta: [0.0; 6],
        yy: 0.0,
        equations: 0,
    };

    /// Adds one stretch's rows of axis `r` with weight `w`, its intercept eliminated:
    /// `Lambda += w (sum dP dP^T - s s^T / n)`, `eta += w (sum dP dy - s sum dy / n)`.
    fn add_stretch(&mut self, rows: &FullRowSums, n: f32, w: f32) {
        let inv_n = 1.0 / n;
        let mut k = 0;
        for i in 0..6 {
            let si = rows.p.get(i).copied().unwrap_or(0.0);
            for j in i..6 {
                let sj = rows.p.get(j).copied().unwrap_or(0.0);
                if let (Some(l), Some(pp)) = (self.lam.get_mut(k), rows.pp.get(k)) {
                    *l += w * (pp - si * sj * inv_n);
                }
                k += 1;
            }
        }
        for ((e, py), s) in self.eta.iter_mut().zip(rows.py.iter()).zip(rows.p.iter()) {
            *e += w * (py - s * rows.y * inv_n);
        }
        self.yy += w * (rows.yy - rows.y * rows.y * inv_n);
    }

    fn add(&mut self, o: &Normal) {
        for (a, b) in self.lam.iter_mut().zip(o.lam.iter()) {
            *a += b;
        }
        for (a, b) in self.eta.iter_mut().zip(o.eta.iter()) {
            *a += b;
        }
        self.yy += o.yy;
        self.equations += o.equations;
    }

    fn full(&self) -> Sym<6> {
        let mut m = [[0.0f32; 6]; 6];
        let mut k = 0;
        for i in 0..6 {
            for j in i..6 {
                let v = self.lam.get(k).copied().unwrap_or(0.0);
                if let Some(e) = m.get_mut(i).and_then(|r| r.get_mut(j)) {
                    *e = v;
                }
                if let Some(e) = m.get_mut(j).and_then(|r| r.get_mut(i)) {
                    *e = v;
                }
                k += 1;
            }
        }
        m
    }
}

/// The open stretch: integrals, reference row and sums.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Stretch {
    /// Previous accepted sample `(w, h)`, `None` before the anchor.
    last: Option<([f32; 3], [f32; 3])>,
    /// `Q_ab`: xx, yy, zz, xy, xz, yz.
    q: [f32; 6],
    /// `integral w x h dt`.
    wh: [f32; 3],
    /// Rows and right-hand side at the anchor.
    p0: [[f32; KEPT]; 3],
    y0: [f32; 3],
    /// `sum dt^2 |w|^2`, the integral's noise variance over `sigma^2`.
    drift: f32,
    n: u32,
    block_n: u16,
    block: [RowSums; 3],
    sums: [RowSums; 3],
}

impl Stretch {
    const EMPTY: Stretch = Stretch {
        last: None,
        q: [0.0; 6],
        wh: [0.0; 3],
        p0: [[0.0; KEPT]; 3],
        y0: [0.0; 3],
        drift: 0.0,
        n: 0,
        block_n: 0,
        block: [RowSums::ZERO; 3],
        sums: [RowSums::ZERO; 3],
    };

    fn flush_block(&mut self) {
        for (s, b) in self.sums.iter_mut().zip(self.block.iter_mut()) {
            s.absorb(b);
            *b = RowSums::ZERO;
        }
        self.block_n = 0;
    }
}

/// The [`KEPT`] entries of the rows (T3) at `w` with integrals `q` (x: all but Jyy's, y: all
/// but Jzz's, z: all but Jxx's; [`EXPAND`] restores them).
#[inline(always)]
fn rows(w: [f32; 3], q: &[f32; 6]) -> [[f32; KEPT]; 3] {
    let [wx, wy, wz] = w;
    let [qxx, qyy, qzz, qxy, qxz, qyz] = *q;
    [
        [wx, qyz, wy - qxz, wz + qxy, qyy - qzz],
        [qxz, wy, wx + qyz, qzz - qxx, wz - qxy],
        [qxy, wz, qxx - qyy, wx - qyz, wy + qxz],
    ]
}

#[inline(always)]
fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
fn products(w: [f32; 3]) -> [f32; 6] {
    let [x, y, z] = w;
    [x * x, y * y, z * z, x * y, x * z, y * z]
}

/// `j` (xx, yy, zz, xy, xz, yz) as a symmetric 3x3 matrix.
pub fn to_matrix(j: &[f32; 6]) -> [[f32; 3]; 3] {
    let [xx, yy, zz, xy, xz, yz] = *j;
    [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]
}

/// Standard deviations `sqrt(diag(C))` of `j` laid out as a 3x3 matrix.
fn std_matrix(c: &Sym<6>) -> [[f32; 3]; 3] {
    let d = |i: usize| sqrt(c.get(i).and_then(|r| r.get(i)).copied().unwrap_or(0.0));
    to_matrix(&[d(0), d(1), d(2), d(3), d(4), d(5)])
}

/// `g^T C g`.
fn quad(c: &Sym<6>, g: &[f32; 6]) -> f32 {
    let mut s = 0.0;
    for (row, gi) in c.iter().zip(g.iter()) {
        for (cij, gj) in row.iter().zip(g.iter()) {
            s += gi * cij * gj;
        }
    }
    s
}

/// The on-board estimator of the inertia tensor: one [`TensorEstimator::step`] per gyro
/// sample with the rotor momentum at that sample. Fixed size, no heap, no buffers.
///
/// ```
/// use identifier_core::{Status, TensorEstimator, TensorSettings};
///
/// // Rates in deg/s fed as rad/s (60 "rad/s" spins are beyond any thrown body): never
/// // trusted, and the status says why.
/// let mut e = TensorEstimator::new(TensorSettings::for_rate(1000.0, 2e-3)).unwrap();
/// for k in 0..2000 {
///     let t = k as f32 * 1e-3;
///     e.step([60.0 + t, -30.0, 80.0 - t], [0.0; 3], 1e-3);
/// }
/// assert_eq!(e.estimate().status, Status::UnitsLookWrong);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TensorEstimator {
    settings: TensorSettings,
    stretch: Stretch,
    closed: Normal,
    closed_stretches: u32,
    /// Axis weights of the rows (T3). Equal: weights `1 / (J J^T)_rr` from the estimate (the
    /// white part of the residual, `J n`) make the reported standard deviation several times
    /// too small on simulated throws, because the integrals' noise mixes all three axes into
    /// every row; with equal weights it stays near the errors (`tensor-bench` measures both).
    weights: [f32; 3],
    pending_dt: f32,
    restart: bool,
    counters: TensorCounters,
}

impl TensorEstimator {
    /// A new estimator, or `None` when the settings are not usable.
    pub fn new(settings: TensorSettings) -> Option<Self> {
        if !settings.is_valid() {
            return None;
        }
        Some(TensorEstimator {
            settings,
            stretch: Stretch::EMPTY,
            closed: Normal::ZERO,
            closed_stretches: 0,
            weights: [1.0; 3],
            pending_dt: 0.0,
            restart: false,
            counters: TensorCounters::default(),
        })
    }

    /// The settings.
    pub fn settings(&self) -> &TensorSettings {
        &self.settings
    }

    /// Counters for diagnosis.
    pub fn counters(&self) -> &TensorCounters {
        &self.counters
    }

    /// Forgets everything learnt.
    pub fn reset(&mut self) {
        let s = self.settings;
        *self = TensorEstimator {
            settings: s,
            stretch: Stretch::EMPTY,
            closed: Normal::ZERO,
            closed_stretches: 0,
            weights: [1.0; 3],
            pending_dt: 0.0,
            restart: false,
            counters: TensorCounters::default(),
        };
    }

    /// Adds one sample: `omega` the measured rate (rad/s), `h` the known rotor momentum in the
    /// body (kg m^2/s; zeros without rotors), `dt` the time since the previous sample (s).
    ///
    /// Refused samples (non-finite, saturated, bad `dt`) are counted and end the stretch; a
    /// gap longer than `max_dt` starts a new stretch at this sample.
    pub fn step(&mut self, omega: [f32; 3], h: [f32; 3], dt: f32) -> SampleStatus {
        if !omega.iter().chain(h.iter()).all(|x| x.is_finite()) {
            self.counters.non_finite = self.counters.non_finite.saturating_add(1);
            self.pending_dt += if dt.is_finite() && dt > 0.0 { dt } else { 0.0 };
            return SampleStatus::NonFinite;
        }
        if omega.iter().any(|w| w.abs() >= self.settings.full_scale) {
            self.counters.saturated = self.counters.saturated.saturating_add(1);
            self.restart = true;
            return SampleStatus::Saturated;
        }
        if !(dt.is_finite() && dt > 0.0) {
            self.counters.bad_dt = self.counters.bad_dt.saturating_add(1);
            self.restart = true;
            return SampleStatus::InvalidTimeStep;
        }
        if omega
            .iter()
            .any(|w| w.abs() > self.settings.max_plausible_rate)
        {
            self.counters.implausible = self.counters.implausible.saturating_add(1);
        }
        let dt = dt + self.pending_dt;
        self.pending_dt = 0.0;
        if self.restart {
            self.restart = false;
            self.end_stretch();
        }
        let Some((w0, h0)) = self.stretch.last else {
            self.anchor(omega, h);
            self.counters.used = self.counters.used.saturating_add(1);
            return SampleStatus::Anchored;
        };
        // A step is a gap when it is long against the sample rate or against the motion: the
        // samples must follow the body's turning (`|w|_1 dt`, at least the angle turned).
        let turn = (omega[0].abs() + omega[1].abs() + omega[2].abs()) * dt;
        if dt > self.settings.max_dt || turn > MAX_STEP_TURN_RAD {
            self.counters.gaps = self.counters.gaps.saturating_add(1);
            self.end_stretch();
            self.anchor(omega, h);
            self.counters.used = self.counters.used.saturating_add(1);
            return SampleStatus::Gap;
        }
        let st = &mut self.stretch;
        let half = 0.5 * dt;
        let (qa, qb) = (products(w0), products(omega));
        for ((q, a), b) in st.q.iter_mut().zip(qa.iter()).zip(qb.iter()) {
            *q += half * (a + b);
        }
        let (ca, cb) = (cross(w0, h0), cross(omega, h));
        for ((s, a), b) in st.wh.iter_mut().zip(ca.iter()).zip(cb.iter()) {
            *s += half * (a + b);
        }
        // Euler-Maclaurin end correction: the trapezoid's error up to t telescopes to
        // -dt^2/12 (f'(t) - f'(t0)); f'(t0) is a constant the intercept absorbs, and
        // dt^2 f'(t) is taken as dt (f(t) - f(t_prev)), leaving an O(dt^3) error.
        let k = dt * (1.0 / 12.0);
        let mut qc = st.q;
        for ((q, a), b) in qc.iter_mut().zip(qa.iter()).zip(qb.iter()) {
            *q -= k * (b - a);
        }
        let mut whc = st.wh;
        for ((s, a), b) in whc.iter_mut().zip(ca.iter()).zip(cb.iter()) {
            *s -= k * (b - a);
        }
        // The rows relative to the anchor's, `dP = P - P0`. At the anchor the integrals are
        // zero, so two kept entries of each anchor row are zero by construction and are not
        // subtracted (`x - 0 = x` exactly: the same bits as subtracting them).
        let [px, py, pz] = rows(omega, &qc);
        let [[x0, _, x2, x3, _], [_, y1, y2, _, y4], [_, z1, _, z3, z4]] = st.p0;
        let [b0, b1, b2] = &mut st.block;
        b0.add(
            &[px[0] - x0, px[1], px[2] - x2, px[3] - x3, px[4]],
            -(h[0] + whc[0]) - st.y0[0],
        );
        b1.add(
            &[py[0], py[1] - y1, py[2] - y2, py[3], py[4] - y4],
            -(h[1] + whc[1]) - st.y0[1],
        );
        b2.add(
            &[pz[0], pz[1] - z1, pz[2], pz[3] - z3, pz[4] - z4],
            -(h[2] + whc[2]) - st.y0[2],
        );
        st.n += 1;
        st.block_n += 1;
        st.drift += dt * dt * (omega[0] * omega[0] + omega[1] * omega[1] + omega[2] * omega[2]);
        st.last = Some((omega, h));
        self.counters.used = self.counters.used.saturating_add(1);
        if st.block_n >= BLOCK {
            st.flush_block();
        }
        let limit = self.settings.stretch_noise * self.settings.stretch_noise;
        if self.stretch.drift > limit {
            // Close here and start afresh from this very sample, so no interval is lost.
            self.end_stretch();
            self.anchor(omega, h);
        }
        SampleStatus::Updated
    }

    /// Ends the open stretch (release, catch, or any break in the data); the next sample
    /// anchors a new one. What the stretch taught is kept.
    pub fn end_stretch(&mut self) {
        self.stretch.flush_block();
        if self.stretch.n >= 2 {
            let mut add = Normal::ZERO;
            let n = self.stretch.n as f32;
            for (axis, (rows, &w)) in self
                .stretch
                .sums
                .iter()
                .zip(self.weights.iter())
                .enumerate()
            {
                add.add_stretch(&rows.expanded(axis), n, w);
            }
            add.equations = 3 * (self.stretch.n - 1);
            self.closed.add(&add);
            self.closed_stretches = self.closed_stretches.saturating_add(1);
        }
        self.stretch = Stretch::EMPTY;
    }

    fn anchor(&mut self, omega: [f32; 3], h: [f32; 3]) {
        let st = &mut self.stretch;
        *st = Stretch::EMPTY;
        st.p0 = rows(omega, &[0.0; 6]);
        st.y0 = [-h[0], -h[1], -h[2]];
        st.last = Some((omega, h));
        st.n = 1;
    }

    /// Normal equations of everything so far: the closed stretches plus the open one with the
    /// current weights.
    fn normal(&self) -> (Normal, u32) {
        let mut nrm = self.closed;
        let mut st = self.stretch;
        st.flush_block();
        let mut stretches = self.closed_stretches;
        if st.n >= 2 {
            let n = st.n as f32;
            let mut add = Normal::ZERO;
            for (axis, (rows, &w)) in st.sums.iter().zip(self.weights.iter()).enumerate() {
                add.add_stretch(&rows.expanded(axis), n, w);
            }
            add.equations = 3 * (st.n - 1);
            nrm.add(&add);
            stretches += 1;
        }
        (nrm, stretches)
    }

    /// The estimate from everything so far (see the module docs). Costs a few thousand
    /// floating-point operations: call it at the report rate, not per sample.
    pub fn estimate(&self) -> TensorEstimate {
        self.solve_all()
    }

    /// The equation error's tensor in kg m^2 from the rotor momentum alone, whatever its
    /// excitation measure says (that measure is the tensor up to scale's): a starting point
    /// for the output-error fit where [`TensorEstimator::estimate`] gives none, as on a
    /// satellite at rest turned by its wheels (total momentum zero, `J w = -h`). `None`
    /// without rotor momentum or when the equations are singular.
    pub(crate) fn absolute_guess(&self) -> Option<[[f32; 3]; 3]> {
        let (nrm, _) = self.normal();
        let lam = nrm.full();
        let abs = solve_absolute(&lam, &nrm, false)?;
        let j = abs.j;
        let ok = j.iter().all(|x| x.is_finite()) && j[0] > 0.0 && j[1] > 0.0 && j[2] > 0.0;
        ok.then(|| to_matrix(&j))
    }

    fn solve_all(&self) -> TensorEstimate {
        let (nrm, stretches) = self.normal();
        let samples = self.counters.used;
        let mut out = TensorEstimate {
            status: Status::TooFewSamples,
            model: TensorModel::Full,
            tensor: None,
            tensor_std: None,
            tensor_cov: None,
            normalized: None,
            normalized_std: None,
            principal_moments: None,
            principal_axes: None,
            a: None,
            std_a: None,
            residual_ratio: 0.0,
            excitation: 0.0,
            samples,
            stretches,
            method: TensorMethod::EquationError,
            uncertainty: Uncertainty::Noise,
            determined: false,
        };
        let c = &self.counters;
        if c.implausible > 0 || c.gaps.saturating_mul(10) > c.used {
            out.status = Status::UnitsLookWrong;
            return out;
        }
        if samples < self.settings.min_samples || nrm.equations < 12 {
            return out;
        }
        let lam = nrm.full();
        let sigma2 = self.settings.noise_std * self.settings.noise_std;

        // Up to scale: the homogeneous equations under trace = 1, full and principal.
        let full_n = solve_normalized(&lam, nrm.equations, false);
        let princ_n = solve_normalized(&lam, nrm.equations, true);
        let Some(full_n) = full_n else {
            out.status = Status::NoExcitation;
            return out;
        };
        let mut model = TensorModel::Full;
        let mut chosen = full_n;
        if let Some(p) = princ_n {
            let chi2 = products_chi2(&full_n.j, &full_n.cov, sigma2, full_n.s2);
            if chi2 < self.settings.products_chi2 {
                model = TensorModel::Principal;
                chosen = p;
            }
        }
        let mut maxvar = 0.0f32;
        for (i, row) in chosen.cov.iter().enumerate() {
            maxvar = max(maxvar, row.get(i).copied().unwrap_or(0.0));
        }
        out.excitation = 1.0 / (sigma2 * nrm.equations as f32 * maxvar);
        if !(out.excitation >= self.settings.min_excitation) {
            out.status = Status::NoExcitation;
            return out;
        }
        // The rows are not whitened (equal weights): a perfect fit leaves `J n`, of variance
        // `sigma^2 (J J^T)_rr` per row, about `sigma^2 |N|_F^2 / 3` for the normalised tensor.
        let f = {
            let mut t = 0.0;
            for x in chosen.j.iter().take(3) {
                t += x * x;
            }
            for x in chosen.j.iter().skip(3) {
                t += 2.0 * x * x;
            }
            let t = t / 3.0;
            if t > 0.0 && t.is_finite() {
                t
            } else {
                1.0
            }
        };
        let floor = sigma2 * f;
        // The uncertainty uses the larger floor `sigma^2`: the least squares ignore that the
        // integrals' noise is correlated from sample to sample, and the white floor alone would
        // make the reported standard deviation several times too small on simulated throws;
        // `sigma^2` brings it near the errors (measured with `tensor-bench`).
        let s2n = max(chosen.s2, sigma2);
        let cov_n = scale(&chosen.cov, s2n);

        // Absolute, when the rotor momentum fixes the scale.
        let mut absolute: Option<([f32; 6], Sym<6>)> = None;
        let mut s2 = chosen.s2;
        if let Some(abs) = solve_absolute(&lam, &nrm, model == TensorModel::Principal) {
            let tr = abs.j[0] + abs.j[1] + abs.j[2];
            let s2a = max(abs.s2, sigma2 * tr * tr);
            let cov = scale(&abs.cov, s2a);
            let t = [1.0, 1.0, 1.0, 0.0, 0.0, 0.0];
            let var_tr = quad(&cov, &t);
            if tr > 0.0 && var_tr < 0.01 * tr * tr {
                absolute = Some((abs.j, cov));
                s2 = abs.s2 / (tr * tr);
            }
        }
        out.model = model;
        out.residual_ratio = sqrt(s2 / floor);
        self.describe(out, chosen.j, cov_n, absolute)
    }

    /// `base` (this estimator's own estimate on the same samples) with the tensor replaced by
    /// `j` (entries xx, yy, zz, xy, xz, yz in kg m^2) of covariance `cov`, from another fit of
    /// the same samples (the output-error [`crate::TensorFit`]) whose residual is
    /// `residual_ratio` times the gyro noise (`coloured`: that residual is coloured, (F10') of
    /// the fit, so it does not fit to the noise whatever its level): the full model, described
    /// and judged as the estimator's own. `NoExcitation` from the equation error's own measure (which is that
    /// of the tensor up to scale) gives way to the fit's `Converged` or `Converging`: a body
    /// whose total momentum is zero (a satellite at rest, turned by its wheels alone, `J w =
    /// -h`) leaves the homogeneous equations nothing, while the rotor's momentum still
    /// determines `J` in kg m^2, as well as the fit's own covariance says.
    pub fn with_tensor(
        &self,
        base: TensorEstimate,
        j: [f32; 6],
        cov: Sym<6>,
        residual_ratio: f32,
        coloured: bool,
    ) -> TensorEstimate {
        let out = self.with_fit(base, j, cov, residual_ratio, coloured, Some((j, cov)));
        let informative = matches!(out.status, Status::Converged | Status::Converging);
        if base.status == Status::NoExcitation && !informative {
            return base;
        }
        out
    }

    /// `base` with the tensor up to scale replaced by `nj` (entries xx, yy, zz, xy, xz, yz of
    /// `J / trace J`) of covariance `cov_n`, from the output-error fit of the same samples
    /// without rotor momentum ([`crate::TensorFit::close_normalized`]) whose residual is
    /// `residual_ratio` times the gyro noise (`coloured` as for [`TensorEstimator::with_tensor`]):
    /// the full model, described and judged as the estimator's own. `base` is returned unchanged when there are too few samples or the
    /// units look wrong. `NoExcitation` from the equation error's own measure is kept unless
    /// the fit is `Converged`: a body spinning near a principal axis gives the equation error
    /// too little to go on while the trajectory still determines `J / trace J` to its
    /// tolerance (the fit's own covariance says how well).
    pub fn with_normalized(
        &self,
        base: TensorEstimate,
        nj: [f32; 6],
        cov_n: Sym<6>,
        residual_ratio: f32,
        coloured: bool,
    ) -> TensorEstimate {
        let out = self.with_fit(base, nj, cov_n, residual_ratio, coloured, None);
        // Lifted from `NoExcitation` only as far as `Converged`: a still gyro's noise still
        // gives the fit a finite covariance, and "converging" would say more than it knows.
        if base.status == Status::NoExcitation && out.status != Status::Converged {
            return base;
        }
        out
    }

    /// What [`TensorEstimator::with_tensor`] and [`TensorEstimator::with_normalized`] share:
    /// `base` unchanged with too few samples or units that look wrong, else the fit's tensor
    /// (full model, output error) described and judged as the estimator's own.
    fn with_fit(
        &self,
        base: TensorEstimate,
        nj: [f32; 6],
        cov_n: Sym<6>,
        residual_ratio: f32,
        coloured: bool,
        absolute: Option<([f32; 6], Sym<6>)>,
    ) -> TensorEstimate {
        if matches!(base.status, Status::TooFewSamples | Status::UnitsLookWrong) {
            return base;
        }
        let mut out = base;
        out.method = TensorMethod::OutputError;
        out.model = TensorModel::Full;
        out.residual_ratio = residual_ratio;
        out.tensor = None;
        out.tensor_std = None;
        out.tensor_cov = None;
        let mut out = self.describe(out, nj, cov_n, absolute);
        // The fit's model is efficient and its covariance the bound's only where the residual
        // is the gyro's noise: beyond [`OUTPUT_ERROR_FIT_RATIO`] times it (an effect the model lacks, coloured noise) the
        // covariance comes from the residual seen, and the status says so instead of
        // `Converged`: `ModelMismatch`, the estimate usable with its stated uncertainty.
        // Where the momentum is read in steps ((F7), (F8) of the fit), the residual also holds
        // the reading's expected error, and `mismatch_ratio` alone judges it.
        // A residual at the noise's level that is coloured ((F10') of the fit) does not fit to
        // the noise either: a walking or truncating gyro, a small unmodelled torque.
        let exact_momentum = !(self.settings.momentum_resolution > 0.0);
        let fits = (residual_ratio <= OUTPUT_ERROR_FIT_RATIO && !coloured) || !exact_momentum;
        if !fits && matches!(out.status, Status::Converged | Status::Converging) {
            out.status = Status::ModelMismatch;
        }
        // Beyond the noise (or coloured) the fit's covariance is the residual's ((F10),
        // (F11), (F14) of the fit), whatever the momentum's reading.
        out.uncertainty = if residual_ratio <= OUTPUT_ERROR_FIT_RATIO && !coloured {
            Uncertainty::Noise
        } else {
            Uncertainty::Residual
        };
        out
    }

    /// The estimate's description from the normalised tensor `nj` (entries xx, yy, zz, xy,
    /// xz, yz, trace 1) with its covariance, or from the absolute one when given (then the
    /// normalised follows, `N = J / tr`, `dN = (I - N t^T) dJ / tr`): principal moments and
    /// axes, `a` and their standard deviations, physical validity to three standard
    /// deviations, and the status (`out` carries the model, residual ratio and excitation).
    pub(crate) fn describe(
        &self,
        mut out: TensorEstimate,
        nj: [f32; 6],
        cov_n: Sym<6>,
        absolute: Option<([f32; 6], Sym<6>)>,
    ) -> TensorEstimate {
        let mut chosen_j = nj;
        let mut cov_n = cov_n;
        if let Some((j, cov)) = absolute {
            let tr = j[0] + j[1] + j[2];
            let nj = [
                j[0] / tr,
                j[1] / tr,
                j[2] / tr,
                j[3] / tr,
                j[4] / tr,
                j[5] / tr,
            ];
            let mut d = [[0.0f32; 6]; 6];
            for (i, row) in d.iter_mut().enumerate() {
                for (k, e) in row.iter_mut().enumerate() {
                    let id = if i == k { 1.0 } else { 0.0 };
                    let tk = if k < 3 { 1.0 } else { 0.0 };
                    *e = (id - nj.get(i).copied().unwrap_or(0.0) * tk) / tr;
                }
            }
            cov_n = congruence(&d, &cov);
            chosen_j = nj;
        }
        let nmat = to_matrix(&chosen_j);
        out.normalized = Some(nmat);
        out.normalized_std = Some(std_matrix(&cov_n));
        if let Some((j, cov)) = absolute {
            out.tensor = Some(to_matrix(&j));
            out.tensor_std = Some(std_matrix(&cov));
            out.tensor_cov = Some(cov);
        }

        // Principal moments and axes, ratios.
        let Some(eig) = eigen_symmetric3(&nmat) else {
            out.status = Status::NoExcitation;
            return out;
        };
        let unit = match absolute {
            Some((j, _)) => j[0] + j[1] + j[2],
            None => 1.0,
        };
        out.principal_moments = Some([
            eig.values[0] * unit,
            eig.values[1] * unit,
            eig.values[2] * unit,
        ]);
        out.principal_axes = Some(eig.vectors);
        let grads = eig.vectors.map(|v| {
            [
                v[0] * v[0],
                v[1] * v[1],
                v[2] * v[2],
                2.0 * v[0] * v[1],
                2.0 * v[0] * v[2],
                2.0 * v[1] * v[2],
            ]
        });
        let var_l = grads.map(|g| quad(&cov_n, &g));
        let (a, std_a) = ratios(&eig, &grads, &cov_n);
        out.a = a;
        out.std_a = std_a;

        // Validity: positive definite and the triangle inequalities, to three sigma.
        let [l0, l1, l2] = eig.values;
        let sd0 = sqrt(var_l[0]);
        let slack = l0 + l1 - l2;
        let g_slack: [f32; 6] = core::array::from_fn(|k| {
            grads[0].get(k).copied().unwrap_or(0.0) + grads[1].get(k).copied().unwrap_or(0.0)
                - grads[2].get(k).copied().unwrap_or(0.0)
        });
        let sd_slack = sqrt(quad(&cov_n, &g_slack));
        let impossible = l0 < -3.0 * sd0 || slack < -3.0 * sd_slack;
        let positive = eig
            .values
            .iter()
            .zip(var_l.iter())
            .all(|(&l, &v)| l > 3.0 * sqrt(v));
        out.determined = positive && !impossible;
        let valid = l0 > 0.0 && slack >= 0.0;

        let c = &self.counters;
        let seen = c.used.saturating_add(c.saturated);
        out.status = if c.implausible > 0 || c.gaps.saturating_mul(10) > c.used {
            Status::UnitsLookWrong
        } else if c.saturated.saturating_mul(100) > seen {
            Status::Saturated
        } else if out.residual_ratio > self.settings.mismatch_ratio {
            Status::ModelMismatch
        } else if impossible {
            Status::PhysicallyImpossible
        } else if !valid {
            Status::Converging
        } else {
            let tol = self.settings.tolerance;
            let a_ok = std_a.is_some_and(|s| s.iter().all(|&x| x < tol));
            let m_ok = eig
                .values
                .iter()
                .zip(var_l.iter())
                .all(|(&l, &v)| sqrt(v) < tol * l);
            if a_ok && m_ok {
                Status::Converged
            } else {
                Status::Converging
            }
        };
        // The covariance above is scaled by the residual's level alone: beyond the mismatch
        // ratio the residual is no white noise, and that level does not count its correlation.
        out.uncertainty = if out.residual_ratio > self.settings.mismatch_ratio {
            Uncertainty::Unaccounted
        } else {
            Uncertainty::Noise
        };
        out
    }
}

fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

fn scale(c: &Sym<6>, s: f32) -> Sym<6> {
    c.map(|row| row.map(|x| x * s))
}

/// `D C D^T`.
fn congruence(d: &Sym<6>, c: &Sym<6>) -> Sym<6> {
    let mut dc = [[0.0f32; 6]; 6];
    for (dcr, dr) in dc.iter_mut().zip(d.iter()) {
        for (k, e) in dcr.iter_mut().enumerate() {
            let mut s = 0.0;
            for (dri, cr) in dr.iter().zip(c.iter()) {
                s += dri * cr.get(k).copied().unwrap_or(0.0);
            }
            *e = s;
        }
    }
    let mut out = [[0.0f32; 6]; 6];
    for (outr, dcr) in out.iter_mut().zip(dc.iter()) {
        for (e, dr) in outr.iter_mut().zip(d.iter()) {
            let mut s = 0.0;
            for (a, b) in dcr.iter().zip(dr.iter()) {
                s += a * b;
            }
            *e = s;
        }
    }
    out
}

/// A solution `j` with its unscaled covariance (multiply by the residual variance) and the
/// residual variance per equation `s2`.
#[derive(Clone, Copy)]
struct Solution {
    j: [f32; 6],
    cov: Sym<6>,
    s2: f32,
}

/// Normalised solution: `j = e_zz + Z z` with `z = (Jxx, Jyy, Jxy, Jxz, Jyz)` (or the first two
/// for the principal model), minimising `j^T Lambda j` (the equations without `h`).
fn solve_normalized(lam: &Sym<6>, equations: u32, principal: bool) -> Option<Solution> {
    // Z maps z to j: xx -> (e_xx - e_zz), yy -> (e_yy - e_zz), xy, xz, yz -> themselves.
    let zcol = |c: usize| -> [f32; 6] {
        match c {
            0 => [1.0, 0.0, -1.0, 0.0, 0.0, 0.0],
            1 => [0.0, 1.0, -1.0, 0.0, 0.0, 0.0],
            2 => [0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
            3 => [0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            _ => [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        }
    };
    let ezz = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
    let lz = |v: &[f32; 6]| -> [f32; 6] {
        let mut o = [0.0f32; 6];
        for (oi, row) in o.iter_mut().zip(lam.iter()) {
            let mut s = 0.0;
            for (a, b) in row.iter().zip(v.iter()) {
                s += a * b;
            }
            *oi = s;
        }
        o
    };
    let dot6 = |a: &[f32; 6], b: &[f32; 6]| -> f32 {
        let mut s = 0.0;
        for (x, y) in a.iter().zip(b.iter()) {
            s += x * y;
        }
        s
    };
    let l_ezz = lz(&ezz);
    let (j, cov_small, p) = if principal {
        let (z0, z1) = (zcol(0), zcol(1));
        let (lz0, lz1) = (lz(&z0), lz(&z1));
        let m: Sym<2> = [
            [dot6(&z0, &lz0), dot6(&z0, &lz1)],
            [dot6(&z1, &lz0), dot6(&z1, &lz1)],
        ];
        let b = [-dot6(&z0, &l_ezz), -dot6(&z1, &l_ezz)];
        let l = cholesky(&m)?;
        let z = cholesky_solve(&l, &b);
        let inv = cholesky_inverse(&l);
        let j = [z[0], z[1], 1.0 - z[0] - z[1], 0.0, 0.0, 0.0];
        let cov = z_inv_zt(&[z0, z1], &inv);
        (j, cov, 2u32)
    } else {
        let cols: [[f32; 6]; 5] = core::array::from_fn(zcol);
        let lcols: [[f32; 6]; 5] = cols.map(|c| lz(&c));
        let mut m: Sym<5> = [[0.0; 5]; 5];
        for (r, row) in m.iter_mut().enumerate() {
            for (c, e) in row.iter_mut().enumerate() {
                if let (Some(a), Some(b)) = (cols.get(r), lcols.get(c)) {
                    *e = dot6(a, b);
                }
            }
        }
        let b: [f32; 5] =
            core::array::from_fn(|r| cols.get(r).map(|c| -dot6(c, &l_ezz)).unwrap_or(0.0));
        let l = cholesky(&m)?;
        let z = cholesky_solve(&l, &b);
        let inv = cholesky_inverse(&l);
        let j = [z[0], z[1], 1.0 - z[0] - z[1], z[2], z[3], z[4]];
        let cov = z_inv_zt(&cols, &inv);
        (j, cov, 5u32)
    };
    let rss = dot6(&j, &lz(&j));
    let dof = equations.checked_sub(p)?;
    if dof == 0 {
        return None;
    }
    let s2 = rss / dof as f32;
    (j.iter().all(|x| x.is_finite()) && s2.is_finite()).then_some(Solution {
        j,
        cov: cov_small,
        s2,
    })
}

/// `Z inv Z^T`: the covariance of `j = e_zz + Z z` from that of the free entries `z`
/// (`cols` the columns of `Z`).
fn z_inv_zt<const K: usize>(cols: &[[f32; 6]; K], inv: &Sym<K>) -> Sym<6> {
    let mut cov = [[0.0f32; 6]; 6];
    for (r, row) in cov.iter_mut().enumerate() {
        for (c, e) in row.iter_mut().enumerate() {
            let mut s = 0.0;
            for (ca, ia) in cols.iter().zip(inv.iter()) {
                for (cb, iab) in cols.iter().zip(ia.iter()) {
                    s +=
                        ca.get(r).copied().unwrap_or(0.0) * iab * cb.get(c).copied().unwrap_or(0.0);
                }
            }
            *e = s;
        }
    }
    cov
}

/// Absolute solution `Lambda j = eta` (full, or the diagonal block for the principal model).
fn solve_absolute(lam: &Sym<6>, nrm: &Normal, principal: bool) -> Option<Solution> {
    let eta = nrm.eta;
    let eta_norm = eta.iter().fold(0.0f32, |s, e| s + e * e);
    if !(eta_norm > 0.0) {
        return None;
    }
    let (j, cov, p) = if principal {
        let m: Sym<3> = [
            [lam[0][0], lam[0][1], lam[0][2]],
            [lam[1][0], lam[1][1], lam[1][2]],
            [lam[2][0], lam[2][1], lam[2][2]],
        ];
        let l = cholesky(&m)?;
        let x = cholesky_solve(&l, &[eta[0], eta[1], eta[2]]);
        let inv = cholesky_inverse(&l);
        let mut cov = [[0.0f32; 6]; 6];
        for (r, row) in inv.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                if let Some(e) = cov.get_mut(r).and_then(|x| x.get_mut(c)) {
                    *e = *v;
                }
            }
        }
        ([x[0], x[1], x[2], 0.0, 0.0, 0.0], cov, 3u32)
    } else {
        let l = cholesky(lam)?;
        (cholesky_solve(&l, &eta), cholesky_inverse(&l), 6u32)
    };
    // RSS = yy - 2 j.eta + j^T Lambda j = yy - j.eta at the optimum.
    let mut jeta = 0.0;
    for (a, b) in j.iter().zip(eta.iter()) {
        jeta += a * b;
    }
    let rss = nrm.yy - jeta;
    let dof = nrm.equations.checked_sub(p)?;
    if dof == 0 {
        return None;
    }
    let s2 = max(rss, 0.0) / dof as f32;
    (j.iter().all(|x| x.is_finite()) && s2.is_finite()).then_some(Solution { j, cov, s2 })
}

/// Wald statistic of the three products of inertia: `z^T C_zz^-1 z` with `C` the normalised
/// covariance scaled by the residual variance.
fn products_chi2(j: &[f32; 6], cov: &Sym<6>, sigma2: f32, s2: f32) -> f32 {
    let s = max(s2, sigma2);
    let mut scaled = *cov;
    for row in scaled.iter_mut() {
        for x in row.iter_mut() {
            *x *= s;
        }
    }
    products_wald(j, &scaled)
}

/// Wald statistic of the products of inertia `z = (Jxy, Jxz, Jyz)` (entries 3..6 of `j`, the
/// order `(Jxx, Jyy, Jzz, Jxy, Jxz, Jyz)`) under their covariance `C_zz` (the same block of
/// `cov`): `z^T C_zz^-1 z`, chi-square with 3 degrees of freedom when the products are zero;
/// infinite when `C_zz` is not positive definite or the statistic is not finite.
pub(crate) fn products_wald(j: &[f32; 6], cov: &Sym<6>) -> f32 {
    let m: Sym<3> = [
        [cov[3][3], cov[3][4], cov[3][5]],
        [cov[4][3], cov[4][4], cov[4][5]],
        [cov[5][3], cov[5][4], cov[5][5]],
    ];
    let z = [j[3], j[4], j[5]];
    let Some(l) = cholesky(&m) else {
        return f32::INFINITY;
    };
    let x = cholesky_solve(&l, &z);
    let v = x[0] * z[0] + x[1] * z[1] + x[2] * z[2];
    if v.is_finite() {
        v
    } else {
        f32::INFINITY
    }
}

/// `a_k = (A_{k+1} - A_{k+2}) / A_k` with `A_k` the principal moment whose axis lies closest to
/// sensor axis `k`, and the standard deviations by first-order propagation.
fn ratios(
    eig: &crate::symmetric::Eigen3,
    grads: &[[f32; 6]; 3],
    cov: &Sym<6>,
) -> (Option<[f32; 3]>, Option<[f32; 3]>) {
    // Sensor axis of each principal axis.
    let mut axis_of = [0usize; 3];
    for (i, v) in eig.vectors.iter().enumerate() {
        let mut big = 0;
        for k in 1..3 {
            if v[k].abs() > v[big].abs() {
                big = k;
            }
        }
        axis_of[i] = big;
    }
    let mut which = [usize::MAX; 3];
    for (i, &k) in axis_of.iter().enumerate() {
        if let Some(w) = which.get_mut(k) {
            *w = i;
        }
    }
    if which.iter().any(|&w| w > 2) {
        return (None, None);
    }
    let m = |k: usize| -> f32 {
        which
            .get(k)
            .and_then(|&i| eig.values.get(i))
            .copied()
            .unwrap_or(0.0)
    };
    let g = |k: usize| -> [f32; 6] {
        which
            .get(k)
            .and_then(|&i| grads.get(i))
            .copied()
            .unwrap_or([0.0; 6])
    };
    let mut a = [0.0f32; 3];
    let mut sd = [0.0f32; 3];
    for k in 0..3 {
        let (i1, i2, i3) = (k, (k + 1) % 3, (k + 2) % 3);
        let (m1, m2, m3) = (m(i1), m(i2), m(i3));
        if !(m1 > 0.0) {
            return (None, None);
        }
        let ak = (m2 - m3) / m1;
        let (g1, g2, g3) = (g(i1), g(i2), g(i3));
        let gr: [f32; 6] = core::array::from_fn(|e| {
            let (a1, a2, a3) = (
                g1.get(e).copied().unwrap_or(0.0),
                g2.get(e).copied().unwrap_or(0.0),
                g3.get(e).copied().unwrap_or(0.0),
            );
            (a2 - a3 - ak * a1) / m1
        });
        a[k] = ak;
        sd[k] = sqrt(quad(cov, &gr));
    }
    if a.iter().chain(sd.iter()).all(|x| x.is_finite()) {
        (Some(a), Some(sd))
    } else {
        (None, None)
    }
}
