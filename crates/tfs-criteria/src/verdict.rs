//! Does the data support the library? The verdict each DOF's trace carries (and the CLI prints
//! first): the identified model must keep some term, a restoring-force term where the library
//! offers one, a significant term in the DOF's own motion, and every kept term must pass the term
//! test; an input term must survive where the records are driven.

use tfs_library::{Coord, Library, Term, Var};

use crate::criterion1::cause::SnrVerdict;
use crate::criterion1::kappa::Criterion1;
use crate::trace::{DofTrace, NoiseCause, Problem, Support};
use crate::uncertainty::TermTest;

/// Does term `t` move with DOF `dof` itself (its displacement or velocity, own or relative)?
fn own_motion(t: &Term, dof: &str) -> bool {
    t.vars().iter().any(|v| match v {
        Var::Disp(n) | Var::Vel(n) | Var::RelDisp(n, _) | Var::RelVel(n, _) => n == dof,
        Var::Input(_) => false,
    })
}

/// Is term `t` a displacement term of DOF `dof` on either side of an element: its own
/// displacement, or a relative coordinate it takes part in (the tied fit's reading, where an
/// element's law is shared by the two DOFs it connects).
pub(crate) fn element_displacement(t: &Term, dof: &str) -> bool {
    t.vars().iter().any(|v| match v {
        Var::Disp(n) => n == dof,
        Var::RelDisp(a, b) => a == dof || matches!(b, Coord::Dof(m) if m == dof),
        _ => false,
    })
}

/// What the support verdict of one DOF of the single-DOF fit reads: the library columns `keep`
/// with coefficients `coef`, their intervals and the term test.
pub(crate) struct SupportInput<'a> {
    /// The DOF.
    pub dof: &'a str,
    /// The pass's library.
    pub lib: &'a Library,
    /// The library columns of the regression.
    pub keep: &'a [usize],
    /// Coefficients per regression column.
    pub coef: &'a [f64],
    /// Interval per regression column.
    pub intervals: &'a [Option<[f64; 2]>],
    /// The term test, if intervals were computed.
    pub term_test: Option<&'a TermTest>,
}

/// Writes the support verdict into `c1` (see [`SupportInput`]).
pub(crate) fn support_verdict(v: &SupportInput<'_>, c1: &mut Criterion1) {
    let (lib, keep, coef, dof) = (v.lib, v.keep, v.coef, v.dof);
    let names = lib.names();
    let support: Vec<bool> = coef.iter().map(|c| *c != 0.0).collect();
    let significant = |j: usize| {
        v.intervals[j].is_none_or(|iv| {
            v.term_test
                .is_none_or(|t| t.passes(&names[keep[j]], coef[j], iv))
        })
    };
    let weak_terms: Vec<String> = (0..keep.len())
        .filter(|&j| support[j] && !significant(j))
        .map(|j| names[keep[j]].clone())
        .collect();
    let term = |col: usize| &lib.terms()[col];
    let own_supported =
        (0..keep.len()).any(|j| support[j] && own_motion(term(keep[j]), dof) && significant(j));
    let offers_disp = keep.iter().any(|&c| term(c).involves_displacement_of(dof));
    let keeps_disp =
        (0..keep.len()).any(|j| support[j] && term(keep[j]).involves_displacement_of(dof));
    let problem = if !support.iter().any(|&s| s) {
        Some(Problem::NoTermSurvives)
    } else if offers_disp && !keeps_disp {
        Some(Problem::NoRestoringTerm {
            dof: dof.to_string(),
        })
    } else if !own_supported {
        Some(Problem::NoOwnTerm {
            dof: dof.to_string(),
        })
    } else if let (false, Some(t)) = (weak_terms.is_empty(), v.term_test) {
        Some(Problem::FailsTermTest {
            terms: weak_terms,
            t_critical: t.t_critical,
            candidates: t.candidates,
        })
    } else {
        None
    };
    let snr_db = c1.estimated_snr_db;
    c1.support = match problem {
        Some(problem) => Support::NotSupported {
            snr_db,
            problem,
            cause: noise_cause(c1),
        },
        None => Support::Supported { snr_db },
    };
}

/// What Criterion 1's comparison of the library's residual with the records' own noise
/// estimate says about a verdict that the data do not support the library: noise only when
/// that estimate says the residual is the size of the noise; records whose spectra show no
/// noise floor while κ reaches κ0 get a sentence that does not ask for cleaner data.
pub(crate) fn noise_cause(c1: &Criterion1) -> NoiseCause {
    match c1.snr {
        SnrVerdict::LowSnr { .. } => NoiseCause::Noise,
        SnrVerdict::ModelError { .. } | SnrVerdict::Derivatives { .. } => NoiseCause::NotNoise,
        SnrVerdict::High if c1.estimated_snr_db.is_some_and(|s| s.lower_bound) => {
            NoiseCause::NoNoiseFloor
        }
        SnrVerdict::High | SnrVerdict::Undetermined { .. } => NoiseCause::Unknown,
    }
}

/// Whether the library offers an input term among `keep`, and whether the model keeps one.
pub(crate) fn inputs_offered_kept(lib: &Library, keep: &[usize], coef: &[f64]) -> (bool, bool) {
    let input = |col: usize| lib.terms()[col].uses_input();
    (
        keep.iter().any(|&c| input(c)),
        (0..keep.len()).any(|j| coef[j] != 0.0 && input(keep[j])),
    )
}

/// Records of a driven structure, and a model that no input drives: every DOF's verdict says so
/// (STLSQ can choose a threshold that drops the excitation with the damping, seen at 10 dB).
pub(crate) fn no_input_term(traces: &mut [DofTrace]) {
    for t in traces {
        if let Some(c1) = t.criterion1.as_mut() {
            let note = Support::NotSupported {
                snr_db: None,
                problem: Problem::NoInputTerm,
                cause: noise_cause(c1),
            };
            if c1.support.is_supported() {
                t.assembly_verdict.qualify(note.clone());
                c1.support = note;
            }
        }
    }
}

/// The support verdict of one DOF of the tied fit, written into `c1`. The tied fit has no term
/// test (nor the elimination that goes with it), so the verdict rests on the structure: something
/// must survive, and a library that offers a displacement term of this DOF (or of its elements)
/// must keep one.
pub(crate) fn tied_support_verdict(dof: &str, lib: &Library, coef: &[f64], c1: &mut Criterion1) {
    let kept: Vec<&Term> = lib
        .terms()
        .iter()
        .zip(coef)
        .filter(|(_, c)| **c != 0.0)
        .map(|(t, _)| t)
        .collect();
    let disp = |t: &Term| element_displacement(t, dof);
    let cause = noise_cause(c1);
    c1.support = if kept.is_empty() {
        Support::NotSupported {
            snr_db: None,
            problem: Problem::NoTermSurvives,
            cause,
        }
    } else if lib.terms().iter().any(disp) && !kept.iter().any(|t| disp(t)) {
        Support::NotSupported {
            snr_db: None,
            problem: Problem::NoRestoringTerm {
                dof: dof.to_string(),
            },
            cause,
        }
    } else {
        Support::SupportedTied
    };
}
