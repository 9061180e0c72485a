use super::*;
use crate::identify::EstimateJson;

/// A body with products of inertia (one of them negative), kg m^2: principal moments about
/// 2.0e-4, 2.9e-4 and 3.6e-4.
const J: [[f32; 3]; 3] = [
    [2.4e-4, -1.2e-5, 3.0e-6],
    [-1.2e-5, 1.5e-4, 8.0e-6],
    [3.0e-6, 8.0e-6, 3.1e-4],
];

fn estimate(tensor: Option<[[f32; 3]; 3]>, status: &str) -> EstimateJson {
    EstimateJson {
        start_s: 1.0,
        end_s: 1.7,
        samples: 1400,
        status: status.into(),
        a_source: "Tensor".into(),
        tensor_status: status.into(),
        tensor_uncertainty: "Noise".into(),
        tensor_usable: status == "Converged",
        tensor_method: "OutputError".into(),
        model: "Full".into(),
        tensor_kg_m2: tensor,
        tensor_std_kg_m2: tensor.map(|t| t.map(|r| r.map(|x| x.abs() * 1e-3 + 1e-8))),
        tensor_cov_kg2_m4: None,
        tensor_normalized: Some([[0.4, 0.0, 0.0], [0.0, 0.25, 0.0], [0.0, 0.0, 0.35]]),
        tensor_normalized_std: None,
        a: Some([-0.6, 0.3, 0.4]),
        std_a: Some([1e-3; 3]),
        principal_moments: None,
        principal_axes: None,
        residual_ratio: 1.0,
        excitation: 1.0,
    }
}

fn report(tensor: Option<[[f32; 3]; 3]>, status: &str) -> Report {
    Report {
        input: "sim--throw.bbl (blackbox)".into(),
        log_samples: 1400,
        rate_hz: 2000.0,
        noise_std: 2e-3,
        gyro_bias: [0.0; 3],
        gyro_bias_measured: false,
        free_flight_detection: false,
        rotor_momentum_quantum: None,
        gravity_gradient: false,
        throws: vec![estimate(tensor, status)],
        pooled: estimate(tensor, status),
        warnings: Vec::new(),
        fed_runs: Vec::new(),
        trace: None,
        gyro_scale: None,
        gyro_scale_factor: None,
        clock_scale_factor: None,
        gyro_grid: None,
        gyro_lsb: None,
        gyro_bias_walk_rad_s_per_sqrt_s: None,
    }
}

fn opts(format: ExportFormat, mass: Option<f64>) -> ExportOptions {
    ExportOptions {
        format,
        mass_kg: mass,
        com_m: None,
        force: false,
    }
}

#[test]
fn eigenvalues_of_a_rotated_diagonal_matrix_are_its_diagonal() {
    // R diag(1, 2, 4) R^T with R a rotation by 0.3 rad about z then 0.5 rad about x.
    let d = [1.0, 2.0, 4.0];
    let (c, s) = (0.3f64.cos(), 0.3f64.sin());
    let rz = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
    let (c, s) = (0.5f64.cos(), 0.5f64.sin());
    let rx = [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]];
    let r: [[f64; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| rx[i][k] * rz[k][j]).sum()));
    let a: [[f64; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| (0..3).map(|k| r[i][k] * d[k] * r[j][k]).sum())
    });
    let m = eigenvalues(&a);
    for i in 0..3 {
        assert!((m[i] - d[i]).abs() < 1e-12, "{m:?}");
    }
    assert_eq!(
        eigenvalues(&[[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]]),
        [2.0; 3]
    );
}

#[test]
fn a_rigid_body_passes_and_its_moments_are_given() {
    let m = check_tensor(&J).unwrap();
    assert!(m[0] > 0.0 && m[0] <= m[1] && m[1] <= m[2], "{m:?}");
    let trace = f64::from(J[0][0]) + f64::from(J[1][1]) + f64::from(J[2][2]);
    assert!((m.iter().sum::<f64>() - trace).abs() < 1e-12 * trace.max(1.0));
    // A thin plate reaches the triangle's equality: still a rigid body.
    check_tensor(&[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]).unwrap();
}

