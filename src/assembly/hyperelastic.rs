//! The element kernel of the incrementally linearised and non-linear
//! formulations (paper eq. (15), Table 1), for any [`Material`].
//!
//! On the current geometry Ω_n with F_n = ∂x_n/∂X (X the straight-sided
//! mesh, so ∂X/∂ξ is constant per cell):
//!
//! K_(a i)(b j) = ∫ ∂_k N_a c_ikjl ∂_l N_b dΩ_n  [+ δ_ij ∫ ∂_k N_a σ_kl ∂_l N_b dΩ_n]
//! R_(a i)      = ∫ σ_ik ∂_k N_a dΩ_n
//!
//! with gradients on Ω_n. The bracketed geometric term and c = c_n belong to
//! CIL and Newton ([`TangentMode::Consistent`]); IIL uses c_0 = c(F = I) and
//! no geometric term ([`TangentMode::Initial`]). In 2D (plane strain) F is
//! padded with F_33 = 1 and only in-plane components are used.

use super::ElementKernel;
use crate::linalg::{self, Mat3};
use crate::mapping::{self, ElementCache};
use crate::material::{Material, Tangent};
use crate::mesh::HighOrderMesh;

/// Which tangent the matrix uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TangentMode {
    /// c_n at the current F plus the geometric stiffness σ_n (CIL, Newton).
    Consistent,
    /// c_0 = c(F = I), no geometric stiffness (IIL; ILE for anisotropic models).
    Initial,
}

/// See the module documentation.
pub struct MaterialKernel<'a> {
    pub cache: &'a ElementCache,
    pub material: &'a dyn Material,
    pub mode: TangentMode,
    /// Per cell: (∂X/∂ξ)⁻¹ of the straight-sided element.
    pub straight_jinv: Vec<Mat3>,
    /// Per cell: unit fibre direction (used by anisotropic models).
    pub fibres: &'a [[f64; 3]],
}

/// Scratch space of one thread.
pub struct MaterialWorkspace {
    grad: Vec<f64>,
    t: Vec<f64>,
}

impl<'a> MaterialKernel<'a> {
    /// Precompute the straight-element Jacobians from the straight node
    /// coordinates `straight` of `mesh` (vertices are the first nodes of each cell).
    pub fn new(
        mesh: &HighOrderMesh,
        straight: &[f64],
        cache: &'a ElementCache,
        material: &'a dyn Material,
        mode: TangentMode,
        fibres: &'a [[f64; 3]],
    ) -> MaterialKernel<'a> {
        let dim = mesh.dim();
        let straight_jinv = (0..mesh.n_cells())
            .map(|c| {
                let xv: Vec<[f64; 3]> = mesh.cell(c)[..=dim]
                    .iter()
                    .map(|&v| {
                        let mut x = [0.0; 3];
                        x[..dim].copy_from_slice(&straight[v * dim..(v + 1) * dim]);
                        x
                    })
                    .collect();
                linalg::inverse(dim, &mapping::affine_jacobian(dim, &xv)).0
            })
            .collect();
        MaterialKernel { cache, material, mode, straight_jinv, fibres }
    }
}

fn pad(dim: usize, m: &Mat3) -> Mat3 {
    let mut f = *m;
    if dim == 2 {
        f[0][2] = 0.0;
        f[1][2] = 0.0;
        f[2] = [0.0, 0.0, 1.0];
    }
    f
}

const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

