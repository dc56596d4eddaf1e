//! STLSQ at the paper's Table B1 size (200,020 rows × 36 monomials of (x, x') up to degree 7):
//! compressed fit end to end versus a baseline that redoes a full m-row QR every iteration,
//! and versus a normal-equations STLSQ.

use criterion::{Criterion, criterion_group, criterion_main};
use faer::linalg::solvers::Solve;
use faer::linalg::solvers::SolveLstsq;
use faer::{Mat, Side};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;
use tfs_regress::{Compressed, Regressor, Stlsq};

const M: usize = 200_020;
const DEG: usize = 7;

fn data() -> (Mat<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let xs: Vec<(f64, f64)> = (0..M)
        .map(|_| (rng.random_range(-1.5..1.5), rng.random_range(-3.0..3.0)))
        .collect();
    let mut pows = Vec::new();
    for d in 0..=DEG {
        for j in 0..=d {
            pows.push((d - j, j));
        }
    }
    let n = pows.len();
    let a = Mat::from_fn(M, n, |r, c| {
        let (x, v) = xs[r];
        x.powi(pows[c].0 as i32) * v.powi(pows[c].1 as i32)
    });
    // b = −x − 0.1·x' + 12·x⁵ − 18·x⁶ + 6.5·x⁷ + noise
    let col = |i: usize, j: usize| pows.iter().position(|&p| p == (i, j)).unwrap();
    let terms = [
        (col(1, 0), -1.0),
        (col(0, 1), -0.1),
        (col(5, 0), 12.0),
        (col(6, 0), -18.0),
        (col(7, 0), 6.5),
    ];
    let b = (0..M)
        .map(|r| {
            terms.iter().map(|&(c, k)| k * a[(r, c)]).sum::<f64>()
                + 0.05 * rng.random_range(-1.0..1.0)
        })
        .collect();
    (a, b)
}

/// Baseline: the same scaled STLSQ, but every iteration solves the m-row subset problem by a
/// fresh thin QR (what a naive SINDy implementation does).
fn stlsq_full_qr(a: &Mat<f64>, b: &[f64], threshold: f64, max_iter: usize) -> Vec<f64> {
    let n = a.ncols();
    let norms: Vec<f64> = (0..n).map(|j| a.col(j).norm_l2()).collect();
    let bn = b.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut cols: Vec<usize> = (0..n).collect();
    let mut x = vec![0.0; n];
    for _ in 0..max_iter {
        let sub = Mat::from_fn(a.nrows(), cols.len(), |i, jj| {
            a[(i, cols[jj])] / norms[cols[jj]]
        });
        let rhs = Mat::from_fn(a.nrows(), 1, |i, _| b[i] / bn);
        let sol = sub.qr().solve_lstsq(&rhs);
        x.iter_mut().for_each(|v| *v = 0.0);
        for (jj, &j) in cols.iter().enumerate() {
            x[j] = sol[(jj, 0)];
        }
        let keep: Vec<usize> = cols
            .iter()
            .copied()
            .filter(|&j| x[j].abs() >= threshold)
            .collect();
        if keep.len() == cols.len() {
            break;
        }
        cols = keep;
    }
    (0..n).map(|j| x[j] * bn / norms[j]).collect()
}

/// Baseline: STLSQ on the normal equations (Gram matrix formed once, Cholesky per iteration).
fn stlsq_normal(a: &Mat<f64>, b: &[f64], threshold: f64, max_iter: usize) -> Vec<f64> {
    let n = a.ncols();
    let bm = Mat::from_fn(a.nrows(), 1, |i, _| b[i]);
    let g = a.transpose() * a;
    let q = a.transpose() * &bm;
    let norms: Vec<f64> = (0..n).map(|j| g[(j, j)].sqrt()).collect();
    let bn = b.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut cols: Vec<usize> = (0..n).collect();
    let mut x = vec![0.0; n];
    for _ in 0..max_iter {
        let k = cols.len();
        let gs = Mat::from_fn(k, k, |i, j| {
            g[(cols[i], cols[j])] / (norms[cols[i]] * norms[cols[j]])
        });
        let qs = Mat::from_fn(k, 1, |i, _| q[(cols[i], 0)] / (norms[cols[i]] * bn));
        let sol = match gs.llt(Side::Lower) {
            Ok(l) => l.solve(&qs),
            Err(_) => return x,
        };
        x.iter_mut().for_each(|v| *v = 0.0);
        for (jj, &j) in cols.iter().enumerate() {
            x[j] = sol[(jj, 0)];
        }
        let keep: Vec<usize> = cols
            .iter()
            .copied()
            .filter(|&j| x[j].abs() >= threshold)
            .collect();
        if keep.len() == cols.len() {
            break;
        }
        cols = keep;
    }
    (0..n).map(|j| x[j] * bn / norms[j]).collect()
}

fn bench(c: &mut Criterion) {
    let (a, b) = data();
    let est = Stlsq {
        threshold: 0.01,
        ..Stlsq::default()
    };
    let fit = est.fit(a.as_ref(), &b).unwrap();
    let base = stlsq_full_qr(&a, &b, 0.01, 20);
    let ne = stlsq_normal(&a, &b, 0.01, 20);
    eprintln!(
        "compressed STLSQ: {} terms, {} iterations; full-QR baseline terms {}, normal-equations terms {}",
        fit.n_terms(),
        fit.iterations,
        base.iter().filter(|v| **v != 0.0).count(),
        ne.iter().filter(|v| **v != 0.0).count()
    );
    let mut group = c.benchmark_group("stlsq_200020x36");
    group.sample_size(10);
    group.bench_function("compress_only", |bch| {
        bch.iter(|| Compressed::from_rows(black_box(a.as_ref()), black_box(&b)).unwrap())
    });
    group.bench_function("compressed_stlsq_end_to_end", |bch| {
        bch.iter(|| est.fit(black_box(a.as_ref()), black_box(&b)).unwrap())
    });
    group.bench_function("baseline_full_qr_per_iteration", |bch| {
        bch.iter(|| stlsq_full_qr(black_box(&a), black_box(&b), 0.01, 20))
    });
    group.bench_function("baseline_normal_equations", |bch| {
        bch.iter(|| stlsq_normal(black_box(&a), black_box(&b), 0.01, 20))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
