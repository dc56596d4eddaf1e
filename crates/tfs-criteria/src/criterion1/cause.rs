//! Why κ is below κ0: noise or model error. κ of `[Θ | x'']` is low whenever `x''` lies off the
//! span of the library's columns, and two things put it there: measurement noise (amplified by
//! the differentiation) and a law the library cannot express (a missing term, a memory effect).
//! The calibration cannot tell them apart, since both look alike to κ. The records' own noise
//! estimate can (`tfs_signal::estimate`: the fitted floor of each channel's spectrum). It is
//! carried through the library's linear terms and two ways of differentiating — the records
//! reconstructed at each one's best cut-off, where the least noise comes in for the signal kept,
//! and Criterion 1's Savitzky–Golay derivatives — and gives the share of `x''` that noise alone would leave
//! unexplained each way. A library residual well above that share on the band-limited `x''` is
//! model error, however noisy Criterion 1's own block is; the verdict says low SNR only when the
//! noise accounts for the residual there and in the block.

use faer::Mat;
use rayon::prelude::*;
use serde::Serialize;
use tfs_library::{Factor, Library, Var};
use tfs_regress::{Compressed, lstsq_support};

use std::sync::{Arc, Mutex};
use tfs_signal::band::reconstruct_every;

use crate::blocks::{InputBands, Prepared, td_step, td_stride, td_trim, time_domain};
use crate::error::Result;

/// The residual counts as noise when it is at most this many times the RMS the noise estimate
/// says noise alone would leave (then at least ~45 % of its power is noise); the diagnosis' residual
/// verdict uses the same rule.
pub(crate) const NOISE_FACTOR: f64 = 1.5;

/// Criterion 1's verdict on the data: κ against κ0 and, below κ0, which of noise and model
/// error put `x''` off the library's span, from the records' own noise estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SnrVerdict {
    /// κ ≥ κ0: `x''` lies in the library's span to within a little noise.
    High,
    /// κ < κ0 and the library's residual is about the size measurement noise alone would leave.
    LowSnr {
        /// RMS of the least-squares residual of Criterion 1's Savitzky–Golay `x''` on the
        /// library, over the RMS of that `x''`.
        residual_share: f64,
        /// The same share that the estimated measurement noise alone would leave.
        noise_share: f64,
        /// The library's residual on the records reconstructed at each one's best cut-off, same
        /// scale.
        band_residual_share: f64,
        /// What the estimated noise alone would leave there.
        band_noise_share: f64,
        /// Those best cut-offs over the records (Hz, lowest and highest).
        band_hz: [f64; 2],
    },
    /// κ < κ0, the residual is well above what the estimated noise would leave, and the library
    /// leaves a material part of it on the band-limited reconstruction too: the data are clean
    /// enough, and the library does not explain them (a missing term, a memory effect).
    ModelError {
        /// RMS of the least-squares residual of the band-limited `x''` on the library, over its RMS.
        residual_share: f64,
        /// The same share that the estimated measurement noise alone would leave there.
        noise_share: f64,
        /// True when every floor was fitted on noise alone; otherwise some channel's band reaches
        /// into the half of the spectrum the floor is fitted on and `noise_share` is an upper bound.
        noise_only: bool,
        /// RMS of Criterion 1's Savitzky–Golay `x''` error on the noise-free reconstruction, same
        /// scale (shown when it is a cause too).
        derivative_share: f64,
        /// Those best cut-offs over the records (Hz, lowest and highest).
        band_hz: [f64; 2],
    },
    /// κ < κ0, and the noise estimate could not be carried through the blocks (the reason given):
    /// noise and model error are not told apart.
    Undetermined {
        /// Why.
        reason: &'static str,
    },
    /// κ < κ0, but neither noise nor the library is the cause: Criterion 1's Savitzky–Golay
    /// derivatives err on the signal itself (too few samples per period of its fastest
    /// components), while the library explains the band-limited reconstruction.
    Derivatives {
        /// RMS of the library's residual on Criterion 1's block, over the RMS of `x''`.
        residual_share: f64,
        /// RMS of the Savitzky–Golay `x''` error on the noise-free reconstruction, same scale.
        derivative_share: f64,
        /// The library's residual on the band-limited reconstruction, same scale.
        band_residual_share: f64,
        /// What the estimated noise alone would leave there.
        band_noise_share: f64,
        /// Those best cut-offs over the records (Hz, lowest and highest).
        band_hz: [f64; 2],
    },
}

