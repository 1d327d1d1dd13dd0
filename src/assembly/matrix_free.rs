//! The condensed operator of isotropic linear elasticity applied cell by
//! cell, without its matrix.
//!
//! A later increment of the ILE stage, whose preconditioner is kept from an
//! earlier matrix, needs its own matrix only in a few products (the start's
//! residual, one or two PCG iterations). Those products are made here from
//! each cell's geometry at its points; the interior nodes are condensed with
//! K_II and W = K_II⁻¹ K_IB per cell (K_BI = Wᵀ K_II), found from the cell
//! matrix's column at each interior dof. W also recovers the interior
//! values.

use super::kernel::{factors_per_point, LinearElasticKernel, CELL_LANES};
use super::System;
use crate::error::{Error, Result};
use crate::mesh::HighOrderMesh;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::Arc;

/// What the products need of one geometry: per cell, J⁻¹ and w det J at
/// the points, and K_II (the cell matrix's block at its interior dofs; with
/// W, K_BI = Wᵀ K_II); and where the cells' values go, which the geometry
/// does not change. All in the layout's order of the cells.
#[derive(Debug, Clone)]
pub struct CellOperator {
    /// J⁻¹ and w det J by groups of [`CELL_LANES`] cells, each group's values
    /// lane by lane as [`LinearElasticKernel::apply4`] reads them (zeros
    /// for the lanes past the last cell).
    factors: Vec<f64>,
    /// K_II per cell.
    kii: Vec<f64>,
    per_cell: usize,
    n_cells: usize,
    layout: Arc<CellLayout>,
}

/// The order in which the products take the cells, and where each cell's
/// values go in the system: found once for a [`System`], kept for each
/// later geometry.
///
/// The cells with a prescribed dof come first, so that a right-hand side
/// (values on the prescribed dofs only) reads only them; within each of
/// the two, the cells follow the mean of their system rows, so that each
/// run of cells reaches a narrow band of rows: its share of a product is
/// summed in a buffer of that band, not of the whole system (on a torus
/// cavity at p = 4 in the mesh's order, each of 16 runs reached all
/// 131,559 rows).
#[derive(Debug)]
pub struct CellLayout {
    /// The cell at each position.
    order: Arc<[usize]>,
    /// Per position, for each of its cell's non-interior dofs (the split's
    /// `boundary` order): its system row, or the number of system rows plus
    /// its dof when it is prescribed.
    slots: Vec<usize>,
    /// The positions before this hold every cell with a prescribed dof; a
    /// multiple of [`CELL_LANES`], or the number of cells.
    prescribed_end: usize,
    /// The positions in runs of at most `n_cells / PARTS` cells, each with the
    /// range of system rows it reaches; each run starts a group of
    /// [`CELL_LANES`].
    parts: Vec<(Range<usize>, Range<usize>)>,
}

/// Runs of cells whose products are summed apart, then added in order:
/// the same sums whatever the threads.
const PARTS: usize = 16;

/// One thread's scratch for the product of a group of cells.
struct CellScratch {
    /// A cell's values and products at its non-interior dofs.
    vb: Vec<f64>,
    yb: Vec<f64>,
    /// The group's values and products, lane by lane (interior dofs zero).
    ue4: Vec<f64>,
    ye4: Vec<f64>,
    z: Vec<f64>,
}

impl System {
    /// The cell operator of the geometry `coords` (and W into the interior
    /// recovery, as an assembly leaves it), or the error an assembly would
    /// give: a cell with det J ≤ 0 at a point, or a singular interior block.
    pub fn cell_operator(
        &mut self,
        mesh: &HighOrderMesh,
        coords: &[f64],
        kernel: &LinearElasticKernel,
    ) -> Result<CellOperator> {
        match mesh.dim() {
            2 => self.cell_operator_in::<2>(mesh, coords, kernel),
            _ => self.cell_operator_in::<3>(mesh, coords, kernel),
        }
    }

