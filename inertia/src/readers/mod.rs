//! Log readers: every format comes out as one [`Recording`] in SI units and the log's own
//! sensor axes.
//!
//! [`read`] detects the format from the content, never from the file name:
//!
//! | format | recognised by | module |
//! |---|---|---|
//! | Betaflight blackbox (also INDIflight) | first line `H Product:Blackbox flight data recorder` | [`blackbox`] |
//! | PX4 ULog | magic bytes `ULog` `0x01 0x12 0x35` | [`ulog`] |
//! | phyphox export | a folder holding `Raw Data.csv`, or that file (`"Time (s)",...`) | [`phyphox`] |
//! | CSV with named columns | any other text: `t`/`time`, `wx,wy,wz` or `gx,gy,gz`, ... | [`csv`] |
//!
//! Every malformed input comes back as a [`ReadError`] naming the file and, where one is to
//! blame, the line (text formats) or the frame/record (binary formats); nothing here panics.
//! Checks shared by all formats: time strictly increasing (an exact duplicate timestamp is
//! dropped with a warning, time going backwards is an error), every value finite, at least two
//! samples; warnings in [`Recording::warnings`] when the units look wrong (rates above
//! 50 rad/s sustained look like deg/s; a median time step below 1e-5 s or above 1 s looks like
//! the wrong time unit).

pub mod blackbox;
mod check;
pub mod csv;
pub mod gyro_filters;
mod output;
pub mod phyphox;
mod text;
pub mod ulog;
mod ulog_rotors;
mod units;

pub use output::{
    Channels, Extra, Flow, Reading, Recording, RotorSpeed, RotorUnit, Sample, Source, Visit,
    MAX_WHEELS,
};
pub use units::{
    ratios_warning, time_warning, unit_warnings, AccelCheck, UnitCheck, DEG_PER_SEC_SUSPECT_RAD_S,
    NEAR_SPHERE_RATIO, SLOW_DEG_PER_SEC_RAD_S, SUSTAINED_S,
};

use std::fmt;
use std::path::{Path, PathBuf};

use check::Checker;

/// Where in a file a problem is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// 1-based text line.
    Line(usize),
    /// 0-based main frame (blackbox) or data record (ULog) in the order of the file.
    Frame(usize),
}

/// A malformed or unreadable log: which file, where (when one place is to blame) and what.
#[derive(Clone, Debug, PartialEq)]
pub struct ReadError {
    /// The file (for a phyphox folder, its `Raw Data.csv`).
    pub file: PathBuf,
    /// The line or frame, if the problem is at one place.
    pub at: Option<Location>,
    /// What is wrong.
    pub message: String,
}

impl ReadError {
    /// An error about `file` as a whole.
    pub fn new(file: &Path, message: impl Into<String>) -> Self {
        ReadError {
            file: file.to_path_buf(),
            at: None,
            message: message.into(),
        }
    }

    /// An error at one place of `file`.
    pub fn at(file: &Path, at: Location, message: impl Into<String>) -> Self {
        ReadError {
            file: file.to_path_buf(),
            at: Some(at),
            message: message.into(),
        }
    }

    /// The 1-based line, for text formats.
    pub fn line(&self) -> Option<usize> {
        match self.at {
            Some(Location::Line(l)) => Some(l),
            _ => None,
        }
    }

    /// The 0-based frame or record, for binary formats.
    pub fn frame(&self) -> Option<usize> {
        match self.at {
            Some(Location::Frame(f)) => Some(f),
            _ => None,
        }
    }
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.at {
            Some(Location::Line(l)) => write!(f, "{}:{}: {}", self.file.display(), l, self.message),
            Some(Location::Frame(n)) => {
                write!(f, "{}: frame {}: {}", self.file.display(), n, self.message)
            }
            None => write!(f, "{}: {}", self.file.display(), self.message),
        }
    }
}

impl std::error::Error for ReadError {}

/// Unit of the gyro columns of a CSV.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GyroUnit {
    /// rad/s (the default).
    #[default]
    RadPerSec,
    /// deg/s.
    DegPerSec,
}

impl GyroUnit {
    /// Factor from this unit to rad/s.
    pub fn to_rad_per_sec(self) -> f64 {
        match self {
            GyroUnit::RadPerSec => 1.0,
            GyroUnit::DegPerSec => core::f64::consts::PI / 180.0,
        }
    }
}

/// Unit of the accelerometer columns of a CSV (the specific force, gravity included).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AccelUnit {
    /// m/s^2 (the default).
    #[default]
    MetersPerSec2,
    /// Standard gravities, 9.80665 m/s^2.
    G,
    /// Thousandths of a standard gravity.
    MilliG,
}

