//! Records as the stages see them: cut into blocks of fast transform lengths (a single record
//! into two halves, so there is always held-out data), checked, every DOF reconstructed in its
//! data-chosen band, and the time-domain blocks `(Θ, x'')` the held-out checks score on.

use faer::Mat;
use rayon::prelude::*;
use std::sync::Mutex;
use tfs_data::{Columns, Record};
use tfs_library::{ColumnSet, Library};
use tfs_signal::band::{band_guarded, reconstruct_guarded, reconstruct_keeping};
use tfs_signal::spectra::Spectra;
use tfs_signal::{Band, Smoothed};

use crate::error::{CriteriaError, Result, invalid};
use crate::options::Checked;
use crate::trace::RecordBins;

/// The first `len` samples of a record.
fn head(r: &Record, len: usize, name: String) -> Result<Record> {
    let cols = r
        .names()
        .iter()
        .map(|nm| {
            (
                nm.clone(),
                r.column(nm).expect("own column")[..len].to_vec(),
            )
        })
        .collect();
    Ok(Record::new(name, r.t()[..len].to_vec(), cols)?)
}

/// Records cut to a fast FFT length (at most a fraction of a percent of the samples dropped at
/// the end); a single record is split into two halves so there is always held-out data.
pub(crate) fn blocks_of(records: &[Record]) -> Result<Vec<Record>> {
    if records.is_empty() {
        return invalid("no records given; pass at least one measurement record");
    }
    if records.len() > 1 {
        return records
            .par_iter()
            .map(|r| {
                let m = tfs_signal::smooth_len(r.len());
                if m == r.len() {
                    Ok(r.clone())
                } else {
                    head(r, m, r.source().to_string())
                }
            })
            .collect();
    }
    let r = &records[0];
    let n = r.len();
    let h = tfs_signal::smooth_len(n / 2);
    let mut out = Vec::new();
    for (k, (a, b)) in [(0, h), (h, h + tfs_signal::smooth_len(n - h))]
        .into_iter()
        .enumerate()
    {
        let cols = r
            .names()
            .iter()
            .map(|nm| (nm.clone(), r.column(nm).expect("own column")[a..b].to_vec()))
            .collect();
        out.push(Record::new(
            format!("{}#{}", r.source(), k + 1),
            r.t()[a..b].to_vec(),
            cols,
        )?);
    }
    Ok(out)
}

/// Every block checked and its DOFs reconstructed (see [`prepare`]; the band searches' spectra
/// kept for Criterion 1's cause when `keep_spectra`), the blocks in parallel; the error reported
/// is the first block's.
pub(crate) fn prepare_all<'a>(
    blocks: &'a [Record],
    spec: &Checked<'_>,
    keep_spectra: bool,
) -> Result<Vec<Prepared<'a>>> {
    blocks
        .par_iter()
        .with_max_len(1)
        .map(|r| {
            prepare(
                r,
                &spec.dofs,
                spec.tfs.criterion3.cutoff_hz,
                spec.tfs.reconstruction_guard(),
                keep_spectra,
            )
        })
        // Collected in order so the error reported is the first record's (rayon's own
        // collection into a `Result` keeps whichever failed first in time).
        .collect::<Vec<_>>()
        .into_iter()
        .collect()
}

/// Checks a record has the DOF columns, enough samples and a usable time step.
pub(crate) fn check_record(rec: &Record, dofs: &[String]) -> Result<f64> {
    let dt = rec.dt();
    if rec.len() < 64 {
        return invalid(format!(
            "record '{}' has {} samples; at least 64 are needed",
            rec.source(),
            rec.len()
        ));
    }
    if !(dt.is_finite() && dt > 0.0) {
        return invalid(format!(
            "record '{}': the time column 't' must increase uniformly (dt = {dt})",
            rec.source()
        ));
    }
    for d in dofs {
        let Some(c) = rec.column(d) else {
            return invalid(format!(
                "record '{}' has no column '{d}' for DOF '{d}'; columns are {:?}",
                rec.source(),
                rec.names()
            ));
        };
        if let Some(i) = c.iter().position(|v| !v.is_finite()) {
            return invalid(format!(
                "record '{}', column '{d}', row {}: value {} is not finite",
                rec.source(),
                i + 1,
                c[i]
            ));
        }
    }
    Ok(dt)
}

