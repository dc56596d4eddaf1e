//! A chain model (DOFs `x1..xN`, cell 1 between the base and `x1`, cell `i` between `x(i-1)` and
//! `xi`) as a system with its wells, for basins and the minimum-energy deployment: each cell's
//! force law is read from its own DOF's equation, the chain's stable states are the products of
//! the cells' stable heights, its saddles every other product.
//!
//! Where the next cell rests its force is zero, so the terms of DOF `i`'s equation that name the
//! next cell's coordinate `(x(i+1)-xi)` push nothing there. A tied fit has that by construction
//! (those terms are the next cell's own law); an untied fit does not: the data pin down only
//! the sum of cell `i`'s polynomial and the coupling's, and a constant force can move between the
//! two (polynomials without a constant term still make one over the heights the records span).
//! Cell `i`'s law is therefore its own terms plus the coupling's force where the next cell rests
//! (the mean over the next cell's stable heights): zero for a tied fit, and the constant an
//! untied fit moved into the coupling otherwise.

use std::sync::Arc;

use tfs_basin::{ChainWells, WellInfo};
use tfs_library::{Coord, Factor, Model, Restoring, Var};
use tfs_origami::Chain;

use crate::error::{Context, Result};
use crate::invalid;

/// One cell's equilibria: stable and unstable heights.
#[derive(Debug, Clone, PartialEq)]
pub struct CellStates {
    /// Stable heights, ascending.
    pub stable: Vec<f64>,
    /// Unstable heights, ascending.
    pub unstable: Vec<f64>,
    /// The force per unit mass of the next cell's terms in this DOF's equation where the next
    /// cell rests (mean over its stable heights), moved into this cell's law (see the module
    /// docs): 0 for the last cell and for a tied fit.
    pub coupling_at_rest: f64,
    /// This cell's stable heights with the coupling taken at each stable height of the next
    /// cell in turn (`(next cell's height, this cell's stable heights)`); empty for the last
    /// cell. They differ when an untied fit's coupling is not the next cell's law.
    pub by_next: Vec<(f64, Vec<f64>)>,
    /// A stable state of the model at h = 0 that the data do not decide (see
    /// [`FoldedBalance`]): not among [`CellStates::stable`], though the model's dynamics (and
    /// its chain wells) have it.
    pub folded: Option<FoldedBalance>,
    /// Stable heights at which the cell presses into a stop of its own law (`below(h, c)` with
    /// h < c, `above(h, c)` with h > c): the cell resting on its contact. A law whose balance at
    /// the fold is unstable (a polynomial without a constant term) has one wherever its stop
    /// lies a little past the fold, however little. Not among [`CellStates::stable`], which
    /// are the balances of the cell's law off its contact, as the truth's are read.
    pub on_stop: Vec<f64>,
}

/// The model's cell balances at h = 0 (the cell folded flat) because no term of its law pushes
/// there — a polynomial without a constant term vanishes at 0 whatever the data — and is stable
/// there only by the sign of its linear term, the one term whose coefficient sets the stiffness
/// at h = 0, while that coefficient's interval holds both signs: the records do not decide
/// whether the folded cell is a stable state of the model. A real cell meets its folded stop
/// there, which no polynomial represents (`tfs refit --add stop@xI` fits it).
#[derive(Debug, Clone, PartialEq)]
pub struct FoldedBalance {
    /// The linear term of the cell's own coordinate (`x1`, `(x2-x1)`).
    pub term: String,
    /// Its coefficient in the cell's equation (the stiffness at h = 0 is minus it).
    pub coef: f64,
    /// The coefficient's interval as the model file gives it.
    pub interval: [f64; 2],
}

/// One cell's force law along its height: its own terms' restoring force plus a constant.
#[derive(Debug, Clone)]
struct CellLaw {
    own: Restoring,
    shift: f64,
}

impl CellLaw {
    fn force(&self, h: f64) -> f64 {
        self.own.force(h) + self.shift
    }

    fn potential(&self, h: f64) -> f64 {
        self.own.potential(h) + self.shift * h
    }

