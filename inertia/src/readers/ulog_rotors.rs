//! The rotor fields a vehicle file names in a PX4 ULog, and their values at the gyro's times.
//!
//! A field is named `topic.field` (`esc_status.esc[0].esc_rpm`, `actuator_outputs.output[2]`),
//! or `topic:N.field` for the instance with multi id `N`; without `:N` the topic's first
//! instance (lowest multi id) is read, as the gyro's `sensor_combined` is. Names match as
//! written, else ignoring case. The field's messages are stamped by the topic's `timestamp`
//! (microseconds); each gyro sample takes the last value at or before its time as read (the
//! middle of its `gyro_integral_dt`; zero-order hold, [`hold`]):
//!
//! - gyro samples before a rotor field's first message have no speed: they are left out (the
//!   log starts, for the identification, where every rotor is known), with a warning; a log
//!   in which no gyro sample comes at or after them all is refused;
//! - a value that is not finite (or beyond `f32`) where a gyro sample takes it is refused,
//!   naming the rotor and both times, as every reader refuses a non-finite value;
//! - a hold longer than ten times the field's median message interval (a topic that drops out
//!   or stops before the gyro) is kept, with a warning;
//! - integer fields are converted exactly (up to 2^53); `bool` and `char` fields are refused;
//!   an array is named by one element (`output[2]`), and its bare name is refused with the
//!   elements listed.
//!
//! A topic, instance or field the log lacks is refused with the rotor named and the log's
//! topics or fields that come closest to the name listed.

use std::collections::HashMap;
use std::path::Path;

use px4_ulog::full_parser::{MultiId, SomeVec};

use super::{quote, ReadError};

/// A topic instance's fields by their flattened names (`esc[0].esc_rpm`).
pub(super) type Topic = HashMap<String, SomeVec>;
/// A parsed log's topics, by name and multi id.
pub(super) type Topics = HashMap<String, HashMap<MultiId, Topic>>;

/// One field of a topic as `f64`s (integers converted exactly up to 2^53).
pub(super) fn as_f64(v: &SomeVec) -> Vec<f64> {
    match v {
        SomeVec::Int8(x) => x.iter().map(|&a| f64::from(a)).collect(),
        SomeVec::UInt8(x) => x.iter().map(|&a| f64::from(a)).collect(),
        SomeVec::Int16(x) => x.iter().map(|&a| f64::from(a)).collect(),
        SomeVec::UInt16(x) => x.iter().map(|&a| f64::from(a)).collect(),
        SomeVec::Int32(x) => x.iter().map(|&a| f64::from(a)).collect(),
        SomeVec::UInt32(x) => x.iter().map(|&a| f64::from(a)).collect(),
        SomeVec::Int64(x) => x.iter().map(|&a| a as f64).collect(),
        SomeVec::UInt64(x) => x.iter().map(|&a| a as f64).collect(),
        SomeVec::Float(x) => x.iter().map(|&a| f64::from(a)).collect(),
        SomeVec::Double(x) => x.clone(),
        SomeVec::Bool(x) => x.iter().map(|&a| f64::from(u8::from(a))).collect(),
        SomeVec::Char(x) => x.iter().map(|&a| f64::from(u32::from(a))).collect(),
    }
}

/// The first instance (lowest multi id) of a topic.
pub(super) fn first_instance<'a>(topics: &'a Topics, name: &str) -> Option<&'a Topic> {
    topics
        .get(name)?
        .iter()
        .min_by_key(|(id, _)| id.value())
        .map(|(_, t)| t)
}

/// One rotor field's messages: times (us, non-decreasing) and values as logged.
pub(super) struct Series {
    /// The rotor and its field, for messages: `rotor "rw1" (esc_status.esc[0].esc_rpm)`.
    label: String,
    t_us: Vec<f64>,
    v: Vec<f64>,
}

/// How many names an error lists at most.
const LISTED: usize = 8;

