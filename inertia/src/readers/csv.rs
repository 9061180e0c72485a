//! CSV with named columns.
//!
//! The header names the columns (case-insensitive, quotes and spaces ignored, in any order,
//! extra columns ignored):
//!
//! | quantity | header names | unit |
//! |---|---|---|
//! | time (required) | `t`, `time`, `t_s` or `time_s` | [`ReadOptions::time_unit`], default seconds |
//! | gyro (required) | `wx,wy,wz`, `gx,gy,gz`, `w_x,...`, `gyro_x,...` or `omega_x,...` | [`ReadOptions::gyro_unit`], default rad/s |
//! | accelerometer (optional) | `ax,ay,az`, `a_x,...`, `acc_x,...` or `accel_x,...` | [`ReadOptions::accel_unit`], default m/s^2 (gravity included) |
//! | rotor speed (optional) | `rotor_rad_s` (rad/s), `rotor_rpm` (mechanical rpm) or `erpm` (true eRPM) | |
//! | a vehicle file's rotors (optional) | the names its `column` keys give ([`ReadOptions::rotor_columns`]) | as logged; the vehicle file's `speed_unit` |
//! | attitude (optional) | `qw,qx,qy,qz`, scalar first, `v_N = R(q) v_B` | |
//! | position (optional) | `rx,ry,rz`, Earth-centred inertial | m |
//! | magnetometer (optional) | `bx,by,bz`, body frame | T |
//!
//! The plain `t,wx,wy,wz` (seconds, rad/s) reads as it always did. Separators `,`, `;` (with
//! decimal commas) and tab are accepted, as in [`super::phyphox`].

use std::path::Path;

use super::{collect, fields, quote, text, Extra, Location, ReadError, ReadOptions, MAX_WHEELS};
use crate::readers::Recording;
use crate::readers::{Channels, Reading, RotorUnit, Source, Visit};

/// Column positions found in a header.
struct Columns {
    t: usize,
    gyro: [usize; 3],
    accel: Option<[usize; 3]>,
    rotor: Option<(usize, RotorUnit)>,
    /// What the rotor column's values are multiplied by (`rotor_rpm`: 2 pi / 60 to rad/s).
    rotor_scale: f64,
    attitude: Option<[usize; 4]>,
    position: Option<[usize; 3]>,
    magnetic: Option<[usize; 3]>,
    /// The vehicle file's rotor columns, in its order.
    wheels: Vec<usize>,
}

fn columns(path: &Path, header: &str, rotor_columns: &[String]) -> Result<Columns, ReadError> {
    let names: Vec<String> = fields(header)
        .into_iter()
        .map(|n| n.to_ascii_lowercase())
        .collect();
    let col = |n: &str| names.iter().position(|c| c == n);
    let triple = |p: &str| -> Option<[usize; 3]> {
        Some([
            col(&format!("{p}x"))?,
            col(&format!("{p}y"))?,
            col(&format!("{p}z"))?,
        ])
    };
    let bad = |what: &str| {
        ReadError::at(
            path,
            Location::Line(1),
            format!(
                "header {} has no {what}: expected t (or time), wx,wy,wz (or gx,gy,gz), \
                 optional ax,ay,az and rotor_rad_s, rotor_rpm or erpm",
                quote(header)
            ),
        )
    };
    let first = |names: &[&str]| names.iter().find_map(|n| col(n));
    let first3 = |prefixes: &[&str]| prefixes.iter().find_map(|p| triple(p));
    let t = first(&["t", "time", "t_s", "time_s"]).ok_or_else(|| bad("time column"))?;
    let gyro = first3(&["w", "g", "w_", "gyro_", "omega_"]).ok_or_else(|| bad("gyro columns"))?;
    let accel = first3(&["a", "a_", "acc_", "accel_"]);
    let rpm = core::f64::consts::TAU / 60.0;
    let (rotor, rotor_scale) = match (col("rotor_rad_s"), col("rotor_rpm"), col("erpm")) {
        (Some(c), _, _) => (Some((c, RotorUnit::RadPerSec)), 1.0),
        (None, Some(c), _) => (Some((c, RotorUnit::RadPerSec)), rpm),
        (None, None, Some(c)) => (Some((c, RotorUnit::Erpm)), 1.0),
        (None, None, None) => (None, 1.0),
    };
    let attitude = (|| Some([col("qw")?, col("qx")?, col("qy")?, col("qz")?]))();
    if rotor_columns.len() > MAX_WHEELS {
        return Err(ReadError::new(
            path,
            format!("more than {MAX_WHEELS} rotor columns"),
        ));
    }
    let mut wheels = Vec::with_capacity(rotor_columns.len());
    for name in rotor_columns {
        let c = col(&name.trim().to_ascii_lowercase()).ok_or_else(|| {
            ReadError::at(
                path,
                Location::Line(1),
                format!(
                    "the vehicle file names the rotor column {}, which header {} does not have",
                    quote(name),
                    quote(header)
                ),
            )
        })?;
        wheels.push(c);
    }
    Ok(Columns {
        t,
        gyro,
        accel,
        rotor,
        rotor_scale,
        attitude,
        position: triple("r"),
        magnetic: triple("b"),
        wheels,
    })
}