    /// The equilibria on `search`.
    fn wells(&self, search: (f64, f64)) -> tfs_basin::Result<WellInfo> {
        let (f, p) = (self.clone(), self.clone());
        WellInfo::from_force(move |h| f.force(h), move |h| p.potential(h), search, 1.0)
    }
}

/// A chain model's cells, masses and wells.
pub struct ChainModel {
    /// Each cell's equilibria (base cell first).
    pub cells: Vec<CellStates>,
    /// The masses the potential weighs the cells' per-unit-mass laws with (the tied fit's, else 1).
    pub masses: Vec<f64>,
    /// The chain's stable states (displacements), saddles' lowest energy and potential.
    pub wells: ChainWells,
    /// Whether the model was fitted with ties (see [`is_tied`]).
    pub tied: bool,
}

/// Whether `model` was fitted with its chain elements' laws tied between the equations they
/// enter: its trace lists the ties (`"ties"`, beside the fit's `"masses"`).
pub fn is_tied(model: &Model) -> bool {
    model.is_tied()
}

/// The model with DOF `i`'s equation reduced to the terms of cell `i` (those not naming the next
/// cell's coordinate `(x(i+1)-xi)`): its restoring force along `xi` is then the cell's own law.
fn cell_model(model: &Model, i: usize) -> Model {
    split(model, i, false)
}

/// The model with DOF `i + 1`'s equation replaced by the terms of DOF `i`'s equation that name
/// the next cell's coordinate `(x(i+1)-xi)`: its restoring force along `x(i+1)` is minus the
/// coupling's force per unit mass in `xi''` as a function of the next cell's height.
fn coupling_model(model: &Model, i: usize) -> Model {
    let mut m = split(model, i, true);
    let terms = m
        .equations
        .iter()
        .find(|e| e.dof == model.dofs[i])
        .map(|e| e.terms.clone())
        .unwrap_or_default();
    let next = &model.dofs[i + 1];
    if let Some(eq) = m.equations.iter_mut().find(|e| &e.dof == next) {
        eq.terms = terms;
    }
    m
}

/// The model with DOF `i`'s equation reduced to the terms naming the next cell's coordinate
/// (`coupling`) or to the others.
fn split(model: &Model, i: usize, coupling: bool) -> Model {
    let dof = &model.dofs[i];
    let mut m = model.clone();
    if let Some(eq) = m.equations.iter_mut().find(|e| &e.dof == dof) {
        eq.terms.retain(|t| {
            let names_next = t.term.vars().iter().any(|v| match v {
                Var::RelDisp(_, Coord::Dof(b)) | Var::RelVel(_, Coord::Dof(b)) => b == dof,
                _ => false,
            });
            names_next == coupling
        });
    }
    m
}

/// Each cell's law and equilibria on `search`, from the last cell to the first (a cell's law
/// takes the coupling where the next cell rests, see the module docs).
fn cell_laws(label: &str, model: &Model, search: (f64, f64)) -> Result<Vec<(CellLaw, CellStates)>> {
    let n = model.dofs.len();
    let mut out: Vec<(CellLaw, CellStates)> = Vec::with_capacity(n);
    for i in (0..n).rev() {
        let dof = &model.dofs[i];
        let own = cell_model(model, i)
            .restoring(dof)
            .with_context(|| format!("{label}: restoring force of cell {} ('{dof}')", i + 1))?;
        let context = || {
            format!(
                "{label}: equilibria of cell {} on heights {search:?} (choose the range with --search)",
                i + 1
            )
        };
        let (mut shift, mut by_next) = (0.0, Vec::new());
        if let Some((_, next)) = out.last() {
            let g = coupling_model(model, i)
                .restoring(&model.dofs[i + 1])
                .with_context(|| {
                    format!("{label}: the next cell's terms in the equation of '{dof}'")
                })?;
            let at: Vec<f64> = next.stable.iter().map(|z| -g.force(*z)).collect();
            if !at.is_empty() {
                shift = -at.iter().sum::<f64>() / at.len() as f64;
            }
            for (z, a) in next.stable.iter().zip(&at) {
                let law = CellLaw {
                    own: own.clone(),
                    shift: -a,
                };
                let w = law.wells(search).with_context(context)?;
                by_next.push((*z, w.stable().to_vec()));
            }
        }
        let law = CellLaw { own, shift };
        let w = law.wells(search).with_context(context)?;
        let cell = cell_model(model, i);
        let folded = folded_balance(&cell, dof, &law, w.stable());
        let (on_stop, stable): (Vec<f64>, Vec<f64>) = w
            .stable()
            .iter()
            .copied()
            .filter(|h| folded.is_none() || h.abs() > AT_ZERO)
            .partition(|h| presses_stop(&cell, dof, *h));
        let states = CellStates {
            stable,
            unstable: w.unstable().to_vec(),
            coupling_at_rest: 0.0 - shift,
            by_next,
            folded,
            on_stop,
        };
        out.push((law, states));
    }
    out.reverse();
    Ok(out)
}

