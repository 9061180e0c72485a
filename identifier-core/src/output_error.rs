//! What the two output-error fits ([`crate::RatioFit`] and [`crate::TensorFit`]) share: the
//! block buffer that turns a free flight of any length into at most `N` block means, and the
//! Levenberg-Marquardt loop.
//!
//! # Block means
//!
//! Each block keeps its sample count `n`, the time of its first sample `t0`, the sums of the
//! time since `t0` and of its square, and for `K` channels (the rate, and the rotor momentum for
//! the tensor) the first sample and the sum of the deviations from it. From them, the mean time `tbar = t0 + st/n`, the variance of the
//! sample times `v = stt/n - (st/n)^2` and the channel means. A smooth signal's mean over a
//! block's samples is, by Taylor expansion about the mean time,
//!
//! ```text
//! mean_k x(t_k) = x(tbar) + v/2 x''(tbar) + O(dt^3 x''')                          (B1)
//! ```
//!
//! A sample that is itself a mean (of `m` readings of a decimated gyro, each perhaps the mean
//! of the rate over a window, as a gyro driver that integrates over the sample interval
//! reports it) carries the time variance of what it averages into `v`:
//!
//! ```text
//! v_sample = ((m^2 - 1) / 12 + window) (dt / m)^2                              (B0)
//! ```
//!
//! `window` the time variance of one reading's window over its interval squared (0 for a
//! reading at an instant, `1/12` for the mean over the whole interval). A reading that has
//! passed through a low-pass filter (a flight controller's gyro filters: Betaflight logs its
//! filtered gyro) is the filter's impulse response `g` averaged over the rate, a window too:
//! by the same expansion, with the filter's delay taken out of the times, it adds the second
//! cumulant of `g` (`tau^2` for a first-order stage of time constant `tau`), in seconds
//! squared:
//!
//! ```text
//! v_sample = ((m^2 - 1) / 12 + window) (dt / m)^2 + s_filter                  (B0')
//! ```
//!
//! When the `N` blocks are full, neighbours are merged (sums referred to the earlier block's
//! `t0`) and the block length doubles, so any flight fits and blocks stay as short as the
//! buffer allows.
//!
//! # Levenberg-Marquardt
//!
//! Given the weighted cost `C(theta) = sum_b n_b |r_b|^2` with its Gauss-Newton normal
//! equations `F = sum_b n_b S_b^T S_b`, `g = sum_b n_b S_b^T r_b`, a step solves
//! `(D^-1 F D^-1 + mu I) z = D^-1 g`, `delta = D^-1 z`, `D = sqrt(diag F)` (Jacobi scaling: the
//! parameters differ by orders of magnitude), and is accepted when the cost falls, else refused
//! (`mu * 10`); after an accepted step `mu` follows the gain against the Gauss-Newton
//! prediction (see [`levenberg`]). It stops when the undamped step is predicted to gain less
//! than `tol` residual variances ([`TOLERANCE`] on a whole record), taking that step without
//! another evaluation.
#![allow(
    // Fixed-size loops over the parameters read as the equations; the crate's link-time
    // no-panic check proves no bounds check survives.
    clippy::indexing_slicing,
    clippy::needless_range_loop,
    // `!(x > 0.0)` is true for NaN too, which is the point.
    clippy::neg_cmp_op_on_partial_ord
)]

use crate::exact::compensated_add;
use crate::linalg::dot;
use crate::symmetric::{cholesky_inverse, cholesky_rel, cholesky_solve, sqrt, Sym};

/// What happened to the last stretch closed by one of the output-error fits
/// ([`crate::RatioFit::close`], [`crate::TensorFit::close`] and its variants).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StretchOutcome {
    /// No sample was added since the last close.
    Empty,
    /// Fewer than 8 blocks of data: too short to fit.
    TooShort,
    /// The fit did not converge to a finite, positive estimate (no excitation, or a
    /// motion the model cannot produce); the stretch is left out.
    Failed,
    /// Fitted without a bias and pooled.
    Fitted,
    /// Fitted with a constant gyro bias (the likelihood-ratio test chose it) and pooled.
    FittedWithBias,
}

/// One block of samples: count, start time, sums of time since the block's start and of its
/// square, and for each of `K` channels its first sample and the sum of the samples' deviations
/// from it. (Sums of the raw samples would lose the digits that matter: 16 rates of 25 rad/s
/// sum to 400, whose `f32` rounding is 3e-5 rad/s, as large as the effects being fitted.)
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Block<const K: usize> {
    pub(crate) n: f32,
    /// The first sample's time, rounded; `st` and `stt` are sums of the samples' exact times
    /// less `t0` (the compensated time's low part included), so a span between blocks is
    /// taken in two parts ([`Block::since`]).
    pub(crate) t0: f32,
    pub(crate) st: f32,
    pub(crate) stt: f32,
    y0: [f32; K],
    dy: [f32; K],
}

impl<const K: usize> Block<K> {
    pub(crate) const EMPTY: Block<K> = Block {
        n: 0.0,
        t0: 0.0,
        st: 0.0,
        stt: 0.0,
        y0: [0.0; K],
        dy: [0.0; K],
    };

    /// Mean time of the block's samples.
    pub(crate) fn mean_time(&self) -> f32 {
        self.t0 + self.st / self.n
    }

    /// Time from `earlier`'s mean time to this block's, s. Not the difference of the two
    /// [`Block::mean_time`]s: each is rounded to the `f32` ulp of the time since the stretch
    /// began (0.5 us after 8 s), which at 12 rad/s and 130 rad/s^2 put 7e-5 rad/s of model
    /// error into every block mean; the rounded starts are differenced apart from the mean
    /// offsets, which hold the low parts.
    pub(crate) fn since(&self, earlier: &Block<K>) -> f32 {
        (self.t0 - earlier.t0) + (self.st / self.n - earlier.st / earlier.n)
    }

    /// Variance of the times behind the block's gyro readings, `v` of (B1): the sample
    /// times' and the readings' own ((B0), (B0')). A channel read at the sample times (the
    /// rotor's) has this less the readings' own.
    pub(crate) fn time_var(&self) -> f32 {
        let m = self.st / self.n;
        let v = self.stt / self.n - m * m;
        if v > 0.0 {
            v
        } else {
            0.0
        }
    }

