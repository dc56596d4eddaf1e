//! Property tests of the regressors against independent computations on the raw rows.
#![allow(clippy::needless_range_loop)] // parallel indexing of several arrays reads clearer in tests

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tfs_regress::*;

fn rand_mat(rng: &mut ChaCha8Rng, m: usize, n: usize) -> Mat<f64> {
    Mat::from_fn(m, n, |_, _| rng.random_range(-1.0..1.0))
}

/// ‖Aξ − b‖² computed directly on the m rows.
fn direct_rss(a: &Mat<f64>, b: &[f64], x: &[f64]) -> f64 {
    (0..a.nrows())
        .map(|i| {
            let r: f64 = (0..a.ncols()).map(|j| a[(i, j)] * x[j]).sum::<f64>() - b[i];
            r * r
        })
        .sum()
}

/// Sparse ξ with k non-zeros of magnitude in [0.5, 2] and random signs.
fn sparse_coef(rng: &mut ChaCha8Rng, n: usize, k: usize) -> Vec<f64> {
    let mut x = vec![0.0; n];
    let mut placed = 0;
    while placed < k {
        let j = rng.random_range(0..n);
        if x[j] == 0.0 {
            let s = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            x[j] = s * rng.random_range(0.5..2.0);
            placed += 1;
        }
    }
    x
}