/// Reads a CSV with named columns (see the module documentation), converting time and gyro
/// with `opts` (defaults: seconds, rad/s).
pub fn read_csv(path: &Path, opts: &ReadOptions) -> Result<Recording, ReadError> {
    CsvSource::open(path, opts)?.collect()
}

/// A row's values: time, gyro, accelerometer, rotor speed (units converted).
type Row = text::TableRow;

/// Where a value of a row goes: time, the gyro axes, the accelerometer axes, the rotor, the
/// attitude, position and magnetometer ([`SLOT_Q`], [`SLOT_R`], [`SLOT_B`]), the vehicle's
/// rotors ([`SLOT_WHEELS`]).
const SLOTS: usize = SLOT_WHEELS + MAX_WHEELS;
const SLOT_Q: usize = 8;
const SLOT_R: usize = SLOT_Q + 4;
const SLOT_B: usize = SLOT_R + 3;
const SLOT_WHEELS: usize = SLOT_B + 3;
const NO_SLOT: u8 = u8::MAX;

/// A CSV log read row by row (see [`crate::source`]).
pub struct CsvSource {
    path: std::path::PathBuf,
    c: Columns,
    kt: f64,
    kw: f64,
    /// Factor of the accelerometer columns to m/s^2.
    ka: f64,
    /// The highest column a row must have.
    need: usize,
    /// `--gyro-unit` was given (else rad/s is assumed).
    gyro_unit_stated: bool,
    /// For each column up to `need`, the slot its value fills (or [`NO_SLOT`]).
    slot_of: Vec<u8>,
}

impl CsvSource {
    /// Reads the header (the rows are read by each [`Source::read_all`]).
    pub fn open(path: &Path, opts: &ReadOptions) -> Result<Self, ReadError> {
        let Some(header) = text::first_line(path)? else {
            return Err(ReadError::new(path, "empty file"));
        };
        let c =
            columns(path, &header, &opts.rotor_columns).map_err(|e| text::utf8_first(path, e))?;
        let kt = opts.time_unit.unwrap_or_default().to_seconds();
        let kw = opts.gyro_unit.unwrap_or_default().to_rad_per_sec();
        let ka = opts.accel_unit.unwrap_or_default().to_meters_per_sec2();
        let mut need = c.t.max(c.gyro[0]).max(c.gyro[1]).max(c.gyro[2]);
        if let Some(a) = c.accel {
            need = need.max(a[0]).max(a[1]).max(a[2]);
        }
        if let Some((r, _)) = c.rotor {
            need = need.max(r);
        }
        let extra_cols = c
            .attitude
            .iter()
            .flatten()
            .chain(c.position.iter().flatten());
        let extra_cols = extra_cols
            .chain(c.magnetic.iter().flatten())
            .chain(&c.wheels);
        need = extra_cols.fold(need, |m, &k| m.max(k));
        let mut slot_of = vec![NO_SLOT; need + 1];
        let mut put = |col: usize, slot: u8| {
            if let Some(s) = slot_of.get_mut(col) {
                if *s == NO_SLOT {
                    *s = slot;
                }
            }
        };
        put(c.t, 0);
        for k in 0..3 {
            put(c.gyro[k], 1 + k as u8);
            if let Some(a) = c.accel {
                put(a[k], 4 + k as u8);
            }
        }
        if let Some((r, _)) = c.rotor {
            put(r, 7);
        }
        let groups: [(Option<&[usize]>, usize); 4] = [
            (c.attitude.as_ref().map(|v| &v[..]), SLOT_Q),
            (c.position.as_ref().map(|v| &v[..]), SLOT_R),
            (c.magnetic.as_ref().map(|v| &v[..]), SLOT_B),
            (Some(&c.wheels[..]), SLOT_WHEELS),
        ];
        for (cols, first) in groups {
            for (k, &col) in cols.unwrap_or(&[]).iter().enumerate() {
                put(col, (first + k) as u8);
            }
        }
        Ok(CsvSource {
            path: path.to_path_buf(),
            c,
            kt,
            kw,
            ka,
            need,
            slot_of,
            gyro_unit_stated: opts.gyro_unit.is_some(),
        })
    }

