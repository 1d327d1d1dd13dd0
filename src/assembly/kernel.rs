//! Element kernels: values computed at the quadrature points of one element.

use crate::linalg;
use crate::mapping;
use crate::mapping::ElementCache;
use crate::material::LinearElastic;

/// Stiffness of isotropic linear elasticity on the element's current geometry:
/// K_(a i)(b j) = ∫ λ ∂_i N_a ∂_j N_b + μ ∂_j N_a ∂_i N_b + μ δ_ij ∇N_a·∇N_b dx
/// (paper eq. (13) with σ = 0 and c = c_lin; the ILE matrix of Table 1).
#[derive(Debug, Clone)]
pub struct LinearElasticKernel {
    pub cache: ElementCache,
    pub material: LinearElastic,
}

/// Scratch space of one thread. The dofs are padded to `ld`, a multiple of
/// [`TILE_ROWS`], with zeros that no product reads back.
pub struct KernelWorkspace {
    ld: usize,
    /// Aᵀ: per quadrature point, the physical gradients of the basis, dof
    /// (a, i) at a·dim + i (`ld` values a point).
    at: Vec<f64>,
    /// Aᵀ with each point's gradients times its weight and det J.
    awt: Vec<f64>,
    /// The Gram matrix Aw Aᵀ by columns (`ld` values each), dofs in K's
    /// order; its lower triangle is computed, and tiles across the diagonal.
    m: Vec<f64>,
}

/// Rows and columns of M computed together: 8 × 4 sums in registers.
const TILE_ROWS: usize = 8;
const TILE_COLS: usize = 4;

impl super::ElementKernel for LinearElasticKernel {
    type Workspace = KernelWorkspace;
    fn workspace(&self) -> KernelWorkspace {
        LinearElasticKernel::workspace(self)
    }
    fn linear_material(&self) -> Option<LinearElastic> {
        Some(self.material)
    }
    fn cell_kernel(&self) -> Option<&LinearElasticKernel> {
        Some(self)
    }
    /// The ILE operator has no internal force: `re` is zeroed.
    fn compute(
        &self,
        _cell: usize,
        xe: &[f64],
        ke: &mut [f64],
        re: Option<&mut [f64]>,
        ws: &mut KernelWorkspace,
    ) -> Result<(), f64> {
        if let Some(re) = re {
            re.fill(0.0);
        }
        self.stiffness_into(xe, ke, ws)
    }
}

impl LinearElasticKernel {
    /// The kernel of the elastic stage for the nodes `nodes`: every
    /// isotropic model is calibrated so that c(F = I) = c_lin, so this fast
    /// kernel serves them all, with a rule of degree 2p − 2, exact on
    /// straight-sided cells (∇N_a·∇N_b has degree 2p − 2 there): the
    /// symmetric rule has 24 points at p = 4 in 3D, against 46 for degree 2p
    /// and 64 for a collapsed rule of degree 2p − 2. Curved cells are
    /// integrated approximately by any rule.
    pub fn for_nodes(nodes: &crate::reference::NodeSet, material: LinearElastic) -> LinearElasticKernel {
        let basis = crate::reference::LagrangeBasis::new(nodes);
        let rule = crate::quadrature::simplex_rule(nodes.simplex, (2 * nodes.order).saturating_sub(2).max(1));
        LinearElasticKernel { cache: ElementCache::new(&basis, &rule), material }
    }

    pub fn workspace(&self) -> KernelWorkspace {
        let (n, d, nq) = (self.cache.n_basis, self.cache.dim, self.cache.n_points());
        let ld = (n * d).div_ceil(TILE_ROWS) * TILE_ROWS;
        KernelWorkspace { ld, at: vec![0.0; ld * nq], awt: vec![0.0; ld * nq], m: vec![0.0; ld * ld] }
    }