impl AccelUnit {
    /// Factor from this unit to m/s^2.
    pub fn to_meters_per_sec2(self) -> f64 {
        match self {
            AccelUnit::MetersPerSec2 => 1.0,
            AccelUnit::G => 9.806_65,
            AccelUnit::MilliG => 9.806_65e-3,
        }
    }
}

/// Unit of the time column of a CSV.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TimeUnit {
    /// Seconds (the default).
    #[default]
    S,
    /// Milliseconds.
    Ms,
    /// Microseconds.
    Us,
}

impl TimeUnit {
    /// Factor from this unit to seconds.
    pub fn to_seconds(self) -> f64 {
        match self {
            TimeUnit::S => 1.0,
            TimeUnit::Ms => 1e-3,
            TimeUnit::Us => 1e-6,
        }
    }
}

/// Options for formats that do not state their units (the named-column CSV). The binary
/// formats and phyphox state theirs and ignore these.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Gyro unit of a CSV; `None` means rad/s.
    pub gyro_unit: Option<GyroUnit>,
    /// Time unit of a CSV; `None` means seconds.
    pub time_unit: Option<TimeUnit>,
    /// Accelerometer unit of a CSV; `None` means m/s^2.
    pub accel_unit: Option<AccelUnit>,
    /// The rotor-speed columns a vehicle file names ([`crate::vehicle`]), in its order, at
    /// most [`MAX_WHEELS`]: read into [`Extra::wheels`] as logged. A column the log lacks is
    /// an error. In a ULog they are `topic.field` or `topic:N.field` ([`ulog`]).
    pub rotor_columns: Vec<String>,
    /// The names of the rotors those columns belong to, in the same order, for messages (a
    /// column a ULog lacks is refused with its rotor named); may be left empty.
    pub rotor_names: Vec<String>,
}

/// The formats [`read`] knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Betaflight blackbox (`.BFL`, `.BBL`), INDIflight included.
    Blackbox,
    /// PX4 ULog.
    Ulog,
    /// phyphox export (`Raw Data.csv` or its folder).
    Phyphox,
    /// CSV with named columns.
    Csv,
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::Blackbox => "blackbox",
            Format::Ulog => "ulog",
            Format::Phyphox => "phyphox",
            Format::Csv => "csv",
        })
    }
}

/// The first line of every blackbox log.
pub(crate) const BLACKBOX_MARKER: &[u8] = b"H Product:Blackbox flight data recorder";
/// The ULog file magic (with the version-independent bytes after `ULog`).
pub(crate) const ULOG_MAGIC: &[u8] = &[0x55, 0x4c, 0x6f, 0x67, 0x01, 0x12, 0x35];

/// A phyphox export may be given as its folder: then its `Raw Data.csv` is meant.
pub(crate) fn data_file(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join("Raw Data.csv")
    } else {
        path.to_path_buf()
    }
}

/// Which format the file (or phyphox folder) at `path` is, from its first bytes.
pub fn detect(path: &Path) -> Result<Format, ReadError> {
    use std::io::Read;
    if path.is_dir() {
        let f = path.join("Raw Data.csv");
        return if f.is_file() {
            Ok(Format::Phyphox)
        } else {
            Err(ReadError::new(
                path,
                "a folder is read only as a phyphox export, and it has no \"Raw Data.csv\"",
            ))
        };
    }
    let mut head = Vec::with_capacity(256);
    std::fs::File::open(path)
        .and_then(|f| f.take(256).read_to_end(&mut head))
        .map_err(|e| ReadError::new(path, format!("cannot read: {e}")))?;
    if head.starts_with(BLACKBOX_MARKER) {
        return Ok(Format::Blackbox);
    }
    if head.starts_with(ULOG_MAGIC) {
        return Ok(Format::Ulog);
    }
    if head.is_empty() {
        return Err(ReadError::new(path, "empty file"));
    }
    let head = head.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&head);
    let first_line = head.split(|&b| b == b'\n').next().unwrap_or_default();
    let first = String::from_utf8_lossy(first_line);
    if fields(&first)
        .first()
        .is_some_and(|c| c.starts_with("Time (s)"))
    {
        return Ok(Format::Phyphox);
    }
    // Only the first 256 bytes were read: a longer first line may be cut inside a character
    // of more than one byte, an incomplete sequence at the end (`error_len()` `None`) that is
    // no sign of binary content (a wide CSV header must not be refused as binary). A file that
    // really ends there is refused by the CSV reader, at that line.
    let not_utf8 = std::str::from_utf8(first_line).is_err_and(|e| e.error_len().is_some());
    if first_line.contains(&0) || not_utf8 {
        return Err(ReadError::at(
            path,
            Location::Line(1),
            "unknown format: binary content that is neither a blackbox log nor a ULog",
        ));
    }
    Ok(Format::Csv)
}

