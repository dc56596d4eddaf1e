//! Backward elimination by significance: while some kept term fails the term test, the least
//! significant one is removed from the library (a term mask over the library the user offered)
//! and the whole selection re-run on what remains; the re-runs reuse the first pass's
//! time-domain blocks and transforms.

use faer::Mat;
use rayon::prelude::*;
use tfs_library::{Library, Term};

use crate::criterion1::kappa::Criterion1;
use crate::criterion3::rows::WindowTransform;
use crate::eiv::NoiseDraws;
use crate::error::Result;
use crate::trace::{Identified, Problem, Support};

/// What the first pass of [`crate::identify_tfs`] computed for one DOF that a re-run on a subset
/// of its terms can reuse. Each library column enters these one by one (its own time-domain
/// column, its own windowed transform, with bins and the left-hand side shared by all), so the
/// re-run's are column subsets of the first pass's — as long as the decimation, which depends on
/// the highest degree offered, is unchanged. The bin weights are not kept: they come from a fit
/// over the columns, and are recomputed for the re-run's.
pub(crate) struct FirstPass {
    /// The first pass's terms, in the column order of the products below.
    pub terms: Vec<Term>,
    /// Time-domain blocks of every record.
    pub td: Vec<(Mat<f64>, Vec<f64>)>,
    /// Decimation per record.
    pub qs: Vec<usize>,
    /// Windowed transforms per window count and record (with the first pass's bin weights,
    /// which [`FirstPass::unweighted`] resets).
    pub transforms: Vec<Vec<Vec<WindowTransform>>>,
}

impl FirstPass {
    /// Where each term of `lib` sits among the first pass's columns (`None` if one is new).
    pub fn columns(&self, lib: &Library) -> Option<Vec<usize>> {
        lib.terms()
            .iter()
            .map(|t| self.terms.iter().position(|u| u == t))
            .collect()
    }

    /// The transforms restricted to the columns `cols`, every bin weighted 1 (reweighting
    /// changes nothing else).
    pub fn unweighted(&self, cols: &[usize]) -> Vec<Vec<Vec<WindowTransform>>> {
        self.transforms
            .par_iter()
            .map(|by_rec| {
                by_rec
                    .par_iter()
                    .map(|wins| {
                        wins.iter()
                            .map(|w| WindowTransform {
                                freq: w.freq.clone(),
                                rel_amp: w.rel_amp.clone(),
                                lhs: w.lhs.clone(),
                                cols: cols.iter().map(|&j| w.cols[j].clone()).collect(),
                                weight: vec![1.0; w.weight.len()],
                            })
                            .collect()
                    })
                    .collect()
            })
            .collect()
    }
}

/// What the passes of one [`crate::identify_tfs`] call share.
pub(crate) struct Shared<'a> {
    /// The errors-in-variables noise draws.
    pub noise: &'a NoiseDraws,
    /// The first pass's products per DOF (the re-runs of the elimination), if kept.
    pub first: Option<&'a [FirstPass]>,
    /// Keep this pass's products for later passes.
    pub keep_products: bool,
    /// Candidate terms per DOF of the library the user offered (the term test's `m`).
    pub candidates: &'a [usize],
}

/// The terms of the model's equation of `dof`, printed.
fn support(id: &Identified, dof: &str) -> Result<Vec<String>> {
    Ok(id
        .model
        .equation(dof)?
        .terms
        .iter()
        .map(|t| t.term.to_string())
        .collect())
}

