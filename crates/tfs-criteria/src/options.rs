//! What to identify and how: the library per DOF, and the options of every stage of the T-F-S
//! pipeline (grouped by stage) and of the classical baseline, checked once ([`IdentifySpec::check`])
//! before any work starts.

use serde::{Deserialize, Serialize};
use tfs_library::Library;

use crate::criterion1::kappa::KappaVariant;
use crate::criterion3::TransformForm;
use crate::error::{Result, invalid};

/// How κ0 (the Criterion 1 threshold) is obtained.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Kappa0Choice {
    /// Add known white noise to the user's own data and take κ at the knee of κ(SNR).
    Calibrate,
    /// A fixed threshold.
    Fixed(f64),
}

/// Criterion 1: the noise level index κ and its threshold κ0.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
#[non_exhaustive]
pub struct Criterion1Options {
    /// κ variant used by criteria 1 and 2.
    pub kappa_variant: KappaVariant,
    /// κ0 source.
    pub kappa0: Kappa0Choice,
    /// Added-noise SNRs (dB, strictly decreasing) of the κ0 calibration.
    pub calibration_snrs_db: Vec<f64>,
}

impl Default for Criterion1Options {
    fn default() -> Self {
        Self {
            kappa_variant: KappaVariant::Standardised,
            kappa0: Kappa0Choice::Calibrate,
            calibration_snrs_db: vec![80.0, 70.0, 60.0, 50.0, 40.0, 30.0, 20.0, 10.0],
        }
    }
}

/// Criterion 2: library pruning by backward elimination on κ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
#[non_exhaustive]
pub struct Criterion2Options {
    /// Prune the library when Criterion 1 says the SNR is high (default off).
    pub prune: bool,
    /// Fixed κ1 (`None`: the value before the abrupt drop).
    pub kappa1: Option<f64>,
    /// Smallest κ decrease (decades) that counts as the abrupt drop.
    pub min_abrupt_drop: f64,
}

impl Default for Criterion2Options {
    fn default() -> Self {
        Self {
            prune: false,
            kappa1: None,
            min_abrupt_drop: 1.0,
        }
    }
}

/// Criterion 3: the band-limited reconstruction, the windowed transforms and their bins.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
#[non_exhaustive]
pub struct Criterion3Options {
    /// How the frequency-domain rows are formed.
    pub form: TransformForm,
    /// Candidate δ (bins kept where `|ẍ̂| ≥ δ·max`; chosen by held-out error), each in (0, 1].
    pub deltas: Vec<f64>,
    /// Candidate numbers of overlapping windows per record, each ≥ 1.
    pub window_counts: Vec<usize>,
    /// Fixed reconstruction cut-off (Hz); `None` chooses it per record and DOF from the spectrum.
    pub cutoff_hz: Option<f64>,
    /// Guard band above a data-chosen cut-off, in octaves (0–4, default 0.5: the cut-off that
    /// best reconstructs `x` times √2; see [`tfs_signal::band::reconstruct_guarded`]). Ignored
    /// when `cutoff_hz` is given and by the paper's plain Savitzky–Golay form.
    pub guard_octaves: f64,
    /// Savitzky–Golay (half window, order) for the `PlainSavitzkyGolay` form and Criterion 1.
    pub savitzky_golay: (usize, usize),
    /// Noise gate: a bin is used only if its |ẍ̂|² is at least this many times the variance the
    /// estimated displacement noise gives there (`None` = no gate; default 1).
    pub min_bin_snr: Option<f64>,
    /// Evaluate single powers `x^k` as noise-debiased Hermite polynomials of the reconstruction.
    pub debias: bool,
    /// Passes of feasible generalised least squares over the frequency-domain rows (each bin
    /// weighted by `1/√(local residual power)` of a full-library fit; 0 = equal weights).
    pub reweight: usize,
}

impl Default for Criterion3Options {
    fn default() -> Self {
        Self {
            form: TransformForm::Weak,
            deltas: vec![0.01, 0.03, 0.1, 0.3],
            window_counts: vec![1, 3, 7],
            cutoff_hz: None,
            guard_octaves: 0.5,
            savitzky_golay: (12, 3),
            min_bin_snr: Some(1.0),
            debias: true,
            reweight: 2,
        }
    }
}

