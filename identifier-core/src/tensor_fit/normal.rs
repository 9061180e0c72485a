//! The normal equations of a stretch at a parameter vector: one pass over the blocks (the
//! layouts a parameter count implies, the visitors that ride along the pass).

use super::*;

/// Entries of `J` fitted by a parameter vector of length `P`: the six entries in kg m^2 (`P`
/// = 9, or 12 with the bias), or five with the trace held (`P` = 8 or 11: `Jzz = trace - Jxx -
/// Jyy`, the tensor up to scale).
pub(super) const fn entries_of(p: usize) -> usize {
    if p == P0 - 1 || p == P1 - 1 {
        5
    } else {
        6
    }
}

/// The six entries `(xx, yy, zz, xy, xz, yz)` from the first `m` of `theta` (`m` = 6, or 5
/// with the trace held at `trace`).
pub(super) fn six<const P: usize>(theta: &[f32; P], trace: f32, m: usize) -> [f32; 6] {
    let g = |i: usize| theta.get(i).copied().unwrap_or(0.0);
    if m == 6 {
        [g(0), g(1), g(2), g(3), g(4), g(5)]
    } else {
        [g(0), g(1), trace - g(0) - g(1), g(2), g(3), g(4)]
    }
}

/// Cost and normal equations of the first `limit` blocks at `theta`: `P` = 9 (six entries,
/// initial rate) or 12 (and the bias), or 8 and 11 with the trace held at `trace` (the tensor up
/// to scale: the sensitivity to `Jxx` is `d/dJxx - d/dJzz`, and the same for `Jyy`).
///
/// With [`has_offsets`]`(P)` the last [`CELLS`] parameters are the rotor momentum's offsets of
/// (F7) over `cells`' runs; one whose run is empty or starts beyond the first `limit` blocks has no
/// column, and is held where it is (its row and column of the normal matrix the identity's).
pub(super) fn normal<const P: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    limit: usize,
    theta: &[f32; P],
    trace: f32,
    cells: &Cells,
) -> Option<Normal<P>> {
    let fitted = visit_fit::<P, P0>(blocks, rule, limit, theta, trace, cells, &mut ());
    if !has_offsets(P) {
        return fitted;
    }
    let (mut cost, mut f, mut g) = fitted?;
    let mut idle = [0usize; CELLS];
    let mut n = 0;
    for (c, run) in cells.runs.iter().enumerate() {
        let k = P - CELLS + c;
        if run.0 >= run.1 || run.0 >= limit {
            if let Some(slot) = idle.get_mut(n) {
                *slot = k;
                n += 1;
            }
        } else if let (Some(d), Some(fk), Some(gk)) = (
            theta.get(k),
            f.get_mut(k).and_then(|row| row.get_mut(k)),
            g.get_mut(k),
        ) {
            // The offset's prior ((F7)): a pseudo-observation `0 = sqrt(w) d`.
            let w = cells.prior;
            cost += w * d * d;
            *fk += w;
            *gk -= w * d;
        }
    }
    let (f, g) = without(&f, &g, idle.get(..n).unwrap_or(&[]));
    Some((cost, f, g))
}

/// [`normal_visit`] in the layout the parameter count implies ([`has_offsets`]): `C_PLAIN`
/// sensitivity columns without the offsets of (F7) (0 when only the residuals are wanted),
/// [`C_OFFSET`] with them, over `cells`' runs.
pub(super) fn visit_fit<const P: usize, const C_PLAIN: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    limit: usize,
    theta: &[f32; P],
    trace: f32,
    cells: &Cells,
    seen: &mut impl Visitor<P>,
) -> Option<Normal<P>> {
    if has_offsets(P) {
        let layout = Layout {
            offset: *cells,
            ..Layout::PLAIN
        };
        normal_visit::<P, C_OFFSET>(blocks, rule, limit, theta, trace, layout, seen)
    } else {
        normal_visit::<P, C_PLAIN>(blocks, rule, limit, theta, trace, Layout::PLAIN, seen)
    }
}

/// [`normal`] of the fit up to scale extended for its tests: `C = 12` a constant torque
/// ((F4)), inserted after the initial rate; `scale` the gyro's scale-factor errors ((F5)),
/// last. `theta` is the plain or bias model's parameters with those added.
pub(super) fn normal_extended<const P: usize, const C: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; P],
    trace: f32,
    scale: bool,
) -> Option<Normal<P>> {
    normal_visit::<P, C>(
        blocks,
        rule,
        blocks.len(),
        theta,
        trace,
        Layout {
            normalized: true,
            scale,
            offset: Cells::NONE,
        },
        &mut (),
    )
}