    fn cell_operator_in<const D: usize>(
        &mut self,
        mesh: &HighOrderMesh,
        coords: &[f64],
        kernel: &LinearElasticKernel,
    ) -> Result<CellOperator> {
        let nd = mesh.nodes_per_cell() * D;
        let per_cell = factors_per_point(D) * kernel.cache.n_points();
        let mut interior = self.take_interior();
        let (ii, bb) = self.local_dofs(nd);
        let (ni, nb) = (ii.len(), bb.len());
        let layout = match &self.cell_layout {
            Some(layout) => layout.clone(),
            None => self.cell_layout.insert(Arc::new(self.layout::<D>(mesh, &bb))).clone(),
        };
        let order = &layout.order;
        // Without interior dofs, one unused value a cell keeps the three
        // slices in step.
        let (stride, kii_stride) = ((ni * (nb + 1)).max(1), (ni * ni).max(1));
        let groups = mesh.n_cells().div_ceil(CELL_LANES);
        // The buffers of an earlier operator of this system when given back
        // ([`Self::recycle`]): every value the build writes is written
        // again, and the lanes past the last cell, never written, stay zero.
        let (mut factors, mut kii) = match self.spare_operator.take() {
            Some(op) if op.factors.len() == per_cell * CELL_LANES * groups && op.kii.len() == kii_stride * mesh.n_cells() => {
                (op.factors, op.kii)
            }
            _ => (vec![0.0; per_cell * CELL_LANES * groups], vec![0.0; kii_stride * mesh.n_cells()]),
        };
        let mut none = Vec::new();
        let keep = interior.as_mut().map_or(&mut none, |r| &mut r.keep);
        keep.clear();
        keep.resize(stride * mesh.n_cells(), 0.0);
        // Group by group: the factors of each cell in its lane, then the
        // interior columns while the group's factors are in cache.
        let dofs = (&ii[..], &bb[..]);
        factors
            .par_chunks_mut(per_cell * CELL_LANES)
            .zip(kii.par_chunks_mut(kii_stride * CELL_LANES))
            .zip(keep.par_chunks_mut(stride * CELL_LANES))
            .enumerate()
            .try_for_each_init(
                || (vec![0.0; nd], Vec::new(), (vec![0.0; nd * CELL_LANES], vec![0.0; ni * ni])),
                |(xe, jac, scratch), (g, ((f4, kii), keep))| {
                    let cells = &order[g * CELL_LANES..][..kii.len() / kii_stride];
                    for (l, &c) in cells.iter().enumerate() {
                        for (a, &n) in mesh.cell(c).iter().enumerate() {
                            xe[a * D..(a + 1) * D].copy_from_slice(&coords[n * D..(n + 1) * D]);
                        }
                        kernel.point_factors::<D>(xe, f4, l, jac).map_err(|det_j| {
                            Error::invalid_element(Some(c), format!("cell {c} has a non-positive Jacobian ({det_j:.3e})"))
                        })?;
                    }
                    if ni == 0 {
                        return Ok(());
                    }
                    interior_columns::<D>(kernel, f4, dofs, kii, keep, scratch).map_err(|l| {
                        let c = cells[l];
                        Error::invalid_element(Some(c), format!("cell {c}: the stiffness of its interior nodes is singular"))
                    })
                },
            )?;
        if let Some(r) = interior.as_mut() {
            r.order = Some(order.clone());
        }
        self.interior = interior;
        Ok(CellOperator { factors, kii, per_cell, n_cells: mesh.n_cells(), layout })
    }

    /// Keep `op`'s buffers for the next [`Self::cell_operator`], which then
    /// neither allocates nor zeroes them (about 10 MB on the torus cavity
    /// of bench/compare_gmsh.sh).
    pub fn recycle(&mut self, op: CellOperator) {
        self.spare_operator = Some(op);
    }

    /// A cell's interior dofs and the others (all of its `nd` without condensation).
    fn local_dofs(&self, nd: usize) -> (Vec<usize>, Vec<usize>) {
        match self.dofs.split.as_ref() {
            Some(s) => (s.interior.clone(), s.boundary.clone()),
            None => (Vec::new(), (0..nd).collect()),
        }
    }

