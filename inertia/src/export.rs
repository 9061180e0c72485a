//! `inertia identify --export`: the pooled tensor written for simulators and flight stacks
//! (URDF, SDF, PX4 parameters) or as the JSON report.
//!
//! Before anything is written the tensor is checked ([`check_tensor`]): finite, symmetric,
//! positive definite, and its principal moments satisfy the triangle inequalities (each at
//! most the sum of the other two), as every rigid body's do. URDF, SDF and PX4 take the tensor
//! in kg m^2, which only a known rotor momentum gives (`--rotor-inertia`): a tensor known up
//! to scale is refused for them. A tensor whose status is not `Converged` is refused unless
//! [`ExportOptions::force`] is set (then written, with a warning); an invalid tensor is refused
//! whatever the options.
//!
//! # Frames and conventions
//!
//! The tensor is about the centre of mass, in the log's gyro axes (the frame the report's
//! `tensor_kg_m2` is in). The exported link's frame is those axes with its origin at the IMU;
//! the inertial frame is at the centre of mass ([`ExportOptions::com_m`], else at the IMU,
//! which the file says) with the same axes.
//!
//! URDF's `ixx ixy ixz iyy iyz izz` (and SDF's elements of the same names, and PX4's
//! `VM_INERTIA_XX` ... and `SIH_IXX` ...) are the entries of the symmetric inertia matrix `J`
//! (the one of `L = J w`) on and above its diagonal: `ixy = J_xy = -sum m x y`, not the product
//! of inertia `sum m x y` that some texts call `I_xy`. The report's `tensor_kg_m2` is that
//! matrix, so its entries are written as they are, never negated.

use std::fmt;
use std::str::FromStr;

use crate::identify::Report;

/// The status a tensor must have to be exported without [`ExportOptions::force`].
pub const TRUSTED_STATUS: &str = "Converged";

/// Relative allowance, on the largest entry, for the difference of `J_ij` and `J_ji`: `f32`
/// rounding only.
const SYMMETRY_TOLERANCE: f64 = 1e-6;

/// Relative allowance, on the trace, for a principal moment exceeding the sum of the other two
/// (a flat body reaches equality): the `f32` tensor's rounding only.
const TRIANGLE_TOLERANCE: f64 = 1e-6;

/// What `--export` writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportFormat {
    /// A URDF `<robot>` with one `<link>` and its `<inertial>`.
    Urdf,
    /// An SDF (version 1.9) `<model>` with one `<link>` and its `<inertial>`.
    Sdf,
    /// PX4 parameters: `param set` lines for the modules whose parameters hold a vehicle's mass
    /// and inertia (`angular_velocity_controller`'s `VM_*`, the simulator in hardware's
    /// `SIH_*`), and the SDF inertial of a Gazebo model in comments (see [`px4`]).
    Px4,
    /// The JSON report, byte for byte what `--json` writes.
    Json,
}

impl ExportFormat {
    /// The name `--export` takes.
    pub fn name(self) -> &'static str {
        match self {
            ExportFormat::Urdf => "urdf",
            ExportFormat::Sdf => "sdf",
            ExportFormat::Px4 => "px4",
            ExportFormat::Json => "json",
        }
    }

    /// True for the formats that need the tensor in kg m^2 and a mass (all but JSON).
    pub fn is_physical(self) -> bool {
        !matches!(self, ExportFormat::Json)
    }
}

impl fmt::Display for ExportFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ExportFormat {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "urdf" => Ok(ExportFormat::Urdf),
            "sdf" => Ok(ExportFormat::Sdf),
            "px4" => Ok(ExportFormat::Px4),
            "json" => Ok(ExportFormat::Json),
            o => Err(format!("unknown export format {o:?} (urdf|sdf|px4|json)")),
        }
    }
}