/// The sparse selection (STLSQ on a λ path) and the fit of the selected structure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
#[non_exhaustive]
pub struct FitOptions {
    /// Fixed STLSQ threshold (scaled units, ≥ 0); `None` selects it on a λ path by held-out error.
    pub threshold: Option<f64>,
    /// Points of the λ path.
    pub n_thresholds: usize,
    /// After the terms are selected, choose δ and the window count again for their
    /// coefficients (the setting whose least squares on the selected terms has the lowest
    /// held-out residual).
    pub reselect_for_support: bool,
    /// Antithetic noise draws per record of the errors-in-variables correction of the final
    /// coefficients (0 = off).
    pub noise_correction_draws: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            threshold: None,
            n_thresholds: 40,
            reselect_for_support: true,
            noise_correction_draws: 2,
        }
    }
}

/// Criterion 4 with data assembly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
#[non_exhaustive]
pub struct Criterion4Options {
    /// Bound on |μ| (relative to the spread of x''); `None` = 0.05.
    pub mu0: Option<f64>,
    /// Bound on σ (relative to the spread of x''); `None` = σ converged.
    pub sigma0: Option<f64>,
    /// Once the criterion is met with the first `k` records, keep the structure and estimate
    /// its coefficients on every training record (the paper keeps the `k`-record fit).
    pub refit_all_records: bool,
}

impl Default for Criterion4Options {
    fn default() -> Self {
        Self {
            mu0: None,
            sigma0: None,
            refit_all_records: true,
        }
    }
}

/// The uncertainty of the kept coefficients and backward elimination by significance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
#[non_exhaustive]
pub struct UncertaintyOptions {
    /// Bootstrap draws over clusters of bins for the inclusion probability of every term; with
    /// ≥ 2 the kept coefficients also get 95 % intervals from a cluster jackknife (0 = neither).
    pub bagging: usize,
    /// Rounds of backward elimination: while some kept term fails the [`crate::TermTest`], the
    /// least significant one is removed from the library and the selection re-run (0 = off).
    pub elimination_rounds: usize,
}

impl Default for UncertaintyOptions {
    fn default() -> Self {
        Self {
            bagging: 100,
            elimination_rounds: 12,
        }
    }
}

/// Options of the T-F-S pipeline, one group per stage (defaults via [`TfsOptions::default`]).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
#[non_exhaustive]
pub struct TfsOptions {
    /// Criterion 1.
    pub criterion1: Criterion1Options,
    /// Criterion 2.
    pub criterion2: Criterion2Options,
    /// Criterion 3.
    pub criterion3: Criterion3Options,
    /// Selection and fit.
    pub fit: FitOptions,
    /// Criterion 4.
    pub criterion4: Criterion4Options,
    /// Intervals, inclusion and elimination.
    pub uncertainty: UncertaintyOptions,
}

impl TfsOptions {
    /// The guard band the reconstruction uses: [`Criterion3Options::guard_octaves`], except for
    /// the paper's plain Savitzky–Golay form, whose terms are evaluated on the raw data (the band
    /// only selects its bins), which is kept as the paper has it.
    pub(crate) fn reconstruction_guard(&self) -> f64 {
        match self.criterion3.form {
            TransformForm::PlainSavitzkyGolay => 0.0,
            _ => self.criterion3.guard_octaves,
        }
    }

    /// Checks every option; the error names the option and says what is allowed.
    pub fn validate(&self) -> Result<()> {
        let c3 = &self.criterion3;
        if c3.deltas.is_empty() || c3.deltas.iter().any(|d| !(*d > 0.0 && *d <= 1.0)) {
            return invalid(format!(
                "tfs.criterion3.deltas = {:?}: give at least one δ in (0, 1]",
                c3.deltas
            ));
        }
        if c3.window_counts.is_empty() || c3.window_counts.contains(&0) {
            return invalid(format!(
                "tfs.criterion3.window_counts = {:?}: give at least one count ≥ 1",
                c3.window_counts
            ));
        }
        if let Some(c) = c3.cutoff_hz
            && (c.is_nan() || c <= 0.0)
        {
            return invalid(format!("tfs.criterion3.cutoff_hz = {c}: must be positive"));
        }
        if !(c3.guard_octaves.is_finite() && (0.0..=4.0).contains(&c3.guard_octaves)) {
            return invalid(format!(
                "tfs.criterion3.guard_octaves = {}: give a guard band between 0 and 4 octaves (default 0.5)",
                c3.guard_octaves
            ));
        }
        if let Some(t) = self.fit.threshold
            && (t.is_nan() || t < 0.0)
        {
            return invalid(format!("tfs.fit.threshold = {t}: must be ≥ 0"));
        }
        let c1 = &self.criterion1;
        if let Kappa0Choice::Calibrate = c1.kappa0
            && c1.calibration_snrs_db.windows(2).any(|w| w[1] >= w[0])
        {
            return invalid("tfs.criterion1.calibration_snrs_db must be strictly decreasing");
        }
        Ok(())
    }
}

