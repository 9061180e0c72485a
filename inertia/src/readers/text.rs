//! Text logs (CSV, phyphox) read line by line from the file, never whole.
//!
//! The lines are the ones the readers always saw: a BOM stripped from the file's start, a
//! trailing `\r` removed, the empty piece after a final newline left out. The readers used to
//! check the whole file for UTF-8 before parsing a line, so a line that is not UTF-8 is the
//! error even when an earlier line is malformed: once a line fails, the rest of the file is
//! still read, for UTF-8 only.

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

use super::check::Checker;
use super::{quote, Location, ReadError};
use crate::source::{Flow, Reading, Visit};

/// Read buffer: large enough that a line rarely straddles two reads.
const BUFFER: usize = 1 << 20;
/// Lines between two progress reports.
const PROGRESS_EVERY: usize = 1 << 16;

fn cannot_read(path: &Path, e: std::io::Error) -> ReadError {
    ReadError::new(path, format!("cannot read: {e}"))
}

/// Every line of `path` in order to `visit(number, line)` (1-based numbers), until it says
/// [`Flow::Stop`]. An error of `visit` stops the parsing; it is returned unless a later line
/// is not UTF-8 (then that line's error is, as when the whole file was checked first).
pub(crate) fn each_line(
    path: &Path,
    visit: &mut dyn FnMut(usize, &str) -> Result<Flow, ReadError>,
    progress: &mut dyn FnMut(f32),
) -> Result<(), ReadError> {
    let file = File::open(path).map_err(|e| cannot_read(path, e))?;
    let size = file.metadata().map(|m| m.len()).unwrap_or(0).max(1);
    let mut reader = BufReader::with_capacity(BUFFER, file);
    let mut buf: Vec<u8> = Vec::with_capacity(256);
    let mut number = 0usize;
    let mut consumed = 0u64;
    let mut failed: Option<ReadError> = None;
    loop {
        buf.clear();
        let got = reader
            .read_until(b'\n', &mut buf)
            .map_err(|e| cannot_read(path, e))?;
        if got == 0 {
            break;
        }
        consumed += got as u64;
        let last = buf.last() != Some(&b'\n');
        let mut piece: &[u8] = if last { &buf } else { &buf[..buf.len() - 1] };
        if number == 0 {
            piece = piece.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(piece);
        }
        number += 1;
        let line = std::str::from_utf8(piece).map_err(|e| {
            ReadError::at(
                path,
                Location::Line(number),
                format!("not valid UTF-8: {e}"),
            )
        })?;
        let line = line.trim_end_matches('\r');
        // The piece after the last newline, when empty, is no line.
        if last && line.is_empty() {
            break;
        }
        if failed.is_none() {
            match visit(number, line) {
                Ok(Flow::Continue) => {}
                Ok(Flow::Stop) => return Ok(()),
                Err(e) => failed = Some(e),
            }
        }
        if number.is_multiple_of(PROGRESS_EVERY) {
            progress(consumed as f32 / size as f32);
        }
    }
    failed.map_or(Ok(()), Err)
}

/// One data row of a text table: time, gyro, accelerometer and rotor speed (units
/// converted), `None` for a row to skip (blank).
pub(crate) type TableRow = (f64, [f64; 3], Option<[f64; 3]>, Option<f64>);

/// Parses one data row of a table: `(line number, line, scratch) -> row`.
pub(crate) type RowParser<'a> =
    dyn FnMut(usize, &str, &mut String) -> Result<Option<TableRow>, ReadError> + 'a;

