//! Free-flight detection from the accelerometer and the gyro, and the gyro bias from still
//! periods.
//!
//! # Physics
//!
//! In free flight the centre of mass falls freely, so an accelerometer at the offset `r` from
//! the centre of mass reads only the rotation about it:
//!
//! ```text
//! f = w x (w x r) + w' x r = K(w, w') r,     K = [w]x [w]x + [w']x            (F1)
//! ```
//!
//! (`[v]x` the cross-product matrix). On a bench, in a hand or at the catch, gravity, the hand
//! or the impact add a force that (F1) cannot explain with a small constant `r`. The gate fits
//! `r` by least squares to the samples of a sliding window (`w` and `f` at the midpoint of
//! consecutive samples, `w'` their difference over `dt`) and calls the window free when the
//! fit's RMS residual is below [`GateSettings::max_residual`] and `|r|` is at most
//! [`GateSettings::max_offset`]. A plain `|f| < threshold` test would fail: at 30 rad/s and
//! 11 mm, (F1) exceeds 1 g.
//!
//! A hand's slow turn can pass that test with a large `r`: what the hand adds to gravity's
//! support stays nearly constant in the body over a window, and `K r` for a large `r` turning
//! slowly imitates part of it. So (F1) alone may only give offsets up to
//! [`GateSettings::max_offset`] (0.1 m); a window whose offset lies beyond it, up to
//! [`GateSettings::far_offset`] (0.3 m: a large object whose flight controller sits off its
//! centre of mass), must also pass a test of that constant force,
//!
//! ```text
//! f = K(w, w') r + c,     c constant over the window                              (F2)
//! ```
//!
//! fitted on the window's sums centred on their means: in free flight there is no `c` to
//! find and (F2) takes only noise from the residual of (F1); in a hand it finds the support.
//! The window is free when the RMS (F2) takes is below [`GateSettings::max_support`]
//! (0.5 m/s^2): between the windows wholly in free flight, nearly all far below it (the few
//! above are refused, a few blocks of free flight lost), and the hand windows with the IMU
//! 0.1-0.3 m off the centre of mass, above it. The test `gate_sim` measures both on simulated
//! throws with the IMU off the centre of mass.
//!
//! Both sides of (F1) pass through the same low-pass filter ([`GateSettings::lowpass_hz`])
//! before the fit: a linear filter keeps `f = K r` exact for a constant `r`, and it removes what
//! is no contact force but no rigid-body rotation either, the vibration of a spinning rotor's
//! imbalance. On the shared thrown-FC logs the flywheel at 1200-1600 rad/s shakes the
//! accelerometer by several m/s^2, so without the filter the gate would cut a board-alone throw
//! in two and lose the spin-up's peak, where the rotor momentum tells most; with it the free
//! residual stays below [`GateSettings::max_residual`] and each throw is one free flight.
//!
//! The window is made of blocks; per sample only the sums `K^T K`, `K^T f` and `|f|^2` of the
//! open block are updated (about 60 floating-point operations), and one 3x3 solve is done per
//! block. The window's sums are never kept as a running total (adding the newest block and
//! subtracting the oldest would let rounding drift over a long log): the blocks are taken in
//! chunks of one window length, and each window is the sum of two fresh partial sums, the tail
//! of the previous chunk (suffix sums, formed once per chunk) and the head of the current one
//! (a prefix sum). That is three block additions per block instead of one per block of the
//! window.
//!
//! # Still periods and the gyro bias
//!
//! A window is still when the specific force stays within [`GateSettings::still_accel`] of
//! one `g`, every rate stays below [`GateSettings::still_rate`] and the rates' spread over the
//! window stays below [`GateSettings::still_spread`]; the mean rate over the
//! longest run of still windows so far is the gyro bias, subtracted by [`crate::pipeline::Pipeline`] before the
//! estimator sees a sample.
//!
//! # The accelerometer's unit
//!
//! While the gyro is still the specific force is one `g` in any orientation, give or take what
//! a hand adds: [`AccelUnits`] counts the still samples that read within a factor of two of
//! `G` against those that do not. A log in g (about 1 while still), milli-g or mm/s^2 reads
//! far from it on nearly every such sample, and then the gate's thresholds, set in m/s^2, mean
//! nothing (in g a hand's motion looks 9.8 times smaller and passes for free flight).