/// Options of the classical SINDy baseline.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
#[non_exhaustive]
pub struct SindyOptions {
    /// Savitzky–Golay (half window, polynomial order) for x' and x''; `None` (default) =
    /// second-order central differences, the classical baseline's estimator (as in PySINDy's
    /// default `FiniteDifference`).
    pub savitzky_golay: Option<(usize, usize)>,
    /// Fixed STLSQ threshold (scaled units); `None` selects it on a λ path with the last record held out.
    pub threshold: Option<f64>,
    /// Points of the λ path.
    pub n_thresholds: usize,
    /// With a selected threshold: pass over supports whose model (fitted without the held-out
    /// record) cannot simulate that record, taking the lowest held-out BIC among those that can.
    /// Off by default: it simulates the held-out record at least once, several times the cost
    /// of the fit itself (a classical fit stays as cheap as the regression it is).
    pub vet_by_simulation: bool,
}

impl Default for SindyOptions {
    fn default() -> Self {
        Self {
            savitzky_golay: None,
            threshold: None,
            n_thresholds: 40,
            vet_by_simulation: false,
        }
    }
}

/// What to identify and how.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct IdentifySpec {
    /// DOF names (displacement columns).
    pub dofs: Vec<String>,
    /// Library spec used for every DOF (tfs-library grammar).
    pub library: String,
    /// Per-DOF library specs (same order as `dofs`); empty = `library` for all.
    pub dof_libraries: Vec<String>,
    /// T-F-S options.
    pub tfs: TfsOptions,
    /// Classical SINDy options.
    pub sindy: SindyOptions,
}

impl IdentifySpec {
    /// A spec with default options.
    pub fn new(dofs: &[&str], library: &str) -> Self {
        Self {
            dofs: dofs.iter().map(|s| s.to_string()).collect(),
            library: library.to_string(),
            dof_libraries: Vec::new(),
            tfs: TfsOptions::default(),
            sindy: SindyOptions::default(),
        }
    }

    /// The library of every DOF, parsed.
    pub fn libraries(&self) -> Result<Vec<Library>> {
        if self.dofs.is_empty() {
            return invalid("spec.dofs is empty; name at least one displacement column");
        }
        if !self.dof_libraries.is_empty() && self.dof_libraries.len() != self.dofs.len() {
            return invalid(format!(
                "spec.dof_libraries has {} entries for {} DOFs; give one per DOF or none",
                self.dof_libraries.len(),
                self.dofs.len()
            ));
        }
        (0..self.dofs.len())
            .map(|i| {
                let s = self.dof_libraries.get(i).unwrap_or(&self.library);
                Ok(Library::parse(s, &self.dofs)?)
            })
            .collect()
    }

    /// The spec with its T-F-S options validated and its libraries parsed, once for a whole
    /// identification.
    pub(crate) fn check(&self) -> Result<Checked<'_>> {
        self.tfs.validate()?;
        Ok(Checked {
            spec: self,
            libraries: self.libraries()?,
        })
    }
}

/// An [`IdentifySpec`] whose options were validated and libraries parsed ([`IdentifySpec::check`]);
/// the stages take it (it reads as the spec it checked).
pub(crate) struct Checked<'a> {
    /// The spec.
    pub spec: &'a IdentifySpec,
    /// The library offered for every DOF.
    pub libraries: Vec<Library>,
}

impl std::ops::Deref for Checked<'_> {
    type Target = IdentifySpec;
    fn deref(&self) -> &IdentifySpec {
        self.spec
    }
}
