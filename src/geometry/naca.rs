//! NACA 4-digit aerofoils with a closed trailing edge: evaluation and
//! closest points.
//!
//! For the code `MPTT`, with m = M/100, p = P/10, t = TT/100 and ξ = x/chord,
//! the half thickness is (closed trailing edge coefficient −0.1036)
//!
//! y_t(ξ) = 5t (0.2969 √ξ − 0.1260 ξ − 0.3516 ξ² + 0.2843 ξ³ − 0.1036 ξ⁴),
//!
//! the camber line y_c = m/p² (2pξ − ξ²) for ξ < p and
//! y_c = m/(1−p)² ((1−2p) + 2pξ − ξ²) for ξ ≥ p, θ = atan(dy_c/dξ), and the
//! surfaces are x = ξ ∓ y_t sin θ, y = y_c ± y_t cos θ (upper/lower).
//!
//! The whole closed curve is parametrised by q ∈ [−1, 1] with ξ = q² and the
//! signed half thickness Y(q) = sign(q) y_t(q²): q = −1 is the trailing edge
//! on the lower surface, q = 0 the leading edge, q = 1 the trailing edge on
//! the upper surface. Since √ξ = |q|, Y is a polynomial on each side of the
//! leading edge and the curve c(q) = origin + chord (ξ − Y sin θ, y_c + Y cos θ)
//! is smooth there, which resolves the leading edge without special cases.

use crate::{Error, Result};

/// Thickness coefficients a0..a4 (closed trailing edge).
const A: [f64; 5] = [0.2969, -0.1260, -0.3516, 0.2843, -0.1036];

/// A NACA 4-digit aerofoil placed in the plane: leading edge at `origin`,
/// chord along +x.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Naca4 {
    /// Maximum camber as a fraction of the chord.
    pub m: f64,
    /// Chordwise position of the maximum camber, fraction of the chord.
    pub p: f64,
    /// Maximum thickness as a fraction of the chord.
    pub t: f64,
    /// Chord length.
    pub chord: f64,
    /// Leading edge position.
    pub origin: [f64; 2],
}

/// A point of the curve with its first and second parameter derivatives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurvePoint {
    /// c(q).
    pub x: [f64; 2],
    /// c′(q).
    pub d1: [f64; 2],
    /// c″(q).
    pub d2: [f64; 2],
}

impl Naca4 {
    /// The aerofoil of code `digits` (e.g. `[2, 4, 1, 2]` for NACA 2412).
    /// Errors on zero thickness, on camber without a camber position
    /// (`M > 0, P = 0`), on a non-positive or non-finite chord.
    pub fn from_digits(digits: [u8; 4], chord: f64, origin: [f64; 2]) -> Result<Self> {
        if digits.iter().any(|&d| d > 9) {
            return Err(Error::InvalidInput(format!("NACA digits must be 0..9, got {digits:?}")));
        }
        let m = f64::from(digits[0]) / 100.0;
        let p = f64::from(digits[1]) / 10.0;
        let t = f64::from(10 * digits[2] + digits[3]) / 100.0;
        if t <= 0.0 {
            return Err(Error::InvalidInput("NACA thickness (last two digits) must be positive".into()));
        }
        if m > 0.0 && p == 0.0 {
            return Err(Error::InvalidInput(
                "a cambered NACA section needs a camber position (second digit) > 0".into(),
            ));
        }
        if chord <= 0.0 || !chord.is_finite() || !origin.iter().all(|v| v.is_finite()) {
            return Err(Error::InvalidInput("the NACA chord must be positive and the origin finite".into()));
        }
        Ok(Naca4 { m, p, t, chord, origin })
    }

    /// Camber y_c, slope γ = dy_c/dξ and dγ/dξ at ξ (chord 1).
    fn camber(&self, xi: f64) -> (f64, f64, f64) {
        let (m, p) = (self.m, self.p);
        if m == 0.0 || p == 0.0 {
            return (0.0, 0.0, 0.0);
        }
        if xi < p {
            let k = m / (p * p);
            (k * (2.0 * p * xi - xi * xi), 2.0 * k * (p - xi), -2.0 * k)
        } else {
            let k = m / ((1.0 - p) * (1.0 - p));
            (k * ((1.0 - 2.0 * p) + 2.0 * p * xi - xi * xi), 2.0 * k * (p - xi), -2.0 * k)
        }
    }