use crate::linalg::dot;
use crate::symmetric::{cholesky, cholesky_solve, sqrt};

/// The accelerometer's magnitude while the gyro is still (see the module docs): `looks_wrong`
/// once at least [`AccelUnits::MIN_STILL`] still samples were seen and fewer than one in twenty
/// read `|f|` within `[G/2, 2 G]` (a body dropped without spin reads nearly zero while still,
/// and so do a few samples at a release: too few to outvote a bench or a hand).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AccelUnits {
    still: u32,
    near_g: u32,
    sum: f32,
}

impl AccelUnits {
    /// Still samples needed before a verdict.
    pub const MIN_STILL: u32 = 50;

    /// Nothing seen.
    pub const fn new() -> Self {
        AccelUnits {
            still: 0,
            near_g: 0,
            sum: 0.0,
        }
    }

    /// One sample taken with every rate below the still threshold: `fa = |f|` as read.
    pub fn push_still(&mut self, fa: f32) {
        self.still = self.still.saturating_add(1);
        if (0.5 * G..=2.0 * G).contains(&fa) {
            self.near_g = self.near_g.saturating_add(1);
        }
        if fa.is_finite() {
            self.sum += fa;
        }
    }

    /// One sample: rates `w` (rad/s), specific force `f` as read; counted when every rate is
    /// below `still_rate` (rad/s).
    pub fn push(&mut self, w: [f32; 3], f: [f32; 3], still_rate: f32) {
        if w.iter().all(|x| x.abs() < still_rate) {
            self.push_still(sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]));
        }
    }

    /// True when the still samples say the accelerometer is not in m/s^2.
    pub fn looks_wrong(&self) -> bool {
        self.still >= Self::MIN_STILL && (self.near_g as u64) * 20 < self.still as u64
    }

    /// Still samples seen.
    pub fn still_samples(&self) -> u32 {
        self.still
    }

    /// Mean `|f|` over the still samples, as read (`None` before one).
    pub fn mean(&self) -> Option<f32> {
        (self.still > 0).then(|| self.sum / self.still as f32)
    }
}

/// Standard gravity, m/s^2.
pub const G: f32 = 9.806_65;

/// Rates below this on every axis are a still gyro, rad/s: [`GateSettings::still_rate`] of
/// [`GateSettings::for_rate`], and what a host judging a whole log by [`AccelUnits`] uses.
pub const STILL_RATE: f32 = 0.05;

/// Most blocks in a window.
pub const MAX_WINDOW_BLOCKS: usize = 16;

/// Fewest samples [`GateSettings::for_rate`] puts in a window (the three offsets of (F1) are
/// fitted to it).
const MIN_WINDOW_SAMPLES: f32 = 16.0;

/// Tuning of [`FreeFlightGate`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GateSettings {
    /// Samples per block (1 to 1024).
    pub block: u16,
    /// Blocks per window (1 to [`MAX_WINDOW_BLOCKS`]).
    pub window_blocks: u8,
    /// Largest RMS residual of (F1) in a free window, m/s^2.
    pub max_residual: f32,
    /// Largest distance from the accelerometer to the centre of mass that the fit of (F1) alone
    /// may give a free window, m. Beyond it a hand's slow turn can pass: what a hand adds to
    /// gravity's support stays nearly constant in the body over a window, and a large `r`
    /// turning slowly imitates part of it within [`GateSettings::max_residual`].
    pub max_offset: f32,
    /// Largest distance, m, a free window may have when (F2) also holds: a constant force `c`
    /// beside `K r` takes at most [`GateSettings::max_support`] (RMS) from the residual. (For a
    /// large object whose flight controller sits off its centre of mass.)
    pub far_offset: f32,
    /// Largest RMS, m/s^2, that the constant force of (F2) may take from the (F1) residual in
    /// a window whose offset lies beyond [`GateSettings::max_offset`]: in free flight there is
    /// none to find and it takes mostly noise (nearly all windows far below 0.5 m/s^2), in a
    /// hand it finds the support (above it); the test `gate_sim` measures both on simulated
    /// throws with the IMU off the centre of mass.
    pub max_support: f32,
    /// Still: `| |f| - g |` below this, m/s^2, on every sample of the window.
    pub still_accel: f32,
    /// Still: every rate component below this, rad/s (above any plausible gyro bias).
    pub still_rate: f32,
    /// Still: the standard deviation of every rate component over the window below this,
    /// rad/s (a hand turning the body slowly is not still; the gyro's own noise is far less).
    pub still_spread: f32,
    /// Corner frequency, Hz, of the low-pass filter applied to both sides of (F1) before the
    /// fit (two first-order stages). A spinning rotor's imbalance shakes the accelerometer at
    /// the rotor's speed (a flywheel at 1500 rad/s: 240 Hz, 5-7 m/s^2 RMS on the shared
    /// thrown-FC logs), which is no contact force; the rigid-body terms live below about
    /// 15 Hz. The same linear filter on `K` and `f` keeps `f = K r` exact. `INFINITY` for none.
    pub lowpass_hz: f32,
}

