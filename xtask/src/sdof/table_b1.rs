//! Study 4: Appendix B, T-F-S against classical SINDy on the same 30 dB data (Table B1).

use std::time::Instant;

use anyhow::{Context, Result};
use serde_json::json;
use tfs::criteria::{IdentifySpec, identify_sindy, identify_tfs};
use tfs::origami::NoiseKind;
use tfs::plot::{LineChart, Series};

use crate::common::{Opts, f4, num, progress, sim_rmse};
use crate::report::{Study, Table};

use super::{SINDY_LIBRARY, TFS_LIBRARY, records, truth};

/// Study 4: Appendix B, Table B1 — classical SINDy vs T-F-S on the same 30 dB data.
pub fn study_table_b1(st: &mut Study, o: &Opts) -> Result<()> {
    let pb = progress(4, "App. B");
    let scale = o.pick(0.5, 1.0);
    let t = truth()?;
    pb.set_message("data");
    let (train, test) = records(&t, NoiseKind::White, 30.0, scale, 200)?;
    pb.inc(1);
    let samples: usize = train.iter().map(|r| r.len()).sum();
    st.text(format!(
        "Same 30 dB white-noise training data for both methods ({} records, {samples} samples; the paper had 200,020). T-F-S library `{TFS_LIBRARY}` (pipeline defaults); classical SINDy library `{SINDY_LIBRARY}` (36 columns as in the paper) on Savitzky–Golay derivatives, STLSQ with the threshold chosen on the last record held out. Time = wall time of the whole identification call on this machine (2 cores), median of three calls. R-MSE = Eq. B.2 on the test sweep, against the measured (noisy) displacement.",
        train.len()
    ));
    pb.set_message("T-F-S");
    // Each method is timed as the median of three calls on the same data, so neither pays a
    // one-off cost (FFT planning, thread-pool start) that the other does not.
    fn timed<T>(mut f: impl FnMut() -> Result<T>) -> Result<(T, f64)> {
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..3 {
            let t0 = Instant::now();
            last = Some(f()?);
            times.push(t0.elapsed().as_secs_f64());
        }
        times.sort_by(f64::total_cmp);
        Ok((last.expect("three runs"), times[1]))
    }
    let spec = IdentifySpec::new(&["x"], TFS_LIBRARY);
    let (a, t_tfs) = timed(|| identify_tfs(&train, &spec).context("T-F-S identification"))?;
    pb.inc(1);
    pb.set_message("classical SINDy");
    let spec_s = IdentifySpec::new(&["x"], SINDY_LIBRARY);
    let (b, t_sindy) =
        timed(|| identify_sindy(&train, &spec_s).context("classical SINDy identification"))?;
    pb.inc(1);
    let da = &a.trace.dofs[0];
    let tfs_rows = da.assembly.last().map_or(0, |s| s.rows);
    let tfs_cols = da.regression_library.len();
    // Classical SINDy regresses on every sample except the Savitzky–Golay trims at both ends.
    let trim = spec_s.sindy.savitzky_golay.map_or(1, |s| s.0);
    let sindy_rows: usize = train.iter().map(|r| r.len() - 2 * trim).sum();
    let sindy_cols = b.trace.dofs[0].library.len();
    let ra = sim_rmse(&a.model, &test, "x");
    let rb = sim_rmse(&b.model, &test, "x");
    let mut tab = Table::new(
        "table_b1",
        "Table B1: cost and accuracy of T-F-S vs classical SINDy on the same 30 dB data",
        &[
            "method",
            "library matrix (ours)",
            "time (ours)",
            "test R-MSE (ours)",
            "library matrix (paper)",
            "time (paper)",
            "R-MSE (paper)",
        ],
    );
    let show = |r: &std::result::Result<(f64, Vec<f64>), String>| {
        r.as_ref()
            .map(|r| f4(r.0))
            .unwrap_or_else(|e| format!("simulation failed: {e}"))
    };
    tab.row(vec![
        "T-F-S SINDy".into(),
        format!("{tfs_rows}×{tfs_cols}"),
        format!("{t_tfs:.3} s"),
        show(&ra),
        "2143×28".into(),
        "4.4 s".into(),
        "0.0045".into(),
    ]);
    tab.row(vec![
        "classical SINDy".into(),
        format!("{sindy_rows}×{sindy_cols}"),
        format!("{t_sindy:.3} s"),
        show(&rb),
        "200,020×36".into(),
        "120.72 s".into(),
        "0.0332".into(),
    ]);
    st.table(tab)?;
    st.text(format!(
        "T-F-S model: `{}`\n\nClassical SINDy model: `{}`\n\nT-F-S rows are the frequency-domain rows (real and imaginary parts of the kept bins) of the records used by the final fit; its columns are the library after Criterion 2 ({} of {}).\n\nThe paper's cost argument is that T-F-S regresses on a much smaller matrix, which its sparsification solves again for every threshold; that is the check above. The times are shown, not judged: both methods take well under a second here, and our classical SINDy folds its rows into a small triangular factor in one pass before it sparsifies, so its regression no longer grows with the 200,020 rows that cost the paper's implementation two minutes. Most of T-F-S's time goes to its criteria (the noise curve of Criterion 1 and the transforms of Criterion 3), not to regression.",
        a.model.equation_string(),
        b.model.equation_string(),
        tfs_cols,
        da.library.len()
    ));
    let (ea, eb) = (ra.as_ref().map(|r| r.0).ok(), rb.as_ref().map(|r| r.0).ok());
    let better = match (ea, eb) {
        (Some(x), Some(y)) => x < y,
        (Some(_), None) => true,
        _ => false,
    };
    st.compare(
        "Table B1: test R-MSE, T-F-S vs classical",
        "0 (the measured test sweep)",
        &format!(
            "{} vs {}",
            ea.map_or("—".into(), f4),
            eb.map_or("blew up".into(), f4)
        ),
        "0.0045 vs 0.0332",
        Some(better),
        "T-F-S lower than classical SINDy",
    );
    // The paper's cost claim is its mechanism: the criteria shrink the regression problem that
    // the sparsification solves again and again. That is what is checked. The wall times are
    // shown beside the paper's but judge nothing: a timing on a shared machine is not a pass or
    // fail (the report's exit code must not depend on the load), and our classical SINDy folds
    // its rows into a small triangle in one pass before sparsifying, so it no longer pays for
    // its row count the way the paper's did.
    st.compare(
        "Table B1: regression matrix, T-F-S vs classical",
        "—",
        &format!("{tfs_rows}×{tfs_cols} vs {sindy_rows}×{sindy_cols}"),
        "2143×28 vs 200,020×36",
        Some(tfs_rows * tfs_cols < sindy_rows * sindy_cols),
        "T-F-S regresses on a smaller matrix than classical SINDy",
    );
    st.compare(
        "Table B1: fit time, T-F-S vs classical",
        "—",
        &format!("{t_tfs:.3} s vs {t_sindy:.3} s"),
        "4.4 s vs 120.72 s",
        None,
        "informational: wall time on this machine, not a check",
    );
    st.set("tfs", json!({"rows": tfs_rows, "cols": tfs_cols, "seconds": t_tfs, "test_r_mse": ea.map(num), "r_mse_error": ra.as_ref().err(), "equation": a.model.equation_string()}));
    st.set("sindy", json!({"rows": sindy_rows, "cols": sindy_cols, "seconds": t_sindy, "test_r_mse": eb.map(num), "blew_up": eb.is_none(), "r_mse_error": rb.as_ref().err(), "equation": b.model.equation_string()}));
    st.set("paper", json!({"tfs": {"rows": 2143, "cols": 28, "seconds": 4.4, "r_mse": 0.0045}, "sindy": {"rows": 200020, "cols": 36, "seconds": 120.72, "r_mse": 0.0332}}));
    // Figure: test responses.
    let tt = test.t();
    let meas = test.column("x").unwrap_or_default();
    let step = (tt.len() / 3000).max(1);
    let sub = |y: &[f64]| -> Vec<(f64, f64)> {
        tt.iter()
            .zip(y)
            .step_by(step)
            .map(|(a, b)| (*a, *b))
            .collect()
    };
    let mut ch = LineChart::new(
        "Appendix B: test sweep, measured vs simulated models",
        "t (s)",
        "x (length unit c0)",
    )
    .with_series(Series::line("measured (30 dB)", sub(meas)).color(0));
    if let Ok((_, p)) = &ra {
        ch = ch.with_series(Series::dashed("T-F-S model", sub(p)).color(1));
    }
    // A classical fit that kept no term (`x'' = 0`) simulates as uniform motion from its fitted
    // start: a straight line, which the legend and the text say instead of leaving unexplained.
    let empty = b.model.equations.iter().all(|e| e.terms.is_empty());
    if let Ok((_, p)) = &rb {
        let name = if empty {
            "classical SINDy model (x'' = 0: a straight line from its start)"
        } else {
            "classical SINDy model"
        };
        ch = ch.with_series(Series::dashed(name, sub(p)).color(3));
    }
    if empty {
        st.text("The classical SINDy fit kept no term at this noise level (`x'' = 0`): on Savitzky–Golay derivatives of 30 dB data, the threshold chosen on the held-out record removes every column, so its simulation keeps the starting state fitted to the record's first periods, moving at that constant velocity — the straight (or, with zero starting velocity, flat) line in the figure below, and its large test R-MSE.");
    }
    st.figure(
        "figB1_test_response",
        "Appendix B: the test sweep simulated by both models beside the measured response",
        ch,
    )?;
    pb.inc(1);
    pb.finish_and_clear();
    Ok(())
}
