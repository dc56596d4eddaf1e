//! Many starts integrated side by side: fixed-step RK4 on a block of lanes (one start per lane,
//! the state stored component-major so every stage is a loop across lanes that vectorises, the
//! block compiled for the widest SIMD the CPU offers), a finished lane refilled with the next
//! start. Each lane's arithmetic is exactly that of a lone trajectory under
//! `tfs_dynamics::rk4_step`, and its label depends only on its own start.

use rayon::prelude::*;
use tfs_dynamics::SecondOrderSystem;

use crate::grid::{CHECK_EVERY, Judge, Label};

/// Lanes per block: four AVX2 vectors of `f64`, enough independent work to hide latency.
const BLOCK: usize = 16;
/// Starts per parallel task: small enough to balance two cores on uneven trajectories, large
/// enough that a block's set-up is negligible.
const TASK: usize = 256;
const IDLE: usize = usize::MAX;

/// Writes start `k`'s displacements and velocities.
pub(crate) type StartFn<'s> = dyn Fn(usize, &mut [f64], &mut [f64]) + 's;

/// The result of one start: its label and how many times it changed region on the way
/// (see [`Judge::region`]); starts with the same label and the same count went the same way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Outcome {
    pub(crate) label: Label,
    pub(crate) turns: u32,
}

/// The fixed-step run shared by every start of a map.
pub(crate) struct Run<'a, S: ?Sized, J: ?Sized> {
    pub(crate) sys: &'a S,
    pub(crate) judge: &'a J,
    /// RK4 step.
    pub(crate) h: f64,
    /// Steps to `t_max`.
    pub(crate) max_steps: usize,
    /// Whether the trapping test may stop a start early.
    pub(crate) early: bool,
}

/// RK4 scratch for one block, component-major like the state.
struct Scratch {
    a: [Vec<f64>; 4],
    vs: [Vec<f64>; 3],
    xt: Vec<f64>,
}