    /// The cells' order, their slots for their dofs `bb`, and the runs
    /// with the system rows each reaches.
    fn layout<const D: usize>(&self, mesh: &HighOrderMesh, bb: &[usize]) -> CellLayout {
        let n_system = self.dofs.n_system;
        let slots_of = |c: usize| {
            let cell = mesh.cell(c);
            bb.iter().map(move |&l| {
                let dof = cell[l / D] * D + l % D;
                self.dofs.system_row(dof).unwrap_or(n_system + dof)
            })
        };
        // (no prescribed dof, mean system row, cell)
        let mut keys: Vec<(bool, usize, usize)> = (0..mesh.n_cells())
            .into_par_iter()
            .map(|c| {
                let (mut sum, mut count, mut prescribed) = (0, 0, false);
                for k in slots_of(c) {
                    if k < n_system {
                        (sum, count) = (sum + k, count + 1);
                    } else {
                        prescribed = true;
                    }
                }
                (!prescribed, sum / count.max(1), c)
            })
            .collect();
        keys.par_sort_unstable();
        let order: Arc<[usize]> = keys.iter().map(|&(_, _, c)| c).collect();
        let n = order.len();
        let prescribed_end = keys.partition_point(|&(none, _, _)| !none).next_multiple_of(CELL_LANES).min(n);
        let per = n.div_ceil(PARTS).next_multiple_of(CELL_LANES);
        let slots: Vec<usize> = order.par_iter().flat_map_iter(|&c| slots_of(c)).collect();
        let nb = bb.len();
        let parts = [0..prescribed_end, prescribed_end..n]
            .into_iter()
            .flat_map(|segment| segment.clone().step_by(per).map(move |first| first..(first + per).min(segment.end)))
            .map(|cells| {
                let rows = slots[cells.start * nb..cells.end * nb].iter().filter(|&&k| k < n_system);
                let (lo, hi) = rows.fold((usize::MAX, 0), |(lo, hi), &r| (lo.min(r), hi.max(r + 1)));
                (cells, lo.min(hi)..hi)
            })
            .collect();
        CellLayout { order, slots, prescribed_end, parts }
    }

    /// y (one value per system dof) = S v, S the condensed operator of `op`, for v
    /// equal to `x` on the system dofs (zero when None) and `prescribed` on
    /// the prescribed ones (one value per dof; zero when None). With x = 0
    /// and the increment's prescribed values, −y is the condensed right-hand
    /// side. Cells whose values are all zero are skipped.
    pub fn apply_cells(
        &self,
        op: &CellOperator,
        mesh: &HighOrderMesh,
        kernel: &LinearElasticKernel,
        x: Option<&[f64]>,
        prescribed: Option<&[f64]>,
        y: &mut [f64],
    ) {
        match mesh.dim() {
            2 => self.apply_cells_in::<2>(op, mesh, kernel, x, prescribed, y),
            _ => self.apply_cells_in::<3>(op, mesh, kernel, x, prescribed, y),
        }
    }

    fn apply_cells_in<const D: usize>(
        &self,
        op: &CellOperator,
        mesh: &HighOrderMesh,
        kernel: &LinearElasticKernel,
        x: Option<&[f64]>,
        prescribed: Option<&[f64]>,
        y: &mut [f64],
    ) {
        let nd = mesh.nodes_per_cell() * D;
        let (ii, bb) = self.local_dofs(nd);
        let ni = ii.len();
        let w = self.interior.as_ref().map_or(&[][..], |r| &r.keep[..]);
        let product = Product { op, kernel, x, prescribed, bb: &bb, ni, w, n_system: self.dofs.n_system };
        let init = || CellScratch {
            vb: vec![0.0; bb.len()],
            yb: vec![0.0; bb.len()],
            ue4: vec![0.0; nd * CELL_LANES],
            ye4: vec![0.0; nd * CELL_LANES],
            z: vec![0.0; ni],
        };
        // Without x, only the cells with a prescribed dof have values.
        let end = if x.is_none() { op.layout.prescribed_end } else { op.n_cells };
        let sums: Vec<Vec<f64>> = op
            .layout
            .parts
            .par_iter()
            .map_init(init, |s, (cells, rows)| {
                let mut part = vec![0.0; rows.len()];
                let cells = cells.start..cells.end.min(end);
                cells.step_by(CELL_LANES).for_each(|c| product.group::<D>(s, c, rows.start, &mut part));
                part
            })
            .collect();
        // Each row adds the parts that reach it, in order.
        const ROWS: usize = 4096;
        y.par_chunks_mut(ROWS).enumerate().for_each(|(k, yc)| {
            let first = k * ROWS;
            yc.fill(0.0);
            for ((_, rows), part) in op.layout.parts.iter().zip(&sums) {
                let (lo, hi) = (rows.start.max(first), rows.end.min(first + yc.len()));
                for r in lo..hi {
                    yc[r - first] += part[r - rows.start];
                }
            }
        });
    }
}

