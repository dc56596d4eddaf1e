//! The κ0 calibration of Criterion 1: white noise added at decreasing SNRs to a segment of the
//! user's own data, κ measured at every level, κ0 at the knee of κ(SNR) plus a margin.

use rayon::prelude::*;
use tfs_data::Record;
use tfs_library::Library;

use super::criterion1_columns;
use super::criterion1_kappa;
use super::kappa::{CalibrationPoint, Kappa, Kappa0Source, kappa0_from_curve};
use crate::error::Result;
use crate::options::{Checked, TfsOptions};

/// Least fall of κ (decades) over the whole calibration for the data to count as cleaner than the
/// noise added, and the margin by which κ must exceed the κ at the knee: κ of clean data falls by
/// a decade or more when 10 dB noise is added (x'' by differentiation becomes noise), while its
/// scatter between noise draws is a few hundredths.
pub(crate) const MIN_CALIBRATION_DROP: f64 = 0.25;

/// Most samples the κ0 calibration looks at (a central segment of the longest record).
const CALIBRATION_SAMPLES: usize = 20_000;

/// The κ0 calibration's measurements: white noise added at each SNR of
/// `calibration_snrs_db` to the DOF displacements and linear inputs of the central ≤ 20,000
/// samples of the longest record, and κ recomputed. Returns κ of that segment itself and the
/// point of each level; the segment and every level are computed in parallel.
pub(crate) fn calibration_points(
    blocks: &[Record],
    spec: &Checked<'_>,
    d: usize,
    lib: &Library,
    nonconst: &[usize],
) -> Result<(Kappa, Vec<CalibrationPoint>)> {
    let opt = &spec.tfs;
    // Each column once, in order of first mention: several terms of one input (`xb_acc`,
    // `xb_acc^2`) name the same column, and a record holds each column once.
    let mut noisy_cols: Vec<String> = Vec::new();
    let named = spec.dofs.iter().cloned().chain(
        lib.terms()
            .iter()
            .filter(|t| t.uses_input() && t.factors().len() == 1)
            .flat_map(|t| t.required_columns()),
    );
    for c in named {
        if !noisy_cols.contains(&c) {
            noisy_cols.push(c);
        }
    }
    // The central ≤ 20,000 samples of the longest record are enough to see where κ starts to fall.
    let longest = (0..blocks.len())
        .max_by_key(|&i| blocks[i].len())
        .unwrap_or(0);
    let src = &blocks[longest];
    let n = src.len();
    let (a, b) = if n > CALIBRATION_SAMPLES {
        ((n - CALIBRATION_SAMPLES) / 2, (n + CALIBRATION_SAMPLES) / 2)
    } else {
        (0, n)
    };
    let cols = src
        .names()
        .iter()
        .map(|nm| {
            (
                nm.clone(),
                src.column(nm).expect("own column")[a..b].to_vec(),
            )
        })
        .collect();
    let segment = Record::new(src.source(), src.t()[a..b].to_vec(), cols)?;
    // One unit-level noise draw per column, scaled to each calibration SNR (common random
    // numbers: the curve's steps show the effect of the level, not of a new draw, and the draw is
    // made once instead of once per level).
    let reference_db = 0.0;
    let unit: Vec<(String, Vec<f64>)> = noisy_cols
        .iter()
        .enumerate()
        .filter_map(|(ci, c)| {
            segment.column(c).map(|v| {
                tfs_signal::noise::noise_for(
                    v,
                    reference_db,
                    tfs_signal::NoiseKind::White,
                    1000 + ci as u64,
                )
                .map(|n| (c.clone(), n))
            })
        })
        .collect::<std::result::Result<_, _>>()?;
    // Criterion 1's columns (samples, Savitzky–Golay derivatives) are linear in the record's:
    // those of the segment plus noise at a level are the segment's plus the level's scale
    // times the noise's, so both are made once and every level only adds them.
    let noise_rec = Record::new(segment.source(), segment.t().to_vec(), unit)?;
    let (seg_cols, seg_acc) = criterion1_columns(&segment, spec, d, lib)?;
    let (noise_cols, noise_acc) = criterion1_columns(&noise_rec, spec, d, lib)?;
    // The segment as it is (no added noise) first, then every level.
    let levels: Vec<Option<f64>> = std::iter::once(None)
        .chain(opt.criterion1.calibration_snrs_db.iter().map(|&v| Some(v)))
        .collect();
    let mut points: Vec<CalibrationPoint> = levels
        .par_iter()
        .with_max_len(1)
        .map(|&snr| -> Result<CalibrationPoint> {
            let block = match snr {
                None => (lib.evaluate(&seg_cols)?, seg_acc.clone()),
                Some(snr) => {
                    let scale = 10f64.powf(-(snr - reference_db) / 20.0);
                    let acc = seg_acc
                        .iter()
                        .zip(&noise_acc)
                        .map(|(a, b)| a + scale * b)
                        .collect();
                    (
                        lib.evaluate(&seg_cols.plus_scaled(scale, &noise_cols))?,
                        acc,
                    )
                }
            };
            Ok(CalibrationPoint {
                added_snr_db: snr,
                kappa: criterion1_kappa(&[block], nonconst)?,
            })
        })
        .collect::<Result<_>>()?;
    let seg_kappa = points.remove(0).kappa;
    Ok((seg_kappa, points))
}

