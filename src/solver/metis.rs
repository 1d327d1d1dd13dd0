//! The METIS calls of the crate: `METIS_NodeND`, nested dissection of a
//! graph, and `METIS_PartMeshDual`, the partition of a mesh's cells for a
//! distributed run.
//!
//! METIS 5.2.1 and GKlib are vendored in `third_party/metis` and compiled by
//! `build.rs` with 32-bit `idx_t` and every global symbol renamed
//! `hocurve_<name>` (`third_party/metis/hocurve_metis_rename.h`), so a host
//! may link its own METIS beside libhocurve; hence the `link_name`s below.

use std::os::raw::c_int;
use std::sync::Mutex;

use crate::mesh::HighOrderMesh;
use crate::{Error, Result, SolverFailure};

/// METIS's `idx_t` as compiled by `build.rs` (`IDXTYPEWIDTH=32`).
type Idx = i32;

/// `METIS_NOPTIONS` of metis.h.
const METIS_NOPTIONS: usize = 40;
/// `METIS_OK` of metis.h's `rstatus_et`.
const METIS_OK: c_int = 1;

extern "C" {
    #[link_name = "hocurve_METIS_SetDefaultOptions"]
    fn metis_set_default_options(options: *mut Idx) -> c_int;

    #[link_name = "hocurve_METIS_NodeND"]
    fn metis_node_nd(
        nvtxs: *mut Idx,
        xadj: *mut Idx,
        adjncy: *mut Idx,
        vwgt: *mut Idx,
        options: *mut Idx,
        perm: *mut Idx,
        iperm: *mut Idx,
    ) -> c_int;
}

#[cfg_attr(not(feature = "mpi"), allow(dead_code))]
extern "C" {
    #[link_name = "hocurve_METIS_PartMeshDual"]
    fn metis_part_mesh_dual(
        ne: *mut Idx,
        nn: *mut Idx,
        eptr: *mut Idx,
        eind: *mut Idx,
        vwgt: *mut Idx,
        vsize: *mut Idx,
        ncommon: *mut Idx,
        nparts: *mut Idx,
        tpwgts: *mut f32,
        options: *mut Idx,
        objval: *mut Idx,
        epart: *mut Idx,
        npart: *mut Idx,
    ) -> c_int;
}

/// The part (0..`parts`) of each cell of `mesh`: METIS's k-way partition
/// of the cells' dual graph (cells sharing a facet), balanced with few
/// facets between parts.
pub fn partition(mesh: &HighOrderMesh, parts: usize) -> Result<Vec<usize>> {
    let nodes = crate::reference::NodeSet::new(mesh.simplex, mesh.order, mesh.spacing);
    // The local positions of a cell's vertices (the nodes with one λ = 1).
    let corners: Vec<usize> = (0..mesh.nodes_per_cell()).filter(|&a| nodes.multi[a].contains(&mesh.order)).collect();
    let mut vertices = Vec::with_capacity(mesh.n_cells() * corners.len());
    for c in 0..mesh.n_cells() {
        vertices.extend(corners.iter().map(|&a| mesh.cell(c)[a]));
    }
    try_part_cells(&vertices, corners.len(), mesh.n_vertices, parts)
}

