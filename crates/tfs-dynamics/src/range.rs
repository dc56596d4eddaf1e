//! Runs stopped once a displacement leaves the range its record measured.
//!
//! A model's run under a measured input that wanders far outside everything the record shows
//! has already failed as a prediction of it; left to go on, a model with high powers of `x`
//! stiffens out there and an explicit integrator crawls at its stability limit until the run
//! blows up or exhausts its step budget (minutes per run). [`Ranged`] ends such a run at the
//! first output time past the band and says so ([`DynError::LeftRange`]).

use crate::{DynError, Integrator, Result, SampledInput, SecondOrderSystem, Trajectory};

/// The band a measured displacement may reach in a run: the record's own span widened by
/// `factor` spans on each side. A constant record (a generator's start at rest, not a
/// measurement) and an empty one bound nothing.
pub fn range_band(measured: &[f64], factor: f64) -> (f64, f64) {
    let (lo, hi) = measured
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let span = hi - lo;
    if !(span > 0.0 && span.is_finite()) {
        return (f64::NEG_INFINITY, f64::INFINITY);
    }
    (lo - factor * span, hi + factor * span)
}

/// An integrator whose runs stop with [`DynError::LeftRange`] at the first output time where
/// displacement `i` (the first `bands.len()` coordinates, the measured ones) leaves
/// `bands[i]`. Samples before the stop are the inner integrator's, bit for bit.
pub(crate) struct Ranged<'a, I> {
    /// The integrator that does the stepping.
    pub inner: &'a I,
    /// Allowed `(low, high)` per measured displacement.
    pub bands: Vec<(f64, f64)>,
    /// Each measured displacement's name, for the error.
    pub names: Vec<String>,
}

impl<I: Integrator> Ranged<'_, I> {
    /// The first measured displacement outside its band, as `(index, value)`.
    fn outside(&self, x: &[f64]) -> Option<(usize, f64)> {
        self.bands
            .iter()
            .zip(x)
            .enumerate()
            .find(|(_, ((lo, hi), v))| !(*v >= lo && *v <= hi))
            .map(|(i, (_, v))| (i, *v))
    }

    fn left(&self, t: f64, i: usize, x: f64) -> DynError {
        let (lo, hi) = self.bands[i];
        DynError::LeftRange {
            t,
            dof: self
                .names
                .get(i)
                .cloned()
                .unwrap_or_else(|| format!("x{i}")),
            x,
            lo,
            hi,
        }
    }
}

impl<I: Integrator> Integrator for Ranged<'_, I> {
    fn integrate<S: SecondOrderSystem + ?Sized>(
        &self,
        sys: &S,
        input: &SampledInput,
        x0: &[f64],
        v0: &[f64],
        t_out: &[f64],
    ) -> Result<Trajectory> {
        match self.integrate_until(sys, input, x0, v0, t_out, |_, _| true)? {
            Some(tr) => Ok(tr),
            // Only the band stops a run whose caller never does, and that returns an error.
            None => unreachable!("a ranged run without a caller's stop ends whole or in error"),
        }
    }

    fn integrate_until<S: SecondOrderSystem + ?Sized, F: FnMut(usize, &[f64]) -> bool>(
        &self,
        sys: &S,
        input: &SampledInput,
        x0: &[f64],
        v0: &[f64],
        t_out: &[f64],
        mut keep_going: F,
    ) -> Result<Option<Trajectory>> {
        let mut left = None;
        let run = self
            .inner
            .integrate_until(sys, input, x0, v0, t_out, |k, x| {
                if let Some((i, v)) = self.outside(x) {
                    left = Some((k, i, v));
                    return false;
                }
                keep_going(k, x)
            })?;
        match left {
            Some((k, i, v)) => Err(self.left(t_out[k], i, v)),
            None => Ok(run),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Dopri5, FnSystem};

    /// A slowly diverging oscillator (negative damping) stops as soon as it passes its band,
    /// with the time and the value; every sample before is the unbounded run's.
    #[test]
    fn a_run_that_wanders_off_its_band_stops_there() {
        let sys = FnSystem::new(
            1,
            0,
            |_t, x: &[f64], v: &[f64], _u: &[f64], a: &mut [f64]| a[0] = 0.2 * v[0] - x[0],
        );
        let t: Vec<f64> = (0..=400).map(|k| k as f64 * 0.1).collect();
        let d = Dopri5::default();
        let free = d
            .integrate(&sys, &SampledInput::zero(0), &[1.0], &[0.0], &t)
            .unwrap();
        let ranged = Ranged {
            inner: &d,
            bands: vec![range_band(&[-1.0, 1.0], 2.0)],
            names: vec!["x".into()],
        };
        let e = ranged
            .integrate(&sys, &SampledInput::zero(0), &[1.0], &[0.0], &t)
            .unwrap_err();
        let DynError::LeftRange {
            t: tl, x, lo, hi, ..
        } = e.clone()
        else {
            panic!("expected LeftRange, got {e}");
        };
        assert_eq!((lo, hi), (-5.0, 5.0));
        assert!(x.abs() > 5.0);
        let k = t.iter().position(|&v| v == tl).unwrap();
        assert!(free.x[0][..k].iter().all(|v| v.abs() <= 5.0));
        assert_eq!(free.x[0][k], x);
        assert!(e.to_string().contains("left the range"), "{e}");
        // Inside its band the run is the unbounded one, bit for bit.
        let wide = Ranged {
            inner: &d,
            bands: vec![(-1e9, 1e9)],
            names: vec!["x".into()],
        };
        let same = wide
            .integrate(&sys, &SampledInput::zero(0), &[1.0], &[0.0], &t)
            .unwrap();
        assert_eq!(same.x, free.x);
    }

    #[test]
    fn a_constant_record_bounds_nothing() {
        assert_eq!(range_band(&[1.0, 3.0], 2.0), (-3.0, 7.0));
        let none = (f64::NEG_INFINITY, f64::INFINITY);
        assert_eq!(range_band(&[0.0, 0.0], 10.0), none);
        assert_eq!(range_band(&[], 10.0), none);
    }
}
