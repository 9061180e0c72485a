//! The rotor telemetry as read: its steady runs, whose constant errors are fitted as offsets
//! ((F7)), and the reading's errors along the ramps counted in the covariance ((F8)).

use super::*;

/// The rotor momentum's errors along ramps and short steady runs ((F8)) in the covariance of
/// the fitted parameters, `sum_g v_g (F^-1 gamma_g) (F^-1 gamma_g)^T` (the parameters' units
/// squared, not scaled by the noise), with `F` the fit's normal matrix at its optimum (see the
/// module docs, (F8)), and the weighted cost the errors are expected to leave in the residual,
/// their direct and integrated parts less what the fit takes up, `tr(F^-1 K)` (module docs).
/// One pass over the trajectory forms each block's `gamma_b = a_b u - (Z - Y_b) c_b`
/// ([`each_gamma`]) from the suffix `Z - Y_b` of `Z = sum_b a_b Phi_b`, which the normal
/// matrix holds already. (The sums `S_pp`, `S_pc`, `S_cc` of the expanded square, with `Z`
/// applied at the end, are the same algebra, but in `f32` their terms cancel to less than
/// their rounding and can give negative variances.) `None` without a
/// resolution, a rotor or a trajectory.
pub(super) fn input_cov<const P: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; P],
    cells: &Cells,
    res: Resolution,
    f: &Sym<P>,
) -> Option<(Sym<P>, f32)> {
    let quantum = res.quantum;
    if !(quantum > 0.0) {
        return None;
    }
    let u = rotor_direction(blocks)?;
    let along = |b: usize| blocks.get(b).map(|blk| dot(rotor_of(blk), u));
    let mut sums = InputSums::<P> {
        fi: scaled_inverse(f)?,
        out: [[0.0; P]; P],
        group: None,
    };
    let mut expected = 0.0f32;
    // The covariance of the integrated momentum's error referred to t_0, `sum v_k c_k c_k^T`.
    let mut drift = [[0.0f32; 3]; 3];
    let ok = each_gamma(blocks, rule, theta, cells, f, u, &mut |nd, gain| {
        let Some((gamma, c, phi)) = gain else {
            // A steady run's error is a parameter of the fit.
            sums.flush();
            return;
        };
        let b = nd.index;
        let here = along(b).unwrap_or(0.0);
        // The quanta the speed crosses over the block, from the neighbours' means.
        let prev = along(b.saturating_sub(1)).unwrap_or(here);
        let next = along(b + 1).unwrap_or(here);
        let crossed = 0.5 * (next - prev).abs() / quantum;
        let var = quantum * quantum / 12.0 * ramp_share(crossed, nd.weight * res.readings);
        let ku = mul(nd.k, u);
        expected += nd.weight * var * dot(ku, ku);
        // The integrated part at this node: tr(M C M^T), M = J^-1 Phi_b.
        let m: Mat3 = core::array::from_fn(|i| {
            core::array::from_fn(|j| (0..3).map(|q| nd.k[i][q] * phi[q][j]).sum())
        });
        for row in &m {
            expected += nd.weight * dot(*row, mul(&drift, *row));
        }
        for i in 0..3 {
            for j in 0..3 {
                drift[i][j] += var * c[i] * c[j];
            }
        }
        sums.push(*gamma, var, here, quantum);
    });
    sums.flush();
    // What the fit itself takes up of the errors: tr(F^-1 K) = tr(F out).
    let absorbed: f32 = f.iter().zip(&sums.out).map(|(fr, or)| dot_n(fr, or)).sum();
    let expected = (expected - absorbed).max(0.0);
    (ok && sums.out.iter().flatten().all(|x| x.is_finite())).then_some((sums.out, expected))
}

/// A block's `gamma_b`, `c_b` and `Phi_b` of (F8).
pub(super) type Gain<'a, const P: usize> = (&'a [f32; P], [f32; 3], &'a Mat3);

