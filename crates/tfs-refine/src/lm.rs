//! Multiple-shooting least-squares problem, block-structured normal equations and the
//! Levenberg–Marquardt loop.

use faer::Mat;
use faer::linalg::solvers::Solve;
use rayon::prelude::*;
use tfs_dynamics::{Rk4Scratch, SampledInput, rk4_step};

use crate::sens::{Augmented, Structure};

/// One training record prepared for fitting.
pub(crate) struct Prepared {
    pub input: SampledInput,
    pub t0: f64,
    pub dt: f64,
    /// Measured displacement per DOF.
    pub xm: Vec<Vec<f64>>,
    /// Smoothed velocity estimate per DOF (segment initial guesses).
    pub vm: Vec<Vec<f64>>,
    /// Each internal state computed along the smoothed velocity from rest (segment initial
    /// guesses).
    pub zm: Vec<Vec<f64>>,
    /// Residual weight per DOF.
    pub w: Vec<f64>,
}

/// A shooting segment: samples `k0..=k1` of record `rec`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Segment {
    pub rec: usize,
    pub k0: usize,
    pub k1: usize,
    /// True if the next segment continues this record (a continuity defect at `k1`).
    pub linked: bool,
}

/// The least-squares problem: unknowns
/// `p = [coefficients (P) | state parameters (R) | per segment (x0, v0, z0) (2n + m)]`, all
/// scaled (`c_j = pscale_j p_j`, `x0_i = xs_i p`, `v0_i = vs_i p`, `z0_j = zs_j p`).
pub(crate) struct Problem<'a> {
    pub st: &'a Structure,
    pub recs: &'a [Prepared],
    pub segs: Vec<Segment>,
    pub pscale: Vec<f64>,
    pub xs: Vec<f64>,
    pub vs: Vec<f64>,
    /// Scales of the internal states.
    pub zs: Vec<f64>,
    pub defect_weight: f64,
    pub substeps: usize,
    /// Blow-up limit on |x_i| / xs_i and |v_i| / vs_i.
    pub limit: f64,
}

/// Per-segment contribution to the normal equations.
struct SegNormal {
    cost: f64,
    /// Local normal matrix over `[model unknowns | own state]` (Q × Q).
    l: Mat<f64>,
    gl: Vec<f64>,
    /// Coupling of local columns to the next segment's state (Q × (2n + m)), if linked.
    next: Option<Mat<f64>>,
    /// Gradient contribution to the next segment's state (−w_d · defect).
    gnext: Vec<f64>,
    defect2: f64,
}

/// Assembled, block-structured normal equations `H δ = -g` pieces.
pub(crate) struct Normal {
    pub cost: f64,
    pub defect_rms: f64,
    hcc: Mat<f64>,
    gc: Vec<f64>,
    /// Per segment (`S = 2n + m` states, `P` model unknowns): A_s (S × S), C_s (S × P),
    /// B_s (S × S, coupling to s+1), b_s.
    a: Vec<Mat<f64>>,
    c: Vec<Mat<f64>>,
    b: Vec<Option<Mat<f64>>>,
    gs: Vec<Vec<f64>>,
}