    /// Central moments `(v, mu4, mu6)` of the block's sample times: `v` from the sums
    /// ([`Block::time_var`]); `mu4`, `mu6` from `v` and `n` as for `n` equally spaced samples
    /// (spacing `d`, `v = (n^2 - 1) d^2 / 12`):
    ///
    /// ```text
    /// mu4 = (n^2 - 1)(3 n^2 - 7) d^4 / 240         = 3/5 v^2 (3 n^2 - 7) / (n^2 - 1)
    /// mu6 = (n^2 - 1)(3 n^4 - 18 n^2 + 31) d^6 / 1344 = 9/7 v^3 (3 n^4 - 18 n^2 + 31) / (n^2 - 1)^2
    /// ```
    ///
    /// (1.8 v^2 and 3.86 v^3 for long blocks). The odd moments are zero for such blocks. Only
    /// the higher terms of the block mean's expansion use `mu4` and `mu6`, so a block of
    /// jittered samples is off by the jitter's share of a small term.
    pub(crate) fn time_moments(&self) -> [f32; 3] {
        let v = self.time_var();
        let n2 = self.n * self.n;
        if !(n2 > 1.0) {
            return [v, 0.0, 0.0];
        }
        let q = n2 - 1.0;
        let mu4 = 0.6 * v * v * (3.0 * n2 - 7.0) / q;
        let mu6 = (9.0 / 7.0) * v * v * v * (3.0 * n2 * n2 - 18.0 * n2 + 31.0) / (q * q);
        [v, mu4, mu6]
    }

    /// `mean(k) - x`, without rounding the mean first: `(y0 - x) + dy / n`. The first
    /// sample `y0` and a model value `x` near it differ exactly, so the deviation keeps the
    /// digits a rounded mean of a rate of 12 rad/s would lose (half an ulp, 5e-7 rad/s, on
    /// residuals of 5e-4: the fit's cost then moved by 1e-4 of itself between evaluations
    /// with no real change, a unit of log-likelihood on a 4 s flight).
    pub(crate) fn deviation(&self, k: usize, x: f32) -> f32 {
        let (y0, dy) = (
            self.y0.get(k).copied().unwrap_or(0.0),
            self.dy.get(k).copied().unwrap_or(0.0),
        );
        (y0 - x) + dy / self.n
    }

    /// Mean of channel `k`.
    pub(crate) fn mean(&self, k: usize) -> f32 {
        self.y0[k] + self.dy[k] / self.n
    }

    /// This block and the later `o` as one, sums referred to this block's start and first
    /// sample.
    fn merge(&self, o: &Block<K>) -> Block<K> {
        let d = o.t0 - self.t0;
        let mut dy = self.dy;
        for k in 0..K {
            dy[k] += o.dy[k] + o.n * (o.y0[k] - self.y0[k]);
        }
        Block {
            n: self.n + o.n,
            t0: self.t0,
            st: self.st + o.st + o.n * d,
            stt: self.stt + o.stt + 2.0 * d * o.st + o.n * d * d,
            y0: self.y0,
            dy,
        }
    }
}

/// How far the block mean's expansion must go (2, 4 or 6), from the first coefficients `c_0 =
/// w(tbar)` and `c_2 = w''/2` of the motion at a block's mean time: the terms fall roughly like
/// `(|c_2| / |c_0|)^k mu_2k`, and a term below 1e-6 of `|w|` is left out (a gyro's noise on a
/// block mean is hundreds of times more; with 1e-8, the `f32` rounding of `w`, the paper's
/// 20 s flight would take every term to sixth order and make its fit dearer for nothing the
/// benchmark can see). Short blocks (most flights) stop at the `v/2 w''` term. Shared by
/// both fits' block means.
pub(crate) fn higher_orders(mu4: f32, mu6: f32, c0: &[f32; 3], c2: &[f32; 3]) -> usize {
    let (w2, c22) = (dot(*c0, *c0), dot(*c2, *c2));
    let r = if w2 > 0.0 { c22 / w2 } else { 0.0 };
    if !(mu4 * mu4 * r * r > 1e-12) {
        2
    } else if !(mu6 * mu6 * r * r * r > 1e-12) {
        4
    } else {
        6
    }
}

/// At most `N` block means of `K` channels of one stretch (a free flight).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct BlockBuffer<const N: usize, const K: usize> {
    blocks: [Block<K>; N],
    len: usize,
    /// Samples per block at the current merge level.
    span: f32,
    cur: Block<K>,
    /// Time since the stretch's first sample, compensated sum (the time is `t - t_lo`).
    t: f32,
    t_lo: f32,
    started: bool,
    /// A time step that could not be used: the stretch takes no more samples.
    frozen: bool,
    samples: u32,
}

impl<const N: usize, const K: usize> BlockBuffer<N, K> {
    pub(crate) const EMPTY: Self = BlockBuffer {
        blocks: [Block::EMPTY; N],
        len: 0,
        span: 1.0,
        cur: Block::EMPTY,
        t: 0.0,
        t_lo: 0.0,
        started: false,
        frozen: false,
        samples: 0,
    };

    /// Adds one sample: channels `y` (used only when `usable`), the time since the previous
    /// sample (ignored for the stretch's first) and `spread`, the variance of the times behind
    /// it ([`Readings::spread`]: 0 for a single reading at an instant; it adds to the block's `v`
    /// of (B1)). A time step that is not finite, not positive or above `max_dt` freezes the
    /// stretch: the time of what follows is not known well enough for a trajectory.
    pub(crate) fn add(&mut self, y: &[f32; K], usable: bool, dt: f32, max_dt: f32, spread: f32) {
        if self.frozen {
            return;
        }
        if self.started {
            if !(dt > 0.0 && dt <= max_dt) {
                self.frozen = true;
                return;
            }
            // Compensated sum: 20 s of 1 kHz steps keep the time to a few ulp.
            compensated_add(&mut self.t, &mut self.t_lo, dt);
        }
        self.started = true;
        if !usable {
            return;
        }
        let c = &mut self.cur;
        if c.n == 0.0 {
            c.t0 = self.t;
            c.y0 = *y;
        }
        // The sample's exact time (`t - t_lo`) less the block's rounded start.
        let tb = (self.t - c.t0) - self.t_lo;
        c.n += 1.0;
        c.st += tb;
        c.stt += tb * tb + spread;
        for k in 0..K {
            c.dy[k] += y[k] - c.y0[k];
        }
        self.samples = self.samples.saturating_add(1);
        if c.n >= self.span {
            self.push();
        }
    }