impl GateSettings {
    /// Settings for a sample rate: windows of about 40 ms (as many blocks of about 2.5 ms as
    /// fit, at most [`MAX_WINDOW_BLOCKS`]: the window's length in time decides how long a touch
    /// must last to be seen) but never fewer than 16 samples (below 400 Hz the window is 16
    /// one-sample blocks, longer than 40 ms: three offsets are fitted to it), residual 2 m/s^2
    /// (0.2 g), offset up to 0.1 m (0.3 m when (F2) finds no support beyond 0.5 m/s^2), still
    /// within 0.5 m/s^2 of `g`, rates below 0.05 rad/s
    /// (3 deg/s) and their spread over the window below 0.01 rad/s.
    pub fn for_rate(rate_hz: f32) -> Self {
        // Samples per block: about 2.5 ms, rounded (1 to 1024).
        let b = rate_hz * 0.0025 + 0.5;
        let block = if b >= 1024.0 {
            1024
        } else if b >= 1.0 {
            b as u16
        } else {
            1
        };
        // Blocks per window: 40 ms of blocks, rounded, and at least 16 samples (1 to
        // MAX_WINDOW_BLOCKS).
        let bf = f32::from(block);
        let w = 0.04 * rate_hz / bf + 0.5;
        let least = (MIN_WINDOW_SAMPLES + bf - 1.0) / bf;
        let w = if w < least { least } else { w };
        let window_blocks = if w >= MAX_WINDOW_BLOCKS as f32 {
            MAX_WINDOW_BLOCKS as u8
        } else if w >= 1.0 {
            w as u8
        } else {
            1
        };
        GateSettings {
            block,
            window_blocks,
            max_residual: 2.0,
            max_offset: 0.1,
            far_offset: 0.3,
            max_support: 0.5,
            still_accel: 0.5,
            still_rate: STILL_RATE,
            still_spread: 0.01,
            lowpass_hz: 30.0,
        }
    }

    /// True when every field is usable.
    pub fn is_valid(&self) -> bool {
        let pos = |x: f32| x.is_finite() && x > 0.0;
        self.block >= 1
            && self.block <= 1024
            && self.window_blocks >= 1
            && self.window_blocks as usize <= MAX_WINDOW_BLOCKS
            && pos(self.max_residual)
            && pos(self.max_offset)
            && pos(self.far_offset)
            && pos(self.max_support)
            && pos(self.still_accel)
            && pos(self.still_rate)
            && pos(self.still_spread)
            && self.lowpass_hz > 0.0
    }
}

/// Sums over the samples of one block.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct BlockSums {
    /// `K^T K`: xx, yy, zz, xy, xz, yz.
    kk: [f32; 6],
    kf: [f32; 3],
    ff: f32,
    w: [f32; 3],
    /// Sum of the squared rates (the window's spread of the rate).
    ww: [f32; 3],
    n: u16,
    /// Every sample still.
    still: bool,
}

impl BlockSums {
    const ZERO: BlockSums = BlockSums {
        kk: [0.0; 6],
        kf: [0.0; 3],
        ff: 0.0,
        w: [0.0; 3],
        ww: [0.0; 3],
        n: 0,
        still: true,
    };

