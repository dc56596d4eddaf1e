//! Localise: the equation residual `r = x''_meas − model(x, x', u)` on smoothed states, mapped over
//! (x, x') bins, over frequency and over time, with a plain-words summary derived by general rules:
//! correlation with probe functions of the present state, partial correlation with probes of the
//! motion's history beyond what the present state explains (memory), odd/even symmetry in x and
//! x', and the size of the residual against what measurement noise can explain
//! ([`crate::noise`]): the residual is called noise only when that estimate says so.

use serde::Serialize;
use tfs_data::{Columns, Record};
use tfs_library::{ColumnSet, Model, StateLaw, evaluate_term};
use tfs_regress::{Compressed, LeastSquares, Regressor};
use tfs_signal::amplitude_spectrum;

use crate::Result;
use crate::noise::NoiseEstimate;
use crate::prepare::{DiagnoseOptions, RecordStates, check_records, dominant_period, rms};

/// Residual statistics on a regular (x, x') grid; `mean[i][j]` for x bin `i`, x' bin `j`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualMap {
    /// x bin edges (centred on the mean of x).
    pub x_edges: Vec<f64>,
    /// x' bin edges (symmetric about 0).
    pub v_edges: Vec<f64>,
    /// Mean residual per bin (NaN when empty).
    pub mean: Vec<Vec<f64>>,
    /// Standard deviation per bin (NaN when fewer than 2 samples).
    pub spread: Vec<Vec<f64>>,
    /// Samples per bin.
    pub count: Vec<Vec<usize>>,
}

/// The localisation of one DOF's residual.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Localisation {
    /// The DOF.
    pub dof: String,
    /// RMS of the residual over RMS of x''.
    pub relative_rms: f64,
    /// Mean of the residual over RMS of x''.
    pub relative_mean: f64,
    /// Correlation of the residual with each probe function of the present state.
    pub correlations: Vec<(String, f64)>,
    /// Partial correlation of the residual with each probe of the motion's history (the
    /// velocity low-pass filtered, friction-like states of the displacement), both with what
    /// the present-state probes explain removed.
    pub history: Vec<(String, f64)>,
    /// What measurement noise can explain of the residual.
    pub noise: NoiseEstimate,
    /// The RMS of the residual the estimated noise alone would leave, over the RMS of x'' (the
    /// share the residual line prints beside `relative_rms`).
    pub relative_noise: f64,
    /// Share of the binned residual power that is odd in x' (about 0).
    pub odd_in_velocity: f64,
    /// Share of the binned residual power that is odd in x (about its mean).
    pub odd_in_displacement: f64,
    /// The (x, x') map.
    #[serde(skip)]
    pub map: ResidualMap,
    /// Residual amplitude spectrum (frequencies, amplitudes), all records concatenated per record.
    #[serde(skip)]
    pub spectrum: Vec<(Vec<f64>, Vec<f64>)>,
    /// Residual RMS per time window per record: (record, t0, t1, rms).
    pub windows: Vec<(String, f64, f64, f64)>,
    /// Plain-words summary.
    pub summary: String,
}

/// A probe function of (x, x', u).
type Probe = Box<dyn Fn(f64, f64, f64) -> f64>;

fn corr(a: &[f64], b: &[f64]) -> f64 {
    corr_with(a, |k| b[k])
}