/// The messages of the field `column` names (see the module documentation); `rotor` is the
/// rotor's name for messages (empty when unknown).
pub(super) fn series(
    path: &Path,
    topics: &Topics,
    column: &str,
    rotor: &str,
) -> Result<Series, ReadError> {
    let column = column.trim();
    let label = if rotor.is_empty() {
        format!("rotor field {}", quote(column))
    } else {
        format!("rotor {} ({})", quote(rotor), quote(column))
    };
    let fail = |what: String| ReadError::new(path, format!("{label}: {what}"));
    let Some((topic_part, field)) = column.split_once('.') else {
        return Err(fail(
            "a ULog field is named topic.field (esc_status.esc[0].esc_rpm) or topic:N.field \
             (instance N)"
                .into(),
        ));
    };
    let (topic_name, instance) = match topic_part.split_once(':') {
        None => (topic_part, None),
        Some((name, n)) => match n.trim().parse::<u8>() {
            Ok(n) => (name, Some(n)),
            Err(_) => {
                return Err(fail(format!(
                    "instance {} is not a number from 0 to 255",
                    quote(n)
                )))
            }
        },
    };
    let (topic_name, field) = (topic_name.trim(), field.trim());
    let Some((name, instances)) = lookup(topics, topic_name) else {
        let mut names: Vec<&str> = topics.keys().map(String::as_str).collect();
        names.sort_unstable();
        return Err(fail(format!(
            "the log has no topic {} (with data){}",
            quote(topic_name),
            listing("topics", topic_name, &names)
        )));
    };
    let data = match instance {
        None => instances
            .iter()
            .min_by_key(|(id, _)| id.value())
            .map(|(_, t)| t),
        Some(n) => instances
            .iter()
            .find(|(id, _)| id.value() == n)
            .map(|(_, t)| t),
    };
    let Some(data) = data else {
        let mut ids: Vec<u8> = instances.keys().map(MultiId::value).collect();
        ids.sort_unstable();
        let ids: Vec<String> = ids.iter().map(u8::to_string).collect();
        return Err(fail(format!(
            "topic {name} has no instance {} (it has {})",
            instance.unwrap_or_default(),
            ids.join(", ")
        )));
    };
    let Some((field_name, values)) = lookup(data, field) else {
        let mut names: Vec<&str> = data.keys().map(String::as_str).collect();
        names.sort_unstable();
        let prefix = format!("{}[", field.to_ascii_lowercase());
        let elements: Vec<&str> = names
            .iter()
            .copied()
            .filter(|n| n.to_ascii_lowercase().starts_with(&prefix))
            .collect();
        if let (Some(first), Some(last)) = (elements.first(), elements.last()) {
            return Err(fail(format!(
                "{field} of topic {name} is an array: name one element ({first} to {last})"
            )));
        }
        return Err(fail(format!(
            "topic {name} has no field {}{}",
            quote(field),
            listing("fields", field, &names)
        )));
    };
    if matches!(values, SomeVec::Bool(_) | SomeVec::Char(_)) {
        return Err(fail(format!(
            "{name}.{field_name} is a bool or char field, not a speed"
        )));
    }
    let Some(stamps) = data.get("timestamp") else {
        return Err(fail(format!("topic {name} has no timestamp field")));
    };
    let (t_us, v) = (as_f64(stamps), as_f64(values));
    if t_us.len() != v.len() || v.is_empty() {
        return Err(fail(format!(
            "topic {name}: {} timestamps for {} values",
            t_us.len(),
            v.len()
        )));
    }
    if let Some(k) = t_us.windows(2).position(|w| w[1] < w[0]) {
        return Err(fail(format!(
            "topic {name}'s time goes backwards at its message {} ({:.6} s after {:.6} s)",
            k + 1,
            t_us[k + 1] * 1e-6,
            t_us[k] * 1e-6
        )));
    }
    Ok(Series { label, t_us, v })
}

/// `key` in `map`: as written, else the one key equal ignoring case.
fn lookup<'a, V>(map: &'a HashMap<String, V>, key: &str) -> Option<(&'a str, &'a V)> {
    if let Some((k, v)) = map.get_key_value(key) {
        return Some((k.as_str(), v));
    }
    let mut same = map.iter().filter(|(k, _)| k.eq_ignore_ascii_case(key));
    match (same.next(), same.next()) {
        (Some((k, v)), None) => Some((k.as_str(), v)),
        _ => None,
    }
}