    /// Element stiffness into `ke` (row-major, dof (a, i) = a·dim + i) for the
    /// element with node coordinates `xe` (`dim` components per node).
    /// Returns `Err(det J)` if the Jacobian is not positive at a quadrature point.
    pub fn stiffness_into(&self, xe: &[f64], ke: &mut [f64], ws: &mut KernelWorkspace) -> Result<(), f64> {
        crate::linalg::with_avx2(
            #[inline(always)]
            || self.stiffness(xe, ke, ws),
        )
    }

    /// [`Self::stiffness_into`], inlined into each copy.
    #[inline(always)]
    fn stiffness(&self, xe: &[f64], ke: &mut [f64], ws: &mut KernelWorkspace) -> Result<(), f64> {
        let c = &self.cache;
        let (dim, ld, nq) = (c.dim, ws.ld, c.n_points());
        let nd = c.n_basis * dim;
        for q in 0..nq {
            let rg = c.grads_at(q);
            let jac = mapping::jacobian(dim, xe, rg);
            let (jinv, det) = linalg::inverse(dim, &jac);
            if det.is_nan() || det <= 0.0 {
                return Err(det);
            }
            let g = &mut ws.at[q * ld..q * ld + nd];
            mapping::physical_gradients_into(dim, rg, &jinv, g);
            let w = c.weights[q] * det;
            for (gw, &g) in ws.awt[q * ld..q * ld + nd].iter_mut().zip(&*g) {
                *gw = w * g;
            }
        }
        // M = Aw Aᵀ: M[(a i), (b j)] = ∫ ∂_i N_a ∂_j N_b, in the dof order of K.
        gram_lower(nd, nq, ld, &ws.awt, &ws.at, &mut ws.m);
        match dim {
            2 => self.stiffness_from_gram::<2>(ke, &ws.m, ld),
            _ => self.stiffness_from_gram::<3>(ke, &ws.m, ld),
        }
        Ok(())
    }

    /// K from the lower triangle of the Gram matrix M (columns of `ld`
    /// values), block (a, b) by block for a ≥ b: K_(a i)(b j) =
    /// λ M_(a i)(b j) + μ M_(a j)(b i) + μ δ_ij Σ_k M_(a k)(b k). Each block
    /// is written twice, in rows (b j), columns (a i), and, below the
    /// diagonal, transposed in rows (a i), columns (b j): runs of `D` values
    /// either way, so K is exactly symmetric without a strided pass over it.
    #[inline(always)]
    fn stiffness_from_gram<const D: usize>(&self, ke: &mut [f64], m: &[f64], ld: usize) {
        let (lam, mu) = (self.material.lambda, self.material.mu);
        let nd = ke.len().isqrt();
        // kb[j][i] = K_(a i)(b j) from mb[i][j] = M_(a i)(b j).
        let block = |mb: [[f64; D]; D]| -> [[f64; D]; D] {
            let lap = (0..D).fold(0.0, |s, k| s + mb[k][k]);
            std::array::from_fn(|j| {
                std::array::from_fn(|i| lam * mb[i][j] + mu * mb[j][i] + if i == j { mu * lap } else { 0.0 })
            })
        };
        for b in 0..nd / D {
            let cols: [&[f64]; D] = std::array::from_fn(|j| &m[(b * D + j) * ld..(b * D + j + 1) * ld]);
            // The diagonal block: its upper entries from the lower ones.
            let mb: [[f64; D]; D] =
                std::array::from_fn(|i| std::array::from_fn(|j| cols[i.min(j)][b * D + i.max(j)]));
            let kb = block(mb);
            for (j, kb) in kb.iter().enumerate() {
                ke[(b * D + j) * nd + b * D..][..D].copy_from_slice(kb);
            }
            for a in b + 1..nd / D {
                let mb: [[f64; D]; D] = std::array::from_fn(|i| std::array::from_fn(|j| cols[j][a * D + i]));
                let kb = block(mb);
                for (j, kb) in kb.iter().enumerate() {
                    ke[(b * D + j) * nd + a * D..][..D].copy_from_slice(kb);
                }
                for i in 0..D {
                    let row: [f64; D] = std::array::from_fn(|j| kb[j][i]);
                    ke[(a * D + i) * nd + b * D..][..D].copy_from_slice(&row);
                }
            }
        }
    }
}

