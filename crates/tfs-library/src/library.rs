//! Libraries of candidate terms and their evaluation on data into one faer matrix.

use std::borrow::Cow;

use faer::{Mat, MatMut};
use tfs_data::Columns;

use crate::term::{Factor, Term, Var};
use crate::{LibraryError, Result};

/// An ordered set of distinct candidate terms over named DOFs.
///
/// Built from a spec with [`Library::parse`]. Duplicate terms (after range expansion and
/// canonicalisation, so `x*x` equals `x^2`) are removed silently, keeping the first occurrence:
/// `poly(x, x'; 0..3), x'` is the same library as `poly(x, x'; 0..3)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Library {
    dofs: Vec<String>,
    terms: Vec<Term>,
}

impl Library {
    /// Parses a comma-separated spec; identifiers listed in `dofs` are DOFs, all others inputs.
    ///
    /// ```
    /// use tfs_library::Library;
    /// let lib = Library::parse("x^1..3, x', xb_acc", &["x"]).unwrap();
    /// assert_eq!(lib.names(), ["x", "x^2", "x^3", "x'", "xb_acc"]);
    /// assert_eq!(Library::parse("poly(x, x'; 0..7)", &["x"]).unwrap().len(), 36);
    /// ```
    pub fn parse<S: AsRef<str>>(spec: &str, dofs: &[S]) -> Result<Self> {
        let dof_refs: Vec<&str> = dofs.iter().map(|s| s.as_ref()).collect();
        check_dofs(&dof_refs)?;
        let terms = crate::parse::parse_spec(spec, &dof_refs)?;
        Self::new(dofs, terms)
    }

    /// Builds a library from terms, removing duplicates (first occurrence kept).
    /// Every DOF a term mentions must be in `dofs`.
    pub fn new<S: AsRef<str>>(dofs: &[S], terms: Vec<Term>) -> Result<Self> {
        let dofs: Vec<String> = dofs.iter().map(|s| s.as_ref().to_string()).collect();
        let refs: Vec<&str> = dofs.iter().map(String::as_str).collect();
        check_dofs(&refs)?;
        let mut out: Vec<Term> = Vec::with_capacity(terms.len());
        for t in terms {
            for d in t.dofs() {
                if !dofs.contains(&d) {
                    return Err(LibraryError::Invalid {
                        field: "terms".into(),
                        message: format!(
                            "term '{t}' uses DOF '{d}', which is not among the DOFs {dofs:?}; declare it as a DOF"
                        ),
                    });
                }
            }
            if !out.contains(&t) {
                out.push(t);
            }
        }
        Ok(Self { dofs, terms: out })
    }

    /// The DOF names.
    pub fn dofs(&self) -> &[String] {
        &self.dofs
    }

    /// The terms, in spec order.
    pub fn terms(&self) -> &[Term] {
        &self.terms
    }

    /// Number of terms (matrix columns).
    pub fn len(&self) -> usize {
        self.terms.len()
    }

    /// True if the library has no terms.
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// Canonical term names, one per column.
    pub fn names(&self) -> Vec<String> {
        self.terms.iter().map(Term::to_string).collect()
    }

    /// The canonical spec: names joined by `", "` (parses back to the same library).
    pub fn spec(&self) -> String {
        self.names().join(", ")
    }

    /// Columns that must be supplied to [`Library::evaluate`] (`x`, `x'`, `xb`, `xb_vel`, …), in
    /// first-use order.
    pub fn required_columns(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for t in &self.terms {
            for c in t.required_columns() {
                if !out.contains(&c) {
                    out.push(c);
                }
            }
        }
        out
    }

    /// Input names (non-DOF columns) the library needs, in first-use order.
    pub fn inputs(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for t in &self.terms {
            for c in t.required_inputs() {
                if !out.contains(&c) {
                    out.push(c);
                }
            }
        }
        out
    }

    /// Position of a term (by value) in the library.
    pub fn index_of(&self, term: &Term) -> Option<usize> {
        self.terms.iter().position(|t| t == term)
    }

    /// Returns a library with `term` appended (unchanged if already present).
    pub fn with_term(&self, term: Term) -> Result<Self> {
        let mut terms = self.terms.clone();
        terms.push(term);
        Self::new(&self.dofs, terms)
    }

