//! `inertia`: the product's host tool. See `inertia --help` and the README.
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use inertia::close_loop;
use inertia::export::{ExportError, ExportFormat, ExportOptions};
use inertia::identify::{
    identify_source, parse_axis, IdentifyError, IdentifyOptions, Progress, Report, Rotor, RotorHold,
};
use inertia::vehicle::Vehicle;
use inertia::{read, AccelUnit, Format, GyroUnit, ReadOptions, TimeUnit};

mod replay;
mod telemetry;

#[derive(Parser)]
#[command(
    name = "inertia",
    version,
    about = "Inertia of a rigid body from the flight logs you already have"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Find the free flights in a log and identify the inertia tensor (per throw and pooled).
    Identify(IdentifyArgs),
    /// Write the per-sample inputs `identify` gives its pipeline as a replay file for the
    /// firmware under QEMU (`scripts/run.sh --log`).
    ExportReplay(ExportReplayArgs),
    /// Decode a captured telemetry stream (the firmware's UART) to JSON lines.
    Telemetry(TelemetryArgs),
    /// Rotor inertia from throws of the board alone and bolted to a proof body; the board's
    /// tensor and centre of mass; an unknown object by difference.
    Calibrate(inertia::calibrate::CalibrateArgs),
    /// Close the loop on a gyro log: residual, effect, extended model, error before and after.
    CloseLoop(CloseLoopArgs),
}

#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
struct CloseLoopArgs {
    /// The log: a phyphox export (`Raw Data.csv` or its folder), a CSV `t,wx,wy,wz` (or with
    /// named columns), a blackbox log or a ULog.
    #[arg(long)]
    input: PathBuf,
    /// Free-flight windows (`segment,start,end,keep,comment`; rows with keep false are
    /// skipped); default: a phyphox export's `meta/segments.csv`, else the whole log.
    #[arg(long)]
    segments: Option<PathBuf>,
    /// Input format (phyphox, csv, blackbox, ulog); detected from the content when absent.
    #[arg(long, value_parser = parse_format)]
    format: Option<Format>,
    /// Where to write the JSON result.
    #[arg(long)]
    json: PathBuf,
    /// Directory for the markdown table and SVG plots.
    #[arg(long)]
    plots: Option<PathBuf>,
    /// Reference `a` (comma separated) for the parameter error.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    truth: Option<Vec<f64>>,
    /// Title of the markdown table.
    #[arg(long)]
    title: Option<String>,
    /// Family-wise significance level of each selection round.
    #[arg(long, default_value_t = 1e-3)]
    alpha: f64,
    /// Gyro unit of a CSV: rad/s or deg/s (also confirms rates that look like deg/s).
    #[arg(long, value_parser = parse_gyro_unit)]
    gyro_unit: Option<GyroUnit>,
    /// Time unit of a CSV: s, ms or us (also confirms a time step that looks wrong).
    #[arg(long, value_parser = parse_time_unit)]
    time_unit: Option<TimeUnit>,
    /// Accelerometer unit of a CSV: m/s^2, g or mg (the specific force, gravity included).
    #[arg(long, value_parser = parse_accel_unit)]
    accel_unit: Option<AccelUnit>,
    /// With a rotor, the base model becomes the inertia tensor with the rotor momentum
    /// (products of inertia and the rotor exact), on the free flights `identify` finds (or the
    /// segments given). With --vehicle, the tensor with the vehicle's rotors, and the gravity
    /// gradient, a residual magnetic dipole, a body torque and a drifting gyro bias as the
    /// candidates (docs/close-loop.md).
    #[command(flatten)]
    rotor: RotorArgs,
}

impl CloseLoopArgs {
    /// The report's title: `--title`, else the input's path.
    fn title(&self) -> String {
        self.title
            .clone()
            .unwrap_or_else(|| self.input.display().to_string())
    }
}

/// Writes `value` as pretty JSON to `path`.
fn write_json(path: &std::path::Path, value: &impl serde::Serialize) -> Result<(), String> {
    let json = serde_json::to_string_pretty(value).map_err(|e| e.to_string())?;
    std::fs::write(path, json).map_err(|e| format!("writing {}: {e}", path.display()))
}

/// The rotor options `identify`, `export-replay` and `close-loop` share.
#[derive(clap::Args)]
struct RotorArgs {
    /// Rotor (flywheel) inertia about its axis, kg m^2: makes the tensor absolute.
    #[arg(long)]
    rotor_inertia: Option<f32>,
    /// Rotor axis in the gyro frame: x, y, z, -x, -y or -z (direction of positive speed).
    #[arg(long, value_parser = parse_axis, allow_hyphen_values = true)]
    rotor_axis: Option<[f32; 3]>,
    /// Motor poles, to turn eRPM into mechanical speed.
    #[arg(long)]
    rotor_poles: Option<u32>,
    /// Use the rotor speed exactly as logged (sample and hold). Default: as logged when the
    /// telemetry updates fast (most changes within 5 ms), interpolated when it is slow.
    #[arg(long, conflicts_with = "rotor_unhold")]
    rotor_raw: bool,
    /// Interpolate the telemetry's held steps (each new value taken as the speed at the middle
    /// of the hold it ends), whatever its update rate.
    #[arg(long)]
    rotor_unhold: bool,
    /// A vehicle file (TOML, `[[rotor]]` tables: name, column, inertia_kg_m2, axis, optional
    /// poles and speed_unit) describing any number of rotors, each with its log column: makes
    /// the tensor absolute. See docs/formats.md.
    #[arg(long, conflicts_with_all = ["rotor_inertia", "rotor_axis", "rotor_poles"])]
    vehicle: Option<PathBuf>,
}