    fn add(&mut self, o: &BlockSums) {
        for (a, b) in self.kk.iter_mut().zip(o.kk.iter()) {
            *a += b;
        }
        for (a, b) in self.kf.iter_mut().zip(o.kf.iter()) {
            *a += b;
        }
        for (a, b) in self.w.iter_mut().zip(o.w.iter()) {
            *a += b;
        }
        for (a, b) in self.ww.iter_mut().zip(o.ww.iter()) {
            *a += b;
        }
        self.ff += o.ff;
        self.n = self.n.saturating_add(o.n);
        self.still &= o.still;
    }
}

/// What the gate concluded about the window that ended with the latest block.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WindowFit {
    /// The window is in free flight.
    pub free: bool,
    /// The window is still (on a bench or held still).
    pub still: bool,
    /// RMS residual of (F1), m/s^2.
    pub residual: f32,
    /// Fitted accelerometer offset from the centre of mass, m.
    pub offset: [f32; 3],
    /// The RMS, m/s^2, that the constant force of (F2) takes from the (F1) residual,
    /// `sqrt((rss1 - rss2) / n)`, where it was fitted: a window whose offset lies between
    /// [`GateSettings::max_offset`] and [`GateSettings::far_offset`] and whose (F1) residual
    /// is small.
    pub support: Option<f32>,
    /// Samples in the window.
    pub samples: u32,
}

/// The free-flight gate: one [`FreeFlightGate::step`] per sample with gyro and accelerometer.
///
/// ```
/// use identifier_core::{FreeFlightGate, GateSettings};
///
/// // A body spinning at 30 rad/s about z, accelerometer 15 mm off the axis: the centripetal
/// // reading (13.5 m/s^2, more than 1 g) is explained by the fit, so the window is free.
/// let mut g = FreeFlightGate::new(GateSettings::for_rate(1000.0)).unwrap();
/// let mut fit = None;
/// for _ in 0..100 {
///     fit = g.step([0.0, 0.0, 30.0], [-13.5, 0.0, 0.0], 1e-3).or(fit);
/// }
/// assert!(fit.unwrap().free);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FreeFlightGate {
    settings: GateSettings,
    prev: Option<([f32; 3], [f32; 3])>,
    open: BlockSums,
    /// The low-pass filter's two stages over the row `(K by rows, f)` of (F1).
    lowpass: Option<[[f32; 12]; 2]>,
    /// `suffix[j]`, `j >= chunk`: the sum of blocks `j..window_blocks` of the previous chunk;
    /// `suffix[j]`, `j < chunk`: block `j` of the current chunk (its slot is free once the
    /// window has moved past the previous chunk's block `j`).
    suffix: [BlockSums; MAX_WINDOW_BLOCKS],
    /// Sum of the current chunk's blocks so far.
    prefix: BlockSums,
    /// Blocks in the current chunk.
    chunk: u8,
    /// A whole chunk has been seen since the window was last broken (`suffix` is valid).
    filled: bool,
    last_fit: Option<WindowFit>,
    /// The open block's (F2) sums, and those of the window's latest blocks (a ring written at
    /// `forces_next`: once the window is `filled`, every slot holds one of its blocks).
    open_forces: ForceSums,
    forces: [ForceSums; MAX_WINDOW_BLOCKS],
    forces_next: u8,
    bias: Option<[f32; 3]>,
    /// Sum of the rates and sample count over the current run of still windows.
    still_sum: [f32; 3],
    still_n: u32,
    /// Samples behind the bias in use (the longest still run so far).
    bias_n: u32,
    /// The accelerometer's magnitude while the gyro is still.
    units: AccelUnits,
}

impl FreeFlightGate {
    /// A new gate, or `None` when the settings are not usable.
    pub fn new(settings: GateSettings) -> Option<Self> {
        settings.is_valid().then_some(FreeFlightGate {
            settings,
            prev: None,
            open: BlockSums::ZERO,
            lowpass: None,
            suffix: [BlockSums::ZERO; MAX_WINDOW_BLOCKS],
            prefix: BlockSums::ZERO,
            chunk: 0,
            filled: false,
            last_fit: None,
            open_forces: ForceSums::ZERO,
            forces: [ForceSums::ZERO; MAX_WINDOW_BLOCKS],
            forces_next: 0,
            bias: None,
            still_sum: [0.0; 3],
            still_n: 0,
            bias_n: 0,
            units: AccelUnits::new(),
        })
    }

