//! How big a hidden effect is, two ways, both as a share of the RMS acceleration on the
//! training records: its *realised* size (the RMS of its force) and its *unrepresentable part*
//! (the RMS of what is left of its force after the best least-squares fit by the start
//! library's columns, evaluated on the clean states). The first says how strong the effect is;
//! the second how much of it a model built from the start library must miss, whatever its
//! coefficients — the part a diagnosis can find at all.

use anyhow::{Context, Result, bail};
use faer::Mat;
use tfs::data::Record;
use tfs::library::Library;
use tfs::records::Offsets;

use super::hide::Hide;
use super::truth::{Baseline, Clean, std_dev};

/// Coordinate `dof` of `q` (displacements or velocities of the masses) relative to the mass
/// below it (the ground for the first).
fn relative(q: &[Vec<f64>], dof: usize) -> Vec<f64> {
    if dof == 0 {
        q[0].clone()
    } else {
        q[dof].iter().zip(&q[dof - 1]).map(|(a, b)| a - b).collect()
    }
}

/// The force per unit mass of hidden effect `h` along clean record `c`, on the equation of
/// DOF `h.dof`. `slot` is the index of the effect's first placed force in `c.motion.forces`.
fn force(b: &Baseline, h: &Hide, slot: usize, c: &Clean) -> Vec<f64> {
    if !h.placed.is_empty() {
        c.motion.forces[slot]
            .iter()
            .map(|f| f / b.masses[h.dof])
            .collect()
    } else if !h.exciter.is_empty() {
        c.felt
            .iter()
            .zip(&c.u)
            .map(|(f, u)| b.gain * (f - u))
            .collect()
    } else {
        // The baseline's own term: its dashpot `coef·v` or stiffness power `coef·x^p`, on the
        // element's (relative) coordinate.
        let coef = h.params["coef"].as_f64().unwrap_or(0.0);
        if h.effect == "linear-damping" {
            let v = relative(&c.motion.v, h.dof);
            v.iter().map(|v| coef * v).collect()
        } else {
            let p = h.params["own_term"]
                .as_str()
                .and_then(|t| t.rsplit_once('^').map(|(_, p)| p.parse().unwrap_or(1)))
                .unwrap_or(1);
            let x = relative(&c.motion.x, h.dof);
            x.iter().map(|v| coef * v.powi(p)).collect()
        }
    }
}

/// Each hidden effect's force per unit mass along each clean record.
fn forces(b: &Baseline, hides: &[Hide], clean: &[Clean]) -> Vec<Vec<Vec<f64>>> {
    let mut slot = 0;
    hides
        .iter()
        .map(|h| {
            let f = clean.iter().map(|c| force(b, h, slot, c)).collect();
            slot += h.placed.len();
            f
        })
        .collect()
}

/// Sum over the records of the acceleration variance of DOF `dof`, times the rows (so that a
/// sum of squares over the rows divided by it is a share of the RMS acceleration squared).
fn acceleration_energy(clean: &[Clean], dof: usize) -> f64 {
    clean
        .iter()
        .map(|c| {
            let a = std_dev(&c.motion.a[dof]);
            a * a * c.motion.a[dof].len() as f64
        })
        .sum::<f64>()
        .max(f64::MIN_POSITIVE)
}

/// Realised share of each hidden effect over the clean records: the RMS of its force (about
/// its mean, except for an offset, which is nothing but its mean: a force's mean only moves the
/// rest state) over the RMS acceleration of its DOF.
pub fn realised(b: &Baseline, hides: &[Hide], clean: &[Clean]) -> Vec<f64> {
    forces(b, hides, clean)
        .iter()
        .zip(hides)
        .map(|(per_record, h)| {
            let num: f64 = per_record
                .iter()
                .map(|f| {
                    let s = if h.effect == "offset" {
                        super::truth::rms(f)
                    } else {
                        std_dev(f)
                    };
                    s * s * f.len() as f64
                })
                .sum();
            (num / acceleration_energy(clean, h.dof)).sqrt()
        })
        .collect()
}

/// The clean states of record `c` as the columns the library reads: each DOF, its velocity
/// (`x'`), and the recorded input.
fn state_columns(b: &Baseline, c: &Clean) -> Result<Record> {
    let n = c.u.len();
    let mut cols = Vec::new();
    for (d, name) in b.dofs.iter().enumerate() {
        cols.push((name.clone(), c.motion.x[d].clone()));
        cols.push((format!("{name}'"), c.motion.v[d].clone()));
    }
    cols.push((b.input.clone(), c.u.clone()));
    Ok(Record::new("clean", tfs::signal::time_grid(n, b.dt), cols)?)
}

