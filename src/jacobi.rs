//! Gauss–Jacobi and Gauss–Lobatto–Legendre rules on [−1, 1]: the 1D points
//! that the reference nodes (edges at Gauss–Lobatto points) and the simplex
//! quadrature rules (collapsed Gauss–Jacobi products) are built from.
//!
//! The nodes of the n-point Gauss–Jacobi rule for the weight
//! w(x) = (1 − x)^α (1 + x)^β are the zeros of the Jacobi polynomial
//! P_n^{(α,β)}, i.e. the eigenvalues of the symmetric tridiagonal Jacobi
//! matrix J (Golub & Welsch 1969). They are found here by Sturm-sequence
//! bisection on J, polished by Newton's method on the three-term recurrence,
//! and the weights come from the Christoffel function
//! w_i = 1 / Σ_{k<n} p̂_k(x_i)², with p̂_k the orthonormal Jacobi polynomials.

use std::f64::consts::PI;

/// Gamma function Γ(x) for x > 0.
///
/// Exact products for integers and half-integers (the only arguments the
/// collapsed simplex rules use); Lanczos' approximation (g = 7, 9 terms,
/// relative error ~1e-15) otherwise.
pub(crate) fn gamma(x: f64) -> f64 {
    assert!(x > 0.0, "gamma: argument must be positive, got {x}");
    let twice = 2.0 * x;
    if x <= 170.0 && twice == twice.round() {
        // Γ(n) = (n−1)!, Γ(n + 1/2) = √π · Π_{k=0}^{n−1} (k + 1/2).
        let (mut g, mut t) = if x == x.round() { (1.0, 1.0) } else { (PI.sqrt(), 0.5) };
        while t < x - 0.25 {
            g *= t;
            t += 1.0;
        }
        return g;
    }
    if x < 0.5 {
        return PI / ((PI * x).sin() * gamma(1.0 - x));
    }
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, &c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    (2.0 * PI).sqrt() * t.powf(x + 0.5) * (-t).exp() * a
}

/// Recurrence coefficients (a_k, b_k) of the orthonormal Jacobi polynomials:
/// x p̂_k = b_{k+1} p̂_{k+1} + a_k p̂_k + b_k p̂_{k−1}, with
/// a_k = (β² − α²) / ((2k+α+β)(2k+α+β+2)) and
/// b_k² = 4k(k+α)(k+β)(k+α+β) / ((2k+α+β)² (2k+α+β+1)(2k+α+β−1)).
/// b_0 is returned as 0.
fn jacobi_recurrence(k: usize, alpha: f64, beta: f64) -> (f64, f64) {
    let kf = k as f64;
    let s = 2.0 * kf + alpha + beta;
    let a =
        if k == 0 { (beta - alpha) / (alpha + beta + 2.0) } else { (beta * beta - alpha * alpha) / (s * (s + 2.0)) };
    let b = match k {
        0 => 0.0,
        // the factor (k + α + β) / (2k + α + β − 1) is 1 at k = 1.
        1 => (4.0 * (1.0 + alpha) * (1.0 + beta) / ((s * s) * (s + 1.0))).sqrt(),
        _ => (4.0 * kf * (kf + alpha) * (kf + beta) * (kf + alpha + beta) / (s * s * (s + 1.0) * (s - 1.0))).sqrt(),
    };
    (a, b)
}

/// Total mass μ_0 = ∫_{−1}^{1} (1−x)^α (1+x)^β dx = 2^{α+β+1} Γ(α+1) Γ(β+1) / Γ(α+β+2).
fn jacobi_mass(alpha: f64, beta: f64) -> f64 {
    2f64.powf(alpha + beta + 1.0) * gamma(alpha + 1.0) * gamma(beta + 1.0) / gamma(alpha + beta + 2.0)
}

/// Number of eigenvalues of the Jacobi matrix (diagonal `a`, off-diagonal
/// `b[1..]`) strictly below `x`, by the Sturm sequence of LDLᵀ pivots.
fn sturm_count(a: &[f64], b: &[f64], x: f64) -> usize {
    let mut count = 0;
    let mut q = 1.0;
    for i in 0..a.len() {
        q = if i == 0 { a[0] - x } else { a[i] - x - b[i] * b[i] / q };
        if q == 0.0 {
            q = -f64::EPSILON * (1.0 + x.abs());
        }
        if q < 0.0 {
            count += 1;
        }
    }
    count
}

