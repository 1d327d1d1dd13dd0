//! Checks every model's unit tests share: σ against finite differences of Ψ,
//! c against finite differences of σ (spatial form of eq. (10)), c and σ at
//! F = I, symmetries and objectivity. Deterministic pseudo-random samples.

use super::tensor::{contract, delta, small_strain};
use super::{Material, Tangent};
use crate::linalg::{det, matmul, Mat3};

pub(crate) const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// The Poisson ratios every calibration test sweeps.
pub(crate) const POISSON_SWEEP: [f64; 6] = [0.0, 0.001, 0.2, 0.3, 0.45, 0.495];

pub(crate) use crate::testing::Rng;

/// A random F with J uniform in [0.5, 2]; plane strain keeps F = diag(F₂, 1).
pub(crate) fn random_f(rng: &mut Rng, plane: bool) -> Mat3 {
    loop {
        let mut f = IDENTITY;
        let n = if plane { 2 } else { 3 };
        for i in 0..n {
            for j in 0..n {
                f[i][j] += rng.range(-0.4, 0.4);
            }
        }
        let j = det(3, &f);
        if j < 0.2 {
            continue;
        }
        let target = rng.range(0.5, 2.0);
        let s = (target / j).powf(1.0 / n as f64);
        for row in f.iter_mut().take(n) {
            for x in row.iter_mut().take(n) {
                *x *= s;
            }
        }
        assert!((det(3, &f) - target).abs() < 1e-12);
        return f;
    }
}

/// A random unit vector (in the plane for plane strain).
pub(crate) fn random_unit(rng: &mut Rng, plane: bool) -> [f64; 3] {
    loop {
        let v = [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), if plane { 0.0 } else { rng.range(-1.0, 1.0) }];
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if n > 0.2 {
            return [v[0] / n, v[1] / n, v[2] / n];
        }
    }
}

/// A rotation by Rodrigues' formula about a random axis.
pub(crate) fn random_rotation(rng: &mut Rng) -> Mat3 {
    let k = random_unit(rng, false);
    let t = rng.range(0.3, 3.0);
    let (s, c) = t.sin_cos();
    let mut q = [[0.0; 3]; 3];
    let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
    for i in 0..3 {
        for j in 0..3 {
            q[i][j] = c * delta(i, j) + s * kx[i][j] + (1.0 - c) * k[i] * k[j];
        }
    }
    q
}

pub(crate) fn max_abs(m: &Mat3) -> f64 {
    m.iter().flatten().fold(0.0, |a, x| a.max(x.abs()))
}

pub(crate) fn max_abs_t(c: &Tangent) -> f64 {
    c.iter().flatten().flatten().flatten().fold(0.0, |a, x| a.max(x.abs()))
}

pub(crate) fn max_diff(a: &Mat3, b: &Mat3) -> f64 {
    let mut d: f64 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            d = d.max((a[i][j] - b[i][j]).abs());
        }
    }
    d
}

pub(crate) fn max_diff_t(a: &Tangent, b: &Tangent) -> f64 {
    let mut d: f64 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                for l in 0..3 {
                    d = d.max((a[i][j][k][l] - b[i][j][k][l]).abs());
                }
            }
        }
    }
    d
}

/// Five 3D and five plane-strain samples (F, N).
pub(crate) fn samples(seed: u64) -> Vec<(Mat3, [f64; 3])> {
    let mut rng = Rng::new(seed);
    [false, true]
        .into_iter()
        .flat_map(|plane| std::iter::repeat_n(plane, 5))
        .map(|plane| (random_f(&mut rng, plane), random_unit(&mut rng, plane)))
        .collect()
}

/// The model's stiffness scale: max |c(I)|.
fn scale(m: &dyn Material, n: &[f64; 3]) -> f64 {
    max_abs_t(&m.stress_and_tangent(&IDENTITY, n).1)
}

/// P = ∂Ψ/∂F by central differences.
pub(crate) fn fd_first_piola(m: &dyn Material, f: &Mat3, n: &[f64; 3], h: f64) -> Mat3 {
    let mut p = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let (mut fp, mut fm) = (*f, *f);
            fp[i][j] += h;
            fm[i][j] -= h;
            p[i][j] = (m.energy(&fp, n) - m.energy(&fm, n)) / (2.0 * h);
        }
    }
    p
}