    /// Moves the current block into the buffer, merging neighbours when it is full.
    fn push(&mut self) {
        if self.cur.n == 0.0 {
            return;
        }
        if self.len >= N {
            let half = N / 2;
            for i in 0..half {
                let (a, b) = (
                    self.blocks.get(2 * i).copied(),
                    self.blocks.get(2 * i + 1).copied(),
                );
                if let (Some(a), Some(b), Some(dst)) = (a, b, self.blocks.get_mut(i)) {
                    *dst = a.merge(&b);
                }
            }
            self.len = half;
            self.span *= 2.0;
        }
        if let Some(dst) = self.blocks.get_mut(self.len) {
            *dst = self.cur;
            self.len += 1;
        }
        self.cur = Block::EMPTY;
    }

    /// The stretch's blocks, the one being filled included.
    pub(crate) fn finish(&mut self) -> &[Block<K>] {
        self.push();
        let len = if self.len < N { self.len } else { N };
        self.blocks.get(..len).unwrap_or(&[])
    }

    /// Samples in the stretch.
    pub(crate) fn samples(&self) -> u32 {
        self.samples
    }

    /// Empties the buffer for the next stretch.
    pub(crate) fn clear(&mut self) {
        self.len = 0;
        self.span = 1.0;
        self.cur = Block::EMPTY;
        self.t = 0.0;
        self.t_lo = 0.0;
        self.started = false;
        self.frozen = false;
        self.samples = 0;
    }
}

/// `F^-1` via the Jacobi-scaled Cholesky factor (unscaled back); `None` when `F` is not
/// numerically positive definite.
pub(crate) fn scaled_inverse<const P: usize>(f: &Sym<P>) -> Option<Sym<P>> {
    let (d, l) = scaled_cholesky(f)?;
    let mut inv = cholesky_inverse(&l);
    for i in 0..P {
        for j in 0..P {
            inv[i][j] *= d[i] * d[j];
        }
    }
    Some(inv)
}

/// The Jacobi-scaled Cholesky factor of `F`: `D = diag(1 / sqrt(F_ii))` and `L` with
/// `D F D = L L^T`; `None` when `F` is not numerically positive definite.
pub(crate) fn scaled_cholesky<const P: usize>(f: &Sym<P>) -> Option<([f32; P], Sym<P>)> {
    let mut d = [0.0f32; P];
    for i in 0..P {
        if !(f[i][i] > 0.0) {
            return None;
        }
        d[i] = 1.0 / sqrt(f[i][i]);
    }
    let mut m = *f;
    for i in 0..P {
        for j in 0..P {
            m[i][j] *= d[i] * d[j];
        }
    }
    Some((d, cholesky_rel(&m, 1e-6)?))
}

/// What the fits know of how each gyro reading spreads over time ((B0), (B0')): the time
/// variance of its averaging window over its interval squared (`window`: 0 for a reading at
/// an instant, `1/12` for the mean over the whole interval, as a PX4 `sensor_combined` gyro
/// reports) and of the low-pass filters it has passed through (`smoothing`, s^2). Both fits
/// keep one, set by their `with_reading_window` and `with_reading_smoothing`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Readings {
    window: f32,
    smoothing: f32,
}

impl Readings {
    /// Readings at instants, unfiltered.
    pub(crate) const INSTANTS: Readings = Readings {
        window: 0.0,
        smoothing: 0.0,
    };

    /// The same with the window `window` when in `(0, 1)` (a window's time variance over its
    /// interval squared is at most `1/4`), else 0 (a reading at an instant).
    pub(crate) const fn with_window(mut self, window: f32) -> Self {
        self.window = if window > 0.0 && window < 1.0 {
            window
        } else {
            0.0
        };
        self
    }

    /// The same with the filters' time variance `smoothing` (s^2) when in `(0, 1e-4]` (a
    /// first-order stage at 16 Hz; beyond, the expansion's next terms would matter on a
    /// thrown body's motion), else 0.
    pub(crate) const fn with_smoothing(mut self, smoothing: f32) -> Self {
        self.smoothing = if smoothing > 0.0 && smoothing <= 1e-4 {
            smoothing
        } else {
            0.0
        };
        self
    }

    /// The variance of the times behind one sample that is the mean of `inputs` equally
    /// spaced readings spanning a step `dt`:
    ///
    /// ```text
    /// v = (m^2 - 1) / 12 (dt / m)^2  +  window (dt / m)^2 + smoothing            (B0, B0')
    /// ```
    ///
    /// (the spread of the readings' centres plus the mean of their own spreads), returned as
    /// its two parts: the centres' (every channel's) and the readings' own (the gyro's alone:
    /// the rotor's speed is neither averaged over a gyro's window nor filtered by its
    /// filters). With `m = 1` and `window = 1/12` the sum is `dt^2 / 12`, the uniform
    /// window's.
    pub(crate) fn spread(&self, dt: f32, inputs: u8) -> [f32; 2] {
        let Readings { window, smoothing } = *self;
        // One reading at an instant (every sample of a gyro below 1.5 kHz) returns at once:
        // this runs on every sample.
        if inputs <= 1 {
            return if window > 0.0 && dt.is_finite() {
                [0.0, window * dt * dt + smoothing]
            } else {
                [0.0, smoothing]
            };
        }
        let m = f32::from(inputs);
        if dt.is_finite() {
            let d = dt / m;
            [(m * m - 1.0) / 12.0 * d * d, window * d * d + smoothing]
        } else {
            [0.0, smoothing]
        }
    }
}

/// Cost and normal equations at a parameter vector (see the module docs).
pub(crate) type Normal<const P: usize> = (f32, Sym<P>, [f32; P]);

/// The weighted normal equations being summed: `C += n r^2`, `F += n s s^T`, `g += n s r`
/// for each residual `r` with sensitivity row `s` and weight `n` (the block's sample count).
pub(crate) struct NormalSums<const P: usize> {
    cost: f32,
    f: Sym<P>,
    g: [f32; P],
}

impl<const P: usize> NormalSums<P> {
    pub(crate) const EMPTY: Self = NormalSums {
        cost: 0.0,
        f: [[0.0; P]; P],
        g: [0.0; P],
    };

    /// Adds one residual `r` with its row `s` and weight `n`.
    pub(crate) fn add(&mut self, n: f32, r: f32, s: &[f32; P]) {
        self.cost += n * r * r;
        for c in 0..P {
            let ns = n * s[c];
            self.g[c] += ns * r;
            for d in c..P {
                self.f[c][d] += ns * s[d];
            }
        }
    }

    /// Adds one residual `r` of weight `n` to the cost alone.
    pub(crate) fn add_cost(&mut self, n: f32, r: f32) {
        self.cost += n * r * r;
    }

