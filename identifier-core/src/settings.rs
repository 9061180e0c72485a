//! Tuning of the identifier: the gain matrix `C` of (9)-(10), the identifiability threshold
//! `w_min` of (2), the accuracy criterion (`eps`, `h`) of section 4, and the input limits that
//! decide when a sample is rejected rather than integrated.

use crate::linalg::{det, Mat3};

/// The matrix `C = (c_ij)` of (9). It must be Hurwitz (all eigenvalues with negative real
/// part) so that the mismatch obeying (10), `eta' = |w1 w2 w3| C eta`, decays to zero.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GainMatrix(pub [[f32; 3]; 3]);

impl GainMatrix {
    /// `C = -lambda E`, the paper's choice in section 4, which gives (13)-(14).
    pub const fn scalar(lambda: f32) -> Self {
        GainMatrix([
            [-lambda, 0.0, 0.0],
            [0.0, -lambda, 0.0],
            [0.0, 0.0, -lambda],
        ])
    }

    /// The rows of `C`.
    pub const fn rows(&self) -> &Mat3 {
        &self.0
    }

    /// Routh-Hurwitz test of the characteristic polynomial `s^3 + k2 s^2 + k1 s + k0` of `C`:
    /// the roots `lambda_1..3` of (11) all have negative real parts iff
    /// `k2 > 0`, `k0 > 0` and `k2 k1 > k0`.
    pub fn is_hurwitz(&self) -> bool {
        let m = &self.0;
        let [[c11, c12, c13], [c21, c22, c23], [c31, c32, c33]] = *m;
        if !m.iter().flatten().all(|c| c.is_finite()) {
            return false;
        }
        let k2 = -(c11 + c22 + c33);
        let k1 = (c11 * c22 - c12 * c21) + (c11 * c33 - c13 * c31) + (c22 * c33 - c23 * c32);
        let k0 = -det(m);
        k2 > 0.0 && k0 > 0.0 && k2 * k1 > k0
    }
}

/// What to do with the auxiliary state alpha when `w1 w2 w3` changes sign (last section of the
/// paper).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SignChangeCorrection {
    /// The paper's correction: at a sign change, alpha is shifted by the jump of `Phi` taken
    /// with the opposite sign, so the estimate (12) is continuous.
    Enabled,
    /// The scheme of the paper's Fig. 1, without the correction: alpha is continuous and the
    /// estimate (12) jumps by the jump of `Phi`. Kept to reproduce the paper and to show what
    /// the correction buys; not for use in flight.
    Disabled,
}

/// All tuning of an [`crate::Identifier`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Settings {
    /// Gain matrix `C` of (9); Hurwitz.
    pub gain: GainMatrix,
    /// `w_min` of (2), in (rad/s)^3: samples with `|w1 w2 w3| < w_min` are not integrated
    /// because the parameters are not identifiable there and the estimate would only collect
    /// noise. Must be finite and `>= 0`.
    pub w_min: f32,
    /// Sign-change correction of the paper's last section.
    pub sign_change: SignChangeCorrection,
    /// Gyro full scale in rad/s: a sample with any `|w_i| >= full_scale` is saturated and is
    /// rejected. Must be `> 0` (use `f32::INFINITY` for no limit).
    pub full_scale: f32,
    /// Longest time step in seconds that is still integrated; a longer interval since the last
    /// integrated sample (dropped samples, a paused log) restarts the integration from the new
    /// sample with the estimate held. Must be `> 0`.
    pub max_dt: f32,
    /// `eps` of the paper's accuracy criterion: identification at accuracy `eps` is reached when
    /// every component of the estimate (14) varies by no more than `2 eps` over an interval `h`.
    pub eps: f32,
    /// `h` of the criterion, in seconds of identifiable time.
    pub h: f32,
    /// Estimate before the first sample (the paper's arbitrary alpha(0) of (3)).
    pub initial_estimate: [f32; 3],
}

impl Settings {
    /// The paper's settings with `C = -lambda E`: `w_min = 1e-3 (rad/s)^3`, correction enabled,
    /// no full-scale limit, `max_dt = 0.1 s`, `eps = 1e-3`, `h = 1 s`, zero initial estimate.
    pub const fn with_lambda(lambda: f32) -> Self {
        Settings {
            gain: GainMatrix::scalar(lambda),
            w_min: 1e-3,
            sign_change: SignChangeCorrection::Enabled,
            full_scale: f32::INFINITY,
            max_dt: 0.1,
            eps: 1e-3,
            h: 1.0,
            initial_estimate: [0.0; 3],
        }
    }

