//! Unit sanity warnings: sustained rates above 50 rad/s (deg/s read as rad/s?) and a median
//! time step outside `[1e-5 s, 1 s]` (wrong time unit?). [`UnitCheck`] follows the samples as
//! they come; the median time step is given to it at the end (exact medians need the whole
//! log: [`crate::select`]). [`AccelCheck`] does the same for the accelerometer: while the
//! gyro is still it must read about one `g` in m/s^2.

/// Rates above this, sustained, look like deg/s read as rad/s.
pub const DEG_PER_SEC_SUSPECT_RAD_S: f32 = 50.0;
/// How long the rate must stay above [`DEG_PER_SEC_SUSPECT_RAD_S`] to count as sustained, s.
pub const SUSTAINED_S: f64 = 0.1;

/// The longest run of samples whose rate magnitude exceeds [`DEG_PER_SEC_SUSPECT_RAD_S`],
/// followed sample by sample.
#[derive(Clone, Debug, Default)]
pub struct UnitCheck {
    /// Time of the first sample of the run in progress.
    start: Option<f64>,
    /// The longest run so far: its first time and its span.
    best: Option<(f64, f64)>,
}

impl UnitCheck {
    /// The next sample.
    #[inline]
    pub fn push(&mut self, t: f64, w: [f32; 3]) {
        let norm = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
        if norm > DEG_PER_SEC_SUSPECT_RAD_S {
            let s = *self.start.get_or_insert(t);
            let span = t - s;
            if self.best.is_none_or(|(_, b)| span > b) {
                self.best = Some((s, span));
            }
        } else {
            self.start = None;
        }
    }

    /// The warnings, given the median time step (`None` with fewer than two samples).
    pub fn warnings(&self, median_dt: Option<f64>) -> Vec<String> {
        let mut out: Vec<String> = self.rate_warning(f32::INFINITY).into_iter().collect();
        out.extend(time_warning(median_dt));
        out
    }

    /// The warning when the rate stayed above [`DEG_PER_SEC_SUSPECT_RAD_S`] for
    /// [`SUSTAINED_S`] or longer; `full_scale` (rad/s, infinite when unknown) is the gyro's
    /// range as the reader knows it: a rate sustained beyond it is no clipped reading but
    /// another unit.
    pub fn rate_warning(&self, full_scale: f32) -> Option<String> {
        let (t0, span) = self.best.filter(|(_, span)| *span >= SUSTAINED_S)?;
        let head = format!(
            "gyro rate stays above {DEG_PER_SEC_SUSPECT_RAD_S} rad/s for {span:.3} s (from t = \
             {t0:.3} s)"
        );
        Some(if full_scale < DEG_PER_SEC_SUSPECT_RAD_S {
            format!(
                "{head}, beyond the gyro's full scale of {full_scale:.1} rad/s: the rates are \
                 not in the unit they were read in (deg/s read as rad/s, or raw counts read as \
                 deg/s); check the gyro unit"
            )
        } else {
            format!("{head}: that looks like deg/s read as rad/s; check the gyro unit")
        })
    }
}

/// Every ratio `|a_i|` at most this looks like deg/s read as rad/s, when the rates are above
/// [`SLOW_DEG_PER_SEC_RAD_S`]: a rigid body has `|a_i| <= 1` (`|A_j - A_k| <= A_i`), so
/// rates read 57.3 times too large give ratios 57.3 times too small, at most `1 / 57.3 =
/// 0.0175`, and the motion is otherwise the same torque-free motion (for a body with one
/// `a_i` near zero the ratios even satisfy the rigid-body constraint, so the fits' test of it
/// cannot tell). In rad/s such ratios are a body within 2 % of a sphere.
pub const NEAR_SPHERE_RATIO: f32 = 0.02;
/// The rate (rad/s as read) above which [`NEAR_SPHERE_RATIO`] is questioned: a tumble of
/// 2 deg/s and more read as rad/s; below it a log is too slow to say much either way.
pub const SLOW_DEG_PER_SEC_RAD_S: f32 = 2.0;