    /// The sums with `F` made symmetric; `None` when anything is not finite.
    pub(crate) fn finish(mut self) -> Option<Normal<P>> {
        for c in 0..P {
            for d in 0..c {
                self.f[c][d] = self.f[d][c];
            }
        }
        let finite = self.cost.is_finite()
            && self
                .f
                .iter()
                .flatten()
                .chain(self.g.iter())
                .all(|v| v.is_finite());
        finite.then_some((self.cost, self.f, self.g))
    }
}

/// Most RK4 steps between two block means.
const MAX_SUBSTEPS: u32 = 512;

/// RK4 steps over `span` seconds for a motion whose fastest rate is `rate` (rad/s): steps no
/// longer than `0.1 / rate` (local error about `0.1^5 / 120`, 8e-8 of the state: the `f32`
/// rounding of the state itself, which is what limits the noise-free error; steps of
/// `0.05 / rate` cost twice as much and left the benchmark's noise-free errors where they were,
/// at most 1e-6), at least one, at most 512.
pub(crate) fn substeps(span: f32, rate: f32) -> u32 {
    let want = span * rate * 10.0;
    if !(want < MAX_SUBSTEPS as f32) {
        MAX_SUBSTEPS
    } else if want < 1.0 {
        1
    } else {
        want as u32 + 1
    }
}

/// Levenberg-Marquardt on growing prefixes of `total` blocks: 16 blocks, then doubling, up to
/// 10 steps each and 30 on the whole record, so the trajectory's phase is never far from the
/// data. A prefix is done at [`STAGE_TOLERANCE`] (the next one moves the optimum by about a
/// standard deviation anyway), the whole record at [`TOLERANCE`]; the first prefix starts
/// cold, the others from the prefix before. `normal(theta, limit)` evaluates the first
/// `limit` blocks. Returns the parameters, cost and normal matrix on all blocks.
pub(crate) fn staged_fit<const P: usize>(
    normal: impl Fn(&[f32; P], usize) -> Option<Normal<P>>,
    theta: [f32; P],
    total: usize,
) -> Option<([f32; P], f32, Sym<P>)> {
    let mut theta = theta;
    let mut limit = if total < 16 { total } else { 16 };
    let mut start = Start::Cold;
    loop {
        let last = limit == total;
        let dof = (3 * limit) as f32 - P as f32;
        let (iters, tol) = if last {
            (30, TOLERANCE)
        } else {
            (10, STAGE_TOLERANCE)
        };
        let (t, cost, f) = levenberg(|p| normal(p, limit), theta, iters, dof, tol, start)?;
        theta = t;
        start = Start::Warm;
        if last {
            return Some((theta, cost, f));
        }
        limit = if 2 * limit < total { 2 * limit } else { total };
    }
}

/// The fit of the whole record: [`levenberg`] on all the blocks at once, and [`staged_fit`]
/// (growing prefixes) only when that does not fit to twice `noise_floor` (its cost above
/// `4 noise_floor^2` per degree of freedom), the lower cost of the two taken.
///
/// Why all the blocks first: growing prefixes keep a start whose trajectory drifts away from
/// the data from being pulled into a wrong basin by the far blocks, and a wrong basin does not
/// fit (its trajectory is out of phase with the data), so it is caught by the cost and the
/// prefixes are run then. From a good start they only cost evaluations and throw information
/// away: on a short noisy toss the tensor fit's first 16 blocks determine its eight
/// parameters so poorly that the staged fit can leave the right basin, and the ratio fit would
/// spend several times the evaluations of its trajectory for the same optimum (`bench-mcu`
/// measures the fit's cost after the benchmark's 85-sample toss).
pub(crate) fn whole_or_staged<const P: usize>(
    normal: impl Fn(&[f32; P], usize) -> Option<Normal<P>>,
    theta: [f32; P],
    total: usize,
    noise_floor: f32,
) -> Option<([f32; P], f32, Sym<P>)> {
    let dof = (3 * total) as f32 - P as f32;
    let direct = levenberg(|p| normal(p, total), theta, 30, dof, TOLERANCE, Start::Cold);
    let fits = 4.0 * noise_floor * noise_floor * dof;
    match direct {
        Some(d) if d.1 <= fits => Some(d),
        d => {
            let staged = staged_fit(normal, theta, total);
            match (d, staged) {
                (Some(d), Some(st)) => Some(if st.1 < d.1 { st } else { d }),
                (d, st) => d.or(st),
            }
        }
    }
}

/// Where a fit of the whole record stops: the Gauss-Newton step is predicted to lower the cost
/// by less than this many residual variances (`TOLERANCE / 2` units of log-likelihood, a tenth
/// of a standard deviation along the worst direction: at most 1 % more variance).
pub(crate) const TOLERANCE: f32 = 0.01;

/// Where a fit of a prefix stops ([`staged_fit`]), in the units of [`TOLERANCE`].
pub(crate) const STAGE_TOLERANCE: f32 = 1.0;

/// Where a Levenberg-Marquardt fit starts, which sets the damping of its first step (on the
/// normal matrix scaled to a unit diagonal).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Start {
    /// From a rough guess (a per-axis least-squares start, a tensor from the equation error):
    /// 1e-3. Undamped, the first step from such a start on a short toss at 100 Hz overshoots
    /// into another minimum often enough to take the benchmark's `toss` scenario far above the
    /// bound on `a1`.
    Cold,
    /// From a nearby optimum (a prefix's, the plain model's for the bias model or a refit):
    /// 1e-7, also the damping's floor. The scaled matrices are ill-conditioned (the moments
    /// and the initial rates are correlated), and a damping of 1e-3 would shorten the steps
    /// along the weak directions tenfold per iteration: more evaluations on a long flight, and
    /// a fit of a fast tumble stopped short of its optimum, above the bound.
    Warm,
}

impl Start {
    fn damping(self) -> f32 {
        match self {
            Start::Cold => 1e-3,
            Start::Warm => MU_FLOOR,
        }
    }
}

/// The least damping.
const MU_FLOOR: f32 = 1e-7;