impl SnrVerdict {
    /// True for [`SnrVerdict::High`].
    pub fn is_high(&self) -> bool {
        matches!(self, SnrVerdict::High)
    }

    /// True for [`SnrVerdict::LowSnr`]: the data are too noisy for κ to reach κ0.
    pub fn is_low_snr(&self) -> bool {
        matches!(self, SnrVerdict::LowSnr { .. })
    }
}

impl std::fmt::Display for SnrVerdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Four significant digits, whatever the size.
        let pct = |v: f64| {
            let p = 100.0 * v;
            let digits = if p > 0.0 {
                (3 - p.log10().floor() as i32).clamp(0, 12) as usize
            } else {
                0
            };
            format!("{p:.digits$} %")
        };
        match *self {
            SnrVerdict::High => f.write_str("high SNR"),
            SnrVerdict::LowSnr {
                residual_share,
                noise_share,
                band_residual_share,
                band_noise_share,
                band_hz,
            } => write!(
                f,
                "low SNR: the library leaves {} of Criterion 1's Savitzky–Golay x'' unexplained and measurement noise alone would leave {} there; of x'' {} (each record's best cut-off) it leaves {} and the noise {} (noise estimate: the fitted floor of the records' spectra through the derivatives)",
                pct(residual_share),
                pct(noise_share),
                tfs_signal::estimate::band_words(band_hz),
                pct(band_residual_share),
                pct(band_noise_share)
            ),
            SnrVerdict::ModelError {
                residual_share,
                noise_share,
                noise_only,
                derivative_share,
                band_hz,
            } => {
                write!(
                    f,
                    "κ below κ0 from model error, not noise: the library leaves {} of x'' {} (each record's best cut-off) unexplained, while measurement noise alone would leave {}{} (noise estimate: the fitted floor of the records' spectra through the derivatives), so the data are clean enough and the library misses part of the law (a term or a memory effect; `tfs diagnose` ranks candidates)",
                    pct(residual_share),
                    tfs_signal::estimate::band_words(band_hz),
                    if noise_only { "" } else { "at most " },
                    pct(noise_share)
                )?;
                if derivative_share > residual_share {
                    write!(
                        f,
                        "; Criterion 1's Savitzky–Golay x'' is also off by {} on the noise-free signal (few samples per period of its fastest components), which holds κ down too",
                        pct(derivative_share)
                    )?;
                }
                Ok(())
            }
            SnrVerdict::Undetermined { reason } => write!(
                f,
                "κ below κ0 from noise or model error (not told apart: {reason})"
            ),
            SnrVerdict::Derivatives {
                residual_share,
                derivative_share,
                band_residual_share,
                band_noise_share,
                band_hz,
            } => write!(
                f,
                "κ below κ0 mostly from the derivatives, not noise: the library leaves {} of x'' unexplained in Criterion 1's block, whose Savitzky–Golay x'' is itself off by {} on the band-limited signal (too few samples per period of its fastest components); of x'' {} (each record's best cut-off) it leaves {} (measurement noise alone would leave {})",
                pct(residual_share),
                pct(derivative_share),
                tfs_signal::estimate::band_words(band_hz),
                pct(band_residual_share),
                pct(band_noise_share)
            ),
        }
    }
}

/// A library column that is one channel to the first power: which channel and through which
/// filter Criterion 1's block sees it (0: as sampled, 1: Savitzky–Golay first derivative).
fn linear_channel(lib: &Library, j: usize) -> Option<(&str, usize)> {
    match lib.terms()[j].factors() {
        [Factor::Pow(Var::Disp(n), 1)] | [Factor::Pow(Var::Input(n), 1)] => Some((n.as_str(), 0)),
        [Factor::Pow(Var::Vel(n), 1)] => Some((n.as_str(), 1)),
        _ => None,
    }
}