/// The rows of a text table with a header line, each parsed by `row(number, line, scratch)`,
/// checked ([`Checker`]) and given to `visit` until it says [`Flow::Stop`]: the reading loop
/// of the CSV and phyphox readers.
pub(crate) fn read_table(
    path: &Path,
    visit: &mut Visit<'_>,
    progress: &mut dyn FnMut(f32),
    row: &mut RowParser<'_>,
) -> Result<Reading, ReadError> {
    let mut check = Checker::new(path);
    let mut scratch = String::new();
    let mut stopped = false;
    each_line(
        path,
        &mut |n, line| {
            if n == 1 {
                return Ok(Flow::Continue);
            }
            let Some((t, w, a, r)) = row(n, line, &mut scratch)? else {
                return Ok(Flow::Continue);
            };
            match check.check(Location::Line(n), t, w, a, r)? {
                Some(s) => {
                    let f = visit(&s)?;
                    stopped = f == Flow::Stop;
                    Ok(f)
                }
                None => Ok(Flow::Continue),
            }
        },
        progress,
    )?;
    check.reading(stopped)
}

/// The first line of `path` (`None` for a file with no line). Only that line is read: a
/// caller that finds it wrong gives [`utf8_first`] its error.
pub(crate) fn first_line(path: &Path) -> Result<Option<String>, ReadError> {
    let file = File::open(path).map_err(|e| cannot_read(path, e))?;
    let mut reader = BufReader::new(file);
    let mut buf = Vec::new();
    let got = reader
        .read_until(b'\n', &mut buf)
        .map_err(|e| cannot_read(path, e))?;
    let last = buf.last() != Some(&b'\n');
    let piece: &[u8] = if last { &buf } else { &buf[..buf.len() - 1] };
    let piece = piece.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(piece);
    let line = std::str::from_utf8(piece)
        .map_err(|e| ReadError::at(path, Location::Line(1), format!("not valid UTF-8: {e}")))?
        .trim_end_matches('\r');
    if got == 0 || (last && line.is_empty()) {
        return Ok(None);
    }
    Ok(Some(line.to_string()))
}

/// Returns `err`, or the error of the first line of `path` that is not UTF-8 if there is one
/// (what a reader that checked the whole file first reported).
pub(crate) fn utf8_first(path: &Path, err: ReadError) -> ReadError {
    match each_line(path, &mut |_, _| Ok(Flow::Continue), &mut |_| {}) {
        Err(e) => e,
        Ok(()) => err,
    }
}

/// The separator of a line and whether its numbers use decimal commas: `;` (then with decimal
/// commas), tab or `,`, taken from the line itself.
#[inline]
pub(crate) fn separator(line: &str) -> (char, bool) {
    if line.contains(';') {
        (';', true)
    } else if line.contains('\t') {
        ('\t', false)
    } else {
        (',', false)
    }
}

/// A field without surrounding spaces and quotes (as [`super::fields`] gives it, before the
/// decimal commas are replaced).
#[inline]
pub(crate) fn clean(f: &str) -> &str {
    // Most fields start and end with a printable ASCII character other than a quote: nothing
    // to trim (whitespace is at most U+0020 in ASCII, and non-ASCII takes the long way).
    let plain = |b: Option<&u8>| b.is_some_and(|&c| (b'!'..=b'~').contains(&c) && c != b'"');
    let b = f.as_bytes();
    if plain(b.first()) && plain(b.last()) {
        return f;
    }
    f.trim().trim_matches('"').trim()
}

/// A finite number from a field, decimal commas turned to points first when `decimal_comma`
/// (`scratch` holds that copy); the errors of [`super::number`].
#[inline]
pub(crate) fn number(
    path: &Path,
    line: usize,
    what: &str,
    field: &str,
    decimal_comma: bool,
    scratch: &mut String,
) -> Result<f64, ReadError> {
    let s = if decimal_comma && field.contains(',') {
        scratch.clear();
        scratch.extend(field.chars().map(|c| if c == ',' { '.' } else { c }));
        scratch.as_str()
    } else {
        field
    };
    match decimal(s).map_or_else(|| s.parse::<f64>(), Ok) {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(ReadError::at(
            path,
            Location::Line(line),
            format!("{what}: {} is not finite", quote(s)),
        )),
        Err(_) => Err(ReadError::at(
            path,
            Location::Line(line),
            format!("{what}: {} is not a number", quote(s)),
        )),
    }
}