/// The part (0..`parts`) of each of `n_cells` cells of `vertices_per_cell`
/// vertices each (`cells`, vertex indices below `n_vertices`), balanced
/// and with few facets between parts: METIS's k-way partition of the dual
/// graph whose edges are the shared facets (`vertices_per_cell − 1`
/// common vertices). One part: all zeros, without METIS.
pub fn try_part_cells(
    cells: &[usize],
    vertices_per_cell: usize,
    n_vertices: usize,
    parts: usize,
) -> Result<Vec<usize>> {
    let n_cells = cells.len() / vertices_per_cell.max(1);
    if parts <= 1 || n_cells <= 1 {
        return Ok(vec![0; n_cells]);
    }
    let too_big = || Error::solver(SolverFailure::Setup, "METIS_PartMeshDual: the mesh exceeds 32-bit indices");
    let mut ne = Idx::try_from(n_cells).map_err(|_| too_big())?;
    let mut nn = Idx::try_from(n_vertices).map_err(|_| too_big())?;
    let mut eptr: Vec<Idx> = (0..=n_cells).map(|c| (c * vertices_per_cell) as Idx).collect();
    let mut eind: Vec<Idx> = cells.iter().map(|&v| v as Idx).collect();
    let mut ncommon = (vertices_per_cell - 1) as Idx;
    let mut nparts = parts as Idx;
    let mut options = [0 as Idx; METIS_NOPTIONS];
    let (mut objval, mut epart, mut npart) = (0 as Idx, vec![0 as Idx; n_cells], vec![0 as Idx; n_vertices]);
    let _guard = METIS_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    // SAFETY: the arrays have the lengths METIS_PartMeshDual expects
    // (eptr: ne + 1; eind: eptr[ne]; epart: ne; npart: nn; options:
    // METIS_NOPTIONS); the weights may be null. METIS keeps no pointer.
    let status = unsafe {
        metis_set_default_options(options.as_mut_ptr());
        metis_part_mesh_dual(
            &mut ne,
            &mut nn,
            eptr.as_mut_ptr(),
            eind.as_mut_ptr(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            &mut ncommon,
            &mut nparts,
            std::ptr::null_mut(),
            options.as_mut_ptr(),
            &mut objval,
            epart.as_mut_ptr(),
            npart.as_mut_ptr(),
        )
    };
    if status != METIS_OK {
        return Err(Error::solver(SolverFailure::Setup, format!("METIS_PartMeshDual failed (status {status})")));
    }
    Ok(epart.into_iter().map(|p| p as usize).collect())
}

/// METIS installs process-wide SIGABRT/SIGTERM handlers for the length of a
/// call and restores the previous ones after; two concurrent calls would
/// restore them out of order. One call at a time within this library.
static METIS_LOCK: Mutex<()> = Mutex::new(());

/// Nested-dissection ordering of the graph in CSR form (`xadj`: n + 1
/// offsets; `adjncy`: neighbours, both directions of every edge, no self
/// loops; n ≥ 1). Returns `perm` with `perm[new] = old`.
pub fn try_node_nd(xadj: &mut [Idx], adjncy: &mut [Idx]) -> Result<Vec<Idx>> {
    let n = xadj
        .len()
        .checked_sub(1)
        .filter(|&n| n > 0)
        .ok_or_else(|| Error::solver(SolverFailure::Setup, "METIS_NodeND: empty graph"))?;
    if n > Idx::MAX as usize || xadj[n] as usize != adjncy.len() {
        return Err(Error::solver(SolverFailure::Setup, "METIS_NodeND: malformed graph"));
    }
    let mut nvtxs = n as Idx;
    let mut options = [0 as Idx; METIS_NOPTIONS];
    let mut perm = vec![0 as Idx; n];
    let mut iperm = vec![0 as Idx; n];
    let _guard = METIS_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    // SAFETY: the arrays have the lengths METIS_NodeND expects (options:
    // METIS_NOPTIONS; xadj: nvtxs + 1; adjncy: xadj[nvtxs]; perm, iperm:
    // nvtxs); vwgt may be null. METIS does not keep the pointers.
    let status = unsafe {
        metis_set_default_options(options.as_mut_ptr());
        metis_node_nd(
            &mut nvtxs,
            xadj.as_mut_ptr(),
            adjncy.as_mut_ptr(),
            std::ptr::null_mut(),
            options.as_mut_ptr(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    if status != METIS_OK {
        return Err(Error::solver(SolverFailure::Setup, format!("METIS_NodeND failed (status {status})")));
    }
    Ok(perm)
}

#[cfg(test)]
mod partition_tests {
    use super::try_part_cells;

    /// The two triangles of each square of an m × m grid.
    fn grid(m: usize) -> Vec<usize> {
        let v = |i: usize, j: usize| i * (m + 1) + j;
        let mut cells = Vec::new();
        for i in 0..m {
            for j in 0..m {
                cells.extend([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                cells.extend([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            }
        }
        cells
    }

    #[test]
    fn parts_are_balanced_and_their_boundaries_short() {
        let m = 20;
        let cells = grid(m);
        let n_cells = cells.len() / 3;
        assert_eq!(try_part_cells(&cells, 3, (m + 1) * (m + 1), 1).unwrap(), vec![0; n_cells]);
        for parts in [2, 3, 4] {
            let part = try_part_cells(&cells, 3, (m + 1) * (m + 1), parts).unwrap();
            assert_eq!(part.len(), n_cells);
            let mut sizes = vec![0usize; parts];
            part.iter().for_each(|&p| sizes[p] += 1);
            let ideal = n_cells as f64 / parts as f64;
            assert!(sizes.iter().all(|&s| (s as f64 - ideal).abs() <= 0.05 * ideal), "{parts} parts: {sizes:?}");
            // Facets between parts: each square's diagonal and its right and
            // top edges, compared; a strip partition cuts about m per cut.
            let mut cut = 0;
            for i in 0..m {
                for j in 0..m {
                    let (a, b) = (part[2 * (i * m + j)], part[2 * (i * m + j) + 1]);
                    cut += (a != b) as usize;
                    if i + 1 < m {
                        cut += (a != part[2 * ((i + 1) * m + j) + 1]) as usize;
                    }
                    if j + 1 < m {
                        cut += (b != part[2 * (i * m + j + 1)]) as usize;
                    }
                }
            }
            assert!(cut <= 3 * m * (parts - 1), "{parts} parts cut {cut} facets");
        }
    }
}
