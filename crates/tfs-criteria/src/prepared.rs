//! Records prepared once for several T-F-S identifications that differ only in their libraries.
//!
//! Cutting the records to blocks, reconstructing every DOF in its data-chosen band and drawing
//! the errors-in-variables noise spectra depend on the records and a few options, never on the
//! library offered. A caller that fits the same records with many libraries (a stop's position
//! scanned, `tfs::contact`) prepares them once ([`RecordBlocks::prepare`]) and identifies with
//! each library from that preparation ([`PreparedRecords::identify_tfs`]); each fit is
//! [`crate::identify_tfs`]'s, to the bit.

use std::time::Instant;

use tfs_data::Record;

use crate::blocks::{Prepared, blocks_of, prepare_all};
use crate::criterion3::TransformForm;
use crate::eiv::NoiseDraws;
use crate::error::{Result, invalid};
use crate::options::{Checked, IdentifySpec};
use crate::pipeline::{identify_prepared, ms};
use crate::trace::Identified;

/// What one identification reads of its records besides the library: the blocks, each one's
/// reconstructed DOFs (made in `recon_ms`) and the noise draws (made on first use, kept).
pub(crate) struct Preparation<'a> {
    pub blocks: &'a [Record],
    pub preps: Vec<Prepared<'a>>,
    pub recon_ms: f64,
    pub noise: NoiseDraws,
}

impl<'a> Preparation<'a> {
    /// Prepares `blocks` for `spec`; `keep_spectra` keeps the band searches' spectra for the
    /// first Criterion 1 cause that asks (one identification; a shared preparation does not keep
    /// them, and every cause then transforms again, to the same bits).
    pub(crate) fn new(
        blocks: &'a [Record],
        spec: &Checked<'_>,
        keep_spectra: bool,
    ) -> Result<Self> {
        let t0 = Instant::now();
        let preps = prepare_all(blocks, spec, keep_spectra)?;
        let recon_ms = ms(t0);
        let noise = NoiseDraws::new(
            preps.len(),
            spec.dofs.len(),
            spec.tfs.fit.noise_correction_draws,
            spec.tfs.criterion3.form,
        );
        Ok(Self {
            blocks,
            preps,
            recon_ms,
            noise,
        })
    }
}

/// Records cut to the blocks a T-F-S identification fits on (fast transform lengths; a single
/// record split in two halves), ready to be prepared once for several identifications
/// ([`RecordBlocks::prepare`]).
pub struct RecordBlocks {
    blocks: Vec<Record>,
}

impl RecordBlocks {
    /// Cuts `records` to blocks. Errors: no records.
    pub fn new(records: &[Record]) -> Result<Self> {
        Ok(Self {
            blocks: blocks_of(records)?,
        })
    }

    /// Checks every block and reconstructs its DOFs as `spec` asks (its DOFs, Criterion 3's
    /// cut-off and guard band, the transform form and the number of noise draws); the
    /// preparation then serves any spec that agrees with `spec` on those and differs in its
    /// libraries or other options. Errors: `spec`'s own, or a block that fails the checks.
    pub fn prepare(&self, spec: &IdentifySpec) -> Result<PreparedRecords<'_>> {
        let checked = spec.check()?;
        Ok(PreparedRecords {
            prep: Preparation::new(&self.blocks, &checked, false)?,
            made_with: MadeWith::of(&checked),
        })
    }
}

/// Records prepared for T-F-S identifications ([`RecordBlocks::prepare`]); shared by fits made
/// side by side (it is `Sync`).
pub struct PreparedRecords<'a> {
    prep: Preparation<'a>,
    made_with: MadeWith,
}

impl PreparedRecords<'_> {
    /// T-F-S identification ([`crate::identify_tfs`]) with `spec` on these records, without
    /// preparing them again: the same model and trace as [`crate::identify_tfs`] gives (the
    /// trace's timing aside). Errors: `spec`'s own, one whose options the preparation depends
    /// on differ from those it was made with (named), and the identification's.
    pub fn identify_tfs(&self, spec: &IdentifySpec) -> Result<Identified> {
        let checked = spec.check()?;
        self.made_with.check(&checked)?;
        identify_prepared(&checked, &self.prep)
    }
}

/// The options a preparation depends on.
#[derive(Debug, Clone, PartialEq)]
struct MadeWith {
    dofs: Vec<String>,
    cutoff_hz: Option<f64>,
    guard_octaves: f64,
    form: TransformForm,
    draws: usize,
}

impl MadeWith {
    fn of(spec: &Checked<'_>) -> Self {
        Self {
            dofs: spec.dofs.clone(),
            cutoff_hz: spec.tfs.criterion3.cutoff_hz,
            guard_octaves: spec.tfs.reconstruction_guard(),
            form: spec.tfs.criterion3.form,
            draws: spec.tfs.fit.noise_correction_draws,
        }
    }

    /// An error naming the first option where `spec` differs from the preparation's.
    fn check(&self, spec: &Checked<'_>) -> Result<()> {
        let now = Self::of(spec);
        let differs = if now.dofs != self.dofs {
            Some((
                "dofs",
                format!("{:?}", self.dofs),
                format!("{:?}", now.dofs),
            ))
        } else if now.cutoff_hz != self.cutoff_hz {
            Some((
                "tfs.criterion3.cutoff_hz",
                format!("{:?}", self.cutoff_hz),
                format!("{:?}", now.cutoff_hz),
            ))
        } else if now.guard_octaves != self.guard_octaves {
            Some((
                "tfs.criterion3.guard_octaves",
                self.guard_octaves.to_string(),
                now.guard_octaves.to_string(),
            ))
        } else if now.form != self.form {
            Some((
                "tfs.criterion3.form",
                format!("{:?}", self.form),
                format!("{:?}", now.form),
            ))
        } else if now.draws != self.draws {
            Some((
                "tfs.fit.noise_correction_draws",
                self.draws.to_string(),
                now.draws.to_string(),
            ))
        } else {
            None
        };
        match differs {
            None => Ok(()),
            Some((name, was, is)) => invalid(format!(
                "the records were prepared with {name} = {was} and this identification asks for {is}; prepare them again with this spec (RecordBlocks::prepare)"
            )),
        }
    }
}
