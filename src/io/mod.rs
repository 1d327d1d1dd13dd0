//! gmsh and VTK files: the only code in hocurve that touches the file system.
//!
//! - [`gmsh`]: read MSH 4.1 (ASCII and binary) into [`gmsh::MshContent`], turn
//!   it into the [`LinearMesh`](crate::mesh::LinearMesh) to curve or into the
//!   high-order cells to assess, and write order-p meshes as MSH 4.1 ASCII.
//! - [`vtk`]: write order-p meshes as VTK XML unstructured grids with
//!   Lagrange cells (types 69 and 71) and point/cell data.
//! - [`report`]: the JSON report of a run (text; the caller writes it).
//!
//! Writers are atomic: they write `<path>.tmp` and rename it over `path`, so a
//! failed run leaves no half-written file behind.

pub mod gmsh;
pub mod mesh_file;
pub mod report;
pub mod vtk;

pub use mesh_file::{check_mesh_extension, write_mesh, write_mesh_partitioned};

use crate::error::{Error, Result};
use crate::reference::ordering::permutation;
use crate::reference::Simplex;
use std::io::Write;
use std::path::{Path, PathBuf};

/// A high-order simplex mesh to write: nodes at the *equispaced* Lagrange
/// positions (the gmsh/VTK convention).
#[derive(Debug, Clone, Copy)]
pub struct CellMeshView<'a> {
    /// Triangle (2D) or tetrahedron (3D).
    pub simplex: Simplex,
    /// Polynomial order, 1..=10.
    pub order: usize,
    /// Node coordinates, `simplex.dim()` interleaved components per node.
    pub coords: &'a [f64],
    /// Cell nodes, `simplex.n_nodes(order)` per cell, in the local order `cell_multi`.
    pub cells: &'a [usize],
    /// Barycentric multi-index of each local node of `cells` (see
    /// [`crate::reference::ordering`]).
    pub cell_multi: &'a [[usize; 4]],
}

impl CellMeshView<'_> {
    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.coords.len() / self.simplex.dim()
    }
    /// Nodes per cell.
    pub fn nodes_per_cell(&self) -> usize {
        self.simplex.n_nodes(self.order)
    }
    /// Number of cells.
    pub fn n_cells(&self) -> usize {
        self.cells.len() / self.nodes_per_cell()
    }
    /// Node `i` as a 3-vector (z = 0 in 2D).
    pub fn node(&self, i: usize) -> [f64; 3] {
        let d = self.simplex.dim();
        let mut x = [0.0; 3];
        x[..d].copy_from_slice(&self.coords[i * d..(i + 1) * d]);
        x
    }

    /// Checks the view's sizes, indices and coordinates and returns, for the
    /// target ordering `target`, the permutation `perm` with
    /// `target_node[k] = cell_node[perm[k]]`.
    fn checked_permutation(&self, target: &[[usize; 4]]) -> Result<Vec<usize>> {
        let bad = |m: String| Err(Error::InvalidInput(m));
        if !(1..=10).contains(&self.order) {
            return bad(format!("order {} is outside 1..=10", self.order));
        }
        let d = self.simplex.dim();
        let npc = self.nodes_per_cell();
        if !self.coords.len().is_multiple_of(d) {
            return bad(format!("{} coordinates is not a multiple of dim = {d}", self.coords.len()));
        }
        if !self.cells.len().is_multiple_of(npc) {
            return bad(format!("{} cell entries is not a multiple of {npc} nodes per cell", self.cells.len()));
        }
        if let Some(x) = self.coords.iter().find(|x| !x.is_finite()) {
            return bad(format!("non-finite coordinate {x}"));
        }
        let n = self.n_nodes();
        if let Some(&i) = self.cells.iter().find(|&&i| i >= n) {
            return bad(format!("cell node {i} out of range (mesh has {n} nodes)"));
        }
        permutation(self.cell_multi, target).ok_or_else(|| {
            Error::InvalidInput(format!(
                "cell_multi is not the set of multi-indices of an order-{} {:?}",
                self.order, self.simplex
            ))
        })
    }
}

/// Writes through `write` into `<path>.tmp`, then renames it to `path`. On
/// failure the temporary file is removed and `path` is left untouched.
pub(crate) fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> Result<()>,
) -> Result<()> {
    let tmp = tmp_path(path);
    // Errors name the file the caller asked for, not the temporary one.
    let io = |e: std::io::Error| Error::Io(format!("cannot write {}: {e}", path.display()));
    let result = (|| {
        let file = std::fs::File::create(&tmp).map_err(io)?;
        let mut w = std::io::BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| io(e.into_error()))?;
        file.sync_all().map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn tmp_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".tmp");
    path.with_file_name(name)
}

/// Maps a `std::io::Error` of a writer to [`Error::Io`].
pub(crate) fn io_err(e: std::io::Error) -> Error {
    Error::Io(e.to_string())
}

/// Writes `x` so that it reads back exactly: plain decimals for moderate
/// magnitudes, exponent notation otherwise.
pub(crate) fn write_f64<W: Write>(w: &mut W, x: f64) -> std::io::Result<()> {
    let a = x.abs();
    if a == 0.0 || (1e-5..1e15).contains(&a) {
        write!(w, "{x}")
    } else {
        write!(w, "{x:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn write_f64_round_trips() {
        for x in [0.0, -0.0, 1.0, 0.1, -2.5e-7, 1e300, 1.0 / 3.0, 123456.789] {
            let mut s = Vec::new();
            write_f64(&mut s, x).unwrap();
            let s = String::from_utf8(s).unwrap();
            assert_eq!(s.parse::<f64>().unwrap(), x, "{s}");
            assert!(s.len() < 30, "{s}");
        }
    }

    #[test]
    fn failed_atomic_write_leaves_nothing() {
        let dir = std::env::temp_dir().join(format!("hocurve-io-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("failed.txt");
        let r = write_atomically(&path, |w| {
            w.write_all(b"half").map_err(io_err)?;
            Err(Error::Io("boom".into()))
        });
        assert!(r.is_err());
        assert!(!path.exists());
        assert!(!tmp_path(&path).exists());
        write_atomically(&path, |w| w.write_all(b"ok").map_err(io_err)).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "ok");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