/// What one product of [`System::apply_cells`] reads.
struct Product<'a> {
    op: &'a CellOperator,
    kernel: &'a LinearElasticKernel,
    x: Option<&'a [f64]>,
    prescribed: Option<&'a [f64]>,
    /// The cells' non-interior local dofs, and the number of interior ones.
    bb: &'a [usize],
    ni: usize,
    /// The interior recovery's W and g per cell (with interior dofs), in
    /// the layout's order.
    w: &'a [f64],
    n_system: usize,
}

impl Product<'_> {
    /// The share of the cells from `first` (a group of [`CELL_LANES`], fewer
    /// at the end) added to `part`, which holds the system rows from `rows`
    /// on. A cell whose values are all zero adds nothing.
    fn group<const D: usize>(&self, s: &mut CellScratch, first: usize, rows: usize, part: &mut [f64]) {
        const L: usize = CELL_LANES;
        let (ni, nb, n_system) = (self.ni, self.bb.len(), self.n_system);
        let lanes = (self.op.n_cells - first).min(L);
        let mut live = [false; L];
        for (l, live) in live.iter_mut().enumerate() {
            if l >= lanes {
                // Past the last cell: zero factors, and zero values.
                self.bb.iter().for_each(|&b| s.ue4[b * L + l] = 0.0);
                continue;
            }
            let slots = &self.op.layout.slots[(first + l) * nb..][..nb];
            for (&b, &k) in self.bb.iter().zip(slots) {
                let v = if k < n_system {
                    self.x.map_or(0.0, |x| x[k])
                } else {
                    self.prescribed.map_or(0.0, |p| p[k - n_system])
                };
                s.ue4[b * L + l] = v;
                *live |= v != 0.0;
            }
        }
        if !live.contains(&true) {
            return;
        }
        let per_group = self.op.per_cell * L;
        let factors = &self.op.factors[first / L * per_group..][..per_group];
        self.kernel.apply4::<D>(factors, &s.ue4, &mut s.ye4);
        for l in (0..lanes).filter(|&l| live[l]) {
            let at = first + l;
            for ((v, y), &b) in s.vb.iter_mut().zip(s.yb.iter_mut()).zip(self.bb) {
                (*v, *y) = (s.ue4[b * L + l], s.ye4[b * L + l]);
            }
            if ni > 0 {
                // z = −W v_B; y_B += K_BI z = Wᵀ (K_II z).
                let w = &self.w[at * ni * (nb + 1)..][..ni * nb];
                for (z, wi) in s.z.iter_mut().zip(w.chunks_exact(nb)) {
                    *z = -crate::linalg::dot4(wi, &s.vb);
                }
                let kii = &self.op.kii[at * ni * ni..][..ni * ni];
                for (ki, wi) in kii.chunks_exact(ni).zip(w.chunks_exact(nb)) {
                    let t = ki.iter().zip(&s.z).map(|(k, z)| k * z).sum::<f64>();
                    for (y, w) in s.yb.iter_mut().zip(wi) {
                        *y += w * t;
                    }
                }
            }
            let slots = &self.op.layout.slots[at * nb..][..nb];
            for (&k, &y) in slots.iter().zip(&s.yb) {
                if k < n_system {
                    part[k - rows] += y;
                }
            }
        }
    }
}

