//! Logs read sample by sample, as often as needed, without keeping the samples.
//!
//! `inertia identify` reads a log several times (statistics first, then the pipeline) instead
//! of holding it as a [`Recording`]: a 10-minute 8 kHz log held whole took 950 MiB. Every
//! reading gives the same samples, checked as [`crate::read`] checks them (values finite, time
//! increasing, an exact duplicate timestamp dropped), in SI units and the log's own axes.
//!
//! | format | how a reading goes | memory |
//! |---|---|---|
//! | CSV, phyphox | line by line from the file | a read buffer |
//! | blackbox | frame by frame, as `blackbox-log` decodes them | the file's bytes (the crate decodes from a byte slice; 10-30 bytes a frame) |
//! | ULog | from a [`Recording`]: `px4-ulog` parses the whole file into memory anyway | the recording |

use std::path::Path;

use crate::readers::gyro_filters::GyroFilters;
use crate::readers::{self, Format, ReadError, ReadOptions};
pub use crate::readers::{
    Channels, Extra, Flow, Reading, RotorUnit, Sample, Source, Visit, MAX_WHEELS,
};
use crate::recording::{Recording, RotorSpeed};

/// Opens the log at `path` for reading sample by sample, the format detected from the
/// content as [`crate::read`] does.
pub fn open<'a>(path: &Path, opts: &ReadOptions) -> Result<Box<dyn Source + 'a>, ReadError> {
    Ok(match readers::detect(path)? {
        Format::Blackbox => Box::new(
            readers::blackbox::BlackboxSource::open(path)?
                .with_rotor_fields(&opts.rotor_columns)?,
        ),
        Format::Ulog => Box::new(RecordingSource::owned(readers::ulog::read_ulog_with(
            path, opts,
        )?)),
        Format::Phyphox => Box::new(readers::phyphox::PhyphoxSource::open(path)?),
        Format::Csv => Box::new(readers::csv::CsvSource::open(path, opts)?),
    })
}

/// A [`Recording`] already in memory as a [`Source`]: its samples as they are (a recording
/// from [`crate::read`] is already checked), its warnings as they are.
pub struct RecordingSource<'a> {
    rec: std::borrow::Cow<'a, Recording>,
}

impl<'a> RecordingSource<'a> {
    /// Borrows `rec`.
    pub fn new(rec: &'a Recording) -> Self {
        RecordingSource {
            rec: std::borrow::Cow::Borrowed(rec),
        }
    }

    /// Owns `rec`.
    pub fn owned(rec: Recording) -> Self {
        RecordingSource {
            rec: std::borrow::Cow::Owned(rec),
        }
    }
}

impl Source for RecordingSource<'_> {
    fn name(&self) -> String {
        self.rec.source.clone()
    }

    fn channels(&self) -> Channels {
        let rec = &*self.rec;
        Channels {
            accel: rec.accel.is_some(),
            rotor: rec.rotor.as_ref().map(RotorUnit::of),
            wheels: rec.wheels.len(),
            attitude: rec.attitude.is_some(),
            position: rec.position.is_some(),
            magnetic: rec.magnetic.is_some(),
        }
    }

    fn full_scale(&self) -> f32 {
        self.rec.gyro_full_scale
    }

    fn gyro_averaging(&self) -> f32 {
        self.rec.gyro_averaging
    }

    fn gyro_filters(&self) -> Option<GyroFilters> {
        self.rec.gyro_filters.clone()
    }

    fn gyro_unit_stated(&self) -> bool {
        self.rec.gyro_unit_stated
    }

    fn read_all(
        &self,
        visit: &mut Visit<'_>,
        progress: &mut dyn FnMut(f32),
    ) -> Result<Reading, ReadError> {
        let rec = &*self.rec;
        let n = rec.t.len();
        let rotor = rec.rotor.as_ref().map(|r| match r {
            RotorSpeed::Erpm(v) | RotorSpeed::RadPerSec(v) => v,
        });
        let uneven = rec.gyro.len() != n
            || rec.accel.as_ref().is_some_and(|a| a.len() != n)
            || rotor.is_some_and(|r| r.len() != n)
            || rec.wheels.len() > MAX_WHEELS
            || rec.wheels.iter().any(|w| w.len() != n)
            || rec.attitude.as_ref().is_some_and(|v| v.len() != n)
            || rec.position.as_ref().is_some_and(|v| v.len() != n)
            || rec.magnetic.as_ref().is_some_and(|v| v.len() != n);
        if uneven {
            return Err(ReadError::new(
                Path::new(&rec.source),
                "the recording's channels differ in length",
            ));
        }
        for i in 0..n {
            let s = Sample {
                t: rec.t[i],
                gyro: rec.gyro[i],
                accel: rec.accel.as_ref().map_or([0.0; 3], |a| a[i]),
                rotor: rotor.map_or(0.0, |r| r[i]),
                extra: Extra {
                    wheels: core::array::from_fn(|k| rec.wheels.get(k).map_or(0.0, |w| w[i])),
                    attitude: rec.attitude.as_ref().map_or([0.0; 4], |v| v[i]),
                    position: rec.position.as_ref().map_or([0.0; 3], |v| v[i]),
                    magnetic: rec.magnetic.as_ref().map_or([0.0; 3], |v| v[i]),
                },
            };
            if visit(&s)? == Flow::Stop {
                return Ok(Reading {
                    samples: i + 1,
                    duplicates: None,
                });
            }
            if i % 65536 == 0 {
                progress(i as f32 / n as f32);
            }
        }
        Ok(Reading {
            samples: n,
            duplicates: None,
        })
    }

    fn warnings(&self, _found: Vec<String>) -> Vec<String> {
        // A recording's warnings already hold what a reading finds (`read` put them there),
        // or are whatever its maker chose.
        self.rec.warnings.clone()
    }
}

