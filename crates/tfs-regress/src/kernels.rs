//! The two vector loops of the Householder updates (compression, merges, subset solves): an
//! inner product and `y −= s·x`.

/// `Σ aᵢbᵢ` over the common length, in eight interleaved partial sums (lane `l` sums the
/// products of the indices `≡ l mod 8`): a single running sum is one dependency chain the
/// compiler may not reorder (each add waits for the last), while eight independent ones keep
/// the vector units busy. The sums are kept as two arrays of four so that they map onto two
/// AVX2 registers (or four SSE2 ones) without shuffles; the partial sums and the order they
/// are added in do not depend on the vector width, so neither does the result.
#[inline(always)]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor has AVX2, checked just above.
        return unsafe { dot_avx2(a, b) };
    }
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut lo = [0.0f64; 4];
    let mut hi = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            lo[i] += x[i] * y[i];
        }
        for i in 0..4 {
            hi[i] += x[i + 4] * y[i + 4];
        }
    }
    let mut s = ((lo[0] + hi[0]) + (lo[1] + hi[1])) + ((lo[2] + hi[2]) + (lo[3] + hi[3]));
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

/// [`dot`] with AVX2 registers: the same eight partial sums (two registers of four) added in
/// the same order, so the same bits.
///
/// # Safety
/// The processor must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn dot_avx2(a: &[f64], b: &[f64]) -> f64 {
    use std::arch::x86_64::{
        _mm256_add_pd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_setzero_pd, _mm256_storeu_pd,
    };
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let (mut lo, mut hi) = (_mm256_setzero_pd(), _mm256_setzero_pd());
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        // SAFETY: `x` and `y` hold eight values each; unaligned loads.
        unsafe {
            let p = _mm256_mul_pd(_mm256_loadu_pd(x.as_ptr()), _mm256_loadu_pd(y.as_ptr()));
            let q = _mm256_mul_pd(
                _mm256_loadu_pd(x.as_ptr().add(4)),
                _mm256_loadu_pd(y.as_ptr().add(4)),
            );
            lo = _mm256_add_pd(lo, p);
            hi = _mm256_add_pd(hi, q);
        }
    }
    let (mut l, mut h) = ([0.0f64; 4], [0.0f64; 4]);
    // SAFETY: four values each.
    unsafe {
        _mm256_storeu_pd(l.as_mut_ptr(), lo);
        _mm256_storeu_pd(h.as_mut_ptr(), hi);
    }
    let mut s = ((l[0] + h[0]) + (l[1] + h[1])) + ((l[2] + h[2]) + (l[3] + h[3]));
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

/// `y −= s·x` over the common length.
#[inline(always)]
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