/// What the parameters beyond the plain or bias model hold, where their count cannot tell.
#[derive(Clone, Copy, Debug)]
pub(super) struct Layout {
    /// The trace is held (five entries; else six).
    pub(super) normalized: bool,
    /// The last three are the gyro's scale-factor errors of (F5).
    pub(super) scale: bool,
    /// With `C = 13`: the rotor momentum's errors of (F7), the last [`CELLS`] parameters.
    pub(super) offset: Cells,
}

impl Layout {
    /// The plain or bias model's own parameters.
    pub(super) const PLAIN: Layout = Layout {
        normalized: false,
        scale: false,
        offset: Cells::NONE,
    };
}

/// [`normal`], showing `seen` each block's residual on each axis in turn and then its node. With
/// `C = 12` the parameters hold a constant torque after the initial rate (`normalized`: the
/// trace is held, five entries; else six); with `scale` the last three are the gyro's
/// scale-factor errors `kappa` of (F5); with `C = 13` the last [`CELLS`] are the rotor
/// momentum's errors `d_c` of (F7) over `layout.offset`'s runs (six entries).
///
/// Never inlined: each instantiation's frame (its RK4 stages of `C` columns, its normal
/// sums) then lives only while it runs; inlined into [`normal`], which holds two of them, the
/// frames would add up and overflow the flight build's stack (`bench-mcu` runs it).
#[inline(never)]
pub(super) fn normal_visit<const P: usize, const C: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    limit: usize,
    theta: &[f32; P],
    trace: f32,
    layout: Layout,
    seen: &mut impl Visitor<P>,
) -> Option<Normal<P>> {
    let Layout {
        normalized,
        scale,
        offset,
    } = layout;
    let torque = C == C_TORQUE;
    let oc = if C == C_OFFSET { CELLS } else { 0 };
    // The entry count is told by `normalized` wherever the parameter count cannot tell it: a
    // torque (F4) or scale factors (F5) beyond the plain or bias layout (the torque test of a
    // biased fit up to scale has 14 parameters, which the count alone would read as six
    // entries, taking its tensor from the wrong slots).
    let m = if torque || scale || oc > 0 {
        if normalized {
            5
        } else {
            6
        }
    } else {
        entries_of(P)
    };
    let e6 = six(theta, trace, m);
    let j = tensor_of(&e6);
    let k = symmetric(inverse_pd(&j)?);
    let g = |i: usize| theta.get(i).copied().unwrap_or(0.0);
    let w0 = [g(m), g(m + 1), g(m + 2)];
    // (F7): the rotor momentum's offsets over the steady runs, the last `CELLS` parameters;
    // the model's momentum is the logged one plus `u sum_c d_c` over the runs that are on.
    let d: [f32; CELLS] = core::array::from_fn(|c| if oc > 0 { g(P - oc + c) } else { 0.0 });
    let shift = |on: [bool; CELLS]| {
        let mut t = 0.0f32;
        for (dc, o) in d.iter().zip(on) {
            if o {
                t += *dc;
            }
        }
        offset.u.map(|x| x * t)
    };
    // The model's momentum where the runs `on` are on: the logged one and their offsets.
    let shifted = |h: [f32; 3], on: [bool; CELLS]| if oc > 0 { add3(h, shift(on)) } else { h };
    let (h_first, _) = rotor_node(blocks, 0, rule.gyro_spread);
    let h_first = shifted(h_first, offset.at(0));
    let jw = mul(&j, w0);
    let mut x = Aug::<C> {
        l: [jw[0] + h_first[0], jw[1] + h_first[1], jw[2] + h_first[2]],
        lc: [0.0; 3],
        s: [[0.0; C]; 3],
    };
    // `dL(0)/dJ_c = E_c w0`, `dL(0)/dw0 = J` (no columns at all when only the cost is asked).
    for (i, (row, jrow)) in x.s.iter_mut().zip(j.iter()).enumerate() {
        for (c, dst) in row.iter_mut().enumerate().take(P0) {
            let v = if c < 6 {
                e_times(c, w0).get(i).copied()
            } else {
                jrow.get(c - 6).copied()
            };
            *dst = v.unwrap_or(0.0);
        }
    }
    // Layout: entries (m), initial rate (3), [torque (3)], [bias (3)].
    let tq = if torque { 3 } else { 0 };
    let q = if torque {
        [g(m + 3), g(m + 4), g(m + 5)]
    } else {
        [0.0f32; 3]
    };
    let sc = if scale { 3 } else { 0 };
    let kappa = if scale {
        [g(P - 3), g(P - 2), g(P - 1)]
    } else {
        [0.0f32; 3]
    };
    let biased = P == m + 6 + tq + sc + oc;
    let bias = if biased {
        [g(m + 3 + tq), g(m + 4 + tq), g(m + 5 + tq)]
    } else {
        [0.0f32; 3]
    };
    // Without a rotor momentum and a torque, (F1) keeps `|L|^2` and `L . J^-1 L`. The torque's
    // score test evaluates the extended model at zero torque: the same trajectory as the plain
    // model's, so the same restorations (without them its score would see the difference of
    // the two integrations and reject free bodies on fast tumbles). A rotor
    // momentum, from the first node on, gives them up below.
    // (F7) is for flights with a rotor, which give the invariants up anyway.
    let mut invariants = (q == [0.0; 3] && oc == 0).then(|| Invariants::new(&k, &x));
    let mut forcing = Forcing {
        torque: q,
        offset: offset.u,
        on: [false; CELLS],
    };
    // (F7): `Sigma_d(t_0) = u` for an error on from the first block.
    if oc > 0 {
        for (c, on) in offset.at(0).iter().enumerate() {
            if *on {
                for (row, v) in x.s.iter_mut().zip(offset.u) {
                    if let Some(dst) = row.get_mut(P0 + c) {
                        *dst = v;
                    }
                }
            }
        }
    }
    // (F7): `J^-1 u`, what `dw/dd_c` loses where error `c` is on.
    let ku = if oc > 0 { mul(&k, offset.u) } else { [0.0; 3] };
    let mut sums = NormalSums::<P>::EMPTY;
    // (F12): a walking bias's filter, one per axis, its gains shared.
    let walking = rule.walk > 0.0;
    let mut gains = walk::Gains::new(rule.walk);
    let mut filtered = [walk::Filtered::<P>::ZERO; 3];
    // Node b-1: block, rotor momentum at the mean time, its curvature, `|ybar|`.
    let mut prev: Option<(&Block<6>, [f32; 3], [f32; 3], f32)> = None;
    let mut hd = [0.0f32; 3];
    for (idx, b) in blocks.iter().enumerate().take(limit) {
        let (h, c) = rotor_node(blocks, idx, rule.gyro_spread);
        // A rotor that turns (a motor started after the release) does work on the body: the
        // energy is no longer the start's, even once it stops again.
        if h != [0.0; 3] || c != [0.0; 3] {
            invariants = None;
        }
        let w_here = norm(rate_of(b));
        if let Some((bp, hp, cp, w_prev)) = prev {
            let span = b.since(bp);
            if span > 0.0 {
                let seg = RotorSegment {
                    h0: shifted(hp, offset.between(idx)),
                    s: [
                        (h[0] - hp[0]) / span,
                        (h[1] - hp[1]) / span,
                        (h[2] - hp[2]) / span,
                    ],
                    c: [
                        0.5 * (c[0] + cp[0]),
                        0.5 * (c[1] + cp[1]),
                        0.5 * (c[2] + cp[2]),
                    ],
                    span,
                };
                hd = seg.rate_at_end();
                // The step count from the data and the fit's first guess ([`StepRule`]).
                let speed = rule.speed(w_prev.max(w_here), hp, h);
                let steps = substeps(span, speed);
                let dt = span / steps as f32;
                let mut tau = 0.0f32;
                if oc > 0 {
                    forcing.on = offset.between(idx);
                }
                for _ in 0..steps {
                    x = rk4(&k, &seg, &forcing, &x, tau, dt);
                    tau += dt;
                }
                // Every `RESTORE_EVERY` blocks, while no rotor momentum has been seen.
                if let (Some(inv), 0) = (&invariants, idx % RESTORE_EVERY) {
                    inv.restore(&k, &mut x);
                }
            }
        }
        let hdd = c;
        prev = Some((b, h, c, w_here));
        // The model's momentum at the node: the logged one and the offset of the run it is in.
        let on_here = if oc > 0 {
            offset.at(idx)
        } else {
            [false; CELLS]
        };
        let h_model = shifted(h, on_here);
        let w = mul(&k, sub(x.l, h_model));
        let u = rate_sens(&k, &x, w);
        // (B1): the block mean of w is w(tbar) + v/2 w''(tbar) + ... (`block_mean_correction`).
        let corr = block_mean_correction(&k, x.l, [h_model, hd, hdd], &b.time_moments());
        // The low part of `w`: the momentum is `l - lc` (compensated), so `w - J^-1 lc`.
        let w_lo = mul(&k, x.lc);
        let mut rows = [[0.0f32; P]; 3];
        // The block's weight: its samples, or with a walk the inverse of its innovations'
        // variance ((F12)).
        let (weight, gain) = if walking {
            let (v, gain) = gains.next(b.n);
            (1.0 / v, gain)
        } else {
            (b.n, 0.0)
        };
        for i in 0..3 {
            // (F5): the gyro reads (1 + kappa_i) times the block mean of w_i.
            let mean_w = w[i] + corr[i];
            // The block mean less `w` without rounding the mean first ([`Block::deviation`]:
            // a rounded mean of a rate of 25 rad/s is off by up to 1e-6 rad/s, on residuals of
            // 1e-3, and the cost moved by some 1e-4 of itself between evaluations on that
            // alone), with `w`'s low part.
            let dev = b.deviation(i, w[i]) + w_lo[i] - corr[i] - bias[i];
            let r = if scale { dev - kappa[i] * mean_w } else { dev };
            let mut row = [0.0f32; P];
            let ui = &u[i];
            let uc = |c: usize| ui.get(c).copied().unwrap_or(0.0);
            if m == 6 {
                // Entries, initial rate and torque: the columns as they are; the momentum's
                // errors go last.
                for (dst, src) in row.iter_mut().zip(ui.iter()).take(C - oc) {
                    *dst = *src;
                }
                if oc > 0 {
                    // (F7): `dw/dd_c = J^-1 (Sigma_d - u)` where error `c` is on.
                    for (c, on) in on_here.iter().enumerate() {
                        let v = uc(P0 + c) - if *on { ku[i] } else { 0.0 };
                        if let Some(dst) = row.get_mut(P - oc + c) {
                            *dst = v;
                        }
                    }
                }
            } else {
                // Trace held: Jzz moves against Jxx and Jyy.
                let cols = [
                    uc(0) - uc(2),
                    uc(1) - uc(2),
                    uc(3),
                    uc(4),
                    uc(5),
                    uc(6),
                    uc(7),
                    uc(8),
                    uc(9),
                    uc(10),
                    uc(11),
                ];
                for (dst, src) in row.iter_mut().zip(cols.iter().take(8 + tq)) {
                    *dst = *src;
                }
            }
            if biased {
                if let Some(dst) = row.get_mut(m + 3 + tq + i) {
                    *dst = 1.0;
                }
            }
            if scale {
                if let Some(dst) = row.get_mut(P - 3 + i) {
                    *dst = mean_w;
                }
            }
            // (F12): the residual and its row as the walk's innovations.
            let r = match filtered.get_mut(i) {
                Some(f) if walking => f.innovate(gain, r, &mut row),
                _ => r,
            };
            seen.residual(i, r);
            if C == 0 {
                sums.add_cost(weight, r);
            } else {
                sums.add(weight, r, &row);
            }
            if let Some(dst) = rows.get_mut(i) {
                *dst = row;
            }
        }
        // `dL/dw0 = Phi J` ((F3) from `Sigma(t_0) = J`): the initial rates' columns.
        let col = |i: usize, c: usize| x.s.get(i).and_then(|r| r.get(c)).copied().unwrap_or(0.0);
        let s_w0 = core::array::from_fn(|i| core::array::from_fn(|c| col(i, 6 + c)));
        seen.node(&Node {
            index: idx,
            weight,
            rows: &rows,
            l: x.l,
            k: &k,
            s_w0,
        });
    }
    sums.finish()
}