/// How a block sees a channel's noise at one frequency: through Criterion 1's Savitzky–Golay
/// derivatives of the raw samples, or through the band-limited reconstruction's spectral
/// derivatives (the displacements cut at the band's cut-off, the inputs raw).
#[derive(Clone, Copy)]
enum Filters<'a> {
    /// Savitzky–Golay weights of the first and second derivative.
    SavitzkyGolay([&'a [f64]; 2]),
    /// The band-limited reconstruction.
    Spectral,
}

impl Filters<'_> {
    /// Responses at `f` (Hz) of derivatives 0 (the samples), 1 and 2, each as (re, im), of the
    /// spectral blocks: `dof` says whether the channel is a displacement (band-limited there)
    /// and `cutoff` is its band's cut-off. (The Savitzky–Golay responses come in batches from
    /// [`sg_responses`].)
    fn spectral(f: f64, dof: bool, cutoff: f64) -> [(f64, f64); 3] {
        if dof && f > cutoff {
            return [(0.0, 0.0); 3];
        }
        let w = 2.0 * std::f64::consts::PI * f;
        [(1.0, 0.0), (0.0, w), (-w * w, 0.0)]
    }
}

/// Bins per batch of [`sg_batch`].
const LANES: usize = 8;

/// The frequency responses at each of the frequencies `fs` (Hz) of the centred Savitzky–Golay
/// weights `w[0]` of the first derivative and `w[1]` of the second (equal, odd lengths `2h + 1`)
/// at sample step `dt`: `Σ_m w_m·e^{i2πf(m−h)dt} / dt^order`, as (re, im), one pair per
/// frequency.
///
/// The taps are summed in pairs about the centre, `w_{h+j}·e^{iθj} + w_{h−j}·e^{−iθj} =
/// (w_{h+j} + w_{h−j})·cos θj + i·(w_{h+j} − w_{h−j})·sin θj`, so each frequency takes one sine
/// and cosine and rotates through the `h` taps of one side. Each frequency's arithmetic is that
/// of a lone evaluation, so the result does not depend on the batching; [`LANES`] frequencies go
/// through the taps side by side so that the compiler keeps them in vector registers.
fn sg_responses(w: [&[f64]; 2], dt: f64, fs: &[f64]) -> Vec<[(f64, f64); 2]> {
    debug_assert_eq!(w[0].len(), w[1].len());
    let h = w[0].len() / 2;
    let taps = SgPairs {
        centre: [w[0][h], w[1][h]],
        pairs: (1..=h)
            .map(|j| {
                let (a, b) = (w[0][h + j], w[0][h - j]);
                let (c, d) = (w[1][h + j], w[1][h - j]);
                [a + b, a - b, c + d, c - d]
            })
            .collect(),
    };
    let mut out = Vec::with_capacity(fs.len());
    for chunk in fs.chunks(LANES) {
        let mut lane = [chunk[0]; LANES];
        lane[..chunk.len()].copy_from_slice(chunk);
        #[cfg(target_arch = "x86_64")]
        let r = if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2, checked just above.
            unsafe { sg_batch_avx2(&taps, dt, &lane) }
        } else {
            sg_batch(&taps, dt, &lane)
        };
        #[cfg(not(target_arch = "x86_64"))]
        let r = sg_batch(&taps, dt, &lane);
        out.extend_from_slice(&r[..chunk.len()]);
    }
    out
}

/// Savitzky–Golay weights of the first and second derivative paired about the centre (see
/// [`sg_responses`]).
struct SgPairs {
    /// The centre weights `w_h` of each.
    centre: [f64; 2],
    /// For `j = 1..=h`: `w_{h+j} + w_{h−j}` and `w_{h+j} − w_{h−j}` of the first, then of the
    /// second.
    pairs: Vec<[f64; 4]>,
}

/// [`sg_batch`] compiled for AVX2 (four lanes per register; the same operations per lane, no
/// fused multiply–add, so the same bits).
///
/// # Safety
/// The processor must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn sg_batch_avx2(taps: &SgPairs, dt: f64, fs: &[f64; LANES]) -> [[(f64, f64); 2]; LANES] {
    sg_batch(taps, dt, fs)
}