/// A record with every DOF reconstructed in its data-chosen band.
pub(crate) struct Prepared<'a> {
    pub rec: &'a Record,
    pub dt: f64,
    pub smooth: Vec<Smoothed>,
    /// The bands of its input columns, found on first use.
    pub input_bands: InputBands,
    /// The mirror spectra each DOF's band search transformed (see [`KEEP_SPECTRA_UP_TO`]), for
    /// Criterion 1's cause, which reconstructs the DOFs again at their best cut-offs
    /// ([`Prepared::take_spectra`]); empty when not kept.
    pub spectra: Mutex<Vec<Spectra>>,
}

/// Records up to this many samples keep the mirror spectra of their DOFs' band searches until
/// Criterion 1 has run (a few MB for the peers records; a second search on them transforms
/// nothing again). Longer ones do not: their spectra would be tens of MB each, held through the
/// whole fit for a cause that is needed only below κ0.
const KEEP_SPECTRA_UP_TO: usize = 1 << 18;

impl Prepared<'_> {
    /// The kept spectra of every DOF (empty ones where none were kept), handed over and no
    /// longer held here.
    pub(crate) fn take_spectra(&self, dofs: usize) -> Vec<Spectra> {
        let mut v = std::mem::take(&mut *self.spectra.lock().unwrap_or_else(|e| e.into_inner()));
        v.resize_with(dofs, Spectra::new);
        v
    }

    /// Drops the kept spectra (once no Criterion 1 can need them).
    pub(crate) fn release_spectra(&self) {
        drop(self.take_spectra(0));
    }
}

/// The bands of a record's input columns, each found once on first use (by
/// [`tfs_signal::band::band_guarded`], as [`tfs_signal::band::reconstruct`] would choose it) and
/// shared by every DOF and pass that reads its noise floor (Criterion 1's noise estimate).
#[derive(Default)]
pub(crate) struct InputBands(Mutex<Vec<(String, Band)>>);

impl InputBands {
    /// The band of the column `name` of `rec` (sampled at `dt`), or `None` without that column.
    pub(crate) fn get(&self, rec: &Record, name: &str, dt: f64) -> Option<Band> {
        let found = |v: &[(String, Band)]| v.iter().find(|(n, _)| n == name).map(|(_, b)| *b);
        // A poisoned lock still holds whole entries (each is pushed at once).
        let lock = || self.0.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(b) = found(&lock()) {
            return Some(b);
        }
        let b = band_guarded(rec.column(name)?, dt, None, 0.0);
        lock().push((name.to_string(), b));
        Some(b)
    }

    /// A copy holding the bands found so far (for the same record reconstructed another way).
    pub(crate) fn snapshot(&self) -> Self {
        let v = self.0.lock().unwrap_or_else(|e| e.into_inner()).clone();
        Self(Mutex::new(v))
    }
}

/// Validates a record and reconstructs every DOF: band-limited at `cutoff_hz`, or at the
/// data-chosen cut-off raised by `guard_octaves` (see [`reconstruct_guarded`]). The band
/// searches' spectra are kept when `keep_spectra` and the record is at most
/// [`KEEP_SPECTRA_UP_TO`] long (without them Criterion 1's cause transforms again and finds the
/// same bits).
pub(crate) fn prepare<'a>(
    rec: &'a Record,
    dofs: &[String],
    cutoff_hz: Option<f64>,
    guard_octaves: f64,
    keep_spectra: bool,
) -> Result<Prepared<'a>> {
    let dt = check_record(rec, dofs)?;
    let keep = keep_spectra && rec.len() <= KEEP_SPECTRA_UP_TO;
    let mut spectra = Vec::new();
    let smooth = dofs
        .iter()
        .map(|d| {
            let x = rec.column(d).expect("checked");
            if keep {
                let mut kept = Spectra::new();
                let s = reconstruct_keeping(x, dt, (cutoff_hz, guard_octaves), &mut kept);
                spectra.push(kept);
                s
            } else {
                reconstruct_guarded(x, dt, cutoff_hz, guard_octaves)
            }
        })
        .collect();
    Ok(Prepared {
        rec,
        dt,
        smooth,
        input_bands: InputBands::default(),
        spectra: Mutex::new(spectra),
    })
}