impl ElementKernel for MaterialKernel<'_> {
    type Workspace = MaterialWorkspace;

    fn workspace(&self) -> MaterialWorkspace {
        let (n, d) = (self.cache.n_basis, self.cache.dim);
        MaterialWorkspace { grad: vec![0.0; n * d], t: vec![0.0; n * d * d * d] }
    }

    fn compute(
        &self,
        cell: usize,
        xe: &[f64],
        ke: &mut [f64],
        mut re: Option<&mut [f64]>,
        ws: &mut MaterialWorkspace,
    ) -> Result<(), f64> {
        let c = self.cache;
        let (n, dim) = (c.n_basis, c.dim);
        ke.fill(0.0);
        if let Some(r) = re.as_deref_mut() {
            r.fill(0.0);
        }
        let fibre = &self.fibres[cell];
        let c0: Option<Tangent> = match self.mode {
            TangentMode::Initial => Some(self.material.stress_and_tangent(&IDENTITY, fibre).1),
            TangentMode::Consistent => None,
        };
        for q in 0..c.n_points() {
            let rg = c.grads_at(q);
            let jx = mapping::jacobian(dim, xe, rg);
            let (jinv, det) = linalg::inverse(dim, &jx);
            if det.is_nan() || det <= 0.0 {
                return Err(det);
            }
            mapping::physical_gradients_into(dim, rg, &jinv, &mut ws.grad);
            let f = pad(dim, &linalg::matmul(dim, &jx, &self.straight_jinv[cell]));
            let (sigma, tangent) = match &c0 {
                Some(c0) => (if re.is_some() { self.material.stress(&f, fibre) } else { [[0.0; 3]; 3] }, *c0),
                None => self.material.stress_and_tangent(&f, fibre),
            };
            let w = c.weights[q] * det;
            tangent_gradients(n, dim, &ws.grad, &tangent, &mut ws.t);
            let geometric = (self.mode == TangentMode::Consistent).then_some(&sigma);
            add_stiffness(n, dim, &ws.grad, &ws.t, geometric, w, ke);
            if let Some(r) = re.as_deref_mut() {
                add_internal_force(n, dim, &ws.grad, &sigma, w, r);
            }
        }
        Ok(())
    }
}

/// t[a][i][j][l] = Σ_k g_a,k c_ikjl at one point, for the physical gradients `g` and the tangent c.
fn tangent_gradients(n: usize, dim: usize, g: &[f64], tangent: &Tangent, t: &mut [f64]) {
    for a in 0..n {
        for i in 0..dim {
            for j in 0..dim {
                for l in 0..dim {
                    t[((a * dim + i) * dim + j) * dim + l] =
                        (0..dim).map(|k| g[a * dim + k] * tangent[i][k][j][l]).sum();
                }
            }
        }
    }
}

/// Add one point's material term (from `t`) and geometric term (given σ) to `ke`, with weight `w`.
fn add_stiffness(n: usize, dim: usize, g: &[f64], t: &[f64], geometric: Option<&Mat3>, w: f64, ke: &mut [f64]) {
    let nd = n * dim;
    for a in 0..n {
        for b in 0..n {
            let gs = if let Some(sigma) = geometric {
                let mut s = 0.0;
                for k in 0..dim {
                    for l in 0..dim {
                        s += g[a * dim + k] * sigma[k][l] * g[b * dim + l];
                    }
                }
                s
            } else {
                0.0
            };
            for i in 0..dim {
                for j in 0..dim {
                    let t = &t[((a * dim + i) * dim + j) * dim..((a * dim + i) * dim + j + 1) * dim];
                    let mut v: f64 = (0..dim).map(|l| t[l] * g[b * dim + l]).sum();
                    if i == j {
                        v += gs;
                    }
                    ke[(a * dim + i) * nd + b * dim + j] += w * v;
                }
            }
        }
    }
}