fn matvec(a: &Mat<f64>, x: &[f64]) -> Vec<f64> {
    (0..a.nrows())
        .map(|i| (0..a.ncols()).map(|j| a[(i, j)] * x[j]).sum())
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn compressed_residual_identity(seed in 0u64..10_000, n in 1usize..9, m in 1usize..60) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let a = rand_mat(&mut rng, m, n);
        let b: Vec<f64> = (0..m).map(|_| rng.random_range(-3.0..3.0)).collect();
        let p = Compressed::from_rows(a.as_ref(), &b).unwrap();
        for _ in 0..3 {
            let x: Vec<f64> = (0..n).map(|_| rng.random_range(-5.0..5.0)).collect();
            let d = direct_rss(&a, &b, &x);
            let c = p.rss(&x).unwrap();
            prop_assert!((d - c).abs() <= 1e-10 * (1.0 + d), "direct {d} compressed {c}");
        }
        prop_assert!(p.rss0() >= 0.0);
    }

    #[test]
    fn stlsq_recovers_sparse_exact(seed in 0u64..10_000, n in 3usize..14, extra in 0usize..40, scaled in any::<bool>()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let m = 2 * n + extra;
        let k = rng.random_range(1..=n.div_ceil(2));
        let a = rand_mat(&mut rng, m, n);
        let xi = sparse_coef(&mut rng, n, k);
        let b = matvec(&a, &xi);
        let threshold = if scaled {
            // Half the smallest true scaled magnitude |ξ_j|·‖a_j‖/‖b‖, computed on the raw rows.
            let bn = b.iter().map(|v| v * v).sum::<f64>().sqrt();
            (0..n).filter(|&j| xi[j] != 0.0).map(|j| xi[j].abs() * a.col(j).norm_l2() / bn).fold(f64::INFINITY, f64::min) * 0.5
        } else {
            0.25
        };
        let est = Stlsq { threshold, ridge: 0.0, max_iter: 20, scale_columns: scaled, unbiased_refit: true };
        let fit = est.fit(a.as_ref(), &b).unwrap();
        for j in 0..n {
            prop_assert_eq!(fit.support[j], xi[j] != 0.0, "support mismatch at column {}", j);
            prop_assert!((fit.coef[j] - xi[j]).abs() < 1e-9, "coef {j}: {} vs {}", fit.coef[j], xi[j]);
        }
        prop_assert!(fit.converged);
    }

    #[test]
    fn ridge_matches_normal_equations(seed in 0u64..10_000, n in 1usize..8, extra in 0usize..30, lambda in 0.01f64..10.0) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let m = n + extra + 1;
        let a = rand_mat(&mut rng, m, n);
        let b: Vec<f64> = (0..m).map(|_| rng.random_range(-2.0..2.0)).collect();
        let fit = Ridge { lambda }.fit(a.as_ref(), &b).unwrap();
        // Independent closed form (AᵀA + λI)⁻¹Aᵀb by Cholesky on the raw rows.
        let bm = Mat::from_fn(m, 1, |i, _| b[i]);
        let mut g = a.transpose() * &a;
        for j in 0..n { g[(j, j)] += lambda; }
        let rhs = a.transpose() * &bm;
        let x = g.llt(Side::Lower).unwrap().solve(&rhs);
        for j in 0..n {
            prop_assert!((fit.coef[j] - x[(j, 0)]).abs() < 1e-9 * (1.0 + x[(j, 0)].abs()));
        }
    }

    #[test]
    fn lasso_satisfies_kkt(seed in 0u64..10_000, n in 2usize..10, extra in 0usize..40, frac in 0.01f64..0.9) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let m = n + extra + 2;
        let a = rand_mat(&mut rng, m, n);
        let xi = sparse_coef(&mut rng, n, 1 + n / 3);
        let b: Vec<f64> = matvec(&a, &xi).iter().map(|v| v + 0.1 * rng.random_range(-1.0..1.0)).collect();
        let p = Compressed::from_rows(a.as_ref(), &b).unwrap();
        let lambda = frac * lasso_lambda_max(&p);
        let fit = Lasso { lambda, tol: 1e-13, max_iter: 100_000 }.fit_compressed(&p).unwrap();
        prop_assert!(fit.converged);
        // KKT on the raw rows: g = Aᵀ(b − Aξ)/m.
        let r: Vec<f64> = matvec(&a, &fit.coef).iter().zip(&b).map(|(f, y)| y - f).collect();
        let tol = 1e-7 * (1.0 + lambda);
        for j in 0..n {
            let g: f64 = (0..m).map(|i| a[(i, j)] * r[i]).sum::<f64>() / m as f64;
            if fit.coef[j] != 0.0 {
                prop_assert!((g - lambda * fit.coef[j].signum()).abs() < tol, "active {j}: g {g} λ {lambda}");
            } else {
                prop_assert!(g.abs() <= lambda + tol, "inactive {j}: |g| {} > λ {lambda}", g.abs());
            }
        }
    }

    #[test]
    fn merge_and_append_equal_stacked(seed in 0u64..10_000, n in 1usize..7, blocks in 1usize..5) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let sizes: Vec<usize> = (0..blocks).map(|_| rng.random_range(1..20)).collect();
        let mtot: usize = sizes.iter().sum();
        let a = rand_mat(&mut rng, mtot, n);
        let b: Vec<f64> = (0..mtot).map(|_| rng.random_range(-2.0..2.0)).collect();
        let whole = Compressed::from_rows(a.as_ref(), &b).unwrap();
        let mut parts = Vec::new();
        let mut appended = Compressed::empty(n);
        let mut start = 0;
        for &s in &sizes {
            let ab = a.as_ref().subrows(start, s);
            parts.push(Compressed::from_rows(ab, &b[start..start + s]).unwrap());
            appended.append(ab, &b[start..start + s]).unwrap();
            start += s;
        }
        let merged = Compressed::merge(&parts).unwrap();
        for c in [&merged, &appended] {
            prop_assert_eq!(c.nrows(), mtot);
            // R is unique up to row signs: compare RᵀR, Rᵀc and rss0.
            let (g1, q1) = whole.gram();
            let (g2, q2) = c.gram();
            for i in 0..n {
                prop_assert!((q1[i] - q2[i]).abs() < 1e-10 * (1.0 + q1[i].abs()));
                for j in 0..n {
                    prop_assert!((g1[(i, j)] - g2[(i, j)]).abs() < 1e-10 * (1.0 + g1[(i, j)].abs()));
                }
            }
            prop_assert!((whole.rss0() - c.rss0()).abs() < 1e-10 * (1.0 + whole.rss0()));
            let x: Vec<f64> = (0..n).map(|_| rng.random_range(-2.0..2.0)).collect();
            let d = direct_rss(&a, &b, &x);
            prop_assert!((c.rss(&x).unwrap() - d).abs() < 1e-10 * (1.0 + d));
        }
    }

    /// The structured updates (new rows or another block's factor zeroed into the current
    /// triangle) against the raw rows, on wide, badly scaled and rank-deficient designs, with
    /// blocks on both sides of the row count where `append` switches to the dense QR, and
    /// counted merges against rows repeated.
    #[test]
    fn structured_updates_equal_stacked_rows(
        seed in 0u64..10_000,
        n in 1usize..40,
        blocks in 1usize..5,
        dependent in any::<bool>(),
    ) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let sizes: Vec<usize> = (0..blocks).map(|_| rng.random_range(1..90)).collect();
        let counts: Vec<usize> = (0..blocks).map(|_| rng.random_range(0..3)).collect();
        let mtot: usize = sizes.iter().sum();
        let scale: Vec<f64> = (0..n).map(|_| 10f64.powf(rng.random_range(-4.0..4.0))).collect();
        let mut a = Mat::from_fn(mtot, n, |_, j| scale[j] * rng.random_range(-1.0..1.0));
        if dependent && n > 2 {
            // Column 1 a multiple of column 0, column n-1 a sum of the two before it.
            for i in 0..mtot {
                a[(i, 1)] = 3.0 * a[(i, 0)];
                a[(i, n - 1)] = a[(i, n - 2)] + a[(i, n - 3)];
            }
        }
        let b: Vec<f64> = (0..mtot).map(|_| rng.random_range(-2.0..2.0)).collect();
        let mut parts = Vec::new();
        let mut appended = Compressed::empty(n);
        let (mut start, mut rep_rows) = (0, Vec::new());
        for (&s, &k) in sizes.iter().zip(&counts) {
            let ab = a.as_ref().subrows(start, s);
            parts.push(Compressed::from_rows(ab, &b[start..start + s]).unwrap());
            appended.append(ab, &b[start..start + s]).unwrap();
            rep_rows.extend((0..k).flat_map(|_| start..start + s));
            start += s;
        }
        let merged = Compressed::merge(&parts).unwrap();
        let pairs: Vec<(&Compressed, usize)> = parts.iter().zip(counts.iter().copied()).collect();
        let counted = Compressed::merge_counted(&pairs).unwrap();
        let ar = Mat::from_fn(rep_rows.len(), n, |i, j| a[(rep_rows[i], j)]);
        let br: Vec<f64> = rep_rows.iter().map(|&i| b[i]).collect();
        for (c, (a, b)) in [(&merged, (&a, &b)), (&appended, (&a, &b)), (&counted, (&ar, &br))] {
            prop_assert_eq!(c.nrows(), a.nrows());
            for _ in 0..3 {
                let x: Vec<f64> = (0..n).map(|j| rng.random_range(-2.0..2.0) / scale[j]).collect();
                let d = direct_rss(a, b, &x);
                // Relative to the size of the terms summed, not of their (cancelling) sum.
                let size: f64 = (0..a.nrows())
                    .map(|i| {
                        let t: f64 = (0..n).map(|j| (a[(i, j)] * x[j]).abs()).sum::<f64>();
                        (t + b[i].abs()).powi(2)
                    })
                    .sum();
                let got = c.rss(&x).unwrap();
                prop_assert!((got - d).abs() <= 1e-11 * (1.0 + size), "rss {got} vs {d} (size {size})");
            }
            prop_assert!(c.rss0() >= 0.0 && c.rss0() <= b.iter().map(|v| v * v).sum::<f64>() * (1.0 + 1e-12));
        }
    }

    #[test]
    fn lstsq_matches_normal_equations(seed in 0u64..10_000, n in 1usize..8, extra in 1usize..30) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let m = n + extra;
        let a = rand_mat(&mut rng, m, n);
        let b: Vec<f64> = (0..m).map(|_| rng.random_range(-2.0..2.0)).collect();
        let fit = lstsq(a.as_ref(), &b).unwrap();
        let bm = Mat::from_fn(m, 1, |i, _| b[i]);
        let x = (a.transpose() * &a).llt(Side::Lower).unwrap().solve(&(a.transpose() * &bm));
        for j in 0..n {
            prop_assert!((fit.coef[j] - x[(j, 0)]).abs() < 1e-7 * (1.0 + x[(j, 0)].abs()));
        }
        prop_assert!(fit.dependent.is_empty());
        prop_assert!((fit.rss - direct_rss(&a, &b, &fit.coef)).abs() < 1e-10 * (1.0 + fit.rss));
    }
}