/// The least significant kept term of DOF `i` of `id` that fails its term test, as a position in
/// the pass's library `lib` (one per round: powers of x are nearly collinear, and removing every
/// failing term at once can drop a group — x^5, x^6, x^7 at 10 dB — that is significant as a
/// whole though no member is alone).
fn weakest(id: &Identified, i: usize, dof: &str, lib: &Library) -> Result<Option<usize>> {
    let eq = id.model.equation(dof)?;
    let test = id.trace.dofs.get(i).and_then(|t| t.term_test.as_ref());
    Ok(eq
        .terms
        .iter()
        .filter_map(|t| {
            let (iv, test) = (t.interval?, test?);
            let name = t.term.to_string();
            (!test.passes(&name, t.coef, iv)).then(|| (test.margin(&name, t.coef, iv), t))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .and_then(|(_, t)| lib.index_of(&t.term)))
}

/// One pass of the pipeline on the libraries given (the first pass's Criterion 1 per DOF to keep,
/// whether it is the final pass), as [`run`] calls it.
pub(crate) type Pass<'p> =
    dyn Fn(&[Library], Option<&[Criterion1]>, bool) -> Result<Identified> + 'p;

/// Backward elimination after the first pass `id` (on the libraries `offered`): up to `rounds`
/// rounds, each removing the least significant failing term of every DOF where one is left, and
/// re-running `pass` on the reduced libraries. Afterwards, the verdict of a DOF whose structure
/// the elimination changed says whether the result can be trusted, and the trace's `why` lines
/// list the rounds.
pub(crate) fn run(
    mut id: Identified,
    offered: &[Library],
    dofs: &[String],
    rounds: usize,
    prune: bool,
    pass: &Pass<'_>,
) -> Result<Identified> {
    let first: Vec<Vec<String>> = dofs
        .iter()
        .map(|d| support(&id, d))
        .collect::<Result<_>>()?;
    // Why the first pass was not supported, with the SNR it stated, per DOF.
    let first_problem: Vec<Option<(Option<crate::trace::SnrEstimate>, Problem)>> = id
        .trace
        .dofs
        .iter()
        .map(|d| match d.criterion1.as_ref().map(|c| &c.support) {
            Some(Support::NotSupported {
                snr_db, problem, ..
            }) => Some((*snr_db, problem.clone())),
            _ => None,
        })
        .collect();
    let first_c1: Option<Vec<Criterion1>> =
        id.trace.dofs.iter().map(|d| d.criterion1.clone()).collect();
    // The term mask of each DOF over the library offered.
    let mut masks: Vec<Vec<bool>> = offered.iter().map(|l| vec![true; l.len()]).collect();
    let mut current: Vec<Library> = offered.to_vec();
    let mut notes: Vec<Vec<String>> = vec![Vec::new(); dofs.len()];
    for round in 1..=rounds {
        let mut changed = false;
        for (i, dof) in dofs.iter().enumerate() {
            let Some(w) = weakest(&id, i, dof, &current[i])? else {
                continue;
            };
            if current[i].len() < 2 {
                continue;
            }
            changed = true;
            let name = current[i].terms()[w].to_string();
            notes[i].push(format!(
                "round {round} of backward elimination by significance: removed {name}, the least significant term failing the term test, from the library and re-ran the selection"
            ));
            let at = (0..masks[i].len())
                .filter(|&j| masks[i][j])
                .nth(w)
                .expect("the pass's library is the masked one");
            masks[i][at] = false;
        }
        if !changed {
            break;
        }
        current = offered
            .iter()
            .zip(&masks)
            .map(|(lib, mask)| {
                let terms = lib
                    .terms()
                    .iter()
                    .zip(mask)
                    .filter(|(_, m)| **m)
                    .map(|(t, _)| t.clone())
                    .collect();
                Library::new(lib.dofs(), terms)
            })
            .collect::<std::result::Result<_, _>>()?;
        // Criterion 1 describes the library the user offered: the re-runs keep the first pass's
        // κ and κ0 (and skip the calibration) unless pruning needs the reduced library's factor.
        let keep_c1 = if prune { None } else { first_c1.as_deref() };
        id = pass(&current, keep_c1, round == rounds)?;
    }
    let finals: Vec<Vec<String>> = dofs
        .iter()
        .map(|d| support(&id, d))
        .collect::<Result<_>>()?;
    for (((d, n), first), fin) in id.trace.dofs.iter_mut().zip(notes).zip(&first).zip(finals) {
        // Removing insignificant terms may only shrink the structure. Terms the first pass did
        // not select appearing afterwards mean the data do not pin the structure down: the
        // first pass's "too noisy" verdict stands.
        let new_terms: Vec<String> = fin.into_iter().filter(|t| !first.contains(t)).collect();
        let why_not = if !new_terms.is_empty() {
            Some(Problem::StructureChanged { new_terms })
        } else {
            first_problem[i_of(dofs, &d.dof)]
                .clone()
                .map(|(snr_db, first)| Problem::Reduced {
                    snr_db,
                    first: Box::new(first),
                })
        };
        if !n.is_empty()
            && let Some(problem) = why_not
            && let Some(c1) = d.criterion1.as_mut()
        {
            c1.support = Support::NotSupported {
                snr_db: None,
                problem,
                cause: crate::verdict::noise_cause(c1),
            };
            d.assembly_verdict.qualify(c1.support.clone());
        }
        let given = &offered[i_of(dofs, &d.dof)];
        if given.len() != d.library.len() {
            d.offered_library = Some(given.names());
        }
        let mut n = n;
        n.append(&mut d.settings.why);
        d.settings.why = n;
    }
    Ok(id)
}

/// Index of `dof` in `dofs` (0 if absent).
fn i_of(dofs: &[String], dof: &str) -> usize {
    dofs.iter().position(|d| d == dof).unwrap_or(0)
}