/// Values per point in [`LinearElasticKernel::point_factors`]: J⁻¹ and w det J.
pub const fn factors_per_point(dim: usize) -> usize {
    dim * dim + 1
}

impl LinearElasticKernel {
    /// What the element operator needs of the geometry `xe`, at every point
    /// q: J⁻¹ (row-major, D × D) and the weight times det J, into lane
    /// `lane` of a group of [`CELL_LANES`] cells as [`Self::apply4`] reads
    /// them: factor k at point q in `factors4[(k * nq + q) * CELL_LANES + lane]`.
    /// `Err(det J)` if the Jacobian is not positive at a point.
    pub fn point_factors<const D: usize>(
        &self,
        xe: &[f64],
        factors4: &mut [f64],
        lane: usize,
        jac: &mut Vec<f64>,
    ) -> Result<(), f64> {
        let c = &self.cache;
        let nq = c.n_points();
        c.by_point.jacobians_into::<D>(xe, jac);
        let mut put = |k: usize, q: usize, v: f64| factors4[(k * nq + q) * CELL_LANES + lane] = v;
        for q in 0..nq {
            let (jinv, det) = linalg::inverse(D, &mapping::jacobian_at::<D>(jac, nq, q));
            if det.is_nan() || det <= 0.0 {
                return Err(det);
            }
            for r in 0..D {
                for k in 0..D {
                    put(r * D + k, q, jinv[r][k]);
                }
            }
            put(D * D, q, c.weights[q] * det);
        }
        Ok(())
    }
}

/// Cells in the lanes of [`LinearElasticKernel::apply4`].
pub const CELL_LANES: usize = 4;

impl LinearElasticKernel {
    /// y_e = K_e u_e without K_e for four cells at once, one in each lane of
    /// the vectors, from their [`Self::point_factors`]: at each point,
    /// ∇u = (∂u/∂ξ) J⁻¹, σ = λ tr(∇u) I + μ (∇u + ∇uᵀ), and y_a += w det J
    /// σ J⁻ᵀ ∂N_a/∂ξ. `factors4[(k * nq + q) * 4 + l]` is factor k at point
    /// q of cell l, and `ue4`, `ye4` hold local dof d of cell l at
    /// `d * 4 + l`. Each broadcast reference gradient serves the four
    /// cells, and no sum runs across lanes: at p = 4 in 3D, 0.73 µs a cell,
    /// against 2.0 µs for one cell at a time with the sums over the points
    /// in the lanes. A lane of zero factors (a cell past the last) gives
    /// zeros.
    pub fn apply4<const D: usize>(&self, factors4: &[f64], ue4: &[f64], ye4: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
            // SAFETY: the processor supports AVX2 and FMA (checked just above).
            unsafe { avx2::apply4::<D>(self, factors4, ue4, ye4) };
            return;
        }
        apply4_portable::<D>(self, factors4, ue4, ye4);
    }

    /// Column `dof` of the four cells' matrices, y_e = K_e e_dof, as
    /// [`Self::apply4`] gives it for the unit vector (the same values) but
    /// with ∂u/∂ξ read off the one node's reference gradient: about half
    /// the work. The condensation's interior columns.
    pub fn unit4<const D: usize>(&self, factors4: &[f64], dof: usize, ye4: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
            // SAFETY: the processor supports AVX2 and FMA (checked just above).
            unsafe { avx2::unit4::<D>(self, factors4, dof, ye4) };
            return;
        }
        unit4_portable::<D>(self, factors4, dof, ye4);
    }
}

/// [`LinearElasticKernel::apply4`] lane by lane, with the operations of
/// its AVX2 version in the same order and the same fused multiply-adds:
/// bitwise the same results on every processor.
fn apply4_portable<const D: usize>(k: &LinearElasticKernel, factors4: &[f64], ue4: &[f64], ye4: &mut [f64]) {
    const L: usize = CELL_LANES;
    let ue4 = &ue4[..k.cache.n_basis * D * L];
    each_point_portable::<D>(k, factors4, ye4, |gq, l| {
        let mut g = [[0.0; D]; D];
        for (ga, ua) in gq.chunks_exact(D).zip(ue4.chunks_exact(D * L)) {
            for i in 0..D {
                for j in 0..D {
                    g[i][j] = ua[i * L + l].mul_add(ga[j], g[i][j]);
                }
            }
        }
        g
    });
}