impl Problem<'_> {
    pub fn n_params(&self) -> usize {
        self.st.params() + self.st.seg_states() * self.segs.len()
    }

    /// Initial unknowns from the model's unknowns (coefficients, state parameters) and data.
    pub fn initial(&self, coefs: &[f64]) -> Vec<f64> {
        let n = self.st.n;
        let mut p: Vec<f64> = coefs.iter().zip(&self.pscale).map(|(c, s)| c / s).collect();
        for sg in &self.segs {
            let r = &self.recs[sg.rec];
            for i in 0..n {
                p.push(r.xm[i][sg.k0] / self.xs[i]);
            }
            for i in 0..n {
                p.push(r.vm[i][sg.k0] / self.vs[i]);
            }
            for j in 0..self.st.m {
                p.push(r.zm[j][sg.k0] / self.zs[j]);
            }
        }
        p
    }

    /// The model's unknowns: coefficients, then state parameters.
    pub fn coefs(&self, p: &[f64]) -> Vec<f64> {
        p[..self.st.params()]
            .iter()
            .zip(&self.pscale)
            .map(|(p, s)| p * s)
            .collect()
    }

    /// Scale of segment state `c` (`x0`, `v0`, then the states' start).
    fn state_scale(&self, c: usize) -> f64 {
        let n = self.st.n;
        if c < n {
            self.xs[c]
        } else if c < 2 * n {
            self.vs[c - n]
        } else {
            self.zs[c - 2 * n]
        }
    }

    /// Where segment state `c` lives in the system's `(x, v)`: `(false, i)` for `x[i]`,
    /// `(true, i)` for `v[i]` (a state's value is the velocity of its auxiliary coordinate).
    fn state_slot(&self, c: usize) -> (bool, usize) {
        let n = self.st.n;
        // v0 of DOF i is `v[i]`, the start of state j is `v[n + j]`: both at `c − n`.
        if c < n { (false, c) } else { (true, c - n) }
    }

    /// Simulates one segment with sensitivities and accumulates its normal-equation blocks;
    /// `None` on blow-up, non-finite values or invalid state parameters.
    fn segment(&self, s: usize, model: &[f64], p: &[f64]) -> Option<SegNormal> {
        let (n, nn) = (self.st.n, self.st.nn);
        let np = self.st.params();
        let pc = self.st.n_coefs();
        let ns = self.st.seg_states();
        let q = np + ns;
        let sg = self.segs[s];
        let rec = &self.recs[sg.rec];
        let sys = Augmented::new(self.st, &model[..pc], &model[pc..], &self.pscale, q)?;
        let dim = nn * (1 + q);
        let mut x = vec![0.0; dim];
        let mut v = vec![0.0; dim];
        let off = np + ns * s;
        for c in 0..ns {
            let (is_v, i) = self.state_slot(c);
            let sc = self.state_scale(c);
            // The state and its derivative with respect to its own (scaled) unknown.
            if is_v {
                v[i] = p[off + c] * sc;
                v[nn + (np + c) * nn + i] = sc;
            } else {
                x[i] = p[off + c] * sc;
                x[nn + (np + c) * nn + i] = sc;
            }
        }
        let mut scratch = Rk4Scratch::new(dim);
        let ni = self.st.inputs;
        let (mut u0, mut um, mut u1) = (vec![0.0; ni], vec![0.0; ni], vec![0.0; ni]);
        let h = rec.dt / self.substeps as f64;
        let mut l = Mat::<f64>::zeros(q, q);
        let mut gl = vec![0.0; q];
        let mut cost = 0.0;
        let mut row = vec![0.0; q];
        let last = if sg.linked { sg.k1 } else { sg.k1 + 1 };
        let mut k = sg.k0;
        loop {
            if k < last {
                for i in 0..n {
                    let r = rec.w[i] * (x[i] - rec.xm[i][k]);
                    for (qq, rw) in row.iter_mut().enumerate() {
                        *rw = rec.w[i] * x[nn + qq * nn + i];
                    }
                    accumulate(&mut l, &mut gl, &row, r);
                    cost += r * r;
                }
            }
            if k == sg.k1 {
                break;
            }
            let t_k = rec.t0 + k as f64 * rec.dt;
            for m in 0..self.substeps {
                let t = t_k + m as f64 * h;
                rec.input.eval(t, &mut u0);
                rec.input.eval(t + 0.5 * h, &mut um);
                rec.input.eval(t + h, &mut u1);
                rk4_step(&sys, t, h, &mut x, &mut v, &u0, &um, &u1, &mut scratch);
            }
            for c in 0..ns {
                let (is_v, i) = self.state_slot(c);
                let val = if is_v { v[i] } else { x[i] };
                if !(val.is_finite() && val.abs() <= self.limit * self.state_scale(c)) {
                    return None;
                }
            }
            k += 1;
        }
        let mut next = None;
        let mut gnext = Vec::new();
        let mut defect2 = 0.0;
        if sg.linked {
            let wd = self.defect_weight;
            let offn = off + ns;
            let mut cn = Mat::<f64>::zeros(q, ns);
            gnext = vec![0.0; ns];
            for c in 0..ns {
                let (is_v, i) = self.state_slot(c);
                let sc = self.state_scale(c);
                let (val, sens): (f64, &[f64]) = if is_v {
                    (v[i], &v[nn..])
                } else {
                    (x[i], &x[nn..])
                };
                let d = wd * (val / sc - p[offn + c]);
                for (qq, rw) in row.iter_mut().enumerate() {
                    *rw = wd * sens[qq * nn + i] / sc;
                }
                accumulate(&mut l, &mut gl, &row, d);
                for (qq, rw) in row.iter().enumerate() {
                    cn[(qq, c)] -= wd * rw;
                }
                gnext[c] -= wd * d;
                cost += d * d;
                defect2 += (d / wd) * (d / wd);
            }
            next = Some(cn);
        }
        if !cost.is_finite() || gl.iter().any(|g| !g.is_finite()) {
            return None;
        }
        Some(SegNormal {
            cost,
            l,
            gl,
            next,
            gnext,
            defect2,
        })
    }

    /// Evaluates cost, gradient and Gauss–Newton matrix at `p`; `None` if any segment blows up.
    pub fn normal(&self, p: &[f64]) -> Option<Normal> {
        let n2 = self.st.seg_states();
        let np = self.st.params();
        let coefs = self.coefs(p);
        let parts: Vec<Option<SegNormal>> = (0..self.segs.len())
            .into_par_iter()
            .map(|s| self.segment(s, &coefs, p))
            .collect();
        let mut hcc = Mat::<f64>::zeros(np, np);
        let mut gc = vec![0.0; np];
        let ns = self.segs.len();
        let mut a = Vec::with_capacity(ns);
        let mut c = Vec::with_capacity(ns);
        let mut b = Vec::with_capacity(ns);
        let mut gs = Vec::with_capacity(ns);
        let mut cost = 0.0;
        let mut d2 = 0.0;
        let mut nd = 0usize;
        let mut pending: Option<(Mat<f64>, Vec<f64>)> = None; // (C from prev, g) for this seg
        let wd2 = self.defect_weight * self.defect_weight;
        for part in parts {
            let sn = part?;
            cost += sn.cost;
            d2 += sn.defect2;
            for i in 0..np {
                gc[i] += sn.gl[i];
                for j in 0..np {
                    hcc[(i, j)] += sn.l[(i, j)];
                }
            }
            let mut aa = Mat::<f64>::from_fn(n2, n2, |i, j| sn.l[(np + i, np + j)]);
            let mut cc = Mat::<f64>::from_fn(n2, np, |i, j| sn.l[(np + i, j)]);
            let mut g: Vec<f64> = sn.gl[np..].to_vec();
            if let Some((cprev, gprev)) = pending.take() {
                for i in 0..n2 {
                    aa[(i, i)] += wd2;
                    g[i] += gprev[i];
                    for j in 0..np {
                        cc[(i, j)] += cprev[(j, i)];
                    }
                }
            }
            if let Some(cn) = &sn.next {
                nd += n2;
                let bb = Mat::<f64>::from_fn(n2, n2, |i, j| cn[(np + i, j)]);
                let cnext = Mat::<f64>::from_fn(np, n2, |i, j| cn[(i, j)]);
                pending = Some((cnext, sn.gnext.clone()));
                b.push(Some(bb));
            } else {
                b.push(None);
            }
            a.push(aa);
            c.push(cc);
            gs.push(g);
        }
        let cost = 0.5 * cost;
        if !cost.is_finite() {
            return None;
        }
        Some(Normal {
            cost,
            defect_rms: if nd > 0 { (d2 / nd as f64).sqrt() } else { 0.0 },
            hcc,
            gc,
            a,
            c,
            b,
            gs,
        })
    }

    /// Diagonal of H in unknown order.
    pub fn diag(&self, nm: &Normal) -> Vec<f64> {
        let n2 = self.st.seg_states();
        let np = self.st.params();
        let mut d: Vec<f64> = (0..np).map(|i| nm.hcc[(i, i)]).collect();
        for a in &nm.a {
            d.extend((0..n2).map(|i| a[(i, i)]));
        }
        d
    }

    /// Gradient `g = Jᵀ r` in unknown order.
    pub fn gradient(&self, nm: &Normal) -> Vec<f64> {
        let mut g = nm.gc.clone();
        for gs in &nm.gs {
            g.extend_from_slice(gs);
        }
        g
    }

    /// Solves `(H + diag(damp)) δ = −g` by block elimination of the segment states
    /// (block-tridiagonal with a dense coefficient border); `None` if a pivot block is not
    /// positive definite.
    pub fn solve(&self, nm: &Normal, damp: &[f64]) -> Option<Vec<f64>> {
        let n2 = self.st.seg_states();
        let np = self.st.params();
        let ns = nm.a.len();
        let mut hcc = nm.hcc.clone();
        for i in 0..np {
            hcc[(i, i)] += damp[i];
        }
        let mut rc: Vec<f64> = nm.gc.iter().map(|g| -g).collect();
        // Forward elimination. Store per segment: factor of Ã_s, C̃_s, b̃_s.
        let mut at: Vec<Mat<f64>> = Vec::with_capacity(ns);
        let mut ct: Vec<Mat<f64>> = Vec::with_capacity(ns);
        let mut bt: Vec<Mat<f64>> = Vec::with_capacity(ns);
        // Solutions Ã⁻¹ [B | C̃ | b̃] of the previous segment.
        let mut prev: Option<Mat<f64>> = None;
        for s in 0..ns {
            let mut aa = nm.a[s].clone();
            for i in 0..n2 {
                aa[(i, i)] += damp[np + s * n2 + i];
            }
            let mut cc = nm.c[s].clone();
            let mut bb = Mat::<f64>::from_fn(n2, 1, |i, _| -nm.gs[s][i]);
            if let (Some(pz), Some(bprev)) =
                (&prev, s.checked_sub(1).and_then(|j| nm.b[j].as_ref()))
            {
                // pz = Ã_{s-1}⁻¹ [B_{s-1} | C̃_{s-1} | b̃_{s-1}]
                let bt_prev = bprev.transpose();
                let zb = pz.subcols(0, n2);
                let zc = pz.subcols(n2, np);
                let zr = pz.subcols(n2 + np, 1);
                aa -= bt_prev * zb;
                cc -= bt_prev * zc;
                bb -= bt_prev * zr;
            }
            let llt = aa.llt(faer::Side::Lower).ok()?;
            let bnext = nm.b[s].clone().unwrap_or_else(|| Mat::<f64>::zeros(n2, n2));
            let mut rhs = Mat::<f64>::zeros(n2, n2 + np + 1);
            rhs.subcols_mut(0, n2).copy_from(&bnext);
            rhs.subcols_mut(n2, np).copy_from(&cc);
            rhs.subcols_mut(n2 + np, 1).copy_from(&bb);
            let z = llt.solve(&rhs);
            // Schur update of the coefficient block.
            let zc = z.subcols(n2, np);
            let zr = z.subcols(n2 + np, 1);
            hcc -= cc.transpose() * zc;
            let upd = cc.transpose() * zr;
            for i in 0..np {
                rc[i] -= upd[(i, 0)];
            }
            at.push(aa);
            ct.push(cc);
            bt.push(bb);
            prev = if nm.b[s].is_some() { Some(z) } else { None };
        }
        let mut dc = vec![0.0; np];
        if np > 0 {
            let llt = hcc.llt(faer::Side::Lower).ok()?;
            let r = Mat::<f64>::from_fn(np, 1, |i, _| rc[i]);
            let z = llt.solve(&r);
            for i in 0..np {
                dc[i] = z[(i, 0)];
            }
        }
        let dcm = Mat::<f64>::from_fn(np, 1, |i, _| dc[i]);
        let mut ds = vec![vec![0.0; n2]; ns];
        for s in (0..ns).rev() {
            let mut r = bt[s].clone();
            r -= &ct[s] * &dcm;
            if let Some(bn) = &nm.b[s] {
                let dn = Mat::<f64>::from_fn(n2, 1, |i, _| ds[s + 1][i]);
                r -= bn * dn;
            }
            let llt = at[s].llt(faer::Side::Lower).ok()?;
            let z = llt.solve(&r);
            for i in 0..n2 {
                ds[s][i] = z[(i, 0)];
            }
        }
        let mut out = dc;
        for d in ds {
            out.extend(d);
        }
        if out.iter().all(|v| v.is_finite()) {
            Some(out)
        } else {
            None
        }
    }
}