/// Levenberg-Marquardt from `theta` on the cost `normal` evaluates (`None` where the
/// parameters are not admissible), at most `iters` steps; `dof` is the number of residuals
/// minus `P`. Converged when the Gauss-Newton model predicts a fall of the cost below `tol`
/// residual variances (cost over `dof`): that last step is taken without another evaluation
/// (whatever it gains, at most `tol` is left). The damping starts as `start` says, is raised
/// tenfold after a refused step and after one that gained under a quarter of its prediction,
/// and lowered tenfold after one that gained over three quarters. Returns the final
/// parameters, and the cost and normal matrix of the last point evaluated (the step before
/// them when converged).
pub(crate) fn levenberg<const P: usize>(
    normal: impl Fn(&[f32; P]) -> Option<Normal<P>>,
    theta: [f32; P],
    iters: u32,
    dof: f32,
    tol: f32,
    start: Start,
) -> Option<([f32; P], f32, Sym<P>)> {
    let (mut cost, mut f, mut g) = normal(&theta)?;
    let mut theta = theta;
    let mut mu = start.damping();
    for _ in 0..iters {
        let mut d = [0.0f32; P];
        for i in 0..P {
            d[i] = if f[i][i] > 0.0 {
                1.0 / sqrt(f[i][i])
            } else {
                0.0
            };
        }
        let mut m = f;
        let mut rhs = [0.0f32; P];
        for i in 0..P {
            for j in 0..P {
                m[i][j] *= d[i] * d[j];
            }
            m[i][i] += mu;
            rhs[i] = g[i] * d[i];
        }
        let Some(l) = cholesky_rel(&m, 1e-7) else {
            mu *= 10.0;
            if mu > 1e6 {
                break;
            }
            continue;
        };
        let z = cholesky_solve(&l, &rhs);
        let mut step = [0.0f32; P];
        for i in 0..P {
            step[i] = z[i] * d[i];
        }
        // The Gauss-Newton model's predicted fall of the cost, `2 delta^T g - delta^T F delta`.
        let mut pred = 0.0f32;
        for i in 0..P {
            let mut fs = 0.0f32;
            for j in 0..P {
                fs += f[i][j] * step[j];
            }
            pred += step[i] * (2.0 * g[i] - fs);
        }
        let per = if dof > 0.0 { cost / dof } else { cost };
        let mut cand = theta;
        for i in 0..P {
            cand[i] += step[i];
        }
        // Only the undamped step says the optimum is reached: a damped one is short because
        // of the damping (along the weak directions even 1e-4 shortens it several-fold, and a
        // fit from a cold start that stopped there would leave the tensor up to scale of a fast
        // tumble above its bound). So a small damped step is looked at
        // again undamped (no evaluation). Below `tol` the cost's `f32` rounding (about 1e-4 of
        // itself from one evaluation to the next) would often refuse the step on noise.
        if pred < tol * per {
            if mu > MU_FLOOR {
                mu = MU_FLOOR;
                continue;
            }
            theta = cand;
            break;
        }
        match normal(&cand) {
            Some((c2, f2, g2)) if c2 < cost => {
                // The gain against the model's prediction: a step that gained less than a
                // quarter of it was too long for the quadratic model (an undamped first step
                // from a poor start on a long spin near the major axis gains a few percent of
                // its prediction, and a damping lowered after it would let the next steps
                // wander into another minimum), so the damping goes up; below three quarters
                // it stays.
                let gain = (cost - c2) / pred;
                theta = cand;
                cost = c2;
                f = f2;
                g = g2;
                mu = if gain < 0.25 {
                    mu * 10.0
                } else if gain < 0.75 {
                    mu
                } else if mu > 10.0 * MU_FLOOR {
                    mu * 0.1
                } else {
                    MU_FLOOR
                };
            }
            _ => {
                // A refused, (nearly) undamped step that was to gain under 0.025 of a unit of
                // log-likelihood (`pred < 0.05 cost / dof`): the optimum is reached as far as
                // the cost can tell (a damped step may be short only because of the damping).
                // The trajectory is integrated in `f32`, and the cost moves by about 1e-4
                // of itself from one evaluation to the next with no real change: steps
                // predicted to gain less are refused on that noise, and without this stop the
                // loop would go on refusing and taking them (the damping never back below 1e-2)
                // to its iteration limit, long after the optimum was reached. What is left is
                // at most about 0.2 standard deviations along the worst direction, 0.02
                // typically.
                if pred < 0.05 * per && mu <= 1e-2 {
                    break;
                }
                mu *= 10.0;
                if mu > 1e6 {
                    break;
                }
            }
        }
    }
    Some((theta, cost, f))
}

/// The cost of the model at `theta` refitted with three more parameters free (`normal` its
/// normal equations; `dof` the model's own degrees of freedom): a constant torque ((T4)) or
/// the gyro's scale factors ((T6)) where their test rejected it; `cost`, the model's own, if
/// that fit is not lower; `None` if it fails. The pipeline weighs it against the tensor's
/// products of inertia, which absorb part of either.
pub(crate) fn refit_cost<const P: usize>(
    normal: impl Fn(&[f32; P]) -> Option<Normal<P>>,
    theta: [f32; P],
    cost: f32,
    dof: f32,
) -> Option<f32> {
    levenberg(normal, theta, 30, dof - 3.0, TOLERANCE, Start::Warm).map(|(_, c, _)| c.min(cost))
}

/// The torque's verdict once its score test rejected the torque-free fit (`cost`, `dof`): the
/// cost with the torque fitted (`refit`) when the likelihood ratio `cost - refit` rejects too
/// ((T4) against the same threshold), or when that fit failed (the score's verdict stands).
/// The score is the likelihood ratio's approximation at the exact optimum; on a fast 8 s
/// flight the `f32` fit stops where a step of one ulp moves the cost by units of
/// log-likelihood, so the score alone can call a free body's torque significant where the
/// refit gains under one unit (the test `a_free_body_is_still_converged` runs free bodies).
pub(crate) fn torque_confirmed(
    refit: Option<f32>,
    cost: f32,
    dof: f32,
    noise_floor: f32,
) -> Option<f32> {
    match refit {
        None => Some(cost),
        Some(c) => score_rejects(cost - c, cost, dof, noise_floor).then_some(c),
    }
}

/// The score statistic `g^T F^-1 g` of the normal equations at a point (the cost the
/// Gauss-Newton step would remove): at the plain model's optimum, evaluated for the model with
/// a bias, it approximates the likelihood-ratio statistic of the bias with one evaluation
/// instead of a fit (divided by the noise variance).
pub(crate) fn score<const P: usize>(f: &Sym<P>, g: &[f32; P]) -> Option<f32> {
    let inv = scaled_inverse(f)?;
    let mut s = 0.0f32;
    for i in 0..P {
        let mut r = 0.0f32;
        for j in 0..P {
            r += inv[i][j] * g[j];
        }
        s += g[i] * r;
    }
    s.is_finite().then_some(s)
}

