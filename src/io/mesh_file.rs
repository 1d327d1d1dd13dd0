//! Write a [`HighOrderMesh`] as gmsh `.msh` or VTK `.vtu`, chosen by extension.

use std::path::Path;

use super::CellMeshView;
use crate::mesh::HighOrderMesh;
use crate::quality::ElementQuality;
use crate::reference::{NodeSet, NodeSpacing};
use crate::{Error, Result};

/// Check that `path` ends in `.msh` or `.vtu`.
pub fn check_mesh_extension(path: &Path) -> Result<()> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("msh") | Some("vtu") => Ok(()),
        _ => Err(Error::InvalidInput(format!("output '{}' must end in .msh or .vtu", path.display()))),
    }
}

/// The view of `mesh` at its equispaced nodes `coords` (of `equi`), which
/// gmsh's and VTK's cells interpolate at.
fn equispaced_view<'a>(mesh: &'a HighOrderMesh, coords: &'a [f64], equi: &'a NodeSet) -> CellMeshView<'a> {
    CellMeshView { simplex: mesh.simplex, order: mesh.order, coords, cells: &mesh.cells, cell_multi: &equi.multi }
}

/// Write `mesh` to `path` in gmsh's partitioned MSH 4.1 format, cell `c` in
/// part `part[c]` of `parts` ([`super::gmsh::write_msh_parts_to`]).
pub fn write_mesh_partitioned(path: &Path, mesh: &HighOrderMesh, part: &[usize], parts: usize) -> Result<()> {
    let equi = NodeSet::new(mesh.simplex, mesh.order, NodeSpacing::Equispaced);
    let coords = mesh.equispaced_coords();
    super::gmsh::write_msh_partitioned(path, &equispaced_view(mesh, &coords, &equi), part, parts)
}

/// Write `mesh` to `path` (`.msh`: gmsh MSH 4.1; `.vtu`: VTK Lagrange cells,
/// with Q1 and Q3 as cell data when `cell_quality` is given).
///
/// Both formats interpolate at equispaced reference nodes, so a mesh with
/// optimal nodes is resampled there first (exact: same polynomial space).
pub fn write_mesh(path: &Path, mesh: &HighOrderMesh, cell_quality: Option<&[ElementQuality]>) -> Result<()> {
    check_mesh_extension(path)?;
    let equi = NodeSet::new(mesh.simplex, mesh.order, NodeSpacing::Equispaced);
    let coords = mesh.equispaced_coords();
    let view = equispaced_view(mesh, &coords, &equi);
    if path.extension().and_then(|e| e.to_str()) == Some("vtu") {
        let (q1, q3): (Vec<f64>, Vec<f64>) = cell_quality.unwrap_or(&[]).iter().map(|q| (q.q1, q.q3)).unzip();
        let cell_data: Vec<(&str, &[f64])> =
            if q3.is_empty() { vec![] } else { vec![("Q3", &q3[..]), ("Q1", &q1[..])] };
        super::vtk::write_vtu(path, &view, &[], &cell_data)
    } else {
        super::gmsh::write_msh(path, &view)
    }
}
