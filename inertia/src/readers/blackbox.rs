//! Betaflight blackbox logs (`.BFL`/`.BBL`), INDIflight's included, decoded with the
//! `blackbox-log` crate.
//!
//! Fields read from the main (I/P) frames, kept in the board's axes as logged:
//!
//! | field | unit in the log | in the [`Recording`] |
//! |---|---|---|
//! | frame time | microseconds | `t`, seconds |
//! | `gyroADC[0..2]` | by firmware, see [`GyroAdcUnit`] | `gyro`, rad/s |
//! | `accSmooth[0..2]` | counts, `acc_1G` per g (2048 when the header lacks it) | `accel`, m/s^2 |
//! | `erpm[0]` or `eRPM[0]` | eRPM / 100 | `rotor`, [`RotorSpeed::Erpm`] (true eRPM) |
//!
//! Betaflight logs its *filtered* gyro. The filters the header lists
//! ([`super::gyro_filters`]) delay the rate and spread it in time: each frame's rate is read
//! their delay later, interpolated between the logged readings around that time (the other
//! channels stay with their frames; the last frames, with no reading that late, are dropped),
//! and their time variance goes to the fits ([`Recording::gyro_smoothing`]). INDIflight's `gyroADC` is
//! the unfiltered gyro (on the shared thrown-FC logs it matches the RPM-filtered
//! `gyroADCafterRpm` unfiltered, not through the header's 100 Hz low-pass), so its times stay.
//!
//! The unit trap: the header's `gyro_scale` says 1.0 in both firmwares, yet Betaflight logs
//! `gyroADC` in deg/s (`lrintf(gyro.gyroADCf)`, tenths of deg/s with
//! `blackbox_high_resolution`) and INDIflight in raw counts of the +-2000 deg/s range (16.384
//! per deg/s). The header's scale is therefore ignored and the unit chosen from the firmware's
//! name; a wrong choice is 16.4x either way, which the rates' range check (too fast) or the
//! free-flight gate and the model tests (too slow: no free flight, `ModelMismatch`) catch.

use std::path::{Path, PathBuf};

use blackbox_log::frame::{Frame, FrameDef};
use blackbox_log::{File, Headers, ParserEvent};

use super::check::Checker;
use super::gyro_filters::{self, GyroFilters};
use super::{collect, guard, Location, ReadError, BLACKBOX_MARKER};
use crate::readers::Recording;
#[cfg(doc)]
use crate::readers::RotorSpeed;
use crate::readers::{
    Channels, Extra, Flow, Reading, RotorUnit, Sample, Source, Visit, MAX_WHEELS,
};

/// Raw gyro counts per deg/s (16-bit over +-2000 deg/s).
pub const GYRO_LSB_PER_DEG_S: f64 = 16.384;
/// Gyro full scale, rad/s (2000 deg/s).
pub const GYRO_FULL_SCALE_RAD_S: f32 = 2000.0 * core::f32::consts::PI / 180.0;
/// Accelerometer counts per g when the header has no `acc_1G`.
pub const DEFAULT_ACC_1G: f64 = 2048.0;
/// Standard gravity, m/s^2.
pub const G: f64 = 9.80665;
/// `erpm[0]` is logged divided by this.
pub const ERPM_LOG_FACTOR: f32 = 100.0;

/// The revision handed to `blackbox-log` in place of one it does not know.
const STAND_IN_REVISION: &[u8] = b"Betaflight 4.5.0";
const REVISION_KEY: &[u8] = b"H Firmware revision:";

/// What a log's `gyroADC` counts, chosen from its firmware's name (the header's `gyro_scale`
/// says 1.0 either way).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GyroAdcUnit {
    /// Raw sensor counts of the +-2000 deg/s range, 16.384 per deg/s: INDIflight, whose logs
    /// in `../shared/data/thrown-fc/` were checked against its authors' reader; also taken
    /// for a firmware this reader does not know, with a warning.
    RawCounts,
    /// deg/s (`lrintf(gyro.gyroADCf)`): Betaflight, INAV, EmuFlight, Rotorflight.
    DegPerS,
    /// Tenths of deg/s: Betaflight with `blackbox_high_resolution` set.
    DeciDegPerS,
}

impl GyroAdcUnit {
    /// The unit of the log whose `Firmware revision` is `revision` and whose header says
    /// `high_resolution` (the value of `blackbox_high_resolution`, if any).
    pub fn of(revision: &str, high_resolution: Option<&str>) -> Self {
        let name = revision.split(' ').next().unwrap_or_default();
        let logs_deg_s = ["betaflight", "inav", "emuflight", "rotorflight"]
            .iter()
            .any(|f| name.eq_ignore_ascii_case(f));
        if !logs_deg_s {
            GyroAdcUnit::RawCounts
        } else if high_resolution.is_some_and(|v| v.trim() == "1") {
            GyroAdcUnit::DeciDegPerS
        } else {
            GyroAdcUnit::DegPerS
        }
    }