    /// Signed half thickness Y(q) = sign(q) y_t(q²) and its q-derivatives
    /// (chord 1).
    fn thickness(&self, q: f64) -> (f64, f64, f64) {
        let s = if q < 0.0 { -1.0 } else { 1.0 };
        let k = 5.0 * self.t;
        let q2 = q * q;
        let poly = q2 * (A[1] + q2 * (A[2] + q2 * (A[3] + q2 * A[4])));
        let dpoly = q * (2.0 * A[1] + q2 * (4.0 * A[2] + q2 * (6.0 * A[3] + q2 * 8.0 * A[4])));
        let ddpoly = 2.0 * A[1] + q2 * (12.0 * A[2] + q2 * (30.0 * A[3] + q2 * 56.0 * A[4]));
        (k * (A[0] * q + s * poly), k * (A[0] + s * dpoly), k * s * ddpoly)
    }

    /// The curve c(q), q ∈ [−1, 1], with c′(q) and c″(q) (physical units).
    pub fn eval(&self, q: f64) -> CurvePoint {
        let xi = q * q;
        let (yc, g, dg) = self.camber(xi);
        let (y, dy, ddy) = self.thickness(q);
        let w = 1.0 + g * g;
        let cos = 1.0 / w.sqrt();
        let sin = g * cos;
        // θ(ξ(q)): θ_ξ = γ′/(1+γ²), θ_ξξ = −2γγ′²/(1+γ²)².
        let th_xi = dg / w;
        let th_xixi = -2.0 * g * dg * dg / (w * w);
        let th_q = th_xi * 2.0 * q;
        let th_qq = th_xixi * 4.0 * xi + th_xi * 2.0;
        let x = [xi - y * sin, yc + y * cos];
        let d1 = [2.0 * q - dy * sin - y * cos * th_q, g * 2.0 * q + dy * cos - y * sin * th_q];
        let d2 = [
            2.0 - ddy * sin - 2.0 * dy * cos * th_q + y * sin * th_q * th_q - y * cos * th_qq,
            dg * 4.0 * xi + 2.0 * g + ddy * cos - 2.0 * dy * sin * th_q - y * cos * th_q * th_q - y * sin * th_qq,
        ];
        let c = self.chord;
        CurvePoint {
            x: [self.origin[0] + c * x[0], self.origin[1] + c * x[1]],
            d1: [c * d1[0], c * d1[1]],
            d2: [c * d2[0], c * d2[1]],
        }
    }

    /// The curve point c(q).
    pub fn point(&self, q: f64) -> [f64; 2] {
        self.eval(q).x
    }

    /// Parameter q ∈ [−1, 1] of the closest curve point to `x`.
    ///
    /// Samples the squared distance g(q) = |x − c(q)|² at 256 intervals,
    /// refines every discrete local minimum inside its two neighbouring
    /// intervals (safeguarded Newton on g′/2 = −(x − c)·c′ where g′ changes
    /// sign, golden section otherwise, the interval ends included), and keeps
    /// the best. The trailing-edge corner (q = ±1) is a candidate like any other.
    pub fn closest_parameter(&self, x: [f64; 2]) -> f64 {
        const N: usize = 256;
        let q_at = |i: usize| -1.0 + 2.0 * i as f64 / N as f64;
        let g: Vec<f64> = (0..=N).map(|i| dist2(x, self.point(q_at(i)))).collect();
        let mut best = (f64::INFINITY, 0.0);
        for i in 0..=N {
            let left = if i > 0 { g[i - 1] } else { f64::INFINITY };
            let right = if i < N { g[i + 1] } else { f64::INFINITY };
            if g[i] <= left && g[i] <= right {
                let a = q_at(i.saturating_sub(1));
                let b = q_at((i + 1).min(N));
                let q = self.refine(x, a, b);
                let d = dist2(x, self.point(q));
                if d < best.0 {
                    best = (d, q);
                }
            }
        }
        best.1
    }

    /// Closest curve point to `x`.
    pub fn closest_point(&self, x: [f64; 2]) -> [f64; 2] {
        self.point(self.closest_parameter(x))
    }

    /// h(q) = −(x − c)·c′ = g′/2 and h′(q) = |c′|² − (x − c)·c″.
    fn h(&self, x: [f64; 2], q: f64) -> (f64, f64) {
        let e = self.eval(q);
        let r = [x[0] - e.x[0], x[1] - e.x[1]];
        (-(r[0] * e.d1[0] + r[1] * e.d1[1]), e.d1[0] * e.d1[0] + e.d1[1] * e.d1[1] - (r[0] * e.d2[0] + r[1] * e.d2[1]))
    }

