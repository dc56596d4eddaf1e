//! How strongly a model's equation responds to a small change of each coordinate along a
//! trajectory: the mean and the spread over the samples of its partial derivatives. Noise on a
//! measured coordinate enters an equation residual through these local gains, not through the
//! linear coefficients alone: a polynomial `c1·x + … + c7·x^7` fitted to a stiff curve can have a
//! linear coefficient far larger than its local stiffness anywhere on the records.

use crate::compiled::CompiledModel;

/// The mean and the variance over samples of one local gain (a partial derivative of an
/// equation's right side).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GainMoments {
    /// Mean over the samples.
    pub mean: f64,
    /// Variance over the samples (population form, `Σ(g − mean)²/n`).
    pub var: f64,
}

/// The local gains of one equation with respect to one DOF's displacement and velocity.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LocalGains {
    /// `∂a/∂x_k` over the samples.
    pub disp: GainMoments,
    /// `∂a/∂v_k` over the samples.
    pub vel: GainMoments,
}

/// Running mean and sum of squared deviations (Welford), so that a constant gain comes out
/// exactly with zero variance.
#[derive(Clone, Copy, Default)]
struct Running {
    n: f64,
    mean: f64,
    m2: f64,
}

impl Running {
    fn push(&mut self, g: f64) {
        self.n += 1.0;
        let d = g - self.mean;
        self.mean += d / self.n;
        self.m2 += d * (g - self.mean);
    }
    fn moments(self) -> GainMoments {
        GainMoments {
            mean: self.mean,
            var: if self.n > 0.0 { self.m2 / self.n } else { 0.0 },
        }
    }
}

impl CompiledModel {
    /// The local gains of equation `eq` along the samples `rows` of a trajectory: per DOF `k`
    /// (model order), the mean and variance of `∂a_eq/∂x_k` and `∂a_eq/∂v_k` at the states
    /// `x[k][i]`, `v[k][i]` and inputs `u[j][i]` ([`CompiledModel::input_names`] order). Internal
    /// states are taken at 0 (their terms' gains with respect to `x` and `v` are then those of
    /// the plain terms). A term linear in a coordinate has that coordinate's coefficient as its
    /// gain at every sample, so a linear model's gains are its coefficients, with zero variance.
    ///
    /// # Panics
    /// If a slice is missing (fewer than [`CompiledModel::dofs`] displacement or velocity slices,
    /// fewer than [`CompiledModel::inputs`] input slices), a row is out of a slice's range or
    /// `eq` is not an equation: programming errors.
    pub fn local_gains(
        &self,
        eq: usize,
        x: &[&[f64]],
        v: &[&[f64]],
        u: &[&[f64]],
        rows: impl IntoIterator<Item = usize>,
    ) -> Vec<LocalGains> {
        let n0 = self.dofs();
        let n = self.system_dofs();
        assert!(eq < n0, "equation {eq} of a model of {n0} DOFs");
        let coefs = self.coefficients();
        let (mut xs, mut vs, mut us) = (vec![0.0; n], vec![0.0; n], vec![0.0; self.inputs()]);
        let (mut a, mut theta) = (vec![0.0; n], vec![0.0; self.n_terms()]);
        let (mut ax, mut av) = (vec![0.0; n * n], vec![0.0; n * n]);
        let mut acc = vec![[Running::default(); 2]; n0];
        for i in rows {
            for k in 0..n0 {
                xs[k] = x[k][i];
                vs[k] = v[k][i];
            }
            for (j, uj) in us.iter_mut().enumerate() {
                *uj = u[j][i];
            }
            self.eval_jacobian(&coefs, &xs, &vs, &us, &mut a, &mut theta, &mut ax, &mut av);
            for (k, r) in acc.iter_mut().enumerate() {
                r[0].push(ax[eq * n + k]);
                r[1].push(av[eq * n + k]);
            }
        }
        acc.into_iter()
            .map(|[d, w]| LocalGains {
                disp: d.moments(),
                vel: w.moments(),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use crate::{Library, Model};

    fn model(spec: &str, coefs: &[f64]) -> crate::CompiledModel {
        let lib = Library::parse(spec, &["x"]).unwrap();
        Model::from_coefficients(&lib, &[coefs.to_vec()], "test")
            .unwrap()
            .compile()
            .unwrap()
    }

    /// A linear model's gains are its coefficients, exactly, with no spread.
    #[test]
    fn a_linear_model_s_gains_are_its_coefficients() {
        let m = model("x, x'", &[-3.7, -0.21]);
        let x: Vec<f64> = (0..50).map(|i| (0.3 * i as f64).sin()).collect();
        let v: Vec<f64> = (0..50).map(|i| (0.3 * i as f64).cos()).collect();
        let g = m.local_gains(0, &[&x], &[&v], &[], 0..50);
        assert_eq!(g[0].disp.mean, -3.7);
        assert_eq!(g[0].disp.var, 0.0);
        assert_eq!(g[0].vel.mean, -0.21);
        assert_eq!(g[0].vel.var, 0.0);
    }

    /// A polynomial whose linear coefficient is cancelled by its higher powers: the gain follows
    /// the local slope `Σ k·c_k·x^(k−1)`, not `c_1`.
    #[test]
    fn a_polynomial_s_gain_is_its_local_slope() {
        // f(x) = -1000 x + 1000 x^3 - x: slope -1001 + 3000 x² (≈ -1 near x = ±0.5774).
        let m = model("x, x^3", &[-1001.0, 1000.0]);
        let x: Vec<f64> = (0..200).map(|i| 0.5 + 0.001 * i as f64).collect();
        let v = vec![0.0; 200];
        let g = m.local_gains(0, &[&x], &[&v], &[], 0..200);
        let slopes: Vec<f64> = x.iter().map(|s| -1001.0 + 3000.0 * s * s).collect();
        let mean = slopes.iter().sum::<f64>() / 200.0;
        let var = slopes.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 200.0;
        assert!((g[0].disp.mean - mean).abs() < 1e-9 * mean.abs().max(1.0));
        assert!((g[0].disp.var - var).abs() < 1e-9 * var);
        assert!(g[0].disp.mean.abs() < 300.0, "{:?}", g[0].disp);
    }
}