    /// rad/s per logged unit.
    pub fn rad_s_per_unit(self) -> f64 {
        match self {
            GyroAdcUnit::RawCounts => (1.0 / GYRO_LSB_PER_DEG_S).to_radians(),
            GyroAdcUnit::DegPerS => 1.0f64.to_radians(),
            GyroAdcUnit::DeciDegPerS => 0.1f64.to_radians(),
        }
    }

    fn describe(self) -> String {
        match self {
            GyroAdcUnit::RawCounts => format!("raw counts, {GYRO_LSB_PER_DEG_S} per deg/s"),
            GyroAdcUnit::DegPerS => "deg/s".to_string(),
            GyroAdcUnit::DeciDegPerS => "tenths of deg/s (blackbox_high_resolution)".to_string(),
        }
    }
}

/// Whether `blackbox-log` 0.4 accepts the revision as it is: Betaflight 4.2 to 4.5, INAV 5
/// to 8.
fn crate_accepts(revision: &[u8]) -> bool {
    let text = String::from_utf8_lossy(revision);
    let mut words = text.split(' ');
    let name = words.next().unwrap_or_default();
    let mut version = words
        .next()
        .unwrap_or_default()
        .split('.')
        .map(|v| v.parse::<u32>().ok());
    let major = version.next().flatten();
    let minor = version.next().flatten();
    if name.eq_ignore_ascii_case("betaflight") {
        major == Some(4) && minor.is_some_and(|m| (2..=5).contains(&m))
    } else if name.eq_ignore_ascii_case("inav") {
        major.is_some_and(|m| (5..=8).contains(&m))
    } else {
        false
    }
}

/// Rewrites, in the header block of every log in `data`, a `Firmware revision` that
/// `blackbox-log` would refuse to a Betaflight revision it accepts; returns the new bytes and
/// the revisions replaced.
///
/// Why: `blackbox-log` refuses any firmware but Betaflight 4.2 to 4.5 and INAV 5 to 8, so
/// INDIflight (a Betaflight 4 fork writing `Indiflight 5.0.0 ...`), Betaflight 4.1 or 2025.12
/// and the other forks would not be read at all. The frame layout
/// (field names, predictors, encodings) is fully described by the `H Field ...` headers,
/// which the fork keeps in Betaflight's format; the firmware name only selects the meaning of
/// flag and mode enumerations, none of which this reader uses. Checked against an independent
/// decoder (`scripts/check-blackbox-reader.sh`). The file on disk is never touched.
pub fn rewrite_unknown_firmware(data: &[u8]) -> (Vec<u8>, Vec<String>) {
    rewrite_firmware(data, false)
}