    /// The whole log as a [`Recording`].
    fn collect(&self) -> Result<Recording, ReadError> {
        collect(self)
    }

    /// The fields of a row for each slot (the first column of each name wins, as in the
    /// header), the row's field count and whether it uses decimal commas.
    #[inline]
    fn split<'l>(&self, line: &'l str) -> ([&'l str; SLOTS], usize, bool) {
        let mut out = [""; SLOTS];
        let mut put = |i: usize, f: &'l str| {
            if let Some(&slot) = self.slot_of.get(i) {
                if let Some(o) = out.get_mut(slot as usize) {
                    *o = text::clean(f);
                }
            }
        };
        // The common row: `,` separators, which one scan splits. A `;` or a tab anywhere
        // makes the row's separator another (see `text::separator`).
        let mut start = 0;
        let mut i = 0;
        let mut plain = true;
        for (k, &b) in line.as_bytes().iter().enumerate() {
            // Digits, signs, points and letters are above `;`; one comparison passes them.
            if b > b';' || (b'-'..=b'9').contains(&b) {
                continue;
            }
            if b == b',' {
                put(i, line.get(start..k).unwrap_or_default());
                i += 1;
                start = k + 1;
            } else if b == b';' || b == b'\t' {
                plain = false;
                break;
            }
        }
        if plain {
            put(i, line.get(start..).unwrap_or_default());
            return (out, i + 1, false);
        }
        out = [""; SLOTS];
        let (sep, dc) = text::separator(line);
        let mut count = 0;
        for (i, f) in line.split(sep).enumerate() {
            count = i + 1;
            if let Some(&slot) = self.slot_of.get(i) {
                if let Some(o) = out.get_mut(slot as usize) {
                    *o = text::clean(f);
                }
            }
        }
        (out, count, dc)
    }

    /// The values of the common row (`,` separators, plain decimals in the columns read) by
    /// slot, in one pass over it: most of the time a long log takes. `None` for any other row,
    /// which [`CsvSource::row`]'s general path reads (to the same values when it is one).
    #[inline]
    fn plain_row(&self, line: &str) -> Option<[f64; SLOTS]> {
        let b = line.as_bytes();
        let mut out = [0.0; SLOTS];
        let mut at = 0;
        for col in 0..=self.need {
            let rest = b.get(at..)?;
            let slot = *self.slot_of.get(col)?;
            at += if slot == NO_SLOT {
                // A column not read: only its separators count.
                let end = rest
                    .iter()
                    .position(|&c| c == b',' || c == b';' || c == b'\t');
                end.unwrap_or(rest.len())
            } else {
                let (v, len) = text::decimal_prefix(rest)?;
                *out.get_mut(usize::from(slot))? = v;
                len
            };
            match b.get(at) {
                Some(b',') => at += 1,
                None if col == self.need => return Some(out),
                _ => return None,
            }
        }
        // Columns after the last one read: a `;` or a tab would make the separator another.
        let rest = b.get(at..)?;
        (!rest.iter().any(|&c| c == b';' || c == b'\t')).then_some(out)
    }

    /// One data row: `Ok(None)` for a blank line.
    fn row(&self, n: usize, line: &str, scratch: &mut String) -> Result<Option<Row>, ReadError> {
        if let Some(v) = self.plain_row(line) {
            let w = [v[1], v[2], v[3]].map(|x| x * self.kw);
            let a = self
                .c
                .accel
                .map(|_| [v[4], v[5], v[6]].map(|x| x * self.ka));
            let r = self.c.rotor.map(|_| v[7] * self.c.rotor_scale);
            return Ok(Some((v[0] * self.kt, w, a, r, self.extra(&v))));
        }
        self.general_row(n, line, scratch)
    }

    /// [`CsvSource::row`] for any row: fields split by the row's separator, cleaned, parsed.
    fn general_row(
        &self,
        n: usize,
        line: &str,
        scratch: &mut String,
    ) -> Result<Option<Row>, ReadError> {
        let path = self.path.as_path();
        if line.trim().is_empty() {
            return Ok(None);
        }
        let (f, count, dc) = self.split(line);
        if count <= self.need {
            return Err(ReadError::at(
                path,
                Location::Line(n),
                format!(
                    "truncated row: {} field(s), the header names {}",
                    count,
                    self.need + 1
                ),
            ));
        }
        let t = text::number(path, n, "time", f[0], dc, scratch)? * self.kt;
        let mut w = [0.0; 3];
        for (k, name) in ["wx", "wy", "wz"].iter().enumerate() {
            w[k] = text::number(path, n, name, f[1 + k], dc, scratch)? * self.kw;
        }
        let a = match self.c.accel {
            Some(_) => {
                let mut a = [0.0; 3];
                for (k, name) in ["ax", "ay", "az"].iter().enumerate() {
                    a[k] = text::number(path, n, name, f[4 + k], dc, scratch)? * self.ka;
                }
                Some(a)
            }
            None => None,
        };
        let r = match self.c.rotor {
            Some(_) => {
                Some(text::number(path, n, "rotor speed", f[7], dc, scratch)? * self.c.rotor_scale)
            }
            None => None,
        };
        let mut v = [0.0; SLOTS];
        for (slot, (x, field)) in v.iter_mut().zip(f).enumerate().skip(SLOT_Q) {
            if self.slot_used(slot) {
                *x = text::number(path, n, slot_name(slot), field, dc, scratch)?;
            }
        }
        Ok(Some((t, w, a, r, self.extra(&v))))
    }

    /// Whether a column fills `slot` (the extra slots only).
    fn slot_used(&self, slot: usize) -> bool {
        let c = &self.c;
        match slot {
            s if s < SLOT_Q => true,
            s if s < SLOT_R => c.attitude.is_some(),
            s if s < SLOT_B => c.position.is_some(),
            s if s < SLOT_WHEELS => c.magnetic.is_some(),
            s => s - SLOT_WHEELS < c.wheels.len(),
        }
    }

    /// The vehicle's and the spacecraft's values of a row by slot (zero where absent).
    #[inline]
    fn extra(&self, v: &[f64; SLOTS]) -> Extra {
        let at = |k: usize| v.get(k).copied().unwrap_or(0.0);
        Extra {
            wheels: core::array::from_fn(|k| at(SLOT_WHEELS + k) as f32),
            attitude: core::array::from_fn(|k| at(SLOT_Q + k) as f32),
            position: core::array::from_fn(|k| at(SLOT_R + k)),
            magnetic: core::array::from_fn(|k| at(SLOT_B + k) as f32),
        }
    }
}