/// How close to 0 a stable height must lie to be the folded balance of [`FoldedBalance`] (the
/// root finder's tolerance; the balance is exactly at 0).
const AT_ZERO: f64 = 1e-6;

/// The cell's [`FoldedBalance`], if `stable` (the law's stable heights) holds h = 0 and only the
/// linear term of `dof` in `cell` (the cell's own terms) sets the stiffness there, with an
/// interval that holds both signs.
fn folded_balance(cell: &Model, dof: &str, law: &CellLaw, stable: &[f64]) -> Option<FoldedBalance> {
    if !stable.iter().any(|h| h.abs() <= AT_ZERO) {
        return None;
    }
    let eq = cell.equation(dof).ok()?;
    let linear = eq.terms.iter().find(|t| match t.term.factors() {
        [Factor::Pow(Var::Disp(n), 1)] | [Factor::Pow(Var::RelDisp(n, _), 1)] => n == dof,
        _ => false,
    })?;
    let [lo, hi] = linear.interval?;
    let alone = (law.own.stiffness(0.0) + linear.coef).abs() <= 1e-9 * linear.coef.abs().max(1.0);
    (alone && lo <= 0.0 && hi >= 0.0).then(|| FoldedBalance {
        term: linear.term.to_string(),
        coef: linear.coef,
        interval: [lo, hi],
    })
}

/// Whether height `h` presses cell `dof` into a stop of its own terms (`cell`'s equation of
/// `dof`): `below(q, c)` with h < c or `above(q, c)` with h > c, `q` the cell's coordinate.
fn presses_stop(cell: &Model, dof: &str, h: f64) -> bool {
    let Ok(eq) = cell.equation(dof) else {
        return false;
    };
    let own = |v: &Var| matches!(v, Var::Disp(n) | Var::RelDisp(n, _) if n == dof);
    eq.terms.iter().any(|t| match t.term.factors() {
        [Factor::Below(v, c)] => own(v) && h < *c,
        [Factor::Above(v, c)] => own(v) && h > *c,
        _ => false,
    })
}

/// Each cell's equilibria on `search` (`label` names the model in messages), the base cell
/// first; see the module docs for how each cell's law is read from the equations.
pub fn cell_states(label: &str, model: &Model, search: (f64, f64)) -> Result<Vec<CellStates>> {
    chain_dofs(label, model)?;
    Ok(cell_laws(label, model, search)?
        .into_iter()
        .map(|(_, s)| s)
        .collect())
}

/// Refuses a model of one DOF.
fn chain_dofs(label: &str, model: &Model) -> Result<()> {
    if model.dofs.len() < 2 {
        invalid!(
            "{label}: the model has one DOF ({}); a chain has two or more",
            model.dofs.join(", ")
        );
    }
    Ok(())
}

/// The masses a tied fit used (its trace's `"masses"`, one positive number per DOF), 1 each
/// for a model without them.
pub fn fit_masses(model: &Model) -> Vec<f64> {
    let n = model.dofs.len();
    model.trace["masses"]
        .as_array()
        .map(|a| a.iter().filter_map(|m| m.as_f64()).collect::<Vec<f64>>())
        .filter(|m| m.len() == n && m.iter().all(|v| v.is_finite() && *v > 0.0))
        .unwrap_or_else(|| vec![1.0; n])
}