/// [`rewrite_unknown_firmware`], or with `every` every revision, accepted or not: a log of a
/// supported firmware whose headers `blackbox-log` still refuses (an enumeration value it does
/// not know, such as a newer motor protocol) is then read as Betaflight 4.5's.
fn rewrite_firmware(data: &[u8], every: bool) -> (Vec<u8>, Vec<String>) {
    let mut out = Vec::with_capacity(data.len() + 64);
    let mut replaced = Vec::new();
    let mut copied = 0;
    let mut pos = 0;
    while let Some(start) = find(&data[pos..], BLACKBOX_MARKER).map(|i| pos + i) {
        // The header block: consecutive lines beginning with "H ".
        let mut line = start;
        while data[line..].starts_with(b"H ") {
            let end = data[line..]
                .iter()
                .position(|&b| b == b'\n')
                .map_or(data.len(), |i| line + i);
            if let Some(value) = data[line..end].strip_prefix(REVISION_KEY) {
                if every || !crate_accepts(value.strip_suffix(b"\r").unwrap_or(value)) {
                    out.extend_from_slice(&data[copied..line]);
                    out.extend_from_slice(REVISION_KEY);
                    out.extend_from_slice(STAND_IN_REVISION);
                    copied = end;
                    replaced.push(String::from_utf8_lossy(value).trim().to_string());
                }
            }
            if end >= data.len() {
                break;
            }
            line = end + 1;
        }
        pos = line.max(start + 1);
        if pos >= data.len() {
            break;
        }
    }
    out.extend_from_slice(&data[copied..]);
    (out, replaced)
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Field positions in a main frame (as `Frame::get_raw` indexes them).
struct Fields {
    gyro: [usize; 3],
    gyro_signed: [bool; 3],
    acc: Option<[usize; 3]>,
    acc_signed: [bool; 3],
    erpm: Option<usize>,
}

fn fields(headers: &Headers) -> Result<Fields, String> {
    let def = headers.main_frame_def();
    let mut gyro = [None; 3];
    let mut acc = [None; 3];
    let mut gyro_signed = [true; 3];
    let mut acc_signed = [true; 3];
    let mut erpm = None;
    for (i, f) in def.iter().enumerate() {
        for k in 0..3 {
            if f.name == ["gyroADC[0]", "gyroADC[1]", "gyroADC[2]"][k] {
                gyro[k] = Some(i);
                gyro_signed[k] = f.signed;
            }
            if f.name == ["accSmooth[0]", "accSmooth[1]", "accSmooth[2]"][k] {
                acc[k] = Some(i);
                acc_signed[k] = f.signed;
            }
        }
        if f.name.eq_ignore_ascii_case("erpm[0]") {
            erpm = Some(i);
        }
    }
    let [Some(g0), Some(g1), Some(g2)] = gyro else {
        return Err("the main frames have no gyroADC[0..2] fields".into());
    };
    let acc = match acc {
        [Some(a0), Some(a1), Some(a2)] => Some([a0, a1, a2]),
        _ => None,
    };
    Ok(Fields {
        gyro: [g0, g1, g2],
        gyro_signed,
        acc,
        acc_signed,
        erpm,
    })
}

/// Undoes a `blackbox-log` 0.4.3 decoding error.
///
/// After an I-frame, the blackbox encoder (Betaflight's `writeIntraframe`) makes the I-frame
/// both the previous and the previous-previous state, so the first P-frame's `AVERAGE_2`
/// (predictor 3) and `STRAIGHT_LINE` (predictor 2) fields are predicted from the I-frame
/// alone. `blackbox-log` 0.4.3 keeps the real frame before the I-frame as previous-previous
/// (it does so right only for the frame time): that P-frame comes out wrong by half the
/// change over the I-frame, and the error carries on (about 2/3 of it) through every P-frame
/// until the next I-frame. Found by comparing with the `orangebox` decoder
/// (`scripts/check-blackbox-reader.sh`): `gyroADC` and `accSmooth` (predictor 3) differed
/// from the 2nd P-frame after the first I-frame on.
///
/// The crate's outputs still carry the encoded deltas exactly: `delta = out - pred(crate's
/// history)`. This replays each such field: it recovers the delta with the crate's own
/// predictor on the crate's history, and adds it to the predictor applied to the corrected
/// history, where an I-frame fills both slots.
#[derive(Debug)]
struct Replay {
    predictor: u8,
    signed: bool,
    /// The crate's last two outputs.
    crate_hist: (Option<u32>, Option<u32>),
    /// The corrected last two values.
    true_hist: (Option<u32>, Option<u32>),
}

impl Replay {
    fn new(predictor: u8, signed: bool) -> Self {
        Replay {
            predictor,
            signed,
            crate_hist: (None, None),
            true_hist: (None, None),
        }
    }

    /// `blackbox-log`'s prediction (its `average` / `straight_line`, overflow rules included).
    fn predict(&self, last: Option<u32>, last_last: Option<u32>) -> u32 {
        let wide = |v: u32| {
            if self.signed {
                i64::from(v as i32)
            } else {
                i64::from(v)
            }
        };
        let fits = |r: i64| {
            if self.signed {
                i32::try_from(r).is_ok()
            } else {
                u32::try_from(r).is_ok()
            }
        };
        match self.predictor {
            3 => {
                let l = last.unwrap_or(0);
                last_last.map_or(l, |ll| ((wide(l) + wide(ll)) / 2) as u32)
            }
            2 => match (last, last_last) {
                (Some(l), Some(ll)) => {
                    let r = 2 * wide(l) - wide(ll);
                    if fits(r) {
                        r as u32
                    } else {
                        l
                    }
                }
                (Some(l), None) => l,
                _ => 0,
            },
            _ => 0,
        }
    }

    /// The corrected value of the crate's output `out` for a frame.
    fn step(&mut self, out: u32, intra: bool) -> u32 {
        let value = if intra {
            out
        } else {
            let delta = out.wrapping_sub(self.predict(self.crate_hist.0, self.crate_hist.1));
            self.predict(self.true_hist.0, self.true_hist.1)
                .wrapping_add(delta)
        };
        self.crate_hist = (Some(out), self.crate_hist.0);
        self.true_hist = if intra {
            (Some(value), Some(value))
        } else {
            (Some(value), self.true_hist.0)
        };
        value
    }
}

/// The value of the `H key:value` line `key` of a header block.
fn header_value<'a>(block: &'a [(String, String)], key: &str) -> Option<&'a str> {
    block
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.as_str())
}