fn accumulate(l: &mut Mat<f64>, g: &mut [f64], row: &[f64], r: f64) {
    let q = row.len();
    for i in 0..q {
        let ri = row[i];
        if ri == 0.0 {
            continue;
        }
        g[i] += ri * r;
        for j in 0..q {
            l[(i, j)] += ri * row[j];
        }
    }
}

/// Outcome of one LM run.
pub(crate) struct LmOutcome {
    pub p: Vec<f64>,
    pub cost0: f64,
    pub cost: f64,
    pub iterations: usize,
    pub converged: bool,
    pub message: String,
    pub defect_rms: f64,
}

/// LM settings.
pub(crate) struct LmSettings {
    pub max_iterations: usize,
    pub ftol: f64,
    pub gtol: f64,
}

/// Marquardt scaling `D² = diag(JᵀJ)` at the current point, floored at 1e-12 of its largest entry.
/// (Not the max-so-far variant: an unstable start has enormous sensitivities that would keep the
/// steps tiny long after the model has been stabilised.)
fn scaling(pb: &Problem, nm: &Normal) -> Vec<f64> {
    let d = pb.diag(nm);
    let floor = d.iter().copied().fold(0.0, f64::max) * 1e-12 + 1e-300;
    d.iter().map(|v| v.max(floor)).collect()
}

