//! phyphox exports: `Raw Data.csv` (`"Time (s)","Gyroscope x (rad/s)",...`) in a folder that
//! may also hold `meta/segments.csv` (hand-marked free-flight windows).
//!
//! Moved here from `host-tests`' former `log_input` (same tolerance of real exports: quoted
//! headers, `;` separators with decimal commas, a BOM, `\r\n`, leading spaces, no final
//! newline).

use std::path::{Path, PathBuf};

use super::{
    collect, data_file, fields, number, quote, read_lines, text, Extra, Location, ReadError,
};
use crate::readers::Recording;
use crate::readers::{Channels, Reading, Source, Visit};

/// Reads a phyphox gyroscope export (`Raw Data.csv`, or its folder): time in seconds, rates
/// in rad/s, the phone's axes.
pub fn read_phyphox(path: &Path) -> Result<Recording, ReadError> {
    collect(&PhyphoxSource::open(path)?)
}

/// A phyphox export read row by row (see [`crate::source`]).
pub struct PhyphoxSource {
    file: PathBuf,
}

impl PhyphoxSource {
    /// Checks the header (the rows are read by each [`Source::read_all`]).
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        let file = data_file(path);
        let Some(h) = text::first_line(&file)? else {
            return Err(ReadError::new(&file, "empty file"));
        };
        let f = fields(&h);
        let ok = f.len() >= 4
            && f[0].starts_with("Time (s)")
            && f[1..4]
                .iter()
                .zip(["x", "y", "z"])
                .all(|(c, a)| c.contains(&format!(" {a} ")) && c.contains("rad/s"));
        if !ok {
            let e = ReadError::at(
                &file,
                Location::Line(1),
                format!("not a phyphox gyroscope header: {}", quote(&h)),
            );
            return Err(text::utf8_first(&file, e));
        }
        Ok(PhyphoxSource { file })
    }

    /// One data row: `Ok(None)` for a blank line.
    fn row(
        &self,
        n: usize,
        line: &str,
        scratch: &mut String,
    ) -> Result<Option<(f64, [f64; 3])>, ReadError> {
        let file = self.file.as_path();
        if line.trim().is_empty() {
            return Ok(None);
        }
        let (sep, dc) = text::separator(line);
        let mut f = [""; 4];
        let mut count = 0;
        for (i, x) in line.split(sep).enumerate() {
            count = i + 1;
            if let Some(o) = f.get_mut(i) {
                *o = text::clean(x);
            }
        }
        if count < 4 {
            return Err(ReadError::at(
                file,
                Location::Line(n),
                format!("truncated row: {count} field(s), need 4 (t, wx, wy, wz)"),
            ));
        }
        let t = text::number(file, n, "time", f[0], dc, scratch)?;
        let w = [
            text::number(file, n, "wx", f[1], dc, scratch)?,
            text::number(file, n, "wy", f[2], dc, scratch)?,
            text::number(file, n, "wz", f[3], dc, scratch)?,
        ];
        Ok(Some((t, w)))
    }
}

impl Source for PhyphoxSource {
    fn name(&self) -> String {
        format!("{} (phyphox)", self.file.display())
    }

    fn channels(&self) -> Channels {
        Channels::default()
    }

    fn full_scale(&self) -> f32 {
        f32::INFINITY
    }

    fn read_all(
        &self,
        visit: &mut Visit<'_>,
        progress: &mut dyn FnMut(f32),
    ) -> Result<Reading, ReadError> {
        text::read_table(&self.file, visit, progress, &|n, line, scratch| {
            Ok(self
                .row(n, line, scratch)?
                .map(|(t, w)| (t, w, None, None, Extra::default())))
        })
    }

    fn warnings(&self, found: Vec<String>) -> Vec<String> {
        found
    }
}

/// A free-flight window `[start, end]` in the log's time base, seconds.
#[derive(Clone, Debug, PartialEq)]
pub struct Segment {
    /// Label (the `segment` column, or its rank).
    pub label: String,
    /// Start time, seconds.
    pub start: f64,
    /// End time, seconds.
    pub end: f64,
}