    /// The settings.
    pub fn settings(&self) -> &GateSettings {
        &self.settings
    }

    /// The latest window's fit, `None` before the first full window.
    pub fn last_fit(&self) -> Option<WindowFit> {
        self.last_fit
    }

    /// Gyro bias from the latest still window (rad/s), `None` before one was seen.
    pub fn bias(&self) -> Option<[f32; 3]> {
        self.bias
    }

    /// What the still samples say of the accelerometer's unit ([`AccelUnits`]).
    pub fn accel_units(&self) -> AccelUnits {
        self.units
    }

    /// Forgets the window (after a gap or a bad sample: the next window starts afresh).
    pub fn break_window(&mut self) {
        self.prev = None;
        self.open = BlockSums::ZERO;
        self.lowpass = None;
        self.prefix = BlockSums::ZERO;
        self.chunk = 0;
        self.filled = false;
        self.last_fit = None;
        self.open_forces = ForceSums::ZERO;
    }

    /// Adds one sample (`omega` rad/s, `accel` m/s^2, `dt` s since the previous one). Returns
    /// the window's fit when this sample completed a block and the window is full.
    pub fn step(&mut self, omega: [f32; 3], accel: [f32; 3], dt: f32) -> Option<WindowFit> {
        let ok = omega.iter().chain(accel.iter()).all(|x| x.is_finite()) && dt > 0.0;
        if !ok || !dt.is_finite() {
            self.break_window();
            return None;
        }
        // The rates first: in flight they are never small, and the square root is skipped.
        let still = omega.iter().all(|w| w.abs() < self.settings.still_rate) && {
            let fa = sqrt(accel[0] * accel[0] + accel[1] * accel[1] + accel[2] * accel[2]);
            self.units.push_still(fa);
            (fa - G).abs() < self.settings.still_accel
        };
        self.open.still &= still;
        for ((s, q), w) in self
            .open
            .w
            .iter_mut()
            .zip(self.open.ww.iter_mut())
            .zip(omega.iter())
        {
            *s += w;
            *q += w * w;
        }
        if let Some((w0, f0)) = self.prev {
            let inv = 1.0 / dt;
            let w = mid(w0, omega);
            let f = mid(f0, accel);
            let wd = [
                (omega[0] - w0[0]) * inv,
                (omega[1] - w0[1]) * inv,
                (omega[2] - w0[2]) * inv,
            ];
            let k = kmatrix(w, wd);
            let (k, f) = self.filter(k, f, dt);
            add_normal(&mut self.open, &k, f);
            self.open_forces.add_sample(&k, f);
        }
        self.prev = Some((omega, accel));
        self.open.n = self.open.n.saturating_add(1);
        if self.open.n < self.settings.block {
            return None;
        }
        // Close the block into the current chunk.
        let newest = self.open;
        self.open = BlockSums::ZERO;
        let wb = self
            .settings
            .window_blocks
            .clamp(1, MAX_WINDOW_BLOCKS as u8);
        let c = self.chunk as usize;
        if let Some(slot) = self.suffix.get_mut(c) {
            *slot = newest;
        }
        if let Some(slot) = self.forces.get_mut(self.forces_next as usize) {
            *slot = self.open_forces;
        }
        self.open_forces = ForceSums::ZERO;
        self.forces_next = if self.forces_next + 1 >= wb {
            0
        } else {
            self.forces_next + 1
        };
        self.prefix.add(&newest);
        self.chunk += 1;
        let sum = if self.chunk >= wb {
            // The chunk is a whole window: it is the window, and its suffix sums (formed in
            // place, newest first) serve the next `wb - 1` windows.
            let sum = self.prefix;
            for j in (0..(wb as usize).saturating_sub(1)).rev() {
                let next = self.suffix.get(j + 1).copied().unwrap_or(BlockSums::ZERO);
                if let Some(s) = self.suffix.get_mut(j) {
                    s.add(&next);
                }
            }
            self.prefix = BlockSums::ZERO;
            self.chunk = 0;
            self.filled = true;
            sum
        } else if self.filled {
            // The previous chunk's blocks `chunk..wb` and the current chunk's.
            let mut sum = self
                .suffix
                .get(self.chunk as usize)
                .copied()
                .unwrap_or(BlockSums::ZERO);
            sum.add(&self.prefix);
            sum
        } else {
            return None;
        };
        let fit = self.fit(&sum);
        // The bias is the mean rate over the longest run of still blocks so far (a bench is
        // longer than any pause in a hand, and the average's noise is sigma / sqrt(samples)).
        if fit.still {
            if self.still_n == 0 {
                self.still_sum = sum.w;
                self.still_n = sum.n as u32;
            } else {
                for (a, b) in self.still_sum.iter_mut().zip(newest.w.iter()) {
                    *a += b;
                }
                self.still_n = self.still_n.saturating_add(newest.n as u32);
            }
            if self.still_n >= self.bias_n {
                let n = self.still_n as f32;
                self.bias = Some(self.still_sum.map(|x| x / n));
                self.bias_n = self.still_n;
            }
        } else {
            self.still_n = 0;
            self.still_sum = [0.0; 3];
        }
        self.last_fit = Some(fit);
        Some(fit)
    }