/// Levenberg–Marquardt with Marquardt scaling `D² = diag(JᵀJ)` and Nielsen's
/// trust-region-style damping update. Blow-ups count as rejected steps.
pub(crate) fn levenberg_marquardt(
    pb: &Problem,
    p0: Vec<f64>,
    set: &LmSettings,
) -> Option<LmOutcome> {
    let mut p = p0;
    let mut nm = pb.normal(&p)?;
    let cost0 = nm.cost;
    let mut dscale = scaling(pb, &nm);
    let mut mu = 1e-3;
    let mut nu = 2.0;
    let mut iterations = 0;
    let mut converged = false;
    let mut message = String::from("maximum iterations reached");
    while iterations < set.max_iterations {
        let g = pb.gradient(&nm);
        let gmax = g
            .iter()
            .zip(&dscale)
            .map(|(g, d)| g.abs() / d.sqrt())
            .fold(0.0, f64::max);
        if gmax <= set.gtol * (2.0 * nm.cost).sqrt().max(1e-300) {
            converged = true;
            message = "scaled gradient below tolerance".into();
            break;
        }
        iterations += 1;
        let damp: Vec<f64> = dscale.iter().map(|d| mu * d).collect();
        let trial = pb.solve(&nm, &damp).and_then(|delta| {
            let pn: Vec<f64> = p.iter().zip(&delta).map(|(a, b)| a + b).collect();
            let pred: f64 = 0.5
                * delta
                    .iter()
                    .zip(&damp)
                    .zip(&g)
                    .map(|((d, dm), g)| d * (dm * d - g))
                    .sum::<f64>();
            pb.normal(&pn).map(|n2| (pn, n2, pred))
        });
        match trial {
            Some((pn, n2, pred)) if n2.cost < nm.cost => {
                let rho = (nm.cost - n2.cost) / pred.max(1e-300);
                let rel = (nm.cost - n2.cost) / nm.cost.max(1e-300);
                p = pn;
                nm = n2;
                dscale = scaling(pb, &nm);
                mu *= (1.0f64 / 3.0).max(1.0 - (2.0 * rho - 1.0).powi(3));
                nu = 2.0;
                if rel < set.ftol {
                    converged = true;
                    message = "relative cost decrease below tolerance".into();
                    break;
                }
            }
            _ => {
                mu *= nu;
                nu *= 2.0;
                if mu > 1e16 {
                    converged = true;
                    message = "no further decrease possible (damping at its limit)".into();
                    break;
                }
            }
        }
    }
    Some(LmOutcome {
        p,
        cost0,
        cost: nm.cost,
        iterations,
        converged,
        message,
        defect_rms: nm.defect_rms,
    })
}

#[cfg(test)]
impl Problem<'_> {
    /// The full Gauss–Newton matrix, assembled densely from the blocks (tests only).
    pub fn dense(&self, nm: &Normal) -> Mat<f64> {
        let n2 = self.st.seg_states();
        let np = self.st.params();
        let ns = nm.a.len();
        let dim = np + n2 * ns;
        let mut h = Mat::<f64>::zeros(dim, dim);
        for i in 0..np {
            for j in 0..np {
                h[(i, j)] = nm.hcc[(i, j)];
            }
        }
        for s in 0..ns {
            let o = np + s * n2;
            for i in 0..n2 {
                for j in 0..n2 {
                    h[(o + i, o + j)] = nm.a[s][(i, j)];
                    if let Some(b) = &nm.b[s] {
                        h[(o + i, o + n2 + j)] = b[(i, j)];
                        h[(o + n2 + j, o + i)] = b[(i, j)];
                    }
                }
                for j in 0..np {
                    h[(o + i, j)] = nm.c[s][(i, j)];
                    h[(j, o + i)] = nm.c[s][(i, j)];
                }
            }
        }
        h
    }
}