/// Another [`Source`] with each gyro axis's reading `g` replaced by `map(g, k)` (`k` that
/// axis's constant), and its full scale and times divided by constants: the same log as
/// another gyro and clock would have written it. `I` is how the inner source is held (`&dyn
/// Source` or `Box<dyn Source>`). Three are made: [`MappedSource::scaled`] (`g k`: other
/// scale factors, what `inertia identify --gyro-scale-tolerance` re-identifies to see how far
/// a scale-factor error moves the estimate), [`MappedSource::rescaled`] (the scale factors
/// `inertia calibrate` gives) and `crate::grid::centred` (readings moved to their counts'
/// centres, (Q1)).
pub struct MappedSource<I> {
    inner: I,
    map: fn(f32, f32) -> f32,
    k: [f32; 3],
    centred: bool,
    full_scale_divisor: f32,
    clock: f64,
}

impl<I> MappedSource<I>
where
    I: std::ops::Deref,
    I::Target: Source,
{
    /// `inner` read with each axis's reading `g` as `map(g, k[axis])`; `centred` says the
    /// readings come moved to their counts' centres ([`Source::gyro_centred`]).
    pub fn new(inner: I, map: fn(f32, f32) -> f32, k: [f32; 3], centred: bool) -> Self {
        MappedSource {
            inner,
            map,
            k,
            centred,
            full_scale_divisor: 1.0,
            clock: 1.0,
        }
    }

    /// `inner` read with its gyro axes multiplied by `scale`.
    pub fn scaled(inner: I, scale: [f32; 3]) -> Self {
        let centred = inner.gyro_centred();
        MappedSource::new(inner, |g, k| g * k, scale, centred)
    }

    /// `inner` read through the scale factors `inertia calibrate` gives (its `scale`, as a
    /// gyro's or as a clock's): every reading and the full scale divided by the gyro's
    /// `gyro`, so that saturation is still found where the gyro clipped, and every time
    /// divided by the clock's `clock` (a clock running `clock` times true time); 1 for either
    /// as read.
    pub fn rescaled(inner: I, gyro: f32, clock: f64) -> Self {
        let inv = 1.0 / gyro;
        MappedSource {
            full_scale_divisor: gyro,
            clock,
            ..MappedSource::scaled(inner, [inv; 3])
        }
    }
}

impl<I> Source for MappedSource<I>
where
    I: std::ops::Deref + Sync,
    I::Target: Source,
{
    fn name(&self) -> String {
        self.inner.name()
    }

    fn channels(&self) -> Channels {
        self.inner.channels()
    }

    fn full_scale(&self) -> f32 {
        self.inner.full_scale() / self.full_scale_divisor
    }

    fn gyro_averaging(&self) -> f32 {
        self.inner.gyro_averaging()
    }

    fn gyro_filters(&self) -> Option<GyroFilters> {
        self.inner.gyro_filters()
    }

    fn gyro_unit_stated(&self) -> bool {
        self.inner.gyro_unit_stated()
    }

    fn gyro_centred(&self) -> bool {
        self.centred
    }

    fn read_all(
        &self,
        visit: &mut Visit<'_>,
        progress: &mut dyn FnMut(f32),
    ) -> Result<Reading, ReadError> {
        let (map, k, clock) = (self.map, self.k, self.clock);
        let mut mapped = |s: &Sample| {
            let mut s = *s;
            for (g, k) in s.gyro.iter_mut().zip(k) {
                *g = map(*g, k);
            }
            s.t /= clock;
            visit(&s)
        };
        self.inner.read_all(&mut mapped, progress)
    }

    fn warnings(&self, found: Vec<String>) -> Vec<String> {
        self.inner.warnings(found)
    }
}