/// What to export and with what.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportOptions {
    /// The format.
    pub format: ExportFormat,
    /// The body's mass, kg (`--mass`): needed by URDF, SDF and PX4, which the log cannot give.
    pub mass_kg: Option<f64>,
    /// The centre of mass's position from the IMU in the gyro axes, m (`--com`; `inertia
    /// calibrate` reports it as `board_com_from_imu_m`). Unknown to `identify`: without it the
    /// inertial frame is put at the IMU and the file says so.
    pub com_m: Option<[f64; 3]>,
    /// Export a tensor whose status is not [`TRUSTED_STATUS`] (with a warning). An invalid
    /// tensor is refused all the same.
    pub force: bool,
}

/// Why a tensor is no rigid body's ([`check_tensor`]).
#[derive(Clone, Debug, PartialEq)]
pub enum InvalidTensor {
    /// An entry is NaN or infinite.
    NotFinite,
    /// `J_rc` and `J_cr` differ beyond rounding.
    NotSymmetric {
        /// Row and column of the entry above the diagonal.
        entry: (usize, usize),
        /// `J_rc` and `J_cr`.
        values: (f32, f32),
    },
    /// A principal moment is zero or negative (ascending moments given).
    NotPositiveDefinite([f64; 3]),
    /// The largest principal moment exceeds the sum of the other two (ascending moments given).
    TriangleInequality([f64; 3]),
}

impl fmt::Display for InvalidTensor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            InvalidTensor::NotFinite => write!(f, "an entry is not finite"),
            InvalidTensor::NotSymmetric { entry, values } => write!(
                f,
                "it is not symmetric: J[{}][{}] = {} but J[{}][{}] = {}",
                entry.0, entry.1, values.0, entry.1, entry.0, values.1
            ),
            InvalidTensor::NotPositiveDefinite(m) => write!(
                f,
                "it is not positive definite: principal moments {m:?} (every one must be \
                 positive)"
            ),
            InvalidTensor::TriangleInequality(m) => write!(
                f,
                "its principal moments {m:?} violate the triangle inequality: the largest, {}, \
                 exceeds the sum of the other two, {}, which no rigid body's does",
                m[2],
                m[0] + m[1]
            ),
        }
    }
}

/// Why nothing was exported.
#[derive(Clone, Debug, PartialEq)]
pub enum ExportError {
    /// URDF, SDF and PX4 need `--mass`.
    NoMass(ExportFormat),
    /// `--mass` not a positive finite number.
    BadMass(f64),
    /// `--com` not three finite numbers.
    BadCom(Vec<f64>),
    /// `--mass` or `--com` with the JSON export, which is the report and holds neither.
    NotForJson,
    /// URDF, SDF and PX4 need the tensor in kg m^2, which only a known rotor's momentum gives.
    UpToScale(ExportFormat),
    /// The report has no tensor at all.
    NoTensor,
    /// The tensor's status is not [`TRUSTED_STATUS`] and [`ExportOptions::force`] is not set.
    Untrusted(String),
    /// The tensor is no rigid body's.
    Invalid(InvalidTensor),
    /// The report could not be serialised.
    Json(String),
}

impl fmt::Display for ExportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExportError::NoMass(x) => write!(
                f,
                "--export {x} needs the body's mass: give --mass KG (a log cannot tell it)"
            ),
            ExportError::BadMass(m) => write!(f, "--mass {m} must be a positive number of kg"),
            ExportError::BadCom(v) => write!(
                f,
                "--com {v:?}: give the centre of mass from the IMU as three numbers X,Y,Z in m"
            ),
            ExportError::NotForJson => write!(
                f,
                "--export json writes the JSON report, which holds no mass or centre of mass: \
                 --mass and --com go with urdf, sdf and px4"
            ),
            ExportError::UpToScale(x) => write!(
                f,
                "--export {x} needs the tensor in kg m^2, but the pooled estimate has it only \
                 up to scale: only a known rotor's momentum fixes the scale (--rotor-inertia and \
                 --rotor-axis, the rotor's speed changing during the free flights)"
            ),
            ExportError::NoTensor => write!(f, "the pooled estimate has no tensor to export"),
            ExportError::Untrusted(s) => write!(
                f,
                "the pooled tensor's status is {s}, not {TRUSTED_STATUS}: nothing exported \
                 (give --force to export it anyway)"
            ),
            ExportError::Invalid(e) => {
                write!(f, "the pooled tensor is no rigid body's, not exported: {e}")
            }
            ExportError::Json(e) => write!(f, "the JSON report: {e}"),
        }
    }
}