    /// Minimiser of |x − c(q)|² on [a, b].
    fn refine(&self, x: [f64; 2], mut a: f64, mut b: f64) -> f64 {
        let (ha, _) = self.h(x, a);
        let (hb, _) = self.h(x, b);
        if ha < 0.0 && hb > 0.0 {
            // Safeguarded Newton on h with the bracket h(a) < 0 < h(b).
            let mut q = 0.5 * (a + b);
            for _ in 0..100 {
                let (hq, dh) = self.h(x, q);
                if hq == 0.0 {
                    return q;
                }
                if hq < 0.0 {
                    a = q;
                } else {
                    b = q;
                }
                let newton = q - hq / dh;
                let next = if dh > 0.0 && newton > a && newton < b { newton } else { 0.5 * (a + b) };
                if (next - q).abs() <= 2.0 * f64::EPSILON * q.abs().max(1e-3) || b - a <= 0.0 {
                    return next;
                }
                q = next;
            }
            return q;
        }
        // No sign change: golden section, then compare with the ends.
        let (lo, hi) = (a, b);
        let r = 0.5 * (5f64.sqrt() - 1.0);
        let mut c = b - r * (b - a);
        let mut d = a + r * (b - a);
        let mut gc = dist2(x, self.point(c));
        let mut gd = dist2(x, self.point(d));
        for _ in 0..80 {
            if gc < gd {
                b = d;
                d = c;
                gd = gc;
                c = b - r * (b - a);
                gc = dist2(x, self.point(c));
            } else {
                a = c;
                c = d;
                gc = gd;
                d = a + r * (b - a);
                gd = dist2(x, self.point(d));
            }
        }
        let mid = 0.5 * (a + b);
        [lo, hi, mid]
            .into_iter()
            .min_by(|&u, &v| dist2(x, self.point(u)).total_cmp(&dist2(x, self.point(v))))
            .unwrap_or(mid)
    }
}

fn dist2(a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (a[0] - b[0], a[1] - b[1]);
    dx * dx + dy * dy
}

#[cfg(test)]
mod tests {
    use super::*;

    fn foils() -> Vec<Naca4> {
        vec![
            Naca4::from_digits([0, 0, 1, 2], 1.0, [0.0, 0.0]).unwrap(),
            Naca4::from_digits([2, 4, 1, 2], 2.0, [-0.5, 0.25]).unwrap(),
            Naca4::from_digits([6, 3, 2, 1], 0.7, [0.1, 0.0]).unwrap(),
        ]
    }

    /// Deterministic points around the aerofoil, some inside, some close to
    /// the leading and trailing edges.
    fn probe_points(f: &Naca4) -> Vec<[f64; 2]> {
        let mut pts = Vec::new();
        let c = f.chord;
        let o = f.origin;
        for i in 0..23 {
            for j in 0..11 {
                let u = -0.3 + 1.6 * i as f64 / 22.0;
                let v = -0.3 + 0.6 * j as f64 / 10.0;
                pts.push([o[0] + c * u, o[1] + c * v]);
            }
        }
        for k in 0..40 {
            let a = std::f64::consts::PI * 2.0 * k as f64 / 40.0;
            for r in [1e-4, 1e-2] {
                pts.push([o[0] + c * r * a.cos(), o[1] + c * r * a.sin()]);
                pts.push([o[0] + c * (1.0 + r * a.cos()), o[1] + c * r * a.sin()]);
            }
        }
        pts
    }

    #[test]
    fn thickness_matches_the_naca_formula_and_closes_the_trailing_edge() {
        let f = Naca4::from_digits([0, 0, 1, 2], 1.0, [0.0, 0.0]).unwrap();
        for xi in [0.0, 0.01, 0.3, 0.7, 1.0] {
            let yt = 5.0
                * 0.12
                * (0.2969 * f64::sqrt(xi) - 0.1260 * xi - 0.3516 * xi * xi + 0.2843 * xi.powi(3) - 0.1036 * xi.powi(4));
            let up = f.point(xi.sqrt());
            let lo = f.point(-xi.sqrt());
            assert!((up[0] - xi).abs() < 1e-15 && (up[1] - yt).abs() < 1e-15);
            assert!((lo[0] - xi).abs() < 1e-15 && (lo[1] + yt).abs() < 1e-15);
        }
        // Maximum thickness 12% of the chord near ξ = 0.3.
        let tmax = (0..=1000).map(|i| 2.0 * f.point((i as f64 / 1000.0).sqrt())[1]).fold(0.0, f64::max);
        assert!((tmax - 0.12).abs() < 1e-3, "{tmax}");
        let (a, b) = (f.point(1.0), f.point(-1.0));
        assert!(dist2(a, b).sqrt() < 1e-15);
    }

