//! CSV with named columns.
//!
//! The header names the columns (case-insensitive, quotes and spaces ignored, in any order,
//! extra columns ignored):
//!
//! | quantity | header names | unit |
//! |---|---|---|
//! | time (required) | `t` or `time` | [`ReadOptions::time_unit`], default seconds |
//! | gyro (required) | `wx,wy,wz` or `gx,gy,gz` | [`ReadOptions::gyro_unit`], default rad/s |
//! | accelerometer (optional) | `ax,ay,az` | m/s^2 |
//! | rotor speed (optional) | `rotor_rad_s` (rad/s) or `erpm` (true eRPM) | |
//!
//! The plain `t,wx,wy,wz` (seconds, rad/s) reads as it always did. Separators `,`, `;` (with
//! decimal commas) and tab are accepted, as in [`super::phyphox`].

use std::path::Path;

use super::{
    fields, number, quote, read_lines, Location, ReadError, ReadOptions, RotorWrap, Samples,
};
use crate::recording::{Recording, RotorSpeed};

/// Column positions found in a header.
struct Columns {
    t: usize,
    gyro: [usize; 3],
    accel: Option<[usize; 3]>,
    rotor: Option<(usize, RotorWrap)>,
}

fn columns(path: &Path, header: &str) -> Result<Columns, ReadError> {
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
                 optional ax,ay,az and rotor_rad_s or erpm",
                quote(header)
            ),
        )
    };
    let t = col("t")
        .or_else(|| col("time"))
        .ok_or_else(|| bad("time column"))?;
    let gyro = triple("w")
        .or_else(|| triple("g"))
        .ok_or_else(|| bad("gyro columns"))?;
    let accel = triple("a");
    let rotor = match (col("rotor_rad_s"), col("erpm")) {
        (Some(c), _) => Some((c, RotorSpeed::RadPerSec as RotorWrap)),
        (None, Some(c)) => Some((c, RotorSpeed::Erpm as RotorWrap)),
        (None, None) => None,
    };
    Ok(Columns {
        t,
        gyro,
        accel,
        rotor,
    })
}

/// Reads a CSV with named columns (see the module documentation), converting time and gyro
/// with `opts` (defaults: seconds, rad/s).
pub fn read_csv(path: &Path, opts: &ReadOptions) -> Result<Recording, ReadError> {
    let lines = read_lines(path)?;
    let Some(header) = lines.first() else {
        return Err(ReadError::new(path, "empty file"));
    };
    let c = columns(path, header)?;
    let kt = opts.time_unit.unwrap_or_default().to_seconds();
    let kw = opts.gyro_unit.unwrap_or_default().to_rad_per_sec();
    let mut need = c.t.max(c.gyro[0]).max(c.gyro[1]).max(c.gyro[2]);
    if let Some(a) = c.accel {
        need = need.max(a[0]).max(a[1]).max(a[2]);
    }
    if let Some((r, _)) = c.rotor {
        need = need.max(r);
    }
    let mut samples = Samples::new(path);
    for (i, line) in lines.iter().enumerate().skip(1) {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f = fields(line);
        if f.len() <= need {
            return Err(ReadError::at(
                path,
                Location::Line(n),
                format!(
                    "truncated row: {} field(s), the header names {}",
                    f.len(),
                    need + 1
                ),
            ));
        }
        let t = number(path, n, "time", &f[c.t])? * kt;
        let mut w = [0.0; 3];
        for (k, name) in ["wx", "wy", "wz"].iter().enumerate() {
            w[k] = number(path, n, name, &f[c.gyro[k]])? * kw;
        }
        let a = match c.accel {
            Some(cols) => {
                let mut a = [0.0; 3];
                for (k, name) in ["ax", "ay", "az"].iter().enumerate() {
                    a[k] = number(path, n, name, &f[cols[k]])?;
                }
                Some(a)
            }
            None => None,
        };
        let r = match c.rotor {
            Some((col, _)) => Some(number(path, n, "rotor speed", &f[col])?),
            None => None,
        };
        samples.push(Location::Line(n), t, w, a, r)?;
    }
    samples.finish(
        format!("{} (csv)", path.display()),
        c.rotor.map(|(_, wrap)| wrap),
        f32::INFINITY,
        Vec::new(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::readers::{GyroUnit, TimeUnit};

    fn tmp(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("inertia_csv_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
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
        };
        let r = read_csv(&p, &o).unwrap();
        assert_eq!(r.t, vec![0.0, 0.01]);
        assert!((r.gyro[0][2] - 3.0f32.to_radians()).abs() < 1e-7);
        assert_eq!(r.accel.as_ref().unwrap()[0], [0.0, 0.0, 9.8]);
        assert_eq!(r.rotor, Some(RotorSpeed::Erpm(vec![100.0, 200.0])));
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
