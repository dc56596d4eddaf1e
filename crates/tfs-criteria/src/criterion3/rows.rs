//! Criterion 3's rows: the windowed transforms of one DOF of one record at the bins that can be
//! selected (`|ẍ̂| ≥ δ·max`, and above the variance the estimated displacement noise gives
//! there), the real regression rows of the bins kept at a δ, and the feasible-GLS weights of the
//! bins.

use faer::Mat;
use tfs_signal::{Band, Complex, WindowSamples, bin_omegas, window_layout};

use super::series::{RecordSeries, window};
use crate::error::Result;

/// Windowed transforms of one DOF of one record, at the bins that can be selected.
#[derive(Clone)]
pub(crate) struct WindowTransform {
    /// Frequencies (Hz) of the stored bins.
    pub freq: Vec<f64>,
    /// |LHS| relative to its maximum over the window's bins.
    pub rel_amp: Vec<f64>,
    /// LHS transform at the stored bins.
    pub lhs: Vec<Complex<f64>>,
    /// Term transforms at the stored bins (`cols[j][b]`).
    pub cols: Vec<Vec<Complex<f64>>>,
    /// Row weight of each stored bin (1 = unweighted; see [`reweight`]).
    pub weight: Vec<f64>,
}

/// Variance of the weak-form (or plain) transform of `x''` at each bin that the displacement
/// noise alone produces: for noise of two-sided density `S(f)` the windowed integral of
/// `n·(w'' − 2iωw' − ω²w)` has variance `S(f)·∫|w'' − 2iωw' − ω²w|² dt`
/// `= S(f)·(∫w''² − 2ω²∫w w'' + ω⁴∫w² + 4ω²∫w'²)`.
fn lhs_noise_var(win: &WindowSamples, om: &[f64], dt: f64, noise: &(Band, f64)) -> Vec<f64> {
    let (w, w1, w2) = (&win.w, &win.dw, &win.ddw);
    let int = |f: &dyn Fn(usize) -> f64| (0..w.len()).map(f).sum::<f64>() * dt;
    let i0 = int(&|i| w[i] * w[i]);
    let i1 = int(&|i| w1[i] * w1[i]);
    let i2 = int(&|i| w2[i] * w2[i]);
    let i02 = int(&|i| w[i] * w2[i]);
    om.iter()
        .map(|&w| {
            let f = w / (2.0 * std::f64::consts::PI);
            let g = (i2 - 2.0 * w * w * i02 + w.powi(4) * i0 + 4.0 * w * w * i1).max(0.0);
            noise.0.noise_psd(f, noise.1) * g
        })
        .collect()
}

/// Transforms of `count` overlapping windows; bins with |LHS| < `delta_min`·max are not stored,
/// nor (when `min_bin_snr` is given) bins whose |LHS|² is below `min_bin_snr` times the variance
/// the estimated displacement noise gives there — in those bins the noise of `x` on both sides
/// of the regression would bias the coefficients (errors in variables).
pub(crate) fn window_transforms(
    s: &RecordSeries,
    count: usize,
    delta_min: f64,
    min_bin_snr: Option<f64>,
) -> Vec<WindowTransform> {
    let dt = s.dt;
    let n = s.lhs.len();
    let (starts, len) = window_layout(n, count);
    let win = window(len, dt);
    let om = bin_omegas(len, dt);
    let df = 1.0 / (len as f64 * dt);
    let gate: Option<Vec<f64>> = match (min_bin_snr, &s.noise) {
        (Some(g), Some(nm)) if g > 0.0 => Some(
            lhs_noise_var(&win, &om, dt, nm)
                .into_iter()
                .map(|v| g * v)
                .collect(),
        ),
        _ => None,
    };
    starts
        .iter()
        .map(|&st| {
            let all: Vec<usize> = (0..om.len()).collect();
            let lhs_full = s.lhs_spectrum_at(st, &win, &om, &all);
            // Each bin's magnitude, computed once (a `hypot` each).
            let mag: Vec<f64> = lhs_full.iter().map(|c| c.norm()).collect();
            let max = mag.iter().fold(0.0f64, |a, &m| a.max(m));
            // The strongest bin is always kept so no window is left without rows.
            let top = (0..mag.len())
                .max_by(|&a, &b| mag[a].total_cmp(&mag[b]))
                .unwrap_or(0);
            let bins: Vec<usize> = (0..mag.len())
                .filter(|&k| max > 0.0 && mag[k] >= delta_min * max)
                .filter(|&k| {
                    k == top || gate.as_ref().is_none_or(|g| lhs_full[k].norm_sqr() >= g[k])
                })
                .collect();
            let cols = (0..s.terms.len())
                .map(|j| s.term_spectrum_at(j, st, &win, &om, &bins))
                .collect();
            WindowTransform {
                freq: bins.iter().map(|&k| k as f64 * df).collect(),
                rel_amp: bins.iter().map(|&k| mag[k] / max).collect(),
                lhs: bins.iter().map(|&k| lhs_full[k]).collect(),
                cols,
                weight: vec![1.0; bins.len()],
            }
        })
        .collect()
}