#[test]
fn no_rigid_body_is_refused() {
    let mut nan = J;
    nan[1][2] = f32::NAN;
    assert_eq!(check_tensor(&nan), Err(InvalidTensor::NotFinite));
    let mut skew = J;
    skew[0][1] = 1.2e-5;
    assert!(matches!(
        check_tensor(&skew),
        Err(InvalidTensor::NotSymmetric { entry: (0, 1), .. })
    ));
    let negative = [[1.0, 0.0, 0.0], [0.0, -0.5, 0.0], [0.0, 0.0, 1.0]];
    assert!(matches!(
        check_tensor(&negative),
        Err(InvalidTensor::NotPositiveDefinite(_))
    ));
    // Positive diagonal, but the products make it indefinite.
    let indefinite = [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    assert!(matches!(
        check_tensor(&indefinite),
        Err(InvalidTensor::NotPositiveDefinite(_))
    ));
    let triangle = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.5]];
    let e = check_tensor(&triangle).unwrap_err();
    assert!(matches!(e, InvalidTensor::TriangleInequality(_)));
    assert!(e.to_string().contains("triangle inequality"), "{e}");
}

#[test]
fn urdf_writes_the_matrix_entries_without_negating_them() {
    let text = export(
        &report(Some(J), "Converged"),
        &opts(ExportFormat::Urdf, Some(0.25)),
    )
    .unwrap()
    .text;
    assert!(text.contains("<mass value=\"0.25\"/>"), "{text}");
    assert!(
        text.contains(
            "<inertia ixx=\"0.00024\" ixy=\"-0.000012\" ixz=\"0.000003\" iyy=\"0.00015\" \
             iyz=\"0.000008\" izz=\"0.00031\"/>"
        ),
        "{text}"
    );
    // No centre of mass: at the IMU, and said so.
    assert!(
        text.contains("<origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>"),
        "{text}"
    );
    assert!(text.contains("Centre of mass not known"), "{text}");
    // The input's `--` cannot end the comment early.
    assert!(text.contains("sim- -throw.bbl"), "{text}");
    let mut o = opts(ExportFormat::Urdf, Some(0.25));
    o.com_m = Some([0.01, -0.002, 0.0]);
    let text = export(&report(Some(J), "Converged"), &o).unwrap().text;
    assert!(
        text.contains("<origin xyz=\"0.01 -0.002 0\" rpy=\"0 0 0\"/>"),
        "{text}"
    );
    assert!(!text.contains("Centre of mass not known"), "{text}");
}

#[test]
fn sdf_and_px4_carry_the_same_entries() {
    let r = report(Some(J), "Converged");
    let sdf = export(&r, &opts(ExportFormat::Sdf, Some(0.25)))
        .unwrap()
        .text;
    assert!(sdf.contains("<sdf version=\"1.9\">"), "{sdf}");
    assert!(sdf.contains("<mass>0.25</mass>"), "{sdf}");
    assert!(sdf.contains("<pose>0 0 0 0 0 0</pose>"), "{sdf}");
    assert!(sdf.contains("<ixy>-0.000012</ixy>"), "{sdf}");
    let px4 = export(&r, &opts(ExportFormat::Px4, Some(0.25)))
        .unwrap()
        .text;
    for line in [
        "param set VM_MASS 0.25",
        "param set VM_INERTIA_XX 0.00024",
        "param set VM_INERTIA_XY -0.000012",
        "param set VM_INERTIA_XZ 0.000003",
        "param set VM_INERTIA_YY 0.00015",
        "param set VM_INERTIA_YZ 0.000008",
        "param set VM_INERTIA_ZZ 0.00031",
        "param set SIH_MASS 0.25",
        "param set SIH_IXX 0.00024",
        "param set SIH_IXY -0.000012",
        "param set SIH_IXZ 0.000003",
        "param set SIH_IYY 0.00015",
        "param set SIH_IYZ 0.000008",
        "param set SIH_IZZ 0.00031",
        "# <inertial>",
        "#     <ixy>-0.000012</ixy>",
    ] {
        assert!(px4.lines().any(|l| l == line), "{line:?} missing:\n{px4}");
    }
    // Every line a comment or a parameter.
    assert!(px4.lines().all(|l| l.starts_with('#')
        || l.starts_with("param set SIH_")
        || l.starts_with("param set VM_")));
    // A name with a line break stays in its comment.
    let mut r = r;
    r.input = "a\nparam set X 1".into();
    let px4 = export(&r, &opts(ExportFormat::Px4, Some(0.25)))
        .unwrap()
        .text;
    assert!(!px4.lines().any(|l| l.starts_with("param set X")), "{px4}");
}