/// The `H name:value` lines of each log's header block, in the order of the logs.
fn header_blocks(data: &[u8]) -> Vec<Vec<(String, String)>> {
    let mut out = Vec::new();
    let mut pos = 0;
    while let Some(start) = find(&data[pos..], FULL_MARKER).map(|i| pos + i) {
        let mut block = Vec::new();
        let mut line = start;
        while data[line..].starts_with(b"H ") {
            let end = data[line..]
                .iter()
                .position(|&b| b == b'\n')
                .map_or(data.len(), |i| line + i);
            let text = String::from_utf8_lossy(&data[line + 2..end]);
            if let Some((k, v)) = text.split_once(':') {
                block.push((k.to_string(), v.trim_end_matches('\r').to_string()));
            }
            if end >= data.len() {
                break;
            }
            line = end + 1;
        }
        out.push(block);
        pos = start + FULL_MARKER.len();
    }
    out
}

/// The marker `blackbox-log` splits a file at.
const FULL_MARKER: &[u8] = b"H Product:Blackbox flight data recorder by Nicholas Sherlock\n";

fn value(raw: u32, signed: bool) -> f64 {
    if signed {
        f64::from(raw as i32)
    } else {
        f64::from(raw)
    }
}

/// Reads a blackbox log file. A file holding several logs (several arming periods) gives its
/// longest one, with a warning.
pub fn read_blackbox(path: &Path) -> Result<Recording, ReadError> {
    collect(&BlackboxSource::open(path)?)
}

/// Reads blackbox bytes (`path` only names them in messages).
pub fn read_bytes(path: &Path, data: &[u8]) -> Result<Recording, ReadError> {
    collect(&BlackboxSource::from_bytes(path, data)?)
}

/// A blackbox log read frame by frame (see [`crate::source`]). The file's bytes stay in
/// memory: `blackbox-log` decodes from a byte slice.
pub struct BlackboxSource {
    path: PathBuf,
    /// The file, its unknown firmware revisions rewritten.
    data: Vec<u8>,
    /// The log read (the one with the most main frames).
    index: usize,
    /// Its `H name:value` lines, as written.
    block: Vec<(String, String)>,
    /// What its `gyroADC` counts.
    gyro_unit: GyroAdcUnit,
    /// The filters its `gyroADC` has passed through (Betaflight's family), if known.
    filters: Option<GyroFilters>,
    /// How late its accelerometer's low-pass makes `accSmooth`, s (0: unfiltered).
    accel_delay: f64,
    name: String,
    channels: Channels,
    /// Warnings about the file as a whole (firmware, units, several logs).
    notes: Vec<String>,
    /// The main-frame fields a vehicle file names as its rotors' speeds (`eRPM[2]`), read into
    /// [`crate::readers::Extra::wheels`] ([`BlackboxSource::with_rotor_fields`]).
    wheels: Vec<String>,
}

impl BlackboxSource {
    /// The same log with the main-frame fields `names` (a vehicle file's rotor columns, such
    /// as `eRPM[2]`; case-insensitive) read as the rotors' speeds, as logged (an `eRPM[k]`
    /// field in true eRPM); an error names a field the log does not have.
    pub fn with_rotor_fields(mut self, names: &[String]) -> Result<Self, ReadError> {
        if names.is_empty() {
            return Ok(self);
        }
        if names.len() > MAX_WHEELS {
            return Err(ReadError::new(&self.path, "more than eight rotor fields"));
        }
        let missing = {
            let file = File::new(&self.data);
            let Some(Ok(headers)) = file.parse(self.index) else {
                return Err(ReadError::new(
                    &self.path,
                    "the log's headers no longer parse",
                ));
            };
            let def = headers.main_frame_def();
            let have: Vec<String> = def.iter().map(|f| f.name.to_string()).collect();
            names
                .iter()
                .find(|n| !have.iter().any(|h| h.eq_ignore_ascii_case(n.trim())))
                .map(|n| (n.clone(), have.join(", ")))
        };
        if let Some((n, have)) = missing {
            return Err(ReadError::new(
                &self.path,
                format!(
                    "the vehicle file names the rotor field {n:?}, which the log's main frames do \
                     not have (they have {have})"
                ),
            ));
        }
        self.wheels = names.to_vec();
        self.channels.wheels = names.len();
        Ok(self)
    }

