//! Small dense matrices: 2×2 and 3×3 blocks stored as 3×3, with their
//! determinant, cofactor, inverse and product. The element maps, the
//! materials and the optimisation energy share them.

/// A small square matrix stored as 3×3; in 2D only the leading 2×2 block is used.
pub type Mat3 = [[f64; 3]; 3];

/// Determinant of the leading `dim`×`dim` block.
#[inline]
pub fn det(dim: usize, m: &Mat3) -> f64 {
    if dim == 2 {
        m[0][0] * m[1][1] - m[0][1] * m[1][0]
    } else {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }
}

/// ∛x for x > 0, to within an ulp: FreeBSD's and musl's `cbrt` (a 5-bit
/// estimate from the exponent, a polynomial to 23 bits, one Halley step).
/// Zero, subnormal, infinite and NaN inputs go to `f64::cbrt`. The lanes
/// of [`cbrt_positive_lanes`] are tested against it.
#[cfg(test)]
pub fn cbrt_positive(x: f64) -> f64 {
    if !cbrt_in_range(x) {
        return x.cbrt();
    }
    cbrt_normal(x)
}

/// [`cbrt_positive`] of every lane: the same bits, with no branch for the
/// lanes of the normal range, so that the compiler runs them in vector
/// registers. The optimisation's energy takes one per sample point, and
/// Rust's `f64::cbrt`, correctly rounded, cost it a tenth of its time.
#[inline(always)]
pub fn cbrt_positive_lanes<const L: usize>(x: &[f64; L]) -> [f64; L] {
    let mut t = [0.0; L];
    for l in 0..L {
        t[l] = cbrt_normal(x[l]);
    }
    if x.iter().all(|&x| cbrt_in_range(x)) {
        t
    } else {
        cbrt_out_of_range(x, t)
    }
}

/// [`cbrt_positive_lanes`] when a lane is out of the normal range: apart
/// (and cold), so that the compiler does not move the roots of the normal
/// lanes behind a branch per lane.
#[cold]
#[inline(never)]
fn cbrt_out_of_range<const L: usize>(x: &[f64; L], mut t: [f64; L]) -> [f64; L] {
    for l in 0..L {
        if !cbrt_in_range(x[l]) {
            t[l] = x[l].cbrt();
        }
    }
    t
}

/// Whether x is in the normal positive range where [`cbrt_normal`] holds.
#[inline(always)]
fn cbrt_in_range(x: f64) -> bool {
    (f64::MIN_POSITIVE..f64::INFINITY).contains(&x)
}

/// The root of [`cbrt_positive`] for x in [`cbrt_in_range`] (any bits elsewhere).
#[inline(always)]
#[allow(clippy::excessive_precision)] // musl's constants, as written there
fn cbrt_normal(x: f64) -> f64 {
    const B1: u32 = 715_094_163;
    const P0: f64 = 1.87595182427177009643;
    const P1: f64 = -1.88497979543377169875;
    const P2: f64 = 1.621429720105354466140;
    const P3: f64 = -0.758397934778766047437;
    const P4: f64 = 0.145996192886612446982;
    // Exponent / 3 in the high word: |t - ∛x| < 3.2 % of ∛x. The high word
    // fits in 32 bits, where a division by 3 runs in vector registers.
    let hx = (x.to_bits() >> 32) as u32;
    let mut t = f64::from_bits(((hx / 3).wrapping_add(B1) as u64) << 32);
    // To 23 bits, by a polynomial in r = t³/x.
    let r = (t * t) * (t / x);
    t *= (P0 + r * (P1 + r * P2)) + ((r * r) * r) * (P3 + r * P4);
    // Rounded to 21 bits, so that t² is exact, then one Halley step.
    t = f64::from_bits((t.to_bits() + 0x8000_0000) & 0xffff_ffff_c000_0000);
    let r = x / (t * t);
    t + t * ((r - t) / (t + t + r))
}

/// Cofactor matrix of the leading block: cof(M) = det(M) M⁻ᵀ (defined for any M).
#[inline]
pub fn cofactor(dim: usize, m: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    if dim == 2 {
        c[0][0] = m[1][1];
        c[0][1] = -m[1][0];
        c[1][0] = -m[0][1];
        c[1][1] = m[0][0];
    } else {
        for i in 0..3 {
            for j in 0..3 {
                let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
                let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
                c[i][j] = m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1];
            }
        }
    }
    c
}

/// Inverse and determinant of the leading block. The inverse is meaningless
/// when the determinant is zero; callers check it.
#[inline]
pub fn inverse(dim: usize, m: &Mat3) -> (Mat3, f64) {
    let d = det(dim, m);
    let c = cofactor(dim, m);
    let mut inv = [[0.0; 3]; 3];
    for i in 0..dim {
        for j in 0..dim {
            inv[i][j] = c[j][i] / d;
        }
    }
    (inv, d)
}