impl RotorArgs {
    /// `--rotor-raw`, `--rotor-unhold` or the automatic choice.
    fn hold(&self) -> RotorHold {
        if self.rotor_raw {
            RotorHold::Raw
        } else if self.rotor_unhold {
            RotorHold::Unhold
        } else {
            RotorHold::Auto
        }
    }
}

impl RotorArgs {
    /// The vehicle file, read and checked, when given.
    fn vehicle(&self) -> Result<Option<Vehicle>, String> {
        self.vehicle
            .as_deref()
            .map(Vehicle::load)
            .transpose()
            .map_err(|e| e.to_string())
    }

    /// The rotor columns a reading needs (the vehicle file's).
    fn columns(vehicle: Option<&Vehicle>) -> Vec<String> {
        vehicle.map(Vehicle::columns).unwrap_or_default()
    }

    /// Those columns' rotors' names, for messages.
    fn names(vehicle: Option<&Vehicle>) -> Vec<String> {
        vehicle.map(Vehicle::names).unwrap_or_default()
    }

    /// The rotor, when given: `--rotor-inertia` (positive) and `--rotor-axis` together.
    fn rotor(&self) -> Result<Option<Rotor>, String> {
        match (self.rotor_inertia, self.rotor_axis) {
            (None, None) => Ok(None),
            (Some(j), Some(axis)) => {
                if !(j.is_finite() && j > 0.0) {
                    return Err(format!("--rotor-inertia {j} must be positive"));
                }
                Ok(Some(Rotor {
                    inertia: j,
                    axis,
                    poles: self.rotor_poles,
                }))
            }
            _ => Err("--rotor-inertia and --rotor-axis go together".into()),
        }
    }
}

fn parse_format(s: &str) -> Result<Format, String> {
    match s.to_ascii_lowercase().as_str() {
        "phyphox" => Ok(Format::Phyphox),
        "csv" => Ok(Format::Csv),
        "blackbox" => Ok(Format::Blackbox),
        "ulog" => Ok(Format::Ulog),
        o => Err(format!("unknown format {o:?} (phyphox|csv|blackbox|ulog)")),
    }
}

#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
struct IdentifyArgs {
    /// The log: Betaflight/INDIflight blackbox, PX4 ULog, phyphox export or CSV (detected
    /// from the content). Given more than once (`--input A --input B ...`: throws of one body
    /// in several logs), each log is identified on its own and their tensors are pooled by
    /// their covariances, the spread between them checked against those (needs a rotor:
    /// the tensor in kg m^2; the JSON then holds `pooled`, `spread` and each log's report).
    #[arg(long, required = true)]
    input: Vec<PathBuf>,
    #[command(flatten)]
    rotor: RotorArgs,
    /// CSV of hand-chosen free flights, one `start_s,end_s` per line (log time).
    #[arg(long)]
    segments: Option<PathBuf>,
    /// Gyro unit of a CSV: rad/s or deg/s.
    #[arg(long, value_parser = parse_gyro_unit)]
    gyro_unit: Option<GyroUnit>,
    /// Time unit of a CSV: s, ms or us.
    #[arg(long, value_parser = parse_time_unit)]
    time_unit: Option<TimeUnit>,
    /// Accelerometer unit of a CSV: m/s^2, g or mg (the specific force, gravity included).
    #[arg(long, value_parser = parse_accel_unit)]
    accel_unit: Option<AccelUnit>,
    /// Gyro white noise, rad/s (estimated from the data when absent).
    #[arg(long)]
    noise_std: Option<f32>,
    /// Where to write the JSON report.
    #[arg(long)]
    json: PathBuf,
    /// Directory for plots (SVG).
    #[arg(long)]
    plots: Option<PathBuf>,
    /// The gyro's scale-factor tolerance per axis, percent (1 sigma; a MEMS gyro's is typically
    /// 0.5-1 uncalibrated): the log is identified three more times with one axis scaled by it,
    /// and `gyro_scale` in the JSON gives how far that moves the estimate (the data cannot show a
    /// scale-factor error, and the standard deviations are otherwise the noise's only).
    #[arg(long)]
    gyro_scale_tolerance: Option<f32>,
    /// The gyro's scale factor `k` (it reads `k` times the true rate): `scale` of an `inertia
    /// calibrate --scale-of gyro` report of the same board. The readings and the full scale
    /// are divided by it before anything else.
    #[arg(long, value_parser = parse_scale_factor)]
    gyro_scale: Option<f64>,
    /// The log's clock scale factor `k` (it runs `k` times true time): `scale` of an `inertia
    /// calibrate` report (`scale_of` clock) of the same board. The log's times, and those of
    /// --segments, are divided by it before anything else; the report's times are that
    /// clock's.
    #[arg(long, value_parser = parse_scale_factor)]
    clock_scale: Option<f64>,
    /// Also write the pooled tensor for a simulator or flight stack: urdf, sdf (1.9), px4
    /// (parameters `VM_*` and `SIH_*`, the SDF inertial in comments) or json (the report, as
    /// --json writes it). Refused unless the tensor is a rigid body's and `Converged` (see
    /// --force); urdf, sdf and px4 need --mass and a rotor (the tensor in kg m^2). A refused
    /// export exits with 3, the --json report written all the same.
    #[arg(long, value_name = "FORMAT", value_parser = parse_export_format, requires = "export_out")]
    export: Option<ExportFormat>,
    /// Where to write the --export file.
    #[arg(long, value_name = "PATH", requires = "export")]
    export_out: Option<PathBuf>,
    /// The body's mass, kg, for --export urdf, sdf and px4.
    #[arg(long, value_name = "KG", requires = "export")]
    mass: Option<f64>,
    /// The centre of mass's position from the IMU in the gyro axes, m (X,Y,Z; `inertia
    /// calibrate` gives it), for --export urdf, sdf and px4; without it the inertial frame is
    /// put at the IMU and the file says so.
    #[arg(
        long,
        value_name = "X,Y,Z",
        value_delimiter = ',',
        allow_hyphen_values = true,
        requires = "export"
    )]
    com: Option<Vec<f64>>,
    /// Export a tensor whose status is not `Converged` (with a warning). A tensor that is no
    /// rigid body's is refused all the same.
    #[arg(long, requires = "export")]
    force: bool,
}