/// True when the bias model is worth fitting: the score statistic at the plain optimum,
/// `score / s2` with `s2` the plain model's residual variance (at least `noise_floor^2`), above
/// half the likelihood-ratio test's threshold (so no bias the test would take is skipped).
pub(crate) fn bias_worth_fitting(
    score: f32,
    cost_plain: f32,
    dof_plain: f32,
    noise_floor: f32,
) -> bool {
    if !(dof_plain > 0.0) {
        return true;
    }
    let s2 = residual_variance(cost_plain, dof_plain, noise_floor);
    !(s2 > 0.0) || score > 0.5 * BIAS_CHI2 * s2
}

/// The score (Lagrange multiplier) test of 3 more parameters at the fitted model's optimum:
/// true when `score / s2 > BIAS_CHI2` (chi-square, 3 degrees of freedom, 0.01 %), `score` the
/// statistic `g^T F^-1 g` of the extended model, `s2` the fitted model's residual variance per
/// sample but never below `noise_floor^2`. Asymptotically the likelihood-ratio test, without
/// fitting the extended model. False when `dof` is not positive.
pub(crate) fn score_rejects(score: f32, cost: f32, dof: f32, noise_floor: f32) -> bool {
    score_rejects_at(score, BIAS_CHI2, cost, dof, noise_floor)
}

/// The score statistic of the columns `extra` beyond the rest: `g^T F^-1 g` of the whole
/// model minus the same of the model without `extra` (their rows and columns of `F` and
/// entries of `g` taken out). At the smaller model's optimum the second term is zero; where
/// that optimum was not reached exactly (a fit stopped at `f32` precision, a short flight) the
/// gradient left along its own parameters is not counted against it. `None` when either
/// matrix is not positive definite.
pub(crate) fn score_beyond<const P: usize>(
    f: &Sym<P>,
    g: &[f32; P],
    extra: &[usize],
) -> Option<f32> {
    let whole = score(f, g)?;
    let (fr, gr) = without(f, g, extra);
    let rest = score(&fr, &gr)?;
    Some(whole - rest)
}

/// `F` and `g` of the model without the parameters `drop`: their rows and columns of `F`
/// replaced by those of the identity and their entries of `g` by zeros (a block-diagonal `F`
/// whose score is the smaller model's).
pub(crate) fn without<const P: usize>(
    f: &Sym<P>,
    g: &[f32; P],
    drop: &[usize],
) -> (Sym<P>, [f32; P]) {
    let mut fr = *f;
    let mut gr = *g;
    for &k in drop {
        for i in 0..P {
            if let Some(x) = fr.get_mut(k).and_then(|row| row.get_mut(i)) {
                *x = 0.0;
            }
            if let Some(x) = fr.get_mut(i).and_then(|row| row.get_mut(k)) {
                *x = 0.0;
            }
        }
        if let Some(x) = fr.get_mut(k).and_then(|row| row.get_mut(k)) {
            *x = 1.0;
        }
        if let Some(x) = gr.get_mut(k) {
            *x = 0.0;
        }
    }
    (fr, gr)
}

/// [`score_rejects`] at the chi-square threshold `chi2` instead of 3 degrees of freedom's.
pub(crate) fn score_rejects_at(
    score: f32,
    chi2: f32,
    cost: f32,
    dof: f32,
    noise_floor: f32,
) -> bool {
    if !(dof > 0.0) {
        return false;
    }
    let s2 = residual_variance(cost, dof, noise_floor);
    s2 > 0.0 && score > chi2 * s2
}

/// `cost / dof`, at least `noise_floor^2`.
fn residual_variance(cost: f32, dof: f32, noise_floor: f32) -> f32 {
    let seen = cost / dof;
    let floor = noise_floor * noise_floor;
    if seen > floor {
        seen
    } else {
        floor
    }
}

/// Chi-square (3 degrees of freedom) a constant gyro bias must exceed: 21.11, 0.01 %.
pub(crate) const BIAS_CHI2: f32 = 21.11;

/// The likelihood-ratio test of a constant gyro bias (3 more parameters): true when
/// `(cost_plain - cost_bias) / s2 > BIAS_CHI2` (chi-square, 3 degrees of freedom, 0.01 %), with
/// `s2` the bias model's residual variance per sample but never below `noise_floor^2` (on
/// nearly noise-free data the rounding of the sums is not white, and no bias is worth a
/// 3-parameter model).
pub(crate) fn bias_found(cost_plain: f32, cost_bias: f32, dof_bias: f32, noise_floor: f32) -> bool {
    if !(dof_bias > 0.0) {
        return false;
    }
    let seen = cost_bias / dof_bias;
    let floor = noise_floor * noise_floor;
    let s2 = if seen > floor { seen } else { floor };
    s2 > 0.0 && cost_plain - cost_bias > BIAS_CHI2 * s2
}

/// Free flights pooled by information: each fitted stretch adds the information of its `M`
/// parameters of interest with the others (initial rates, bias) marginalised,
/// `M_s = ((F_s^-1)_mm)^-1`; the pooled mean is `p = p_1 + (sum M_s)^-1 sum M_s (p_s - p_1)`,
/// referred to the first stretch's `p_1` (the information is large and nearly singular, and
/// `M^-1 (M p)` in `f32` would lose digits), with `cov(p) = sigma^2 (sum M_s)^-1` and
/// `sigma^2 = sum cost_s / sum dof_s`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Pooled<const M: usize> {
    info: Sym<M>,
    info_p: [f32; M],
    p_ref: [f32; M],
    /// `sum_s d_s^T M_s d_s`, `d_s = p_s - p_1`: the stretches' spread about the pooled mean
    /// follows from it ((P2)).
    spread: f32,
    cost: f32,
    dof: f32,
    pub(crate) stretches: u32,
    pub(crate) samples: u32,
}

impl<const M: usize> Pooled<M> {
    /// The pooled stretches' summed cost.
    pub(crate) fn cost(&self) -> f32 {
        self.cost
    }

    /// The pooled stretches' summed degrees of freedom.
    pub(crate) fn dof(&self) -> f32 {
        self.dof
    }

    pub(crate) const EMPTY: Self = Pooled {
        info: [[0.0; M]; M],
        info_p: [0.0; M],
        p_ref: [0.0; M],
        spread: 0.0,
        cost: 0.0,
        dof: 0.0,
        stretches: 0,
        samples: 0,
    };