impl<S, J> Run<'_, S, J>
where
    S: SecondOrderSystem + ?Sized,
    J: Judge + ?Sized,
{
    /// Labels the starts `cells` (in order; `start(c, x, v)` writes the start of cell `c`), in
    /// parallel tasks when `parallel`, calling `tick(n)` after each task of `n` starts.
    pub(crate) fn cells<F>(
        &self,
        cells: &[usize],
        parallel: bool,
        start: &F,
        tick: &(dyn Fn(usize) + Sync),
    ) -> Vec<Outcome>
    where
        F: Fn(usize, &mut [f64], &mut [f64]) + Sync,
    {
        let mut out = vec![
            Outcome {
                label: Label::Unsettled,
                turns: 0,
            };
            cells.len()
        ];
        let task = |(o, c): (&mut [Outcome], &[usize])| {
            self.block(&|k, x: &mut [f64], v: &mut [f64]| start(c[k], x, v), o);
            tick(c.len());
        };
        if parallel {
            out.par_chunks_mut(TASK)
                .zip(cells.par_chunks(TASK))
                .for_each(task);
        } else {
            out.chunks_mut(TASK).zip(cells.chunks(TASK)).for_each(task);
        }
        out
    }

    /// Labels `out.len()` starts written by `start(k, x, v)` on one block of lanes, compiled
    /// for the CPU's widest SIMD (same results on every instruction set: no fused operations).
    pub(crate) fn block(&self, start: &StartFn<'_>, out: &mut [Outcome]) {
        struct Job<'r, 'a, S: ?Sized, J: ?Sized> {
            run: &'r Run<'a, S, J>,
            start: &'r StartFn<'r>,
            out: &'r mut [Outcome],
        }
        impl<S: SecondOrderSystem + ?Sized, J: Judge + ?Sized> pulp::WithSimd for Job<'_, '_, S, J> {
            type Output = ();
            #[inline(always)]
            fn with_simd<Sd: pulp::Simd>(self, _simd: Sd) {
                self.run.block_inner(self.start, self.out);
            }
        }
        pulp::Arch::new().dispatch(Job {
            run: self,
            start,
            out,
        });
    }

    #[inline(always)]
    fn block_inner(&self, start: &StartFn<'_>, out: &mut [Outcome]) {
        let n = out.len();
        if n == 0 {
            return;
        }
        let d = self.sys.dofs();
        let w = BLOCK.min(n);
        let len = d * w;
        let (mut x, mut v) = (vec![0.0; len], vec![0.0; len]);
        let mut s = Scratch {
            a: std::array::from_fn(|_| vec![0.0; len]),
            vs: std::array::from_fn(|_| vec![0.0; len]),
            xt: vec![0.0; len],
        };
        let u = vec![0.0; self.sys.inputs()];
        let (mut xl, mut vl) = (vec![0.0; d], vec![0.0; d]);
        let mut cell = vec![IDLE; w];
        let mut born = vec![0usize; w];
        let mut region = vec![0u32; w];
        let mut turns = vec![0u32; w];
        let limit = self.judge.limit();
        let mut next = 0usize;
        let mut clock = 0usize;
        loop {
            // Decisions and refills. Lanes are (re)filled only at multiples of CHECK_EVERY, so
            // every lane's own step count is a multiple of it exactly when the clock is, and the
            // trapping test runs at the lane's steps 0, 4, 8, … as on a lone trajectory.
            let aligned = clock % CHECK_EVERY == 0;
            let mut active = 0usize;
            for l in 0..w {
                loop {
                    if cell[l] == IDLE {
                        if !(aligned && next < n) {
                            break;
                        }
                        start(next, &mut xl, &mut vl);
                        for i in 0..d {
                            x[i * w + l] = xl[i];
                            v[i * w + l] = vl[i];
                        }
                        cell[l] = next;
                        born[l] = clock;
                        region[l] = self.judge.region(&xl);
                        turns[l] = 0;
                        next += 1;
                    }
                    let steps = clock - born[l];
                    let due = aligned || steps >= self.max_steps;
                    if !due {
                        active += 1;
                        break;
                    }
                    for i in 0..d {
                        xl[i] = x[i * w + l];
                        vl[i] = v[i * w + l];
                    }
                    if aligned {
                        let r = self.judge.region(&xl);
                        turns[l] += u32::from(r != region[l]);
                        region[l] = r;
                    }
                    let label = if self.early && aligned {
                        self.judge.trapped(&xl, &vl).map(Label::State)
                    } else {
                        None
                    };
                    let label = match label {
                        Some(lab) => lab,
                        None if steps >= self.max_steps => self.judge.at_cap(&xl, &vl),
                        None => {
                            active += 1;
                            break;
                        }
                    };
                    out[cell[l]] = Outcome {
                        label,
                        turns: turns[l],
                    };
                    cell[l] = IDLE;
                    for i in 0..d {
                        x[i * w + l] = 0.0;
                        v[i * w + l] = 0.0;
                    }
                }
            }
            if active == 0 && next >= n {
                break;
            }
            // Steps to the next decision: the next multiple of CHECK_EVERY, or an earlier cap.
            let mut k = CHECK_EVERY - clock % CHECK_EVERY;
            for l in 0..w {
                if cell[l] != IDLE {
                    let left = born[l] + self.max_steps - clock;
                    if left > 0 {
                        k = k.min(left);
                    }
                }
            }
            for _ in 0..k {
                rk4_lanes(self.sys, self.h, &mut x, &mut v, &u, &mut s);
                clock += 1;
                if !within(&x, &v, limit) {
                    // Rare: find the lanes that left the bound; a start there is Diverged, an
                    // idle lane (zero state drifting under a constant force) is reset.
                    for l in 0..w {
                        let bad = (0..d).any(|i| {
                            let (xi, vi) = (x[i * w + l], v[i * w + l]);
                            !(xi.abs() < limit && vi.is_finite())
                        });
                        if bad {
                            if cell[l] != IDLE {
                                out[cell[l]] = Outcome {
                                    label: Label::Diverged,
                                    turns: turns[l],
                                };
                                cell[l] = IDLE;
                            }
                            for i in 0..d {
                                x[i * w + l] = 0.0;
                                v[i * w + l] = 0.0;
                            }
                        }
                    }
                    // A freed lane is refilled at the next aligned clock.
                    break;
                }
            }
        }
    }
}

/// Whether every component is inside the blow-up bound (a loop that vectorises).
#[inline(always)]
fn within(x: &[f64], v: &[f64], limit: f64) -> bool {
    let mut ok = true;
    for (a, b) in x.iter().zip(v) {
        ok &= (a.abs() < limit) & b.is_finite();
    }
    ok
}

/// One classical RK4 step of every lane, with `tfs_dynamics::rk4_step`'s arithmetic (t = 0,
/// zero input), so each lane's state is the same to the bit as a lone trajectory's.
#[inline(always)]
fn rk4_lanes<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    h: f64,
    x: &mut [f64],
    v: &mut [f64],
    u: &[f64],
    s: &mut Scratch,
) {
    let [a1, a2, a3, a4] = &mut s.a;
    let [v2, v3, v4] = &mut s.vs;
    let xt = &mut s.xt;
    let t = 0.0;
    sys.accel_lanes(t, x, v, u, a1);
    for i in 0..x.len() {
        xt[i] = x[i] + 0.5 * h * v[i];
        v2[i] = v[i] + 0.5 * h * a1[i];
    }
    sys.accel_lanes(t + 0.5 * h, xt, v2, u, a2);
    for i in 0..x.len() {
        xt[i] = x[i] + 0.5 * h * v2[i];
        v3[i] = v[i] + 0.5 * h * a2[i];
    }
    sys.accel_lanes(t + 0.5 * h, xt, v3, u, a3);
    for i in 0..x.len() {
        xt[i] = x[i] + h * v3[i];
        v4[i] = v[i] + h * a3[i];
    }
    sys.accel_lanes(t + h, xt, v4, u, a4);
    for i in 0..x.len() {
        x[i] += h / 6.0 * (v[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i]);
        v[i] += h / 6.0 * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i]);
    }
}