impl std::error::Error for ExportError {}

impl From<InvalidTensor> for ExportError {
    fn from(e: InvalidTensor) -> Self {
        ExportError::Invalid(e)
    }
}

/// The checks of `opts` that need no report: run before the identification, so that a
/// missing `--mass` is said at once. `rotor_known`: `--rotor-inertia` was given (without it
/// the tensor can only be up to scale).
pub fn check_options(opts: &ExportOptions, rotor_known: bool) -> Result<(), ExportError> {
    check_inputs(opts)?;
    if opts.format.is_physical() && !rotor_known {
        return Err(ExportError::UpToScale(opts.format));
    }
    Ok(())
}

/// `--mass` and `--com` as the format wants them.
fn check_inputs(opts: &ExportOptions) -> Result<(), ExportError> {
    if !opts.format.is_physical() {
        if opts.mass_kg.is_some() || opts.com_m.is_some() {
            return Err(ExportError::NotForJson);
        }
        return Ok(());
    }
    let Some(m) = opts.mass_kg else {
        return Err(ExportError::NoMass(opts.format));
    };
    if !(m.is_finite() && m > 0.0) {
        return Err(ExportError::BadMass(m));
    }
    if let Some(c) = opts.com_m {
        if !c.iter().all(|x| x.is_finite()) {
            return Err(ExportError::BadCom(c.to_vec()));
        }
    }
    Ok(())
}

/// Checks that `j` is a rigid body's inertia tensor: finite, symmetric (to `f32` rounding),
/// positive definite, and each principal moment at most the sum of the other two (to rounding:
/// a flat body reaches equality). Gives the principal moments, ascending.
pub fn check_tensor(j: &[[f32; 3]; 3]) -> Result<[f64; 3], InvalidTensor> {
    if !j.iter().flatten().all(|x| x.is_finite()) {
        return Err(InvalidTensor::NotFinite);
    }
    let scale = j
        .iter()
        .flatten()
        .fold(0.0f64, |m, &x| m.max(f64::from(x).abs()));
    for (r, c) in [(0, 1), (0, 2), (1, 2)] {
        let (a, b) = (f64::from(j[r][c]), f64::from(j[c][r]));
        if (a - b).abs() > SYMMETRY_TOLERANCE * scale {
            return Err(InvalidTensor::NotSymmetric {
                entry: (r, c),
                values: (j[r][c], j[c][r]),
            });
        }
    }
    let m = eigenvalues(&symmetrised(j));
    if !m.iter().all(|&x| x.is_finite() && x > 0.0) {
        return Err(InvalidTensor::NotPositiveDefinite(m));
    }
    let trace = m[0] + m[1] + m[2];
    if m[2] > m[0] + m[1] + TRIANGLE_TOLERANCE * trace {
        return Err(InvalidTensor::TriangleInequality(m));
    }
    Ok(m)
}

/// `(J + J^T) / 2` in `f64`.
fn symmetrised(j: &[[f32; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|r| {
        std::array::from_fn(|c| (f64::from(j[r][c]) + f64::from(j[c][r])) / 2.0)
    })
}

/// Eigenvalues of a symmetric 3x3 matrix, ascending: the closed form of the characteristic
/// cubic by the cosine of a third of an angle (`A = q I + p B`, `det B = 2 cos 3 phi`).
fn eigenvalues(a: &[[f64; 3]; 3]) -> [f64; 3] {
    let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    let q = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
    let dev = (a[0][0] - q).powi(2) + (a[1][1] - q).powi(2) + (a[2][2] - q).powi(2) + 2.0 * off;
    let p = (dev / 6.0).sqrt();
    if p == 0.0 || !p.is_finite() {
        return [q; 3];
    }
    let b: [[f64; 3]; 3] = std::array::from_fn(|r| {
        std::array::from_fn(|c| (a[r][c] - if r == c { q } else { 0.0 }) / p)
    });
    let det = b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1])
        - b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0])
        + b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]);
    let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
    let largest = q + 2.0 * p * phi.cos();
    let smallest = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
    let middle = 3.0 * q - largest - smallest;
    let mut m = [smallest, middle, largest];
    m.sort_by(f64::total_cmp);
    m
}