/// κ0 from a calibration, how it was obtained, the curve (the records' own κ first) and the
/// knee's added-noise SNR.
pub(crate) struct Calibration {
    /// The threshold.
    pub kappa0: f64,
    /// How it was obtained.
    pub source: Kappa0Source,
    /// κ of the data and at every added-noise level.
    pub curve: Vec<CalibrationPoint>,
    /// The knee's added-noise SNR (dB), if there is a knee.
    pub knee_snr_db: Option<f64>,
}

/// κ0 from the calibration's measurements ([`calibration_points`]: κ of the segment and the
/// points of every added-noise level), with `kappa` the records' own κ: κ at the knee of
/// κ(SNR) plus a margin. Returns (κ0, how, the curve, the knee's SNR).
pub(crate) fn calibrate(
    kappa: Kappa,
    seg_kappa: Kappa,
    points: Vec<CalibrationPoint>,
    opt: &TfsOptions,
) -> Calibration {
    let mut curve = vec![CalibrationPoint {
        added_snr_db: None,
        kappa,
    }];
    curve.extend(points);
    // The knee is found on the segment's own curve (the data point of `curve` is κ of every
    // record, a slightly different quantity).
    let seg_top = seg_kappa.get(opt.criterion1.kappa_variant);
    let mut seg_curve = vec![CalibrationPoint {
        added_snr_db: None,
        kappa: seg_kappa,
    }];
    seg_curve.extend(curve[1..].iter().cloned());
    let lowest = curve[1..]
        .iter()
        .map(|p| p.kappa.get(opt.criterion1.kappa_variant))
        .fold(f64::INFINITY, f64::min);
    let drop = seg_top - lowest;
    if drop < MIN_CALIBRATION_DROP {
        // Adding noise of every calibration level leaves κ where it was: the data already carry
        // at least that much noise. Clean data always lose κ when noise this strong is added
        // (x'' by differentiation becomes noise), so this is the low-SNR case, not a flat
        // high-SNR plateau.
        let weakest = opt
            .criterion1
            .calibration_snrs_db
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min);
        return Calibration {
            kappa0: seg_top + MIN_CALIBRATION_DROP,
            source: Kappa0Source::LowSnr {
                drop,
                weakest_db: weakest,
            },
            curve,
            knee_snr_db: None,
        };
    }
    match kappa0_from_curve(&seg_curve, opt.criterion1.kappa_variant) {
        // Data whose own noise already sits at the knee give a knee κ equal to their own κ; the
        // margin keeps such data on the low side instead of deciding by the scatter of κ.
        Some((k0, snr)) => Calibration {
            kappa0: k0 + MIN_CALIBRATION_DROP,
            source: Kappa0Source::Knee {
                snr_db: snr,
                kappa: k0,
            },
            curve,
            knee_snr_db: Some(snr),
        },
        None => {
            let k0 = curve
                .iter()
                .map(|p| p.kappa.get(opt.criterion1.kappa_variant))
                .fold(f64::INFINITY, f64::min);
            Calibration {
                kappa0: k0,
                source: Kappa0Source::NeverDropped,
                curve,
                knee_snr_db: None,
            }
        }
    }
}
