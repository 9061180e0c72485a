//! A minimal Betaflight blackbox writer for the tests: header lines and intra frames only
//! (`I interval:1`), every field with predictor 0, the time and iteration unsigned
//! variable-byte encoded, the rest signed (zig-zag) variable-byte encoded.

/// One frame: time (us), gyro (log units), rotor (`eRPM[0]`: eRPM / 100).
pub struct Frame {
    pub time_us: u64,
    pub gyro: [i64; 3],
    pub erpm: Option<u64>,
}

fn unsigned_vb(mut n: u64, out: &mut Vec<u8>) {
    loop {
        let b = (n & 0x7f) as u8;
        n >>= 7;
        if n == 0 {
            out.push(b);
            return;
        }
        out.push(b | 0x80);
    }
}

fn signed_vb(n: i64, out: &mut Vec<u8>) {
    unsigned_vb(((n << 1) ^ (n >> 63)) as u64, out);
}

/// The log's bytes: `extra` header lines (`(name, value)`, e.g. the gyro filters) after the
/// fixed ones; `revision` the firmware revision; a rotor field when the first frame has one.
pub fn blackbox(revision: &str, extra: &[(&str, String)], frames: &[Frame]) -> Vec<u8> {
    let rotor = frames.first().is_some_and(|f| f.erpm.is_some());
    let mut names = vec![
        "loopIteration",
        "time",
        "gyroADC[0]",
        "gyroADC[1]",
        "gyroADC[2]",
    ];
    let mut signed = vec!["0", "0", "1", "1", "1"];
    let mut encoding = vec!["1", "1", "0", "0", "0"];
    let mut p_pred = vec!["6", "2", "1", "1", "1"];
    let mut p_enc = vec!["9", "0", "0", "0", "0"];
    if rotor {
        names.push("eRPM[0]");
        signed.push("0");
        encoding.push("1");
        p_pred.push("1");
        p_enc.push("0");
    }
    let zeros = vec!["0"; names.len()];
    let mut lines: Vec<(String, String)> = [
        (
            "Product",
            "Blackbox flight data recorder by Nicholas Sherlock",
        ),
        ("Data version", "2"),
        ("I interval", "1"),
        ("P interval", "1/1"),
        ("Firmware type", "Cleanflight"),
        ("Firmware revision", revision),
    ]
    .iter()
    .map(|(k, v)| (k.to_string(), v.to_string()))
    .collect();
    for (k, v) in [
        ("Field I name", names.join(",")),
        ("Field I signed", signed.join(",")),
        ("Field I predictor", zeros.join(",")),
        ("Field I encoding", encoding.join(",")),
        ("Field P predictor", p_pred.join(",")),
        ("Field P encoding", p_enc.join(",")),
        ("Field S name", "flightModeFlags".into()),
        ("Field S signed", "0".into()),
        ("Field S predictor", "0".into()),
        ("Field S encoding", "1".into()),
        ("motor_pwm_protocol", "6".into()),
        ("gyro_scale", "0x3f800000".into()),
    ] {
        lines.push((k.to_string(), v));
    }
    lines.extend(extra.iter().map(|(k, v)| (k.to_string(), v.clone())));
    let mut out = Vec::new();
    for (k, v) in &lines {
        out.extend_from_slice(format!("H {k}:{v}\n").as_bytes());
    }
    for (i, f) in frames.iter().enumerate() {
        out.push(b'I');
        unsigned_vb(i as u64, &mut out);
        unsigned_vb(f.time_us, &mut out);
        for g in f.gyro {
            signed_vb(g, &mut out);
        }
        if rotor {
            unsigned_vb(f.erpm.unwrap_or(0), &mut out);
        }
    }
    out
}
