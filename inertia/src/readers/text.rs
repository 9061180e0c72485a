//! Text logs (CSV, phyphox) read line by line from the file, never whole: a table's rows in
//! blocks of whole lines parsed on threads beside the reading and visited in order
//! ([`read_table`]).
//!
//! The lines: a BOM stripped from the file's start, a trailing `\r` removed, the empty piece
//! after a final newline left out. A file that is not UTF-8 is refused for that first, so a
//! line that is not UTF-8 is the error even when an earlier line is malformed: once a line
//! fails, the rest of the file is still read, for UTF-8 only.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::sync::mpsc::sync_channel;

use super::check::Checker;
use super::{quote, Location, ReadError};
use crate::readers::{Extra, Flow, Reading, Visit};

/// Read buffer: large enough that a line rarely straddles two reads.
const BUFFER: usize = 1 << 20;
/// Lines between two progress reports.
const PROGRESS_EVERY: usize = 1 << 16;

fn cannot_read(path: &Path, e: std::io::Error) -> ReadError {
    ReadError::new(path, format!("cannot read: {e}"))
}

/// Every line of `path` in order to `visit(number, line)` (1-based numbers), until it says
/// [`Flow::Stop`]. An error of `visit` stops the parsing; it is returned unless a later line
/// is not UTF-8 (then that line's error is, as if the whole file were checked first).
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

/// One data row of a text table: time, gyro, accelerometer, rotor speed (units converted)
/// and the vehicle's and a spacecraft's columns, `None` for a row to skip (blank).
pub(crate) type TableRow = (f64, [f64; 3], Option<[f64; 3]>, Option<f64>, Extra);

/// Parses one data row of a table: `(line number, line, scratch) -> row`. It runs on the
/// parsing threads ([`read_table`]), so it only reads its source.
pub(crate) type RowParser<'a> =
    dyn Fn(usize, &str, &mut String) -> Result<Option<TableRow>, ReadError> + Sync + 'a;

/// Bytes of whole lines handed to a parsing thread at a time.
const BLOCK: usize = 1 << 18;
/// Blocks waiting per parsing thread, each way.
const BLOCK_QUEUE: usize = 2;
/// Parsing threads at most.
const PARSERS: usize = 4;

/// Whole lines of the file (the last block may end without a newline).
struct Block {
    bytes: Vec<u8>,
    /// Number of its first line (1-based).
    first_line: usize,
    /// File bytes up to its end.
    consumed: u64,
}

/// A block's rows, parsed on a parsing thread.
#[derive(Default)]
struct Parsed {
    /// Line numbers and rows, in order, up to the first row that failed.
    rows: Vec<(usize, TableRow)>,
    /// The error of the first row that failed (the rows above end before it).
    failed: Option<ReadError>,
    /// The first line that is not UTF-8, or a read error: ends the reading.
    fatal: Option<ReadError>,
    /// File bytes up to the block's end.
    consumed: u64,
}

/// Reads `path` into blocks of whole lines for the parsing threads, in turn.
fn split_blocks(path: &Path, to: &[std::sync::mpsc::SyncSender<Result<Block, ReadError>>]) {
    let mut file = match File::open(path) {
        Ok(f) => f,
        Err(e) => {
            if let Some(tx) = to.first() {
                let _ = tx.send(Err(cannot_read(path, e)));
            }
            return;
        }
    };
    let mut carry: Vec<u8> = Vec::new();
    let mut first_line = 1usize;
    let mut consumed = 0u64;
    let mut eof = false;
    for k in 0.. {
        let Some(tx) = to.get(k % to.len().max(1)) else {
            return;
        };
        let mut bytes = std::mem::take(&mut carry);
        // Fill to at least a block holding a newline (or to the end of the file).
        let mut scanned = 0;
        let mut newline = None;
        while !eof && (bytes.len() < BLOCK || newline.is_none()) {
            let at = bytes.len();
            bytes.resize(at + BLOCK, 0);
            match file.read(&mut bytes[at..]) {
                Ok(0) => {
                    bytes.truncate(at);
                    eof = true;
                }
                Ok(got) => bytes.truncate(at + got),
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => bytes.truncate(at),
                Err(e) => {
                    let _ = tx.send(Err(cannot_read(path, e)));
                    return;
                }
            }
            if let Some(i) = bytes[scanned..].iter().rposition(|&b| b == b'\n') {
                newline = Some(scanned + i);
            }
            scanned = bytes.len();
        }
        // The partial line after the last newline waits for the next block.
        if let (false, Some(i)) = (eof, newline) {
            carry = bytes.split_off(i + 1);
        }
        if bytes.is_empty() {
            return;
        }
        consumed += bytes.len() as u64;
        let lines = newlines(&bytes);
        let last = eof && carry.is_empty();
        let block = Block {
            bytes,
            first_line,
            consumed,
        };
        first_line += lines;
        // A parsing thread gone means the reading stopped.
        if tx.send(Ok(block)).is_err() || last {
            return;
        }
    }
}