#[test]
fn rank_deficient_least_squares_reports_dependent_column() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let m = 40;
    let base = rand_mat(&mut rng, m, 3);
    // Column 3 = column 0 + 2·column 2.
    let a = Mat::from_fn(m, 4, |i, j| {
        if j < 3 {
            base[(i, j)]
        } else {
            base[(i, 0)] + 2.0 * base[(i, 2)]
        }
    });
    let b: Vec<f64> = (0..m).map(|_| rng.random_range(-1.0..1.0)).collect();
    let fit = lstsq(a.as_ref(), &b).unwrap();
    assert_eq!(fit.dependent.len(), 1);
    assert!(fit.coef.iter().all(|v| v.is_finite()));
    // Same minimum residual as the full-rank problem on the 3 independent columns.
    let ref_fit = lstsq(base.as_ref(), &b).unwrap();
    assert!((fit.rss - ref_fit.rss).abs() < 1e-10 * (1.0 + ref_fit.rss));
}

#[test]
fn errors_name_the_location() {
    let mut a = Mat::<f64>::zeros(5, 2);
    a[(3, 1)] = f64::NAN;
    let b = vec![0.0; 5];
    match Compressed::from_rows(a.as_ref(), &b) {
        Err(RegressError::NonFinite {
            what: "A",
            row: 3,
            col: 1,
            ..
        }) => {}
        other => panic!("expected NonFinite at (3,1), got {other:?}"),
    }
    let a = Mat::<f64>::zeros(5, 2);
    let err = Compressed::from_rows(a.as_ref(), &[0.0; 4]).unwrap_err();
    assert!(matches!(
        err,
        RegressError::DimensionMismatch {
            expected: 5,
            found: 4,
            ..
        }
    ));
    assert!(err.to_string().contains("b"));
    let p = Compressed::from_rows(Mat::<f64>::identity(3, 2).as_ref(), &[1.0, 2.0, 3.0]).unwrap();
    let bad = Stlsq {
        threshold: -1.0,
        ..Stlsq::default()
    }
    .fit_compressed(&p)
    .unwrap_err();
    assert!(bad.to_string().contains("Stlsq.threshold"));
}