    /// Reads the file and chooses its log.
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        let data =
            std::fs::read(path).map_err(|e| ReadError::new(path, format!("cannot read: {e}")))?;
        Self::from_bytes(path, &data)
    }

    /// Chooses the log of `data` (`path` only names it in messages).
    pub fn from_bytes(path: &Path, input: &[u8]) -> Result<Self, ReadError> {
        if !input.starts_with(BLACKBOX_MARKER) {
            return Err(ReadError::at(
                path,
                Location::Line(1),
                "not a blackbox log: it does not start with \"H Product:Blackbox flight data recorder\"",
            ));
        }
        let original = header_blocks(input);
        let (mut data, mut replaced) = rewrite_unknown_firmware(input);
        let mut chosen = guard(path, "blackbox", || choose_log(path, &data))?;
        if chosen.is_err() {
            let (every, all) = rewrite_firmware(input, true);
            if let Ok(Ok(c)) = guard(path, "blackbox", || choose_log(path, &every)) {
                (data, replaced, chosen) = (every, all, Ok(c));
            }
        }
        let chosen = chosen?;
        let Chosen {
            index,
            count,
            channels,
        } = chosen;
        // The chosen log's header lines as written (its own firmware revision, not the
        // stand-in handed to the decoder).
        let block = original.into_iter().nth(index).unwrap_or_default();
        let revision =
            header_value(&block, "Firmware revision").map_or("unknown firmware", str::trim);
        let gyro_unit = GyroAdcUnit::of(revision, header_value(&block, "blackbox_high_resolution"));
        let name = format!("{} (blackbox, {revision})", path.display());
        let mut notes = Vec::new();
        for r in replaced {
            notes.push(format!(
                "firmware revision {r:?} read as a Betaflight 4.5 log (same frame format)"
            ));
        }
        let firmware = revision.split(' ').next().unwrap_or_default();
        let known =
            gyro_unit != GyroAdcUnit::RawCounts || firmware.eq_ignore_ascii_case("indiflight");
        // Only INDIflight's raw counts are verified; an unknown fork may log deg/s like
        // Betaflight, which this scale would make 16.4x too slow.
        notes.push(if known {
            format!(
                "gyroADC read as {} ({firmware}'s unit)",
                gyro_unit.describe()
            )
        } else {
            format!(
                "gyroADC of firmware {firmware:?} read as {}, as INDIflight logs it; if this \
                 firmware logs deg/s like Betaflight, the rates are 16.4x too small",
                gyro_unit.describe()
            )
        });
        if count > 1 {
            notes.push(format!(
                "the file holds {count} logs; the one with the most main frames was read"
            ));
        }
        // Betaflight's family logs the filtered gyro; INDIflight (raw counts) the unfiltered.
        let lookup = |k: &str| header_value(&block, k).map(|v| v.trim().to_string());
        let filters = if gyro_unit == GyroAdcUnit::RawCounts {
            None
        } else {
            // No filter named: none assumed, the log's unit still counted in its noise.
            let f = gyro_filters::betaflight(&lookup, gyro_unit.rad_s_per_unit())
                .unwrap_or_else(|| GyroFilters::none(gyro_unit.rad_s_per_unit()));
            notes.push(if f.is_none() {
                format!(
                    "gyroADC is {firmware}'s filtered gyro, but the header names no gyro \
                     filter this reader knows: taken as unfiltered (a fast tumble's estimate \
                     may then be off by more than its standard deviation)"
                )
            } else {
                format!(
                    "gyroADC is {firmware}'s filtered gyro ({}): each rate read {:.2} ms after \
                     its frame (the filters' delay) and their time spread, {:.2e} s^2, counted \
                     in the fits{}",
                    f.described,
                    f.delay_s * 1e3,
                    f.variance_s2,
                    if f.uncertain > 0.0 {
                        format!(
                            " (+-{:.1e} s^2 from where the dynamic notches sat, not logged)",
                            f.uncertain
                        )
                    } else {
                        String::new()
                    }
                )
            });
            Some(f)
        };
        // Betaflight's accelerometer low-pass (`acc_lpf_hz`, logged times 100): a PT2 since 4.3,
        // a biquad before; its delay is the time the free-flight gate's model and the
        // accelerometer are apart. INDIflight's `accSmooth` is unfiltered (its centre-of-mass
        // fit on the shared logs is worst with the header's 50 Hz put on the model's side).
        let accel_delay = match (&filters, channels.accel) {
            (Some(_), true) => gyro_filters::betaflight_accel_delay(&lookup, revision),
            _ => 0.0,
        };
        if accel_delay > 0.0 {
            notes.push(format!(
                "accSmooth is {firmware}'s low-passed accelerometer: each reading read {:.1} ms \
                 after its frame (the filter's delay) for the free-flight gate",
                accel_delay * 1e3
            ));
        }
        Ok(BlackboxSource {
            path: path.to_path_buf(),
            data,
            index,
            block,
            gyro_unit,
            filters,
            accel_delay,
            name,
            channels,
            notes,
            wheels: Vec::new(),
        })
    }
}