/// The newlines in `bytes`, counted in byte-wide lanes (a count per chunk of at most 255 fits
/// a byte, which the compiler turns into wide vector compares).
fn newlines(bytes: &[u8]) -> usize {
    bytes
        .chunks(255)
        .map(|c| {
            let n = c
                .iter()
                .fold(0u8, |n, &b| n.wrapping_add(u8::from(b == b'\n')));
            usize::from(n)
        })
        .sum()
}

/// Parses a block's lines: the lines [`each_line`] gives (a BOM stripped from the file's
/// start, a trailing `\r` removed, the empty piece after a final newline left out), the first
/// (the header) skipped.
fn parse_block(path: &Path, block: &Block, row: &RowParser<'_>, scratch: &mut String) -> Parsed {
    let mut out = Parsed {
        consumed: block.consumed,
        ..Parsed::default()
    };
    match std::str::from_utf8(&block.bytes) {
        // A block of UTF-8 cut at newlines is UTF-8 line by line: checked once.
        Ok(text) => parse_lines(
            path,
            block.first_line,
            text.split('\n').map(Ok),
            true,
            row,
            scratch,
            &mut out,
        ),
        Err(_) => parse_lines(
            path,
            block.first_line,
            block.bytes.split(|&b| b == b'\n').map(std::str::from_utf8),
            false,
            row,
            scratch,
            &mut out,
        ),
    }
    out
}

/// [`parse_block`]'s loop over the block's pieces (`all_utf8`: every piece is known to be).
fn parse_lines<'b>(
    path: &Path,
    first_line: usize,
    pieces: impl Iterator<Item = Result<&'b str, std::str::Utf8Error>>,
    all_utf8: bool,
    row: &RowParser<'_>,
    scratch: &mut String,
    out: &mut Parsed,
) {
    let mut pieces = pieces.peekable();
    let mut number = first_line;
    while let Some(piece) = pieces.next() {
        let n = number;
        number += 1;
        let line = match piece {
            Ok(l) => l,
            Err(e) => {
                let e = format!("not valid UTF-8: {e}");
                out.fatal = Some(ReadError::at(path, Location::Line(n), e));
                return;
            }
        };
        let line = line.trim_end_matches('\r');
        if pieces.peek().is_none() && line.is_empty() {
            return;
        }
        if out.failed.is_some() {
            // Only UTF-8 is left to check.
            if all_utf8 {
                return;
            }
            continue;
        }
        if n == 1 {
            // The header (its BOM, if any, is valid UTF-8).
            continue;
        }
        match row(n, line, scratch) {
            Ok(Some(r)) => out.rows.push((n, r)),
            Ok(None) => {}
            Err(e) => out.failed = Some(e),
        }
    }
}

/// The rows of a text table with a header line, each parsed by `row(number, line, scratch)`,
/// checked ([`Checker`]) and given to `visit` until it says [`Flow::Stop`]: the reading loop
/// of the CSV and phyphox readers.
///
/// Why threads: parsing the text is most of the time `identify` spends on a long log. Blocks
/// of whole lines go in turn to up to [`PARSERS`] threads and come back in the same turn, so
/// `visit` sees every row in the file's order, and the outcome is the one of reading line by
/// line ([`each_line`]): an error of a row or of `visit` stops the visits and is returned
/// unless a later line is not UTF-8.
pub(crate) fn read_table(
    path: &Path,
    visit: &mut Visit<'_>,
    progress: &mut dyn FnMut(f32),
    row: &RowParser<'_>,
) -> Result<Reading, ReadError> {
    let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0).max(1);
    let parsers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .clamp(1, PARSERS);
    let mut check = Checker::new(path);
    let mut stopped = false;
    let mut failed: Option<ReadError> = None;
    std::thread::scope(|scope| -> Result<(), ReadError> {
        let mut jobs = Vec::with_capacity(parsers);
        let mut results = Vec::with_capacity(parsers);
        for _ in 0..parsers {
            let (job_tx, job_rx) = sync_channel::<Result<Block, ReadError>>(BLOCK_QUEUE);
            let (res_tx, res_rx) = sync_channel::<Parsed>(BLOCK_QUEUE);
            jobs.push(job_tx);
            results.push(res_rx);
            scope.spawn(move || {
                let mut scratch = String::new();
                for job in job_rx {
                    let parsed = match job {
                        Ok(block) => parse_block(path, &block, row, &mut scratch),
                        Err(e) => Parsed {
                            fatal: Some(e),
                            ..Parsed::default()
                        },
                    };
                    if res_tx.send(parsed).is_err() {
                        return;
                    }
                }
            });
        }
        scope.spawn(move || split_blocks(path, &jobs));
        // The blocks come back in the turn they were handed out; a closed channel is the end.
        for k in 0.. {
            let Some(Ok(parsed)) = results.get(k % parsers).map(|r| r.recv()) else {
                return Ok(());
            };
            // The rows end where a row failed: visited in order, then that row's error.
            if failed.is_none() {
                for (n, (t, w, a, r, extra)) in parsed.rows {
                    let visited = check
                        .check_with(Location::Line(n), t, w, a, r, extra)
                        .and_then(|s| s.map_or(Ok(Flow::Continue), |s| visit(&s)));
                    match visited {
                        Ok(Flow::Continue) => {}
                        Ok(Flow::Stop) => {
                            stopped = true;
                            return Ok(());
                        }
                        Err(e) => {
                            failed = Some(e);
                            break;
                        }
                    }
                }
            }
            if failed.is_none() {
                failed = parsed.failed;
            }
            if let Some(e) = parsed.fatal {
                return Err(e);
            }
            progress(parsed.consumed as f32 / size as f32);
        }
        Ok(())
    })?;
    // Dropping the receivers above ends the threads; what they were reading no longer counts.
    if let Some(e) = failed {
        return Err(e);
    }
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
    decimal_prefix(s.as_bytes())
        .filter(|&(_, len)| len == s.len())
        .map(|(v, _)| v)
}