/// Each block's `gamma_b` of (F8) at `theta`, in order, with its node: how an error of one
/// unit in the block's momentum along `u` moves the fit's gradient (`None` for a block in a
/// steady run of (F7), whose error is a parameter). `f` is the normal matrix at `theta`. False
/// when the trajectory or a block's transition could not be formed.
pub(super) fn each_gamma<const P: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; P],
    cells: &Cells,
    f: &Sym<P>,
    u: [f32; 3],
    visit: &mut dyn FnMut(&Node<'_, P>, Option<Gain<'_, P>>),
) -> bool {
    let mut y = [[0.0f32; 3]; P];
    // Z = sum_b a_b Phi_b = (sum_b n_b R_b^T R_b,w0) J^-1: the normal matrix's initial-rate
    // columns (`R_b,w0 = J^-1 Phi_b J`, the rows' initial-rate block), times `J^-1`.
    let mut z = None;
    let mut failed = false;
    let mut node = |nd: &Node<'_, P>| {
        let b = nd.index;
        let z = z.get_or_insert_with(|| {
            let mut z = [[0.0f32; 3]; P];
            for (zp, fp) in z.iter_mut().zip(f) {
                for j in 0..3 {
                    let fm = |m: usize| fp.get(6 + m).copied().unwrap_or(0.0);
                    zp[j] = (0..3).map(|m| fm(m) * nd.k[m][j]).sum();
                }
            }
            z
        });
        let (a, phi) = gains(nd);
        add_product(&mut y, &a, &phi);
        if cells.at(b).iter().any(|on| *on) {
            visit(nd, None);
            return;
        }
        // c_b = Phi_b^-1 beta_b, beta_b = -(L x J^-1 u) Delta_b over the half spans on either
        // side of the node.
        let gap = |x: usize, y: usize| match (blocks.get(x), blocks.get(y)) {
            (Some(later), Some(earlier)) => later.since(earlier),
            _ => 0.0,
        };
        let half = 0.5 * (gap(b + 1, b) + if b > 0 { gap(b, b - 1) } else { 0.0 });
        let lku = cross(nd.l, mul(nd.k, u));
        let Some(c) = solve(&phi, lku.map(|x| -x * half)) else {
            failed = true;
            return;
        };
        let gamma: [f32; P] = core::array::from_fn(|p| {
            let suffix = [z[p][0] - y[p][0], z[p][1] - y[p][1], z[p][2] - y[p][2]];
            dot(a[p], u) - dot(suffix, c)
        });
        visit(nd, Some((&gamma, c, &phi)));
    };
    let node: &mut dyn FnMut(&Node<'_, P>) = &mut node;
    let mut seen = OnNode(node);
    let ok = visit_fit::<P, P0>(blocks, rule, blocks.len(), theta, 0.0, cells, &mut seen);
    ok.is_some() && !failed
}

/// A node's `a_b = n_b R_b^T J^-1` (P x 3) and `Phi_b = Phi(t_b, t_0) = Sigma_w0 J^-1`.
pub(super) fn gains<const P: usize>(nd: &Node<'_, P>) -> ([[f32; 3]; P], Mat3) {
    let k = nd.k;
    let a = core::array::from_fn(|p| {
        core::array::from_fn(|j| {
            let t: f32 = (0..3).map(|i| nd.rows[i][p] * k[i][j]).sum();
            nd.weight * t
        })
    });
    let phi = core::array::from_fn(|i| {
        core::array::from_fn(|j| (0..3).map(|m| nd.s_w0[i][m] * k[m][j]).sum())
    });
    (a, phi)
}

/// `y += a phi` (P x 3 by 3 x 3).
pub(super) fn add_product<const P: usize>(y: &mut [[f32; 3]; P], a: &[[f32; 3]; P], phi: &Mat3) {
    for (yp, ap) in y.iter_mut().zip(a) {
        for j in 0..3 {
            yp[j] += (0..3).map(|m| ap[m] * phi[m][j]).sum::<f32>();
        }
    }
}

/// The variance of a block mean's quantisation error over a quantum's, `q^2 / 12`, when the
/// speed crosses `d` quanta over the block's `n` readings:
///
/// ```text
/// g(d, n) = c(d) + min(d, n) / n^2,
/// c(d) = (1 - d)^2 + d^2 / 30  (d < 1),   1 / (30 d^2)  (d >= 1)
/// ```
///
/// The error of a reading is a sawtooth of the speed (zero mean, period one quantum). Its mean
/// over a span of `d` periods from a random phase has the variance `q^2 / 12 f^2 (1 - f)^2 /
/// d^2`, `f` the fractional part of `d` (the sawtooth's antiderivative at the two ends; worked
/// out exactly): `(1 - d)^2` below one quantum, `1 / (30 d^2)` on average over `f` above (the
/// `d^2 / 30` below one joins the two where `d`, taken from the neighbours' means, is
/// uncertain). The second term is the readings' own granularity: each of the `d` steps falls
/// between two of the `n` readings at a random point, `q^2 / (12 n^2)` each, up to the `1 / n`
/// of independent readings. Against rounded ramps simulated from random phases it is within
/// 0.7-1.4 of the variance except near one quantum per block, where it is up to 2.6 times
/// larger (`ramp_share_matches_rounded_ramps`).
pub(super) fn ramp_share(d: f32, n: f32) -> f32 {
    let n = n.max(1.0);
    let c = if d < 1.0 {
        (1.0 - d) * (1.0 - d) + d * d / 30.0
    } else {
        1.0 / (30.0 * d * d)
    };
    c + d.min(n) / (n * n)
}