/// What [`normal_visit`] shows besides its sums: each block's residuals, then its node.
pub(super) trait Visitor<const P: usize> {
    /// The current block's residual `r` on axis `i`.
    fn residual(&mut self, _i: usize, _r: f32) {}
    /// The current block's node, once its three residuals are in.
    fn node(&mut self, _node: &Node<'_, P>) {}
}

/// The sums alone.
impl<const P: usize> Visitor<P> for () {}

/// Each node to a function.
pub(super) struct OnNode<F>(pub(super) F);

impl<const P: usize, F: FnMut(&Node<'_, P>)> Visitor<P> for OnNode<F> {
    fn node(&mut self, node: &Node<'_, P>) {
        (self.0)(node);
    }
}

/// [`residual_lag1`]'s sums: the previous residual per axis, `sum r_b r_(b-1)` and `sum r^2`.
pub(super) struct Lag1 {
    pub(super) prev: [Option<f32>; 3],
    pub(super) num: f32,
    pub(super) den: f32,
}

impl<const P: usize> Visitor<P> for Lag1 {
    fn residual(&mut self, i: usize, r: f32) {
        if let Some(slot) = self.prev.get_mut(i) {
            if let Some(p) = *slot {
                self.num += p * r;
            }
            *slot = Some(r);
        }
        self.den += r * r;
    }
}

/// [`score_inflation`]'s sums ((F10)): the blocks' scores `n_b R_b^T r_b` summed over
/// batches of `len` consecutive blocks, each batch's sum `G_k` carried through `F^-1`, and
/// the squares of `F^-1 G_k` summed over the batches.
pub(super) struct BatchScores<'a, const P: usize> {
    /// `F^-1` at the optimum (unit noise).
    pub(super) finv: &'a Sym<P>,
    /// Blocks per batch (at least 1).
    pub(super) len: usize,
    /// Blocks in the open batch.
    pub(super) open: usize,
    /// The current block's residuals.
    pub(super) r: [f32; 3],
    /// The open batch's score sum.
    pub(super) g: [f32; P],
    /// `sum_k (F^-1 G_k)_i^2`.
    pub(super) acc: [f32; P],
    /// Batches closed.
    pub(super) batches: u32,
}

