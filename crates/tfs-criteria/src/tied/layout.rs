//! The ties of a chain and the joint regression's layout: which library terms are an element's
//! force law shared by the two DOFs it connects, the unknowns of the joint regression, and how
//! each DOF's rows map onto them.

use faer::Mat;
use serde::{Deserialize, Serialize};
use tfs_library::{Coord, Library, Term, Var};
use tfs_regress::Compressed;

use crate::error::Result;
use crate::options::IdentifySpec;

/// One tied term: a function of `x_owner − x_partner` in both DOFs' libraries.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tie {
    /// The term's printed name (e.g. `(x2-x1)^3`).
    pub term: String,
    /// Index of the DOF whose relative coordinate it is (`x2` in `(x2-x1)`).
    pub owner: usize,
    /// Index of the other DOF (`x1` in `(x2-x1)`), whose equation gets `−m_owner/m_partner` times
    /// the owner's coefficient.
    pub partner: usize,
    /// Column of the term in the owner's library.
    pub owner_col: usize,
    /// Column of the term in the partner's library.
    pub partner_col: usize,
}

/// How the masses entering the tie factors `−m_owner/m_partner` are obtained.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum MassChoice {
    /// All masses equal (the tie factor is −1), as for identical cells.
    Equal,
    /// Masses per DOF (same order as the spec's DOFs; only ratios matter).
    Given(Vec<f64>),
    /// Estimate each DOF's mass relative to the first DOF's by a one-dimensional scan over these
    /// candidate ratios (DOF by DOF), scored by the leave-one-record-out error of the tied fit on
    /// the held-out record's frequency-domain rows.
    Estimate {
        /// Candidate ratios `m_d/m_0` (positive).
        candidates: Vec<f64>,
    },
}

/// Options of [`crate::identify_tfs_tied`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct TieOptions {
    /// Source of the masses in the tie factors.
    pub masses: MassChoice,
}

impl TieOptions {
    /// Options with the masses from `masses`.
    pub fn new(masses: MassChoice) -> Self {
        Self { masses }
    }
}

impl Default for TieOptions {
    fn default() -> Self {
        Self {
            masses: MassChoice::Equal,
        }
    }
}

/// The `(a, b)` DOF pair when every variable of `t` is the relative coordinate `(a-b)` (or its
/// velocity) between two DOFs.
fn relative_pair(t: &Term) -> Option<(String, String)> {
    let mut pair: Option<(String, String)> = None;
    for v in t.vars() {
        let p = match v {
            Var::RelDisp(a, Coord::Dof(b)) | Var::RelVel(a, Coord::Dof(b)) => {
                (a.clone(), b.clone())
            }
            _ => return None,
        };
        match &pair {
            Some(q) if *q != p => return None,
            _ => pair = Some(p),
        }
    }
    pair
}

pub(crate) fn ties_of(libs: &[Library], dofs: &[String]) -> Vec<Tie> {
    let mut out = Vec::new();
    for (i, lib) in libs.iter().enumerate() {
        for (col, t) in lib.terms().iter().enumerate() {
            let Some((a, b)) = relative_pair(t) else {
                continue;
            };
            if a != dofs[i] {
                continue;
            }
            let Some(j) = dofs.iter().position(|d| *d == b) else {
                continue;
            };
            if j == i {
                continue;
            }
            if let Some(pc) = libs[j].index_of(t) {
                out.push(Tie {
                    term: t.to_string(),
                    owner: i,
                    partner: j,
                    owner_col: col,
                    partner_col: pc,
                });
            }
        }
    }
    out
}

/// The ties among per-DOF libraries `libs` (DOF names `dofs`, in the same order), e.g. a fitted
/// model's equations: every term that is a function of a relative coordinate `(x_i-x_j)` between
/// two DOFs only and appears in both DOF `i`'s and DOF `j`'s library (see [`chain_ties`]).
pub fn library_ties(libs: &[Library], dofs: &[String]) -> Vec<Tie> {
    ties_of(libs, dofs)
}

