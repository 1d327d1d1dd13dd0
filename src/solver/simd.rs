//! The AVX2 vectors of four doubles that the products by 3 × 3 blocks
//! ([`super::bsr`], [`super::pcg`]) work in, where the compiler does not
//! find them itself. Each helper reads through a checked slice, so a read
//! out of bounds panics as safe code would.

#![cfg(target_arch = "x86_64")]

use std::arch::x86_64::*;

/// The four f32 from `a[0]` on, in double precision.
#[inline(always)]
pub(super) unsafe fn load_f32(a: &[f32]) -> __m256d {
    let a = &a[..4];
    _mm256_cvtps_pd(_mm_loadu_ps(a.as_ptr()))
}

/// The four f64 from `x[0]` on.
#[inline(always)]
pub(super) unsafe fn load(x: &[f64]) -> __m256d {
    let x = &x[..4];
    _mm256_loadu_pd(x.as_ptr())
}

/// (t₀ + t₁) + t₂: lanes 0..3 summed as the portable loops sum them
/// ([`super::bsr::sum_lanes`]).
#[inline(always)]
unsafe fn sum3(t: __m256d) -> f64 {
    let mut v = [0.0; 4];
    _mm256_storeu_pd(v.as_mut_ptr(), t);
    (v[0] + v[1]) + v[2]
}

/// The three lanes' sums of each t_r added to y[r], r = 0..3.
#[inline(always)]
pub(super) unsafe fn add_sums(y: &mut [f64], t: &[__m256d; 3]) {
    for (y, &t) in y[..3].iter_mut().zip(t) {
        *y += sum3(t);
    }
}

/// One block of a product: t_r += a_r ⊙ x (the block to its own row
/// node's sums) and, with `to` = (y of the other node, x of this one
/// broadcast), y += Σ_r x_r a_r (the block transposed), r = 0..3.
#[inline(always)]
pub(super) unsafe fn block(
    t: &mut [__m256d; 3],
    a: &[__m256d; 3],
    x: __m256d,
    to: Option<(&mut [f64], &[__m256d; 3])>,
) {
    for r in 0..3 {
        t[r] = _mm256_add_pd(t[r], _mm256_mul_pd(a[r], x));
    }
    if let Some((y, xb)) = to {
        let y = &mut y[..4];
        let mut v = _mm256_loadu_pd(y.as_ptr());
        for r in 0..3 {
            v = _mm256_add_pd(v, _mm256_mul_pd(a[r], xb[r]));
        }
        _mm256_storeu_pd(y.as_mut_ptr(), v);
    }
}
