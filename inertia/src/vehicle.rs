//! The vehicle file: the known rotors of a vehicle (reaction wheels, a flywheel, a
//! quadrotor's own motors with the propellers off), each with the log column of its speed.
//!
//! ```toml
//! [[rotor]]
//! name = "rw1"
//! column = "rw1_rad_s"         # CSV column (or a blackbox field such as "eRPM[2]", a ULog
//!                              # field such as "esc_status.esc[2].esc_rpm")
//! inertia_kg_m2 = 2.387e-5     # about the rotor's own axis
//! axis = [0.5736, 0.0, 0.8192] # unit vector in the gyro frame, positive speed direction
//! # optional: poles = 14 (eRPM fields), speed_unit = "rad/s" | "rpm" | "erpm"
//! ```
//!
//! The speed is the rotor's speed relative to the body, and the momentum the fits take is
//! `h(t) = sum_i j_i w_i(t) g_i` ((R1) of `identifier_core::Rotors`, the function the firmware
//! uses too). The default `speed_unit` is `erpm` for a column whose name starts with `erpm`,
//! else `rad/s`. Refused, with the rotor named: a missing key or an unknown one, a zero,
//! negative or non-finite inertia, an axis that is not a unit vector (within
//! [`identifier_core::AXIS_UNIT_TOLERANCE`]), eRPM without `poles`, a name or column listed
//! twice, more than [`identifier_core::MAX_ROTORS`] rotors. A column the log does not have is
//! refused when the log is read.

use std::fmt;
use std::path::{Path, PathBuf};

use identifier_core::{Rotor, RotorError, Rotors, AXIS_UNIT_TOLERANCE, MAX_ROTORS};
use serde::Deserialize;

/// The unit a rotor's speed column is logged in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
pub enum SpeedUnit {
    /// Mechanical rad/s.
    #[serde(rename = "rad/s")]
    RadPerSec,
    /// Mechanical revolutions per minute.
    #[serde(rename = "rpm")]
    Rpm,
    /// Electrical revolutions per minute (needs `poles`).
    #[serde(rename = "erpm")]
    Erpm,
}

/// One rotor of the vehicle file.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleRotor {
    /// Its name, for messages and the report.
    pub name: String,
    /// The log column (or field) of its speed.
    pub column: String,
    /// Inertia about its own axis, kg m^2.
    pub inertia_kg_m2: f32,
    /// Unit vector in the gyro frame, the positive speed direction.
    pub axis: [f32; 3],
    /// Motor poles (eRPM columns).
    #[serde(default)]
    pub poles: Option<u32>,
    /// The speed column's unit (default: see the module documentation).
    #[serde(default)]
    pub speed_unit: Option<SpeedUnit>,
}

impl VehicleRotor {
    /// The unit of its column, stated or by default.
    pub fn unit(&self) -> SpeedUnit {
        self.speed_unit.unwrap_or_else(|| {
            if self.column.trim().to_ascii_lowercase().starts_with("erpm") {
                SpeedUnit::Erpm
            } else {
                SpeedUnit::RadPerSec
            }
        })
    }

    /// The factor from the logged value to rad/s (`None`: eRPM without usable poles).
    pub fn to_rad_per_sec(&self) -> Option<f32> {
        let rpm = 2.0 * core::f32::consts::PI / 60.0;
        match self.unit() {
            SpeedUnit::RadPerSec => Some(1.0),
            SpeedUnit::Rpm => Some(rpm),
            SpeedUnit::Erpm => {
                let pairs = self.poles.filter(|&p| p >= 2)? as f32 / 2.0;
                Some(rpm / pairs)
            }
        }
    }
}

/// A vehicle file, checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Vehicle {
    /// Where it was read from.
    pub path: PathBuf,
    /// Its rotors, in the file's order.
    pub rotors: Vec<VehicleRotor>,
    /// The same, as the core takes them.
    core: Rotors,
    /// Each rotor's factor from the logged value to rad/s.
    factors: Vec<f32>,
}

/// Why a vehicle file is refused.
#[derive(Clone, Debug, PartialEq)]
pub struct VehicleError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for VehicleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.message)
    }
}

impl std::error::Error for VehicleError {}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(default)]
    rotor: Vec<VehicleRotor>,
}

impl Vehicle {
    /// Reads and checks the vehicle file at `path`.
    pub fn load(path: &Path) -> Result<Self, VehicleError> {
        let text = std::fs::read_to_string(path).map_err(|e| VehicleError {
            path: path.to_path_buf(),
            message: format!("cannot read it: {e}"),
        })?;
        Self::parse(path, &text)
    }

    /// Checks the vehicle file `text` (read from `path`, for messages).
    pub fn parse(path: &Path, text: &str) -> Result<Self, VehicleError> {
        let fail = |message: String| VehicleError {
            path: path.to_path_buf(),
            message,
        };
        let file: File = toml::from_str(text).map_err(|e| fail(e.to_string()))?;
        Self::checked(path, file.rotor)
    }