/// Noisy sparse data with a held-out set: the path's selected support is the true one.
#[test]
fn path_selects_true_support_on_noisy_data() {
    for seed in 0..6u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(100 + seed);
        let n = 12;
        let xi = sparse_coef(&mut rng, n, 3);
        let make = |rng: &mut ChaCha8Rng, m: usize| {
            let a = rand_mat(rng, m, n);
            let b: Vec<f64> = matvec(&a, &xi)
                .iter()
                .map(|v| v + 0.05 * rng.random_range(-1.0..1.0))
                .collect();
            Compressed::from_rows(a.as_ref(), &b).unwrap()
        };
        let train = make(&mut rng, 400);
        let val = make(&mut rng, 200);
        for criterion in [InfoCriterion::Aicc, InfoCriterion::Bic] {
            let path = lambda_path(
                &train,
                &val,
                &PathOptions {
                    criterion,
                    ..PathOptions::default()
                },
            )
            .unwrap();
            let best = path.best();
            let truth: Vec<bool> = xi.iter().map(|v| *v != 0.0).collect();
            assert_eq!(best.support, truth, "seed {seed} {criterion:?}");
            for j in 0..n {
                assert!((best.coef[j] - xi[j]).abs() < 0.05, "seed {seed} coef {j}");
            }
            // The path is ordered by decreasing threshold and reaches the dense model.
            assert!(
                path.points
                    .windows(2)
                    .all(|w| w[0].threshold > w[1].threshold)
            );
            assert!(path.points.iter().any(|p| p.n_terms > 3));
        }
    }
}

/// Monomials of a coordinate that moves ±0.04 about 1.57 cancel one another with scaled
/// coefficients far above 1; the λ path must still reach the term that carries a tenth of the
/// target (a grid anchored at the largest share alone stopped at 10⁻⁴ of it and pruned that term
/// at every point).
#[test]
fn path_reaches_small_terms_beside_cancelling_columns() {
    for seed in 0..4u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(500 + seed);
        let make = |rng: &mut ChaCha8Rng, m: usize| {
            let mut a = Mat::<f64>::zeros(m, 6);
            let mut b = vec![0.0; m];
            for i in 0..m {
                let x: f64 = 1.57 + 0.04 * rng.random_range(-1.0..1.0);
                let w: f64 = rng.random_range(-1.0..1.0);
                for k in 0..5 {
                    a[(i, k)] = x.powi(k as i32 + 1);
                }
                a[(i, 5)] = w;
                // A restoring force about the offset (no constant column: the monomials make
                // it up between them) and a small independent term.
                b[i] = -50.0 * (x - 1.57) + 0.3 * w + 0.01 * rng.random_range(-1.0..1.0);
            }
            Compressed::from_rows(a.as_ref(), &b).unwrap()
        };
        let (train, val) = (make(&mut rng, 400), make(&mut rng, 200));
        let opts = PathOptions {
            criterion: InfoCriterion::Bic,
            extend_when_cancelling: true,
            ..PathOptions::default()
        };
        let top = Stlsq::default()
            .initial_scaled_coef(&train)
            .iter()
            .fold(0.0_f64, |m, v| m.max(v.abs()));
        assert!(
            top > 1e3,
            "seed {seed}: the columns should cancel (top {top})"
        );
        let path = lambda_path(&train, &val, &opts).unwrap();
        let best = path.best();
        assert!(best.support[5], "seed {seed}: the small term was pruned");
        assert!(
            (best.coef[5] - 0.3).abs() < 0.01,
            "seed {seed}: {}",
            best.coef[5]
        );
        // The grid goes on below the usual 40 points and stops at `min_ratio` itself.
        assert!(path.points.len() > opts.n_thresholds);
        assert!(path.points.iter().all(|p| p.threshold >= opts.min_ratio));
        assert!(
            path.points
                .windows(2)
                .all(|w| w[0].threshold > w[1].threshold)
        );
        // Without the extension the grid is the plain one and prunes the small term.
        let plain = lambda_path(
            &train,
            &val,
            &PathOptions {
                extend_when_cancelling: false,
                ..opts
            },
        )
        .unwrap();
        assert_eq!(plain.points.len(), opts.n_thresholds);
        assert!(
            !plain.best().support[5],
            "seed {seed}: the plain grid kept it"
        );
        // A grid of one ratio (every threshold the largest share) has nowhere to go on to.
        let flat = PathOptions {
            min_ratio: 1.0,
            ..opts
        };
        assert_eq!(
            lambda_path(&train, &val, &flat).unwrap().points.len(),
            flat.n_thresholds
        );
    }
}

