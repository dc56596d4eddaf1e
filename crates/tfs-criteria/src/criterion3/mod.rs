//! Criterion 3: frequency-domain (weak-form) rows of every DOF. Per record the decimation and
//! the series of `x''` and of every library column ([`series`]), per candidate window count the
//! windowed transforms of every record and their bin weights ([`rows`]), and the choice of δ and
//! the window count by held-out error ([`settings`]).

pub(crate) mod rows;
pub(crate) mod series;
pub(crate) mod settings;

use std::time::Instant;

use rayon::prelude::*;
use tfs_library::Library;

use crate::blocks::Prepared;
use crate::elimination::FirstPass;
use crate::error::Result;
use crate::options::{Checked, TfsOptions};
use crate::pipeline::ms;
use rows::{WindowTransform, reweight, window_transforms};
pub use series::TransformForm;
use series::{decimation, record_series};

/// Windowed transforms per window count and record (`[window count][record][window]`).
pub(crate) type Transforms = Vec<Vec<Vec<WindowTransform>>>;

/// Criterion 3 transforms of DOF `d`: per record the decimation and the series of `x''` and of
/// every library column, then per candidate window count the windowed transforms of every record
/// (gated by `min_bin_snr`), reweighted by `reweight` passes of feasible GLS over the columns
/// `keep`. Returns (decimation per record, transforms per window count and record). Shared by
/// [`identify_tfs`] and the tied chain fit.
pub(crate) fn dof_transforms(
    preps: &[Prepared<'_>],
    spec: &Checked<'_>,
    d: usize,
    lib: &Library,
    keep: &[usize],
) -> Result<(Vec<usize>, Transforms)> {
    let (qs, mut transforms) = unweighted_transforms(preps, spec, d, lib)?;
    reweight_all(&mut transforms, &spec.tfs, keep)?;
    Ok((qs, transforms))
}

/// The most windows per record among the candidate layouts (see [`decimation`]).
pub(crate) fn max_windows(opt: &TfsOptions) -> usize {
    opt.criterion3
        .window_counts
        .iter()
        .copied()
        .max()
        .unwrap_or(1)
}

/// Per-window-count transforms as their rows are weighted: [`reweight`] by `opt.criterion3.reweight` passes
/// of feasible GLS over the columns `keep`, every window count in parallel.
pub(crate) fn reweight_all(
    transforms: &mut [Vec<Vec<WindowTransform>>],
    opt: &TfsOptions,
    keep: &[usize],
) -> Result<()> {
    if opt.criterion3.reweight == 0 {
        return Ok(());
    }
    let dmin = opt
        .criterion3
        .deltas
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    transforms
        .par_iter_mut()
        .with_max_len(1)
        .try_for_each(|t| reweight(t, dmin, keep, opt.criterion3.reweight))
}

/// [`dof_transforms`] before reweighting (every bin's weight 1).
pub(crate) fn unweighted_transforms(
    preps: &[Prepared<'_>],
    spec: &Checked<'_>,
    d: usize,
    lib: &Library,
) -> Result<(Vec<usize>, Transforms)> {
    let opt = &spec.tfs;
    let dmin = opt
        .criterion3
        .deltas
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    let qs: Vec<usize> = preps
        .iter()
        .map(|p| decimation(p, lib, opt.criterion3.form, max_windows(opt)))
        .collect();
    let series: Vec<_> = preps
        .par_iter()
        .with_max_len(1)
        .zip(&qs)
        .map(|(p, &q)| {
            record_series(
                p,
                &spec.dofs,
                d,
                lib,
                opt.criterion3.form,
                opt.criterion3.savitzky_golay,
                q,
                opt.criterion3.debias,
            )
        })
        .collect::<Result<_>>()?;
    let transforms: Vec<Vec<_>> = opt
        .criterion3
        .window_counts
        .par_iter()
        .with_max_len(1)
        .map(|&wc| {
            series
                .par_iter()
                .with_max_len(1)
                .map(|s| window_transforms(s, wc, dmin, opt.criterion3.min_bin_snr))
                .collect()
        })
        .collect();
    Ok((qs, transforms))
}

/// The transforms of DOF `d` for the pass's columns `keep`, reweighted, with the decimation per
/// record and the milliseconds spent: the first pass's transforms restricted to this library's
/// columns where `reuse` has them at the same decimation, else computed afresh.
pub(crate) fn transforms_for(
    preps: &[Prepared<'_>],
    spec: &Checked<'_>,
    d: usize,
    lib: &Library,
    reuse: Option<(&FirstPass, &[usize])>,
    keep: &[usize],
) -> Result<(Vec<usize>, Transforms, f64)> {
    let opt = &spec.tfs;
    let t0 = Instant::now();
    let qs_now: Vec<usize> = preps
        .iter()
        .map(|p| decimation(p, lib, opt.criterion3.form, max_windows(opt)))
        .collect();
    let (qs, mut transforms) = match reuse {
        Some((fp, cols)) if fp.qs == qs_now => (qs_now, fp.unweighted(cols)),
        _ => unweighted_transforms(preps, spec, d, lib)?,
    };
    reweight_all(&mut transforms, opt, keep)?;
    Ok((qs, transforms, ms(t0)))
}
