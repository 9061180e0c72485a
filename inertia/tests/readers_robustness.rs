//! Reliability of the text log readers (`inertia::readers`: named-column CSV, phyphox,
//! segments; and `inertia::close_loop::load`, which reads a log with its segments) under bad
//! files. Malformed, truncated, empty, non-UTF-8, huge and unsorted-time files must give an
//! error that names the file and, where one line is to blame, that line; nothing may panic.
//! Hand-written cases, then property tests over mutated and random files. The close-loop
//! command on bad files is tested with the host tool (`close_loop_cli.rs`); the binary formats
//! on truncated and garbage input in `readers.rs`.
//!
//! Ported from `host-tests`' tests of its old readers (`log_input`, since removed). Where the
//! inertia readers behave differently, and soundly, the expectation says so in a comment.

use std::path::{Path, PathBuf};

use inertia::close_loop;
use inertia::readers::csv::read_csv;
use inertia::readers::phyphox::{read_phyphox, read_segments};
use inertia::readers::{detect, Format, ReadError, ReadOptions};
use proptest::prelude::*;
use proptest::test_runner::Config;

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("inertia_readers_robustness_{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Removes one test's files (best effort; the folder is per process).
fn cleanup(sub: &str) {
    let _ = std::fs::remove_dir_all(dir().join(sub));
}

fn write(name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir().join(name);
    if let Some(parent) = p.parent() {
        std::fs::create_dir_all(parent).unwrap();
    }
    std::fs::write(&p, bytes).unwrap();
    p
}

/// The default units (seconds, rad/s), as the old readers had them.
fn opts() -> ReadOptions {
    ReadOptions::default()
}

const PHYPHOX_HEADER: &str =
    "\"Time (s)\",\"Gyroscope x (rad/s)\",\"Gyroscope y (rad/s)\",\"Gyroscope z (rad/s)\"\n";
const CSV_HEADER: &str = "t,wx,wy,wz\n";

/// A valid CSV body of `n` rows at 100 Hz.
fn csv_rows(n: usize) -> String {
    (0..n)
        .map(|k| {
            let t = k as f64 * 0.01;
            format!("{t},{},{},{}\n", 1.0 + t.sin(), 0.5 * t.cos(), -0.3)
        })
        .collect()
}

struct Bad {
    name: &'static str,
    bytes: Vec<u8>,
    /// The line the error must name (`None`: the whole file is to blame).
    line: Option<usize>,
}

fn bad(name: &'static str, bytes: impl Into<Vec<u8>>, line: Option<usize>) -> Bad {
    Bad {
        name,
        bytes: bytes.into(),
        line,
    }
}

/// Malformed files for a reader whose header is `header`.
fn malformed(header: &str) -> Vec<Bad> {
    let h = header;
    let ok2 = format!("{h}0,1,2,3\n0.01,1,2,3\n");
    let mut non_utf8 = format!("{h}0,1,2,3\n").into_bytes();
    non_utf8.extend_from_slice(b"0.01,1,\xC3\x28,3\n");
    let mut latin1 = format!("{h}0,1,2,3\n0.01,1,2,3\n").into_bytes();
    latin1.extend_from_slice(b"0.02,1,2,3 \xB0\n");
    let mut huge_field = format!("{h}0,1,2,3\n0.01,").into_bytes();
    huge_field.extend(std::iter::repeat_n(b'9', 5_000_000));
    huge_field.extend_from_slice(b",2,3\n");
    let long_ok: String = format!("{h}{}", csv_rows(200_000));
    let mut long_then_bad = long_ok.clone().into_bytes();
    long_then_bad.extend_from_slice(b"2000,1,2\n");
    vec![
        bad("empty", "", None),
        bad("only_newlines", "\n\n\n", Some(1)),
        bad("header_only", h, None),
        bad("one_row", format!("{h}0,1,2,3\n"), None),
        bad(
            "truncated_mid_row",
            &ok2.as_bytes()[..ok2.len() - 4],
            Some(3),
        ),
        bad(
            "short_row",
            format!("{h}0,1,2,3\n0.01,1,2\n0.02,1,2,3\n"),
            Some(3),
        ),
        bad("empty_fields", format!("{h}0,1,2,3\n0.01,,,\n"), Some(3)),
        bad("text_field", format!("{h}0,1,2,3\n0.01,x,2,3\n"), Some(3)),
        bad("nan_field", format!("{h}0,1,2,3\n0.01,1,NaN,3\n"), Some(3)),
        bad("inf_field", format!("{h}0,1,2,3\n0.01,1,2,inf\n"), Some(3)),
        bad(
            "overflow_field",
            format!("{h}0,1,2,3\n0.01,1e999,2,3\n"),
            Some(3),
        ),
        // Finite as f64 but beyond f32, the type the recording holds.
        bad(
            "beyond_f32_field",
            format!("{h}0,1,2,3\n0.01,1e39,2,3\n"),
            Some(3),
        ),
        bad("huge_field", huge_field, Some(3)),
        bad("non_utf8", non_utf8, Some(3)),
        bad("latin1_degree", latin1, Some(4)),
        bad(
            "unsorted_time",
            format!("{h}0,1,2,3\n0.02,1,2,3\n0.01,1,2,3\n"),
            Some(4),
        ),
        // Adapted: the old readers refused a repeated timestamp at its line (4 in
        // `{h}0\n0.01\n0.01`). The inertia readers drop an exact duplicate with a warning
        // (documented in `inertia::readers`; loggers do write them), which
        // `repeated_time_is_dropped_with_a_warning` checks; a file left with fewer than two
        // samples once its duplicates are dropped is still refused, as a whole.
        bad(
            "repeated_time_only",
            format!("{h}0,1,2,3\n0,1,2,3\n0,1,2,3\n"),
            None,
        ),
        bad("nan_time", format!("{h}0,1,2,3\nnan,1,2,3\n"), Some(3)),
        bad(
            "negative_then_back",
            format!("{h}-1,1,2,3\n5,1,2,3\n-2,1,2,3\n"),
            Some(4),
        ),
        bad("long_then_truncated", long_then_bad, Some(200_002)),
        bad(
            // Bytes 0..=9 make a valid (if odd) first line; 0x80 on line 2 is not UTF-8.
            "binary",
            (0u8..=255).cycle().take(10_000).collect::<Vec<u8>>(),
            Some(2),
        ),
        bad("nul_bytes", vec![0u8; 1000], Some(1)),
    ]
}

/// The line an error message names as `<file>:<line>:`, if any.
fn line_in(msg: &str, file: &str) -> Option<usize> {
    let at = msg.find(&format!("{file}:"))? + file.len() + 1;
    let rest = &msg[at..];
    let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
    if digits == 0 || !rest[digits..].starts_with(':') {
        return None;
    }
    rest[..digits].parse().ok()
}

/// The message names the file (and `line` as `<file>:<line>:`, or no line) and is short.
fn check_message(reader: &str, name: &str, path: &Path, msg: &str, line: Option<usize>) {
    let file = path.file_name().unwrap().to_string_lossy().to_string();
    assert!(
        msg.contains(&file),
        "{reader} {name}: error does not name the file: {msg}"
    );
    assert_eq!(
        line_in(msg, &file),
        line,
        "{reader} {name}: wrong line in {msg}"
    );
    assert!(
        msg.len() < 1000,
        "{reader} {name}: message of {} bytes",
        msg.len()
    );
}

/// A reader's error: the file it names is `path`, its line is `line`, and so is the message's.
fn check(reader: &str, name: &str, path: &Path, got: Result<(), ReadError>, line: Option<usize>) {
    let e = got.expect_err(&format!("{reader} {name}: accepted a malformed file"));
    let msg = e.to_string();
    assert_eq!(e.file, path, "{reader} {name}: wrong file in {msg}");
    assert_eq!(e.line(), line, "{reader} {name}: wrong line in {msg}");
    check_message(reader, name, path, &msg, line);
}

/// `close_loop::load`'s error (a message): names `path` and `line`.
fn check_load(reader: &str, name: &str, path: &Path, got: Result<(), String>, line: Option<usize>) {
    let msg = got.expect_err(&format!("{reader} {name}: accepted a malformed file"));
    check_message(reader, name, path, &msg, line);
}

fn load(
    input: &Path,
    format: Option<Format>,
    segments: Option<&Path>,
) -> Result<close_loop::input::Log, String> {
    close_loop::load(input, format, segments, &opts()).map(|(log, _)| log)
}

#[test]
fn csv_reader_names_file_and_line_for_every_malformed_file() {
    for b in malformed(CSV_HEADER) {
        let p = write(&format!("csv/{}.csv", b.name), &b.bytes);
        check(
            "read_csv",
            b.name,
            &p,
            read_csv(&p, &opts()).map(|_| ()),
            b.line,
        );
        check_load(
            "load(csv)",
            b.name,
            &p,
            load(&p, Some(Format::Csv), None).map(|_| ()),
            b.line,
        );
        // With the format detected from the content (new with the inertia readers, which also
        // know binary formats): a first line holding NUL bytes is refused there as binary
        // content, at line 1, before the CSV reader would find line 2 not UTF-8.
        let detected = match b.name {
            "binary" => Some(1),
            _ => b.line,
        };
        check(
            "read",
            b.name,
            &p,
            inertia::read(&p, &opts()).map(|_| ()),
            detected,
        );
        check_load(
            "load(detect)",
            b.name,
            &p,
            load(&p, None, None).map(|_| ()),
            detected,
        );
        if b.bytes.is_empty() {
            check("detect", b.name, &p, detect(&p).map(|_| ()), None);
        }
    }
    cleanup("csv");
}

#[test]
fn phyphox_reader_names_file_and_line_for_every_malformed_file() {
    for b in malformed(PHYPHOX_HEADER) {
        let p = write(&format!("phyphox/{}/Raw Data.csv", b.name), &b.bytes);
        check(
            "read_phyphox",
            b.name,
            &p,
            read_phyphox(&p).map(|_| ()),
            b.line,
        );
        // Given as its folder, the error still names the data file.
        let folder = p.parent().unwrap().to_path_buf();
        check(
            "read_phyphox(dir)",
            b.name,
            &p,
            read_phyphox(&folder).map(|_| ()),
            b.line,
        );
        check(
            "read(dir)",
            b.name,
            &p,
            inertia::read(&folder, &opts()).map(|_| ()),
            b.line,
        );
        check_load(
            "load(detect)",
            b.name,
            &p,
            load(&folder, None, None).map(|_| ()),
            b.line,
        );
    }
    cleanup("phyphox");
}

#[test]
fn repeated_time_is_dropped_with_a_warning() {
    // The old readers refused this file at line 4; see `malformed`.
    for (sub, header) in [("csv", CSV_HEADER), ("phyphox", PHYPHOX_HEADER)] {
        let p = write(
            &format!("repeated/{sub}/Raw Data.csv"),
            format!("{header}0,1,2,3\n0.01,1,2,3\n0.01,9,9,9\n0.02,1,2,3\n").as_bytes(),
        );
        let r = inertia::read(&p, &opts()).unwrap();
        assert_eq!(r.t, vec![0.0, 0.01, 0.02], "{sub}");
        assert_eq!(
            r.gyro[1],
            [1.0, 2.0, 3.0],
            "{sub}: the first of the two is kept"
        );
        assert!(
            r.warnings.iter().any(|w| w.contains("line 4")),
            "{sub}: {:?}",
            r.warnings
        );
        let (log, warnings) = close_loop::load(&p, None, None, &opts()).unwrap();
        assert_eq!(log.t.len(), 3, "{sub}");
        assert!(
            warnings.iter().any(|w| w.contains("line 4")),
            "{sub}: {warnings:?}"
        );
        // A repeated time that then goes backwards is still refused at that line.
        let p = write(
            &format!("repeated/{sub}/back.csv"),
            format!("{header}0,1,2,3\n0.01,1,2,3\n0.01,1,2,3\n0.005,1,2,3\n").as_bytes(),
        );
        check(
            "read",
            sub,
            &p,
            inertia::read(&p, &opts()).map(|_| ()),
            Some(5),
        );
    }
    cleanup("repeated");
}

#[test]
fn segments_reader_names_file_and_line() {
    let h = "segment,start,end,keep,comment\n";
    let cases = vec![
        bad("empty", "", None),
        bad("no_columns", "a,b,c\n1,2,3\n", Some(1)),
        bad("truncated", format!("{h}0,1.0,2.0,,x\n1,3.0"), Some(3)),
        bad("reversed", format!("{h}0,2.0,1.0,,\n"), Some(2)),
        bad("nan", format!("{h}0,NaN,1.0,,\n"), Some(2)),
        bad("keep_garbage", format!("{h}0,1.0,2.0,maybe,\n"), Some(2)),
        bad(
            "non_utf8",
            [h.as_bytes(), b"0,1.0,2.0,,\xFF\n"].concat(),
            Some(2),
        ),
    ];
    for b in cases {
        let p = write(&format!("segments/{}.csv", b.name), &b.bytes);
        check(
            "read_segments",
            b.name,
            &p,
            read_segments(&p).map(|_| ()),
            b.line,
        );
    }
    // A log whose segments file is bad: the error names the segments file, not the log.
    let log = write(
        "segments/log.csv",
        format!("{CSV_HEADER}{}", csv_rows(100)).as_bytes(),
    );
    let seg = write(
        "segments/bad_for_log.csv",
        format!("{h}0,2.0,1.0,,\n").as_bytes(),
    );
    check_load(
        "load(segments)",
        "bad_for_log",
        &seg,
        load(&log, None, Some(&seg)).map(|_| ()),
        Some(2),
    );
    // Every segment dropped: an error naming the file.
    let none = write(
        "segments/none_kept.csv",
        format!("{h}0,0.1,0.2,false,\n").as_bytes(),
    );
    check_load(
        "load(no kept segment)",
        "none_kept",
        &none,
        load(&log, None, Some(&none)).map(|_| ()),
        None,
    );
    // A phyphox export's own meta/segments.csv, found beside it, is named the same way.
    let export = write(
        "segments/export/Raw Data.csv",
        format!("{PHYPHOX_HEADER}{}", csv_rows(100)).as_bytes(),
    );
    let meta = write(
        "segments/export/meta/segments.csv",
        format!("{h}0,0.2,0.5,,\n1,0.6,0.4,,\n").as_bytes(),
    );
    check_load(
        "load(meta/segments.csv)",
        "export",
        &meta,
        load(export.parent().unwrap(), None, None).map(|_| ()),
        Some(3),
    );
    cleanup("segments");
}

#[test]
fn missing_and_unreadable_inputs_are_errors_naming_the_path() {
    let p = dir().join("does_not_exist.csv");
    check(
        "read_csv",
        "missing",
        &p,
        read_csv(&p, &opts()).map(|_| ()),
        None,
    );
    check(
        "read_phyphox",
        "missing",
        &p,
        read_phyphox(&p).map(|_| ()),
        None,
    );
    check("detect", "missing", &p, detect(&p).map(|_| ()), None);
    check(
        "read",
        "missing",
        &p,
        inertia::read(&p, &opts()).map(|_| ()),
        None,
    );
    check_load(
        "load",
        "missing",
        &p,
        load(&p, None, None).map(|_| ()),
        None,
    );
    // A folder without "Raw Data.csv".
    let d = dir().join("empty_export");
    std::fs::create_dir_all(&d).unwrap();
    let e = load(&d, None, None).unwrap_err();
    assert!(e.contains("Raw Data.csv"), "{e}");
    let e = inertia::read(&d, &opts()).unwrap_err().to_string();
    assert!(
        e.contains("Raw Data.csv") && e.contains("empty_export"),
        "{e}"
    );
    let _ = std::fs::remove_dir(&d);
}

#[test]
fn tolerated_variations_still_read() {
    // BOM, CRLF, no final newline, blank lines, spaces and quotes.
    let body = "\u{FEFF}t,wx,wy,wz\r\n0, 1,2,3\r\n\r\n\"0.01\",1,2,3";
    let p = write("ok/variations.csv", body.as_bytes());
    for r in [read_csv(&p, &opts()), inertia::read(&p, &opts())] {
        let r = r.unwrap();
        assert_eq!(r.t, vec![0.0, 0.01]);
        assert_eq!(r.gyro[0], [1.0, 2.0, 3.0]);
    }
    // The same for phyphox, with `;` and decimal commas.
    let body = "\u{FEFF}\"Time (s)\";\"Gyroscope x (rad/s)\";\"Gyroscope y (rad/s)\";\
                \"Gyroscope z (rad/s)\"\r\n0,00; 1,5;2;3\r\n\r\n\"0,01\";1;2;3";
    let p = write("ok/phyphox/Raw Data.csv", body.as_bytes());
    for r in [
        read_phyphox(&p),
        inertia::read(p.parent().unwrap(), &opts()),
    ] {
        let r = r.unwrap();
        assert_eq!(r.t, vec![0.0, 0.01]);
        assert_eq!(r.gyro[0], [1.5, 2.0, 3.0]);
    }
    // A header longer than the bytes `detect` looks at, with a character of more than one byte
    // across that boundary (the columns of a wide export): still text, still read.
    let pad: String = (0..60).map(|k| format!("c{k:02},")).collect();
    let mut header = format!("t,wx,wy,wz,{pad}");
    while header.len() < 255 {
        header.push('x');
    }
    header.push_str("\u{b0}C\n");
    let p = write(
        "ok/wide.csv",
        format!("{header}0,1,2,3\n0.01,1,2,3\n").as_bytes(),
    );
    let r = inertia::read(&p, &opts()).unwrap();
    assert_eq!(r.t, vec![0.0, 0.01]);
    // A long valid file reads completely.
    let p = write(
        "ok/long.csv",
        format!("{CSV_HEADER}{}", csv_rows(200_000)).as_bytes(),
    );
    assert_eq!(read_csv(&p, &opts()).unwrap().t.len(), 200_000);
    assert_eq!(load(&p, None, None).unwrap().t.len(), 200_000);
    cleanup("ok");
}

// ---------------------------------------------------------------------------------------------
// Properties: mutated valid files and random bytes.

/// `cases` per property, or `PROPTEST_CASES` from the environment for longer runs.
fn config(cases: u32) -> Config {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(cases);
    Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    }
}