fn parse_export_format(s: &str) -> Result<ExportFormat, String> {
    s.parse()
}

/// The `--export` options of `identify`, checked before the log is read (`rotor_known`:
/// `--rotor-inertia` given); `None` without `--export`.
fn export_options(args: &IdentifyArgs, rotor_known: bool) -> Result<Option<ExportOptions>, String> {
    let Some(format) = args.export else {
        return Ok(None);
    };
    let com_m = match &args.com {
        None => None,
        Some(v) => Some(
            <[f64; 3]>::try_from(v.as_slice())
                .map_err(|_| ExportError::BadCom(v.clone()).to_string())?,
        ),
    };
    let opts = ExportOptions {
        format,
        mass_kg: args.mass,
        com_m,
        force: args.force,
    };
    inertia::export::check_options(&opts, rotor_known).map_err(|e| e.to_string())?;
    Ok(Some(opts))
}

fn parse_gyro_unit(s: &str) -> Result<GyroUnit, String> {
    match s {
        "rad/s" | "rad_s" | "rads" => Ok(GyroUnit::RadPerSec),
        "deg/s" | "deg_s" | "dps" => Ok(GyroUnit::DegPerSec),
        o => Err(format!("{o:?}: use rad/s or deg/s")),
    }
}

fn parse_accel_unit(s: &str) -> Result<AccelUnit, String> {
    match s {
        "m/s^2" | "m/s2" | "m_s2" | "mps2" => Ok(AccelUnit::MetersPerSec2),
        "g" => Ok(AccelUnit::G),
        "mg" | "milli-g" => Ok(AccelUnit::MilliG),
        o => Err(format!("{o:?}: use m/s^2, g or mg")),
    }
}

fn parse_time_unit(s: &str) -> Result<TimeUnit, String> {
    match s {
        "s" => Ok(TimeUnit::S),
        "ms" => Ok(TimeUnit::Ms),
        "us" | "µs" => Ok(TimeUnit::Us),
        o => Err(format!("{o:?}: use s, ms or us")),
    }
}