    /// Two first-order low-pass stages (`y += a (x - y)`, `a = x / (1 + x)`, `x = 2 pi fc
    /// dt`: exact for any time step) over the row `(K, f)`; the first row starts the filter.
    fn filter(&mut self, k: [[f32; 3]; 3], f: [f32; 3], dt: f32) -> ([[f32; 3]; 3], [f32; 3]) {
        let [[k0, k1, k2], [k3, k4, k5], [k6, k7, k8]] = k;
        let row = [k0, k1, k2, k3, k4, k5, k6, k7, k8, f[0], f[1], f[2]];
        let fc = self.settings.lowpass_hz;
        let a = if fc < f32::INFINITY {
            let x = 2.0 * core::f32::consts::PI * fc * dt;
            x / (1.0 + x)
        } else {
            1.0
        };
        let [s1, s2] = self.lowpass.get_or_insert([row; 2]);
        for ((y1, y2), x) in s1.iter_mut().zip(s2.iter_mut()).zip(row.iter()) {
            *y1 += a * (x - *y1);
            *y2 += a * (*y1 - *y2);
        }
        let [k0, k1, k2, k3, k4, k5, k6, k7, k8, f0, f1, f2] = *s2;
        ([[k0, k1, k2], [k3, k4, k5], [k6, k7, k8]], [f0, f1, f2])
    }

    fn fit(&self, s: &BlockSums) -> WindowFit {
        let n = if s.n > 0 { s.n as f32 } else { 1.0 };
        let [xx, yy, zz, xy, xz, yz] = s.kk;
        // A small ridge keeps the solve defined when the body barely rotates (then r is not
        // observable and the residual is simply |f|).
        let ridge = 1e-6 * (xx + yy + zz) + 1e-9 * n;
        let m = [
            [xx + ridge, xy, xz],
            [xy, yy + ridge, yz],
            [xz, yz, zz + ridge],
        ];
        let r = cholesky(&m)
            .map(|l| cholesky_solve(&l, &s.kf))
            .unwrap_or([0.0; 3]);
        let explained = r[0] * s.kf[0] + r[1] * s.kf[1] + r[2] * s.kf[2];
        let rss = s.ff - explained;
        let residual = sqrt(if rss > 0.0 { rss / n } else { 0.0 });
        let rn = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
        let fits = residual < self.settings.max_residual && r.iter().all(|x| x.is_finite());
        // (F2) only where (F1) alone would not do: a far offset that might be a hand's.
        let support = (fits && rn > self.settings.max_offset && rn <= self.settings.far_offset)
            .then(|| {
                let mut forces = ForceSums::ZERO;
                let wb = usize::from(self.settings.window_blocks).min(MAX_WINDOW_BLOCKS);
                for b in self.forces.iter().take(wb) {
                    forces.add(b);
                }
                support_rms(s, &forces, ridge, rss)
            })
            .flatten();
        let free = fits
            && (rn <= self.settings.max_offset
                || support.is_some_and(|rms| rms <= self.settings.max_support));
        WindowFit {
            free,
            still: s.still && {
                let lim = self.settings.still_spread * self.settings.still_spread;
                (0..3).all(|k| {
                    let m = s.w.get(k).copied().unwrap_or(0.0) / n;
                    s.ww.get(k).copied().unwrap_or(0.0) / n - m * m < lim
                })
            },
            residual,
            offset: r,
            support,
            samples: s.n as u32,
        }
    }
}