/// The log chosen in a file.
struct Chosen {
    index: usize,
    count: usize,
    channels: Channels,
}

/// The log with the most main frames (the first of equals); with several logs, every log is
/// decoded once to count its frames. A log without the gyro fields counts none.
fn choose_log(path: &Path, data: &[u8]) -> Result<Chosen, ReadError> {
    let file = File::new(data);
    let count = file.log_count();
    let mut best: Option<(usize, usize)> = None;
    let mut header_errors = Vec::new();
    for index in 0..count {
        let headers = match file.parse(index) {
            Some(Ok(h)) => h,
            Some(Err(e)) => {
                header_errors.push(format!("log {}: bad headers: {e}", index + 1));
                continue;
            }
            None => continue,
        };
        let frames = if count == 1 || fields(&headers).is_err() {
            0
        } else {
            let mut parser = headers.data_parser();
            let mut n = 0usize;
            while let Some(event) = parser.next() {
                if let ParserEvent::Main(_) = event {
                    n += 1;
                }
            }
            n
        };
        if best.is_none_or(|(_, n)| frames > n) {
            best = Some((index, frames));
        }
    }
    let Some((index, _)) = best else {
        let why = if header_errors.is_empty() {
            "no log in the file".to_string()
        } else {
            header_errors.join("; ")
        };
        return Err(ReadError::new(path, why));
    };
    let headers = match file.parse(index) {
        Some(Ok(h)) => h,
        _ => {
            return Err(ReadError::new(
                path,
                "the log's headers did not parse twice alike",
            ))
        }
    };
    let f = fields(&headers).map_err(|e| ReadError::new(path, e))?;
    Ok(Chosen {
        index,
        count,
        channels: Channels {
            accel: f.acc.is_some(),
            rotor: f.erpm.map(|_| RotorUnit::Erpm),
            ..Channels::default()
        },
    })
}

impl Source for BlackboxSource {
    fn name(&self) -> String {
        self.name.clone()
    }

    fn channels(&self) -> Channels {
        self.channels
    }

    fn full_scale(&self) -> f32 {
        GYRO_FULL_SCALE_RAD_S
    }

    fn gyro_filters(&self) -> Option<GyroFilters> {
        self.filters.clone()
    }

    fn read_all(
        &self,
        visit: &mut Visit<'_>,
        progress: &mut dyn FnMut(f32),
    ) -> Result<Reading, ReadError> {
        let path = self.path.as_path();
        guard(path, "blackbox", || {
            let file = File::new(&self.data);
            let headers = match file.parse(self.index) {
                Some(Ok(h)) => h,
                _ => return Err(ReadError::new(path, "the log's headers no longer parse")),
            };
            let delay = [
                self.filters.as_ref().map_or(0.0, |f| f.delay_s),
                self.accel_delay,
            ];
            read_log(
                path,
                &headers,
                &self.block,
                (self.gyro_unit, delay),
                &self.wheels,
                visit,
                progress,
            )
        })?
    }

    fn warnings(&self, found: Vec<String>) -> Vec<String> {
        let mut w = self.notes.clone();
        w.extend(found);
        w
    }
}

/// What each frame's gyro and accelerometer readings stand for: a channel whose filters make
/// it `delay` late is read `delay` after the frame, interpolated between the two logged
/// readings around that time ((G3) of [`super::gyro_filters`]). The rotor's speed stays with
/// its frame (it keeps its telemetry steps, which the fits' resolution model reads). Frames
/// wait here until readings that late have been read; the last ones of the log, which have
/// none, are dropped.
struct Advance {
    /// The gyro's and the accelerometer's delays, s.
    delay: [f64; 2],
    /// Frames read, not yet given out, oldest first.
    pending: std::collections::VecDeque<Sample>,
    /// Per channel, the pending frame where the last search ended: the times searched for
    /// only grow, so each search goes on from there (the accelerometer's delay is tens of
    /// frames: searching from the front every time cost as many steps per frame).
    cursor: [usize; 2],
}

impl Advance {
    fn new(delay: [f64; 2]) -> Self {
        Advance {
            delay: delay.map(|d| if d > 0.0 && d.is_finite() { d } else { 0.0 }),
            pending: std::collections::VecDeque::new(),
            cursor: [0; 2],
        }
    }