/// `; the TOPICS that come closest: a, b, c (of N)` for an error.
fn listing(what: &str, wanted: &str, names: &[&str]) -> String {
    if names.is_empty() {
        return format!("; it has no {what}");
    }
    let close = closest(wanted, names, LISTED);
    let of = if names.len() > close.len() {
        format!(" (of {})", names.len())
    } else {
        String::new()
    };
    format!("; the {what} that come closest: {}{of}", close.join(", "))
}

/// Up to `k` of `names` nearest `wanted` (edit distance ignoring case; a name holding `wanted`,
/// or held in it, first), in that order.
fn closest<'a>(wanted: &str, names: &[&'a str], k: usize) -> Vec<&'a str> {
    let w = wanted.to_ascii_lowercase();
    let mut scored: Vec<(bool, usize, &str)> = names
        .iter()
        .map(|&n| {
            let l = n.to_ascii_lowercase();
            let holds = !w.is_empty() && (l.contains(&w) || w.contains(&l));
            (!holds, distance(&w, &l), n)
        })
        .collect();
    scored.sort_unstable();
    scored.into_iter().take(k).map(|(_, _, n)| n).collect()
}

/// Levenshtein distance between `a` and `b` (by characters).
fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let up = row[j + 1];
            row[j + 1] = (diag + usize::from(ca != cb)).min(up + 1).min(row[j] + 1);
            diag = up;
        }
    }
    row[b.len()]
}

/// The rotors' values at the gyro's times.
pub(super) struct Held {
    /// The leading gyro samples before some rotor field's first message (left out).
    pub(super) skip: usize,
    /// Per rotor, the value held at each gyro sample from `skip` on.
    pub(super) values: Vec<Vec<f64>>,
    /// What the user should know (samples left out, long holds).
    pub(super) warnings: Vec<String>,
}

/// Holds each series onto the gyro times `t_us` (us; in order): the last value at or before
/// each time. See the module documentation for what is left out, refused and warned about.
pub(super) fn hold(path: &Path, series: &[Series], t_us: &[f64]) -> Result<Held, ReadError> {
    let mut warnings = Vec::new();
    let fail = |what: String| ReadError::new(path, what);
    let first = |s: &Series| s.t_us.first().copied().unwrap_or(f64::INFINITY);
    // The rotor whose first message comes last (the first such in the file's order).
    let latest = series
        .iter()
        .fold(None, |best: Option<&Series>, s| match best {
            Some(b) if first(b) >= first(s) => Some(b),
            _ => Some(s),
        });
    let Some(latest) = latest else {
        return Ok(Held {
            skip: 0,
            values: Vec::new(),
            warnings,
        });
    };
    let start = first(latest);
    let skip = t_us.iter().take_while(|&&t| t < start).count();
    let (Some(&t0), Some(&t_end)) = (t_us.first(), t_us.last()) else {
        return Ok(Held {
            skip: 0,
            values: vec![Vec::new(); series.len()],
            warnings,
        });
    };
    if skip == t_us.len() {
        return Err(fail(format!(
            "{}: its first message ({:.6} s) comes after the gyro's last sample ({:.6} s): no gyro \
             sample has its speed",
            latest.label,
            start * 1e-6,
            t_end * 1e-6
        )));
    }
    if skip > 0 {
        warnings.push(format!(
            "{}: its first message comes {:.3} s after the gyro's first sample; the {skip} gyro \
             sample(s) before it are left out (no speed known there)",
            latest.label,
            (start - t0) * 1e-6
        ));
    }
    let mut values = Vec::with_capacity(series.len());
    for s in series {
        let mut v = Vec::with_capacity(t_us.len() - skip);
        let mut longest = 0.0f64;
        for &t in &t_us[skip..] {
            let Some(j) = s.t_us.partition_point(|&m| m <= t).checked_sub(1) else {
                return Err(fail(format!(
                    "{}: a gyro sample at {:.6} s comes before its first message (the gyro's time \
                     goes backwards)",
                    s.label,
                    t * 1e-6
                )));
            };
            let x = s.v[j];
            if !(x as f32).is_finite() {
                return Err(fail(format!(
                    "{}: its message at {:.6} s holds {x}, not a finite speed (or beyond f32), \
                     and the gyro sample at {:.6} s would take it",
                    s.label,
                    s.t_us[j] * 1e-6,
                    t * 1e-6
                )));
            }
            longest = longest.max(t - s.t_us[j]);
            v.push(x);
        }
        if let Some(step) = median_step(&s.t_us) {
            if longest > 10.0 * step {
                warnings.push(format!(
                    "{}: a value is held {:.3} s after its message, more than ten times the \
                     topic's median interval ({:.4} s): the topic drops out or stops before the \
                     gyro, and its last value stands in",
                    s.label,
                    longest * 1e-6,
                    step * 1e-6
                ));
            }
        }
        values.push(v);
    }
    Ok(Held {
        skip,
        values,
        warnings,
    })
}