/// The ties Newton's third law imposes on `spec`: every term that is a function of a relative
/// coordinate `(x_i-x_j)` between two DOFs only and appears in the libraries of both DOF `i` and
/// DOF `j`. Empty when the DOFs do not form such a chain.
pub fn chain_ties(spec: &IdentifySpec) -> Result<Vec<Tie>> {
    Ok(ties_of(&spec.libraries()?, &spec.dofs))
}

/// Unknowns of the joint regression and where each library column of each DOF takes its
/// coefficient from.
pub(crate) struct Layout {
    /// Per unknown: (DOF, column) of its owner.
    pub params: Vec<(usize, usize)>,
    /// Per DOF, per column: (unknown, tie index when this is the partner side).
    pub map: Vec<Vec<(usize, Option<usize>)>>,
}

impl Layout {
    pub fn new(libs: &[Library], ties: &[Tie]) -> Self {
        let mut params = Vec::new();
        let mut map: Vec<Vec<(usize, Option<usize>)>> = libs
            .iter()
            .map(|l| vec![(usize::MAX, None); l.len()])
            .collect();
        for (d, slots) in map.iter_mut().enumerate() {
            for (j, slot) in slots.iter_mut().enumerate() {
                if ties.iter().any(|t| t.partner == d && t.partner_col == j) {
                    continue;
                }
                *slot = (params.len(), None);
                params.push((d, j));
            }
        }
        for (k, t) in ties.iter().enumerate() {
            let p = map[t.owner][t.owner_col].0;
            map[t.partner][t.partner_col] = (p, Some(k));
        }
        Self { params, map }
    }

    /// Factor of unknown `map[d][j].0` in column `j` of DOF `d`.
    pub fn factor(&self, d: usize, j: usize, ratios: &[f64]) -> f64 {
        match self.map[d][j].1 {
            Some(k) => -ratios[k],
            None => 1.0,
        }
    }

    /// Joint rows of one block: each DOF's rows with its columns mapped onto the unknowns.
    pub fn joint(&self, per_dof: &[(Mat<f64>, Vec<f64>)], ratios: &[f64]) -> Result<Compressed> {
        let n = self.params.len();
        let rows: usize = per_dof.iter().map(|(a, _)| a.nrows()).sum();
        if rows == 0 {
            return Ok(Compressed::empty(n));
        }
        let mut a = Mat::<f64>::zeros(rows, n);
        let mut y = Vec::with_capacity(rows);
        let mut r0 = 0;
        for (d, (ad, yd)) in per_dof.iter().enumerate() {
            for j in 0..ad.ncols() {
                let (p, _) = self.map[d][j];
                let f = self.factor(d, j, ratios);
                for i in 0..ad.nrows() {
                    a[(r0 + i, p)] += f * ad[(i, j)];
                }
            }
            y.extend_from_slice(yd);
            r0 += ad.nrows();
        }
        Ok(Compressed::from_rows(a.as_ref(), &y)?)
    }

    /// Per-DOF coefficient vectors from the unknowns.
    pub fn expand(&self, theta: &[f64], ratios: &[f64]) -> Vec<Vec<f64>> {
        self.map
            .iter()
            .enumerate()
            .map(|(d, cols)| {
                cols.iter()
                    .enumerate()
                    .map(|(j, &(p, _))| self.factor(d, j, ratios) * theta[p])
                    .collect()
            })
            .collect()
    }
}

/// Frequency-domain rows of one DOF in one block: (A, y, kept frequencies).
pub(crate) type DofRows = (Mat<f64>, Vec<f64>, Vec<f64>);

pub(crate) fn stack(parts: Vec<(Mat<f64>, Vec<f64>, Vec<f64>)>, ncols: usize) -> DofRows {
    let rows: usize = parts.iter().map(|p| p.0.nrows()).sum();
    let mut a = Mat::<f64>::zeros(rows, ncols);
    let mut y = Vec::with_capacity(rows);
    let mut f = Vec::new();
    let mut r0 = 0;
    for (pa, py, pf) in parts {
        for i in 0..pa.nrows() {
            for j in 0..ncols {
                a[(r0 + i, j)] = pa[(i, j)];
            }
        }
        r0 += pa.nrows();
        y.extend(py);
        f.extend(pf);
    }
    (a, y, f)
}