    /// Channel `ch` (0 the gyro, 1 the accelerometer, `pick` reads it) at `when`, interpolated
    /// between the first two pending frames around it (the newest frame's when none are).
    fn at(&mut self, ch: usize, when: f64, pick: fn(&Sample) -> [f32; 3]) -> [f32; 3] {
        let p = &self.pending;
        let mut c = self.cursor[ch];
        while p.get(c + 1).is_some_and(|b| b.t < when) {
            c += 1;
        }
        self.cursor[ch] = c;
        match (p.get(c), p.get(c + 1)) {
            (Some(a), Some(b)) if a.t <= when && when <= b.t => {
                let f = ((when - a.t) / (b.t - a.t)) as f32;
                let (x, y) = (pick(a), pick(b));
                [0, 1, 2].map(|k| x[k] + f * (y[k] - x[k]))
            }
            _ => p.back().map_or([0.0; 3], pick),
        }
    }

    /// Takes the next frame; gives out, oldest first, every frame whose readings can now be
    /// read.
    fn push(
        &mut self,
        s: Sample,
        out: &mut dyn FnMut(Sample) -> Result<Flow, ReadError>,
    ) -> Result<Flow, ReadError> {
        let [dg, da] = self.delay;
        if dg == 0.0 && da == 0.0 {
            return out(s);
        }
        self.pending.push_back(s);
        loop {
            let (Some(front), Some(last)) = (self.pending.front(), self.pending.back()) else {
                return Ok(Flow::Continue);
            };
            if last.t < front.t + dg.max(da) {
                return Ok(Flow::Continue);
            }
            let t = front.t;
            let gyro = self.at(0, t + dg, |s| s.gyro);
            let accel = self.at(1, t + da, |s| s.accel);
            let Some(mut s) = self.pending.pop_front() else {
                return Ok(Flow::Continue);
            };
            self.cursor = self.cursor.map(|c| c.saturating_sub(1));
            (s.gyro, s.accel) = (gyro, accel);
            if out(s)? == Flow::Stop {
                return Ok(Flow::Stop);
            }
        }
    }
}

