//! Small fixed-size symmetric linear algebra for the tensor estimator: a square root, a
//! Cholesky factorisation with solve and inverse for `N <= 6`, and the eigen-decomposition of a
//! symmetric 3x3 matrix by cyclic Jacobi rotations.
//!
//! Everything is written with `f32` basic operations only, so the host build and the
//! Cortex-M4F build execute the same operations and give the same bits (no `std` maths, no
//! fused multiply-add: Rust does not contract `a * b + c`).
//!
//! Indices are loop counters bounded by the const size `N`; the crate's link-time no-panic
//! check (`scripts/check-no-panic.sh`) proves that no bounds check survives in the firmware
//! build, which is why `clippy::indexing_slicing` is allowed in this module only.
#![allow(
    clippy::indexing_slicing,
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord
)]

/// `sqrt(x)` for `x >= 0` (`0` for anything else, including NaN and infinity): a first guess
/// from halving the exponent, then five Newton steps `y <- (y + x / y) / 2`, which converge to
/// within one or two ulp of the true root over the whole `f32` range.
pub fn sqrt(x: f32) -> f32 {
    if !(x > 0.0 && x.is_finite()) {
        return 0.0;
    }
    let mut y = f32::from_bits((x.to_bits() >> 1).wrapping_add(0x1fbd_1df5));
    let mut i = 0;
    while i < 5 {
        y = 0.5 * (y + x / y);
        i += 1;
    }
    if y.is_finite() {
        y
    } else {
        0.0
    }
}

/// A symmetric `N x N` matrix stored in full (both triangles kept equal by construction).
pub type Sym<const N: usize> = [[f32; N]; N];

/// Lower Cholesky factor `L` with `m = L L^T`, or `None` when `m` is not numerically positive
/// definite (a pivot `<= tol * max diagonal`, or anything non-finite).
pub fn cholesky<const N: usize>(m: &Sym<N>) -> Option<Sym<N>> {
    cholesky_rel(m, 1e-7)
}

/// [`cholesky`] with the pivot tolerance `rel * max diagonal` given.
pub fn cholesky_rel<const N: usize>(m: &Sym<N>, rel: f32) -> Option<Sym<N>> {
    let mut maxd = 0.0f32;
    for i in 0..N {
        if !(m[i][i] > maxd) {
            continue;
        }
        maxd = m[i][i];
    }
    if !(maxd > 0.0 && maxd.is_finite()) {
        return None;
    }
    let tol = maxd * rel;
    let mut l = [[0.0f32; N]; N];
    for j in 0..N {
        let mut d = m[j][j];
        for k in 0..j {
            d -= l[j][k] * l[j][k];
        }
        if !(d > tol && d.is_finite()) {
            return None;
        }
        let ljj = sqrt(d);
        l[j][j] = ljj;
        let inv = 1.0 / ljj;
        for i in (j + 1)..N {
            let mut s = m[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            l[i][j] = s * inv;
        }
    }
    Some(l)
}

/// Solves `L L^T x = b` for a Cholesky factor `L`.
pub fn cholesky_solve<const N: usize>(l: &Sym<N>, b: &[f32; N]) -> [f32; N] {
    let mut y = [0.0f32; N];
    for i in 0..N {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i][k] * y[k];
        }
        y[i] = s / l[i][i];
    }
    let mut x = [0.0f32; N];
    for ii in 0..N {
        let i = N - 1 - ii;
        let mut s = y[i];
        for k in (i + 1)..N {
            s -= l[k][i] * x[k];
        }
        x[i] = s / l[i][i];
    }
    x
}

/// `(L L^T)^-1` for a Cholesky factor `L`, column by column.
pub fn cholesky_inverse<const N: usize>(l: &Sym<N>) -> Sym<N> {
    let mut inv = [[0.0f32; N]; N];
    for c in 0..N {
        let mut e = [0.0f32; N];
        e[c] = 1.0;
        let col = cholesky_solve(l, &e);
        for r in 0..N {
            inv[r][c] = col[r];
        }
    }
    // Symmetrise: the two triangles differ by rounding only.
    for r in 0..N {
        for c in (r + 1)..N {
            let v = 0.5 * (inv[r][c] + inv[c][r]);
            inv[r][c] = v;
            inv[c][r] = v;
        }
    }
    inv
}