/// [`LinearElasticKernel::unit4`] as its AVX2 version computes it.
fn unit4_portable<const D: usize>(k: &LinearElasticKernel, factors4: &[f64], dof: usize, ye4: &mut [f64]) {
    let (a, i) = (dof / D, dof % D);
    each_point_portable::<D>(k, factors4, ye4, |gq, _| {
        let mut g = [[0.0; D]; D];
        g[i].copy_from_slice(&gq[a * D..][..D]);
        g
    });
}

/// y_e = Σ_q, lane by lane, of the pushed-back stress of the gradient
/// ∂u/∂ξ that `gradient` gives at the point (its reference gradients, lane).
#[inline(always)]
fn each_point_portable<const D: usize>(
    k: &LinearElasticKernel,
    factors4: &[f64],
    ye4: &mut [f64],
    gradient: impl Fn(&[f64], usize) -> [[f64; D]; D],
) {
    const L: usize = CELL_LANES;
    let (grads, n, nq, m) = (&k.cache.ref_grads[..], k.cache.n_basis, k.cache.n_points(), k.material);
    let ye4 = &mut ye4[..n * D * L];
    ye4.fill(0.0);
    for q in 0..nq {
        let gq = &grads[q * n * D..][..n * D];
        for l in 0..L {
            let f = |k: usize| factors4[(k * nq + q) * L + l];
            let sigma = stress_at::<D>(&f, &gradient(gq, l), m);
            let p: [[f64; D]; D] = std::array::from_fn(|i| {
                std::array::from_fn(|k| {
                    (1..D).fold(sigma[i][0] * f(k * D), |v, j| sigma[i][j].mul_add(f(k * D + j), v))
                })
            });
            for (ga, ya) in gq.chunks_exact(D).zip(ye4.chunks_exact_mut(D * L)) {
                for i in 0..D {
                    for k in 0..D {
                        ya[i * L + l] = p[i][k].mul_add(ga[k], ya[i * L + l]);
                    }
                }
            }
        }
    }
}

