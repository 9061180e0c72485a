//! Readers for gyro logs: phyphox exports (`Raw Data.csv` plus `meta/segments.csv`) and a
//! plain CSV with header `t,wx,wy,wz` (seconds, rad/s).
//!
//! Every malformed input is an [`InputError`] naming the file and, where one is to blame, the
//! line (1-based). Nothing here panics: non-UTF-8 bytes, empty files, truncated or short rows,
//! NaN or infinite fields and time that does not increase all come back as errors.

use std::fmt;
use std::path::{Path, PathBuf};

/// A malformed or unreadable input: which file, which line (1-based, when one is to blame)
/// and what is wrong.
#[derive(Clone, Debug, PartialEq)]
pub struct InputError {
    /// The file.
    pub file: PathBuf,
    /// The 1-based line, if the problem is on one line.
    pub line: Option<usize>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(l) => write!(f, "{}:{}: {}", self.file.display(), l, self.message),
            None => write!(f, "{}: {}", self.file.display(), self.message),
        }
    }
}

impl std::error::Error for InputError {}

fn err(file: &Path, line: Option<usize>, message: impl Into<String>) -> InputError {
    InputError {
        file: file.to_path_buf(),
        line,
        message: message.into(),
    }
}

/// The two accepted log formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// phyphox "Raw Data.csv": quoted header `"Time (s)","Gyroscope x (rad/s)",...`.
    Phyphox,
    /// Plain CSV with header `t,wx,wy,wz`.
    Csv,
}

impl std::str::FromStr for Format {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "phyphox" => Ok(Format::Phyphox),
            "csv" => Ok(Format::Csv),
            other => Err(format!("unknown format {} (phyphox|csv)", quote(other))),
        }
    }
}

/// A free-flight window `[start, end]` in the log's time base.
#[derive(Clone, Debug, PartialEq)]
pub struct Segment {
    /// Label (the `segment` column, or "all").
    pub label: String,
    /// Start time, seconds.
    pub start: f64,
    /// End time, seconds.
    pub end: f64,
}

/// A gyro log with its free-flight segments (sorted by start time).
#[derive(Clone, Debug, PartialEq)]
pub struct Log {
    /// Where it came from.
    pub source: PathBuf,
    /// Sample times, strictly increasing, seconds.
    pub t: Vec<f64>,
    /// Angular velocity, rad/s, sensor axes.
    pub omega: Vec<[f64; 3]>,
    /// Free-flight windows; the whole log when no segments file was given.
    pub segments: Vec<Segment>,
}

impl Log {
    /// Sample index ranges `[i0, i1)` of each segment.
    pub fn segment_ranges(&self) -> Vec<(usize, usize)> {
        self.segments
            .iter()
            .map(|s| {
                let i0 = self.t.partition_point(|&t| t < s.start);
                let i1 = self.t.partition_point(|&t| t <= s.end);
                (i0, i1.max(i0))
            })
            .collect()
    }
}

/// Reads the file's lines, refusing non-UTF-8 bytes (with the line) and stripping a BOM and
/// `\r`.
fn read_lines(path: &Path) -> Result<Vec<String>, InputError> {
    let bytes = std::fs::read(path).map_err(|e| err(path, None, format!("cannot read: {e}")))?;
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
    let mut lines = Vec::new();
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let s = std::str::from_utf8(raw)
            .map_err(|e| err(path, Some(i + 1), format!("not valid UTF-8: {e}")))?;
        lines.push(s.trim_end_matches('\r').to_string());
    }
    // A final newline leaves one empty piece; a missing one leaves none.
    if lines.last().is_some_and(|l| l.is_empty()) {
        lines.pop();
    }
    Ok(lines)
}

/// The fields of a line. phyphox exports may use `,`, `;` (then with decimal commas) or tab
/// as separator; the separator is taken from the line itself.
fn fields(line: &str) -> Vec<String> {
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
fn quote(s: &str) -> String {
    const MAX: usize = 40;
    if s.chars().count() <= MAX {
        format!("{s:?}")
    } else {
        let head: String = s.chars().take(MAX).collect();
        format!("{head:?}... ({} bytes)", s.len())
    }
}

fn number(path: &Path, line: usize, what: &str, s: &str) -> Result<f64, InputError> {
    let v: f64 = s.parse().map_err(|_| {
        err(
            path,
            Some(line),
            format!("{what}: {} is not a number", quote(s)),
        )
    })?;
    if !v.is_finite() {
        return Err(err(
            path,
            Some(line),
            format!("{what}: {} is not finite", quote(s)),
        ));
    }
    Ok(v)
}

/// Which format the file at `path` is, from its header line.
pub fn detect(path: &Path) -> Result<Format, InputError> {
    let file = data_file(path);
    let lines = read_lines(&file)?;
    let Some(h) = lines.first() else {
        return Err(err(&file, None, "empty file"));
    };
    let f = fields(h);
    if f.first().is_some_and(|c| c.starts_with("Time (s)")) {
        Ok(Format::Phyphox)
    } else if f.first().is_some_and(|c| c == "t") {
        Ok(Format::Csv)
    } else {
        Err(err(
            &file,
            Some(1),
            format!(
                "unknown header {}: expected phyphox \"Time (s)\",... or t,wx,wy,wz",
                quote(h)
            ),
        ))
    }
}

/// A phyphox export may be given as its folder: then its `Raw Data.csv` is read.
fn data_file(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join("Raw Data.csv")
    } else {
        path.to_path_buf()
    }
}