/// How the rotor momentum is read: its quantum (kg m^2/s; 0: exact) and the readings each
/// sample of the fit stands for (the inputs averaged into it; one reading per input assumed);
/// and the gyro readings' own time variance ((B0), (B0')), which the rotor's readings lack.
#[derive(Clone, Copy, Debug)]
pub(super) struct Resolution {
    pub(super) quantum: f32,
    pub(super) readings: f32,
    pub(super) gyro_spread: f32,
}

impl Resolution {
    pub(super) const EXACT: Resolution = Resolution {
        quantum: 0.0,
        readings: 1.0,
        gyro_spread: 0.0,
    };
}

/// [`input_cov`]'s groups of blocks that share one reading error (variance `v`), summed as
/// `out += v (F^-1 gamma) (F^-1 gamma)^T` with `gamma` the group's sum of `gamma_b`.
pub(super) struct InputSums<const P: usize> {
    pub(super) fi: Sym<P>,
    pub(super) out: Sym<P>,
    /// The open group: `gamma`, its variance and the momentum (along `u`) it started at.
    pub(super) group: Option<([f32; P], f32, f32)>,
}

impl<const P: usize> InputSums<P> {
    /// Adds a block's `gamma_b` to the open group when its momentum is within one quantum of
    /// the group's first (one reading, one error), else starts a group with it.
    pub(super) fn push(&mut self, gamma: [f32; P], var: f32, here: f32, quantum: f32) {
        if let Some((g, _, start)) = &mut self.group {
            if (here - *start).abs() < quantum {
                for (gi, x) in g.iter_mut().zip(gamma) {
                    *gi += x;
                }
                return;
            }
        }
        self.flush();
        self.group = Some((gamma, var, here));
    }

    /// Closes the open group into `out`.
    pub(super) fn flush(&mut self) {
        let Some((g, v, _)) = self.group.take() else {
            return;
        };
        let d: [f32; P] = core::array::from_fn(|i| dot_n(&self.fi[i], &g));
        for i in 0..P {
            for j in 0..P {
                self.out[i][j] += v * d[i] * d[j];
            }
        }
    }
}

/// `a . b` over `P` entries.
pub(super) fn dot_n<const P: usize>(a: &[f32; P], b: &[f32; P]) -> f32 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// [`steady_cells`] for the fits of a rotor read at `res`'s quantum (none when it is exact),
/// with the offsets' prior of (F7): a quantum's uniform variance in units of the gyro's noise
/// variance, `noise_floor^2 / (q^2 / 12)`.
pub(super) fn cells_for(blocks: &[Block<6>], res: Resolution, noise_floor: f32) -> Option<Cells> {
    let q = res.quantum;
    (q > 0.0)
        .then(|| steady_cells(blocks, q))
        .flatten()
        .map(|c| Cells {
            prior: noise_floor * noise_floor * 12.0 / (q * q),
            ..c
        })
}

/// The rotor's steady stretches for (F7): the direction `u` of the largest block-mean rotor
/// momentum, and the [`CELLS`] longest runs of at least three consecutive blocks over which
/// the momentum along `u` stays within one `quantum` of the run's first block (`None` without
/// a rotor momentum or such a run). A reading that keeps one value keeps one error.
pub(super) fn steady_cells(blocks: &[Block<6>], quantum: f32) -> Option<Cells> {
    let u = rotor_direction(blocks)?;
    let along = |b: &Block<6>| dot(rotor_of(b), u);
    let mut cells = Cells {
        u,
        runs: [(0, 0); CELLS],
        prior: 0.0,
        quantum,
    };
    let mut keep = |run: (usize, usize)| {
        let len = |r: &(usize, usize)| r.1.saturating_sub(r.0);
        if len(&run) < 3 {
            return;
        }
        // Replace the shortest kept run when this one is longer.
        let shortest = cells
            .runs
            .iter_mut()
            .fold(None::<&mut (usize, usize)>, |s, r| match s {
                Some(s) if len(s) <= len(r) => Some(s),
                _ => Some(r),
            });
        if let Some(s) = shortest {
            if len(&run) > len(s) {
                *s = run;
            }
        }
    };
    let mut start = 0;
    let mut first = blocks.first().map_or(0.0, along);
    for (b, block) in blocks.iter().enumerate() {
        let here = along(block);
        if !((here - first).abs() < quantum) {
            keep((start, b));
            start = b;
            first = here;
        }
    }
    keep((start, blocks.len()));
    cells.runs.iter().any(|r| r.1 > r.0).then_some(cells)
}

/// The direction of the largest block-mean rotor momentum (`None` without one).
pub(super) fn rotor_direction(blocks: &[Block<6>]) -> Option<[f32; 3]> {
    let h =
        blocks.iter().map(rotor_of).fold(
            [0.0f32; 3],
            |a, h| if dot(h, h) > dot(a, a) { h } else { a },
        );
    let n = norm(h);
    (n > 0.0 && n.is_finite()).then(|| h.map(|x| x / n))
}