/// Decodes one log, giving each checked sample to `visit`; `(gyro_unit, delay)`: what
/// `gyroADC` counts and how late the gyro's and the accelerometer's filters made them (s;
/// each frame's readings are read that much later, [`Advance`]).
fn read_log(
    path: &Path,
    headers: &Headers,
    block: &[(String, String)],
    (gyro_unit, delay): (GyroAdcUnit, [f64; 2]),
    wheel_names: &[String],
    visit: &mut Visit<'_>,
    progress: &mut dyn FnMut(f32),
) -> Result<Reading, ReadError> {
    let f = fields(headers).map_err(|e| ReadError::new(path, e))?;
    // The vehicle's rotor fields: column, eRPM (logged / 100) or not.
    let wheels: Vec<(usize, bool)> = wheel_names
        .iter()
        .filter_map(|n| {
            let def = headers.main_frame_def();
            let c = def
                .iter()
                .position(|fd| fd.name.eq_ignore_ascii_case(n.trim()))?;
            Some((c, n.trim().to_ascii_lowercase().starts_with("erpm")))
        })
        .collect();
    let header = |k: &str| header_value(block, k);
    // P-frame predictors by field name. (The header lists include `time`, which the crate's
    // frame definition leaves out: match by name, never by position.)
    let names: Vec<&str> = header("Field I name")
        .unwrap_or_default()
        .split(',')
        .collect();
    let p_predictors: Vec<u8> = header("Field P predictor")
        .unwrap_or_default()
        .split(',')
        .map(|p| p.trim().parse().unwrap_or(0))
        .collect();
    let def = headers.main_frame_def();
    let predictor_of = |i: usize| -> u8 {
        def.get(i)
            .and_then(|fd| names.iter().position(|n| *n == fd.name))
            .and_then(|j| p_predictors.get(j).copied())
            .unwrap_or(0)
    };
    let i_interval: u32 = header("I interval")
        .and_then(|v| v.trim().parse().ok())
        .filter(|&v| v > 0)
        .unwrap_or(32);
    let replay_for = |i: usize, signed: bool| {
        let p = predictor_of(i);
        (p == 2 || p == 3).then(|| Replay::new(p, signed))
    };
    let mut gyro_fix: Vec<Option<Replay>> = (0..3)
        .map(|k| replay_for(f.gyro[k], f.gyro_signed[k]))
        .collect();
    let mut acc_fix: Vec<Option<Replay>> = (0..3)
        .map(|k| f.acc.and_then(|a| replay_for(a[k], f.acc_signed[k])))
        .collect();
    let mut erpm_fix = f.erpm.and_then(|c| replay_for(c, false));
    let mut wheel_fix: Vec<Option<Replay>> =
        wheels.iter().map(|&(c, _)| replay_for(c, false)).collect();
    let acc_1g = headers
        .unknown()
        .get("acc_1G")
        .and_then(|s| s.trim().parse::<f64>().ok())
        .filter(|&g| g > 0.0)
        .unwrap_or(DEFAULT_ACC_1G);
    let kw = gyro_unit.rad_s_per_unit();
    let ka = G / acc_1g;
    let mut check = Checker::new(path);
    let mut advance = Advance::new(delay);
    let mut given = 0usize;
    let mut parser = headers.data_parser();
    let mut n = 0usize;
    loop {
        if n % 65536 == 65535 {
            progress(parser.stats().progress);
        }
        let Some(event) = parser.next() else {
            break;
        };
        let ParserEvent::Main(frame) = event else {
            continue;
        };
        let at = Location::Frame(n);
        n += 1;
        // I-frames are the frames whose iteration is a multiple of the I interval (Betaflight
        // writes them so; checked on every frame of the ten thrown-fc logs).
        let intra = frame.get_raw(0).is_some_and(|it| it % i_interval == 0);
        let read3 = |cols: [usize; 3],
                     signed: [bool; 3],
                     fix: &mut [Option<Replay>],
                     k: f64|
         -> Option<[f64; 3]> {
            let mut out = [0.0; 3];
            for (o, ((&c, s), fx)) in out
                .iter_mut()
                .zip(cols.iter().zip(signed).zip(fix.iter_mut()))
            {
                let raw = frame.get_raw(c)?;
                let raw = fx.as_mut().map_or(raw, |r| r.step(raw, intra));
                *o = value(raw, s) * k;
            }
            Some(out)
        };
        let Some(w) = read3(f.gyro, f.gyro_signed, &mut gyro_fix, kw) else {
            return Err(ReadError::at(path, at, "frame lacks a gyro field"));
        };
        // A missing value becomes NaN, which the check refuses naming the frame.
        let a = f
            .acc
            .map(|cols| read3(cols, f.acc_signed, &mut acc_fix, ka).unwrap_or([f64::NAN; 3]));
        let r = f.erpm.map(|c| {
            frame.get_raw(c).map_or(f64::NAN, |v| {
                let v = erpm_fix.as_mut().map_or(v, |r| r.step(v, intra));
                value(v, false) * f64::from(ERPM_LOG_FACTOR)
            })
        });
        let mut extra = Extra::default();
        for ((o, &(c, erpm)), fx) in extra.wheels.iter_mut().zip(&wheels).zip(&mut wheel_fix) {
            *o = frame.get_raw(c).map_or(f32::NAN, |v| {
                let v = fx.as_mut().map_or(v, |r| r.step(v, intra));
                let k = if erpm {
                    f64::from(ERPM_LOG_FACTOR)
                } else {
                    1.0
                };
                (value(v, false) * k) as f32
            });
        }
        let t = frame.time_raw() as f64 * 1e-6;
        if let Some(s) = check.check_with(at, t, w, a, r, extra)? {
            let flow = advance.push(s, &mut |s| {
                given += 1;
                visit(&s)
            })?;
            if flow == Flow::Stop {
                return check.reading(true).map(|r| Reading {
                    samples: given,
                    ..r
                });
            }
        }
    }
    // The frames still waiting for a later reading (the last ones) are not given.
    check.reading(false).map(|r| Reading {
        samples: given,
        ..r
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rewrites_only_unknown_revisions_in_headers() {
        let log = b"H Product:Blackbox flight data recorder by Nicholas Sherlock\nH Firmware revision:Indiflight 5.0.0 (x) STM32H743\nH a:b\nI\x00H Firmware revision:Indiflight\n";
        let (out, r) = rewrite_unknown_firmware(log);
        assert_eq!(r, vec!["Indiflight 5.0.0 (x) STM32H743".to_string()]);
        let s = String::from_utf8_lossy(&out);
        assert!(
            s.contains("H Firmware revision:Betaflight 4.5.0\nH a:b\n"),
            "{s}"
        );
        // After the header block, bytes are data: left alone.
        assert!(s.ends_with("I\u{0}H Firmware revision:Indiflight\n"), "{s}");
        let bf = b"H Product:Blackbox flight data recorder by Nicholas Sherlock\nH Firmware revision:Betaflight 4.4.2\n";
        assert_eq!(rewrite_unknown_firmware(bf), (bf.to_vec(), vec![]));
        // Betaflight versions `blackbox-log` 0.4 refuses are rewritten too.
        let old = b"H Product:Blackbox flight data recorder by Nicholas Sherlock\nH Firmware revision:Betaflight 2025.12.1 (x) F7\n";
        assert_eq!(
            rewrite_unknown_firmware(old).1,
            vec!["Betaflight 2025.12.1 (x) F7".to_string()]
        );
    }
}