    /// The same rotors with every inertia multiplied by `k`: their ratios are kept, which is
    /// all `inertia calibrate` takes from them (it identifies each throw with the rotors
    /// scaled to a unit inertia, then calibrates the common scale). Checked again: a `k`
    /// that leaves an inertia zero, negative or not finite is refused.
    pub fn scaled(&self, k: f32) -> Result<Self, VehicleError> {
        let rotors = self
            .rotors
            .iter()
            .map(|r| VehicleRotor {
                inertia_kg_m2: r.inertia_kg_m2 * k,
                ..r.clone()
            })
            .collect();
        Self::checked(&self.path, rotors)
    }

    /// Checks the rotors read from `path` (for messages).
    fn checked(path: &Path, rotors: Vec<VehicleRotor>) -> Result<Self, VehicleError> {
        let fail = |message: String| VehicleError {
            path: path.to_path_buf(),
            message,
        };
        if rotors.is_empty() {
            return Err(fail("no [[rotor]] table".into()));
        }
        if rotors.len() > MAX_ROTORS {
            return Err(fail(format!(
                "{} rotors: at most {MAX_ROTORS}",
                rotors.len()
            )));
        }
        for (i, r) in rotors.iter().enumerate() {
            let earlier = rotors.get(..i).unwrap_or(&[]);
            if earlier.iter().any(|o| o.name == r.name) {
                return Err(fail(format!("rotor {:?} is listed twice", r.name)));
            }
            let same_column =
                |o: &&VehicleRotor| o.column.trim().eq_ignore_ascii_case(r.column.trim());
            if let Some(o) = earlier.iter().find(same_column) {
                return Err(fail(format!(
                    "rotors {:?} and {:?} both read column {:?}",
                    o.name, r.name, r.column
                )));
            }
            if r.to_rad_per_sec().is_none() {
                return Err(fail(format!(
                    "rotor {:?}: its column is in eRPM and needs `poles` (at least 2)",
                    r.name
                )));
            }
        }
        let core: Vec<Rotor> = rotors
            .iter()
            .map(|r| Rotor::new(r.inertia_kg_m2, r.axis))
            .collect();
        let core = Rotors::new(&core).map_err(|e| {
            let name = |i: u8| rotors.get(usize::from(i)).map_or("?", |r| r.name.as_str());
            fail(match e {
                RotorError::TooMany => format!("more than {MAX_ROTORS} rotors"),
                RotorError::Inertia(i) => format!(
                    "rotor {:?}: inertia_kg_m2 must be positive and finite",
                    name(i)
                ),
                RotorError::Axis(i) => format!(
                    "rotor {:?}: axis must be a unit vector (length 1 within {AXIS_UNIT_TOLERANCE})",
                    name(i)
                ),
            })
        })?;
        let factors = rotors
            .iter()
            .map(|r| r.to_rad_per_sec().unwrap_or(f32::NAN))
            .collect();
        Ok(Vehicle {
            path: path.to_path_buf(),
            rotors,
            core,
            factors,
        })
    }

    /// The columns to read, in the file's order.
    pub fn columns(&self) -> Vec<String> {
        self.rotors.iter().map(|r| r.column.clone()).collect()
    }

    /// The rotors' names, in the file's order.
    pub fn names(&self) -> Vec<String> {
        self.rotors.iter().map(|r| r.name.clone()).collect()
    }

    /// The rotors as the core takes them.
    pub fn core_rotors(&self) -> Rotors {
        self.core
    }

