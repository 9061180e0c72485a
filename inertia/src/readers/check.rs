//! The checks every reader makes on each sample as it comes (values finite, also once in
//! `f32`; time strictly increasing, an exact duplicate dropped and counted, going backwards an
//! error), shared by the readers that collect a [`crate::Recording`] and the ones that stream.

use std::path::{Path, PathBuf};

use super::{Location, ReadError};
use crate::readers::{Extra, Reading, Sample};

const AXES: [&str; 3] = ["x", "y", "z"];

/// Checks samples in order.
pub(crate) struct Checker {
    file: PathBuf,
    prev_t: Option<f64>,
    samples: usize,
    duplicates: usize,
    first_duplicate: Option<Location>,
}

impl Checker {
    pub(crate) fn new(file: &Path) -> Self {
        Checker {
            file: file.to_path_buf(),
            prev_t: None,
            samples: 0,
            duplicates: 0,
            first_duplicate: None,
        }
    }

    fn finite(&self, at: Location, what: &str, v: f64) -> Result<f32, ReadError> {
        let x = v as f32;
        if x.is_finite() {
            Ok(x)
        } else {
            Err(ReadError::at(
                &self.file,
                at,
                format!("{what} = {v} is not finite (or beyond f32)"),
            ))
        }
    }

    fn vec3(&self, at: Location, what: &str, v: [f64; 3]) -> Result<[f32; 3], ReadError> {
        let out = v.map(|x| x as f32);
        if out.iter().all(|x| x.is_finite()) {
            return Ok(out);
        }
        // The label is built only for the error (formatting one per value cost most of the
        // reading time of a long log).
        for k in 0..3 {
            self.finite(at, &format!("{what} {}", AXES[k]), v[k])?;
        }
        Ok(out)
    }

    /// Checks one sample: `Ok(None)` when it repeats the previous timestamp (dropped).
    /// `accel` and `rotor` must be given for every sample or for none; the vehicle's rotor
    /// columns and a spacecraft's columns in `extra` must be finite too.
    pub(crate) fn check_with(
        &mut self,
        at: Location,
        t: f64,
        gyro: [f64; 3],
        accel: Option<[f64; 3]>,
        rotor: Option<f64>,
        extra: Extra,
    ) -> Result<Option<Sample>, ReadError> {
        let finite = extra.wheels.iter().all(|x| x.is_finite())
            && extra.attitude.iter().all(|x| x.is_finite())
            && extra.position.iter().all(|x| x.is_finite())
            && extra.magnetic.iter().all(|x| x.is_finite());
        if !finite {
            return Err(ReadError::at(
                &self.file,
                at,
                "a rotor, attitude, position or magnetometer value is not finite (or beyond f32)",
            ));
        }
        if !t.is_finite() {
            return Err(ReadError::at(
                &self.file,
                at,
                format!("time = {t} is not finite"),
            ));
        }
        let g = self.vec3(at, "gyro", gyro)?;
        let a = accel.map(|a| self.vec3(at, "accel", a)).transpose()?;
        let r = rotor
            .map(|r| self.finite(at, "rotor speed", r))
            .transpose()?;
        if let Some(prev) = self.prev_t {
            if t == prev {
                self.duplicates += 1;
                self.first_duplicate.get_or_insert(at);
                return Ok(None);
            }
            if t < prev {
                return Err(ReadError::at(
                    &self.file,
                    at,
                    format!("time goes backwards: {t} s after {prev} s"),
                ));
            }
        }
        self.prev_t = Some(t);
        self.samples += 1;
        Ok(Some(Sample {
            t,
            gyro: g,
            accel: a.unwrap_or([0.0; 3]),
            rotor: r.unwrap_or(0.0),
            extra,
        }))
    }

    /// What a reading gave: when the visitor stopped it early, the samples so far and no
    /// end-of-log checks; otherwise [`Checker::finish`]'s.
    pub(crate) fn reading(&self, stopped: bool) -> Result<Reading, ReadError> {
        Ok(Reading {
            samples: self.samples,
            duplicates: if stopped { None } else { self.finish()? },
        })
    }

    /// After the last sample: at least two samples, and the duplicates warning if any were
    /// dropped.
    pub(crate) fn finish(&self) -> Result<Option<String>, ReadError> {
        let n = self.samples;
        if n < 2 {
            return Err(ReadError::new(
                &self.file,
                format!("fewer than two samples ({n})"),
            ));
        }
        if self.duplicates == 0 {
            return Ok(None);
        }
        let at = match self.first_duplicate {
            Some(Location::Line(l)) => format!(" (first at line {l})"),
            Some(Location::Frame(f)) => format!(" (first at frame {f})"),
            None => String::new(),
        };
        Ok(Some(format!(
            "dropped {} sample(s) repeating the previous timestamp{at}",
            self.duplicates
        )))
    }
}