/// Columns of a prepared record: the DOFs and their velocities replaced by the reconstruction.
pub(crate) fn smoothed_columns<'a>(p: &'a Prepared<'_>, dofs: &[String]) -> Result<ColumnSet<'a>> {
    let mut cs = ColumnSet::new(p.rec as &dyn Columns);
    for (d, s) in dofs.iter().zip(&p.smooth) {
        cs.insert(d.clone(), s.x.clone())?;
        cs.insert(format!("{d}'"), s.v.clone())?;
    }
    Ok(cs)
}

/// Raw columns with Savitzky–Golay velocities, and the SG acceleration of DOF `dof`.
pub(crate) fn raw_columns_sg<'a>(
    rec: &'a Record,
    dofs: &[String],
    dof: usize,
    dt: f64,
    sg: (usize, usize),
) -> Result<(ColumnSet<'a>, Vec<f64>)> {
    let mut cs = ColumnSet::new(rec as &dyn Columns);
    let mut acc = Vec::new();
    for (i, d) in dofs.iter().enumerate() {
        let x = rec.column(d).expect("checked");
        let v = tfs_signal::savitzky_golay(x, dt, sg.0, sg.1, 1)?;
        cs.insert(format!("{d}'"), v)?;
        if i == dof {
            acc = tfs_signal::savitzky_golay(x, dt, sg.0, sg.1, 2)?;
        }
    }
    Ok((cs, acc))
}

/// Owned columns of equal length (a strided subsample of a [`ColumnSet`]).
pub(crate) struct OwnedColumns {
    /// Row count.
    pub rows: usize,
    /// The columns by name.
    pub cols: Vec<(String, Vec<f64>)>,
}

impl OwnedColumns {
    /// These columns plus `s` times the column of the same name in `other` (a column `other`
    /// lacks is kept as it is).
    pub(crate) fn plus_scaled(&self, s: f64, other: &OwnedColumns) -> OwnedColumns {
        OwnedColumns {
            rows: self.rows,
            cols: self
                .cols
                .iter()
                .map(|(name, v)| {
                    let v = match other.column(name) {
                        Some(o) => v.iter().zip(o).map(|(a, b)| a + s * b).collect(),
                        None => v.clone(),
                    };
                    (name.clone(), v)
                })
                .collect(),
        }
    }
}

impl Columns for OwnedColumns {
    fn column(&self, name: &str) -> Option<&[f64]> {
        self.cols
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }
    fn rows(&self) -> usize {
        self.rows
    }
}