#[test]
fn json_is_the_report_as_written() {
    let r = report(Some(J), "Converged");
    let e = export(&r, &opts(ExportFormat::Json, None)).unwrap();
    assert_eq!(e.text, serde_json::to_string_pretty(&r).unwrap());
    assert!(e.warnings.is_empty());
    // Up to scale is fine for JSON (the normalised tensor is checked).
    export(&report(None, "Converged"), &opts(ExportFormat::Json, None)).unwrap();
    assert_eq!(
        export(&r, &opts(ExportFormat::Json, Some(1.0))),
        Err(ExportError::NotForJson)
    );
}

#[test]
fn an_untrusted_status_needs_force() {
    let r = report(Some(J), "ModelMismatch");
    for format in [ExportFormat::Urdf, ExportFormat::Json] {
        let mass = format.is_physical().then_some(0.25);
        let e = export(&r, &opts(format, mass)).unwrap_err();
        assert_eq!(e, ExportError::Untrusted("ModelMismatch".into()));
        assert!(e.to_string().contains("--force"), "{e}");
        let mut o = opts(format, mass);
        o.force = true;
        let done = export(&r, &o).unwrap();
        assert_eq!(done.warnings.len(), 1);
        assert!(
            done.warnings[0].contains("ModelMismatch"),
            "{:?}",
            done.warnings
        );
    }
}

#[test]
fn force_does_not_pass_an_invalid_tensor() {
    let mut o = opts(ExportFormat::Sdf, Some(0.25));
    o.force = true;
    let bad = [[1e-4, 0.0, 0.0], [0.0, 1e-4, 0.0], [0.0, 0.0, 3e-4]];
    for status in ["Converged", "Converging"] {
        assert!(matches!(
            export(&report(Some(bad), status), &o),
            Err(ExportError::Invalid(InvalidTensor::TriangleInequality(_)))
        ));
    }
}

#[test]
fn physical_formats_need_a_mass_and_the_tensor_in_kg_m2() {
    for format in [ExportFormat::Urdf, ExportFormat::Sdf, ExportFormat::Px4] {
        let r = report(Some(J), "Converged");
        assert_eq!(
            export(&r, &opts(format, None)),
            Err(ExportError::NoMass(format))
        );
        assert_eq!(
            check_options(&opts(format, None), true),
            Err(ExportError::NoMass(format))
        );
        assert!(matches!(
            export(&r, &opts(format, Some(-1.0))),
            Err(ExportError::BadMass(_))
        ));
        assert_eq!(
            check_options(&opts(format, Some(1.0)), false),
            Err(ExportError::UpToScale(format))
        );
        assert_eq!(
            export(&report(None, "Converged"), &opts(format, Some(1.0))),
            Err(ExportError::UpToScale(format))
        );
        let mut o = opts(format, Some(1.0));
        o.com_m = Some([0.0, f64::NAN, 0.0]);
        assert!(matches!(
            check_options(&o, true),
            Err(ExportError::BadCom(_))
        ));
    }
    check_options(&opts(ExportFormat::Json, None), false).unwrap();
}

#[test]
fn formats_parse_by_name() {
    for f in [
        ExportFormat::Urdf,
        ExportFormat::Sdf,
        ExportFormat::Px4,
        ExportFormat::Json,
    ] {
        assert_eq!(f.name().parse::<ExportFormat>(), Ok(f));
        assert_eq!(f.name().to_uppercase().parse::<ExportFormat>(), Ok(f));
    }
    assert!("mjcf".parse::<ExportFormat>().is_err());
}

#[test]
fn xml_comments_stay_comments() {
    assert_eq!(xml_comment("a -- b"), "<!-- a - - b -->");
    assert_eq!(xml_comment("a---b-"), "<!-- a- - -b-  -->");
    assert!(!xml_comment("----")
        .trim_start_matches("<!--")
        .trim_end_matches("-->")
        .contains("--"));
}
