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

/// Writes `x` so that it reads back exactly ([`push_f64`]).
pub(crate) fn write_f64<W: Write>(w: &mut W, x: f64) -> std::io::Result<()> {
    w.write_all(shortest(&mut ryu::Buffer::new(), x))
}

/// Appends `x` as the shortest decimal that reads back exactly: plain
/// decimals for moderate magnitudes (integers without a fraction),
/// exponent notation otherwise; `NaN`, `inf` and `-inf` for the others.
pub(crate) fn push_f64(buf: &mut Vec<u8>, x: f64) {
    buf.extend_from_slice(shortest(&mut ryu::Buffer::new(), x));
}

/// `x` formatted by ryu, less the ".0" it gives integers.
fn shortest(buf: &mut ryu::Buffer, x: f64) -> &[u8] {
    let s = buf.format(x).as_bytes();
    s.strip_suffix(b".0").unwrap_or(s)
}

/// Appends `n` in decimal.
pub(crate) fn push_usize(buf: &mut Vec<u8>, n: usize) {
    buf.extend_from_slice(itoa::Buffer::new().format(n).as_bytes());
}

/// Items per task of [`write_formatted`].
const FORMAT_CHUNK: usize = 4096;

/// Tasks formatted at once by [`write_formatted`] before they are written,
/// which bounds the text held in memory.
const FORMAT_BATCH: usize = 64;

/// Writes the text of items `0..n`, `format(i, buf)` appending item i's to
/// `buf`: formatted in parallel, by chunks of items, and written in order.
pub(crate) fn write_formatted<W: Write>(
    w: &mut W,
    n: usize,
    format: impl Fn(usize, &mut Vec<u8>) + Sync,
) -> std::io::Result<()> {
    use rayon::prelude::*;
    let tasks = n.div_ceil(FORMAT_CHUNK);
    for first in (0..tasks).step_by(FORMAT_BATCH) {
        let texts: Vec<Vec<u8>> = (first..tasks.min(first + FORMAT_BATCH))
            .into_par_iter()
            .map(|t| {
                let mut buf = Vec::new();
                for i in t * FORMAT_CHUNK..n.min((t + 1) * FORMAT_CHUNK) {
                    format(i, &mut buf);
                }
                buf
            })
            .collect();
        for text in texts {
            w.write_all(&text)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formatted_items_are_written_in_order_across_chunks_and_batches() {
        let n = FORMAT_CHUNK * FORMAT_BATCH + 3 * FORMAT_CHUNK + 17;
        let mut out = Vec::new();
        write_formatted(&mut out, n, |i, buf| {
            push_usize(buf, i);
            buf.push(b' ');
            push_f64(buf, i as f64 / 7.0);
            buf.push(b'\n');
        })
        .unwrap();
        let text = String::from_utf8(out).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), n);
        for (i, line) in lines.iter().enumerate() {
            let (a, b) = line.split_once(' ').unwrap();
            assert_eq!(a.parse::<usize>().unwrap(), i);
            assert_eq!(b.parse::<f64>().unwrap(), i as f64 / 7.0);
        }
    }

    #[test]
    fn integers_are_written_without_a_fraction_and_non_finite_values_by_name() {
        let text = |x: f64| {
            let mut s = Vec::new();
            push_f64(&mut s, x);
            String::from_utf8(s).unwrap()
        };
        assert_eq!(text(0.0), "0");
        assert_eq!(text(-2.0), "-2");
        assert_eq!(text(0.5), "0.5");
        assert_eq!(text(1e-7), "1e-7");
        assert_eq!(text(f64::NAN), "NaN");
        assert_eq!(text(f64::NEG_INFINITY), "-inf");
    }

    #[test]
    fn write_f64_round_trips() {
        for x in [0.0, -0.0, 1.0, 0.1, -2.5e-7, 1e300, 1.0 / 3.0, 123456.789, f64::MIN_POSITIVE, -f64::MAX, 5e-324] {
            let mut s = Vec::new();
            write_f64(&mut s, x).unwrap();
            let s = String::from_utf8(s).unwrap();
            assert_eq!(s.parse::<f64>().unwrap().to_bits(), x.to_bits(), "{s}");
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