/// One batch of [`sg_responses`].
#[inline(always)]
fn sg_batch(taps: &SgPairs, dt: f64, fs: &[f64; LANES]) -> [[(f64, f64); 2]; LANES] {
    // e^{iθj} by rotation from j = 1: one sine and cosine per frequency.
    let (mut c, mut s, mut dc, mut ds) = ([0.0; LANES], [0.0; LANES], [0.0; LANES], [0.0; LANES]);
    for l in 0..LANES {
        let step = 2.0 * std::f64::consts::PI * fs[l] * dt;
        (ds[l], dc[l]) = step.sin_cos();
        (c[l], s[l]) = (dc[l], ds[l]);
    }
    let [c1, c2] = taps.centre;
    let (mut re1, mut im1, mut re2, mut im2) =
        ([c1; LANES], [0.0; LANES], [c2; LANES], [0.0; LANES]);
    for &[p1, m1, p2, m2] in &taps.pairs {
        for l in 0..LANES {
            re1[l] += p1 * c[l];
            im1[l] += m1 * s[l];
            re2[l] += p2 * c[l];
            im2[l] += m2 * s[l];
            (c[l], s[l]) = (c[l] * dc[l] - s[l] * ds[l], s[l] * dc[l] + c[l] * ds[l]);
        }
    }
    let (d1, d2) = (dt.powi(1), dt.powi(2));
    std::array::from_fn(|l| [(re1[l] / d1, im1[l] / d1), (re2[l] / d2, im2[l] / d2)])
}

/// The noise density of a band's floor at its bins `1..=mirror_len/2`
/// ([`tfs_signal::Band::noise_psd`] at `k·bin_hz`, a logarithm and an exponential each), made
/// once per band and step and shared: the block's shares and the band's read the same input
/// bands, and a DOF's floor where its reconstruction at the best cut-off kept the same one. The
/// values are the ones `noise_psd` gives there, so the sums are unchanged to the bit.
#[derive(Default)]
struct Densities(Mutex<Vec<(DensityKey, Arc<Vec<f64>>)>>);

/// What a band's densities depend on: its floor (`ln A`, `β`), bin width and mirror length, and
/// the sampling step (bits).
type DensityKey = (u64, u64, u64, usize, u64);

impl Densities {
    /// The densities of `band` at step `dt` (made on first use).
    fn of(&self, band: &tfs_signal::Band, dt: f64) -> Arc<Vec<f64>> {
        let key = (
            band.floor_log_a.to_bits(),
            band.floor_beta.to_bits(),
            band.bin_hz.to_bits(),
            band.mirror_len,
            dt.to_bits(),
        );
        // A poisoned lock still holds whole entries (each is pushed at once).
        let lock = || self.0.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, d)) = lock().iter().find(|(k, _)| *k == key) {
            return Arc::clone(d);
        }
        let d: Arc<Vec<f64>> = Arc::new(
            (1..=band.mirror_len / 2)
                .map(|k| band.noise_psd(k as f64 * band.bin_hz, dt))
                .collect(),
        );
        lock().push((key, Arc::clone(&d)));
        d
    }
}

/// A channel's gains or their variances, per derivative order: (order, value).
type Gains<'a> = &'a [(usize, f64)];