    /// Evaluates every term on every row: an `rows × len` matrix, column `j` = term `j`.
    /// Velocity columns are looked up as `"x'"`, input velocities as `"xb_vel"`.
    /// Missing or short columns and non-finite results are errors naming the column and term.
    pub fn evaluate(&self, cols: &dyn Columns) -> Result<Mat<f64>> {
        let mut powers = PowerCache::new();
        let mut m = Mat::<f64>::zeros(cols.rows(), self.terms.len());
        for (j, t) in self.terms.iter().enumerate() {
            evaluate_term_into(t, cols, &mut powers, m.col_as_slice_mut(j))?;
        }
        Ok(m)
    }

    /// Whether every term's value on a row depends on that row alone: true unless a term has
    /// an internal state (whose value integrates its drive over the record's history). A
    /// row-local library can be evaluated a block of rows at a time ([`Library::evaluate_rows`]).
    pub fn is_row_local(&self) -> bool {
        self.terms
            .iter()
            .all(|t| t.factors().iter().all(|f| f.state_law().is_none()))
    }

    /// Evaluates every term on the rows `rows` of `cols` into `out` (`rows.len() × len`, row `i`
    /// of `out` = row `rows.start + i`): the same values, to the bit, as those rows of
    /// [`Library::evaluate`], without the matrix of every row (so a tall library can be built
    /// and compressed a cache-sized block at a time). Errors as [`Library::evaluate`] (the row
    /// of a non-finite value is counted in `cols`), and for a library that is not
    /// [row-local](Library::is_row_local) or rows beyond `cols`.
    pub fn evaluate_rows(
        &self,
        cols: &dyn Columns,
        rows: std::ops::Range<usize>,
        mut out: MatMut<'_, f64>,
    ) -> Result<()> {
        let invalid = |message: String| LibraryError::Invalid {
            field: "rows".into(),
            message,
        };
        if !self.is_row_local() {
            return Err(invalid(
                "a term with an internal state depends on the whole record; evaluate the library on every row".into(),
            ));
        }
        if rows.start > rows.end
            || rows.end > cols.rows()
            || out.shape() != (rows.len(), self.len())
        {
            return Err(invalid(format!(
                "rows {}..{} into a {}×{} block: the record has {} rows and the library {} terms",
                rows.start,
                rows.end,
                out.nrows(),
                out.ncols(),
                cols.rows(),
                self.len()
            )));
        }
        // Every column a term reads is checked on the whole record first, so that a missing or
        // short column is reported as `evaluate` reports it.
        for t in &self.terms {
            for c in t.required_columns() {
                fetch(cols, &c, t)?;
            }
        }
        let window = RowWindow {
            base: cols,
            rows: rows.clone(),
        };
        let mut powers = PowerCache::new();
        let mut scratch = Vec::new();
        for (j, t) in self.terms.iter().enumerate() {
            let res = match out.as_mut().col_mut(j).try_as_col_major_mut() {
                Some(col) => evaluate_term_into(t, &window, &mut powers, col.as_slice_mut()),
                None => {
                    scratch.resize(rows.len(), 0.0);
                    let r = evaluate_term_into(t, &window, &mut powers, &mut scratch);
                    for (i, v) in scratch.iter().enumerate() {
                        out[(i, j)] = *v;
                    }
                    r
                }
            };
            if let Err(LibraryError::NonFinite { term, row }) = res {
                return Err(LibraryError::NonFinite {
                    term,
                    row: rows.start + row,
                });
            }
            res?;
        }
        Ok(())
    }

    /// The first term, in library order, that is not finite on some row of `cols`, and its first
    /// such row (`(term index, row)`), as [`Library::evaluate`] would report it; `None` when every
    /// term is finite everywhere. Terms that cannot be evaluated (a missing column) are skipped:
    /// evaluation reports those.
    ///
    /// Far cheaper than evaluating the library: a term that is a product of powers, `abs`,
    /// `sign`, `tanh` and contact factors is bounded by the same product of its variables'
    /// largest magnitudes (one pass over each variable, shared by every term), and a term whose
    /// bound is far below overflow (≤ 1e300, so the few roundings of the evaluation cannot
    /// reach it) is finite on every row. Only a term with a larger bound, or an internal state,
    /// is evaluated to find the row.
    pub fn first_non_finite(&self, cols: &dyn Columns) -> Option<(usize, usize)> {
        let mut largest: Vec<(Var, Option<f64>)> = Vec::new();
        let mut powers = PowerCache::new();
        for (j, t) in self.terms.iter().enumerate() {
            if term_bound(t, cols, &mut largest).is_some_and(|b| b <= FINITE_BOUND) {
                continue;
            }
            if let Err(LibraryError::NonFinite { row, .. }) =
                evaluate_term_cached(t, cols, &mut powers)
            {
                return Some((j, row));
            }
        }
        None
    }
}