/// The warning when a gyro whose unit was assumed (not fixed by the format nor declared)
/// gives ratios `a` that are all within [`NEAR_SPHERE_RATIO`] while it read up to `rate_max`
/// rad/s (above [`SLOW_DEG_PER_SEC_RAD_S`]): what a slow tumble logged in deg/s gives, below
/// the [`DEG_PER_SEC_SUSPECT_RAD_S`] the sustained-rate check needs. Such a tumble read as
/// rad/s comes out `Converged` with `a` 57 times too small (the unit's factor), so only this
/// warning tells. The fix either way is to declare the unit.
pub fn ratios_warning(a: [f32; 3], rate_max: f32) -> Option<String> {
    let biggest = a.iter().fold(0.0f32, |m, x| m.max(x.abs()));
    let near_sphere = a.iter().all(|x| x.is_finite()) && biggest <= NEAR_SPHERE_RATIO;
    (near_sphere && rate_max > SLOW_DEG_PER_SEC_RAD_S).then(|| {
        format!(
            "every ratio |a_i| is at most {biggest:.4} while the gyro reads up to {rate_max:.1} \
             rad/s: that is what deg/s read as rad/s gives (ratios 57.3 times too small; a \
             rigid body's are at most 1, so at most 0.0175 that way), or a body within 2 % of \
             a sphere; declare the gyro unit (--gyro-unit deg/s, or rad/s if that is right)"
        )
    })
}

/// The warning when the median time step (`None` with fewer than two samples) looks like
/// another unit: below `1e-5` s or above 1 s.
pub fn time_warning(median_dt: Option<f64>) -> Option<String> {
    let median = median_dt?;
    if median < 1e-5 {
        Some(format!(
            "median time step {median:.3e} s is below 1e-5 s: is the time in ms or us read as \
             seconds? check the time unit"
        ))
    } else if median > 1.0 {
        Some(format!(
            "median time step {median:.3e} s is above 1 s: is the time in ms or us read as \
             seconds? check the time unit"
        ))
    } else {
        None
    }
}

/// Unit sanity warnings of a whole recording (see the module documentation).
pub fn unit_warnings(t: &[f64], gyro: &[[f32; 3]]) -> Vec<String> {
    let mut check = UnitCheck::default();
    for (&ti, &w) in t.iter().zip(gyro) {
        check.push(ti, w);
    }
    let median = (t.len() >= 2).then(|| {
        let mut dt: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
        let mid = dt.len() / 2;
        *dt.select_nth_unstable_by(mid, f64::total_cmp).1
    });
    check.warnings(median)
}

/// The accelerometer's unit judged from the whole log with the gate's own rule
/// ([`identifier_core::AccelUnits`]: while the gyro is still, one `g` in m/s^2), and the
/// warning that says which unit it looks like.
#[derive(Clone, Debug, Default)]
pub struct AccelCheck {
    units: identifier_core::AccelUnits,
}

impl AccelCheck {
    /// The next sample: rates (rad/s) and specific force (as read); still below the gate's
    /// [`identifier_core::free_flight::STILL_RATE`].
    #[inline]
    pub fn push(&mut self, w: [f32; 3], a: [f32; 3]) {
        self.units
            .push(w, a, identifier_core::free_flight::STILL_RATE);
    }

    /// The warning when the still stretches say the accelerometer is not in m/s^2.
    pub fn warning(&self) -> Option<String> {
        if !self.units.looks_wrong() {
            return None;
        }
        let mean = self.units.mean().unwrap_or(0.0);
        let g = identifier_core::free_flight::G;
        let (guess, fix) = if (0.5..=2.0).contains(&mean) {
            ("g", "declare --accel-unit g")
        } else if (500.0..=2000.0).contains(&mean) {
            ("milli-g", "declare --accel-unit mg")
        } else if (0.5 * g * 1000.0..=2.0 * g * 1000.0).contains(&mean) {
            ("mm/s^2", "write ax,ay,az in m/s^2")
        } else if mean < 0.5 {
            (
                "a linear acceleration with gravity taken out (the gate needs the specific \
                 force, gravity included), or no signal",
                "write the specific force in m/s^2",
            )
        } else {
            ("raw counts or another unit", "write ax,ay,az in m/s^2")
        };
        Some(format!(
            "while the gyro is still ({} samples) the accelerometer reads {mean:.4} on average, \
             where 1 g is {g:.3} m/s^2: that looks like {guess}, not m/s^2: {fix} (the \
             free-flight detection and the bench's gyro bias rely on it)",
            self.units.still_samples()
        ))
    }
}