/// Add one point's r_(a i) += w σ_ik ∂_k N_a to the internal-force vector.
fn add_internal_force(n: usize, dim: usize, g: &[f64], sigma: &Mat3, w: f64, r: &mut [f64]) {
    for a in 0..n {
        for i in 0..dim {
            r[a * dim + i] += w * (0..dim).map(|k| sigma[i][k] * g[a * dim + k]).sum::<f64>();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::{make_material, MaterialModel};
    use crate::mesh::NodeConstraint;
    use crate::quadrature::simplex_rule;
    use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing, Simplex};

    /// One straight element as a mesh, and a curved, stretched configuration of it.
    fn element(simplex: Simplex, p: usize) -> (HighOrderMesh, Vec<f64>, ElementCache) {
        let nodes = NodeSet::new(simplex, p, NodeSpacing::Optimal);
        let dim = simplex.dim();
        let straight: Vec<f64> = nodes.coords.iter().flat_map(|x| x[..dim].to_vec()).collect();
        let mesh = HighOrderMesh {
            simplex,
            order: p,
            spacing: NodeSpacing::Optimal,
            coords: straight.clone(),
            cells: (0..nodes.len()).collect(),
            n_vertices: dim + 1,
            constraint: vec![NodeConstraint::Free; nodes.len()],
        };
        let curved: Vec<f64> = nodes
            .coords
            .iter()
            .flat_map(|x| {
                let b = 0.08 * x[0] * x[1];
                let y = [1.1 * x[0] + 0.2 * x[1] + b, 0.9 * x[1] - b + 0.05 * x[2], 1.05 * x[2] + 0.1 * x[0] * x[2]];
                y[..dim].to_vec()
            })
            .collect();
        let cache = ElementCache::new(&LagrangeBasis::new(&nodes), &simplex_rule(simplex, 2 * p));
        (mesh, curved, cache)
    }

    #[test]
    fn consistent_tangent_is_the_derivative_of_the_residual() {
        for simplex in [Simplex::Tri, Simplex::Tet] {
            for model in [MaterialModel::NeoHookean, MaterialModel::MooneyRivlin, MaterialModel::TransverselyIsotropic]
            {
                let (mesh, x, cache) = element(simplex, 2);
                let material = make_material(model, 10.0, 0.3).unwrap();
                let fibres = [[0.6, 0.8, 0.0]];
                let k = MaterialKernel::new(
                    &mesh,
                    &mesh.coords,
                    &cache,
                    material.as_ref(),
                    TangentMode::Consistent,
                    &fibres,
                );
                let nd = x.len();
                let mut ws = k.workspace();
                let (mut ke, mut re) = (vec![0.0; nd * nd], vec![0.0; nd]);
                k.compute(0, &x, &mut ke, Some(&mut re), &mut ws).unwrap();
                let scale = ke.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let h = 1e-6;
                for col in 0..nd {
                    let (mut xp, mut xm) = (x.clone(), x.clone());
                    xp[col] += h;
                    xm[col] -= h;
                    let (mut rp, mut rm, mut tmp) = (vec![0.0; nd], vec![0.0; nd], vec![0.0; nd * nd]);
                    k.compute(0, &xp, &mut tmp, Some(&mut rp), &mut ws).unwrap();
                    k.compute(0, &xm, &mut tmp, Some(&mut rm), &mut ws).unwrap();
                    for row in 0..nd {
                        let fd = (rp[row] - rm[row]) / (2.0 * h);
                        let e = (fd - ke[row * nd + col]).abs();
                        assert!(
                            e < 1e-6 * scale,
                            "{simplex:?} {model:?} K[{row},{col}] = {} vs FD {fd}",
                            ke[row * nd + col]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn initial_tangent_kernel_equals_linear_elastic_kernel_for_isotropic_models() {
        use crate::assembly::LinearElasticKernel;
        use crate::material::LinearElastic;
        let (mesh, x, cache) = element(Simplex::Tet, 3);
        let material = make_material(MaterialModel::NeoHookean, 5.0, 0.35).unwrap();
        let fibres = [[1.0, 0.0, 0.0]];
        let k = MaterialKernel::new(&mesh, &mesh.coords, &cache, material.as_ref(), TangentMode::Initial, &fibres);
        let lin = LinearElasticKernel {
            cache: cache.clone(),
            material: LinearElastic::try_from_young_poisson(5.0, 0.35).unwrap(),
        };
        let nd = x.len();
        let (mut a, mut b) = (vec![0.0; nd * nd], vec![0.0; nd * nd]);
        k.compute(0, &x, &mut a, None, &mut k.workspace()).unwrap();
        lin.stiffness_into(&x, &mut b, &mut lin.workspace()).unwrap();
        let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (u, v) in a.iter().zip(&b) {
            assert!((u - v).abs() < 1e-10 * scale);
        }
    }
}