/// Reads the log at `path` (a file, or a phyphox export's folder), its format detected from
/// the content, with the rotor columns `opts` names (CSV, blackbox and ULog logs) as
/// [`crate::source::open`] reads them.
pub fn read(path: &Path, opts: &ReadOptions) -> Result<Recording, ReadError> {
    match detect(path)? {
        Format::Blackbox => {
            collect(&blackbox::BlackboxSource::open(path)?.with_rotor_fields(&opts.rotor_columns)?)
        }
        Format::Ulog => ulog::read_ulog_with(path, opts),
        Format::Phyphox => phyphox::read_phyphox(path),
        Format::Csv => csv::read_csv(path, opts),
    }
}

// ---- shared text helpers (phyphox and CSV) ----

/// The file's lines, refusing non-UTF-8 bytes (with the line), stripping a BOM and `\r`.
pub(crate) fn read_lines(path: &Path) -> Result<Vec<String>, ReadError> {
    let bytes =
        std::fs::read(path).map_err(|e| ReadError::new(path, format!("cannot read: {e}")))?;
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
    let mut lines = Vec::new();
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let s = std::str::from_utf8(raw).map_err(|e| {
            ReadError::at(path, Location::Line(i + 1), format!("not valid UTF-8: {e}"))
        })?;
        lines.push(s.trim_end_matches('\r').to_string());
    }
    // A final newline leaves one empty piece; a missing one leaves none.
    if lines.last().is_some_and(|l| l.is_empty()) {
        lines.pop();
    }
    Ok(lines)
}

/// The fields of a line: `,`, `;` (then with decimal commas) or tab as separator, taken from
/// the line itself; quotes and surrounding spaces removed.
pub(crate) fn fields(line: &str) -> Vec<String> {
    let (sep, decimal_comma) = if line.contains(';') {
        (';', true)
    } else if line.contains('\t') {
        ('\t', false)
    } else {
        (',', false)
    };
    line.split(sep)
        .map(|f| {
            let f = f.trim().trim_matches('"').trim();
            if decimal_comma {
                f.replace(',', ".")
            } else {
                f.to_string()
            }
        })
        .collect()
}

/// `s` for an error message: at most 40 characters, marked when cut.
pub(crate) fn quote(s: &str) -> String {
    const MAX: usize = 40;
    if s.chars().count() <= MAX {
        format!("{s:?}")
    } else {
        let head: String = s.chars().take(MAX).collect();
        format!("{head:?}... ({} bytes)", s.len())
    }
}

/// A finite number from a text field.
pub(crate) fn number(path: &Path, line: usize, what: &str, s: &str) -> Result<f64, ReadError> {
    let at = Location::Line(line);
    let v: f64 = s
        .parse()
        .map_err(|_| ReadError::at(path, at, format!("{what}: {} is not a number", quote(s))))?;
    if !v.is_finite() {
        return Err(ReadError::at(
            path,
            at,
            format!("{what}: {} is not finite", quote(s)),
        ));
    }
    Ok(v)
}

// ---- the checks every reader shares ----

/// Collects samples in SI units, checking each as it comes ([`Checker`]).
pub(crate) struct Samples {
    check: Checker,
    t: Vec<f64>,
    gyro: Vec<[f32; 3]>,
    accel: Vec<[f32; 3]>,
    rotor: Vec<f32>,
    /// The vehicle file's rotors ([`Samples::push`]), one vector per rotor.
    wheels: Vec<Vec<f32>>,
}

/// How a reader's rotor values become a [`RotorSpeed`] (`RotorSpeed::Erpm` or `RadPerSec`).
pub(crate) type RotorWrap = fn(Vec<f32>) -> RotorSpeed;

impl Samples {
    pub(crate) fn new(file: &Path) -> Self {
        Samples {
            check: Checker::new(file),
            t: Vec::new(),
            gyro: Vec::new(),
            accel: Vec::new(),
            rotor: Vec::new(),
            wheels: Vec::new(),
        }
    }

    /// Collects `wheels` rotor speeds besides ([`Samples::push`]; at most
    /// [`MAX_WHEELS`]).
    pub(crate) fn with_wheels(mut self, wheels: usize) -> Self {
        self.wheels = vec![Vec::new(); wheels.min(MAX_WHEELS)];
        self
    }