/// w det J σ at a point, σ = λ tr H I + μ (H + Hᵀ) with H = (∂u/∂ξ) J⁻¹,
/// from J⁻¹ (row-major, `f(k)` for k < D²) and w det J (`f(D²)`).
#[inline(always)]
fn stress_at<const D: usize>(f: impl Fn(usize) -> f64, g: &[[f64; D]; D], m: LinearElastic) -> [[f64; D]; D] {
    let h: [[f64; D]; D] = std::array::from_fn(|i| {
        std::array::from_fn(|j| (1..D).fold(g[i][0] * f(j), |v, k| g[i][k].mul_add(f(k * D + j), v)))
    });
    let w = f(D * D);
    let div = (1..D).fold(h[0][0], |v, k| v + h[k][k]);
    let (wmu, diag) = (w * m.mu, w * (m.lambda * div));
    std::array::from_fn(|i| std::array::from_fn(|j| wmu * (h[i][j] + h[j][i]) + if i == j { diag } else { 0.0 }))
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{LinearElasticKernel, CELL_LANES as L};
    use std::arch::x86_64::*;

    /// The four f64 from `x[0]` on (a checked slice: out of bounds panics).
    #[inline(always)]
    unsafe fn load(x: &[f64]) -> __m256d {
        let x = &x[..4];
        _mm256_loadu_pd(x.as_ptr())
    }

    /// [`super::LinearElasticKernel::apply4`], the four cells in the lanes
    /// of one AVX2 vector.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn apply4<const D: usize>(
        k: &LinearElasticKernel,
        factors4: &[f64],
        ue4: &[f64],
        ye4: &mut [f64],
    ) {
        let ue4 = &ue4[..k.cache.n_basis * D * L];
        each_point::<D>(k, factors4, ye4, |gq| {
            // ∂u_i/∂ξ_j at the point.
            let mut g = [[_mm256_setzero_pd(); 3]; 3];
            for (ga, ua) in gq.chunks_exact(D).zip(ue4.chunks_exact(D * L)) {
                for i in 0..D {
                    let u = load(&ua[i * L..]);
                    for j in 0..D {
                        g[i][j] = _mm256_fmadd_pd(u, _mm256_set1_pd(ga[j]), g[i][j]);
                    }
                }
            }
            g
        });
    }

    /// [`super::LinearElasticKernel::unit4`]: ∂u/∂ξ is the node's
    /// reference gradient in the dof's row.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn unit4<const D: usize>(k: &LinearElasticKernel, factors4: &[f64], dof: usize, ye4: &mut [f64]) {
        let (a, i) = (dof / D, dof % D);
        each_point::<D>(k, factors4, ye4, |gq| {
            let mut g = [[_mm256_setzero_pd(); 3]; 3];
            for j in 0..D {
                g[i][j] = _mm256_set1_pd(gq[a * D + j]);
            }
            g
        });
    }

    /// y_e = Σ_q of the pushed-back stress of the gradient ∂u/∂ξ that
    /// `gradient` gives at the point (from its reference gradients), the four
    /// cells in the lanes.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    unsafe fn each_point<const D: usize>(
        k: &LinearElasticKernel,
        factors4: &[f64],
        ye4: &mut [f64],
        gradient: impl Fn(&[f64]) -> [[__m256d; 3]; 3],
    ) {
        let (grads, n, nq, m) = (&k.cache.ref_grads[..], k.cache.n_basis, k.cache.n_points(), k.material);
        let ye4 = &mut ye4[..n * D * L];
        ye4.fill(0.0);
        let (lam, mu) = (_mm256_set1_pd(m.lambda), _mm256_set1_pd(m.mu));
        let zero = _mm256_setzero_pd();
        for q in 0..nq {
            let gq = &grads[q * n * D..][..n * D];
            let f = |k: usize| load(&factors4[(k * nq + q) * L..]);
            let g = gradient(gq);
            // H = (∂u/∂ξ) J⁻¹, then w det J σ as in super::stress_at.
            let mut h = [[zero; 3]; 3];
            for i in 0..D {
                for j in 0..D {
                    h[i][j] = _mm256_mul_pd(g[i][0], f(j));
                    for k in 1..D {
                        h[i][j] = _mm256_fmadd_pd(g[i][k], f(k * D + j), h[i][j]);
                    }
                }
            }
            let w = f(D * D);
            let mut div = h[0][0];
            for k in 1..D {
                div = _mm256_add_pd(div, h[k][k]);
            }
            let (wmu, diag) = (_mm256_mul_pd(w, mu), _mm256_mul_pd(w, _mm256_mul_pd(lam, div)));
            let mut sigma = [[zero; 3]; 3];
            for i in 0..D {
                for j in 0..D {
                    let s = _mm256_mul_pd(wmu, _mm256_add_pd(h[i][j], h[j][i]));
                    sigma[i][j] = _mm256_add_pd(s, if i == j { diag } else { zero });
                }
            }
            // P = σ J⁻ᵀ, then y_(a i) += Σ_k P_ik ∂N_a/∂ξ_k.
            let mut p = [[zero; 3]; 3];
            for i in 0..D {
                for k in 0..D {
                    p[i][k] = _mm256_mul_pd(sigma[i][0], f(k * D));
                    for j in 1..D {
                        p[i][k] = _mm256_fmadd_pd(sigma[i][j], f(k * D + j), p[i][k]);
                    }
                }
            }
            for (ga, ya) in gq.chunks_exact(D).zip(ye4.chunks_exact_mut(D * L)) {
                for i in 0..D {
                    let y = &mut ya[i * L..][..L];
                    let mut v = _mm256_loadu_pd(y.as_ptr());
                    for k in 0..D {
                        v = _mm256_fmadd_pd(p[i][k], _mm256_set1_pd(ga[k]), v);
                    }
                    _mm256_storeu_pd(y.as_mut_ptr(), v);
                }
            }
        }
    }
}