/// Bagging over blocks: the true coefficients lie inside the 95 % intervals in most replicates.
#[test]
fn bagging_intervals_cover_truth() {
    let n = 5;
    let mut covered = 0;
    let mut total = 0;
    for rep in 0..8u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(500 + rep);
        let xi = sparse_coef(&mut rng, n, 3);
        let blocks: Vec<Compressed> = (0..20)
            .map(|_| {
                let a = rand_mat(&mut rng, 30, n);
                let b: Vec<f64> = matvec(&a, &xi)
                    .iter()
                    .map(|v| v + 0.2 * rng.random_range(-1.0..1.0))
                    .collect();
                Compressed::from_rows(a.as_ref(), &b).unwrap()
            })
            .collect();
        let est = Stlsq {
            threshold: 0.1,
            scale_columns: false,
            ..Stlsq::default()
        };
        let s = bagging(
            &blocks,
            &est,
            &BagOptions {
                n_boot: 100,
                level: 0.95,
                seed: rep,
            },
        )
        .unwrap();
        for j in 0..n {
            total += 1;
            if s.lower[j] <= xi[j] && xi[j] <= s.upper[j] {
                covered += 1;
            }
            if xi[j] != 0.0 {
                assert!(
                    s.inclusion[j] > 0.9,
                    "true term {j} inclusion {}",
                    s.inclusion[j]
                );
            }
            assert!(s.lower[j] <= s.mean[j] + 1e-12 && s.mean[j] <= s.upper[j] + 1e-12);
        }
        // Determinism: same seed, same draws.
        let again = bagging(
            &blocks,
            &est,
            &BagOptions {
                n_boot: 100,
                level: 0.95,
                seed: rep,
            },
        )
        .unwrap();
        assert_eq!(s.draws, again.draws);
    }
    assert!(
        covered as f64 >= 0.8 * total as f64,
        "coverage {covered}/{total}"
    );
}

/// Compression of more rows than one internal chunk (several chunk boundaries) keeps the
/// residual identity and agrees with the merge of two halves.
#[test]
fn long_inputs_compress_exactly() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let (m, n) = (7001, 6);
    let a = rand_mat(&mut rng, m, n);
    let b: Vec<f64> = (0..m).map(|_| rng.random_range(-1.0..1.0)).collect();
    let p = Compressed::from_rows(a.as_ref(), &b).unwrap();
    assert_eq!(p.nrows(), m);
    let h = 3500;
    let halves = [
        Compressed::from_rows(a.as_ref().subrows(0, h), &b[..h]).unwrap(),
        Compressed::from_rows(a.as_ref().subrows(h, m - h), &b[h..]).unwrap(),
    ];
    let merged = Compressed::merge(&halves).unwrap();
    for _ in 0..5 {
        let x: Vec<f64> = (0..n).map(|_| rng.random_range(-3.0..3.0)).collect();
        let d = direct_rss(&a, &b, &x);
        assert!((p.rss(&x).unwrap() - d).abs() < 1e-9 * d);
        assert!((merged.rss(&x).unwrap() - d).abs() < 1e-9 * d);
    }
    // The least-squares residual equals rss0.
    let fit = lstsq(a.as_ref(), &b).unwrap();
    assert!((direct_rss(&a, &b, &fit.coef) - p.rss0()).abs() < 1e-9 * p.rss0());
}