#[derive(Clone, Debug)]
enum Mutation {
    Truncate(usize),
    Flip(usize, u8),
    Insert(usize, Vec<u8>),
    SwapLines(usize, usize),
    DeleteLine(usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Flip(i, b)),
        (
            any::<usize>(),
            prop_oneof![
                Just(b",".to_vec()),
                Just(b"\n".to_vec()),
                Just(b"\xFF".to_vec()),
                Just(b"NaN".to_vec()),
                Just(b"-".to_vec()),
                Just(b"e999".to_vec()),
                Just(b"\"".to_vec()),
                Just(b"\r".to_vec()),
                prop::collection::vec(any::<u8>(), 0..8),
            ]
        )
            .prop_map(|(i, v)| Mutation::Insert(i, v)),
        (any::<usize>(), any::<usize>()).prop_map(|(a, b)| Mutation::SwapLines(a, b)),
        any::<usize>().prop_map(Mutation::DeleteLine),
    ]
}

fn apply(mut bytes: Vec<u8>, muts: &[Mutation]) -> Vec<u8> {
    for m in muts {
        let n = bytes.len().max(1);
        match m {
            Mutation::Truncate(i) => bytes.truncate(i % n),
            Mutation::Flip(i, b) => {
                if let Some(x) = bytes.get_mut(i % n) {
                    *x = *b;
                }
            }
            Mutation::Insert(i, v) => {
                let at = (i % n).min(bytes.len());
                bytes.splice(at..at, v.iter().copied());
            }
            Mutation::SwapLines(a, b) => {
                let mut lines: Vec<Vec<u8>> =
                    bytes.split(|&c| c == b'\n').map(<[u8]>::to_vec).collect();
                let l = lines.len();
                lines.swap(a % l, b % l);
                bytes = lines.join(&b'\n');
            }
            Mutation::DeleteLine(a) => {
                let mut lines: Vec<Vec<u8>> =
                    bytes.split(|&c| c == b'\n').map(<[u8]>::to_vec).collect();
                let l = lines.len();
                lines.remove(a % l);
                bytes = lines.join(&b'\n');
            }
        }
    }
    bytes
}