/// The lower triangle of M = Aw Aᵀ for `nd` dofs and `nq` points (`awt`,
/// `at`: `ld` values a point), by tiles of [`TILE_ROWS`] × [`TILE_COLS`]
/// sums kept in registers: those on or below the diagonal, which also cover
/// some entries above it, in fused multiply-adds. M is symmetric, so this is
/// half the products of a full one.
#[inline(always)]
fn gram_lower(nd: usize, nq: usize, ld: usize, awt: &[f64], at: &[f64], m: &mut [f64]) {
    for c0 in (0..nd).step_by(TILE_COLS) {
        for r0 in (c0 - c0 % TILE_ROWS..nd).step_by(TILE_ROWS) {
            let mut acc = [[0.0f64; TILE_ROWS]; TILE_COLS];
            for q in 0..nq {
                let a: &[f64; TILE_ROWS] = awt[q * ld + r0..][..TILE_ROWS].try_into().expect("tile rows");
                let s: &[f64; TILE_COLS] = at[q * ld + c0..][..TILE_COLS].try_into().expect("tile columns");
                for (acc, &s) in acc.iter_mut().zip(s) {
                    for (x, &a) in acc.iter_mut().zip(a) {
                        *x = a.mul_add(s, *x);
                    }
                }
            }
            for (k, acc) in acc.iter().enumerate() {
                m[(c0 + k) * ld + r0..][..TILE_ROWS].copy_from_slice(acc);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature::simplex_rule;
    use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing, Simplex};

    /// A curved element: straight nodes of a skewed simplex plus a smooth bump.
    fn curved_element(simplex: Simplex, p: usize) -> (LinearElasticKernel, Vec<f64>) {
        let nodes = NodeSet::new(simplex, p, NodeSpacing::Optimal);
        let dim = simplex.dim();
        let cache = ElementCache::new(&LagrangeBasis::new(&nodes), &simplex_rule(simplex, 2 * p));
        let material = LinearElastic::try_from_young_poisson(3.0, 0.3).unwrap();
        let mut xe = Vec::new();
        for x in &nodes.coords {
            let bump = 0.05 * (x[0] * x[1] + 0.5 * x[0] * x[0]);
            xe.push(x[0] + 0.3 * x[1] + bump);
            xe.push(x[1] * 1.2 - bump);
            if dim == 3 {
                xe.push(x[2] + 0.1 * x[0]);
            }
        }
        (LinearElasticKernel { cache, material }, xe)
    }

    #[test]
    fn element_stiffness_is_symmetric_and_annihilates_rigid_motions() {
        for simplex in [Simplex::Tri, Simplex::Tet] {
            for p in [1, 2, 4] {
                let (k, xe) = curved_element(simplex, p);
                let dim = simplex.dim();
                let nd = xe.len();
                let mut ke = vec![0.0; nd * nd];
                let mut ws = k.workspace();
                k.stiffness_into(&xe, &mut ke, &mut ws).unwrap();
                let scale = ke.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for r in 0..nd {
                    for c in 0..nd {
                        assert!((ke[r * nd + c] - ke[c * nd + r]).abs() < 1e-12 * scale);
                    }
                    assert!(ke[r * nd + r] > 0.0);
                }
                // Rigid motions: translations and infinitesimal rotations.
                let mut modes: Vec<Vec<f64>> =
                    (0..dim).map(|d| (0..nd).map(|i| if i % dim == d { 1.0 } else { 0.0 }).collect()).collect();
                let rot = |i: usize, j: usize| -> Vec<f64> {
                    let mut u = vec![0.0; nd];
                    for a in 0..nd / dim {
                        u[a * dim + i] = -xe[a * dim + j];
                        u[a * dim + j] = xe[a * dim + i];
                    }
                    u
                };
                modes.push(rot(0, 1));
                if dim == 3 {
                    modes.push(rot(0, 2));
                    modes.push(rot(1, 2));
                }
                for u in &modes {
                    for r in 0..nd {
                        let f: f64 = (0..nd).map(|c| ke[r * nd + c] * u[c]).sum();
                        assert!(f.abs() < 1e-10 * scale, "{simplex:?} p={p}: K·rigid = {f:e}");
                    }
                }
            }
        }
    }

    #[test]
    fn element_stiffness_is_the_integral_summed_point_by_point() {
        // Every order 1..6 in 2D and 3D: dof counts on and off the 8 × 4
        // tiles of the Gram product, against the integrand of
        // K_(a i)(b j) summed directly over the quadrature points.
        for simplex in [Simplex::Tri, Simplex::Tet] {
            for p in 1..=6 {
                let (k, xe) = curved_element(simplex, p);
                let (c, dim, nd) = (&k.cache, simplex.dim(), xe.len());
                let mut ke = vec![0.0; nd * nd];
                k.stiffness_into(&xe, &mut ke, &mut k.workspace()).unwrap();
                let (lam, mu) = (k.material.lambda, k.material.mu);
                let mut want = vec![0.0; nd * nd];
                let mut g = vec![0.0; nd];
                for q in 0..c.n_points() {
                    let jac = mapping::jacobian(dim, &xe, c.grads_at(q));
                    let (jinv, det) = linalg::inverse(dim, &jac);
                    mapping::physical_gradients_into(dim, c.grads_at(q), &jinv, &mut g);
                    let w = c.weights[q] * det;
                    for (r, s) in (0..nd).flat_map(|r| (0..nd).map(move |s| (r, s))) {
                        let (a, i, b, j) = (r / dim, r % dim, s / dim, s % dim);
                        let dot: f64 = (0..dim).map(|l| g[a * dim + l] * g[b * dim + l]).sum();
                        let delta = if i == j { dot } else { 0.0 };
                        want[r * nd + s] +=
                            w * (lam * g[a * dim + i] * g[b * dim + j] + mu * g[a * dim + j] * g[b * dim + i] + mu * delta);
                    }
                }
                let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for (e, (x, y)) in ke.iter().zip(&want).enumerate() {
                    assert!((x - y).abs() < 1e-12 * scale, "{simplex:?} p = {p}, entry {e}: {x} against {y}");
                }
                assert!(ke.iter().enumerate().all(|(e, x)| x.to_bits() == ke[(e % nd) * nd + e / nd].to_bits()));
            }
        }
    }

    #[test]
    fn the_avx2_copy_gives_bitwise_the_portable_stiffness() {
        for simplex in [Simplex::Tri, Simplex::Tet] {
            let (k, xe) = curved_element(simplex, 4);
            let nd = xe.len();
            let (mut dispatched, mut portable) = (vec![0.0; nd * nd], vec![0.0; nd * nd]);
            k.stiffness_into(&xe, &mut dispatched, &mut k.workspace()).unwrap();
            k.stiffness(&xe, &mut portable, &mut k.workspace()).unwrap();
            assert!(dispatched.iter().zip(&portable).all(|(a, b)| a.to_bits() == b.to_bits()), "{simplex:?}");
        }
    }

    /// K_e u computed without K_e, four cells in the lanes, matches each
    /// element matrix's product in 2D and 3D on curved cells; a lane of zero
    /// factors gives zeros; rigid translations are in the kernel; the AVX2
    /// version is bitwise the portable one; the unit columns are the
    /// products with unit vectors; an inverted cell is refused.
    #[test]
    fn four_cells_in_lanes_are_their_element_matrices_products() {
        fn check<const D: usize>(simplex: Simplex, p: usize) {
            let (k, xe) = curved_element(simplex, p);
            let (nd, nf) = (xe.len(), factors_per_point(D) * k.cache.n_points());
            let mut f4 = vec![0.0; nf * CELL_LANES];
            let mut u4 = vec![0.0; nd * CELL_LANES];
            let mut want = Vec::new();
            // Three cells, the curved one stretched differently; lane 3 empty.
            for l in 0..3 {
                let x: Vec<f64> = xe.iter().enumerate().map(|(i, v)| v * (1.0 + 0.2 * l as f64 * (i % D) as f64)).collect();
                k.point_factors::<D>(&x, &mut f4, l, &mut Vec::new()).unwrap();
                let mut ke = vec![0.0; nd * nd];
                k.stiffness_into(&x, &mut ke, &mut k.workspace()).unwrap();
                let ue: Vec<f64> = (0..nd).map(|i| ((i * 5 + l * 11) as f64 * 0.31).sin()).collect();
                for (i, v) in ue.iter().enumerate() {
                    u4[i * CELL_LANES + l] = *v;
                }
                want.push((0..nd).map(|r| (0..nd).map(|c| ke[r * nd + c] * ue[c]).sum::<f64>()).collect::<Vec<_>>());
            }
            for i in 0..nd {
                u4[i * CELL_LANES + 3] = 1.0;
            }
            let mut y4 = vec![f64::NAN; nd * CELL_LANES];
            k.apply4::<D>(&f4, &u4, &mut y4);
            for (l, want) in want.iter().enumerate() {
                let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for (i, y) in want.iter().enumerate() {
                    let got = y4[i * CELL_LANES + l];
                    assert!((got - y).abs() < 1e-12 * scale, "{simplex:?} p = {p}, lane {l}: {got} against {y}");
                }
            }
            assert!((0..nd).all(|i| y4[i * CELL_LANES + 3] == 0.0), "{simplex:?} p = {p}: the empty lane");
            let mut portable = vec![f64::NAN; nd * CELL_LANES];
            apply4_portable::<D>(&k, &f4, &u4, &mut portable);
            assert!(portable.iter().zip(&y4).all(|(a, b)| a.to_bits() == b.to_bits()), "{simplex:?} p = {p}");
            // Each column from unit4 is apply4's product with the unit vector.
            let mut column = vec![f64::NAN; nd * CELL_LANES];
            for dof in 0..nd {
                let mut unit = vec![0.0; nd * CELL_LANES];
                unit[dof * CELL_LANES..][..CELL_LANES].fill(1.0);
                k.apply4::<D>(&f4, &unit, &mut y4);
                k.unit4::<D>(&f4, dof, &mut column);
                assert!(column == y4, "{simplex:?} p = {p}: column {dof}");
                unit4_portable::<D>(&k, &f4, dof, &mut portable);
                assert!(portable == y4, "{simplex:?} p = {p}: portable column {dof}");
            }
            // Rigid translations, in every lane.
            let shift: Vec<f64> = (0..nd * CELL_LANES).map(|i| if (i / CELL_LANES).is_multiple_of(D) { 1.0 } else { 0.0 }).collect();
            k.apply4::<D>(&f4, &shift, &mut y4);
            assert!(y4.iter().all(|v| v.abs() < 1e-10), "{simplex:?} p = {p}: {y4:?}");
            let mut flipped = xe.clone();
            for x in flipped.chunks_exact_mut(D) {
                x[0] = -x[0];
            }
            assert!(k.point_factors::<D>(&flipped, &mut f4, 0, &mut Vec::new()).is_err());
        }
        for p in [1, 2, 4] {
            check::<2>(Simplex::Tri, p);
            check::<3>(Simplex::Tet, p);
        }
        check::<3>(Simplex::Tet, 5);
    }

    #[test]
    fn inverted_element_is_reported() {
        let (k, mut xe) = curved_element(Simplex::Tri, 2);
        // Swap the x and y coordinates: a reflection, det J < 0.
        for a in 0..xe.len() / 2 {
            xe.swap(2 * a, 2 * a + 1);
        }
        let mut ke = vec![0.0; xe.len() * xe.len()];
        assert!(k.stiffness_into(&xe, &mut ke, &mut k.workspace()).is_err());
    }
}