/// The `meta/segments.csv` beside a phyphox export (`path` is the folder or its
/// `Raw Data.csv`), if there is one.
pub fn segments_file(path: &Path) -> Option<PathBuf> {
    let dir = if path.is_dir() {
        path.to_path_buf()
    } else {
        path.parent().map(Path::to_path_buf).unwrap_or_default()
    };
    let p = dir.join("meta").join("segments.csv");
    p.is_file().then_some(p)
}

/// Reads a segments file (`segment,start,end,keep,comment`, as phyphox writes it; leading
/// spaces, quotes, `;` with decimal commas and a missing final newline tolerated). Rows whose
/// `keep` is false are skipped before their times are read (a rejected row may leave them
/// empty); an empty `keep` means true. Returned sorted by start.
pub fn read_segments(path: &Path) -> Result<Vec<Segment>, ReadError> {
    let lines = read_lines(path)?;
    let Some(h) = lines.first() else {
        return Err(ReadError::new(path, "empty file"));
    };
    let head = fields(h);
    let col = |name: &str| head.iter().position(|c| c.eq_ignore_ascii_case(name));
    let (Some(cs), Some(ce)) = (col("start"), col("end")) else {
        return Err(ReadError::at(
            path,
            Location::Line(1),
            format!("header needs start and end columns, found {}", quote(h)),
        ));
    };
    let (cl, ck) = (col("segment"), col("keep"));
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate().skip(1) {
        let n = i + 1;
        let at = Location::Line(n);
        if line.trim().is_empty() {
            continue;
        }
        let f = fields(line);
        let get = |c: usize| f.get(c).map(String::as_str);
        let keep = match ck.and_then(get).map(str::to_ascii_lowercase).as_deref() {
            None | Some("") | Some("true") | Some("1") | Some("yes") => true,
            Some("false") | Some("0") | Some("no") => false,
            Some(other) => {
                return Err(ReadError::at(
                    path,
                    at,
                    format!("keep must be true/false/empty, found {}", quote(other)),
                ))
            }
        };
        if !keep {
            continue;
        }
        let (Some(s), Some(e)) = (get(cs), get(ce)) else {
            return Err(ReadError::at(
                path,
                at,
                "truncated row: missing start or end",
            ));
        };
        let start = number(path, n, "start", s)?;
        let end = number(path, n, "end", e)?;
        if end <= start {
            return Err(ReadError::at(
                path,
                at,
                format!("end {end} is not after start {start}"),
            ));
        }
        let label = cl
            .and_then(get)
            .filter(|l| !l.is_empty())
            .map_or_else(|| format!("{}", out.len()), str::to_string);
        out.push(Segment { label, start, end });
    }
    out.sort_by(|a, b| a.start.total_cmp(&b.start));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str, bytes: &[u8]) -> PathBuf {
        crate::readers::test_file("phyphox", name, bytes)
    }

    #[test]
    fn semicolons_and_decimal_commas() {
        let p = tmp(
            "semi.csv",
            "\u{feff}\"Time (s)\";\"Gyroscope x (rad/s)\";\"Gyroscope y (rad/s)\";\"Gyroscope z (rad/s)\"\r\n0,01;1,5;2;3\r\n0,02;1;2;3\r\n"
                .as_bytes(),
        );
        let r = read_phyphox(&p).unwrap();
        assert_eq!(r.t, vec![0.01, 0.02]);
        assert_eq!(r.gyro[0], [1.5, 2.0, 3.0]);
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
        // phyphox's rejected rows may leave the times empty: skipped before they are read.
        let p = tmp(
            "segrej.csv",
            b"segment,start,end,keep,comment\n28,,,false,noise\n1,1.0,2.0,,\n",
        );
        assert_eq!(read_segments(&p).unwrap().len(), 1);
        let p = tmp("segbad.csv", b"segment,start,end\n1,3.0,2.0\n");
        assert_eq!(read_segments(&p).unwrap_err().line(), Some(2));
    }
}