/// Real rows (real and imaginary parts stacked) of the bins with relative amplitude ≥ `delta`,
/// restricted to the columns `keep`, each bin's rows multiplied by its weight. Returns (A, b,
/// kept bin frequencies).
pub(crate) fn rows_for(
    w: &WindowTransform,
    delta: f64,
    keep: &[usize],
) -> (Mat<f64>, Vec<f64>, Vec<f64>) {
    rows_for_band(w, delta, f64::INFINITY, keep)
}

/// The rows of [`rows_for`] of every window of `wins`, stacked in order (written straight into
/// one matrix).
fn stacked_rows<'w>(
    wins: impl Iterator<Item = &'w WindowTransform> + Clone,
    delta: f64,
    keep: &[usize],
) -> (Mat<f64>, Vec<f64>) {
    let rows: Vec<Vec<(usize, bool)>> = wins
        .clone()
        .map(|w| bin_rows(w, delta, f64::INFINITY))
        .collect();
    let total: usize = rows.iter().map(Vec::len).sum();
    let mut a = Mat::<f64>::zeros(total, keep.len());
    let mut y = Vec::with_capacity(total);
    for (w, rows) in wins.zip(&rows) {
        write_rows(w, rows, keep, &mut a, &mut y);
    }
    (a, y)
}

/// The frequencies of the bins of `w` whose rows [`rows_for`] keeps at `delta` (its third
/// output, without the rows).
pub(crate) fn kept_freqs(w: &WindowTransform, delta: f64) -> Vec<f64> {
    bin_rows(w, delta, f64::INFINITY)
        .iter()
        .filter(|(_, im)| !im)
        .map(|&(b, _)| w.freq[b])
        .collect()
}

/// The rows of the bins of `w` with `lo ≤` relative amplitude `< hi`: `(bin, imaginary part)`,
/// a real row for every bin and an imaginary one unless it is DC.
fn bin_rows(w: &WindowTransform, lo: f64, hi: f64) -> Vec<(usize, bool)> {
    let mut rows = Vec::new();
    for b in (0..w.lhs.len()).filter(|&b| w.rel_amp[b] >= lo && w.rel_amp[b] < hi) {
        rows.push((b, false));
        if w.freq[b] > 0.0 {
            rows.push((b, true));
        }
    }
    rows
}

/// Writes the weighted rows `rows` of `w` over the columns `keep` into `a` from row `y.len()`
/// on, and their left-hand sides onto `y`.
fn write_rows(
    w: &WindowTransform,
    rows: &[(usize, bool)],
    keep: &[usize],
    a: &mut Mat<f64>,
    y: &mut Vec<f64>,
) {
    let start = y.len();
    let part = |c: Complex<f64>, im: bool| if im { c.im } else { c.re };
    for (k, &j) in keep.iter().enumerate() {
        let col = &w.cols[j];
        let out = &mut a.col_as_slice_mut(k)[start..start + rows.len()];
        for (o, &(b, im)) in out.iter_mut().zip(rows) {
            *o = part(col[b] * w.weight[b], im);
        }
    }
    y.extend(rows.iter().map(|&(b, im)| part(w.lhs[b] * w.weight[b], im)));
}

/// [`rows_for`] restricted to the bins with `lo ≤` relative amplitude `< hi`: the rows a smaller
/// δ adds to a larger one's (the kept sets are nested in δ).
pub(crate) fn rows_for_band(
    w: &WindowTransform,
    lo: f64,
    hi: f64,
    keep: &[usize],
) -> (Mat<f64>, Vec<f64>, Vec<f64>) {
    let rows = bin_rows(w, lo, hi);
    let mut a = Mat::<f64>::zeros(rows.len(), keep.len());
    let mut y = Vec::with_capacity(rows.len());
    write_rows(w, &rows, keep, &mut a, &mut y);
    let freqs = rows
        .iter()
        .filter(|(_, im)| !im)
        .map(|&(b, _)| w.freq[b])
        .collect();
    (a, y, freqs)
}

/// Stored bins on each side of a bin whose residual powers are averaged by [`reweight`].
pub(crate) const REWEIGHT_HALF: usize = 16;