/// σ = J⁻¹ P Fᵀ with P from central differences of Ψ (linear models: σ = P),
/// and `stress` agrees with `stress_and_tangent`.
pub(crate) fn assert_stress_matches_fd_of_energy(m: &dyn Material, seed: u64) {
    for (f, n) in samples(seed) {
        let p = fd_first_piola(m, &f, &n, 1e-6);
        let expected = if m.is_linear() {
            p
        } else {
            let j = det(3, &f);
            let mut s = [[0.0; 3]; 3];
            for a in 0..3 {
                for b in 0..3 {
                    s[a][b] = (0..3).map(|k| p[a][k] * f[b][k]).sum::<f64>() / j;
                }
            }
            s
        };
        let sigma = m.stress(&f, &n);
        let tol = 1e-6 * max_abs(&sigma).max(scale(m, &n));
        let d = max_diff(&sigma, &expected);
        assert!(
            d < tol,
            "{}: σ differs from the FD of Ψ by {d:e} (tol {tol:e}) at F = {f:?}, N = {n:?}\nσ = {sigma:?}\nfd = {expected:?}",
            m.name()
        );
        let d = max_diff(&sigma, &m.stress_and_tangent(&f, &n).0);
        assert!(d <= 1e-13 * max_abs(&sigma).max(1.0), "{}", m.name());
    }
}

/// Hyperelastic models: J c : sym(L) = d/dh τ(F + hLF) − Lτ − τLᵀ (Oldroyd rate
/// of τ = Jσ) for random L (plane strain: 2×2 block only).
/// Linear models: c : sym(G) = d/dh σ(I + hG) at F = I.
pub(crate) fn assert_tangent_matches_fd_of_stress(m: &dyn Material, seed: u64) {
    let mut rng = Rng::new(seed ^ 0xABCD);
    let h = 1e-6;
    for (k, (f, n)) in samples(seed).into_iter().enumerate() {
        let plane = k >= 5;
        let nd = if plane { 2 } else { 3 };
        let mut l = [[0.0; 3]; 3];
        for row in l.iter_mut().take(nd) {
            for x in row.iter_mut().take(nd) {
                *x = rng.range(-1.0, 1.0);
            }
        }
        let f = if m.is_linear() { IDENTITY } else { f };
        let (sigma, c) = m.stress_and_tangent(&f, &n);
        let j = det(3, &f);
        let mut d = [[0.0; 3]; 3];
        for a in 0..3 {
            for b in 0..3 {
                d[a][b] = 0.5 * (l[a][b] + l[b][a]);
            }
        }
        let cd = contract(&c, &d);
        let (lhs, rhs) = if m.is_linear() {
            let (mut fp, mut fm) = (f, f);
            for a in 0..3 {
                for b in 0..3 {
                    fp[a][b] += h * l[a][b];
                    fm[a][b] -= h * l[a][b];
                }
            }
            let (sp, sm) = (m.stress(&fp, &n), m.stress(&fm, &n));
            let mut r = [[0.0; 3]; 3];
            for a in 0..3 {
                for b in 0..3 {
                    r[a][b] = (sp[a][b] - sm[a][b]) / (2.0 * h);
                }
            }
            (cd, r)
        } else {
            let lf = matmul(3, &l, &f);
            let tau = |g: &Mat3| -> Mat3 {
                let s = m.stress(g, &n);
                let jg = det(3, g);
                s.map(|row| row.map(|x| jg * x))
            };
            let (mut fp, mut fm) = (f, f);
            for a in 0..3 {
                for b in 0..3 {
                    fp[a][b] += h * lf[a][b];
                    fm[a][b] -= h * lf[a][b];
                }
            }
            let (tp, tm) = (tau(&fp), tau(&fm));
            let t0 = sigma.map(|row| row.map(|x| j * x));
            let lt = matmul(3, &l, &t0);
            let mut r = [[0.0; 3]; 3];
            for a in 0..3 {
                for b in 0..3 {
                    r[a][b] = (tp[a][b] - tm[a][b]) / (2.0 * h) - lt[a][b] - lt[b][a];
                }
            }
            (cd.map(|row| row.map(|x| j * x)), r)
        };
        let tol = 1e-6 * j.max(1.0) * max_abs_t(&c).max(scale(m, &n)) * max_abs(&l);
        let diff = max_diff(&lhs, &rhs);
        assert!(
            diff < tol,
            "{}: tangent differs from the FD of σ by {diff:e} (tol {tol:e}) at F = {f:?}, N = {n:?}\nJc:d = {lhs:?}\nfd = {rhs:?}",
            m.name()
        );
    }
}