/// [`corr`] of `a` with the column whose row `k` is `b(k)` (never stored: a record of 640k
/// samples is 5 MB per column).
fn corr_with(a: &[f64], b: impl Fn(usize) -> f64) -> f64 {
    let n = a.len() as f64;
    let ma = a.iter().sum::<f64>() / n;
    let mb = (0..a.len()).map(&b).sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (k, x) in a.iter().enumerate() {
        let y = b(k);
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    if saa <= 0.0 || sbb <= 0.0 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

/// Localises the residual of every DOF of `model` on `records`.
pub fn localise(
    model: &Model,
    records: &[Record],
    opts: &DiagnoseOptions,
) -> Result<Vec<Localisation>> {
    opts.validate()?;
    check_records(model, records)?;
    let states: Vec<RecordStates> = records
        .iter()
        .map(|r| RecordStates::new(model, r, opts))
        .collect::<Result<_>>()?;
    (0..model.dofs.len())
        .map(|i| localise_dof(model, i, &states, opts))
        .collect()
}

/// One DOF's equation residual on the usable rows of every record, side by side with the
/// smoothed displacement, velocity and first input there (records concatenated in order), with
/// each record's residual spectrum and RMS per time window.
struct ResidualRows {
    xs: Vec<f64>,
    vs: Vec<f64>,
    us: Vec<f64>,
    rs: Vec<f64>,
    spectrum: Vec<(Vec<f64>, Vec<f64>)>,
    windows: Vec<(String, f64, f64, f64)>,
}

/// [`ResidualRows`] of DOF `idx` of `model` on `states`, `opts.windows` windows a record.
fn residual_rows(
    model: &Model,
    idx: usize,
    states: &[RecordStates],
    opts: &DiagnoseOptions,
) -> Result<ResidualRows> {
    let dof = &model.dofs[idx];
    let mut rows = ResidualRows {
        xs: vec![],
        vs: vec![],
        us: vec![],
        rs: vec![],
        spectrum: Vec::new(),
        windows: Vec::new(),
    };
    for s in states {
        let set = ColumnSet::new(s);
        let n = s.rows();
        let mut pred = vec![0.0; n];
        for t in &model.equations[idx].terms {
            let v = evaluate_term(&t.term, &set)?;
            for (p, q) in pred.iter_mut().zip(v) {
                *p += t.coef * q;
            }
        }
        let (lo, hi) = (s.margin, s.margin + s.usable());
        let r: Vec<f64> = (lo..hi).map(|k| s.acc[idx][k] - pred[k]).collect();
        let x = s.column(dof).unwrap_or(&[]);
        let v = s.column(&format!("{dof}'")).unwrap_or(&[]);
        rows.xs.extend_from_slice(&x[lo..hi]);
        rows.vs.extend_from_slice(&v[lo..hi]);
        let u = model
            .inputs
            .iter()
            .find_map(|i| s.column(i))
            .map(|u| u[lo..hi].to_vec())
            .unwrap_or_else(|| vec![0.0; hi - lo]);
        rows.us.extend(u);
        let dt = s.record.dt();
        rows.spectrum.push(amplitude_spectrum(&r, dt)?);
        let w = opts.windows.min(r.len() / 2).max(1);
        for k in 0..w {
            let (a, b) = (k * r.len() / w, (k + 1) * r.len() / w);
            rows.windows.push((
                s.record.source().to_string(),
                s.record.t()[lo + a],
                s.record.t()[lo + b - 1],
                rms(&r[a..b]),
            ));
        }
        rows.rs.extend(r);
    }
    Ok(rows)
}

/// The rows of `s` whose states and accelerations are used (past the smoothing margin).
fn used(s: &RecordStates) -> std::ops::Range<usize> {
    s.margin..s.margin + s.usable()
}

/// The RMS of DOF `idx`'s accelerations over the usable rows of every record, in record order
/// (at least the smallest positive number, as the residual's normaliser).
fn acceleration_rms(states: &[RecordStates], idx: usize) -> f64 {
    let acc_n: usize = states.iter().map(|s| used(s).len()).sum();
    if acc_n == 0 {
        0.0
    } else {
        let squares = states.iter().flat_map(|s| &s.acc[idx][used(s)]);
        (squares.map(|a| a * a).sum::<f64>() / acc_n as f64).sqrt()
    }
    .max(f64::MIN_POSITIVE)
}

/// The probe functions of the present state (x about its mean `xm`, x', the first input).
fn present_probes(xm: f64) -> Vec<(&'static str, Probe)> {
    vec![
        ("sign(x')", Box::new(|_x, v, _u| v.signum())),
        ("x'*abs(x')", Box::new(|_x, v, _u| v * v.abs())),
        ("x'^3", Box::new(|_x, v, _u| v * v * v)),
        ("x'", Box::new(|_x, v, _u| v)),
        ("x^2*x'", Box::new(move |x, v, _u| (x - xm).powi(2) * v)),
        ("x", Box::new(move |x, _v, _u| x - xm)),
        ("x^2", Box::new(move |x, _v, _u| (x - xm).powi(2))),
        ("x^3", Box::new(move |x, _v, _u| (x - xm).powi(3))),
        ("input", Box::new(|_x, _v, u| u)),
    ]
}

/// The residual `rs` binned on a symmetric `nb` × `nb` grid over x (about `xm`) and x' (about
/// 0): the map, and the centre (x, x') of its worst bin (largest |mean| among bins of at least 5
/// samples; the first bin when none is).
fn residual_map(
    xs: &[f64],
    vs: &[f64],
    rs: &[f64],
    xm: f64,
    nb: usize,
) -> (ResidualMap, (f64, f64)) {
    let xr = xs
        .iter()
        .map(|x| (x - xm).abs())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let vr = vs
        .iter()
        .map(|v| v.abs())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let x_edges: Vec<f64> = (0..=nb)
        .map(|i| xm - xr + 2.0 * xr * i as f64 / nb as f64)
        .collect();
    let v_edges: Vec<f64> = (0..=nb)
        .map(|i| -vr + 2.0 * vr * i as f64 / nb as f64)
        .collect();
    let bin =
        |val: f64, lo: f64, r: f64| (((val - lo) / (2.0 * r) * nb as f64) as usize).min(nb - 1);
    let mut sum = vec![vec![0.0; nb]; nb];
    let mut sum2 = vec![vec![0.0; nb]; nb];
    let mut count = vec![vec![0usize; nb]; nb];
    for k in 0..rs.len() {
        let i = bin(xs[k], xm - xr, xr);
        let j = bin(vs[k], -vr, vr);
        sum[i][j] += rs[k];
        sum2[i][j] += rs[k] * rs[k];
        count[i][j] += 1;
    }
    let mean: Vec<Vec<f64>> = (0..nb)
        .map(|i| {
            (0..nb)
                .map(|j| {
                    if count[i][j] > 0 {
                        sum[i][j] / count[i][j] as f64
                    } else {
                        f64::NAN
                    }
                })
                .collect()
        })
        .collect();
    let spread: Vec<Vec<f64>> = (0..nb)
        .map(|i| {
            (0..nb)
                .map(|j| {
                    let c = count[i][j];
                    if c > 1 {
                        ((sum2[i][j] - sum[i][j].powi(2) / c as f64) / (c - 1) as f64)
                            .max(0.0)
                            .sqrt()
                    } else {
                        f64::NAN
                    }
                })
                .collect()
        })
        .collect();
    let mut worst = (0, 0, 0.0);
    for i in 0..nb {
        for j in 0..nb {
            if count[i][j] >= 5 && mean[i][j].abs() > worst.2 {
                worst = (i, j, mean[i][j].abs());
            }
        }
    }
    let centre = (
        0.5 * (x_edges[worst.0] + x_edges[worst.0 + 1]),
        0.5 * (v_edges[worst.1] + v_edges[worst.1 + 1]),
    );
    let map = ResidualMap {
        x_edges,
        v_edges,
        mean,
        spread,
        count,
    };
    (map, centre)
}

/// The localisation of DOF `idx`'s residual: its size against the accelerations and the noise,
/// its correlations with present-state and history probes, its (x, x') map and its symmetry,
/// spectrum and windows, and the summary in words.
fn localise_dof(
    model: &Model,
    idx: usize,
    states: &[RecordStates],
    opts: &DiagnoseOptions,
) -> Result<Localisation> {
    let dof = &model.dofs[idx];
    let laws = history_laws(dof, states)?;
    let ResidualRows {
        xs,
        vs,
        us,
        rs,
        spectrum,
        windows,
    } = residual_rows(model, idx, states, opts)?;
    let acc_rms = acceleration_rms(states, idx);
    let relative_rms = rms(&rs) / acc_rms;
    let relative_mean = rs.iter().sum::<f64>() / rs.len().max(1) as f64 / acc_rms;
    let xm = xs.iter().sum::<f64>() / xs.len().max(1) as f64;
    let probes = present_probes(xm);
    // The probes' columns are evaluated where they are read, never stored.
    let present = |k: usize, j: usize| (probes[j].1)(xs[k], vs[k], us[k]);
    let mut correlations: Vec<(String, f64)> = probes
        .iter()
        .enumerate()
        .map(|(j, (name, _))| (name.to_string(), corr_with(&rs, |k| present(k, j))))
        .collect();
    correlations.push((
        "offset".into(),
        relative_mean / relative_rms.max(f64::MIN_POSITIVE),
    ));
    // One history probe at a time: the law integrated along each record's smoothed velocity.
    let hist = |law: &StateLaw| -> Vec<f64> {
        let mut h = Vec::with_capacity(rs.len());
        for s in states {
            let v = s.column(&format!("{dof}'")).unwrap_or(&[]);
            h.extend_from_slice(&law.integrate(v, s.record.dt())[used(s)]);
        }
        h
    };
    let history = partial_correlations(&rs, (&present, probes.len()), &laws, hist)
        .into_iter()
        .zip(&laws)
        .map(|(c, (name, _))| (name.clone(), c))
        .collect::<Vec<_>>();
    let noise = crate::noise::estimate(model, idx, states);
    let nb = opts.bins;
    let (map, worst) = residual_map(&xs, &vs, &rs, xm, nb);
    let odd_in_velocity = odd_share(&map.count, &map.mean, &|i, j| (i, nb - 1 - j));
    let odd_in_displacement = odd_share(&map.count, &map.mean, &|i, j| (nb - 1 - i, j));
    let summary = summarise(
        dof,
        relative_rms,
        noise.residual_rms / acc_rms,
        &noise,
        &correlations,
        &history,
        odd_in_velocity,
        odd_in_displacement,
        worst,
        windows
            .iter()
            .max_by(|a, b| a.3.total_cmp(&b.3))
            .map(|w| (w.0.clone(), w.1, w.2)),
    );
    Ok(Localisation {
        dof: dof.clone(),
        relative_rms,
        relative_mean,
        correlations,
        history,
        noise,
        relative_noise: noise.residual_rms / acc_rms,
        odd_in_velocity,
        odd_in_displacement,
        map,
        spectrum,
        windows,
        summary,
    })
}

/// The probes of the motion's history: the velocity low-pass filtered over 0.05, 0.2 and 1
/// dominant periods (relaxation) and friction-like states of the displacement saturating after
/// 1/3 and 1/30 of its RMS (hysteresis, presliding friction), as internal-state laws
/// integrated along the smoothed velocity from rest.
fn history_laws(dof: &str, states: &[RecordStates]) -> Result<Vec<(String, StateLaw)>> {
    let mut periods = Vec::new();
    let (mut n, mut s1, mut s2) = (0usize, 0.0, 0.0);
    for s in states {
        let x = s.column(dof).unwrap_or(&[]);
        periods.push(dominant_period(x, s.record.dt())?);
        for &v in &x[s.margin.min(x.len())..(s.margin + s.usable()).min(x.len())] {
            n += 1;
            s1 += v;
            s2 += v * v;
        }
    }
    periods.sort_by(f64::total_cmp);
    let period = periods.get(periods.len() / 2).copied().unwrap_or(f64::NAN);
    let mean = s1 / n.max(1) as f64;
    let x_rms = (s2 / n.max(1) as f64 - mean * mean).max(0.0).sqrt();
    let mut out = Vec::new();
    if period.is_finite() && period > 0.0 {
        for r in [0.05, 0.2, 1.0] {
            out.push((
                format!("{dof}' low-passed over {:.3} s", r * period),
                StateLaw::Maxwell { tau: r * period },
            ));
        }
    }
    if x_rms > 0.0 && x_rms.is_finite() {
        for k in [3.0, 30.0] {
            out.push((
                format!(
                    "a friction-like state of {dof} saturating after {:.3e}",
                    x_rms / k
                ),
                StateLaw::Dahl { kappa: k / x_rms },
            ));
        }
    }
    Ok(out)
}

/// Partial correlations of `r` with the history column `hist(law)` of each of `laws`, both
/// residualised on the `present` columns (`present.0(k, j)` is row `k` of column `j`, of
/// `present.1` columns) and a constant by least squares (0 where a column has nothing left).
/// Only `r`, its residual and one history column with its residual are held at a time.
fn partial_correlations<L>(
    r: &[f64],
    present: (&dyn Fn(usize, usize) -> f64, usize),
    laws: &[(String, L)],
    hist: impl Fn(&L) -> Vec<f64>,
) -> Vec<f64> {
    let n = r.len();
    if n == 0 || laws.is_empty() {
        return vec![0.0; laws.len()];
    }
    let (column, p) = present;
    // Columns scaled to unit RMS so the factorisation sees comparable magnitudes.
    let scales: Vec<Option<f64>> = (0..p)
        .map(|j| {
            let squares = (0..n).map(|k| {
                let v = column(k, j);
                v * v
            });
            let s = (squares.sum::<f64>() / n as f64).sqrt();
            (s > 0.0 && s.is_finite()).then_some(s)
        })
        .collect();
    // Row `i`, column `j` of the design: a constant, then the scaled present columns.
    let a = |i: usize, j: usize| -> f64 {
        match j {
            0 => 1.0,
            _ => scales[j - 1].map_or(0.0, |s| column(i, j - 1) / s),
        }
    };
    let cols = p + 1;
    // The least-squares residual by the project's own compression, whose sums run in a fixed
    // order (a dense QR of the tall matrix splits its work by the thread count, which moved
    // these correlations in their last digits between 1, 2 and 7 threads); its rows are
    // written a chunk at a time, never the whole design. A fit that fails (non-finite data)
    // leaves `y` as it is.
    let resid = |y: &[f64]| -> Vec<f64> {
        let fill = |start: usize, mut chunk: faer::MatMut<'_, f64>| {
            for i in 0..chunk.nrows() {
                for j in 0..cols {
                    chunk[(i, j)] = a(start + i, j);
                }
                chunk[(i, cols)] = y[start + i];
            }
            Ok::<(), tfs_regress::RegressError>(())
        };
        let Ok(fit) =
            Compressed::from_chunks(cols, n, fill).and_then(|p| LeastSquares.fit_compressed(&p))
        else {
            return y.to_vec();
        };
        (0..n)
            .map(|i| {
                y[i] - fit
                    .coef
                    .iter()
                    .enumerate()
                    .map(|(k, c)| a(i, k) * c)
                    .sum::<f64>()
            })
            .collect()
    };
    let rr = resid(r);
    laws.iter()
        .map(|(_, law)| corr(&rr, &resid(&hist(law))))
        .collect()
}

/// The share of the binned residual's power that is odd under `mirror` (a bin's mirror bin in
/// x' or in x): each pair of bins with means `a`, `b` splits into an odd part `(a − b)/2` and an
/// even part `(a + b)/2`, whose powers add up to `(a² + b²)/2`, weighted by the precision of
/// their difference, `c_a·c_b/(c_a + c_b)` (the same weight for both bins of a pair, so the share
/// is between 0 and 1 however unevenly the motion fills the two sides). NaN when no pair of bins
/// is filled.
fn odd_share(
    count: &[Vec<usize>],
    mean: &[Vec<f64>],
    mirror: &dyn Fn(usize, usize) -> (usize, usize),
) -> f64 {
    let (mut odd, mut all) = (0.0, 0.0);
    for (i, row) in count.iter().enumerate() {
        for (j, &c) in row.iter().enumerate() {
            let (mi, mj) = mirror(i, j);
            let cm = count[mi][mj];
            if c > 0 && cm > 0 {
                let w = (c * cm) as f64 / (c + cm) as f64;
                let o = 0.5 * (mean[i][j] - mean[mi][mj]);
                odd += w * o * o;
                all += w * mean[i][j] * mean[i][j];
            }
        }
    }
    if all > 0.0 { odd / all } else { f64::NAN }
}

/// Plain words from the probe correlations, the history probes, the symmetry shares and the
/// noise estimate (general rules, no case tables).
#[allow(clippy::too_many_arguments)]
fn summarise(
    dof: &str,
    rel: f64,
    noise_rel: f64,
    noise: &NoiseEstimate,
    corr: &[(String, f64)],
    history: &[(String, f64)],
    odd_v: f64,
    odd_x: f64,
    worst: (f64, f64),
    worst_window: Option<(String, f64, f64)>,
) -> String {
    let pick = |list: &[(String, f64)]| {
        list.iter()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .cloned()
            .unwrap_or(("none".into(), 0.0))
    };
    let best = pick(corr);
    let past = pick(history);
    let mut s = format!(
        "{dof}: equation residual is {:.1} % of the RMS of {dof}'' {}",
        100.0 * rel,
        tfs_signal::estimate::band_words(noise.band_hz)
    );
    // Noise only when the noise estimate says the residual is its size: at most 1.5 times the
    // residual noise alone would leave (at least ~45 % of the residual power is noise).
    let is_noise = rel <= NOISE_FACTOR * noise_rel;
    let systematic = best.1.abs() >= 0.2 || past.1.abs() >= 0.2;
    if noise.clean() {
        s.push_str(&format!(
            "; the records are clean (estimated displacement SNR {}), so none of it is noise",
            noise.snr_words()
        ));
    } else if is_noise {
        s.push_str(&format!(
            "; measurement noise alone would leave {:.1} % (estimated displacement SNR {})",
            100.0 * noise_rel,
            noise.snr_words()
        ));
        if !systematic {
            s.push_str(&format!(
                "; no systematic dependence on x, x', the input or their history (largest correlation {:.2} with {}) — consistent with noise",
                best.1, best.0
            ));
            return s;
        }
    } else {
        s.push_str(&format!(
            "; measurement noise {} {:.1} % (estimated displacement SNR {}), so it is mostly model error, not noise",
            if noise.noise_only {
                "would leave"
            } else {
                "would leave at most"
            },
            100.0 * noise_rel,
            noise.snr_words()
        ));
    }
    if past.1.abs() >= 0.2 && past.1.abs() >= best.1.abs() * 0.5 {
        s.push_str(&format!(
            "; it depends on the motion's history, not only on the present state: partial correlation {:.2} with {} beyond what {dof}, {dof}' and the input explain (a memory effect: hysteresis, relaxation or friction)",
            past.1, past.0
        ));
    } else if best.1.abs() >= 0.2 {
        let shape = match best.0.as_str() {
            "sign(x')" => format!(
                "changes sign with {dof}' and has nearly constant magnitude (dry-friction-like)"
            ),
            "x'*abs(x')" | "x'^3" => format!("grows with |{dof}'| and changes sign with {dof}'"),
            "x'" => format!("is proportional to {dof}' (linear damping is off)"),
            "x^2*x'" => format!("changes sign with {dof}' and grows with the amplitude of {dof}"),
            "x" | "x^3" => {
                format!("changes sign with {dof} and grows with |{dof}| (stiffness is off)")
            }
            "x^2" => format!(
                "has the same sign on both sides of the mean of {dof} and grows with |{dof}| (even in {dof})"
            ),
            "offset" => "is a constant offset".to_string(),
            _ => "follows the input (input gain or delay)".to_string(),
        };
        s.push_str(&format!(
            "; it {shape} (correlation {:.2} with {})",
            best.1, best.0
        ));
    } else {
        s.push_str(&format!(
            "; no simple dependence on x, x', the input or their recent history (largest correlation {:.2} with {}, {:.2} with {})",
            best.1, best.0, past.1, past.0
        ));
    }
    if odd_v.is_finite() && odd_x.is_finite() {
        s.push_str(&format!(
            "; {:.0} % of its binned power is odd in {dof}', {:.0} % odd in {dof}",
            100.0 * odd_v,
            100.0 * odd_x
        ));
    }
    s.push_str(&format!(
        "; largest near {dof} = {:.3}, {dof}' = {:.3}",
        worst.0, worst.1
    ));
    if let Some((rec, t0, t1)) = worst_window {
        s.push_str(&format!("; worst in {rec} at t = {t0:.2}..{t1:.2} s"));
    }
    s
}

/// A residual at most this many times what measurement noise alone would leave is called the
/// size of the noise.
pub const NOISE_FACTOR: f64 = 1.5;

#[cfg(test)]
mod tests {
    use super::odd_share;

    /// The odd share is a share: an even residual gives 0, an odd one 1, and a pair of bins
    /// filled a hundred to one gives the split of its two means (0 and 1: half odd), not the
    /// count-weighted 25× the old weighting gave.
    #[test]
    fn the_odd_share_is_between_zero_and_one_however_uneven_the_bins() {
        let flip = |i: usize, j: usize| (i, 1 - j);
        let even = odd_share(&[vec![3, 7]], &[vec![2.0, 2.0]], &flip);
        let odd = odd_share(&[vec![3, 7]], &[vec![2.0, -2.0]], &flip);
        let uneven = odd_share(&[vec![100, 1]], &[vec![0.0, 1.0]], &flip);
        assert_eq!(even, 0.0);
        assert!((odd - 1.0).abs() < 1e-12, "{odd}");
        assert!((uneven - 0.5).abs() < 1e-12, "{uneven}");
        assert!(odd_share(&[vec![0, 4]], &[vec![0.0, 1.0]], &flip).is_nan());
    }
}