/// The least-squares residual of `y` regressed on the columns of `a`: `y − a·ξ` with `ξ` from
/// the project's least squares (`tfs::regress::lstsq`: columns scaled to unit norm, a
/// column-pivoted QR that drops columns found dependent and columns that are all zeros).
/// Columns that nearly cancel one another, as the truss cell's monomials about its offset do,
/// are then dropped by the rank test instead of solved with pivots at rounding level.
pub fn residual(a: &Mat<f64>, y: &[f64]) -> Result<Vec<f64>> {
    let (n, p) = (a.nrows(), a.ncols());
    if y.len() != n {
        bail!("residual: {} rows against {} values", n, y.len());
    }
    if p == 0 {
        return Ok(y.to_vec());
    }
    let fit = tfs::regress::lstsq(a.as_ref(), y).context("residual: the least-squares fit")?;
    let xi = Mat::<f64>::from_fn(p, 1, |j, _| fit.coef[j]);
    let held = a * &xi;
    Ok((0..n).map(|i| y[i] - held[(i, 0)]).collect())
}

/// The unrepresentable part of each hidden effect: the RMS of the least-squares residual of its
/// force regressed on the start library of its DOF's equation (`libraries[dof]`, plus the
/// constant when `identify` adds one), all training records at once with one set of
/// coefficients as `identify` fits them, over the RMS acceleration of that DOF. Clean states:
/// what no coefficients of the start library could hold, noise aside.
pub fn unrepresentable(
    b: &Baseline,
    hides: &[Hide],
    libraries: &[String],
    clean: &[Clean],
) -> Result<Vec<f64>> {
    let dofs: Vec<&str> = b.dofs.iter().map(String::as_str).collect();
    let records: Vec<Record> = clean
        .iter()
        .map(|c| state_columns(b, c))
        .collect::<Result<_>>()?;
    forces(b, hides, clean)
        .iter()
        .zip(hides)
        .map(|(per_record, h)| {
            let spec = libraries
                .get(h.dof)
                .or(libraries.first())
                .context("no start library")?;
            let lib = Library::parse(spec, &dofs)?;
            let blocks: Vec<Mat<f64>> = records
                .iter()
                .map(|r| lib.evaluate(r))
                .collect::<std::result::Result<_, _>>()?;
            let constant = b.offsets == Offsets::ConstantTerm;
            let rows: usize = blocks.iter().map(|m| m.nrows()).sum();
            let p = lib.len() + constant as usize;
            let mut a = Mat::<f64>::zeros(rows, p);
            let mut r0 = 0;
            for m in &blocks {
                for j in 0..m.ncols() {
                    for i in 0..m.nrows() {
                        a[(r0 + i, j)] = m[(i, j)];
                    }
                }
                if constant {
                    for i in 0..m.nrows() {
                        a[(r0 + i, p - 1)] = 1.0;
                    }
                }
                r0 += m.nrows();
            }
            let y: Vec<f64> = per_record.concat();
            let e = residual(&a, &y)?;
            let ss: f64 = e.iter().map(|v| v * v).sum();
            Ok((ss / acceleration_energy(clean, h.dof)).sqrt())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A force the columns hold exactly leaves nothing; one orthogonal to every column leaves
    /// all of itself; a mix leaves its orthogonal part.
    #[test]
    fn residual_keeps_only_what_the_columns_cannot_hold() {
        let n = 2000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
        // A sine motion: the columns x, x^3, x' hold the harmonics sin(2t), sin(6t), cos(2t).
        let x: Vec<f64> = t.iter().map(|t| (2.0 * t).sin()).collect();
        let v: Vec<f64> = t.iter().map(|t| 2.0 * (2.0 * t).cos()).collect();
        let rec = Record::new(
            "test",
            t.clone(),
            vec![("x".into(), x.clone()), ("x'".into(), v.clone())],
        )
        .unwrap();
        let lib = Library::parse("x, x^3, x'", &["x"]).unwrap();
        let a = lib.evaluate(&rec).unwrap();
        let rms = |e: &[f64]| (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt();

        let held: Vec<f64> = x
            .iter()
            .zip(&v)
            .map(|(x, v)| 3.0 * x.powi(3) - 0.5 * v)
            .collect();
        let e = residual(&a, &held).unwrap();
        assert!(rms(&e) < 1e-10 * rms(&held), "held exactly: {}", rms(&e));

        // cos(4t) is orthogonal to those three over whole periods of sin(2t).
        let periods = (n as f64 * 0.01 * 2.0 / std::f64::consts::TAU).floor();
        let m = (periods * std::f64::consts::TAU / 2.0 / 0.01) as usize;
        let a_m = Mat::<f64>::from_fn(m, a.ncols(), |i, j| a[(i, j)]);
        let orth: Vec<f64> = t[..m].iter().map(|t| 0.7 * (4.0 * t).cos()).collect();
        let e = residual(&a_m, &orth).unwrap();
        let ratio = rms(&e) / rms(&orth);
        assert!((ratio - 1.0).abs() < 0.01, "orthogonal kept whole: {ratio}");

        let mix: Vec<f64> = orth.iter().zip(&held[..m]).map(|(o, h)| o + h).collect();
        let e = residual(&a_m, &mix).unwrap();
        let ratio = rms(&e) / rms(&orth);
        assert!(
            (ratio - 1.0).abs() < 0.01,
            "the orthogonal part of a mix: {ratio}"
        );
    }

    /// Columns that nearly cancel one another (monomials about an offset, one repeated) give a
    /// finite residual: nearly nothing of a force they hold, most of one they cannot.
    #[test]
    fn residual_of_columns_that_cancel_is_finite() {
        // Monomials of a coordinate that moves ±0.04 about 1.57, and a copy of one of them:
        // an unpivoted triangular solve meets a zero pivot; the rank test must drop it.
        let n = 600;
        let x: Vec<f64> = (0..n)
            .map(|i| 1.57 + 0.04 * (0.05 * i as f64).sin())
            .collect();
        let a = Mat::<f64>::from_fn(n, 8, |i, j| x[i].powi(j.min(6) as i32 + 1));
        let rms = |e: &[f64]| (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt();
        let held: Vec<f64> = x.iter().map(|x| 2.0 * x - 0.5 * x * x).collect();
        let e = residual(&a, &held).unwrap();
        assert!(e.iter().all(|v| v.is_finite()));
        // Columns the rank test finds dependent are dropped, so "held" is only to about 1e-6
        // here (the part is reported in per cent of the acceleration: far below its digits).
        assert!(rms(&e) < 1e-4 * rms(&held), "held: {}", rms(&e));
        let outside: Vec<f64> = (0..n).map(|i| (0.37 * i as f64).cos()).collect();
        let e = residual(&a, &outside).unwrap();
        assert!(e.iter().all(|v| v.is_finite()));
        let ratio = rms(&e) / rms(&outside);
        assert!(ratio > 0.5 && ratio <= 1.0 + 1e-12, "{ratio}");
    }

    /// On a drawn Duffing truth with quadratic damping hidden: the full library leaves the
    /// effect's force whole but no more (the part is at most the realised size); a library that
    /// holds the effect's own law exactly leaves nothing of it.
    #[test]
    fn unrepresentable_part_on_a_drawn_truth() {
        use super::super::hide::hide;
        use super::super::truth::{Kind, draw, simulate};
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let b = draw(Kind::Duffing, &mut rng).unwrap();
        let pilot = simulate(&b, 0, &[], &[]).unwrap();
        let h = hide("quadratic-damping", &b, &pilot, 0.2, &mut rng)
            .unwrap()
            .unwrap();
        let hides = vec![h];
        let clean: Vec<Clean> = (0..3)
            .map(|i| simulate(&b, i, &hides[0].placed, &[]).unwrap())
            .collect();
        let real = realised(&b, &hides, &clean)[0];
        assert!((real / 0.2 - 1.0).abs() < 0.5, "realised {real}");
        let start = unrepresentable(&b, &hides, &b.libraries, &clean).unwrap()[0];
        assert!(start > 0.0 && start <= 1.05 * real, "{start} vs {real}");
        // x'|x'| is odd in x' as the dashpot is: the dashpot holds much of it, not all.
        assert!(start < 0.6 * real, "{start} vs {real}");
        let with_law = vec![format!("{}, x'*abs(x')", b.libraries[0])];
        let none = unrepresentable(&b, &hides, &with_law, &clean).unwrap()[0];
        assert!(none < 1e-8 * real, "the law in the library: {none}");
    }
}
