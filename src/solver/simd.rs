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
pub(super) unsafe fn sum3(t: __m256d) -> f64 {
    let mut v = [0.0; 4];
    _mm256_storeu_pd(v.as_mut_ptr(), t);
    (v[0] + v[1]) + v[2]
}
