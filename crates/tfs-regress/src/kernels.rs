//! The two vector loops of the Householder updates (compression, merges, subset solves): an
//! inner product and `y −= s·x`.

/// `Σ aᵢbᵢ` over the common length, in eight interleaved partial sums: a single running sum is
/// one dependency chain the compiler may not reorder (each add waits for the last), while eight
/// independent ones keep the vector units busy.
#[inline]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    let mut s = ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

/// `y −= s·x` over the common length.
#[inline]
pub(crate) fn sub_scaled(y: &mut [f64], s: f64, x: &[f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi -= s * xi;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The interleaved sums agree with a running sum to rounding, for lengths around the lane
    /// count.
    #[test]
    fn dot_matches_a_running_sum() {
        for n in [0usize, 1, 7, 8, 9, 31, 64, 1001] {
            let a: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin() * 1e3).collect();
            let b: Vec<f64> = (0..n).map(|i| (i as f64 * 1.1).cos() / 7.0).collect();
            let naive: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
            let scale: f64 = a.iter().zip(&b).map(|(x, y)| (x * y).abs()).sum();
            assert!(
                (dot(&a, &b) - naive).abs() <= 1e-14 * scale.max(1.0),
                "n = {n}"
            );
            let mut y = b.clone();
            sub_scaled(&mut y, 0.3, &a);
            for i in 0..n {
                assert_eq!(y[i], b[i] - 0.3 * a[i]);
            }
        }
    }
}