/// σ(I) = 0 and c(I) = `expected` to 1e-10 relative.
pub(crate) fn assert_tangent_at_identity(m: &dyn Material, n: &[f64; 3], expected: &Tangent) {
    let (sigma, c) = m.stress_and_tangent(&IDENTITY, n);
    let s = max_abs_t(expected);
    assert!(max_abs(&sigma) <= 1e-12 * s, "{}: σ(I) = {sigma:?}", m.name());
    let d = max_diff_t(&c, expected);
    assert!(d <= 1e-10 * s, "{}: c(I) differs from the linear tensor by {d:e} (scale {s:e})", m.name());
}

/// σ symmetric, c minor-symmetric and (if `major`) major-symmetric.
pub(crate) fn assert_symmetries(m: &dyn Material, major: bool, seed: u64) {
    let mut all = samples(seed);
    all.push((IDENTITY, [0.0, 0.6, 0.8]));
    for (f, n) in all {
        let (sigma, c) = m.stress_and_tangent(&f, &n);
        let tol = 1e-12 * max_abs_t(&c).max(max_abs(&sigma));
        for i in 0..3 {
            for j in 0..3 {
                assert!((sigma[i][j] - sigma[j][i]).abs() <= tol, "{} σ", m.name());
                for k in 0..3 {
                    for l in 0..3 {
                        let x = c[i][j][k][l];
                        assert!((x - c[j][i][k][l]).abs() <= tol, "{} minor ij", m.name());
                        assert!((x - c[i][j][l][k]).abs() <= tol, "{} minor kl", m.name());
                        if major {
                            assert!((x - c[k][l][i][j]).abs() <= tol, "{} major", m.name());
                        }
                    }
                }
            }
        }
    }
}

/// Ψ(QF) = Ψ(F), σ(QF) = Q σ(F) Qᵀ and c(QF) = Q⊛Q⊛Q⊛Q c(F) for rotations Q.
pub(crate) fn assert_objective(m: &dyn Material, seed: u64) {
    let mut rng = Rng::new(seed ^ 0x5151);
    for (f, n) in samples(seed) {
        let q = random_rotation(&mut rng);
        let qf = matmul(3, &q, &f);
        let (s0, c0) = m.stress_and_tangent(&f, &n);
        let (s1, c1) = m.stress_and_tangent(&qf, &n);
        let (e0, e1) = (m.energy(&f, &n), m.energy(&qf, &n));
        let sc = scale(m, &n);
        assert!((e0 - e1).abs() <= 1e-12 * sc, "{} Ψ", m.name());
        let mut rs = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                for p in 0..3 {
                    for r in 0..3 {
                        rs[i][j] += q[i][p] * q[j][r] * s0[p][r];
                    }
                }
            }
        }
        assert!(max_diff(&rs, &s1) <= 1e-11 * sc.max(max_abs(&s0)), "{} σ not objective", m.name());
        // c rotated one index at a time.
        let mut t = c0;
        for slot in 0..4 {
            let mut u = [[[[0.0; 3]; 3]; 3]; 3];
            for i in 0..3 {
                for j in 0..3 {
                    for k in 0..3 {
                        for l in 0..3 {
                            let mut idx = [i, j, k, l];
                            let mut acc = 0.0;
                            let out = idx[slot];
                            for p in 0..3 {
                                idx[slot] = p;
                                acc += q[out][p] * t[idx[0]][idx[1]][idx[2]][idx[3]];
                            }
                            u[i][j][k][l] = acc;
                        }
                    }
                }
            }
            t = u;
        }
        assert!(max_diff_t(&t, &c1) <= 1e-11 * sc.max(max_abs_t(&c0)), "{} c not objective", m.name());
    }
}

/// Linear models are not objective: a finite rotation produces stress.
pub(crate) fn assert_rotation_stresses_linear_model(m: &dyn Material) {
    let mut rng = Rng::new(7);
    let q = random_rotation(&mut rng);
    let s = m.stress(&q, &[1.0, 0.0, 0.0]);
    assert!(max_abs(&s) > 1e-3 * scale(m, &[1.0, 0.0, 0.0]));
    // …but σ = c:ε exactly.
    let (_, c) = m.stress_and_tangent(&q, &[1.0, 0.0, 0.0]);
    assert!(max_diff(&s, &contract(&c, &small_strain(&q))) <= 1e-13 * max_abs_t(&c));
}