/// A bound of a term's magnitude at or below which its evaluation is finite (see
/// [`Library::first_non_finite`]).
const FINITE_BOUND: f64 = 1e300;

/// An upper bound of `|term|` over every row of `cols` from its variables' largest magnitudes
/// (cached in `largest`; `None` for a variable that cannot be read); `None` when the term has an
/// internal state, a variable cannot be read or is not finite somewhere.
fn term_bound(
    term: &Term,
    cols: &dyn Columns,
    largest: &mut Vec<(Var, Option<f64>)>,
) -> Option<f64> {
    let mut bound = 1.0f64;
    for f in term.factors() {
        if matches!(f, Factor::State(..)) {
            return None;
        }
        let v = f.var();
        let m = match largest.iter().find(|(w, _)| w == v) {
            Some((_, m)) => *m,
            None => {
                let m = var_values(v, cols, term).ok().and_then(|vals| {
                    let (mut m, mut finite) = (0.0f64, true);
                    for x in vals.iter() {
                        finite &= x.is_finite();
                        m = m.max(x.abs());
                    }
                    finite.then_some(m)
                });
                largest.push((v.clone(), m));
                m
            }
        }?;
        bound *= match f {
            Factor::Pow(_, k) => m.powi(*k as i32),
            Factor::Abs(_) => m,
            Factor::Sign(_) | Factor::Tanh(..) => 1.0,
            Factor::Below(_, c) | Factor::Above(_, c) => c.abs() + m,
            Factor::State(..) => return None,
        };
    }
    Some(bound)
}

/// The rows `rows` of every column of `base` (which [`Library::evaluate_rows`] has checked to
/// hold every row).
struct RowWindow<'a> {
    base: &'a dyn Columns,
    rows: std::ops::Range<usize>,
}

impl Columns for RowWindow<'_> {
    fn column(&self, name: &str) -> Option<&[f64]> {
        self.base
            .column(name)
            .map(|c| c.get(self.rows.clone()).unwrap_or(c))
    }
    fn rows(&self) -> usize {
        self.rows.len()
    }
}

fn check_dofs(dofs: &[&str]) -> Result<()> {
    if dofs.is_empty() {
        return Err(LibraryError::Invalid {
            field: "dofs".into(),
            message: "no DOF names given; pass at least one, e.g. [\"x\"]".into(),
        });
    }
    for (i, d) in dofs.iter().enumerate() {
        let ok = d
            .chars()
            .next()
            .is_some_and(|c| c.is_alphabetic() || c == '_')
            && d.chars().all(|c| c.is_alphanumeric() || c == '_');
        if !ok {
            return Err(LibraryError::Invalid {
                field: format!("dofs[{i}]"),
                message: format!(
                    "'{d}' is not a valid DOF name; use letters, digits and '_' starting with a letter"
                ),
            });
        }
        if dofs[..i].contains(d) {
            return Err(LibraryError::Invalid {
                field: format!("dofs[{i}]"),
                message: format!("DOF '{d}' is listed twice"),
            });
        }
    }
    Ok(())
}

fn fetch<'c>(cols: &'c dyn Columns, name: &str, term: &Term) -> Result<&'c [f64]> {
    let c = cols
        .column(name)
        .ok_or_else(|| LibraryError::MissingColumn {
            column: name.to_string(),
            term: term.to_string(),
        })?;
    if c.len() != cols.rows() {
        return Err(LibraryError::ColumnLength {
            column: name.to_string(),
            len: c.len(),
            rows: cols.rows(),
        });
    }
    Ok(c)
}