/// The free-flight windows of `--segments`: either `start_s,end_s` per line, or a table with
/// named `start` and `end` columns (and optional `segment`, `keep`, `comment`), the format of a
/// phyphox export's `meta/segments.csv` that `close-loop` reads (rows with `keep` false
/// skipped). Overlapping windows are refused (a sample would be fed twice).
fn parse_segments(path: &PathBuf) -> Result<Vec<(f64, f64)>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let header = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'));
    let named = header.is_some_and(|h| {
        let cols: Vec<String> = h
            .split([',', ';', '\t'])
            .map(|c| c.trim().trim_matches('"').to_ascii_lowercase())
            .collect();
        cols.iter().any(|c| c == "start") && cols.iter().any(|c| c == "end")
    });
    if named {
        let segs = inertia::readers::phyphox::read_segments(path).map_err(|e| e.to_string())?;
        for w in segs.windows(2) {
            if w[1].start < w[0].end {
                return Err(format!(
                    "{}: segment {} ({}..{} s) overlaps segment {} ({}..{} s)",
                    path.display(),
                    w[1].label,
                    w[1].start,
                    w[1].end,
                    w[0].label,
                    w[0].start,
                    w[0].end
                ));
            }
        }
        if segs.is_empty() {
            return Err(format!("{}: no segment kept", path.display()));
        }
        return Ok(segs.iter().map(|s| (s.start, s.end)).collect());
    }
    let mut out = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let l = line.trim();
        if l.is_empty() || l.starts_with('#') || l.chars().next().is_some_and(|c| c.is_alphabetic())
        {
            continue;
        }
        let mut it = l.split([',', ';', ' ', '\t']).filter(|s| !s.is_empty());
        let (Some(a), Some(b)) = (it.next(), it.next()) else {
            return Err(format!(
                "{}:{}: expected start_s,end_s",
                path.display(),
                ln + 1
            ));
        };
        let (Ok(a), Ok(b)) = (a.parse::<f64>(), b.parse::<f64>()) else {
            return Err(format!("{}:{}: not two numbers", path.display(), ln + 1));
        };
        if !(a.is_finite() && b.is_finite() && b > a) {
            return Err(format!(
                "{}:{}: need finite start < end",
                path.display(),
                ln + 1
            ));
        }
        if out.iter().any(|&(s, e): &(f64, f64)| a < e && b > s) {
            return Err(format!(
                "{}:{}: overlaps an earlier segment",
                path.display(),
                ln + 1
            ));
        }
        out.push((a, b));
    }
    if out.is_empty() {
        return Err(format!("{}: no segment", path.display()));
    }
    Ok(out)
}

/// The rotor options (both or neither) and the noise option of `identify` and
/// `export-replay`, checked the same way for both: a replay must be refused exactly when
/// `identify` would refuse.
fn rotor_and_noise(rotor: &RotorArgs, noise_std: Option<f32>) -> Result<Option<Rotor>, String> {
    let rotor = rotor.rotor()?;
    if let Some(s) = noise_std {
        if !(s.is_finite() && s > 0.0) {
            return Err(format!("--noise-std {s} must be positive"));
        }
    }
    Ok(rotor)
}

/// The progress bar of `identify`: on a terminal only (stderr), and only for a log large
/// enough to take a while.
struct Bar(Option<indicatif::ProgressBar>);

impl Bar {
    /// Files below this size are done before a bar would tell anything.
    const MIN_BYTES: u64 = 8 << 20;