/// A body as the physical formats write it.
#[derive(Clone, Debug, PartialEq)]
pub struct Inertial {
    /// Mass, kg.
    pub mass_kg: f64,
    /// Centre of mass from the IMU in the gyro axes, m; `None` when unknown.
    pub com_m: Option<[f64; 3]>,
    /// The inertia matrix about the centre of mass, gyro axes, kg m^2 (symmetric).
    pub tensor_kg_m2: [[f32; 3]; 3],
    /// Standard deviation of each entry, kg m^2, when the report has them.
    pub tensor_std_kg_m2: Option<[[f32; 3]; 3]>,
    /// The tensor's status in the report.
    pub status: String,
    /// Where it comes from (the report's `input`), for a comment.
    pub source: String,
}

impl Inertial {
    /// The six entries `ixx ixy ixz iyy iyz izz`: the matrix's own entries on and above its
    /// diagonal (URDF's, SDF's and PX4's convention; see the module documentation).
    pub fn six(&self) -> [(&'static str, f32); 6] {
        let j = &self.tensor_kg_m2;
        [
            ("ixx", j[0][0]),
            ("ixy", j[0][1]),
            ("ixz", j[0][2]),
            ("iyy", j[1][1]),
            ("iyz", j[1][2]),
            ("izz", j[2][2]),
        ]
    }

    /// The centre of mass, `0 0 0` when unknown.
    fn xyz(&self) -> String {
        let c = self.com_m.unwrap_or([0.0; 3]);
        format!("{} {} {}", c[0], c[1], c[2])
    }

    /// The comment lines every format starts with (without comment markers).
    fn header(&self) -> Vec<String> {
        let mut v = vec![
            format!(
                "Identified by `inertia identify` from {} (pooled tensor status {}).",
                self.source.replace(char::is_control, " "),
                self.status
            ),
            "Link frame: the log's gyro axes, origin at the IMU. The inertia is about the \
             centre of mass, in those axes, kg m^2."
                .to_string(),
            "ixy, ixz, iyz are the inertia matrix's off-diagonal entries J_xy = -sum m x y \
             (not the products of inertia sum m x y)."
                .to_string(),
        ];
        if let Some(s) = self.tensor_std_kg_m2 {
            v.push(format!(
                "Standard deviations, kg m^2: ixx {} ixy {} ixz {} iyy {} iyz {} izz {}.",
                s[0][0], s[0][1], s[0][2], s[1][1], s[1][2], s[2][2]
            ));
        }
        v
    }

    /// Said where the centre of mass is unknown.
    const NO_COM: &'static str = "Centre of mass not known (identify cannot tell it; its \
                                  option com X,Y,Z gives it): the inertial frame is put at the \
                                  IMU, 0 0 0.";
}

/// Text fit for an XML comment: no `--`, not ending in `-`.
fn xml_comment(s: &str) -> String {
    let mut t = s.replace("--", "- -");
    while t.contains("--") {
        t = t.replace("--", "- -");
    }
    if t.ends_with('-') {
        t.push(' ');
    }
    format!("<!-- {t} -->")
}

/// The URDF: a `<robot>` with one `<link>` whose `<inertial>` has the `<origin>` (the centre of
/// mass; no rotation), the `<mass>` and the `<inertia>`.
///
/// URDF's `<inertia ixx ixy ixz iyy iyz izz>` are the entries of the 3x3 rotational inertia
/// matrix in the inertial frame, the six on and above its diagonal: `ixy` is `J[0][1]`, the
/// matrix's own entry (`-sum m x y` for point masses), as parsers build the matrix
/// `[[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]` from them. The report's tensor is
/// that matrix, so nothing is negated.
pub fn urdf(b: &Inertial) -> String {
    let mut s = String::from("<?xml version=\"1.0\"?>\n");
    for line in b.header() {
        s += &xml_comment(&line);
        s.push('\n');
    }
    s += "<robot name=\"body\">\n  <link name=\"body\">\n    <inertial>\n";
    if b.com_m.is_none() {
        s += &format!("      {}\n", xml_comment(Inertial::NO_COM));
    }
    s += &format!("      <origin xyz=\"{}\" rpy=\"0 0 0\"/>\n", b.xyz());
    s += &format!("      <mass value=\"{}\"/>\n", b.mass_kg);
    let attrs: Vec<String> = b
        .six()
        .iter()
        .map(|(k, v)| format!("{k}=\"{v}\""))
        .collect();
    s += &format!("      <inertia {}/>\n", attrs.join(" "));
    s += "    </inertial>\n  </link>\n</robot>\n";
    s
}

/// The `<inertial>` element of an SDF link, each line indented by `indent`.
fn sdf_inertial(b: &Inertial, indent: &str) -> Vec<String> {
    let mut v = vec![format!("{indent}<inertial>")];
    if b.com_m.is_none() {
        v.push(format!("{indent}  {}", xml_comment(Inertial::NO_COM)));
    }
    v.push(format!("{indent}  <mass>{}</mass>", b.mass_kg));
    v.push(format!("{indent}  <pose>{} 0 0 0</pose>", b.xyz()));
    v.push(format!("{indent}  <inertia>"));
    for (k, x) in b.six() {
        v.push(format!("{indent}    <{k}>{x}</{k}>"));
    }
    v.push(format!("{indent}  </inertia>"));
    v.push(format!("{indent}</inertial>"));
    v
}

/// The SDF (version 1.9): `<sdf><model><link><inertial>` with `<mass>`, `<pose>` (the centre
/// of mass in the link frame, no rotation) and `<inertia>` whose `<ixx>` ... `<izz>` follow
/// URDF's convention: the inertia matrix's entries on and above the diagonal.
pub fn sdf(b: &Inertial) -> String {
    let mut s = String::from("<?xml version=\"1.0\"?>\n");
    for line in b.header() {
        s += &xml_comment(&line);
        s.push('\n');
    }
    s += "<sdf version=\"1.9\">\n  <model name=\"body\">\n    <link name=\"body\">\n";
    for line in sdf_inertial(b, "      ") {
        s += &line;
        s.push('\n');
    }
    s += "    </link>\n  </model>\n</sdf>\n";
    s
}

/// The PX4 parameters, as `param set` lines for the PX4 shell (an airframe file takes them as
/// `param set-default`), in two blocks, each for the module that reads it (a build without the
/// module answers `param set` with "parameter not found"):
///
/// * `VM_MASS` (kg) and `VM_INERTIA_XX`, `VM_INERTIA_XY`, `VM_INERTIA_XZ`, `VM_INERTIA_YY`,
///   `VM_INERTIA_YZ`, `VM_INERTIA_ZZ` (kg m^2), group "Vehicle Model", read by the module
///   `angular_velocity_controller`, an alternative rate controller that outputs torque (the
///   default multicopter rate controller, `mc_rate_control`, takes gains and no inertia);
/// * `SIH_MASS` and `SIH_IXX`, `SIH_IXY`, `SIH_IXZ`, `SIH_IYY`, `SIH_IYZ`, `SIH_IZZ`, read by
///   SIH, PX4's simulator in hardware (module `simulator_sih`).
///
/// Both modules assemble their symmetric inertia matrix from the parameters as they are: the
/// `XY` ones are the matrix's entry, as URDF's `ixy`. Both take the body frame (FRD) with the
/// centre of mass at its origin (`angular_velocity_controller` and SIH have no centre-of-mass
/// parameter). Gazebo SITL models take the SDF inertial of their base link, which follows in
/// comments ([`sdf`]); their base link is FLU, so from FRD axes `ixy`, `ixz` and the pose's
/// `y`, `z` change sign (`J' = R J R^T`, `R = diag(1, -1, -1)`), which the comments say rather
/// than do, the log's axes being whatever its gyro's are.
pub fn px4(b: &Inertial) -> String {
    let mut s = String::new();
    for line in b.header() {
        s += &format!("# {line}\n");
    }
    s += "# The parameters are in the body frame (FRD): the gyro axes above must be FRD for\n\
          # them to apply as they are (a PX4 log's sensor_combined is). Neither module below has\n\
          # a centre-of-mass parameter. A build without a module answers its lines with\n\
          # \"parameter not found\".\n\
          # angular_velocity_controller (an alternative rate controller; the default\n\
          # mc_rate_control takes gains, no inertia):\n";
    s += &format!("param set VM_MASS {}\n", b.mass_kg);
    for (k, x) in b.six() {
        s += &format!("param set VM_INERTIA_{} {x}\n", k[1..].to_ascii_uppercase());
    }
    s += "# SIH, PX4's simulator in hardware (simulator_sih):\n";
    s += &format!("param set SIH_MASS {}\n", b.mass_kg);
    for (k, x) in b.six() {
        s += &format!("param set SIH_{} {x}\n", k.to_ascii_uppercase());
    }
    s += "# Gazebo SITL models take the inertial of the model's base link in its model.sdf\n\
          # (SDF 1.9; link frame as above). Gazebo's base link is FLU: from FRD axes, negate\n\
          # ixy and ixz (y and z reversed) and the pose's y and z.\n";
    for line in sdf_inertial(b, "") {
        s += &format!("# {line}\n");
    }
    s
}

/// The exported text and the warnings to print.
#[derive(Clone, Debug, PartialEq)]
pub struct Exported {
    /// What to write to `--export-out`.
    pub text: String,
    /// Warnings for the user (an untrusted tensor exported with `--force`).
    pub warnings: Vec<String>,
}

/// Exports `report`'s pooled tensor as `opts` asks: `--mass` and `--com` checked, then the
/// status (refused unless [`TRUSTED_STATUS`] or [`ExportOptions::force`]), then the tensor (in
/// kg m^2 for the physical formats; [`check_tensor`]).
pub fn export(report: &Report, opts: &ExportOptions) -> Result<Exported, ExportError> {
    check_inputs(opts)?;
    let p = &report.pooled;
    let mut warnings = Vec::new();
    if p.tensor_status != TRUSTED_STATUS {
        if !opts.force {
            return Err(ExportError::Untrusted(p.tensor_status.clone()));
        }
        warnings.push(format!(
            "--force: exporting a pooled tensor whose status is {}, not {TRUSTED_STATUS}: it is \
             not to be trusted",
            p.tensor_status
        ));
    }
    let write: fn(&Inertial) -> String = match opts.format {
        ExportFormat::Json => {
            let t = p
                .tensor_kg_m2
                .or(p.tensor_normalized)
                .ok_or(ExportError::NoTensor)?;
            check_tensor(&t)?;
            let text = serde_json::to_string_pretty(report)
                .map_err(|e| ExportError::Json(e.to_string()))?;
            return Ok(Exported { text, warnings });
        }
        ExportFormat::Urdf => urdf,
        ExportFormat::Sdf => sdf,
        ExportFormat::Px4 => px4,
    };
    let t = p.tensor_kg_m2.ok_or(ExportError::UpToScale(opts.format))?;
    check_tensor(&t)?;
    let body = Inertial {
        mass_kg: opts.mass_kg.ok_or(ExportError::NoMass(opts.format))?,
        com_m: opts.com_m,
        tensor_kg_m2: std::array::from_fn(|r| std::array::from_fn(|c| (t[r][c] + t[c][r]) / 2.0)),
        tensor_std_kg_m2: p.tensor_std_kg_m2,
        status: p.tensor_status.clone(),
        source: report.input.clone(),
    };
    Ok(Exported {
        text: write(&body),
        warnings,
    })
}

#[cfg(test)]
mod tests;