    /// Checks every field; the identifier refuses settings that fail.
    pub fn validate(&self) -> Result<(), SettingsError> {
        if !self.gain.is_hurwitz() {
            return Err(SettingsError::GainNotHurwitz);
        }
        if !(self.w_min.is_finite() && self.w_min >= 0.0) {
            return Err(SettingsError::InvalidWMin);
        }
        if self.full_scale.is_nan() || self.full_scale <= 0.0 {
            return Err(SettingsError::InvalidFullScale);
        }
        if !(self.max_dt.is_finite() && self.max_dt > 0.0) {
            return Err(SettingsError::InvalidMaxDt);
        }
        if !(self.eps.is_finite() && self.eps > 0.0 && self.h.is_finite() && self.h > 0.0) {
            return Err(SettingsError::InvalidCriterion);
        }
        if !self.initial_estimate.iter().all(|a| a.is_finite()) {
            return Err(SettingsError::InvalidInitialEstimate);
        }
        Ok(())
    }
}

impl Default for Settings {
    /// [`Settings::with_lambda`]`(3.0)`, the paper's successful gain.
    fn default() -> Self {
        Settings::with_lambda(3.0)
    }
}

/// Why [`Settings::validate`] refused a configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SettingsError {
    /// `C` is not Hurwitz (or not finite), so (10) would not converge.
    GainNotHurwitz,
    /// `w_min` of (2) is negative or not finite.
    InvalidWMin,
    /// `full_scale` is not positive.
    InvalidFullScale,
    /// `max_dt` is not positive and finite.
    InvalidMaxDt,
    /// `eps` or `h` of the criterion is not positive and finite.
    InvalidCriterion,
    /// The initial estimate is not finite.
    InvalidInitialEstimate,
}

impl core::fmt::Display for SettingsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let why = match self {
            SettingsError::GainNotHurwitz => "gain matrix C is not Hurwitz",
            SettingsError::InvalidWMin => "w_min must be finite and >= 0",
            SettingsError::InvalidFullScale => "full_scale must be > 0",
            SettingsError::InvalidMaxDt => "max_dt must be finite and > 0",
            SettingsError::InvalidCriterion => "eps and h must be finite and > 0",
            SettingsError::InvalidInitialEstimate => "initial estimate must be finite",
        };
        f.write_str(why)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalar_gain_is_hurwitz_only_for_positive_lambda() {
        assert!(GainMatrix::scalar(3.0).is_hurwitz());
        assert!(!GainMatrix::scalar(0.0).is_hurwitz());
        assert!(!GainMatrix::scalar(-1.0).is_hurwitz());
        assert!(!GainMatrix::scalar(f32::NAN).is_hurwitz());
    }

    #[test]
    fn non_diagonal_hurwitz_and_not() {
        // Eigenvalues -1 +- 2i and -3: Hurwitz.
        let c = GainMatrix([[-1.0, 2.0, 0.0], [-2.0, -1.0, 0.0], [0.0, 0.0, -3.0]]);
        assert!(c.is_hurwitz());
        // Eigenvalues +1 +- 2i and -3: not.
        let c = GainMatrix([[1.0, 2.0, 0.0], [-2.0, 1.0, 0.0], [0.0, 0.0, -3.0]]);
        assert!(!c.is_hurwitz());
    }

    #[test]
    fn validate_rejects_each_bad_field() {
        let ok = Settings::default();
        assert_eq!(ok.validate(), Ok(()));
        let mut s = ok;
        s.w_min = -1.0;
        assert_eq!(s.validate(), Err(SettingsError::InvalidWMin));
        let mut s = ok;
        s.full_scale = 0.0;
        assert_eq!(s.validate(), Err(SettingsError::InvalidFullScale));
        let mut s = ok;
        s.max_dt = f32::INFINITY;
        assert_eq!(s.validate(), Err(SettingsError::InvalidMaxDt));
        let mut s = ok;
        s.h = 0.0;
        assert_eq!(s.validate(), Err(SettingsError::InvalidCriterion));
        let mut s = ok;
        s.initial_estimate[1] = f32::NAN;
        assert_eq!(s.validate(), Err(SettingsError::InvalidInitialEstimate));
        let mut s = ok;
        s.gain = GainMatrix::scalar(-0.5);
        assert_eq!(s.validate(), Err(SettingsError::GainNotHurwitz));
    }
}