/// The variance of one channel's estimated noise (floor `band`) through the filter
/// `own·H₂ − Σ c·H_k` (H₂ the second derivative when the channel is the DOF's own displacement,
/// `H_k` the filter the channel's derivative of order `k` is seen through, `c` the fit's local
/// gain in it: its mean over the records), plus each gain's variance over the records in
/// `spread` (order, variance) times the noise through `H_k` alone: the noise of one channel
/// enters `x''` and the library's columns coherently, through gains that vary along the
/// records (`tfs_signal::estimate::residual_noise_var` combines them the same way).
fn channel_noise_var(
    (band, densities): (&tfs_signal::Band, &Densities),
    dt: f64,
    (own, dof): (bool, bool),
    (terms, spread): (Gains<'_>, Gains<'_>),
    filters: Filters<'_>,
) -> f64 {
    if band.bin_hz <= 0.0 || band.mirror_len < 2 {
        return 0.0;
    }
    let cutoff = band.cutoff_hz;
    let bins = band.mirror_len / 2;
    let freq = |k: usize| k as f64 * band.bin_hz;
    // A flat floor has one density at every frequency (`β = 0` adds exactly zero to its log);
    // another floor's densities are made once per band (see [`Densities`]).
    let flat = (band.floor_beta == 0.0).then(|| band.noise_psd(band.bin_hz, dt));
    let psd = match flat {
        Some(_) => None,
        None => Some(densities.of(band, dt)),
    };
    // The Savitzky–Golay responses of every bin, where a derivative reaches this channel (not
    // for an input's own column, which only the samples' response reaches).
    let derivatives = own
        || terms.iter().any(|&(order, _)| order > 0)
        || spread.iter().any(|&(order, v)| order > 0 && v > 0.0);
    let sg = match filters {
        Filters::SavitzkyGolay(w) if derivatives => {
            let fs: Vec<f64> = (1..=bins).map(freq).collect();
            sg_responses(w, dt, &fs)
        }
        _ => Vec::new(),
    };
    (1..=bins)
        .map(|k| {
            let f = freq(k);
            let resp = match filters {
                Filters::SavitzkyGolay(_) if derivatives => {
                    let [r1, r2] = sg[k - 1];
                    [(1.0, 0.0), r1, r2]
                }
                Filters::SavitzkyGolay(_) => [(1.0, 0.0), (0.0, 0.0), (0.0, 0.0)],
                Filters::Spectral => Filters::spectral(f, dof, cutoff),
            };
            let (mut re, mut im) = if own { resp[2] } else { (0.0, 0.0) };
            for &(order, c) in terms {
                let (r, i) = resp[order];
                re -= c * r;
                im -= c * i;
            }
            let mut power = re * re + im * im;
            for &(order, v) in spread {
                if v > 0.0 {
                    let (r, i) = resp[order];
                    power += v * (r * r + i * i);
                }
            }
            flat.unwrap_or_else(|| psd.as_ref().map_or(0.0, |d| d[k - 1])) * power
        })
        .sum::<f64>()
        * 2.0
        * band.bin_hz
}

/// The local gains of `model`'s equation `d` in every DOF along one record's full-length
/// reconstructions (`prep.smooth`), over the rows of its time-domain block (trimmed ends, every
/// [`td_stride`]-th sample); `None` when an input the model reads is not in the record or the
/// reconstructions are not full length.
fn local_gains(
    model: &tfs_library::CompiledModel,
    d: usize,
    prep: &Prepared<'_>,
) -> Option<Vec<tfs_library::LocalGains>> {
    let len = prep.rec.len();
    if prep
        .smooth
        .iter()
        .any(|s| s.x.len() != len || s.v.len() != len)
    {
        return None;
    }
    let x: Vec<&[f64]> = prep.smooth.iter().map(|s| s.x.as_slice()).collect();
    let v: Vec<&[f64]> = prep.smooth.iter().map(|s| s.v.as_slice()).collect();
    let u: Vec<&[f64]> = model
        .input_names()
        .iter()
        .map(|n| prep.rec.column(n).filter(|c| c.len() == len))
        .collect::<Option<_>>()?;
    let trim = td_trim(len);
    let rows = (trim..len.saturating_sub(trim)).step_by(td_stride(len));
    Some(model.local_gains(d, &x, &v, &u, rows))
}