/// What (F2), `f = K r + c` with `c` constant over the window, takes from the (F1) residual
/// sum of squares `rss1`, as an RMS: `sqrt((rss1 - rss2) / n)`, with `rss2 = sum |f|^2 -
/// |sum f|^2 / n - r . b` for `r` solving the sums centred on the window's means (`sum K^T K -
/// (sum K)^T (sum K) / n` against `b = sum K^T f - (sum K)^T (sum f) / n`). `None` when the
/// centred system is singular or the result not finite.
fn support_rms(s: &BlockSums, forces: &ForceSums, ridge: f32, rss1: f32) -> Option<f32> {
    let n = if s.n > 0 { s.n as f32 } else { 1.0 };
    let col = |j: usize| -> [f32; 3] {
        let at = |i: usize| forces.k.get(3 * i + j).copied().unwrap_or(0.0);
        [at(0), at(1), at(2)]
    };
    let (c0, c1, c2) = (col(0), col(1), col(2));
    let d = |a: [f32; 3], b: [f32; 3]| dot(a, b) / n;
    let [xx, yy, zz, xy, xz, yz] = s.kk;
    let m = [
        [xx - d(c0, c0) + ridge, xy - d(c0, c1), xz - d(c0, c2)],
        [xy - d(c0, c1), yy - d(c1, c1) + ridge, yz - d(c1, c2)],
        [xz - d(c0, c2), yz - d(c1, c2), zz - d(c2, c2) + ridge],
    ];
    let sf = forces.f;
    let b = [
        s.kf[0] - d(c0, sf),
        s.kf[1] - d(c1, sf),
        s.kf[2] - d(c2, sf),
    ];
    let r = cholesky(&m).map(|l| cholesky_solve(&l, &b))?;
    let rss2 = s.ff - d(sf, sf) - (r[0] * b[0] + r[1] * b[1] + r[2] * b[2]);
    let taken = rss1 - rss2;
    let rms = sqrt(if taken > 0.0 { taken / n } else { 0.0 });
    rms.is_finite().then_some(rms)
}

#[inline(always)]
fn mid(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        0.5 * (a[0] + b[0]),
        0.5 * (a[1] + b[1]),
        0.5 * (a[2] + b[2]),
    ]
}

/// `K = [w]x [w]x + [w']x`, by rows.
#[inline(always)]
fn kmatrix(w: [f32; 3], wd: [f32; 3]) -> [[f32; 3]; 3] {
    let [x, y, z] = w;
    let [a, b, c] = wd;
    // [w]x [w]x = w w^T - |w|^2 I.
    let n2 = x * x + y * y + z * z;
    [
        [x * x - n2, x * y - c, x * z + b],
        [y * x + c, y * y - n2, y * z - a],
        [z * x - b, z * y + a, z * z - n2],
    ]
}

#[inline(always)]
fn add_normal(s: &mut BlockSums, k: &[[f32; 3]; 3], f: [f32; 3]) {
    let [r0, r1, r2] = k;
    let col = |j: usize| -> [f32; 3] {
        [
            r0.get(j).copied().unwrap_or(0.0),
            r1.get(j).copied().unwrap_or(0.0),
            r2.get(j).copied().unwrap_or(0.0),
        ]
    };
    let (c0, c1, c2) = (col(0), col(1), col(2));
    let d = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    s.kk[0] += d(c0, c0);
    s.kk[1] += d(c1, c1);
    s.kk[2] += d(c2, c2);
    s.kk[3] += d(c0, c1);
    s.kk[4] += d(c0, c2);
    s.kk[5] += d(c1, c2);
    s.kf[0] += d(c0, f);
    s.kf[1] += d(c1, f);
    s.kf[2] += d(c2, f);
    s.ff += d(f, f);
}

/// `sum K` (by rows) and `sum f` over the samples of one block: what (F2) centres on. Kept
/// apart from [`BlockSums`], one per block of the window in a ring, and summed only for a
/// window that needs (F2): the window machinery's chunks and suffix sums stay as small as
/// (F1) needs (carrying these twelve sums through them cost the pipeline a tenth more per
/// sample).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct ForceSums {
    k: [f32; 9],
    f: [f32; 3],
}