    #[test]
    fn cambered_surfaces_follow_the_camber_line() {
        // NACA 2412: camber line y_c(0.4) = 0.02 at ξ = p.
        let f = Naca4::from_digits([2, 4, 1, 2], 1.0, [0.0, 0.0]).unwrap();
        let (yc, g, _) = f.camber(0.4);
        assert!((yc - 0.02).abs() < 1e-15 && g.abs() < 1e-15);
        // Mid-points of upper and lower surface at equal q lie on the camber line.
        let q = 0.4f64.sqrt();
        let (u, l) = (f.point(q), f.point(-q));
        assert!(((u[1] + l[1]) / 2.0 - 0.02).abs() < 1e-15);
    }

    #[test]
    fn derivatives_match_finite_differences() {
        for f in foils() {
            for q in [-0.95, -0.6, -0.2, -0.01, 0.013, 0.3, 0.63, 0.9] {
                let h = 1e-6;
                let (e, ep, em) = (f.eval(q), f.eval(q + h), f.eval(q - h));
                for k in 0..2 {
                    let d1 = (ep.x[k] - em.x[k]) / (2.0 * h);
                    let d2 = (ep.d1[k] - em.d1[k]) / (2.0 * h);
                    assert!((d1 - e.d1[k]).abs() < 1e-7 * f.chord, "{f:?} q={q} d1");
                    assert!((d2 - e.d2[k]).abs() < 1e-5 * f.chord, "{f:?} q={q} d2");
                }
            }
        }
    }

    #[test]
    fn closest_point_is_stationary_on_curve_and_beats_sampling() {
        for f in foils() {
            let dense: Vec<[f64; 2]> = (0..=200_000).map(|i| f.point(-1.0 + 2.0 * i as f64 / 200_000.0)).collect();
            for x in probe_points(&f) {
                let q = f.closest_parameter(x);
                assert!((-1.0..=1.0).contains(&q));
                let e = f.eval(q);
                let d = dist2(x, e.x).sqrt();
                // The found point is a curve point by construction; check
                // optimality: stationary (unless at the trailing-edge corner)...
                let r = [x[0] - e.x[0], x[1] - e.x[1]];
                let res = (r[0] * e.d1[0] + r[1] * e.d1[1]) / (e.d1[0].hypot(e.d1[1]));
                if q.abs() < 1.0 {
                    assert!(res.abs() <= 1e-12 * f.chord, "{f:?} {x:?} q={q} res={res}");
                }
                // ... and global: no dense sample is closer.
                let brute = dense.iter().map(|s| dist2(x, *s).sqrt()).fold(f64::INFINITY, f64::min);
                assert!(d <= brute + 1e-13 * f.chord, "{f:?} {x:?}: {d} > {brute}");
            }
        }
    }

    #[test]
    fn projection_is_idempotent_on_the_curve() {
        for f in foils() {
            for i in 0..=400 {
                let q = -1.0 + 2.0 * i as f64 / 400.0;
                let x = f.point(q);
                let y = f.closest_point(x);
                assert!(dist2(x, y).sqrt() <= 1e-14 * f.chord, "{f:?} q={q}: moved by {}", dist2(x, y).sqrt());
            }
        }
    }

    #[test]
    fn shape_naca4_projects_through_the_shape_api() {
        use crate::geometry::shapes::Shape;
        let s = Shape::parse("naca4:2412,2,-0.5,0.25").unwrap();
        let f = foils()[1];
        let y = s.closest_point([0.5, 0.6, 0.3]);
        let z = f.closest_point([0.5, 0.6]);
        assert_eq!(y, [z[0], z[1], 0.0]);
        assert!((s.distance([0.5, 0.6, 0.3]) - (dist2([0.5, 0.6], z) + 0.09).sqrt()).abs() < 1e-15);
        assert_eq!(s.entity_dim(), 1);
    }
}
