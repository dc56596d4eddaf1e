//! [`crate::Method::Scalar`]: the original path, kept as the benchmark's baseline. Every start of a
//! row is integrated with one scalar model call per start and RK4 stage (`tfs_dynamics::rk4_step`
//! on eight starts side by side for instruction-level parallelism), rows in parallel.

use tfs_dynamics::{Rk4Scratch, SecondOrderSystem, rk4_step};

use crate::grid::{BasinConfig, CHECK_EVERY, Judge, Label};

/// Independent trajectories integrated side by side in one row by [`crate::Method::Scalar`]
/// (instruction-level parallelism; each lane's arithmetic is exactly that of a lone trajectory).
pub(crate) const LANES: usize = 8;

/// `LANES` copies of a `d`-DOF system side by side: lane `l` owns components `l·d .. (l+1)·d`.
struct Lanes<'a, S: ?Sized> {
    sys: &'a S,
    d: usize,
    k: usize,
}

impl<S: SecondOrderSystem + ?Sized> SecondOrderSystem for Lanes<'_, S> {
    fn dofs(&self) -> usize {
        self.d * self.k
    }
    fn inputs(&self) -> usize {
        self.sys.inputs()
    }
    #[inline]
    fn accel(&self, t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        let d = self.d;
        for ((xl, vl), al) in x
            .chunks_exact(d)
            .zip(v.chunks_exact(d))
            .zip(a.chunks_exact_mut(d))
        {
            self.sys.accel(t, xl, vl, u, al);
        }
    }
}

/// [`crate::Method::Scalar`]: labels the `out.len()` starts written by `start(i, x, v)`, integrating
/// up to `lanes` of them at once with [`rk4_step`] (zero input; the unforced dynamics are
/// treated as autonomous and `t = 0` is passed). Each start's label depends only on that start.
pub(crate) fn run_row<S, J, F>(
    sys: &S,
    judge: &J,
    cfg: &BasinConfig,
    lanes: usize,
    start: F,
    out: &mut [Label],
) where
    S: SecondOrderSystem + ?Sized,
    J: Judge + ?Sized,
    F: Fn(usize, &mut [f64], &mut [f64]),
{
    let d = sys.dofs();
    if out.is_empty() {
        return;
    }
    let k = lanes.clamp(1, out.len());
    let multi = Lanes { sys, d, k };
    let mut scratch = Rk4Scratch::new(d * k);
    let u = vec![0.0; sys.inputs()];
    let (mut x, mut v) = (vec![0.0; d * k], vec![0.0; d * k]);
    let mut cell: Vec<Option<usize>> = vec![None; k];
    let mut steps = vec![0usize; k];
    let mut next = 0usize;
    let max_steps = cfg.steps();
    let early = cfg.early_exit && judge.early();
    let h = cfg.dt;
    // Fill every lane (k ≤ out.len(), so every lane gets a start).
    for (l, c) in cell.iter_mut().enumerate() {
        let r = l * d..(l + 1) * d;
        start(next, &mut x[r.clone()], &mut v[r]);
        *c = Some(next);
        next += 1;
    }
    loop {
        let mut active = false;
        for l in 0..k {
            let r = l * d..(l + 1) * d;
            while let Some(c) = cell[l] {
                let label = if early && steps[l] % CHECK_EVERY == 0 {
                    judge
                        .trapped(&x[r.clone()], &v[r.clone()])
                        .map(Label::State)
                } else {
                    None
                };
                let label = match label {
                    Some(lab) => Some(lab),
                    None if steps[l] >= max_steps => {
                        Some(judge.at_cap(&x[r.clone()], &v[r.clone()]))
                    }
                    None => None,
                };
                let Some(label) = label else {
                    active = true;
                    break;
                };
                out[c] = label;
                cell[l] = None;
                if next < out.len() {
                    start(next, &mut x[r.clone()], &mut v[r.clone()]);
                    cell[l] = Some(next);
                    steps[l] = 0;
                    next += 1;
                }
            }
        }
        if !active {
            break;
        }
        rk4_step(&multi, 0.0, h, &mut x, &mut v, &u, &u, &u, &mut scratch);
        for l in 0..k {
            if let Some(c) = cell[l] {
                steps[l] += 1;
                let r = l * d..(l + 1) * d;
                if judge.blown(&x[r.clone()], &v[r.clone()]) {
                    out[c] = Label::Diverged;
                    // Restart the lane from a finite state: the next cell, or lane-idle.
                    cell[l] = None;
                    if next < out.len() {
                        start(next, &mut x[r.clone()], &mut v[r]);
                        cell[l] = Some(next);
                        steps[l] = 0;
                        next += 1;
                    } else {
                        x[r.clone()].fill(0.0);
                        v[r].fill(0.0);
                    }
                }
            }
        }
    }
}