/// K_II (`kii`, the interior dofs ii in order) and W = K_II⁻¹ K_IB (the
/// first ni·nb values of each cell's `keep`, columns in the order of `bb`)
/// of a group of cells (up to [`CELL_LANES`], `factors4` as
/// [`LinearElasticKernel::apply4`] reads them), from the cell matrices'
/// columns at the interior dofs (K is symmetric); `lu` holds the factors of
/// K_II. Err(l): the interior block of the group's cell l is singular.
fn interior_columns<const D: usize>(
    kernel: &LinearElasticKernel,
    factors4: &[f64],
    (ii, bb): (&[usize], &[usize]),
    kii: &mut [f64],
    keep: &mut [f64],
    (ye4, lu): &mut (Vec<f64>, Vec<f64>),
) -> std::result::Result<(), usize> {
    const L: usize = CELL_LANES;
    let (ni, nb) = (ii.len(), bb.len());
    let (kii_stride, stride) = (ni * ni, ni * (nb + 1));
    let lanes = kii.len() / kii_stride;
    for (j, &dj) in ii.iter().enumerate() {
        kernel.unit4::<D>(factors4, dj, ye4);
        for l in 0..lanes {
            for (i, &di) in ii.iter().enumerate() {
                kii[l * kii_stride + i * ni + j] = ye4[di * L + l];
            }
            for (b, &db) in bb.iter().enumerate() {
                keep[l * stride + j * nb + b] = ye4[db * L + l];
            }
        }
    }
    for l in 0..lanes {
        lu.copy_from_slice(&kii[l * kii_stride..][..kii_stride]);
        solve_in_place(lu, ni, &mut keep[l * stride..][..ni * nb], nb).map_err(|_| l)?;
    }
    Ok(())
}