/// The sampling interval of `cols` from its time column `t`, which an internal state needs to
/// be integrated along its drive.
fn sample_interval(cols: &dyn Columns, term: &Term) -> Result<f64> {
    let t = fetch(cols, "t", term)?;
    let dt = if t.len() >= 2 {
        (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64
    } else {
        1.0
    };
    if !(dt.is_finite() && dt > 0.0) {
        return Err(LibraryError::Invalid {
            field: "t".into(),
            message: format!(
                "the time column gives a sampling interval of {dt}; term '{term}' integrates an internal state and needs increasing, uniformly sampled times"
            ),
        });
    }
    Ok(dt)
}

/// Values of a variable on every row (borrowed for plain columns, computed for relative ones).
fn var_values<'c>(v: &Var, cols: &'c dyn Columns, term: &Term) -> Result<Cow<'c, [f64]>> {
    let names = v.required_columns();
    match v {
        Var::RelDisp(..) | Var::RelVel(..) => {
            let a = fetch(cols, &names[0], term)?;
            let b = fetch(cols, &names[1], term)?;
            Ok(Cow::Owned(a.iter().zip(b).map(|(a, b)| a - b).collect()))
        }
        _ => Ok(Cow::Borrowed(fetch(cols, &names[0], term)?)),
    }
}

/// `vals[i]^k` for every row, as [`evaluate_term`] computes it: `pow_u` for `k ≤ 3`, binary
/// exponentiation done a whole column at a time above (the same multiplications, in the same
/// order, as `f64::powi`, so the same bits, but in loops the compiler vectorises instead of one
/// library call per sample).
fn power_column(vals: &[f64], k: u32) -> Vec<f64> {
    if k <= 3 {
        return vals.iter().map(|&v| crate::term::pow_u(v, k)).collect();
    }
    let mut acc = vec![1.0; vals.len()];
    mul_pow(&mut acc, vals, k);
    acc
}

/// `out[i] *= vals[i]^k` with `vals[i]^k` by binary exponentiation (see [`power_column`]).
fn mul_pow(out: &mut [f64], vals: &[f64], k: u32) {
    let mut base = vals.to_vec();
    let mut acc: Option<Vec<f64>> = None;
    let mut e = k;
    loop {
        if e & 1 == 1 {
            match acc.as_mut() {
                Some(a) => a.iter_mut().zip(&base).for_each(|(a, b)| *a *= b),
                None => acc = Some(base.clone()),
            }
        }
        e >>= 1;
        if e == 0 {
            break;
        }
        base.iter_mut().for_each(|b| *b *= *b);
    }
    let acc = acc.unwrap_or_else(|| vec![1.0; vals.len()]);
    out.iter_mut().zip(&acc).for_each(|(o, a)| *o *= a);
}

/// Powers `v^k` (`k ≥ 2`) already computed by [`Library::evaluate`] for earlier terms: a
/// polynomial library uses each power of a variable in many terms.
type PowerCache = std::collections::HashMap<(crate::term::Var, u32), Vec<f64>>;

/// [`evaluate_term`] taking the powers from (and adding them to) `cache`. Same values: the
/// cached power is the factor the uncached evaluation multiplies by.
fn evaluate_term_cached(
    term: &Term,
    cols: &dyn Columns,
    cache: &mut PowerCache,
) -> Result<Vec<f64>> {
    let mut out = vec![0.0; cols.rows()];
    evaluate_term_into(term, cols, cache, &mut out)?;
    Ok(out)
}

/// [`evaluate_term_cached`] written into `out` (one value per row). The product starts from
/// the first factor itself rather than from 1 times it (the same values).
fn evaluate_term_into(
    term: &Term,
    cols: &dyn Columns,
    cache: &mut PowerCache,
    out: &mut [f64],
) -> Result<()> {
    let mut first = true;
    for f in term.factors() {
        match f {
            Factor::Pow(v, k) if *k >= 2 => {
                let key = (v.clone(), *k);
                if !cache.contains_key(&key) {
                    let vals = var_values(v, cols, term)?;
                    cache.insert(key.clone(), power_column(&vals, *k));
                }
                let pw = &cache[&key];
                if first {
                    out.copy_from_slice(pw);
                } else {
                    out.iter_mut().zip(pw).for_each(|(o, p)| *o *= p);
                }
            }
            Factor::State(drive, law) => {
                let q = var_values(drive, cols, term)?;
                let z = law.integrate(&q, sample_interval(cols, term)?);
                if first {
                    out.copy_from_slice(&z);
                } else {
                    out.iter_mut().zip(&z).for_each(|(o, p)| *o *= p);
                }
            }
            _ => {
                let vals = var_values(f.var(), cols, term)?;
                if first {
                    for (o, v) in out.iter_mut().zip(vals.iter()) {
                        *o = f.apply(*v);
                    }
                } else {
                    for (o, v) in out.iter_mut().zip(vals.iter()) {
                        *o *= f.apply(*v);
                    }
                }
            }
        }
        first = false;
    }
    if first {
        out.fill(1.0);
    }
    if let Some(row) = out.iter().position(|v| !v.is_finite()) {
        return Err(LibraryError::NonFinite {
            term: term.to_string(),
            row,
        });
    }
    Ok(())
}

