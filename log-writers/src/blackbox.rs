//! A minimal Betaflight blackbox log: the header lines a decoder needs and intra frames only
//! (`I interval:1`), every field with predictor 0, the time and the iteration unsigned
//! variable-byte encoded, the rest signed (zig-zag) variable-byte encoded. The main frame holds
//! `loopIteration`, `time`, `gyroADC[0..2]`, and when the first frame has them
//! `accSmooth[0..2]` and `eRPM[0]`.

/// One main frame, in the log's units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Time, microseconds.
    pub time_us: u64,
    /// `gyroADC`, in the firmware's unit (deg/s, or tenths with `blackbox_high_resolution`).
    pub gyro: [i64; 3],
    /// `accSmooth`, counts (`acc_1G` per g).
    pub accel: Option<[i64; 3]>,
    /// `eRPM[0]`: electrical RPM / 100.
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

/// The log's bytes: `revision` the firmware revision (`"Betaflight 4.4.2 (abc) STM32F405"`),
/// `extra` header lines (`(name, value)`: the gyro filters, `blackbox_high_resolution`, ...)
/// after the fixed ones, and the frames.
pub fn blackbox(revision: &str, extra: &[(&str, String)], frames: &[Frame]) -> Vec<u8> {
    let accel = frames.first().is_some_and(|f| f.accel.is_some());
    let rotor = frames.first().is_some_and(|f| f.erpm.is_some());
    // (name, signed, I encoding, P predictor, P encoding)
    let mut fields = vec![
        ("loopIteration", "0", "1", "6", "9"),
        ("time", "0", "1", "2", "0"),
        ("gyroADC[0]", "1", "0", "1", "0"),
        ("gyroADC[1]", "1", "0", "1", "0"),
        ("gyroADC[2]", "1", "0", "1", "0"),
    ];
    if accel {
        fields.extend([
            ("accSmooth[0]", "1", "0", "1", "0"),
            ("accSmooth[1]", "1", "0", "1", "0"),
            ("accSmooth[2]", "1", "0", "1", "0"),
        ]);
    }
    if rotor {
        fields.push(("eRPM[0]", "0", "1", "1", "0"));
    }
    let col = |k: usize| {
        fields
            .iter()
            .map(|f| [f.0, f.1, f.2, f.3, f.4][k])
            .collect::<Vec<_>>()
            .join(",")
    };
    let zeros = vec!["0"; fields.len()].join(",");
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
        ("Field I name", col(0)),
        ("Field I signed", col(1)),
        ("Field I predictor", zeros),
        ("Field I encoding", col(2)),
        ("Field P predictor", col(3)),
        ("Field P encoding", col(4)),
        ("Field S name", "flightModeFlags".into()),
        ("Field S signed", "0".into()),
        ("Field S predictor", "0".into()),
        ("Field S encoding", "1".into()),
        ("motor_pwm_protocol", "6".into()),
        ("gyro_scale", "0x3f800000".into()),
        ("acc_1G", "2048".into()),
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
        if accel {
            for a in f.accel.unwrap_or([0; 3]) {
                signed_vb(a, &mut out);
            }
        }
        if rotor {
            unsigned_vb(f.erpm.unwrap_or(0), &mut out);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variable_bytes() {
        let mut v = Vec::new();
        unsigned_vb(300, &mut v);
        assert_eq!(v, [0xac, 0x02]);
        v.clear();
        signed_vb(-2, &mut v);
        assert_eq!(v, [3]);
        v.clear();
        signed_vb(2, &mut v);
        assert_eq!(v, [4]);
    }
}
