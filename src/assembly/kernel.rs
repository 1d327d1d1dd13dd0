//! Element kernels: values computed at the quadrature points of one element.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};

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

/// Scratch space of one thread.
pub struct KernelWorkspace {
    grad: Vec<f64>,
    a: Mat<f64>,
    aw: Mat<f64>,
    m: Mat<f64>,
    lap: Vec<f64>,
}

impl super::ElementKernel for LinearElasticKernel {
    type Workspace = KernelWorkspace;
    fn workspace(&self) -> KernelWorkspace {
        LinearElasticKernel::workspace(self)
    }
    fn linear_material(&self) -> Option<LinearElastic> {
        Some(self.material)
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
        KernelWorkspace {
            grad: vec![0.0; n * d],
            a: Mat::zeros(nq, n * d),
            aw: Mat::zeros(nq, n * d),
            m: Mat::zeros(n * d, n * d),
            lap: vec![0.0; n],
        }
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
        let (n, dim) = (c.n_basis, c.dim);
        for q in 0..c.n_points() {
            let rg = c.grads_at(q);
            let jac = mapping::jacobian(dim, xe, rg);
            let (jinv, det) = linalg::inverse(dim, &jac);
            if det.is_nan() || det <= 0.0 {
                return Err(det);
            }
            mapping::physical_gradients_into(dim, rg, &jinv, &mut ws.grad);
            let w = c.weights[q] * det;
            for i in 0..dim {
                for a in 0..n {
                    let g = ws.grad[a * dim + i];
                    ws.a[(q, i * n + a)] = g;
                    ws.aw[(q, i * n + a)] = w * g;
                }
            }
        }
        // M = Awᵀ A: M[(i n + a), (j n + b)] = ∫ ∂_i N_a ∂_j N_b.
        matmul(ws.m.as_mut(), Accum::Replace, ws.aw.as_ref().transpose(), ws.a.as_ref(), 1.0, Par::Seq);
        // K is symmetric, so the entry of (a i)(b j) is written at row (b j),
        // column (a i): every inner loop then runs down a column of M.
        let (lam, mu) = (self.material.lambda, self.material.mu);
        let nd = n * dim;
        let (m, lap) = (&ws.m, &mut ws.lap);
        for b in 0..n {
            // lap[a] = ∫ ∇N_a·∇N_b
            lap.fill(0.0);
            for k in 0..dim {
                for (l, v) in lap.iter_mut().zip(&m.col_as_slice(k * n + b)[k * n..][..n]) {
                    *l += v;
                }
            }
            for j in 0..dim {
                let row = &mut ke[(b * dim + j) * nd..][..nd];
                let cj = m.col_as_slice(j * n + b);
                for i in 0..dim {
                    let ci = m.col_as_slice(i * n + b);
                    let (lam_part, mu_part) = (&cj[i * n..][..n], &ci[j * n..][..n]);
                    let diag = if i == j { mu } else { 0.0 };
                    for a in 0..n {
                        row[a * dim + i] = lam * lam_part[a] + mu * mu_part[a] + diag * lap[a];
                    }
                }
            }
        }
        Ok(())
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
