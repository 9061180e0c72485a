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