/// Feasible generalised least squares on the frequency-domain rows of one window layout (`recs`:
/// the windows of every record). The rows of different bins carry very different noise — the
/// weak-form `x''` row carries `ω²` times the displacement noise, and coloured (e.g. pink) noise
/// has a density that changes by orders of magnitude across the band — so equal weights let the
/// noisiest bins dominate. Each pass fits every column of `keep` by least squares on the bins with
/// relative amplitude ≥ `delta`, takes the residual power `|ê_b|²` of every stored bin, averages
/// it over the `2·REWEIGHT_HALF + 1` neighbouring stored bins of the same window (a local noise
/// level that does not follow one bin's chance residual), and sets the bin's weight to
/// `1/√(that power)`. Weights are normalised to unit mean square; a fit that fails leaves the
/// weights as they were.
pub(crate) fn reweight(
    recs: &mut [Vec<WindowTransform>],
    delta: f64,
    keep: &[usize],
    passes: usize,
) -> Result<()> {
    use tfs_regress::{Compressed, lstsq_support};
    if keep.is_empty() {
        return Ok(());
    }
    for _ in 0..passes {
        // Every window's rows stacked and compressed in one call (its cache-sized chunks are
        // far cheaper than one small QR per window).
        let (a, y) = stacked_rows(recs.iter().flatten(), delta, keep);
        if y.is_empty() {
            return Ok(());
        }
        let all = Compressed::from_rows(a.as_ref(), &y)?;
        let Ok(fit) = lstsq_support(&all, &vec![true; keep.len()]) else {
            return Ok(());
        };
        if fit.coef.iter().any(|c| !c.is_finite()) {
            return Ok(());
        }
        let mut power: Vec<Vec<f64>> = Vec::new();
        for w in recs.iter().flatten() {
            let e: Vec<f64> = (0..w.lhs.len())
                .map(|b| {
                    let mut r = w.lhs[b];
                    for (j, &c) in keep.iter().zip(&fit.coef) {
                        r -= w.cols[*j][b] * c;
                    }
                    r.norm_sqr()
                })
                .collect();
            let n = e.len();
            power.push(
                (0..n)
                    .map(|b| {
                        let lo = b.saturating_sub(REWEIGHT_HALF);
                        let hi = (b + REWEIGHT_HALF + 1).min(n);
                        e[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
                    })
                    .collect(),
            );
        }
        let mut all_p: Vec<f64> = power.iter().flatten().copied().collect();
        if all_p.is_empty() {
            return Ok(());
        }
        let mid = all_p.len() / 2;
        let med = *all_p.select_nth_unstable_by(mid, f64::total_cmp).1;
        if !(med.is_finite() && med > 0.0) {
            return Ok(());
        }
        // A floor keeps a bin the fit happens to match exactly from taking all the weight.
        let floor = 1e-6 * med;
        for (w, p) in recs.iter_mut().flatten().zip(&power) {
            w.weight = p.iter().map(|v| 1.0 / v.max(floor).sqrt()).collect();
        }
    }
    // Unit mean square over the stored bins (the scale does not change any fit; it keeps the
    // rows' magnitudes comparable with the unweighted ones in traces).
    let (ss, n) = recs
        .iter()
        .flatten()
        .flat_map(|w| w.weight.iter())
        .fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    if n > 0 && ss > 0.0 {
        let k = (n as f64 / ss).sqrt();
        recs.iter_mut()
            .flatten()
            .for_each(|w| w.weight.iter_mut().for_each(|v| *v *= k));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use tfs_regress::{Compressed, lstsq_support};
    use tfs_signal::NoiseKind;
    use tfs_signal::noise::noise_for;

    /// The reweighting's stacked rows are exactly the rows of every window one after another,
    /// with DC bins giving one row and an infinite relative amplitude none (as `rows_for`).
    #[test]
    fn stacked_rows_are_the_windows_rows_in_order() {
        let win = |k: usize, seed: f64| {
            let c = |b: usize, j: usize| {
                Complex::new(
                    (seed + b as f64 * 0.7 + j as f64).sin(),
                    (b as f64 - seed).cos(),
                )
            };
            let rel_amp: Vec<f64> = (0..k)
                .map(|b| match b {
                    3 => f64::INFINITY,
                    5 => f64::NAN,
                    _ => ((b as f64 + seed) * 1.3).sin().abs(),
                })
                .collect();
            WindowTransform {
                freq: (0..k).map(|b| b as f64 * 0.1).collect(),
                rel_amp,
                lhs: (0..k).map(|b| c(b, 9)).collect(),
                cols: (0..4).map(|j| (0..k).map(|b| c(b, j)).collect()).collect(),
                weight: (0..k).map(|b| 1.0 + 0.01 * b as f64).collect(),
            }
        };
        let wins = [win(12, 0.2), win(7, 1.1), win(20, 2.5)];
        let keep = [0, 2, 3];
        let (a, y) = stacked_rows(wins.iter(), 0.3, &keep);
        let mut row = 0;
        for w in &wins {
            let (wa, wy, _) = rows_for(w, 0.3, &keep);
            for i in 0..wa.nrows() {
                assert_eq!(y[row + i], wy[i]);
                for j in 0..keep.len() {
                    assert_eq!(a[(row + i, j)], wa[(i, j)]);
                }
            }
            row += wa.nrows();
        }
        assert_eq!((row, a.nrows(), y.len()), (a.nrows(), row, row));
        assert!(row > 0);
    }

    /// Unit-variance white noise (seeded).
    fn gauss(n: usize, seed: u64) -> Vec<f64> {
        noise_for(&vec![1.0; n], 0.0, NoiseKind::White, seed).expect("noise")
    }

    /// Two windows of 200 bins, `y = 1.5·θ0 − 0.7·θ1 + e` with noise sd 1 in the lower half of
    /// the bins and 10 in the upper half.
    fn windows() -> Vec<Vec<WindowTransform>> {
        let nb = 200;
        (0..2u64)
            .map(|w| {
                let g: Vec<Vec<f64>> = (0..6).map(|k| gauss(nb, 10 * w + k)).collect();
                let c = |a: usize, b: usize| -> Vec<Complex<f64>> {
                    (0..nb).map(|i| Complex::new(g[a][i], g[b][i])).collect()
                };
                let cols = vec![c(0, 1), c(2, 3)];
                let lhs = (0..nb)
                    .map(|i| {
                        let s = if i < nb / 2 { 1.0 } else { 10.0 };
                        cols[0][i] * 1.5 - cols[1][i] * 0.7 + Complex::new(g[4][i], g[5][i]) * s
                    })
                    .collect();
                vec![WindowTransform {
                    freq: (1..=nb).map(|k| k as f64 * 0.1).collect(),
                    rel_amp: vec![1.0; nb],
                    lhs,
                    cols,
                    weight: vec![1.0; nb],
                }]
            })
            .collect()
    }

    fn fit(recs: &[Vec<WindowTransform>]) -> Vec<f64> {
        let parts: Vec<Compressed> = recs
            .iter()
            .flatten()
            .map(|w| {
                let (a, y, _) = rows_for(w, 0.5, &[0, 1]);
                Compressed::from_rows(a.as_ref(), &y).expect("rows")
            })
            .collect();
        let all = Compressed::merge(&parts).expect("merge");
        lstsq_support(&all, &[true, true]).expect("fit").coef
    }

    #[test]
    fn reweight_follows_the_noise_level_and_sharpens_the_fit() {
        let mut recs = windows();
        let plain = fit(&recs);
        reweight(&mut recs, 0.5, &[0, 1], 2).expect("reweight");
        // Weights ≈ 1/noise sd: the noisy half gets about a tenth of the weight (away from the
        // boundary, where the smoothing mixes the halves).
        let w = &recs[0][0].weight;
        let lo = w[10..90].iter().sum::<f64>() / 80.0;
        let hi = w[110..190].iter().sum::<f64>() / 80.0;
        let ratio = hi / lo;
        assert!((0.05..0.2).contains(&ratio), "weight ratio {ratio}");
        // Unit mean square.
        let ms = recs
            .iter()
            .flatten()
            .flat_map(|t| t.weight.iter())
            .map(|v| v * v)
            .sum::<f64>()
            / 400.0;
        assert!((ms - 1.0).abs() < 1e-9, "mean square weight {ms}");
        let gls = fit(&recs);
        let err = |c: &[f64]| ((c[0] - 1.5).powi(2) + (c[1] + 0.7).powi(2)).sqrt();
        assert!(
            err(&gls) < err(&plain),
            "weighted error {} vs equal weights {}",
            err(&gls),
            err(&plain)
        );
    }

    #[test]
    fn rows_scale_with_the_bin_weight() {
        let mut recs = windows();
        let (a1, y1, _) = rows_for(&recs[0][0], 0.5, &[0, 1]);
        recs[0][0].weight = (0..200).map(|i| 1.0 + i as f64).collect();
        let (a2, y2, _) = rows_for(&recs[0][0], 0.5, &[0, 1]);
        for i in 0..a1.nrows() {
            let wt = 1.0 + (i / 2) as f64;
            assert!((y2[i] - wt * y1[i]).abs() <= 1e-12 * (1.0 + y2[i].abs()));
            for j in 0..2 {
                assert!((a2[(i, j)] - wt * a1[(i, j)]).abs() <= 1e-12 * (1.0 + a2[(i, j)].abs()));
            }
        }
    }
}
