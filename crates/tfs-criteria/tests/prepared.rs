//! Records prepared once for several T-F-S identifications (`RecordBlocks::prepare`, used by
//! the stop's position scan) give each library exactly the fit `identify_tfs` gives from the
//! raw records, whatever was fitted from the same preparation before; a spec whose options the
//! preparation depends on is refused with the option named.

mod common;

use tfs_criteria::{Identified, IdentifySpec, RecordBlocks, identify_tfs};
use tfs_signal::NoiseKind;

/// The trace as JSON without its timings (wall-clock times differ from run to run).
fn trace_without_timing(id: &Identified) -> serde_json::Value {
    let mut v = serde_json::to_value(&id.trace).unwrap();
    v.as_object_mut().unwrap().remove("timing_ms");
    v
}

#[test]
fn a_shared_preparation_fits_every_library_as_a_fresh_one_does() {
    // At 40 dB terms are kept and their noise corrected; at 10 dB κ falls below κ0 and
    // Criterion 1's cause runs, which reads the band searches' spectra a single identification
    // keeps. Three shortened sweeps keep the test quick.
    for snr_db in [40.0, 10.0] {
        let records = common::train(Some((snr_db, NoiseKind::White)), 0.3, 3);
        let libraries = ["x^1..7, x', xb_acc", "x, x^3, x^5, x', xb_acc"];
        let blocks = RecordBlocks::new(&records).unwrap();
        let prepared = blocks
            .prepare(&IdentifySpec::new(&["x"], libraries[0]))
            .unwrap();
        // Each library twice, interleaved: a fit must not change what the next one reads.
        for lib in [libraries[0], libraries[1], libraries[0], libraries[1]] {
            let spec = IdentifySpec::new(&["x"], lib);
            let fresh = identify_tfs(&records, &spec).unwrap();
            let shared = prepared.identify_tfs(&spec).unwrap();
            assert_eq!(fresh.model, shared.model, "{snr_db} dB, library {lib}");
            assert_eq!(
                trace_without_timing(&fresh),
                trace_without_timing(&shared),
                "{snr_db} dB, library {lib}"
            );
        }
    }
}

#[test]
fn a_spec_the_preparation_does_not_fit_is_refused_by_name() {
    let records = common::train(Some((40.0, NoiseKind::White)), 0.2, 2);
    let blocks = RecordBlocks::new(&records).unwrap();
    let prepared = blocks
        .prepare(&IdentifySpec::new(&["x"], "x^1..3, x', xb_acc"))
        .unwrap();
    let mut spec = IdentifySpec::new(&["x"], "x^1..3, x', xb_acc");
    spec.tfs.criterion3.cutoff_hz = Some(3.0);
    let e = prepared.identify_tfs(&spec).unwrap_err().to_string();
    assert!(e.contains("tfs.criterion3.cutoff_hz"), "{e}");
    let mut spec = IdentifySpec::new(&["x"], "x^1..3, x', xb_acc");
    spec.tfs.fit.noise_correction_draws += 1;
    let e = prepared.identify_tfs(&spec).unwrap_err().to_string();
    assert!(e.contains("noise_correction_draws"), "{e}");
}