/// A = `a` (n × n, row-major) factored by Gaussian elimination with partial
/// pivoting, and the `m` columns of `b` (n × m, row-major) overwritten by
/// A⁻¹ b; fails on a pivot ≤ 1e-14 of the largest entry of A.
fn solve_in_place(a: &mut [f64], n: usize, b: &mut [f64], m: usize) -> std::result::Result<(), ()> {
    let scale = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    for k in 0..n {
        let p = (k..n).max_by(|&i, &j| a[i * n + k].abs().total_cmp(&a[j * n + k].abs())).expect("k < n");
        let pivot = a[p * n + k];
        if pivot.is_nan() || pivot.abs() <= 1e-14 * scale {
            return Err(());
        }
        if p != k {
            for j in 0..n {
                a.swap(k * n + j, p * n + j);
            }
            for j in 0..m {
                b.swap(k * m + j, p * m + j);
            }
        }
        for i in k + 1..n {
            let f = a[i * n + k] / pivot;
            if f == 0.0 {
                continue;
            }
            for j in k..n {
                a[i * n + j] -= f * a[k * n + j];
            }
            for j in 0..m {
                b[i * m + j] -= f * b[k * m + j];
            }
        }
    }
    for k in (0..n).rev() {
        for j in 0..m {
            let mut v = b[k * m + j];
            for i in k + 1..n {
                v -= a[k * n + i] * b[i * m + j];
            }
            b[k * m + j] = v / a[k * n + k];
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assembly::DofMap;
    use crate::cases;
    use crate::material::LinearElastic;
    use crate::mesh::{validate_and_orient, Topology};
    use crate::reference::{NodeSet, NodeSpacing};

    /// The products without the matrix match the assembled matrix's, and
    /// the right-hand side and interior recovery match the assembly's, on a
    /// curved mesh in 2D and 3D, with and without condensation; and again
    /// on a second geometry, with the layout and the buffers kept from the
    /// first.
    #[test]
    fn products_by_cells_match_the_assembled_system() {
        // 63, 576 and 861 cells: remainders 3, 0 and 1 in the groups of four
        // cells the products take (cells away from the boundary dropped:
        // holes, which the products do not mind).
        let cases = [(cases::cylinder_channel_2d(8, 2, 1.0), 4, 1), (cases::sphere_in_box_3d(2, 2), 4, 0), (cases::sphere_in_box_3d(2, 3), 2, 3)];
        for (mut case, p, drop) in cases {
            let m = &mut case.mesh;
            let on_facets: std::collections::HashSet<usize> = m.facets.iter().copied().collect();
            let inner: Vec<usize> = (0..m.cells.len() / (m.dim + 1))
                .filter(|&c| m.cells[c * (m.dim + 1)..][..m.dim + 1].iter().all(|v| !on_facets.contains(v)))
                .take(drop)
                .collect();
            assert_eq!(inner.len(), drop);
            let kept = (0..m.cells.len() / (m.dim + 1)).filter(|c| !inner.contains(c));
            m.cells = kept.flat_map(|c| m.cells[c * (m.dim + 1)..][..m.dim + 1].to_vec()).collect();
            let (lin, _) = validate_and_orient(&case.mesh).unwrap();
            let topo = Topology::new(&lin).unwrap();
            let nodes = NodeSet::new(topo.simplex, p, NodeSpacing::Optimal);
            let mut mesh = HighOrderMesh::elevate(&lin, &topo, &nodes, NodeSpacing::Optimal).unwrap();
            for (i, x) in mesh.coords.iter_mut().enumerate() {
                *x += 2e-3 * ((i as f64) * 0.7).sin();
            }
            let kernel = LinearElasticKernel::for_nodes(&nodes, LinearElastic::try_from_young_poisson(7.0, 0.4).unwrap());
            // Prescribed values on the boundary, a smooth field.
            let prescribed: Vec<f64> = (0..mesh.coords.len()).map(|i| 1e-2 * ((i as f64) * 0.31).cos()).collect();
            let mut system = None;
            for (condensed, geometry) in [false, true].into_iter().flat_map(|c| [(c, 0), (c, 1)]) {
                if geometry == 0 {
                    let dofs = if condensed { DofMap::condensed(&mesh) } else { DofMap::new(&mesh) };
                    system = Some(System::new(&mesh, dofs));
                }
                for (i, x) in mesh.coords.iter_mut().enumerate() {
                    *x += 1e-3 * geometry as f64 * ((i as f64) * 1.3).cos();
                }
                let system = system.as_mut().expect("made for the first geometry");
                system.assemble(&mesh, &mesh.coords, &kernel, &prescribed, false).unwrap();
                let n = system.dofs().n_system;
                let x: Vec<f64> = (0..n).map(|i| ((i as f64) * 0.37).cos()).collect();
                // The free dofs completed from the system's x by the interior recovery.
                let recovered = |system: &System| {
                    let mut u = x.clone();
                    u.resize(system.dofs().n_free, f64::NAN);
                    system.recover_interior(&mesh, &prescribed, &mut u);
                    u
                };
                let (values, rhs, interior) = (system.values().to_vec(), system.rhs().to_vec(), recovered(system));
                let op = system.cell_operator(&mesh, &mesh.coords, &kernel).unwrap();
                let mut y = vec![0.0; n];
                system.apply_cells(&op, &mesh, &kernel, Some(&x), None, &mut y);
                let want = system.pattern().sym_matvec(&values, &x);
                let close = |a: &[f64], b: &[f64], what: &str| {
                    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    let err = a.iter().zip(b).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                    assert!(
                        err <= 1e-10 * scale,
                        "p = {p}, condensed {condensed}, geometry {geometry}: {what} off by {err:e} (scale {scale:e})"
                    );
                };
                close(&y, &want, "product");
                system.apply_cells(&op, &mesh, &kernel, None, Some(&prescribed), &mut y);
                let minus: Vec<f64> = y.iter().map(|v| -v).collect();
                close(&minus, &rhs, "right-hand side");
                // (the assembly's g = K_II⁻¹ f_I is zero without a residual, as is the cells')
                close(&recovered(system), &interior, "interior recovery");
                // The second geometry's operator is built in these buffers.
                system.recycle(op);
            }
        }
    }

    #[test]
    fn a_small_dense_solve_with_pivoting() {
        // A row swap is needed at the first step.
        let mut a = vec![0.0, 2.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.0, 1.0];
        let x = [1.0, -2.0, 0.5, 3.0, 0.25, -1.0];
        let b_of = |a: &[f64]| -> Vec<f64> {
            (0..3).flat_map(|i| (0..2).map(move |j| (0..3).map(|k| a[i * 3 + k] * x[k * 2 + j]).sum::<f64>()).collect::<Vec<_>>()).collect()
        };
        let mut b = b_of(&a);
        solve_in_place(&mut a, 3, &mut b, 2).unwrap();
        for (u, v) in b.iter().zip(&x) {
            assert!((u - v).abs() < 1e-14, "{b:?}");
        }
        let mut singular = vec![1.0, 2.0, 2.0, 4.0];
        assert!(solve_in_place(&mut singular, 2, &mut [1.0, 1.0], 1).is_err());
    }
}