/// The name of an extra slot's column, for messages.
fn slot_name(slot: usize) -> &'static str {
    const NAMES: [&str; SLOT_WHEELS - SLOT_Q] =
        ["qw", "qx", "qy", "qz", "rx", "ry", "rz", "bx", "by", "bz"];
    NAMES
        .get(slot.wrapping_sub(SLOT_Q))
        .copied()
        .unwrap_or("rotor speed")
}

impl Source for CsvSource {
    fn name(&self) -> String {
        format!("{} (csv)", self.path.display())
    }

    fn channels(&self) -> Channels {
        Channels {
            accel: self.c.accel.is_some(),
            rotor: self.c.rotor.map(|(_, unit)| unit),
            wheels: self.c.wheels.len(),
            attitude: self.c.attitude.is_some(),
            position: self.c.position.is_some(),
            magnetic: self.c.magnetic.is_some(),
        }
    }

    fn full_scale(&self) -> f32 {
        f32::INFINITY
    }

    fn gyro_unit_stated(&self) -> bool {
        self.gyro_unit_stated
    }

    fn read_all(
        &self,
        visit: &mut Visit<'_>,
        progress: &mut dyn FnMut(f32),
    ) -> Result<Reading, ReadError> {
        text::read_table(&self.path, visit, progress, &|n, line, scratch| {
            self.row(n, line, scratch)
        })
    }

