//! The estimators' settings for the configured gyro: the paper's identifier, the refined one
//! and the free-flight pipeline.

use icm42688::Config;
use identifier_core::{PipelineSettings, RefinedSettings, Settings};

/// The identifier's settings for a gyro configured with `config`: the paper's
/// `C = -3 E` (section 4), and `full_scale` just below the gyro's clip level, so that a
/// clipped reading (+-32767 counts) is rejected as saturated instead of integrated as a
/// wrong rate.
pub fn identifier_settings(config: &Config) -> Settings {
    let mut s = Settings::with_lambda(3.0);
    s.full_scale = icm42688::raw_to_rad_s(32767, config.full_scale);
    s
}

/// Gyro rate noise density of the ICM-42688-P, degrees per second per sqrt(Hz) (datasheet
/// DS-000347, table 1: 2.8 mdps/sqrt(Hz)).
pub const GYRO_NOISE_DENSITY_DPS: f32 = 2.8e-3;

/// The refined identifier's settings for a gyro configured with `config`:
/// [`RefinedSettings::for_rate`] at the configured output data rate (block size and end
/// correction from the rate, the same function the host uses), with
/// * `noise_std`: the part's noise density times the square root of the Nyquist bandwidth
///   `odr / 2` (1.09 mrad/s at 1 kHz; an upper bound, the part's default UI filter is
///   narrower). It sets only the weight of the prior, the filter's gains do not depend on it;
/// * `full_scale`, `max_dt`, `eps` and `h` as for the paper's identifier
///   ([`identifier_settings`]), so that both reject the same samples, restart after the same
///   gaps and are judged by the same accuracy criterion.
pub fn refined_settings(config: &Config) -> RefinedSettings {
    let paper = identifier_settings(config);
    let odr = config.odr.hz();
    let noise_std = GYRO_NOISE_DENSITY_DPS * (core::f32::consts::PI / 180.0) * sqrt_pos(0.5 * odr);
    let mut s = RefinedSettings::for_rate(odr, noise_std);
    s.full_scale = paper.full_scale;
    s.max_dt = paper.max_dt;
    s.eps = paper.eps;
    s.h = paper.h;
    s
}

/// The free-flight pipeline's settings for a gyro configured with `config`:
/// [`PipelineSettings::for_rate`] at the output data rate with the noise of
/// [`refined_settings`], and the estimator's `full_scale` at the gyro's clip level (the same
/// function and the same fields `inertia identify` sets from a log).
pub fn pipeline_settings(config: &Config) -> PipelineSettings {
    let r = refined_settings(config);
    PipelineSettings::for_rate(config.odr.hz(), r.noise_std)
        .with_full_scale(identifier_settings(config).full_scale)
}

/// Square root of `x > 0` by Newton's iteration (`core` has none); run once, at start-up.
fn sqrt_pos(x: f32) -> f32 {
    let mut y = x.max(1.0);
    for _ in 0..40 {
        y = 0.5 * (y + x / y);
    }
    y
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use identifier_core::{Identifier, Refined, SampleStatus};

    #[test]
    fn refined_settings_follow_the_part_and_the_odr() {
        let config = Config::identifier();
        let s = refined_settings(&config);
        // 2.8 mdps/sqrt(Hz) over 500 Hz: 1.093 mrad/s.
        let expect = 2.8e-3 * core::f32::consts::PI / 180.0 * 500f32.sqrt();
        assert!(
            (s.noise_std - expect).abs() < 1e-6 * expect,
            "{}",
            s.noise_std
        );
        assert_eq!(s.block, 32);
        assert!(s.end_correction);
        assert_eq!(s.full_scale, identifier_settings(&config).full_scale);
        assert!(Refined::new(s).is_some());
        let slow = Config {
            odr: icm42688::GyroOdr::Hz100,
            ..config
        };
        let s = refined_settings(&slow);
        assert_eq!(s.block, 8);
        assert!(s.end_correction);
        assert!(Refined::new(s).is_some());
    }

    #[test]
    fn settings_reject_clipped_readings() {
        let s = identifier_settings(&Config::identifier());
        let clip = icm42688::raw_to_rad_s(32767, icm42688::GyroFullScale::Dps2000);
        assert_eq!(s.full_scale, clip);
        let mut id = Identifier::new(s).unwrap();
        assert_eq!(
            id.step([clip, 1.0, 1.0], 1e-3).status,
            SampleStatus::Saturated
        );
    }
}