/// The residual of `x''` on the library over blocks `td` (columns `nonconst`, with a constant)
/// as a share of `x''`'s RMS, and the share the records' estimated noise would leave through the
/// blocks' `filters`: each displacement's noise through the fit's local gains in it along the
/// records (`gain_states`, full-length reconstructions of the same records; see
/// [`local_gains`]), each input's through the fit's linear terms in it, the floors' densities
/// read from `densities`. Also says whether every floor was fitted on noise alone.
fn shares(
    td: &[(Mat<f64>, Vec<f64>)],
    nonconst: &[usize],
    (preps, gain_states): (&[Prepared<'_>], &[Prepared<'_>]),
    (dofs, d, lib): (&[String], usize, &Library),
    (filters, densities): (Filters<'_>, &Densities),
) -> Result<(f64, f64, bool)> {
    let comps = td
        .par_iter()
        .map(|(a, y)| {
            let aa = Mat::<f64>::from_fn(a.nrows(), nonconst.len() + 1, |i, j| {
                if j == 0 { 1.0 } else { a[(i, nonconst[j - 1])] }
            });
            Compressed::from_rows(aa.as_ref(), y)
        })
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let merged = Compressed::merge(&comps)?;
    let fit = lstsq_support(&merged, &vec![true; nonconst.len() + 1])?;
    let rows: usize = td.iter().map(|(_, y)| y.len()).sum();
    let mean = td.iter().flat_map(|(_, y)| y).sum::<f64>() / rows.max(1) as f64;
    let var_acc = td
        .iter()
        .flat_map(|(_, y)| y)
        .map(|v| (v - mean).powi(2))
        .sum::<f64>();
    let residual_share = (fit.rss.max(0.0) / var_acc.max(f64::MIN_POSITIVE)).sqrt();
    // The linear terms of each channel with their fitted coefficients: the inputs' are used as
    // they are, the DOFs' stand in for the local gains where those cannot be evaluated.
    let mut channels: Vec<(String, Vec<(usize, f64)>)> =
        dofs.iter().map(|n| (n.clone(), Vec::new())).collect();
    let mut coefs = vec![vec![0.0; lib.len()]; dofs.len()];
    for (jj, &j) in nonconst.iter().enumerate() {
        let c = fit.coef[jj + 1];
        coefs[d][j] = c;
        if let Some((name, order)) = linear_channel(lib, j) {
            match channels.iter_mut().find(|(n, _)| n == name) {
                Some((_, t)) => t.push((order, c)),
                None => channels.push((name.to_string(), vec![(order, c)])),
            }
        }
    }
    let compiled = tfs_library::Model::from_coefficients(lib, &coefs, "criterion 1")
        .and_then(|m| m.compile())
        .ok();
    // Per record (in parallel, summed in order): the noise variance left in x'' and whether every
    // floor was fitted on noise alone.
    let per_record: Vec<(f64, bool)> = preps
        .par_iter()
        .zip(gain_states)
        .with_max_len(1)
        .map(|(p, g)| {
            let dt = p.dt;
            let gains = compiled.as_ref().and_then(|c| local_gains(c, d, g));
            let (mut var, mut noise_only) = (0.0, true);
            for (name, terms) in &channels {
                let own = *name == dofs[d];
                let dof = dofs.iter().position(|n| n == name);
                let (terms, spread) = match (dof, &gains) {
                    (Some(k), Some(gains)) => {
                        let g = gains[k];
                        let mean: Vec<(usize, f64)> = [(0, g.disp.mean), (1, g.vel.mean)]
                            .into_iter()
                            .filter(|&(_, c)| c != 0.0)
                            .collect();
                        (mean, vec![(0, g.disp.var), (1, g.vel.var)])
                    }
                    _ => (terms.clone(), Vec::new()),
                };
                if !own && terms.is_empty() && spread.iter().all(|&(_, v)| v <= 0.0) {
                    continue;
                }
                let band = match dof {
                    Some(k) => p.smooth[k].band,
                    None => match p.input_bands.get(p.rec, name, dt) {
                        Some(b) => b,
                        None => continue,
                    },
                };
                noise_only &= band.floor_is_noise_only();
                var += channel_noise_var(
                    (&band, densities),
                    dt,
                    (own, dof.is_some()),
                    (&terms, &spread),
                    filters,
                );
            }
            (var, noise_only)
        })
        .collect();
    let noise_only = per_record.iter().all(|r| r.1);
    let (noise_sum, weight) = per_record
        .iter()
        .zip(td)
        .fold((0.0, 0.0), |(s, n), ((v, _), (_, y))| {
            (s + v * y.len() as f64, n + y.len() as f64)
        });
    let noise_share = if weight > 0.0 && var_acc > 0.0 {
        (noise_sum / weight / (var_acc / rows as f64)).sqrt()
    } else {
        0.0
    };
    Ok((residual_share, noise_share, noise_only))
}

/// The error of Criterion 1's Savitzky–Golay second derivative on the records' band-limited
/// reconstructions (noise-free for clean records) against their spectral second derivative, as a
/// share of the latter's RMS: how far the block's `x''` is off for want of samples per period,
/// whatever the noise.
fn derivative_share(preps: &[Prepared<'_>], d: usize, w2: &[f64]) -> f64 {
    let h = w2.len() / 2;
    let (mut err, mut sum, mut sum2, mut rows) = (0.0, 0.0, 0.0, 0usize);
    for p in preps {
        let s = &p.smooth[d];
        let n = s.x.len();
        let trim = (n / 50).max(h + 1);
        let scale = p.dt * p.dt;
        for i in trim..n.saturating_sub(trim) {
            let sg = w2
                .iter()
                .zip(&s.x[i - h..=i + h])
                .map(|(a, b)| a * b)
                .sum::<f64>()
                / scale;
            err += (sg - s.a[i]).powi(2);
            sum += s.a[i];
            sum2 += s.a[i] * s.a[i];
            rows += 1;
        }
    }
    if rows == 0 {
        return 0.0;
    }
    let var = sum2 - sum * sum / rows as f64;
    if var > 0.0 { (err / var).sqrt() } else { 0.0 }
}

/// Least share of the power of Criterion 1's residual (beyond its noise) that the library's
/// band-limited residual must reach to be named a cause: below a tenth, the model error is too
/// small a part of what holds κ down.
const MODEL_SHARE: f64 = 0.1;

/// Why κ is below κ0 (see the module docs): `td` is Criterion 1's own block (columns
/// `nonconst`), `sg` its Savitzky–Golay half window and order. The band-limited reconstruction
/// is looked at first, being where the noise is least: model error when the library leaves more
/// of its `x''` than [`NOISE_FACTOR`] times what the noise would, and that excess is at least
/// [`MODEL_SHARE`] of the block's excess over its own noise. Otherwise low SNR when noise
/// explains the block's residual (it leaves at least 1/[`NOISE_FACTOR`]² of its power);
/// otherwise the block's derivatives are the cause.
pub(crate) fn low_kappa_cause(
    td: &[(Mat<f64>, Vec<f64>)],
    nonconst: &[usize],
    preps: &[Prepared<'_>],
    (dofs, d, lib): (&[String], usize, &Library),
    sg: (usize, usize),
) -> Result<SnrVerdict> {
    let (h, order) = sg;
    let w1 = tfs_signal::savitzky_golay_weights(h, order, 1, h)?;
    let w2 = tfs_signal::savitzky_golay_weights(h, order, 2, h)?;
    let densities = Densities::default();
    // Criterion 1's own block, and the records reconstructed at the cut-off that best
    // reconstructs each DOF (no guard band): where the least noise is let in for the signal kept.
    // Independent, so both at once; the reconstructions read the spectra each DOF's own band
    // search kept, which hold every spectrum this search needs when it tries the same end trends.
    let (block, plain) = rayon::join(
        || {
            shares(
                td,
                nonconst,
                (preps, preps),
                (dofs, d, lib),
                (Filters::SavitzkyGolay([&w1, &w2]), &densities),
            )
        },
        || -> Vec<Prepared<'_>> {
            preps
                .par_iter()
                .with_max_len(1)
                .map(|p| {
                    let kept = p.take_spectra(dofs.len());
                    Prepared {
                        rec: p.rec,
                        dt: p.dt,
                        input_bands: InputBands::default(),
                        spectra: Default::default(),
                        smooth: p
                            .smooth
                            .iter()
                            .zip(dofs)
                            .zip(kept)
                            .map(|((s, name), mut kept)| {
                                let x = p.rec.column(name).expect("checked when prepared");
                                let cut = (Some(s.band.mse_cutoff_hz), 0.0);
                                let q = td_step(p.rec.len());
                                reconstruct_every(x, p.dt, cut, &mut kept, q)
                            })
                            .collect(),
                    }
                })
                .collect()
        },
    );
    let (residual_share, noise_share, _) = block?;
    // The input columns' bands the block's shares found (the same records).
    let plain: Vec<Prepared<'_>> = plain
        .into_iter()
        .zip(preps)
        .map(|(q, p)| Prepared {
            input_bands: p.input_bands.snapshot(),
            ..q
        })
        .collect();
    // Only the block's rows of each reconstruction were made (every `td_step`-th sample).
    let bl = plain
        .par_iter()
        .with_max_len(1)
        .map(|p| time_domain(p, dofs, d, lib, td_step(p.rec.len())))
        .collect::<Result<Vec<_>>>()?;
    let (band_residual, band_noise, noise_only) = shares(
        &bl,
        nonconst,
        (&plain, preps),
        (dofs, d, lib),
        (Filters::Spectral, &densities),
    )?;
    let band_hz = plain
        .iter()
        .map(|p| p.smooth[d].band.cutoff_hz)
        .fold([f64::INFINITY, 0.0], |[lo, hi], c| [lo.min(c), hi.max(c)]);
    let model_power = band_residual.powi(2) - band_noise.powi(2);
    let block_power = residual_share.powi(2) - noise_share.powi(2);
    // A residual well above the noise where the noise is least is the library's, whatever the
    // noisier block says: the noise cannot be the reason the fit misses the law there.
    if band_residual > NOISE_FACTOR * band_noise && model_power >= MODEL_SHARE * block_power {
        return Ok(SnrVerdict::ModelError {
            residual_share: band_residual,
            noise_share: band_noise,
            noise_only,
            derivative_share: derivative_share(preps, d, &w2),
            band_hz,
        });
    }
    if residual_share <= NOISE_FACTOR * noise_share {
        return Ok(SnrVerdict::LowSnr {
            residual_share,
            noise_share,
            band_residual_share: band_residual,
            band_noise_share: band_noise,
            band_hz,
        });
    }
    Ok(SnrVerdict::Derivatives {
        residual_share,
        derivative_share: derivative_share(preps, d, &w2),
        band_residual_share: band_residual,
        band_noise_share: band_noise,
        band_hz,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The response of one set of weights at one frequency, alone: one sine and cosine, the
    /// taps paired about the centre and summed outward by rotation.
    fn one_response(w: &[f64], order: usize, dt: f64, f: f64) -> (f64, f64) {
        let h = w.len() / 2;
        let step = 2.0 * std::f64::consts::PI * f * dt;
        let (ds, dc) = step.sin_cos();
        let (mut c, mut s) = (dc, ds);
        let (mut re, mut im) = (w[h], 0.0);
        for j in 1..=h {
            re += (w[h + j] + w[h - j]) * c;
            im += (w[h + j] - w[h - j]) * s;
            (c, s) = (c * dc - s * ds, s * dc + c * ds);
        }
        let scale = dt.powi(order as i32);
        (re / scale, im / scale)
    }

    /// The batched Savitzky–Golay responses are the one-at-a-time ones to the bit, for every
    /// frequency of a batch and of a partial last batch, and match the filter's defining sum.
    #[test]
    fn batched_sg_responses_equal_single_ones_to_the_bit() {
        let dt = 0.005;
        for h in [3usize, 12] {
            let w1 = tfs_signal::savitzky_golay_weights(h, 3, 1, h).unwrap();
            let w2 = tfs_signal::savitzky_golay_weights(h, 3, 2, h).unwrap();
            let fs: Vec<f64> = (1..=3 * LANES + 5).map(|k| 0.37 * k as f64).collect();
            let got = sg_responses([&w1, &w2], dt, &fs);
            assert_eq!(got.len(), fs.len());
            for (f, [r1, r2]) in fs.iter().zip(&got) {
                let (a1, a2) = (one_response(&w1, 1, dt, *f), one_response(&w2, 2, dt, *f));
                assert_eq!(
                    (r1.0.to_bits(), r1.1.to_bits()),
                    (a1.0.to_bits(), a1.1.to_bits())
                );
                assert_eq!(
                    (r2.0.to_bits(), r2.1.to_bits()),
                    (a2.0.to_bits(), a2.1.to_bits())
                );
                // The defining sum with each phase factor computed directly.
                for (w, order, r) in [(&w1, 1, r1), (&w2, 2, r2)] {
                    let direct = w
                        .iter()
                        .enumerate()
                        .map(|(m, wm)| {
                            let th = 2.0 * std::f64::consts::PI * f * (m as f64 - h as f64) * dt;
                            (wm * th.cos(), wm * th.sin())
                        })
                        .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
                    let d = dt.powi(order);
                    let scale = (w.iter().map(|v| v.abs()).sum::<f64>()) / d;
                    assert!((direct.0 / d - r.0).abs() < 1e-9 * scale);
                    assert!((direct.1 / d - r.1).abs() < 1e-9 * scale);
                }
            }
        }
    }
}
