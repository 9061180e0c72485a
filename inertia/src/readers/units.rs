//! Unit sanity warnings: sustained rates above 50 rad/s (deg/s read as rad/s?) and a median
//! time step outside `[1e-5 s, 1 s]` (wrong time unit?). [`UnitCheck`] follows the samples as
//! they come; the median time step is given to it at the end (exact medians need the whole
//! log: [`crate::select`]).

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
        let mut out = Vec::new();
        if let Some((t0, span)) = self.best {
            if span >= SUSTAINED_S {
                out.push(format!(
                    "gyro rate stays above {DEG_PER_SEC_SUSPECT_RAD_S} rad/s for {span:.3} s \
                     (from t = {t0:.3} s): that looks like deg/s read as rad/s; check the gyro \
                     unit"
                ));
            }
        }
        if let Some(median) = median_dt {
            if median < 1e-5 {
                out.push(format!(
                    "median time step {median:.3e} s is below 1e-5 s: is the time in ms or us \
                     read as seconds? check the time unit"
                ));
            } else if median > 1.0 {
                out.push(format!(
                    "median time step {median:.3e} s is above 1 s: is the time in ms or us read \
                     as seconds? check the time unit"
                ));
            }
        }
        out
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
