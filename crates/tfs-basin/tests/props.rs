//! Property tests: equilibria of random cubic forces in closed form; BOA error is a metric-like
//! share.

use proptest::prelude::*;
use tfs_basin::{BasinConfig, Label, Polynomial1Dof, WellInfo, basin_sdof, compare};

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// f(x) = k (x − a)(x − b)(x − c), k > 0: stable at a and c, unstable at b, and the barrier
    /// of each well is V(b) minus the safety margin (10⁻⁶ of the depth) (the search ends are higher walls).
    #[test]
    fn cubic_force_equilibria(a in -2.0f64..-0.3, b in -0.2f64..0.2, c in 0.3f64..2.0, k in 0.2f64..5.0) {
        // Expand k (x − a)(x − b)(x − c) into power coefficients.
        let c0 = -k * a * b * c;
        let c1 = k * (a * b + b * c + a * c);
        let c2 = -k * (a + b + c);
        let sys = Polynomial1Dof::new(0.5, vec![c0, c1, c2, k]).unwrap();
        let w = WellInfo::from_polynomial(&sys, (-6.0, 6.0)).unwrap();
        prop_assert_eq!(w.stable().len(), 2);
        prop_assert_eq!(w.unstable().len(), 1);
        prop_assert!((w.stable()[0] - a).abs() < 1e-9);
        prop_assert!((w.stable()[1] - c).abs() < 1e-9);
        prop_assert!((w.unstable()[0] - b).abs() < 1e-9);
        let vb = w.potential(b);
        for well in w.wells() {
            let depth = vb - w.potential(well.bottom);
            prop_assert!(depth > 0.0);
            prop_assert!(well.barrier < vb && well.barrier >= vb - 2e-6 * depth);
        }
        // A start at rest just inside a well stays there.
        prop_assert_eq!(w.trapped(a, 0.0), Some(0));
        prop_assert_eq!(w.trapped(c, 0.0), Some(1));
    }

    /// The BOA error is symmetric, in [0, 1], and equals the share of the disagreement mask.
    #[test]
    fn boa_error_is_a_share(flips in proptest::collection::vec(0usize..64, 0..20)) {
        let sys = Polynomial1Dof::new(0.5, vec![0.0, -1.0, 0.0, 1.0]).unwrap();
        let w = WellInfo::from_polynomial(&sys, (-3.0, 3.0)).unwrap();
        let a = basin_sdof(&sys, &w, &BasinConfig::new(8, 8, (-2.0, 2.0), (-2.0, 2.0)), None).unwrap();
        let mut b = a.clone();
        for &f in &flips {
            b.labels[f] = Label::Unsettled;
        }
        let ab = compare(&a, &b).unwrap();
        let ba = compare(&b, &a).unwrap();
        prop_assert_eq!(ab.error, ba.error);
        prop_assert!((0.0..=1.0).contains(&ab.error));
        let n = ab.disagree.iter().filter(|&&d| d).count();
        prop_assert_eq!(ab.error, n as f64 / 64.0);
    }
}