    /// The momentum (R1), kg m^2/s, of the speeds as logged (the file's order and units).
    pub fn momentum(&self, logged: &[f32]) -> [f32; 3] {
        let mut w = [0.0f32; MAX_ROTORS];
        for ((o, &v), &k) in w.iter_mut().zip(logged).zip(&self.factors) {
            *o = v * k;
        }
        self.core.momentum(&w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vehicle, String> {
        Vehicle::parse(Path::new("v.toml"), text).map_err(|e| e.message)
    }

    const PYRAMID: &str = r#"
[[rotor]]
name = "rw1"
column = "rw1_rad_s"
inertia_kg_m2 = 2.387e-5
axis = [0.5736, 0.0, 0.8192]

[[rotor]]
name = "rw2"
column = "rw2_rpm"
inertia_kg_m2 = 2.387e-5
axis = [-0.5736, 0.0, 0.8192]
speed_unit = "rpm"

[[rotor]]
name = "fly"
column = "eRPM[2]"
inertia_kg_m2 = 1.689e-6
axis = [0.0, 0.0, -1.0]
poles = 14
"#;

    #[test]
    fn reads_the_relied_upon_form() {
        let v = parse(PYRAMID).unwrap();
        assert_eq!(v.rotors.len(), 3);
        assert_eq!(v.columns(), ["rw1_rad_s", "rw2_rpm", "eRPM[2]"]);
        assert_eq!(v.rotors[2].unit(), SpeedUnit::Erpm);
        // rw1 at 100 rad/s, rw2 at 955 rpm (100 rad/s), the flywheel at 7000 eRPM.
        let h = v.momentum(&[100.0, 954.929_7, 7000.0]);
        let fly = 1.689e-6 * 7000.0 * 2.0 * core::f32::consts::PI / 60.0 / 7.0;
        assert!(h[0].abs() < 1e-8, "{h:?}");
        assert!(
            (h[2] - (2.0 * 2.387e-3 * 0.8192 - fly)).abs() < 1e-7,
            "{h:?}"
        );
    }

    /// Scaled, every inertia (and so the momentum) is multiplied by the factor, the rest
    /// kept; a factor that leaves an inertia not positive is refused with the rotor named.
    #[test]
    fn scaled_keeps_the_ratios() {
        let v = parse(PYRAMID).unwrap();
        let s = v.scaled(0.5).unwrap();
        for (a, b) in v.rotors.iter().zip(&s.rotors) {
            assert_eq!(b.inertia_kg_m2, a.inertia_kg_m2 * 0.5);
            assert_eq!((&a.name, &a.column, a.axis), (&b.name, &b.column, b.axis));
        }
        let speeds = [100.0, 954.929_7, 7000.0];
        let (h, hs) = (v.momentum(&speeds), s.momentum(&speeds));
        for k in 0..3 {
            assert!(
                (hs[k] - 0.5 * h[k]).abs() <= 1e-6 * h[k].abs().max(1e-9),
                "{h:?} {hs:?}"
            );
        }
        let e = v.scaled(0.0).unwrap_err().message;
        assert!(e.contains("\"rw1\": inertia_kg_m2 must be positive"), "{e}");
    }

    #[test]
    fn refuses_what_is_wrong_with_the_rotor_named() {
        let one = |extra: &str| {
            format!(
                "[[rotor]]\nname = \"a\"\ncolumn = \"c\"\ninertia_kg_m2 = 1e-4\naxis = [1.0, 0.0, 0.0]\n{extra}"
            )
        };
        assert!(parse(&one("")).is_ok());
        let e = parse(&one("[[rotor]]\nname = \"a\"\ncolumn = \"d\"\ninertia_kg_m2 = 1e-4\naxis = [0.0, 1.0, 0.0]\n")).unwrap_err();
        assert!(e.contains("\"a\" is listed twice"), "{e}");
        let e = parse(&one("[[rotor]]\nname = \"b\"\ncolumn = \"C\"\ninertia_kg_m2 = 1e-4\naxis = [0.0, 1.0, 0.0]\n")).unwrap_err();
        assert!(e.contains("both read column"), "{e}");
        let e = parse(&one("[[rotor]]\nname = \"b\"\ncolumn = \"d\"\ninertia_kg_m2 = 0.0\naxis = [0.0, 1.0, 0.0]\n")).unwrap_err();
        assert!(e.contains("\"b\": inertia_kg_m2 must be positive"), "{e}");
        let e = parse(&one("[[rotor]]\nname = \"b\"\ncolumn = \"d\"\ninertia_kg_m2 = -1e-4\naxis = [0.0, 1.0, 0.0]\n")).unwrap_err();
        assert!(e.contains("positive"), "{e}");
        let e = parse(&one("[[rotor]]\nname = \"b\"\ncolumn = \"d\"\ninertia_kg_m2 = 1e-4\naxis = [0.0, 0.9, 0.0]\n")).unwrap_err();
        assert!(e.contains("\"b\": axis must be a unit vector"), "{e}");
        let e = parse(&one("[[rotor]]\nname = \"b\"\ncolumn = \"erpm_b\"\ninertia_kg_m2 = 1e-4\naxis = [0.0, 1.0, 0.0]\n")).unwrap_err();
        assert!(e.contains("needs `poles`"), "{e}");
        let e = parse(&one("spin = 3\n")).unwrap_err();
        assert!(e.contains("unknown field"), "{e}");
        let e = parse("[[rotor]]\nname = \"a\"\ninertia_kg_m2 = 1e-4\naxis = [1.0, 0.0, 0.0]\n")
            .unwrap_err();
        assert!(e.contains("missing field `column`"), "{e}");
        assert!(parse("").unwrap_err().contains("no [[rotor]]"));
        let nine: String = (0..9)
            .map(|i| format!("[[rotor]]\nname = \"r{i}\"\ncolumn = \"c{i}\"\ninertia_kg_m2 = 1e-4\naxis = [1.0, 0.0, 0.0]\n"))
            .collect();
        assert!(parse(&nine).unwrap_err().contains("at most 8"));
    }
}