/// `s` as `f64` when it is a plain decimal (`[+-]digits[.digits]`, at most 19 digits, the
/// digits below 2^53): the digits as an integer divided by a power of ten, both exact, so the
/// one rounding of the division gives the correctly rounded value, the one `str::parse` gives
/// (Clinger's fast path; about three times faster than `parse` on a log's numbers). `None`
/// for anything else, which `parse` then reads.
#[inline]
pub(crate) fn decimal(s: &str) -> Option<f64> {
    const POW10: [f64; 23] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
        1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
    ];
    let b = s.as_bytes();
    let (neg, b) = match b.first() {
        Some(b'-') => (true, &b[1..]),
        Some(b'+') => (false, &b[1..]),
        _ => (false, b),
    };
    let mut m: u64 = 0;
    let mut digits = 0usize;
    let mut frac: Option<usize> = None;
    for &c in b {
        match c {
            b'0'..=b'9' => {
                m = m * 10 + u64::from(c - b'0');
                digits += 1;
                if digits > 19 {
                    return None;
                }
                if let Some(f) = &mut frac {
                    *f += 1;
                }
            }
            b'.' if frac.is_none() => frac = Some(0),
            _ => return None,
        }
    }
    let int_digits = digits - frac.unwrap_or(0);
    if int_digits == 0 || m >= 1 << 53 {
        return None;
    }
    let v = m as f64 / *POW10.get(frac.unwrap_or(0))?;
    Some(if neg { -v } else { v })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_not_utf8_wins_over_an_earlier_bad_line() {
        let dir = std::env::temp_dir().join(format!("inertia_text_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("utf8_late.csv");
        std::fs::write(&p, b"t,wx,wy,wz\n0,1,2,3\n0.01,abc,2,3\n0.02,\xff,2,3\n").unwrap();
        let e = crate::read(&p, &Default::default()).unwrap_err();
        assert_eq!(e.line(), Some(4), "{e}");
        assert!(e.message.contains("UTF-8"), "{e}");
        // Without it, the bad number is the error.
        std::fs::write(&p, b"t,wx,wy,wz\n0,1,2,3\n0.01,abc,2,3\n0.02,1,2,3").unwrap();
        assert_eq!(
            crate::read(&p, &Default::default()).unwrap_err().line(),
            Some(3)
        );
    }

    #[test]
    fn decimal_is_parse_bit_for_bit() {
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let fixed = [
            "0",
            "-0",
            "+0",
            "0.",
            "-0.0",
            "1",
            "1.5",
            "-1.25",
            "0.1",
            "0.2",
            "0.3",
            "0.0010652645",
            "-0.004261058",
            "9.80665",
            "174.53293",
            "9007199254740991",
            "9007199254740992",
            "123456789.0123456789",
            "1e5",
            ".5",
            "-.5",
            "1.2.3",
            "",
            "-",
            "+",
            "1,5",
            "inf",
            "NaN",
            " 1",
            "0x10",
            "00000000000000000001.5",
        ];
        for s in fixed {
            let want = s.parse::<f64>().ok();
            let got = decimal(s);
            if let Some(g) = got {
                assert_eq!(Some(g.to_bits()), want.map(f64::to_bits), "{s:?}");
            }
        }
        for _ in 0..200_000 {
            let int = next() % 10u64.pow((next() % 8) as u32 + 1);
            let fd = (next() % 13) as usize;
            let fv = next() % 10u64.pow(fd as u32);
            let sign = if next() % 2 == 0 { "-" } else { "" };
            let s = if fd == 0 {
                format!("{sign}{int}")
            } else {
                format!("{sign}{int}.{fv:0fd$}")
            };
            let want = s.parse::<f64>().unwrap();
            let got = decimal(&s).unwrap_or(want);
            assert_eq!(got.to_bits(), want.to_bits(), "{s}");
        }
    }
}