    fn warnings(&self, found: Vec<String>) -> Vec<String> {
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::readers::RotorSpeed;
    use crate::readers::{AccelUnit, GyroUnit, TimeUnit};
    use crate::readers::{Flow, Sample};

    fn tmp(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        crate::readers::test_file("csv", name, bytes)
    }

    #[test]
    fn plain_and_named_columns() {
        let p = tmp("plain.csv", b"t,wx,wy,wz\n0,1,2,3\n0.01,1,2,3");
        let r = read_csv(&p, &ReadOptions::default()).unwrap();
        assert_eq!(r.t, vec![0.0, 0.01]);
        assert_eq!(r.gyro[1], [1.0, 2.0, 3.0]);
        assert!(r.accel.is_none() && r.rotor.is_none());

        let p = tmp(
            "named.csv",
            b"erpm,gz,Time,gy,gx,az,ay,ax\n100,3,0,2,1,9.8,0,0\n200,3,10,2,1,9.8,0,0\n",
        );
        let o = ReadOptions {
            gyro_unit: Some(GyroUnit::DegPerSec),
            time_unit: Some(TimeUnit::Ms),
            ..ReadOptions::default()
        };
        let r = read_csv(&p, &o).unwrap();
        assert_eq!(r.t, vec![0.0, 0.01]);
        assert!((r.gyro[0][2] - 3.0f32.to_radians()).abs() < 1e-7);
        assert_eq!(r.accel.as_ref().unwrap()[0], [0.0, 0.0, 9.8]);
        assert_eq!(r.rotor, Some(RotorSpeed::Erpm(vec![100.0, 200.0])));

        // The accelerometer declared in g or milli-g, on the common row and on one the
        // general path reads (a decimal comma).
        let p = tmp(
            "g.csv",
            b"t,wx,wy,wz,ax,ay,az\n0,0,0,0,0,0,1\n0.01,0,0,0,0,0,1\n",
        );
        let mut o = ReadOptions {
            accel_unit: Some(AccelUnit::G),
            ..ReadOptions::default()
        };
        let r = read_csv(&p, &o).unwrap();
        assert_eq!(r.accel.as_ref().unwrap()[1], [0.0, 0.0, 9.806_65]);
        let p = tmp(
            "mg.csv",
            b"t;wx;wy;wz;ax;ay;az\n0;0;0;0;0;0;1000,0\n0,01;0;0;0;0;0;1000,0\n",
        );
        o.accel_unit = Some(AccelUnit::MilliG);
        let r = read_csv(&p, &o).unwrap();
        assert_eq!(r.accel.as_ref().unwrap()[0], [0.0, 0.0, 9.806_65]);
    }

    /// The one-pass reading of the common row gives the general path's values bit for bit,
    /// and leaves every other row to it.
    #[test]
    fn plain_rows_read_as_the_general_path_reads_them() {
        let p = tmp(
            "plain_fast.csv",
            b"time,note,gz,gx,gy,ax,ay,az,rotor_rad_s,extra\n0,a,1,2,3,4,5,6,7,x\n",
        );
        let src = CsvSource::open(&p, &ReadOptions::default()).unwrap();
        let mut scratch = String::new();
        let lines = [
            "0.0001250,note,-0.0031957934,-0,+0.5,0.39743748,0.10055647,9.763555,174.53293,z",
            "12.5,,1,2,3,4,5,6,7",
            "1,x y \"q\",1.,2,3,4,5,6,7,tail,more",
            "1,n,00000000000000000001.5,2,3,4,5,6,7,",
            "1,n,12345678901234567890,2,3,4,5,6,7,",
            "1,n,9007199254740993,2,3,4,5,6,7,",
            "1,n,1e3,2,3,4,5,6,7",
            "1,n, 1,2,3,4,5,6,7",
            "1,n,\"1\",2,3,4,5,6,7",
            "1,n;x,1,2,3,4,5,6,7",
            "1,n,1,2,3,4,5,6,7,a;b",
            "1;n;1,5;2;3;4;5;6;7",
            "1\tn\t1\t2\t3\t4\t5\t6\t7",
            "1,n,1,2,3,4,5,6",
            "1,n,1,2,3,4,5,6,",
            "1,n,.5,2,3,4,5,6,7",
            "1,n,-,2,3,4,5,6,7",
            "",
            "1,n,1,2,3,4,5,6,inf",
        ];
        let mut fast = 0;
        for line in lines {
            let got = src.row(2, line, &mut scratch);
            let want = src.general_row(2, line, &mut scratch);
            match (&got, &want) {
                (Ok(g), Ok(w)) => assert_eq!(format!("{g:?}"), format!("{w:?}"), "{line}"),
                (Err(g), Err(w)) => assert_eq!(g.to_string(), w.to_string(), "{line}"),
                _ => panic!("{line}: {got:?} against {want:?}"),
            }
            fast += usize::from(src.plain_row(line).is_some());
        }
        // The first three take the one pass; the long digit strings (beyond 19 digits or 2^53,
        // where one division would not round as `parse` does) and the rest do not.
        assert_eq!(fast, 3);
    }

    /// The reading without the blocks and threads: line by line, each row parsed, checked and
    /// kept in turn (the reference for [`CsvSource::read_all`]).
    fn line_by_line(src: &CsvSource) -> Result<(Vec<Sample>, Reading), ReadError> {
        let mut check = super::super::check::Checker::new(&src.path);
        let mut scratch = String::new();
        let mut out = Vec::new();
        text::each_line(
            &src.path,
            &mut |n, line| {
                if n == 1 {
                    return Ok(Flow::Continue);
                }
                if let Some((t, w, a, r, x)) = src.row(n, line, &mut scratch)? {
                    if let Some(s) = check.check_with(Location::Line(n), t, w, a, r, x)? {
                        out.push(s);
                    }
                }
                Ok(Flow::Continue)
            },
            &mut |_| {},
        )?;
        Ok((out, check.reading(false)?))
    }

    /// Random logs of several blocks, with blank lines, CR LF endings, repeated times and,
    /// in most, a fault somewhere (a bad number, a truncated row, time going backwards, a
    /// line that is not UTF-8, or two of them): the blocks read on threads give what the line
    /// by line reading gives, samples, warnings and errors alike.
    #[test]
    fn blocks_read_as_lines_are_read() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for file in 0..16 {
            let mut bytes = b"t,wx,wy,wz,ax,ay,az,rotor_rad_s\n".to_vec();
            let mut t = 0.0f64;
            let faults = file % 4;
            let rows = 14_000;
            let at: Vec<u64> = (0..faults).map(|_| next() % rows).collect();
            for i in 0..rows {
                let r = next();
                if r % 50 != 0 {
                    t += 1.25e-4;
                }
                let mut line = format!(
                    "{t:.7},{:.6},-{:.5},{},9.80665,{}.5,-0.25,{}",
                    (r % 1000) as f64 * 1e-3,
                    (r % 777) as f64 * 1e-2,
                    r % 7,
                    r % 3,
                    174 + r % 9
                );
                if at.contains(&i) {
                    match next() % 4 {
                        0 => line = line.replacen("9.80665", "9.8.0", 1),
                        1 => line = line.rsplit_once(',').map_or(line.clone(), |p| p.0.into()),
                        2 => line = line.replacen(&format!("{t:.7}"), "0.0000001", 1),
                        _ => {
                            bytes.extend_from_slice(line.as_bytes());
                            bytes.extend_from_slice(b"\xC3(\n");
                            continue;
                        }
                    }
                }
                bytes.extend_from_slice(line.as_bytes());
                bytes.extend_from_slice(if r % 3 == 0 { b"\r\n" } else { b"\n" });
                if r % 97 == 0 {
                    bytes.push(b'\n');
                }
            }
            let p = tmp(&format!("blocks-{file}.csv"), &bytes);
            let src = CsvSource::open(&p, &ReadOptions::default()).unwrap();
            let mut got = Vec::new();
            let read = src.read_all(
                &mut |s| {
                    got.push(*s);
                    Ok(Flow::Continue)
                },
                &mut |_| {},
            );
            match (read, line_by_line(&src)) {
                (Ok(r), Ok((want, w))) => {
                    assert_eq!((r.samples, &r.duplicates), (w.samples, &w.duplicates));
                    assert_eq!(format!("{got:?}"), format!("{want:?}"), "file {file}");
                }
                (Err(e), Err(w)) => assert_eq!(e.to_string(), w.to_string(), "file {file}"),
                (r, w) => panic!("file {file}: {r:?} against {w:?}"),
            }
        }
    }

    #[test]
    fn duplicates_dropped_backwards_refused() {
        let p = tmp("dup.csv", b"t,wx,wy,wz\n0,1,2,3\n0,9,9,9\n0.01,1,2,3\n");
        let r = read_csv(&p, &ReadOptions::default()).unwrap();
        assert_eq!(r.len(), 2);
        assert_eq!(r.gyro[0], [1.0, 2.0, 3.0]);
        assert!(r.warnings.iter().any(|w| w.contains("line 3")), "{r:?}");
        let p = tmp("back.csv", b"t,wx,wy,wz\n0,1,2,3\n0.02,1,2,3\n0.01,1,2,3\n");
        let e = read_csv(&p, &ReadOptions::default()).unwrap_err();
        assert_eq!(e.line(), Some(4), "{e}");
    }
}