/// Evaluates one term on every row of `cols`.
pub fn evaluate_term(term: &Term, cols: &dyn Columns) -> Result<Vec<f64>> {
    evaluate_term_cached(term, cols, &mut PowerCache::new())
}

/// A [`Columns`] view that adds named columns (derived velocities, filtered signals, …) on top of
/// a base record; added columns shadow base columns of the same name.
pub struct ColumnSet<'a> {
    base: &'a dyn Columns,
    extra: Vec<(String, Vec<f64>)>,
}

impl<'a> ColumnSet<'a> {
    /// Wraps a base record (or any other [`Columns`]).
    pub fn new(base: &'a dyn Columns) -> Self {
        Self {
            base,
            extra: Vec::new(),
        }
    }

    /// Adds or replaces a column; its length must equal the base's row count.
    pub fn insert(&mut self, name: impl Into<String>, values: Vec<f64>) -> Result<()> {
        let name = name.into();
        if values.len() != self.base.rows() {
            return Err(LibraryError::ColumnLength {
                column: name,
                len: values.len(),
                rows: self.base.rows(),
            });
        }
        match self.extra.iter_mut().find(|(n, _)| *n == name) {
            Some(slot) => slot.1 = values,
            None => self.extra.push((name, values)),
        }
        Ok(())
    }

    /// Builder form of [`ColumnSet::insert`].
    pub fn with(mut self, name: impl Into<String>, values: Vec<f64>) -> Result<Self> {
        self.insert(name, values)?;
        Ok(self)
    }
}

impl Columns for ColumnSet<'_> {
    fn column(&self, name: &str) -> Option<&[f64]> {
        self.extra
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
            .or_else(|| self.base.column(name))
    }

    fn rows(&self) -> usize {
        self.base.rows()
    }
}

#[cfg(test)]
mod tests {
    use super::{Library, evaluate_term, mul_pow};

    /// The library matrix (powers shared between terms) equals each term evaluated on its own,
    /// to the bit, and the factors applied row by row to rounding.
    #[test]
    fn shared_powers_give_the_same_columns() {
        let n = 300;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
        let x: Vec<f64> = t.iter().map(|v| 1.3 * (2.1 * v).sin() - 0.2).collect();
        let xd: Vec<f64> = t.iter().map(|v| 2.7 * (2.1 * v).cos()).collect();
        let u: Vec<f64> = t.iter().map(|v| (5.0 * v).sin()).collect();
        let rec = tfs_data::Record::new(
            "r",
            t,
            vec![("x".into(), x), ("x'".into(), xd), ("xb_acc".into(), u)],
        )
        .unwrap();
        let lib = Library::parse("poly(x, x'; 0..7), abs(x')*x^2, xb_acc", &["x"]).unwrap();
        let m = lib.evaluate(&rec).unwrap();
        for (j, term) in lib.terms().iter().enumerate() {
            let one = evaluate_term(term, &rec).unwrap();
            for (i, v) in one.iter().enumerate() {
                assert_eq!(m[(i, j)].to_bits(), v.to_bits(), "{term} row {i}");
                // Against the factors applied row by row (`powi` for the powers).
                let direct: f64 = term
                    .factors()
                    .iter()
                    .map(|f| {
                        let name = &f.var().required_columns()[0];
                        f.apply(tfs_data::Columns::column(&rec, name).unwrap()[i])
                    })
                    .product();
                assert!(
                    (v - direct).abs() <= 1e-14 * direct.abs().max(1e-300),
                    "{term} row {i}"
                );
            }
        }
    }

    #[test]
    fn column_powers_match_powi() {
        let vals: Vec<f64> = (0..257)
            .map(|i| (i as f64 - 128.0) * 0.0173 + 1e-3)
            .collect();
        for k in 0..=13u32 {
            let mut out = vec![1.5; vals.len()];
            mul_pow(&mut out, &vals, k);
            for (o, v) in out.iter().zip(&vals) {
                let want = 1.5 * v.powi(k as i32);
                assert!(
                    (o - want).abs() <= 1e-15 * want.abs(),
                    "k {k}: {o} vs {want}"
                );
            }
        }
    }
}