/// Samples `(t, omega)` from the data lines of either format (header already checked).
fn samples(path: &Path, lines: &[String]) -> Result<(Vec<f64>, Vec<[f64; 3]>), InputError> {
    let mut t = Vec::new();
    let mut omega = Vec::new();
    for (i, line) in lines.iter().enumerate().skip(1) {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f = fields(line);
        if f.len() < 4 {
            return Err(err(
                path,
                Some(n),
                format!(
                    "truncated row: {} field(s), need 4 (t, wx, wy, wz)",
                    f.len()
                ),
            ));
        }
        let tk = number(path, n, "time", &f[0])?;
        let w = [
            number(path, n, "wx", &f[1])?,
            number(path, n, "wy", &f[2])?,
            number(path, n, "wz", &f[3])?,
        ];
        if let Some(&prev) = t.last() {
            if tk <= prev {
                return Err(err(
                    path,
                    Some(n),
                    format!("time {tk} does not increase (previous sample {prev})"),
                ));
            }
        }
        t.push(tk);
        omega.push(w);
    }
    if t.len() < 2 {
        return Err(err(path, None, "fewer than two data rows"));
    }
    Ok((t, omega))
}

/// Reads a phyphox gyroscope export (`Raw Data.csv`, or its folder).
pub fn read_phyphox(path: &Path) -> Result<(Vec<f64>, Vec<[f64; 3]>), InputError> {
    let file = data_file(path);
    let lines = read_lines(&file)?;
    let Some(h) = lines.first() else {
        return Err(err(&file, None, "empty file"));
    };
    let f = fields(h);
    let ok = f.len() >= 4
        && f[0].starts_with("Time (s)")
        && f[1..4]
            .iter()
            .zip(["x", "y", "z"])
            .all(|(c, a)| c.contains(&format!(" {a} ")) && c.contains("rad/s"));
    if !ok {
        return Err(err(
            &file,
            Some(1),
            format!("not a phyphox gyroscope header: {}", quote(h)),
        ));
    }
    samples(&file, &lines)
}

/// Reads a plain CSV with header `t,wx,wy,wz`.
pub fn read_csv(path: &Path) -> Result<(Vec<f64>, Vec<[f64; 3]>), InputError> {
    let lines = read_lines(path)?;
    let Some(h) = lines.first() else {
        return Err(err(path, None, "empty file"));
    };
    let f = fields(h);
    if f.len() < 4 || f[..4] != ["t", "wx", "wy", "wz"] {
        return Err(err(
            path,
            Some(1),
            format!("header must be t,wx,wy,wz, found {}", quote(h)),
        ));
    }
    samples(path, &lines)
}

/// Reads a phyphox `segments.csv` (`segment,start,end,keep,comment`; leading spaces, quotes
/// and a missing final newline tolerated). Rows with `keep` false are dropped; the rest are
/// returned sorted by start.
pub fn read_segments(path: &Path) -> Result<Vec<Segment>, InputError> {
    let lines = read_lines(path)?;
    let Some(h) = lines.first() else {
        return Err(err(path, None, "empty file"));
    };
    let head = fields(h);
    let col = |name: &str| head.iter().position(|c| c.eq_ignore_ascii_case(name));
    let (Some(cs), Some(ce)) = (col("start"), col("end")) else {
        return Err(err(
            path,
            Some(1),
            format!("header needs start and end columns, found {}", quote(h)),
        ));
    };
    let (cl, ck) = (col("segment"), col("keep"));
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate().skip(1) {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f = fields(line);
        let get = |c: usize| f.get(c).map(String::as_str);
        let (Some(s), Some(e)) = (get(cs), get(ce)) else {
            return Err(err(path, Some(n), "truncated row: missing start or end"));
        };
        let start = number(path, n, "start", s)?;
        let end = number(path, n, "end", e)?;
        if end <= start {
            return Err(err(
                path,
                Some(n),
                format!("end {end} is not after start {start}"),
            ));
        }
        let keep = match ck.and_then(get).map(str::to_ascii_lowercase).as_deref() {
            None | Some("") | Some("true") | Some("1") | Some("yes") => true,
            Some("false") | Some("0") | Some("no") => false,
            Some(other) => {
                return Err(err(
                    path,
                    Some(n),
                    format!("keep must be true/false/empty, found {}", quote(other)),
                ))
            }
        };
        if keep {
            let label = cl
                .and_then(get)
                .map_or_else(|| format!("{}", out.len()), str::to_string);
            out.push(Segment { label, start, end });
        }
    }
    out.sort_by(|a, b| a.start.total_cmp(&b.start));
    Ok(out)
}