/// Reads a chain model's cells and wells (`label` names it in messages): each cell's stable and
/// unstable heights on `search`, the masses from the tied fit's trace (1 each otherwise), and the
/// chain's stable states ordered by the last DOF's displacement.
pub fn model_chain(label: &str, model: &Model, search: (f64, f64)) -> Result<ChainModel> {
    chain_dofs(label, model)?;
    let masses = fit_masses(model);
    let (laws, cells): (Vec<CellLaw>, Vec<CellStates>) =
        cell_laws(label, model, search)?.into_iter().unzip();
    let weights = masses.clone();
    let potentials: Vec<CellPotential> = laws
        .into_iter()
        .zip(weights)
        .map(|(law, m)| Arc::new(move |h: f64| m * law.potential(h)) as CellPotential)
        .collect();
    let wells = chain_wells(label, &cells, masses.clone(), potentials, search)?;
    Ok(ChainModel {
        cells,
        masses,
        wells,
        tied: is_tied(model),
    })
}

/// One cell's share of the chain's potential energy as a function of its height.
type CellPotential = Arc<dyn Fn(f64) -> f64 + Send + Sync>;

/// The chain's wells from its cells' equilibria, the masses and each cell's potential energy:
/// the stable states are the products of stable heights, the barrier the lowest saddle.
fn chain_wells(
    label: &str,
    cells: &[CellStates],
    masses: Vec<f64>,
    potentials: Vec<CellPotential>,
    search: (f64, f64),
) -> Result<ChainWells> {
    let (stable, saddles) = products(cells);
    if stable.is_empty() {
        invalid!(
            "{label}: no stable state of the chain on cell heights {search:?} (a cell without a stable height there: {}); choose the range with --search",
            cells
                .iter()
                .enumerate()
                .filter(|(_, c)| c.stable.is_empty())
                .map(|(i, _)| format!("cell {}", i + 1))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let potential = Arc::new(move |x: &[f64]| {
        (0..x.len())
            .map(|i| {
                let h = if i == 0 { x[0] } else { x[i] - x[i - 1] };
                potentials[i](h)
            })
            .sum::<f64>()
    });
    let barrier = if saddles.is_empty() {
        None
    } else {
        let p = potential.clone();
        Some(ChainWells::barrier_from_saddles(|x| p(x), &saddles)?)
    };
    Ok(ChainWells::new(
        stable,
        masses,
        move |x| potential(x),
        barrier,
    )?)
}

/// A simulated chain's own cells and wells (the truth a chain model is judged against): each
/// cell's equilibria from its force law on `search`, the stable states and barrier as for a
/// model ([`model_chain`]), the cells' masses.
pub fn truth_chain(chain: &Chain, search: (f64, f64)) -> Result<ChainModel> {
    let mut cells = Vec::new();
    let mut potentials: Vec<CellPotential> = Vec::new();
    for (i, c) in chain.cells().iter().enumerate() {
        let (f, p, v) = (
            c.force_law().clone(),
            c.force_law().clone(),
            c.force_law().clone(),
        );
        let w = WellInfo::from_force(
            move |h| f.force(h),
            move |h| p.potential(h),
            search,
            c.mass(),
        )
        .with_context(|| format!("the truth's cell {} on heights {search:?}", i + 1))?;
        cells.push(CellStates {
            stable: w.stable().to_vec(),
            unstable: w.unstable().to_vec(),
            coupling_at_rest: 0.0,
            by_next: Vec::new(),
            folded: None,
            on_stop: Vec::new(),
        });
        potentials.push(Arc::new(move |h| v.potential(h)));
    }
    let masses: Vec<f64> = chain.cells().iter().map(|c| c.mass()).collect();
    let wells = chain_wells("the truth", &cells, masses.clone(), potentials, search)?;
    Ok(ChainModel {
        cells,
        masses,
        wells,
        tied: false,
    })
}

/// Every combination of the cells' equilibria as displacements (cumulative heights): the ones of
/// stable heights only (ordered by the last displacement), and the others (saddles). A folded
/// balance the data do not decide is a stable height of the model's dynamics, and counts here.
fn products(cells: &[CellStates]) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let mut combos: Vec<(Vec<f64>, bool)> = vec![(Vec::new(), true)];
    for c in cells {
        let mut heights = c.stable.clone();
        if c.folded.is_some() {
            heights.insert(0, 0.0);
        }
        let all: Vec<(f64, bool)> = heights
            .iter()
            .map(|h| (*h, true))
            .chain(c.unstable.iter().map(|h| (*h, false)))
            .collect();
        combos = combos
            .iter()
            .flat_map(|(x, s)| {
                all.iter().map(move |(h, sh)| {
                    let mut y = x.clone();
                    y.push(x.last().copied().unwrap_or(0.0) + h);
                    (y, *s && *sh)
                })
            })
            .collect();
    }
    let (mut stable, mut saddles) = (Vec::new(), Vec::new());
    for (x, s) in combos {
        if s {
            stable.push(x);
        } else {
            saddles.push(x);
        }
    }
    stable.sort_by(|a, b| a[a.len() - 1].total_cmp(&b[b.len() - 1]));
    (stable, saddles)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two cells with known laws, the coupling in both equations as a tied fit writes it: cell 1
    /// F1(h) = h − h² (stable at 1), cell 2 F2(h) = −h(h − 0.5)(h − 1)(h − 1.5) (stable at 0.5
    /// and 1.5, a saddle at 1); `extra` is added to the coefficient of `(x2-x1)` in x1'' only
    /// (as an untied fit may leave it), `tied` records ties in the trace.
    fn two_cells(extra: f64, tied: bool) -> Model {
        let f2 = [0.0, 0.75, -2.75, 3.0, -1.0];
        let mut terms1 = vec![("x1".to_string(), 1.0), ("x1^2".to_string(), -1.0)];
        let mut terms2 = Vec::new();
        for (k, c) in f2.iter().enumerate().skip(1) {
            let name = if k == 1 {
                "(x2-x1)".to_string()
            } else {
                format!("(x2-x1)^{k}")
            };
            terms1.push((name.clone(), if k == 1 { extra - c } else { -c }));
            terms2.push((name, *c));
        }
        let eq = |dof: &str, t: &[(String, f64)]| serde_json::json!({"dof": dof, "terms": t.iter().map(|(n, c)| serde_json::json!({"term": n, "coef": c})).collect::<Vec<_>>()});
        let trace = if tied {
            serde_json::json!({"masses": [1.0, 0.5], "ties": [{"term": "(x2-x1)", "owner": "x2", "partner": "x1", "factor_in_partner": -1.0}]})
        } else {
            serde_json::json!({})
        };
        let json = serde_json::json!({"format": "tfs-model/1", "dofs": ["x1", "x2"], "inputs": [],
            "equations": [eq("x1", &terms1), eq("x2", &terms2)], "method": "test", "trace": trace});
        Model::from_json_str(&json.to_string()).unwrap()
    }

    fn close(a: &[f64], b: &[f64]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6)
    }

    /// An untied fit's coupling that does not vanish where cell 2 rests: x1'' = h − h² + 0.1·z
    /// there (z = 0.5 or 1.5), so cell 1 rests where h² − h = 0.1·z, and its law takes the mean
    /// coupling 0.1.
    #[test]
    fn an_untied_coupling_is_taken_where_the_next_cell_rests() {
        let model = two_cells(0.1, false);
        let c = model_chain("test", &model, (0.1, 2.0)).unwrap();
        assert!(!c.tied);
        let root = |cz: f64| (1.0 + (1.0 + 4.0 * cz).sqrt()) / 2.0;
        assert!(close(&c.cells[0].stable, &[root(0.1)]), "{:?}", c.cells);
        assert!(
            (c.cells[0].coupling_at_rest - 0.1).abs() < 1e-9,
            "{:?}",
            c.cells
        );
        let by: Vec<f64> = c.cells[0].by_next.iter().map(|(z, _)| *z).collect();
        assert!(close(&by, &[0.5, 1.5]), "{:?}", c.cells);
        assert!(
            close(&c.cells[0].by_next[0].1, &[root(0.05)]),
            "{:?}",
            c.cells
        );
        assert!(
            close(&c.cells[0].by_next[1].1, &[root(0.15)]),
            "{:?}",
            c.cells
        );
        assert!(close(&c.cells[1].stable, &[0.5, 1.5]), "{:?}", c.cells);
        assert_eq!(c.cells[1].coupling_at_rest, 0.0);
        assert_eq!(cell_states("test", &model, (0.1, 2.0)).unwrap(), c.cells);
    }

    /// A tied two-cell model whose cell 2, x2'' = −a·h + 1.5·h² − h³ (h = x2 − x1), balances at
    /// h = 0 by its form and is stable there when a > 0; `interval` is the interval of a's
    /// term `(x2-x1)`. Cell 1: x1'' = x1 − x1², stable at 1.
    fn folded_cell(a: f64, interval: [f64; 2]) -> Model {
        let t = |n: &str, c: f64| serde_json::json!({"term": n, "coef": c});
        let mut lin = t("(x2-x1)", -a);
        lin["interval"] = serde_json::json!(interval);
        let x2 = vec![lin, t("(x2-x1)^2", 1.5), t("(x2-x1)^3", -1.0)];
        let x1 = vec![
            t("x1", 1.0),
            t("x1^2", -1.0),
            t("(x2-x1)", a),
            t("(x2-x1)^2", -1.5),
            t("(x2-x1)^3", 1.0),
        ];
        let json = serde_json::json!({"format": "tfs-model/1", "dofs": ["x1", "x2"], "inputs": [],
            "equations": [{"dof": "x1", "terms": x1}, {"dof": "x2", "terms": x2}], "method": "test",
            "trace": {"ties": [{"term": "(x2-x1)", "owner": "x2", "partner": "x1", "factor_in_partner": -1.0}]}});
        Model::from_json_str(&json.to_string()).unwrap()
    }

    /// The folded balance is a stable state of the cell only where the data decide the sign of
    /// the linear term; the chain's wells keep it either way (the model's dynamics have it).
    #[test]
    fn a_folded_balance_the_data_do_not_decide_is_not_a_stable_state() {
        let search = (-0.05, 2.0);
        let undecided = model_chain("test", &folded_cell(0.5, [-0.2, 1.2]), search).unwrap();
        let c2 = &undecided.cells[1];
        assert!(close(&c2.stable, &[1.0]), "{c2:?}");
        let f = c2.folded.as_ref().expect("the folded balance is reported");
        assert_eq!(f.term, "(x2-x1)");
        assert_eq!((f.coef, f.interval), (-0.5, [-0.2, 1.2]));
        assert_eq!(undecided.wells.stable().len(), 2);
        // The same law with an interval of one sign: stable at 0 and at 1.
        let decided = model_chain("test", &folded_cell(0.5, [0.3, 0.7]), search).unwrap();
        let c2 = &decided.cells[1];
        assert!(c2.folded.is_none() && c2.stable.len() == 2, "{c2:?}");
        assert!(c2.stable[0].abs() < 1e-6 && (c2.stable[1] - 1.0).abs() < 1e-6);
        assert_eq!(decided.wells.stable().len(), 2);
        // Unstable at 0 (a < 0): nothing to report.
        let open = model_chain("test", &folded_cell(-0.5, [-0.9, 0.1]), search).unwrap();
        assert!(open.cells[1].folded.is_none(), "{:?}", open.cells[1]);
    }

    #[test]
    fn cells_are_read_from_their_own_equations() {
        let model = two_cells(0.0, true);
        let c = model_chain("test", &model, (0.1, 2.0)).unwrap();
        assert!(c.tied);
        assert_eq!(c.masses, vec![1.0, 0.5]);
        assert!(close(&c.cells[0].stable, &[1.0]), "{:?}", c.cells);
        assert!(close(&c.cells[1].stable, &[0.5, 1.5]), "{:?}", c.cells);
        assert!(close(&c.cells[1].unstable, &[1.0]), "{:?}", c.cells);
        let s = c.wells.stable();
        assert_eq!(s.len(), 2);
        assert!(
            close(&s[0], &[1.0, 1.5]) && close(&s[1], &[1.0, 2.5]),
            "{s:?}"
        );
        assert!(c.wells.barrier().is_some());
    }
}