/// The median of the positive steps between the times `t`.
fn median_step(t: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|&x| x > 0.0)
        .collect();
    if d.is_empty() {
        return None;
    }
    let k = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(k, f64::total_cmp);
    Some(*m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_names_come_first() {
        let names = [
            "esc[0].esc_rpm",
            "esc[0].esc_voltage",
            "esc[1].esc_rpm",
            "esc_count",
            "timestamp",
        ];
        assert_eq!(distance("kitten", "sitting"), 3);
        assert_eq!(distance("", "abc"), 3);
        let c = closest("esc[0].rpm", &names, 2);
        assert_eq!(c, ["esc[0].esc_rpm", "esc[1].esc_rpm"]);
        // A name holding the wanted one comes before a nearer one that does not.
        assert_eq!(closest("rpm", &names, 1), ["esc[0].esc_rpm"]);
    }

    fn series_of(t: &[f64], v: &[f64]) -> Series {
        Series {
            label: "rotor \"r\"".into(),
            t_us: t.to_vec(),
            v: v.to_vec(),
        }
    }

    #[test]
    fn holds_the_last_value_at_or_before_each_sample() {
        let p = Path::new("x.ulg");
        let s = [
            series_of(&[10.0, 20.0, 30.0], &[1.0, 2.0, 3.0]),
            series_of(&[15.0, 25.0], &[-1.0, -2.0]),
        ];
        let h = hold(p, &s, &[0.0, 10.0, 15.0, 19.0, 20.0, 29.0, 31.0, 200.0]).unwrap();
        // Before 15 us the second rotor is unknown: 0, 10 left out.
        assert_eq!(h.skip, 2);
        assert_eq!(h.values[0], [1.0, 1.0, 2.0, 2.0, 3.0, 3.0]);
        assert_eq!(h.values[1], [-1.0, -1.0, -1.0, -2.0, -2.0, -2.0]);
        assert!(
            h.warnings[0].contains("the 2 gyro sample(s)"),
            "{:?}",
            h.warnings
        );
        // 200 holds 3.0 for 170 us, beyond ten median intervals of 10 us.
        assert_eq!(h.warnings.len(), 3, "{:?}", h.warnings);
        assert!(h.warnings[1].contains("ten times"), "{:?}", h.warnings);

        let nan = [series_of(&[0.0, 5.0, 8.0], &[1.0, f64::NAN, 2.0])];
        assert!(hold(p, &nan, &[1.0, 4.0, 9.0]).is_ok(), "NaN never taken");
        let e = hold(p, &nan, &[1.0, 6.0]).err().unwrap().message;
        assert!(e.contains("holds NaN") && e.contains("0.000006 s"), "{e}");
        let late = [series_of(&[50.0], &[1.0])];
        let e = hold(p, &late, &[1.0, 6.0]).err().unwrap().message;
        assert!(e.contains("comes after the gyro's last sample"), "{e}");
    }
}