/// Reads a log in `format` (detected from the header when `None`), with the segments from
/// `segments`; without one, a phyphox export's `meta/segments.csv` is used if present, else
/// the whole log is one free flight.
pub fn read_log(
    input: &Path,
    format: Option<Format>,
    segments: Option<&Path>,
) -> Result<Log, InputError> {
    let format = match format {
        Some(f) => f,
        None => detect(input)?,
    };
    let (t, omega) = match format {
        Format::Phyphox => read_phyphox(input)?,
        Format::Csv => read_csv(input)?,
    };
    let seg_file = match segments {
        Some(p) => Some(p.to_path_buf()),
        None if format == Format::Phyphox => {
            let dir = if input.is_dir() {
                input.to_path_buf()
            } else {
                input.parent().map(Path::to_path_buf).unwrap_or_default()
            };
            let p = dir.join("meta").join("segments.csv");
            p.is_file().then_some(p)
        }
        None => None,
    };
    let segments = match seg_file {
        Some(p) => {
            let s = read_segments(&p)?;
            if s.is_empty() {
                return Err(err(&p, None, "no kept segment"));
            }
            s
        }
        None => vec![Segment {
            label: "all".into(),
            start: t[0],
            end: t[t.len() - 1],
        }],
    };
    Ok(Log {
        source: data_file(input),
        t,
        omega,
        segments,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str, bytes: &[u8]) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("log_input_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    #[test]
    fn plain_csv_reads_and_rejects_mess() {
        let p = tmp("ok.csv", b"t,wx,wy,wz\n0,1,2,3\n0.01,1,2,3");
        let log = read_log(&p, None, None).unwrap();
        assert_eq!(log.t.len(), 2);
        assert_eq!(log.segments.len(), 1);
        let cases: [(&str, &[u8], Option<usize>); 7] = [
            ("empty.csv", b"", None),
            ("nan.csv", b"t,wx,wy,wz\n0,1,2,3\n0.01,NaN,2,3\n", Some(3)),
            ("trunc.csv", b"t,wx,wy,wz\n0,1,2,3\n0.01,1,2", Some(3)),
            (
                "unsorted.csv",
                b"t,wx,wy,wz\n0,1,2,3\n0.02,1,2,3\n0.01,1,2,3\n",
                Some(4),
            ),
            ("utf.csv", b"t,wx,wy,wz\n0,1,2,3\n0.01,\xff,2,3\n", Some(3)),
            ("text.csv", b"t,wx,wy,wz\n0,1,2,3\n0.01,abc,2,3\n", Some(3)),
            ("header.csv", b"time,a,b,c\n0,1,2,3\n", Some(1)),
        ];
        for (name, bytes, line) in cases {
            let p = tmp(name, bytes);
            let e = read_log(&p, Some(Format::Csv), None).unwrap_err();
            assert_eq!(e.line, line, "{name}: {e}");
            assert!(e.to_string().contains(name), "{e}");
        }
    }

    #[test]
    fn phyphox_with_semicolons_and_decimal_commas() {
        let p = tmp(
            "semi.csv",
            "\"Time (s)\";\"Gyroscope x (rad/s)\";\"Gyroscope y (rad/s)\";\"Gyroscope z (rad/s)\"\n0,01;1,5;2;3\n0,02;1;2;3\n"
                .as_bytes(),
        );
        let (t, w) = read_phyphox(&p).unwrap();
        assert_eq!(t, vec![0.01, 0.02]);
        assert_eq!(w[0], [1.5, 2.0, 3.0]);
    }

    #[test]
    fn segments_with_spaces_no_newline_and_rejections() {
        let p = tmp(
            "seg.csv",
            b"segment,start,end,keep,comment\n1, 2.5,3.0,,x\n0, 1.0,1.5,false,no\n2, 0.5,0.9,,y",
        );
        let s = read_segments(&p).unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].label, "2");
        assert_eq!(s[1].start, 2.5);
        let p = tmp("segbad.csv", b"segment,start,end\n1,3.0,2.0\n");
        assert_eq!(read_segments(&p).unwrap_err().line, Some(2));
    }
}