impl ForceSums {
    const ZERO: ForceSums = ForceSums {
        k: [0.0; 9],
        f: [0.0; 3],
    };

    #[inline(always)]
    fn add_sample(&mut self, k: &[[f32; 3]; 3], f: [f32; 3]) {
        let [[k0, k1, k2], [k3, k4, k5], [k6, k7, k8]] = *k;
        for (a, b) in self.k.iter_mut().zip([k0, k1, k2, k3, k4, k5, k6, k7, k8]) {
            *a += b;
        }
        for (a, b) in self.f.iter_mut().zip(f) {
            *a += b;
        }
    }

    fn add(&mut self, o: &ForceSums) {
        for (a, b) in self.k.iter_mut().zip(o.k.iter()) {
            *a += b;
        }
        for (a, b) in self.f.iter_mut().zip(o.f.iter()) {
            *a += b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bench read in m/s^2 says nothing wrong; the same in g (about 1) or milli-g does, once
    /// fifty still samples were seen; a release's few still samples reading zero among a
    /// bench's do not outvote it; rates above the still threshold are not counted.
    #[test]
    fn the_accelerometer_unit_is_judged_on_still_samples() {
        let bench = |scale: f32, n: usize| {
            let mut u = AccelUnits::new();
            for k in 0..n {
                let tilt = 0.01 * (k % 7) as f32;
                u.push([0.001, -0.002, 0.0], [tilt * scale, 0.0, G * scale], 0.05);
            }
            u
        };
        assert!(!bench(1.0, 500).looks_wrong());
        assert!(bench(1.0 / G, 500).looks_wrong());
        assert!(bench(1000.0 / G, 500).looks_wrong());
        assert!(!bench(1.0 / G, 49).looks_wrong(), "too few to judge");
        let mut u = bench(1.0, 200);
        for _ in 0..5 {
            u.push([0.0; 3], [0.0; 3], 0.05);
        }
        assert!(!u.looks_wrong());
        let mut u = AccelUnits::new();
        for _ in 0..500 {
            u.push([3.0, 0.0, 0.0], [1.0, 0.0, 0.0], 0.05);
        }
        assert_eq!(u.still_samples(), 0);
        assert!(!u.looks_wrong());
    }

    #[test]
    fn windows_are_about_40_ms_and_never_under_16_samples() {
        for (rate, block, blocks) in [
            (100.0, 1, 16),
            (200.0, 1, 16),
            (400.0, 1, 16),
            (1000.0, 3, 13),
            (2000.0, 5, 16),
            (8000.0, 20, 16),
        ] {
            let g = GateSettings::for_rate(rate);
            assert_eq!((g.block, g.window_blocks), (block, blocks), "{rate} Hz");
        }
    }

    #[test]
    fn still_is_not_free_and_gives_bias() {
        let mut g = FreeFlightGate::new(GateSettings::for_rate(1000.0)).unwrap();
        let mut last = None;
        for _ in 0..200 {
            if let Some(f) = g.step([0.01, -0.02, 0.005], [0.0, 0.0, G], 1e-3) {
                last = Some(f);
            }
        }
        let f = last.unwrap();
        assert!(!f.free && f.still);
        let b = g.bias().unwrap();
        assert!((b[0] - 0.01).abs() < 1e-6 && (b[1] + 0.02).abs() < 1e-6);
    }

    #[test]
    fn spinning_free_body_is_free() {
        // Constant spin about z with the accelerometer 15 mm off axis: f = -w^2 r_perp.
        let mut g = FreeFlightGate::new(GateSettings::for_rate(1000.0)).unwrap();
        let r = [0.015, 0.0, 0.005];
        let w = [0.0, 0.0, 30.0];
        let f = [-900.0 * r[0], -900.0 * r[1], 0.0];
        let mut last = None;
        for _ in 0..200 {
            if let Some(x) = g.step(w, f, 1e-3) {
                last = Some(x);
            }
        }
        let fit = last.unwrap();
        assert!(fit.free, "{fit:?}");
        assert!(fit.residual < 0.1);
    }
}
