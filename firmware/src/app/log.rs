//! The reports as defmt lines.

use super::{Report, SensorStatus};

/// Logs a report as one defmt line (the format the end-to-end check and `scripts/run.sh`
/// read).
#[cfg(feature = "defmt")]
pub fn log_report(r: &Report) {
    if r.saturated_recent > 0 {
        defmt::warn!(
            "{=u32} saturated gyro samples (at the clip level) since the last report; {=u32} in all",
            r.saturated_recent,
            r.counters.saturated
        );
    }
    if r.sensor == SensorStatus::Failed {
        defmt::warn!("sensor failed: no sample for over 150 ms; estimates held");
    }
    let (q2, q3) = r
        .ratios
        .map_or((f32::NAN, f32::NAN), |q| (q.a2_over_a1, q.a3_over_a1));
    let c = &r.counters;
    let (p, f) = (&r.a_paper, &r.a_refined);
    defmt::info!(
        "t={=f32}s a_paper=[{=f32}, {=f32}, {=f32}] {} a_refined=[{=f32}, {=f32}, {=f32}] {} A2/A1={=f32} A3/A1={=f32} consistency={=f32} samples={=u32} skipped={=u32} bus_errors={=u32} invalid={=u32} timeouts={=u32} implausible={=u32} missed={=u32} wrong_id={=u32} stalled={=u32} reinits={=u32} reinit_failures={=u32} saturated={=u32} accel_saturated={=u32} held_out={=u32} sensor={}",
        r.t,
        p[0],
        p[1],
        p[2],
        r.convergence_paper,
        f[0],
        f[1],
        f[2],
        r.convergence_refined,
        q2,
        q3,
        r.consistency,
        c.samples,
        c.skipped,
        c.bus_errors,
        c.invalid,
        c.timeouts,
        c.implausible,
        c.missed,
        c.wrong_id,
        c.stalled,
        c.reinits,
        c.reinit_failures,
        c.saturated,
        c.accel_saturated,
        c.held_out,
        r.sensor
    );
}

/// Logs the free-flight pipeline's tensor estimate of a report as one defmt line, `none` for
/// what is not determined; with `bits`, also the IEEE-754 bits of `a`, `std_a` and `J` (the
/// replay check compares them with the host tool's).
#[cfg(feature = "defmt")]
pub fn log_tensor(r: &Report, bits: bool) {
    let t = &r.tensor;
    defmt::info!(
        "tensor status={} throws={=u32} fed={=u32} not_fed={=u32} in_free_flight={=bool} uncertainty={} usable={=bool}",
        t.status,
        t.throws,
        t.fed,
        t.not_fed,
        t.in_free_flight,
        t.uncertainty,
        t.usable
    );
    match (t.a, t.std_a) {
        (Some(a), Some(s)) => {
            defmt::info!(
                "tensor a=[{=f32}, {=f32}, {=f32}] std_a=[{=f32}, {=f32}, {=f32}]",
                a[0],
                a[1],
                a[2],
                s[0],
                s[1],
                s[2]
            );
            if bits {
                defmt::info!(
                    "tensor bits_a=[{=u32:#010x}, {=u32:#010x}, {=u32:#010x}] bits_std_a=[{=u32:#010x}, {=u32:#010x}, {=u32:#010x}]",
                    a[0].to_bits(),
                    a[1].to_bits(),
                    a[2].to_bits(),
                    s[0].to_bits(),
                    s[1].to_bits(),
                    s[2].to_bits()
                );
            }
        }
        _ => defmt::info!("tensor a=none std_a=none"),
    }
    match t.tensor {
        Some(j) => {
            defmt::info!(
                "tensor J=[{=f32}, {=f32}, {=f32}, {=f32}, {=f32}, {=f32}, {=f32}, {=f32}, {=f32}] kg m^2",
                j[0][0],
                j[0][1],
                j[0][2],
                j[1][0],
                j[1][1],
                j[1][2],
                j[2][0],
                j[2][1],
                j[2][2]
            );
            if bits {
                defmt::info!(
                    "tensor bits_J=[{=u32:#010x}, {=u32:#010x}, {=u32:#010x}, {=u32:#010x}, {=u32:#010x}, {=u32:#010x}, {=u32:#010x}, {=u32:#010x}, {=u32:#010x}]",
                    j[0][0].to_bits(),
                    j[0][1].to_bits(),
                    j[0][2].to_bits(),
                    j[1][0].to_bits(),
                    j[1][1].to_bits(),
                    j[1][2].to_bits(),
                    j[2][0].to_bits(),
                    j[2][1].to_bits(),
                    j[2][2].to_bits()
                );
            }
        }
        None => defmt::info!("tensor J=none"),
    }
}