impl<const P: usize> BatchScores<'_, P> {
    /// Closes the open batch (if it holds any block) into `acc`.
    pub(super) fn flush(&mut self) {
        if self.open == 0 {
            return;
        }
        for (row, a) in self.finv.iter().zip(self.acc.iter_mut()) {
            let mut x = 0.0f32;
            for (f, g) in row.iter().zip(self.g) {
                x += f * g;
            }
            *a += x * x;
        }
        self.g = [0.0; P];
        self.open = 0;
        self.batches += 1;
    }
}

impl<const P: usize> Visitor<P> for BatchScores<'_, P> {
    fn residual(&mut self, i: usize, r: f32) {
        if let Some(slot) = self.r.get_mut(i) {
            *slot = r;
        }
    }

    fn node(&mut self, node: &Node<'_, P>) {
        for (p, g) in self.g.iter_mut().enumerate() {
            let mut s = 0.0f32;
            for (row, r) in node.rows.iter().zip(self.r) {
                s += row.get(p).copied().unwrap_or(0.0) * r;
            }
            *g += node.weight * s;
        }
        self.open += 1;
        if self.open >= self.len {
            self.flush();
        }
    }
}

/// A block's node as [`normal_visit`] leaves it, for [`input_cov`].
pub(super) struct Node<'a, const P: usize> {
    /// The block's index.
    pub(super) index: usize,
    /// Its sample count (the residuals' weight).
    pub(super) weight: f32,
    /// `dw/dtheta` at the node, one row per axis.
    pub(super) rows: &'a [[f32; P]; 3],
    /// The momentum `L`.
    pub(super) l: [f32; 3],
    /// `J^-1`.
    pub(super) k: &'a Mat3,
    /// `dL/dw(t_0)`: the transition `Phi(t, t_0)` of (F3) times `J` (absolute fits only).
    pub(super) s_w0: Mat3,
}

/// The cost alone of all the blocks at `theta` (no sensitivities: a tenth of [`normal`]'s
/// work), for choosing between first guesses.
pub(super) fn cost_only<const P: usize>(
    blocks: &[Block<6>],
    rule: &StepRule,
    theta: &[f32; P],
    trace: f32,
) -> Option<f32> {
    normal_visit::<P, 0>(
        blocks,
        rule,
        blocks.len(),
        theta,
        trace,
        Layout::PLAIN,
        &mut (),
    )
    .map(|(cost, _, _)| cost)
}

/// The first `M` entries of `v` (zeros past its end).
pub(super) fn leading<const M: usize>(v: &[f32]) -> [f32; M] {
    core::array::from_fn(|i| v.get(i).copied().unwrap_or(0.0))
}

/// The leading `M x M` block of the `A x A` matrix `c`.
pub(super) fn leading_block<const A: usize, const M: usize>(c: &[[f32; A]; A]) -> Sym<M> {
    core::array::from_fn(|i| c.get(i).map_or([0.0; M], |row| leading(row)))
}