/// Product of the leading blocks.
#[inline]
pub fn matmul(dim: usize, a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..dim {
        for j in 0..dim {
            c[i][j] = (0..dim).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// aᵀb (the shorter length) in four partial sums, element k in sum k mod 4,
/// added as (s0 + s1) + (s2 + s3) after them: the four chains run side by
/// side, where one sum in order waits on each add before the next.
#[inline]
pub fn dot4(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut s = [0.0; 4];
    for (a, b) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        for k in 0..4 {
            s[k] += a[k] * b[k];
        }
    }
    let tail = n - n % 4;
    for (k, (a, b)) in a[tail..].iter().zip(&b[tail..]).enumerate() {
        s[k] += a * b;
    }
    (s[0] + s[1]) + (s[2] + s[3])
}

/// `f()`, compiled for AVX2 and FMA when the processor has them (four
/// doubles per vector instruction instead of the two of plain x86-64, for
/// which the library is built). `f`, which must be a closure marked
/// `#[inline(always)]`, is inlined into a copy of this function built for
/// them, with what it inlines (mark its helpers `#[inline(always)]` too).
/// The copy does the same operations in the same order, and the compiler
/// never fuses a product and a sum by itself; where `f` asks for a fused
/// multiply-add (`mul_add`, rounded once), the copy has one instruction
/// and the plain build a library call, slower but rounded the same. So the
/// results are the same on every processor.
#[inline(always)]
pub fn with_avx2<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        #[target_feature(enable = "avx2,fma")]
        #[inline]
        unsafe fn copy<R>(f: impl FnOnce() -> R) -> R {
            f()
        }
        // SAFETY: the processor supports AVX2 (checked just above).
        return unsafe { copy(f) };
    }
    f()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot4_is_the_dot_product_in_four_partial_sums() {
        // Integers: every order of the sums is exact, so dot4 must equal the
        // plain sum at every length, tails of 0 to 3 included.
        for n in 0..13 {
            let a: Vec<f64> = (0..n).map(|i| (i * 7 % 5) as f64 - 2.0).collect();
            let b: Vec<f64> = (0..n + 2).map(|i| (i * 3 % 11) as f64).collect();
            let want: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
            assert_eq!(dot4(&a, &b), want, "n = {n}");
        }
        // Element 4 goes to the first sum, where it cancels element 0 before
        // the ones are added: 3, where the sum in order loses them to 1e16.
        let a = [1e16, 1.0, 1.0, 1.0, -1e16];
        assert_eq!(dot4(&a, &[1.0; 5]), 3.0);
        assert_eq!(a.iter().sum::<f64>(), 0.0);
    }

    #[test]
    fn cbrt_positive_is_within_an_ulp_of_the_correctly_rounded_root() {
        // Every binade of the normal range, at irregular points in each, and
        // exact cubes; the rest goes to f64::cbrt.
        let ulp = |y: f64| f64::from_bits(y.to_bits() + 1) - y;
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        for e in -1022..1024 {
            for _ in 0..64 {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let x = (1.0 + (s >> 11) as f64 / (1u64 << 53) as f64) * 2f64.powi(e);
                let (y, exact) = (cbrt_positive(x), x.cbrt());
                assert!((y - exact).abs() <= ulp(exact), "cbrt({x:e}) = {y:e}, not {exact:e}");
            }
        }
        for k in 1..2000 {
            let c = (k as f64).powi(3);
            assert_eq!(cbrt_positive(c), k as f64);
        }
        for x in [0.0, 1e-310, f64::INFINITY] {
            assert_eq!(cbrt_positive(x), x.cbrt());
        }
        assert!(cbrt_positive(f64::NAN).is_nan());
    }

    #[test]
    fn cbrt_lanes_are_bitwise_the_scalar_root_in_and_out_of_the_normal_range() {
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut xs: Vec<f64> = (-1022..1024)
            .map(|e| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (1.0 + (s >> 11) as f64 / (1u64 << 53) as f64) * 2f64.powi(e)
            })
            .collect();
        xs.extend([0.0, -0.0, 1e-310, -8.0, f64::INFINITY, f64::NAN, 27.0, f64::MIN_POSITIVE]);
        for chunk in xs.chunks(4) {
            let mut x = [1.0; 4];
            x[..chunk.len()].copy_from_slice(chunk);
            let lanes = cbrt_positive_lanes(&x);
            for (&v, &y) in x.iter().zip(&lanes) {
                assert_eq!(y.to_bits(), cbrt_positive(v).to_bits(), "cbrt({v:e})");
            }
        }
    }

    #[test]
    fn inverse_times_matrix_is_identity_in_2d_and_3d() {
        let m: Mat3 = [[2.0, 0.3, -0.1], [0.2, 1.5, 0.4], [-0.3, 0.1, 1.1]];
        for dim in [2, 3] {
            let (inv, d) = inverse(dim, &m);
            assert!(d.abs() > 0.1);
            let id = matmul(dim, &m, &inv);
            for i in 0..dim {
                for j in 0..dim {
                    let e = if i == j { 1.0 } else { 0.0 };
                    assert!((id[i][j] - e).abs() < 1e-14, "{dim} {i} {j} {}", id[i][j]);
                }
            }
        }
    }

    #[test]
    fn cofactor_is_det_times_inverse_transpose() {
        let m: Mat3 = [[1.0, 2.0, 0.5], [0.0, 1.0, -1.0], [3.0, 0.2, 2.0]];
        let (inv, d) = inverse(3, &m);
        let c = cofactor(3, &m);
        for i in 0..3 {
            for j in 0..3 {
                assert!((c[i][j] - d * inv[j][i]).abs() < 1e-13);
            }
        }
    }
}