/// Whatever the bytes: no panic; an accepted file has finite, strictly increasing time and
/// finite rates; a refused one names the file and a line that exists.
fn assert_sane(name: &str, bytes: &[u8]) -> Result<(), TestCaseError> {
    let p = write(name, bytes);
    let lines = bytes.split(|&c| c == b'\n').count();
    let file = p.file_name().unwrap().to_string_lossy().to_string();
    let as_f64 = |r: inertia::Recording| {
        let w: Vec<[f64; 3]> = r.gyro.iter().map(|w| w.map(f64::from)).collect();
        (r.t, w)
    };
    for (which, r) in [
        (
            "csv",
            read_csv(&p, &opts()).map(as_f64).map_err(|e| e.to_string()),
        ),
        (
            "phyphox",
            read_phyphox(&p).map(as_f64).map_err(|e| e.to_string()),
        ),
        (
            "read",
            inertia::read(&p, &opts())
                .map(as_f64)
                .map_err(|e| e.to_string()),
        ),
        ("load", load(&p, None, None).map(|l| (l.t, l.omega))),
    ] {
        match r {
            Ok((t, w)) => {
                prop_assert!(t.len() >= 2 && t.len() == w.len(), "{which}");
                prop_assert!(
                    t.windows(2).all(|x| x[1] > x[0]),
                    "{which}: time not increasing"
                );
                prop_assert!(t.iter().all(|x| x.is_finite()), "{which}");
                prop_assert!(w.iter().flatten().all(|x| x.is_finite()), "{which}");
            }
            Err(e) => {
                prop_assert!(e.contains(&file), "{which}: {e}");
                prop_assert!(e.len() < 1000, "{which}: message of {} bytes", e.len());
                if let Some(l) = line_in(&e, &file) {
                    prop_assert!(l >= 1 && l <= lines, "{which}: line {l} of {lines}: {e}");
                }
            }
        }
    }
    match read_segments(&p) {
        Ok(s) => prop_assert!(s.iter().all(|s| s.start.is_finite() && s.end > s.start)),
        Err(e) => {
            prop_assert!(e.to_string().contains(&file), "segments: {e}");
            if let Some(l) = e.line() {
                prop_assert!(l >= 1 && l <= lines, "segments: line {l} of {lines}: {e}");
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(config(300))]

    #[test]
    fn mutated_csv_never_panics(muts in prop::collection::vec(mutation(), 1..6)) {
        let base = format!("{CSV_HEADER}{}", csv_rows(30)).into_bytes();
        assert_sane("prop/mutated.csv", &apply(base, &muts))?;
    }

    #[test]
    fn mutated_phyphox_never_panics(muts in prop::collection::vec(mutation(), 1..6)) {
        let base = format!("{PHYPHOX_HEADER}{}", csv_rows(30)).into_bytes();
        assert_sane("prop/Raw Data.csv", &apply(base, &muts))?;
    }

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..2000)) {
        assert_sane("prop/random.csv", &bytes)?;
    }
}

/// An error message must not quote a huge field in full (a 5 MB field once gave a 5 MB
/// message in the old readers; the inertia readers cut it the same way).
#[test]
fn error_messages_are_bounded() {
    let mut bytes = format!("{CSV_HEADER}0,1,2,3\n0.01,").into_bytes();
    bytes.extend(std::iter::repeat_n(b'9', 5_000_000));
    bytes.extend_from_slice(b",2,3\n");
    let p = write("bounded/huge_field.csv", &bytes);
    let msg = read_csv(&p, &opts()).unwrap_err().to_string();
    assert!(msg.len() < 1000, "message of {} bytes", msg.len());
    // A huge header is quoted cut too.
    let mut bytes = b"t,".to_vec();
    bytes.extend(std::iter::repeat_n(b'x', 5_000_000));
    bytes.extend_from_slice(b"\n0,1,2,3\n");
    let p = write("bounded/huge_header.csv", &bytes);
    let msg = read_csv(&p, &opts()).unwrap_err().to_string();
    assert!(msg.len() < 1000, "message of {} bytes", msg.len());
    cleanup("bounded");
}