    /// Adds one stretch: its parameters `p`, their unit-noise covariance block `cov_mm`, its
    /// cost, degrees of freedom and samples. False (nothing added) when the block is not
    /// invertible or anything is not finite.
    pub(crate) fn add(
        &mut self,
        p: &[f32; M],
        cov_mm: &Sym<M>,
        cost: f32,
        dof: f32,
        samples: u32,
    ) -> bool {
        let Some(m) = scaled_inverse(cov_mm) else {
            return false;
        };
        let finite = cost.is_finite() && dof > 0.0 && p.iter().all(|x| x.is_finite());
        if !finite {
            return false;
        }
        if self.stretches == 0 {
            self.p_ref = *p;
        }
        let mut d = [0.0f32; M];
        for i in 0..M {
            d[i] = p[i] - self.p_ref[i];
        }
        for i in 0..M {
            let mut s = 0.0;
            for j in 0..M {
                self.info[i][j] += m[i][j];
                s += m[i][j] * d[j];
            }
            self.info_p[i] += s;
            self.spread += d[i] * s;
        }
        self.cost += cost;
        self.dof += dof;
        self.stretches = self.stretches.saturating_add(1);
        self.samples = self.samples.saturating_add(samples);
        true
    }

    /// The pooled mean, its covariance (actual units), the residual noise `sigma` and the
    /// inflation of that covariance the stretches' spread about the mean calls for ((P2),
    /// [`spread_inflation`]; 1 for one stretch, not applied to the covariance returned);
    /// `None` before a stretch was added.
    pub(crate) fn mean(&self) -> Option<([f32; M], Sym<M>, f32, f32)> {
        if self.stretches == 0 || !(self.dof > 0.0) {
            return None;
        }
        let inv = scaled_inverse(&self.info)?;
        let s2 = self.cost / self.dof;
        let mut p = self.p_ref;
        let mut cov = inv;
        let mut explained = 0.0f32;
        for i in 0..M {
            let mut s = 0.0;
            for j in 0..M {
                s += inv[i][j] * self.info_p[j];
                cov[i][j] = inv[i][j] * s2;
            }
            p[i] += s;
            explained += s * self.info_p[i];
        }
        let spread = spread_inflation(self.spread - explained, s2, M, self.stretches);
        Some((p, cov, sqrt(s2), spread))
    }
}

/// Standard normal quantile of the spread test's 5 % ((P2)).
const SPREAD_Z: f32 = 1.645;

/// The pooled covariance's inflation from the stretches' spread ((P2)): with `chi2 = (sum_s
/// d_s^T M_s d_s - info_p^T (sum M_s)^-1 info_p) / sigma^2` (the stretches' squared distances
/// from the pooled mean in their own covariances' units, `excess` over `s2`) on
/// `k = M (S - 1)` degrees of freedom for `S` stretches,
///
/// ```text
/// inflation = chi2 / k   where chi2 > k (1 - 2/(9k) + z sqrt(2/(9k)))^3, else 1         (P2)
/// ```
///
/// (Wilson and Hilferty's chi-square quantile at `z` = [`SPREAD_Z`], 5 %): stretches that
/// disagree beyond their stated uncertainty (a walking gyro bias, a torque the model lacks)
/// widen the pooled one by their Birge ratio; stretches that agree leave it as it is.
fn spread_inflation(excess: f32, s2: f32, m: usize, stretches: u32) -> f32 {
    let k = (m as f32) * (stretches as f32 - 1.0);
    if !(k >= 1.0 && s2 > 0.0 && excess.is_finite()) {
        return 1.0;
    }
    let chi2 = excess / s2;
    let a = 2.0 / (9.0 * k);
    let c = 1.0 - a + SPREAD_Z * sqrt(a);
    let limit = k * c * c * c;
    if chi2 > limit {
        chi2 / k
    } else {
        1.0
    }
}

/// One stretch's fit as the pooling takes it: the `M` parameters of interest, their
/// unit-noise covariance block (inflated for the residual's correlation where the fit
/// measured it: `tensor_fit`'s (F10)), the cost, the number of parameters fitted and the bias
/// when the bias model was taken.
pub(crate) struct StretchResult<const M: usize> {
    pub(crate) p: [f32; M],
    pub(crate) cov: Sym<M>,
    /// What the inputs' known errors add to `cov`, in the parameters' units (not scaled by
    /// the residual's variance, as `cov` is): the tensor fit's rotor momentum read at a
    /// resolution ((F8) of `tensor_fit`).
    pub(crate) input: Option<(Sym<M>, f32)>,
    pub(crate) cost: f32,
    pub(crate) params: usize,
    pub(crate) bias: Option<[f32; 3]>,
    /// Lag-1 autocorrelation of the block residuals, measured where the fit does not fit to
    /// the noise (0 otherwise).
    pub(crate) lag1: f32,
    /// The residual, near the noise's level, is coloured (`tensor_fit`'s (F10')).
    pub(crate) coloured: bool,
    /// The cost with a constant torque fitted, when its score test rejected the torque-free
    /// model (`None`: not rejected, or not tested).
    pub(crate) torque: Option<f32>,
    /// The score test of the gyro's scale factors rejected the model (false: not tested).
    pub(crate) scale: bool,
    /// The bias model's fit of the same blocks where it was fitted but not taken (`tensor_fit`'s
    /// checked bias): its parameters of interest, unit-noise covariance, cost and parameter
    /// count, pooled apart for the pooled comparison of the two models.
    pub(crate) alt: Option<Alternative<M>>,
    /// The gyro bias's walk the fit whitened by (`tensor_fit`'s (F12)): its step variance per
    /// sample, (rad/s)^2, and the cost of the fitted parameters without the whitening
    /// (`sum_b n_b |r_b|^2`); `None` without a walk.
    pub(crate) walk: Option<(f32, f32)>,
}

/// A stretch's fit with the other bias model ([`StretchResult::alt`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Alternative<const M: usize> {
    pub(crate) p: [f32; M],
    pub(crate) cov: Sym<M>,
    pub(crate) cost: f32,
    pub(crate) params: usize,
}

/// What both fits keep between samples: the open stretch's blocks (`K` channels), the
/// information pooled over closed stretches (`M` parameters), the last bias found, and what the
/// last close did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FitState<const N: usize, const K: usize, const M: usize> {
    pub(crate) buf: BlockBuffer<N, K>,
    pub(crate) pooled: Pooled<M>,
    pub(crate) biased: bool,
    pub(crate) bias: [f32; 3],
    /// A closed stretch's score test found a constant torque.
    pub(crate) torque: bool,
    /// The pooled stretches' costs, each with the torque fitted where its test rejected.
    pub(crate) torque_cost: f32,
    /// A closed stretch's score test found the gyro's scale factors off.
    pub(crate) scale: bool,
    /// A closed stretch's residual was coloured near the noise's level (`tensor_fit`'s (F10')).
    pub(crate) coloured: bool,
    pub(crate) last: StretchOutcome,
    /// The stretches pooled with the bias model wherever it was fitted ([`StretchResult::alt`]
    /// or taken), for the pooled comparison of the two models.
    pub(crate) alt_pooled: Pooled<M>,
    /// Every stretch in `pooled` is in `alt_pooled` too.
    pub(crate) alt_complete: bool,
    /// The pooled stretches' costs without a walk's whitening ([`StretchResult::walk`]).
    pub(crate) raw_cost: f32,
    /// A pooled stretch was fitted with a walk.
    pub(crate) walked: bool,
    /// The largest walk step variance per sample found on a pooled stretch, (rad/s)^2.
    pub(crate) walk_step_var: f32,
}