/// [`decimal`] of the bytes up to the first `,` (or the end) and their length: the fields of a
/// CSV row read in the pass that finds them. `None` when they are not a plain decimal.
#[inline]
pub(crate) fn decimal_prefix(b: &[u8]) -> Option<(f64, usize)> {
    const POW10: [f64; 23] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
        1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
    ];
    let (neg, mut len) = match b.first() {
        Some(b'-') => (true, 1),
        Some(b'+') => (false, 1),
        _ => (false, 0),
    };
    let mut m: u64 = 0;
    let mut digits = 0usize;
    let mut frac: Option<usize> = None;
    while let Some(&c) = b.get(len) {
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
            b',' => break,
            _ => return None,
        }
        len += 1;
    }
    let int_digits = digits - frac.unwrap_or(0);
    if int_digits == 0 || m >= 1 << 53 {
        return None;
    }
    let v = m as f64 / *POW10.get(frac.unwrap_or(0))?;
    Some((if neg { -v } else { v }, len))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_not_utf8_wins_over_an_earlier_bad_line() {
        let p = write(
            "utf8_late.csv",
            b"t,wx,wy,wz\n0,1,2,3\n0.01,abc,2,3\n0.02,\xff,2,3\n",
        );
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

    fn write(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        crate::readers::test_file("text", name, bytes)
    }

    /// A table of several blocks (and a line longer than a block) read in parallel gives every
    /// row, in order, with the line endings, blank lines and missing final newline a reading
    /// line by line handles.
    #[test]
    fn blocks_give_the_rows_of_a_line_by_line_reading() {
        let mut text = String::from("\u{FEFF}t,wx,wy,wz\r\n");
        let mut want = Vec::new();
        let rows = 3 * BLOCK / 40;
        for i in 0..rows {
            let t = i as f64 * 1e-3;
            let w = [(i % 97) as f64 * 0.01, -(i as f64) * 1e-4, 0.5];
            text.push_str(&format!("{t:.4},{},{},{}", w[0], w[1], w[2]));
            if i == rows / 2 {
                // A line longer than a block (trailing spaces are trimmed from the field).
                text.push_str(&" ".repeat(BLOCK + 17));
            }
            text.push_str(if i % 3 == 0 { "\r\n" } else { "\n" });
            if i % 1000 == 7 {
                text.push('\n');
            }
            want.push((t, w));
        }
        text.pop();
        let rec = crate::read(&write("blocks.csv", text.as_bytes()), &Default::default()).unwrap();
        assert_eq!(rec.len(), want.len());
        for (k, (t, w)) in want.iter().enumerate() {
            assert_eq!(
                rec.t[k],
                format!("{t:.4}").parse::<f64>().unwrap(),
                "row {k}"
            );
            assert_eq!(rec.gyro[k], w.map(|x| x as f32), "row {k}");
        }
    }

    /// Across blocks too, a line that is not UTF-8 is the error, also after a bad row in an
    /// earlier block; without it, the bad row is, with its line number.
    #[test]
    fn errors_across_blocks_keep_the_line_by_line_outcome() {
        let mut text = b"t,wx,wy,wz\n".to_vec();
        let rows = 2 * BLOCK / 20;
        for i in 0..rows {
            let row = if i == 10 {
                "0.5,abc,2,3\n".to_string()
            } else {
                format!("{},1,2,3\n", i as f64 * 1e-3)
            };
            text.extend_from_slice(row.as_bytes());
        }
        let bad_row = 12;
        let e = crate::read(&write("late_ok.csv", &text), &Default::default()).unwrap_err();
        assert_eq!(e.line(), Some(bad_row), "{e}");
        text.extend_from_slice(b"9,\xff,2,3\n");
        let e = crate::read(&write("late_utf8.csv", &text), &Default::default()).unwrap_err();
        assert_eq!(e.line(), Some(rows + 2), "{e}");
        assert!(e.message.contains("UTF-8"), "{e}");
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