    fn new(input: &std::path::Path) -> Self {
        let big = std::fs::metadata(input).is_ok_and(|m| m.len() >= Self::MIN_BYTES);
        if !(big && std::io::stderr().is_terminal()) {
            return Bar(None);
        }
        let b = indicatif::ProgressBar::new(1000);
        b.set_style(
            indicatif::ProgressStyle::with_template("{msg:>11} [{bar:40}] {percent:>3}% {eta}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        Bar(Some(b))
    }

    fn clear(&self) {
        if let Some(b) = &self.0 {
            b.finish_and_clear();
        }
    }
}

impl Progress for Bar {
    fn stage(&mut self, name: &str) {
        if let Some(b) = &self.0 {
            b.set_message(name.to_string());
            b.set_position(0);
            b.reset_eta();
        }
    }

    fn update(&mut self, fraction: f32) {
        if let Some(b) = &self.0 {
            b.set_position((fraction.clamp(0.0, 1.0) * 1000.0) as u64);
        }
    }
}

/// A scale factor for `identify --gyro-scale` and `--clock-scale`: as `calibrate --scale`
/// takes a given one.
fn parse_scale_factor(s: &str) -> Result<f64, String> {
    match inertia::calibrate::parse_scale(s)? {
        inertia::calibrate::ScaleFactor::Given(k) => Ok(k),
        inertia::calibrate::ScaleFactor::Auto => {
            Err("`auto` is for calibrate; give the scale factor its report states".into())
        }
    }
}

fn run_identify(args: IdentifyArgs) -> Result<ExitCode, String> {
    if let Some(tol) = args.gyro_scale_tolerance {
        if !(tol.is_finite() && tol > 0.0 && tol < 50.0) {
            return Err(format!(
                "--gyro-scale-tolerance {tol}: a percentage above 0 and below 50"
            ));
        }
    }
    let rotor = rotor_and_noise(&args.rotor, args.noise_std)?;
    let vehicle = args.rotor.vehicle()?;
    let export = export_options(&args, rotor.is_some() || vehicle.is_some())?;
    let clock = args.clock_scale.unwrap_or(1.0);
    let segments = args
        .segments
        .as_ref()
        .map(parse_segments)
        .transpose()?
        .map(|s| s.into_iter().map(|(a, b)| (a / clock, b / clock)).collect());
    let opts = ReadOptions {
        gyro_unit: args.gyro_unit,
        time_unit: args.time_unit,
        accel_unit: args.accel_unit,
        rotor_columns: RotorArgs::columns(vehicle.as_ref()),
        rotor_names: RotorArgs::names(vehicle.as_ref()),
    };
    let iopts = IdentifyOptions {
        rotor,
        vehicle,
        segments,
        noise_std: args.noise_std,
        rotor_hold: args.rotor.hold(),
        trace: args.plots.is_some(),
    };
    let input = match args.input.as_slice() {
        [one] => one.clone(),
        many => return run_identify_many(many, &args, &opts, &iopts),
    };
    let (src, report) = open_and_identify(&input, &opts, &iopts, &args)?;
    let mut report = report.map_err(|e| e.to_string())?;
    if let Some(tol) = args.gyro_scale_tolerance {
        eprintln!("identifying the log three more times, one gyro axis scaled by {tol} % each");
        // The estimate stands without it: a re-identification that fails is a warning.
        match inertia::identify::scale_systematic(&*src, &iopts, &report, tol) {
            Ok(sys) => {
                if let (Some(s), Some(n)) = (sys.std_a, report.pooled.std_a) {
                    if (0..3).any(|i| s[i] > 3.0 * n[i]) {
                        report.warnings.push(format!(
                            "a {tol} % gyro scale tolerance moves a by {s:?} (1 sigma), more \
                             than three times the noise's standard deviation {n:?}: see \
                             gyro_scale.total_std_a"
                        ));
                    }
                }
                report.gyro_scale = Some(sys);
            }
            Err(e) => report.warnings.push(format!(
                "--gyro-scale-tolerance: the log scaled by it could not be identified ({e}); \
                 no gyro_scale in the report"
            )),
        }
    }
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    let text = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?;
    std::fs::write(&args.json, text).map_err(|e| format!("{}: {e}", args.json.display()))?;
    if let (Some(dir), Some(trace)) = (&args.plots, &report.trace) {
        inertia::plots::identify_plots(trace, &report, dir).map_err(|e| e.to_string())?;
    }
    let p = &report.pooled;
    eprintln!(
        "{} free flight(s), {} samples pooled: status {}, a = {:?} +- {:?}{}",
        report.throws.len(),
        p.samples,
        p.status,
        p.a,
        p.std_a,
        p.tensor_kg_m2
            .map(|t| format!(", J = {t:?} kg m^2"))
            .unwrap_or_default()
    );
    if p.a.is_none() {
        eprintln!("error: the data cannot determine the tensor ({})", p.status);
        if export.is_some() {
            eprintln!("error: nothing exported");
        }
        return Ok(ExitCode::from(4));
    }
    if let (Some(o), Some(path)) = (&export, &args.export_out) {
        let e = inertia::export::export(&report, o).map_err(|e| e.to_string())?;
        for w in &e.warnings {
            eprintln!("warning: {w}");
        }
        std::fs::write(path, &e.text).map_err(|e| format!("{}: {e}", path.display()))?;
        eprintln!("{} export written to {}", o.format, path.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// A log opened for reading (any format `identify` reads).
type LogSource = Box<dyn inertia::source::Source>;

/// Opens `input` (read through `args`' `--gyro-scale` and `--clock-scale`, when given) and
/// identifies it with a progress bar: the source (for further readings) and the
/// identification's outcome; an error when the log cannot be opened.
fn open_and_identify(
    input: &std::path::Path,
    opts: &ReadOptions,
    iopts: &IdentifyOptions,
    args: &IdentifyArgs,
) -> Result<(LogSource, Result<Report, IdentifyError>), String> {
    let mut src = inertia::source::open(input, opts).map_err(|e| e.to_string())?;
    if args.gyro_scale.is_some() || args.clock_scale.is_some() {
        src = Box::new(inertia::source::MappedSource::rescaled(
            src,
            args.gyro_scale.unwrap_or(1.0) as f32,
            args.clock_scale.unwrap_or(1.0),
        ));
    }
    let mut bar = Bar::new(input);
    let mut report = identify_source(&*src, iopts, &mut bar);
    bar.clear();
    if let Ok(r) = &mut report {
        r.gyro_scale_factor = args.gyro_scale;
        r.clock_scale_factor = args.clock_scale;
    }
    Ok((src, report))
}

/// `inertia identify` with several `--input`: each log identified on its own, their tensors
/// pooled ([`inertia::pool`]). Exit 3 for a log that cannot be read or gives no tensor in
/// kg m^2.
fn run_identify_many(
    inputs: &[PathBuf],
    args: &IdentifyArgs,
    opts: &ReadOptions,
    iopts: &IdentifyOptions,
) -> Result<ExitCode, String> {
    if args.export.is_some() || args.plots.is_some() || args.gyro_scale_tolerance.is_some() {
        return Err(
            "--export, --plots and --gyro-scale-tolerance take one --input (identify the logs \
             one by one for them)"
                .into(),
        );
    }
    let mut reports = Vec::new();
    for input in inputs {
        let (_, report) = open_and_identify(input, opts, iopts, args)?;
        reports.push(report.map_err(|e| format!("{}: {e}", input.display()))?);
    }
    let pooled = inertia::pool::pool(reports)?;
    for w in &pooled.warnings {
        eprintln!("warning: {w}");
    }
    write_json(&args.json, &pooled)?;
    let p = &pooled.pooled;
    eprintln!(
        "{} logs, {} free flight(s), {} samples: tensor status {}, spread chi2/dof {:.2}, J = {:?} \
         +- {:?} kg m^2",
        pooled.inputs.len(),
        pooled.throws.len(),
        p.samples,
        p.tensor_status,
        pooled.spread.ratio,
        p.tensor_kg_m2.unwrap_or_default(),
        p.tensor_std_kg_m2.unwrap_or_default()
    );
    Ok(ExitCode::SUCCESS)
}

/// `inertia close-loop`: exit 3 for unusable input (unreadable, wrong units, bad segments), 4
/// when the data cannot identify `a`.
fn run_close_loop(args: CloseLoopArgs) -> Result<ExitCode, String> {
    if args.truth.as_ref().is_some_and(|t| t.len() != 3) {
        return Err("--truth needs three numbers a1,a2,a3".into());
    }
    if !(args.alpha > 0.0 && args.alpha < 1.0) {
        return Err(format!("--alpha {} must be in (0, 1)", args.alpha));
    }
    let vehicle = args.rotor.vehicle()?;
    let units = ReadOptions {
        gyro_unit: args.gyro_unit,
        time_unit: args.time_unit,
        accel_unit: args.accel_unit,
        rotor_columns: RotorArgs::columns(vehicle.as_ref()),
        rotor_names: RotorArgs::names(vehicle.as_ref()),
    };
    if let Some(vehicle) = vehicle {
        return run_close_loop_vehicle(&args, vehicle, &units);
    }
    if let Some(rotor) = args.rotor.rotor()? {
        return run_close_loop_tensor(&args, rotor, &units);
    }
    if args.rotor.rotor_poles.is_some() || args.rotor.rotor_raw || args.rotor.rotor_unhold {
        return Err(
            "--rotor-poles, --rotor-raw and --rotor-unhold go with --rotor-inertia and --rotor-axis"
                .into(),
        );
    }
    let (log, warnings) =
        close_loop::load(&args.input, args.format, args.segments.as_deref(), &units)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    let opts = close_loop::Options {
        alpha: args.alpha,
        truth: args.truth.as_ref().map(|t| [t[0], t[1], t[2]]),
        ..Default::default()
    };
    let an = match close_loop::analyse(&log, &opts) {
        Ok(an) => an,
        Err(e) => {
            eprintln!("error: {}: {e}", args.input.display());
            return Ok(ExitCode::from(4));
        }
    };
    if !an.skipped_segments.is_empty() {
        eprintln!(
            "warning: segments with too few samples skipped: {}",
            an.skipped_segments.join(", ")
        );
    }
    if !an.spikes.is_empty() {
        let at: Vec<String> = an.spikes.iter().map(|k| format!("{:.3} s", k.t)).collect();
        eprintln!(
            "warning: {} isolated spike(s) replaced by the mean of their neighbours: {}",
            an.spikes.len(),
            at.join(", ")
        );
    }
    write_json(&args.json, &an)?;
    let title = args.title();
    if let Some(dir) = &args.plots {
        write_report_dir(dir, &close_loop::markdown(&an, &title), |d| {
            close_loop::plots(&an, d, &title)
        })?;
    }
    println!("{}", close_loop::summary_line(&an));
    Ok(ExitCode::SUCCESS)
}

/// `inertia close-loop` with a rotor: the tensor as the base model
/// ([`close_loop::analyse_tensor`]). Exit 3 for unusable input, 4 when the free flights
/// cannot determine the tensor.
fn run_close_loop_tensor(
    args: &CloseLoopArgs,
    rotor: Rotor,
    units: &ReadOptions,
) -> Result<ExitCode, String> {
    let rec = read(&args.input, units).map_err(|e| e.to_string())?;
    // The same refusals as the torque-free close-loop: rates that look like deg/s, a time step
    // that looks like ms or us, unless the unit was declared.
    let omega: Vec<[f64; 3]> = rec.gyro.iter().map(|w| w.map(f64::from)).collect();
    close_loop::check_series_units(
        &rec.t,
        &omega,
        units.gyro_unit.is_some(),
        units.time_unit.is_some(),
    )
    .map_err(|e| format!("{}: {e}", args.input.display()))?;
    for w in &rec.warnings {
        eprintln!("warning: {w}");
    }
    // Both segment formats, as `identify` takes them (the flights are identify's).
    let segments = args.segments.as_ref().map(parse_segments).transpose()?;
    let opts = close_loop::TensorOptions {
        rotor,
        alpha: args.alpha,
        block_s: 0.01,
        segments,
        rotor_hold: args.rotor.hold(),
    };
    let an = match close_loop::analyse_tensor(&rec, &opts) {
        Ok(an) => an,
        Err(e) => return Ok(loop_error_exit(&args.input, &e)),
    };
    write_json(&args.json, &an)?;
    let title = args.title();
    if let Some(dir) = &args.plots {
        write_report_dir(dir, &close_loop::tensor_markdown(&an, &title), |d| {
            close_loop::tensor_plots(&an, d, &title)
        })?;
    }
    println!("{}", close_loop::tensor_summary_line(&an));
    Ok(ExitCode::SUCCESS)
}

/// Says `close-loop`'s error on `input` and gives its exit code: 3 for unusable input, 4 when
/// the free flights cannot determine what was asked.
fn loop_error_exit(input: &std::path::Path, e: &close_loop::LoopError) -> ExitCode {
    eprintln!("error: {}: {e}", input.display());
    ExitCode::from(match e {
        close_loop::LoopError::Input(_) => 3,
        close_loop::LoopError::Data(_) => 4,
    })
}

/// `summary.md` (the markdown `summary`) and the plots `plots` draws, in `dir` (created).
fn write_report_dir(
    dir: &std::path::Path,
    summary: &str,
    plots: impl FnOnce(&std::path::Path) -> anyhow::Result<()>,
) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    std::fs::write(dir.join("summary.md"), summary)
        .map_err(|e| format!("writing {}: {e}", dir.display()))?;
    plots(dir).map_err(|e| e.to_string())
}

/// `inertia close-loop --vehicle`: the tensor with the vehicle file's rotor momentum as the
/// base model, candidates from the environment (gravity gradient, a residual magnetic dipole)
/// and the gyro ([`close_loop::analyse_vehicle`]). Exit 3 for unusable input, 4 when the free
/// flights cannot determine the tensor.
fn run_close_loop_vehicle(
    args: &CloseLoopArgs,
    vehicle: Vehicle,
    units: &ReadOptions,
) -> Result<ExitCode, String> {
    if args.rotor.rotor_raw || args.rotor.rotor_unhold {
        return Err(
            "--rotor-raw and --rotor-unhold go with --rotor-inertia and --rotor-axis (a vehicle \
             file's speeds are taken as logged)"
                .into(),
        );
    }
    let rec = read(&args.input, units).map_err(|e| e.to_string())?;
    // Rates that look like deg/s are refused as elsewhere; a spacecraft log may be slow, so
    // only a median step above 10 s looks like a time column in ms or us.
    let omega: Vec<[f64; 3]> = rec.gyro.iter().map(|w| w.map(f64::from)).collect();
    close_loop::check_series_units_up_to(
        &rec.t,
        &omega,
        units.gyro_unit.is_some(),
        units.time_unit.is_some(),
        close_loop::MAX_MEDIAN_STEP_VEHICLE_S,
    )
    .map_err(|e| format!("{}: {e}", args.input.display()))?;
    for w in &rec.warnings {
        eprintln!("warning: {w}");
    }
    let segments = args.segments.as_ref().map(parse_segments).transpose()?;
    let opts = close_loop::VehicleOptions {
        vehicle,
        alpha: args.alpha,
        segments,
        block_s: None,
    };
    let an = match close_loop::analyse_vehicle(&rec, &opts) {
        Ok(an) => an,
        Err(e) => return Ok(loop_error_exit(&args.input, &e)),
    };
    write_json(&args.json, &an)?;
    let title = args.title();
    if let Some(dir) = &args.plots {
        write_report_dir(dir, &close_loop::vehicle_markdown(&an, &title), |d| {
            close_loop::vehicle_plots(&an, d, &title)
        })?;
    }
    println!("{}", close_loop::vehicle_summary_line(&an));
    Ok(ExitCode::SUCCESS)
}

fn run_calibrate(args: inertia::calibrate::CalibrateArgs) -> Result<ExitCode, String> {
    let rep = inertia::calibrate::run(&args)?;
    for s in &rep.skipped {
        eprintln!("warning: {} ({}) left out: {}", s.source, s.group, s.reason);
    }
    for w in &rep.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(dir) = &args.plots {
        inertia::plots::calibrate_plot(&rep, dir).map_err(|e| e.to_string())?;
    }
    let text = serde_json::to_string_pretty(&rep).map_err(|e| e.to_string())?;
    std::fs::write(&args.json, text).map_err(|e| format!("{}: {e}", args.json.display()))?;
    eprintln!(
        "rotor inertia {:.4e} +- {:.1e} kg m^2; board tensor {:?} kg m^2; board throws' spread {:?}",
        rep.rotor_inertia_kg_m2,
        rep.rotor_inertia_std_kg_m2.unwrap_or(f64::NAN),
        rep.board_tensor_kg_m2,
        rep.board_spread
    );
    match rep.scale_std {
        Some(sd) => eprintln!(
            "{} scale {:.4} +- {:.1e} ({})",
            rep.scale_of.name(),
            rep.scale,
            sd,
            rep.scale_source
        ),
        None => eprintln!(
            "{} scale {:.4} ({})",
            rep.scale_of.name(),
            rep.scale,
            rep.scale_source
        ),
    }
    let at_rest: Vec<f64> = rep
        .throws
        .iter()
        .filter_map(|t| t.accel_at_rest_g)
        .collect();
    if let (Some(lo), Some(hi)) = (
        at_rest.iter().copied().reduce(f64::min),
        at_rest.iter().copied().reduce(f64::max),
    ) {
        eprintln!(
            "accelerometer at rest {lo:.4}-{hi:.4} g over {} throws (--accel-scale {})",
            at_rest.len(),
            rep.accel_scale
        );
    }
    if let Some(v) = &rep.vehicle {
        eprintln!(
            "rotors' scale {:.4} +- {:.1e} over {}'s inertias:",
            v.scale,
            v.scale_std.unwrap_or(f64::NAN),
            v.file
        );
        for r in &v.rotors {
            eprintln!(
                "  rotor {:?} inertia {:.4e} +- {:.1e} kg m^2",
                r.name,
                r.inertia_kg_m2,
                r.inertia_std_kg_m2.unwrap_or(f64::NAN)
            );
        }
    }
    if let (Some(l), Some(s)) = (
        rep.object_principal_moments_kg_m2,
        rep.object_principal_moments_std_kg_m2,
    ) {
        eprintln!(
            "object principal moments {:.4e} +- {:.1e}, {:.4e} +- {:.1e}, {:.4e} +- {:.1e} kg m^2",
            l[0], s[0], l[1], s[1], l[2], s[2]
        );
    }
    Ok(ExitCode::SUCCESS)
}

#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
struct ExportReplayArgs {
    /// The log (any format `identify` reads).
    #[arg(long)]
    input: PathBuf,
    #[command(flatten)]
    rotor: RotorArgs,
    /// Gyro unit of a CSV: rad/s or deg/s.
    #[arg(long, value_parser = parse_gyro_unit)]
    gyro_unit: Option<GyroUnit>,
    /// Time unit of a CSV: s, ms or us.
    #[arg(long, value_parser = parse_time_unit)]
    time_unit: Option<TimeUnit>,
    /// Accelerometer unit of a CSV: m/s^2, g or mg (the specific force, gravity included).
    #[arg(long, value_parser = parse_accel_unit)]
    accel_unit: Option<AccelUnit>,
    /// Gyro white noise, rad/s (estimated from the data when absent, as `identify` does).
    #[arg(long)]
    noise_std: Option<f32>,
    /// The replay file to write.
    #[arg(long)]
    out: PathBuf,
}

#[derive(clap::Args)]
struct TelemetryArgs {
    /// The captured byte stream (QEMU's `-serial file:...`, or a UART capture).
    #[arg(long)]
    input: PathBuf,
    /// Also write the last report's estimate (status, a, std_a, tensor_kg_m2, throws,
    /// counters) as a JSON file.
    #[arg(long)]
    final_json: Option<PathBuf>,
}

fn run_export_replay(args: ExportReplayArgs) -> Result<ExitCode, String> {
    let rotor = rotor_and_noise(&args.rotor, args.noise_std)?;
    let vehicle = args.rotor.vehicle()?;
    let opts = ReadOptions {
        gyro_unit: args.gyro_unit,
        time_unit: args.time_unit,
        accel_unit: args.accel_unit,
        rotor_columns: RotorArgs::columns(vehicle.as_ref()),
        rotor_names: RotorArgs::names(vehicle.as_ref()),
    };
    let mut rec = read(&args.input, &opts).map_err(|e| e.to_string())?;
    // The readings `identify` fits: moved to their counts' centres where it takes them as
    // truncated toward zero (`Report::gyro_grid`, (Q1) of `inertia::grid`), said in the header
    // so that the firmware's estimate is at most `ModelMismatch` as `identify`'s is.
    let mut centred = false;
    if inertia::grid::detect(&inertia::source::RecordingSource::new(&rec))
        .map_err(|e| e.to_string())?
        .is_some()
    {
        let iopts = IdentifyOptions {
            rotor,
            vehicle: vehicle.clone(),
            segments: None,
            noise_std: args.noise_std,
            rotor_hold: args.rotor.hold(),
            trace: false,
        };
        if let Ok(report) = inertia::identify::identify(&rec, &iopts) {
            if let Some(g) = report.gyro_grid.filter(|g| g.centred) {
                centred = true;
                inertia::grid::centre_readings(&mut rec.gyro, g.lsb_rad_s);
            }
        }
    }
    let rotors = match &vehicle {
        Some(v) => replay::Rotors::Vehicle(v),
        None => replay::Rotors::Flag(rotor),
    };
    let e = replay::export(
        &rec,
        rotors,
        args.noise_std,
        args.rotor.hold(),
        centred,
        &args.out,
    )?;
    eprintln!(
        "{}: {} samples at {} Hz, noise {} rad/s, accelerometer {}, orbit (gravity gradient) {}",
        args.out.display(),
        e.samples,
        e.rate_hz,
        e.noise_std,
        e.with_accel,
        e.orbit
    );
    Ok(ExitCode::SUCCESS)
}

fn run_telemetry(args: TelemetryArgs) -> Result<ExitCode, String> {
    let (n, errors) = telemetry::run(&args.input, args.final_json.as_deref())?;
    eprintln!("{n} reports decoded, {errors} frames did not decode");
    Ok(if n == 0 {
        ExitCode::from(3)
    } else {
        ExitCode::SUCCESS
    })
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let r = match cli.command {
        Command::Identify(a) => run_identify(a),
        Command::Calibrate(a) => run_calibrate(a),
        Command::ExportReplay(a) => run_export_replay(a),
        Command::Telemetry(a) => run_telemetry(a),
        Command::CloseLoop(a) => run_close_loop(a),
    };
    match r {
        Ok(c) => c,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(3)
        }
    }
}