/// Time-domain library matrix and target on the band-limited reconstruction (ends trimmed by
/// [`td_trim`], every [`td_stride`]-th sample). Only the sampled rows are evaluated. The
/// reconstructions `p.smooth` hold every `q`-th sample (1: all); `q` must divide the trim and the
/// stride (see [`td_step`]).
pub(crate) fn time_domain(
    p: &Prepared<'_>,
    dofs: &[String],
    dof: usize,
    lib: &Library,
    q: usize,
) -> Result<(Mat<f64>, Vec<f64>)> {
    let n = p.rec.len();
    let (trim, stride) = (td_trim(n), td_stride(n));
    if n <= 2 * trim + lib.len() + 2 {
        return Err(CriteriaError::Invalid(format!(
            "record '{}' is too short ({n} samples) for a library of {} terms",
            p.rec.source(),
            lib.len()
        )));
    }
    debug_assert!(q >= 1 && trim % q == 0 && stride % q == 0);
    let rows = (n - 2 * trim).div_ceil(stride);
    // The rows of a record column, and of a reconstruction sampled every q-th sample.
    let sub =
        |v: &[f64]| -> Vec<f64> { v[trim..n - trim].iter().step_by(stride).copied().collect() };
    let sub_q = |v: &[f64]| -> Vec<f64> {
        v[trim / q..]
            .iter()
            .step_by(stride / q)
            .take(rows)
            .copied()
            .collect()
    };
    // The DOFs and their velocities from the reconstruction, the rest from the record, as
    // [`smoothed_columns`] has them; a missing column is left out so the evaluation names it.
    let column = |c: &str| -> Option<Vec<f64>> {
        for (name, s) in dofs.iter().zip(&p.smooth) {
            if c == name {
                return Some(sub_q(&s.x));
            }
            if c.strip_suffix('\'') == Some(name.as_str()) {
                return Some(sub_q(&s.v));
            }
        }
        p.rec.column(c).map(sub)
    };
    let cols = lib
        .required_columns()
        .into_iter()
        .filter_map(|c| column(&c).map(|v| (c, v)))
        .collect();
    let a = lib.evaluate(&OwnedColumns { rows, cols })?;
    let y = sub_q(&p.smooth[dof].a);
    Ok((a, y))
}

/// The sampling step a record of `len` samples can be reconstructed at for its time-domain
/// block ([`time_domain`]): the stride when it divides the trim (the block's rows are then
/// every stride-th sample from 0), else 1.
pub(crate) fn td_step(len: usize) -> usize {
    let (trim, stride) = (td_trim(len), td_stride(len));
    if trim % stride == 0 { stride } else { 1 }
}

/// Ends trimmed from a record's time-domain block (2 %, at least 4 samples: the reconstruction's
/// end effects).
pub(crate) fn td_trim(len: usize) -> usize {
    (len / 50).max(4)
}

/// Stride of a record's time-domain block: at most ~4000 rows per record (a subsample; κ and
/// residual statistics do not need every sample).
pub(crate) fn td_stride(len: usize) -> usize {
    (len / 4000).max(1)
}

/// The time-domain block `(Θ, x'')` of DOF `d` of every prepared record (see [`time_domain`]),
/// trimmed by [`td_trim`] and subsampled by [`td_stride`], the records in parallel.
pub(crate) fn time_domain_blocks(
    preps: &[Prepared<'_>],
    dofs: &[String],
    d: usize,
    lib: &Library,
) -> Result<Vec<(Mat<f64>, Vec<f64>)>> {
    preps
        .par_iter()
        .with_max_len(1)
        .map(|p| time_domain(p, dofs, d, lib, 1))
        .collect()
}

/// The columns `cols` of `a` (in that order), copied a whole column at a time.
pub(crate) fn columns_of(a: &Mat<f64>, cols: &[usize]) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(a.nrows(), cols.len());
    for (k, &j) in cols.iter().enumerate() {
        out.col_as_slice_mut(k).copy_from_slice(a.col_as_slice(j));
    }
    out
}

/// Criterion 3's bins of DOF `d` per record: the kept bins' frequencies (`freqs`, one slice per
/// record), the record's reconstruction band and decimation `qs`.
pub(crate) fn record_bins<'f>(
    blocks: &[Record],
    preps: &[Prepared<'_>],
    d: usize,
    qs: &[usize],
    freqs: impl Iterator<Item = &'f [f64]>,
) -> Vec<RecordBins> {
    freqs
        .zip(preps)
        .zip(blocks)
        .zip(qs)
        .map(|(((f, p), r), &q)| {
            let lo = f.iter().cloned().fold(f64::INFINITY, f64::min);
            let hi = f.iter().cloned().fold(0.0, f64::max);
            RecordBins {
                record: r.source().to_string(),
                cutoff_hz: p.smooth[d].band.cutoff_hz,
                mse_cutoff_hz: p.smooth[d].band.mse_cutoff_hz,
                in_band_noise_share: p.smooth[d].band.in_band_noise_share,
                kept_bins: f.len(),
                band_hz: [if lo.is_finite() { lo } else { 0.0 }, hi],
                decimation: q,
            }
        })
        .collect()
}