/// Eigen-decomposition `m = V diag(values) V^T` of a symmetric 3x3 matrix.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Eigen3 {
    /// Eigenvalues, ascending.
    pub values: [f32; 3],
    /// Unit eigenvectors: `vectors[i]` belongs to `values[i]`. Each is signed so that its
    /// largest-magnitude component is positive, and the set is completed to a right-handed
    /// frame by flipping the sign of the last one when needed.
    pub vectors: [[f32; 3]; 3],
}

/// Eigenvalues and eigenvectors of a symmetric 3x3 matrix by cyclic Jacobi rotations: each
/// rotation `J(p, q, theta)` with `tan(2 theta) = 2 m_pq / (m_qq - m_pp)` zeroes `m_pq`; sweeps
/// repeat until the off-diagonal part is below `1e-7` of the diagonal's norm (at most 12
/// sweeps; 3 to 5 are typical in `f32`). `None` when the input is not finite.
pub fn eigen_symmetric3(m: &Sym<3>) -> Option<Eigen3> {
    if !m.iter().flatten().all(|x| x.is_finite()) {
        return None;
    }
    let mut a = *m;
    // Symmetrise the input (the caller's matrix may differ by rounding between triangles).
    for r in 0..3 {
        for c in (r + 1)..3 {
            let v = 0.5 * (a[r][c] + a[c][r]);
            a[r][c] = v;
            a[c][r] = v;
        }
    }
    let mut v = [[1.0f32, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut sweep = 0;
    while sweep < 12 {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let diag = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if !(off > 1e-14 * diag) {
            break;
        }
        rotate::<0, 1>(&mut a, &mut v);
        rotate::<0, 2>(&mut a, &mut v);
        rotate::<1, 2>(&mut a, &mut v);
        sweep += 1;
    }
    // Columns of v are the eigenvectors; sort (value, vector) pairs ascending by value.
    let col = |o: usize| [v[0][o], v[1][o], v[2][o]];
    let mut pairs = [(a[0][0], col(0)), (a[1][1], col(1)), (a[2][2], col(2))];
    if pairs[1].0 < pairs[0].0 {
        pairs.swap(0, 1);
    }
    if pairs[2].0 < pairs[1].0 {
        pairs.swap(1, 2);
    }
    if pairs[1].0 < pairs[0].0 {
        pairs.swap(0, 1);
    }
    let mut values = [0.0f32; 3];
    let mut vectors = [[0.0f32; 3]; 3];
    for ((val, vec), (pv, pe)) in values.iter_mut().zip(vectors.iter_mut()).zip(pairs.iter()) {
        *val = *pv;
        let mut e = *pe;
        let big = if e[0].abs() >= e[1].abs() && e[0].abs() >= e[2].abs() {
            e[0]
        } else if e[1].abs() >= e[2].abs() {
            e[1]
        } else {
            e[2]
        };
        if big < 0.0 {
            e = [-e[0], -e[1], -e[2]];
        }
        *vec = e;
    }
    // Right-handed: v2 = v0 x v1 (up to sign).
    let [x, y, z] = [vectors[0], vectors[1], vectors[2]];
    let cr = [
        x[1] * y[2] - x[2] * y[1],
        x[2] * y[0] - x[0] * y[2],
        x[0] * y[1] - x[1] * y[0],
    ];
    if cr[0] * z[0] + cr[1] * z[1] + cr[2] * z[2] < 0.0 {
        vectors[2] = [-z[0], -z[1], -z[2]];
    }
    if values.iter().all(|x| x.is_finite()) && vectors.iter().flatten().all(|x| x.is_finite()) {
        Some(Eigen3 { values, vectors })
    } else {
        None
    }
}

/// One Jacobi rotation zeroing `a[P][Q]` (the pair as const parameters, so every index is a
/// compile-time constant and no bounds check exists).
fn rotate<const P: usize, const Q: usize>(a: &mut Sym<3>, v: &mut Sym<3>) {
    let apq = a[P][Q];
    if apq == 0.0 {
        return;
    }
    // Stable rotation: t = sgn(theta) / (|theta| + sqrt(theta^2 + 1)).
    let theta = (a[Q][Q] - a[P][P]) / (2.0 * apq);
    let t = if theta.abs() > 1e18 {
        0.5 / theta
    } else {
        let s = if theta >= 0.0 { 1.0 } else { -1.0 };
        s / (theta.abs() + sqrt(theta * theta + 1.0))
    };
    let c = 1.0 / sqrt(t * t + 1.0);
    let s = t * c;
    for row in a.iter_mut() {
        let (akp, akq) = (row[P], row[Q]);
        row[P] = c * akp - s * akq;
        row[Q] = s * akp + c * akq;
    }
    let (rp, rq) = (a[P], a[Q]);
    for k in 0..3 {
        a[P][k] = c * rp[k] - s * rq[k];
        a[Q][k] = s * rp[k] + c * rq[k];
    }
    for row in v.iter_mut() {
        let (vp, vq) = (row[P], row[Q]);
        row[P] = c * vp - s * vq;
        row[Q] = s * vp + c * vq;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sqrt_is_close() {
        for &x in &[1e-30f32, 1e-6, 0.25, 1.0, 2.0, 3.0, 1e6, 3e38] {
            let s = sqrt(x);
            let r = (s * s - x).abs() / x;
            assert!(r < 3e-7, "{x} {s}");
        }
        assert_eq!(sqrt(-1.0), 0.0);
        assert_eq!(sqrt(f32::NAN), 0.0);
        assert_eq!(sqrt(f32::INFINITY), 0.0);
    }

    #[test]
    fn cholesky_solves_and_inverts() {
        let m: Sym<3> = [[4.0, 1.0, 0.5], [1.0, 3.0, -0.2], [0.5, -0.2, 2.0]];
        let l = cholesky(&m).unwrap();
        let x = cholesky_solve(&l, &[1.0, 2.0, 3.0]);
        for r in 0..3 {
            let got: f32 = (0..3).map(|c| m[r][c] * x[c]).sum();
            assert!((got - [1.0, 2.0, 3.0][r]).abs() < 1e-5);
        }
        let inv = cholesky_inverse(&l);
        for r in 0..3 {
            for c in 0..3 {
                let got: f32 = (0..3).map(|k| m[r][k] * inv[k][c]).sum();
                let want = if r == c { 1.0 } else { 0.0 };
                assert!((got - want).abs() < 1e-5);
            }
        }
        assert!(cholesky(&[[1.0, 2.0], [2.0, 1.0]]).is_none());
        assert!(cholesky(&[[f32::NAN, 0.0], [0.0, 1.0]]).is_none());
    }

    #[test]
    fn eigen_reconstructs() {
        let m: Sym<3> = [
            [7.545e-5, -1.68e-6, 1.10e-6],
            [-1.68e-6, 2.179e-5, 6.75e-6],
            [1.10e-6, 6.75e-6, 8.808e-5],
        ];
        let e = eigen_symmetric3(&m).unwrap();
        assert!(e.values[0] <= e.values[1] && e.values[1] <= e.values[2]);
        for r in 0..3 {
            for c in 0..3 {
                let got: f32 = (0..3)
                    .map(|i| e.values[i] * e.vectors[i][r] * e.vectors[i][c])
                    .sum();
                assert!((got - m[r][c]).abs() < 1e-10, "{r}{c} {got} {}", m[r][c]);
            }
        }
        // Repeated eigenvalues and a diagonal matrix.
        let e = eigen_symmetric3(&[[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]]).unwrap();
        assert_eq!(e.values, [1.0, 2.0, 2.0]);
        assert!(eigen_symmetric3(&[[f32::NAN; 3]; 3]).is_none());
    }
}