/// Values p̂_0(x) .. p̂_{n}(x) of the orthonormal Jacobi polynomials and the
/// derivative p̂_n'(x), by the three-term recurrence.
fn orthonormal_values(x: f64, n: usize, a: &[f64], b: &[f64], p0: f64, out: &mut [f64]) -> f64 {
    let (mut pm, mut p) = (0.0, p0);
    let (mut dpm, mut dp) = (0.0, 0.0);
    out[0] = p0;
    for k in 0..n {
        let pn = ((x - a[k]) * p - b[k] * pm) / b[k + 1];
        let dpn = (p + (x - a[k]) * dp - b[k] * dpm) / b[k + 1];
        pm = p;
        p = pn;
        dpm = dp;
        dp = dpn;
        out[k + 1] = p;
    }
    dp
}

/// Gauss–Jacobi rule with `n` points on [−1, 1] for the weight
/// (1 − x)^α (1 + x)^β (α, β > −1): exact for polynomials of degree ≤ 2n − 1,
///
/// ∫_{−1}^{1} (1−x)^α (1+x)^β f(x) dx ≈ Σ_i w_i f(x_i).
///
/// Points are returned in ascending order; the weights sum to
/// 2^{α+β+1} Γ(α+1) Γ(β+1) / Γ(α+β+2). For α = β the rule is made exactly
/// symmetric (x_{n−1−i} = −x_i bit for bit).
///
/// ```
/// let (x, w) = hocurve::quadrature::gauss_jacobi(2, 0.0, 0.0);
/// assert!((x[1] - 1.0 / 3f64.sqrt()).abs() < 1e-15 && (w[0] - 1.0).abs() < 1e-15);
/// ```
pub fn gauss_jacobi(n: usize, alpha: f64, beta: f64) -> (Vec<f64>, Vec<f64>) {
    assert!(alpha > -1.0 && beta > -1.0, "gauss_jacobi: need α, β > −1");
    if n == 0 {
        return (Vec::new(), Vec::new());
    }
    let mut a = Vec::with_capacity(n + 1);
    let mut b = Vec::with_capacity(n + 1);
    for k in 0..=n {
        let (ak, bk) = jacobi_recurrence(k, alpha, beta);
        a.push(ak);
        b.push(bk);
    }
    let p0 = 1.0 / jacobi_mass(alpha, beta).sqrt();
    let mut vals = vec![0.0; n + 1];
    let mut x = Vec::with_capacity(n);
    let mut w = Vec::with_capacity(n);
    for i in 0..n {
        // i-th smallest eigenvalue: the smallest y with count(y) ≥ i + 1.
        let (mut lo, mut hi) = (-1.0f64, 1.0f64);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if sturm_count(&a[..n], &b[..n], mid) > i {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let mut xi = 0.5 * (lo + hi);
        // Newton polish on p̂_n.
        for _ in 0..3 {
            let dp = orthonormal_values(xi, n, &a, &b, p0, &mut vals);
            if dp != 0.0 {
                let step = vals[n] / dp;
                if step.is_finite() && step.abs() < 1e-6 {
                    xi -= step;
                }
            }
        }
        orthonormal_values(xi, n, &a, &b, p0, &mut vals);
        let christoffel: f64 = vals[..n].iter().map(|v| v * v).sum();
        x.push(xi);
        w.push(1.0 / christoffel);
    }
    if alpha == beta {
        for i in 0..n / 2 {
            let j = n - 1 - i;
            let xs = 0.5 * (x[j] - x[i]);
            let ws = 0.5 * (w[i] + w[j]);
            x[i] = -xs;
            x[j] = xs;
            w[i] = ws;
            w[j] = ws;
        }
        if n % 2 == 1 {
            x[n / 2] = 0.0;
        }
    }
    (x, w)
}

/// Gauss–Lobatto–Legendre points on [−1, 1]: the `n` ≥ 2 points ±1 and the
/// zeros of P'_{n−1} (= the Gauss–Jacobi points of P_{n−2}^{(1,1)}), ascending,
/// exactly symmetric.
///
/// ```
/// let x = hocurve::quadrature::gauss_lobatto_legendre(3);
/// assert_eq!(x, vec![-1.0, 0.0, 1.0]);
/// ```
pub fn gauss_lobatto_legendre(n: usize) -> Vec<f64> {
    assert!(n >= 2, "gauss_lobatto_legendre: need n ≥ 2 points");
    let mut x = Vec::with_capacity(n);
    x.push(-1.0);
    x.extend(gauss_jacobi(n - 2, 1.0, 1.0).0);
    x.push(1.0);
    x
}

/// Gauss–Lobatto–Legendre weights for the points of [`gauss_lobatto_legendre`]:
/// w_i = 2 / (n(n−1) P_{n−1}(x_i)²); exact for degree ≤ 2n − 3.
pub fn gauss_lobatto_legendre_weights(n: usize) -> Vec<f64> {
    let x = gauss_lobatto_legendre(n);
    let m = n - 1;
    x.iter()
        .map(|&xi| {
            let (mut pm, mut p) = (1.0, xi);
            for k in 1..m {
                let kf = k as f64;
                let pn = ((2.0 * kf + 1.0) * xi * p - kf * pm) / (kf + 1.0);
                pm = p;
                p = pn;
            }
            if m == 0 {
                p = 1.0;
            }
            2.0 / ((n * m) as f64 * p * p)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫_{−1}^{1} (1−x)^α (1+x)^β (1+x)^k dx = 2^{α+β+k+1} B(α+1, β+k+1).
    fn exact_shifted_moment(alpha: f64, beta: f64, k: usize) -> f64 {
        let bk = beta + k as f64;
        2f64.powf(alpha + bk + 1.0) * gamma(alpha + 1.0) * gamma(bk + 1.0) / gamma(alpha + bk + 2.0)
    }

    #[test]
    fn gamma_matches_factorials_and_half_integers() {
        assert_eq!(gamma(1.0), 1.0);
        assert_eq!(gamma(6.0), 120.0);
        assert!((gamma(0.5) - PI.sqrt()).abs() < 1e-15);
        assert!((gamma(2.5) - 0.75 * PI.sqrt()).abs() < 1e-15);
        // Lanczos branch, Γ(1.3) = 0.8974706963062772...
        assert!((gamma(1.3) - 0.897_470_696_306_277_2).abs() < 1e-14);
    }

    #[test]
    fn gauss_jacobi_exact_to_degree_2n_minus_1() {
        for &(alpha, beta) in &[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (1.0, 1.0), (0.5, 1.5)] {
            for n in 1..=12 {
                let (x, w) = gauss_jacobi(n, alpha, beta);
                assert_eq!(x.len(), n);
                assert!(w.iter().all(|&wi| wi > 0.0));
                assert!(x.windows(2).all(|p| p[0] < p[1]));
                assert!(x.iter().all(|&xi| xi > -1.0 && xi < 1.0));
                for k in 0..2 * n {
                    let q: f64 = x.iter().zip(&w).map(|(xi, wi)| wi * (1.0 + xi).powi(k as i32)).sum();
                    let e = exact_shifted_moment(alpha, beta, k);
                    assert!((q - e).abs() <= 1e-13 * e, "α={alpha} β={beta} n={n} k={k}: {q} vs {e}");
                }
            }
        }
    }

    #[test]
    fn gauss_legendre_two_points_are_plus_minus_one_over_sqrt3() {
        let (x, w) = gauss_jacobi(2, 0.0, 0.0);
        assert!((x[1] - 1.0 / 3f64.sqrt()).abs() < 3e-16);
        assert_eq!(x[0], -x[1]);
        assert!((w[0] - 1.0).abs() < 1e-15 && (w[1] - 1.0).abs() < 1e-15);
    }

    #[test]
    fn gauss_lobatto_legendre_exact_to_degree_2n_minus_3() {
        for n in 2..=16 {
            let x = gauss_lobatto_legendre(n);
            let w = gauss_lobatto_legendre_weights(n);
            assert_eq!(x.len(), n);
            assert_eq!((x[0], x[n - 1]), (-1.0, 1.0));
            assert!(x.windows(2).all(|p| p[0] < p[1]));
            for i in 0..n {
                assert_eq!(x[i], -x[n - 1 - i]);
            }
            for k in 0..=(2 * n - 3) {
                let q: f64 = x.iter().zip(&w).map(|(xi, wi)| wi * xi.powi(k as i32)).sum();
                let e = if k % 2 == 1 { 0.0 } else { 2.0 / (k + 1) as f64 };
                assert!((q - e).abs() < 1e-13, "n={n} k={k}: {q} vs {e}");
            }
        }
    }

    #[test]
    fn gauss_lobatto_legendre_four_points_are_known() {
        let x = gauss_lobatto_legendre(4);
        let s = 1.0 / 5f64.sqrt();
        assert!((x[1] + s).abs() < 3e-16 && (x[2] - s).abs() < 3e-16);
    }
}