    /// Adds one sample. `accel` and `rotor` must be given for every sample or for none;
    /// `wheels` are the speeds of the rotors [`Samples::with_wheels`] set up, as logged (each
    /// must be finite; a missing one is refused as not finite).
    pub(crate) fn push(
        &mut self,
        at: Location,
        t: f64,
        gyro: [f64; 3],
        accel: Option<[f64; 3]>,
        rotor: Option<f64>,
        wheels: &[f64],
    ) -> Result<(), ReadError> {
        let (with_accel, with_rotor) = (accel.is_some(), rotor.is_some());
        let mut extra = Extra::default();
        for (k, o) in extra.wheels.iter_mut().take(self.wheels.len()).enumerate() {
            *o = wheels.get(k).map_or(f32::NAN, |&v| v as f32);
        }
        if let Some(s) = self.check.check_with(at, t, gyro, accel, rotor, extra)? {
            for (w, &v) in self.wheels.iter_mut().zip(&s.extra.wheels) {
                w.push(v);
            }
            self.t.push(s.t);
            self.gyro.push(s.gyro);
            if with_accel {
                self.accel.push(s.accel);
            }
            if with_rotor {
                self.rotor.push(s.rotor);
            }
        }
        Ok(())
    }

    /// The recording, with the duplicate and unit warnings. `rotor` says how the rotor values
    /// are to be wrapped (`None`: no rotor channel).
    pub(crate) fn finish(
        self,
        source: String,
        rotor: Option<RotorWrap>,
        gyro_full_scale: f32,
        mut warnings: Vec<String>,
    ) -> Result<Recording, ReadError> {
        warnings.extend(self.check.finish()?);
        let n = self.t.len();
        let accel = (self.accel.len() == n).then_some(self.accel);
        let rotor = match rotor {
            Some(wrap) if self.rotor.len() == n => Some(wrap(self.rotor)),
            _ => None,
        };
        let mut rec = Recording {
            source,
            t: self.t,
            gyro: self.gyro,
            accel,
            rotor,
            wheels: self.wheels,
            gyro_full_scale,
            gyro_averaging: 0.0,
            gyro_filters: None,
            gyro_unit_stated: true,
            warnings,
            ..Recording::default()
        };
        rec.warnings.extend(unit_warnings(&rec.t, &rec.gyro));
        Ok(rec)
    }
}

/// A streaming reader's whole log as a [`Recording`] (what [`read`] returns).
pub(crate) fn collect(src: &dyn Source) -> Result<Recording, ReadError> {
    let ch = src.channels();
    let mut t = Vec::new();
    let mut gyro = Vec::new();
    let mut accel = Vec::new();
    let mut rotor = Vec::new();
    let mut wheels = vec![Vec::new(); ch.wheels.min(MAX_WHEELS)];
    let (mut attitude, mut position, mut magnetic) = (Vec::new(), Vec::new(), Vec::new());
    let reading = src.read_all(
        &mut |s| {
            t.push(s.t);
            gyro.push(s.gyro);
            if ch.accel {
                accel.push(s.accel);
            }
            if ch.rotor.is_some() {
                rotor.push(s.rotor);
            }
            for (w, &v) in wheels.iter_mut().zip(&s.extra.wheels) {
                w.push(v);
            }
            if ch.attitude {
                attitude.push(s.extra.attitude);
            }
            if ch.position {
                position.push(s.extra.position);
            }
            if ch.magnetic {
                magnetic.push(s.extra.magnetic);
            }
            Ok(Flow::Continue)
        },
        &mut |_| {},
    )?;
    let mut found: Vec<String> = reading.duplicates.into_iter().collect();
    found.extend(unit_warnings(&t, &gyro));
    Ok(Recording {
        source: src.name(),
        t,
        gyro,
        accel: ch.accel.then_some(accel),
        rotor: ch.rotor.map(|u| u.wrap(rotor)),
        wheels,
        attitude: ch.attitude.then_some(attitude),
        position: ch.position.then_some(position),
        magnetic: ch.magnetic.then_some(magnetic),
        gyro_full_scale: src.full_scale(),
        gyro_averaging: src.gyro_averaging(),
        gyro_filters: src.gyro_filters(),
        gyro_unit_stated: src.gyro_unit_stated(),
        warnings: src.warnings(found),
    })
}

/// Runs a third-party parser, turning a panic inside it into a [`ReadError`]: the readers
/// promise never to panic on malformed input, and the crates do not all promise that.
pub(crate) fn guard<T>(file: &Path, what: &str, f: impl FnOnce() -> T) -> Result<T, ReadError> {
    // The panic hook is silenced for the call: the panic becomes the error below, and the
    // default hook would print a panic message and backtrace above a clean error (a fuzzing
    // harness's hook would abort). Hooks are global: another thread's panic in this window
    // would go unprinted, though it still ends that thread.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    std::panic::set_hook(hook);
    caught.map_err(|_| {
        ReadError::new(
            file,
            format!("the {what} parser failed on malformed input (it panicked)"),
        )
    })
}

/// A file of `bytes` named `name` in a folder of this test run's own (`kind` apart), for the
/// readers' tests.
#[cfg(test)]
pub(crate) fn test_file(kind: &str, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("inertia_{kind}_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}