impl<const N: usize, const K: usize, const M: usize> FitState<N, K, M> {
    pub(crate) const EMPTY: Self = FitState {
        buf: BlockBuffer::EMPTY,
        pooled: Pooled::EMPTY,
        biased: false,
        bias: [0.0; 3],
        torque: false,
        torque_cost: 0.0,
        scale: false,
        coloured: false,
        last: StretchOutcome::Empty,
        alt_pooled: Pooled::EMPTY,
        alt_complete: true,
        raw_cost: 0.0,
        walked: false,
        walk_step_var: 0.0,
    };

    /// Ends the open stretch: `fit` fits its blocks (at least 8), the result is pooled, and the
    /// buffer is emptied for the next stretch. What happened is returned and kept. The bias
    /// model's fit, where there is one, is pooled apart ([`FitState::alternative`]).
    pub(crate) fn close(
        &mut self,
        fit: impl FnOnce(&[Block<K>]) -> Option<StretchResult<M>>,
    ) -> StretchOutcome {
        let mut pooled = self.pooled;
        let samples = self.buf.samples();
        let mut other: Option<(Alternative<M>, bool, usize)> = None;
        let outcome = self.close_into(&mut pooled, |blocks| {
            let mut r = fit(blocks)?;
            let own = Alternative {
                p: r.p,
                cov: r.cov,
                cost: r.cost,
                params: r.params,
            };
            let alt = r.alt.take();
            other = Some(match alt {
                Some(a) => (a, true, blocks.len()),
                None => (own, r.bias.is_some(), blocks.len()),
            });
            Some(r)
        });
        self.pooled = pooled;
        if matches!(
            outcome,
            StretchOutcome::Fitted | StretchOutcome::FittedWithBias
        ) {
            match other {
                Some((a, true, n)) => {
                    let dof = (3 * n) as f32 - a.params as f32;
                    if !self.alt_pooled.add(&a.p, &a.cov, a.cost, dof, samples) {
                        self.alt_complete = false;
                    }
                }
                _ => self.alt_complete = false,
            }
        }
        outcome
    }

    /// The pooled estimate with the bias model on every stretch (mean, covariance, noise),
    /// when every pooled stretch had it fitted; `None` otherwise.
    pub(crate) fn alternative(&self) -> Option<([f32; M], Sym<M>, f32, f32)> {
        let all = self.alt_complete && self.alt_pooled.stretches == self.pooled.stretches;
        if all {
            self.alt_pooled.mean()
        } else {
            None
        }
    }

    /// Keeps a pooled stretch's tests: whether its torque test rejected, and its cost with the
    /// torque; its scale test; whether its residual was coloured; its walk.
    fn note_torque<const M2: usize>(&mut self, r: &StretchResult<M2>) {
        self.torque |= r.torque.is_some();
        self.torque_cost += r.torque.unwrap_or(r.cost);
        self.scale |= r.scale;
        self.coloured |= r.coloured;
        if let Some((step_var, raw)) = r.walk {
            self.walked = true;
            self.raw_cost += raw;
            if step_var > self.walk_step_var {
                self.walk_step_var = step_var;
            }
        } else {
            self.raw_cost += r.cost;
        }
    }

    /// [`FitState::close`] pooling into `pooled` instead of the state's own (a fit of other
    /// parameters of the same blocks: the tensor up to scale).
    pub(crate) fn close_into<const M2: usize>(
        &mut self,
        pooled: &mut Pooled<M2>,
        fit: impl FnOnce(&[Block<K>]) -> Option<StretchResult<M2>>,
    ) -> StretchOutcome {
        let samples = self.buf.samples();
        let blocks = self.buf.finish();
        let outcome = if blocks.is_empty() {
            StretchOutcome::Empty
        } else if blocks.len() < 8 {
            StretchOutcome::TooShort
        } else {
            let dof_of = |params: usize| (3 * blocks.len()) as f32 - params as f32;
            match fit(blocks) {
                Some(r) => {
                    if !pooled.add(&r.p, &r.cov, r.cost, dof_of(r.params), samples) {
                        StretchOutcome::Failed
                    } else if let Some(b) = r.bias {
                        self.note_torque(&r);
                        self.biased = true;
                        self.bias = b;
                        StretchOutcome::FittedWithBias
                    } else {
                        self.note_torque(&r);
                        StretchOutcome::Fitted
                    }
                }
                None => StretchOutcome::Failed,
            }
        };
        self.buf.clear();
        self.last = outcome;
        outcome
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two stretches of one parameter, each with unit-noise variance 1 and a residual variance
    /// of 1 (cost = dof): the pooled variance is 1/2, as fitted when they agree, and times their
    /// Birge ratio `chi2 / k` when they are further apart than the 5 % test allows ((P2):
    /// `chi2 = d^2 / 2` for two values `d` apart).
    #[test]
    fn stretches_that_disagree_widen_the_pool_by_their_birge_ratio() {
        let pool = |d: f32| {
            let mut p = Pooled::<1>::EMPTY;
            assert!(p.add(&[10.0], &[[1.0]], 100.0, 100.0, 100));
            assert!(p.add(&[10.0 + d], &[[1.0]], 100.0, 100.0, 100));
            let (m, cov, _, k) = p.mean().unwrap();
            (m[0], cov[0][0], k)
        };
        let (m, v, k) = pool(1.0);
        assert!((m - 10.5).abs() < 1e-5 && (v - 0.5).abs() < 1e-6 && k == 1.0);
        // chi2 = 8 on one degree of freedom: beyond the 5 % point (3.84).
        let (_, _, k) = pool(4.0);
        assert!((k - 8.0).abs() < 1e-3, "{k}");
        // One stretch: nothing to compare.
        let mut p = Pooled::<1>::EMPTY;
        p.add(&[1.0], &[[1.0]], 1.0, 1.0, 1);
        assert_eq!(p.mean().unwrap().3, 1.0);
    }
}
