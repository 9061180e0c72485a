//! Error-free transformations of `f32` arithmetic (Knuth's two-sum, Dekker's two-product):
//! a sum or product as the rounded result and the exact rounding error, for the few
//! quantities that must be known to better than `f32` precision (the invariants of a long,
//! fast trajectory, see [`crate::ratio_fit`]). No fused multiply-add is assumed: `core` has
//! none without `std`, and Rust never contracts `a * b + c` on its own.

/// `a + b = s + e` exactly, `s` the rounded sum.
#[inline(always)]
pub(crate) fn two_sum(a: f32, b: f32) -> (f32, f32) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// Veltkamp's split: `a = hi + lo` with both halves of 12 significant bits.
#[inline(always)]
fn split(a: f32) -> (f32, f32) {
    let c = 4097.0 * a;
    let hi = c - (c - a);
    (hi, a - hi)
}

/// `a b = p + e` exactly, `p` the rounded product (for `|a b|` well inside the `f32` range).
#[inline(always)]
fn two_prod(a: f32, b: f32) -> (f32, f32) {
    let p = a * b;
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    (p, ((ah * bh - p) + ah * bl + al * bh) + al * bl)
}

/// `x += d` for `x` kept as a compensated sum (Kahan): `hi` the rounded running value, `lo`
/// what its rounding left out so far (the true value is `hi - lo`), carried into the next
/// addition instead of being lost.
#[inline(always)]
pub(crate) fn compensated_add(hi: &mut f32, lo: &mut f32, d: f32) {
    let y = d - *lo;
    let s = *hi + y;
    *lo = (s - *hi) - y;
    *hi = s;
}

/// `sum_i c_i x_i^2` to about twice the `f32` precision, with each `x_i = hi_i - lo_i` given as
/// a compensated pair and the weights `c_i` exact; returned as `(hi, lo)`, value `hi + lo`.
pub(crate) fn weighted_squares(c: &[f32; 3], hi: &[f32; 3], lo: &[f32; 3]) -> (f32, f32) {
    let (mut s, mut e) = (0.0f32, 0.0f32);
    for ((&c, &h), &l) in c.iter().zip(hi.iter()).zip(lo.iter()) {
        // x^2 = h^2 - 2 h l (+ l^2, below the precision kept).
        let (p, pe) = two_prod(h, h);
        let pe = pe - 2.0 * h * l;
        // c x^2 = c p + c pe.
        let (q, qe) = two_prod(c, p);
        let qe = qe + c * pe;
        let (t, te) = two_sum(s, q);
        s = t;
        e += te + qe;
    }
    two_sum(s, e)
}

/// `x^T K x` for a symmetric `K` (its upper triangle read) to about twice the `f32`
/// precision, with each `x_i = hi_i - lo_i` a compensated pair; returned as `(hi, lo)`,
/// value `hi + lo`. The entries of `K` are taken as exact.
pub(crate) fn quadratic_form(k: &[[f32; 3]; 3], hi: &[f32; 3], lo: &[f32; 3]) -> (f32, f32) {
    let [x0, x1, x2] = *hi;
    let [l0, l1, l2] = *lo;
    let [[k00, k01, k02], [_, k11, k12], [_, _, k22]] = *k;
    // Off the diagonal each entry counts twice.
    let terms = [
        (k00, (x0, l0), (x0, l0)),
        (k11, (x1, l1), (x1, l1)),
        (k22, (x2, l2), (x2, l2)),
        (2.0 * k01, (x0, l0), (x1, l1)),
        (2.0 * k02, (x0, l0), (x2, l2)),
        (2.0 * k12, (x1, l1), (x2, l2)),
    ];
    let (mut s, mut e) = (0.0f32, 0.0f32);
    for (kij, (xi, li), (xj, lj)) in terms {
        // x_i x_j = hi_i hi_j - hi_i lo_j - lo_i hi_j (+ lo lo, below the precision kept).
        let (p, pe) = two_prod(xi, xj);
        let pe = pe - xi * lj - li * xj;
        let (q, qe) = two_prod(kij, p);
        let qe = qe + kij * pe;
        let (t, te) = two_sum(s, q);
        s = t;
        e += te + qe;
    }
    two_sum(s, e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_sum_and_two_prod_are_exact() {
        let (a, b) = (1.0f32 + f32::EPSILON, 3.0e-8f32);
        let (s, e) = two_sum(a, b);
        assert_eq!(f64::from(s) + f64::from(e), f64::from(a) + f64::from(b));
        let (x, y) = (1.234_567_9f32, 7.654_321f32);
        let (p, e) = two_prod(x, y);
        assert_eq!(f64::from(p) + f64::from(e), f64::from(x) * f64::from(y));
    }

    #[test]
    fn compensated_add_keeps_what_rounding_drops() {
        let (mut hi, mut lo) = (1.0f32, 0.0f32);
        for _ in 0..1000 {
            compensated_add(&mut hi, &mut lo, 1e-8);
        }
        let got = f64::from(hi) - f64::from(lo);
        assert!((got - (1.0 + 1e-5)).abs() < 1e-12, "{got}");
        // Plain f32 addition loses every one of them.
        let mut plain = 1.0f32;
        for _ in 0..1000 {
            plain += 1e-8;
        }
        assert_eq!(plain, 1.0);
    }

    #[test]
    fn quadratic_form_is_twice_as_precise() {
        let k = [
            [0.7f32, -0.123_456_7, 0.031_415_9],
            [-0.123_456_7, 0.45, 0.011_111_1],
            [0.031_415_9, 0.011_111_1, 0.333_333_3],
        ];
        let hi = [12.345_678f32, -3.210_987, 0.987_654_3];
        let lo = [3e-7f32, -1e-7, 2e-8];
        let (s, e) = quadratic_form(&k, &hi, &lo);
        let x: [f64; 3] = core::array::from_fn(|i| f64::from(hi[i]) - f64::from(lo[i]));
        let mut exact = 0.0f64;
        for i in 0..3 {
            for j in 0..3 {
                exact += f64::from(k[i.min(j)][i.max(j)]) * x[i] * x[j];
            }
        }
        let got = f64::from(s) + f64::from(e);
        assert!(((got - exact) / exact).abs() < 1e-12, "{got} vs {exact}");
    }

    #[test]
    fn weighted_squares_is_twice_as_precise() {
        let c = [0.3f32, 0.5, 0.2];
        let hi = [12.345_678f32, -3.210_987, 0.987_654_3];
        let lo = [3e-7f32, -1e-7, 2e-8];
        let (s, e) = weighted_squares(&c, &hi, &lo);
        let exact: f64 = (0..3)
            .map(|i| {
                let x = f64::from(hi[i]) - f64::from(lo[i]);
                f64::from(c[i]) * x * x
            })
            .sum();
        let got = f64::from(s) + f64::from(e);
        assert!(((got - exact) / exact).abs() < 1e-12, "{got} vs {exact}");
    }
}
