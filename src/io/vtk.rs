//! VTK XML unstructured grids (.vtu) with Lagrange cells, for ParaView.
//!
//! Cells are written as `VTK_LAGRANGE_TRIANGLE` (69) or
//! `VTK_LAGRANGE_TETRAHEDRON` (71) with their nodes converted from the
//! caller's order to VTK's ([`vtk_multi_indices`]); points always have three
//! components (z = 0 in 2D). Data arrays are `Float64`; a field's number of
//! components is its length divided by the number of points (or cells), and
//! 2-component fields of a 2D mesh are padded to 3 so ParaView sees vectors.
//!
//! Two encodings: [`VtuEncoding::AppendedRaw`] (little-endian binary after the
//! XML, compact and exact; the default of [`write_vtu`]) and
//! [`VtuEncoding::Ascii`] (readable; rejects non-finite values, which VTK's
//! ASCII parser cannot read back).

use super::{io_err, write_atomically, write_f64, CellMeshView};
use crate::error::{Error, Result};
use crate::reference::ordering::{vtk_cell_type, vtk_multi_indices};
use std::borrow::Cow;
use std::io::Write;
use std::path::Path;

/// How the arrays of a .vtu file are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum VtuEncoding {
    /// Text inside the XML.
    Ascii,
    /// Raw little-endian bytes in an `<AppendedData>` section (UInt64 headers).
    #[default]
    AppendedRaw,
}

/// Writes `mesh` with point and cell fields as a .vtu file (appended raw
/// binary), atomically (see [`crate::io`]).
pub fn write_vtu(
    path: &Path,
    mesh: &CellMeshView,
    point_data: &[(&str, &[f64])],
    cell_data: &[(&str, &[f64])],
) -> Result<()> {
    write_vtu_with(path, mesh, point_data, cell_data, VtuEncoding::AppendedRaw)
}

/// [`write_vtu`] with a chosen encoding.
pub fn write_vtu_with(
    path: &Path,
    mesh: &CellMeshView,
    point_data: &[(&str, &[f64])],
    cell_data: &[(&str, &[f64])],
    encoding: VtuEncoding,
) -> Result<()> {
    write_atomically(path, |w| write_vtu_to(w, mesh, point_data, cell_data, encoding))
}

/// Writes `mesh` with point and cell fields as a .vtu document into `w`.
pub fn write_vtu_to<W: Write>(
    mut w: W,
    mesh: &CellMeshView,
    point_data: &[(&str, &[f64])],
    cell_data: &[(&str, &[f64])],
    encoding: VtuEncoding,
) -> Result<()> {
    let perm = mesh.checked_permutation(&vtk_multi_indices(mesh.simplex, mesh.order))?;
    let n = mesh.n_nodes();
    let ne = mesh.n_cells();
    let npc = mesh.nodes_per_cell();
    let dim = mesh.simplex.dim();

    let point_arrays = fields(point_data, n, dim, "point")?;
    let cell_arrays = fields(cell_data, ne, dim, "cell")?;

    let points: Vec<f64> = (0..n).flat_map(|i| mesh.node(i)).collect();
    let mut connectivity = Vec::with_capacity(mesh.cells.len());
    for cell in mesh.cells.chunks_exact(npc) {
        connectivity.extend(perm.iter().map(|&k| cell[k] as i64));
    }
    let offsets: Vec<i64> = (1..=ne).map(|e| (e * npc) as i64).collect();
    let types = vec![vtk_cell_type(mesh.simplex); ne];
    let topology = [
        Array::new(Some("connectivity"), 1, Values::I64(connectivity)),
        Array::new(Some("offsets"), 1, Values::I64(offsets)),
        Array::new(Some("types"), 1, Values::U8(types)),
    ];
    let points = [Array::new(None, 3, Values::F64(Cow::Owned(points)))];

    if encoding == VtuEncoding::Ascii {
        let all = point_arrays.iter().chain(&cell_arrays).chain(&points);
        if let Some(a) = all.clone().find(|a| a.has_non_finite()) {
            return Err(Error::InvalidInput(format!(
                "array '{}' has non-finite values, which ASCII .vtu cannot hold",
                a.name.as_deref().unwrap_or("Points")
            )));
        }
    }

    let w = &mut w;
    let mut offset = 0u64;
    (|| -> std::io::Result<()> {
        writeln!(w, "<?xml version=\"1.0\"?>")?;
        writeln!(
            w,
            "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" \
             byte_order=\"LittleEndian\" header_type=\"UInt64\">"
        )?;
        writeln!(w, "<UnstructuredGrid>")?;
        writeln!(w, "<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{ne}\">")?;
        let mut section = |w: &mut W, tag: &str, arrays: &[Array]| -> std::io::Result<()> {
            writeln!(w, "<{tag}>")?;
            for a in arrays {
                a.write_header_and_inline(w, encoding, &mut offset)?;
            }
            writeln!(w, "</{tag}>")
        };
        section(w, "PointData", &point_arrays)?;
        section(w, "CellData", &cell_arrays)?;
        section(w, "Points", &points)?;
        section(w, "Cells", &topology)?;
        writeln!(w, "</Piece>")?;
        writeln!(w, "</UnstructuredGrid>")?;
        if encoding == VtuEncoding::AppendedRaw {
            write!(w, "<AppendedData encoding=\"raw\">\n_")?;
            let all = point_arrays.iter().chain(&cell_arrays).chain(&points);
            for a in all.chain(&topology) {
                a.write_raw(w)?;
            }
            writeln!(w, "\n</AppendedData>")?;
        }
        writeln!(w, "</VTKFile>")?;
        w.flush()
    })()
    .map_err(io_err)
}

fn fields<'a>(data: &[(&str, &'a [f64])], count: usize, dim: usize, what: &str) -> Result<Vec<Array<'a>>> {
    data.iter().map(|&(name, values)| field(name, values, count, dim, what)).collect()
}

/// A point or cell field as an array, checking its length.
fn field<'a>(name: &str, values: &'a [f64], count: usize, dim: usize, what: &str) -> Result<Array<'a>> {
    let components = values.len().checked_div(count).unwrap_or(1);
    if components == 0 || values.len() != components * count {
        return Err(Error::InvalidInput(format!(
            "{what} field '{name}' has {} values for {count} {what}s",
            values.len()
        )));
    }
    if dim == 2 && components == 2 {
        let padded = values.chunks_exact(2).flat_map(|v| [v[0], v[1], 0.0]).collect();
        return Ok(Array::new(Some(name), 3, Values::F64(Cow::Owned(padded))));
    }
    Ok(Array::new(Some(name), components, Values::F64(Cow::Borrowed(values))))
}

enum Values<'a> {
    F64(Cow<'a, [f64]>),
    I64(Vec<i64>),
    U8(Vec<u8>),
}

/// One `<DataArray>`.
struct Array<'a> {
    name: Option<String>,
    components: usize,
    values: Values<'a>,
}

impl<'a> Array<'a> {
    fn new(name: Option<&str>, components: usize, values: Values<'a>) -> Self {
        Array { name: name.map(str::to_string), components, values }
    }

    fn has_non_finite(&self) -> bool {
        matches!(&self.values, Values::F64(v) if v.iter().any(|x| !x.is_finite()))
    }

    fn n_bytes(&self) -> u64 {
        match &self.values {
            Values::F64(v) => 8 * v.len() as u64,
            Values::I64(v) => 8 * v.len() as u64,
            Values::U8(v) => v.len() as u64,
        }
    }

    /// The `<DataArray>` element: inline values (ASCII) or an offset into the
    /// appended data, which `offset` tracks.
    fn write_header_and_inline<W: Write>(
        &self,
        w: &mut W,
        encoding: VtuEncoding,
        offset: &mut u64,
    ) -> std::io::Result<()> {
        let ty = match self.values {
            Values::F64(_) => "Float64",
            Values::I64(_) => "Int64",
            Values::U8(_) => "UInt8",
        };
        write!(w, "<DataArray type=\"{ty}\"")?;
        if let Some(name) = &self.name {
            write!(w, " Name=\"{}\"", xml_escape(name))?;
        }
        write!(w, " NumberOfComponents=\"{}\"", self.components)?;
        if encoding == VtuEncoding::AppendedRaw {
            writeln!(w, " format=\"appended\" offset=\"{offset}\"/>")?;
            *offset += 8 + self.n_bytes();
            return Ok(());
        }
        writeln!(w, " format=\"ascii\">")?;
        let per_line = self.components.max(1);
        let mut k = 0;
        let mut sep = |w: &mut W| {
            k += 1;
            w.write_all(if k % per_line == 0 { b"\n" } else { b" " })
        };
        match &self.values {
            Values::F64(v) => {
                for &x in v.iter() {
                    write_f64(w, x)?;
                    sep(w)?;
                }
            }
            Values::I64(v) => {
                for x in v {
                    write!(w, "{x}")?;
                    sep(w)?;
                }
            }
            Values::U8(v) => {
                for x in v {
                    write!(w, "{x}")?;
                    sep(w)?;
                }
            }
        }
        writeln!(w, "</DataArray>")
    }

    /// The appended block: a UInt64 byte count, then the little-endian values.
    fn write_raw<W: Write>(&self, w: &mut W) -> std::io::Result<()> {
        w.write_all(&self.n_bytes().to_le_bytes())?;
        match &self.values {
            Values::F64(v) => v.iter().try_for_each(|x| w.write_all(&x.to_le_bytes())),
            Values::I64(v) => v.iter().try_for_each(|x| w.write_all(&x.to_le_bytes())),
            Values::U8(v) => w.write_all(v),
        }
    }
}

fn xml_escape(s: &str) -> Cow<'_, str> {
    if !s.contains(['&', '<', '>', '"', '\'']) {
        return Cow::Borrowed(s);
    }
    let mut out = String::with_capacity(s.len() + 8);
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    Cow::Owned(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::ordering::gmsh_multi_indices;
    use crate::reference::Simplex;

    fn quadratic_triangle() -> (Vec<f64>, Vec<usize>, Vec<[usize; 4]>) {
        let multi = gmsh_multi_indices(Simplex::Tri, 2);
        let coords = multi.iter().flat_map(|a| [a[1] as f64 / 2.0, a[2] as f64 / 2.0]).collect();
        (coords, (0..6).collect(), multi)
    }

    #[test]
    fn ascii_vtu_lists_points_cells_and_fields() {
        let (coords, cells, multi) = quadratic_triangle();
        let view = CellMeshView { simplex: Simplex::Tri, order: 2, coords: &coords, cells: &cells, cell_multi: &multi };
        let disp = [0.5; 12];
        let mut buf = Vec::new();
        write_vtu_to(&mut buf, &view, &[("u<1>", &disp)], &[("q", &[0.25])], VtuEncoding::Ascii).unwrap();
        let s = String::from_utf8(buf).unwrap();
        assert!(s.contains("NumberOfPoints=\"6\" NumberOfCells=\"1\""));
        assert!(s.contains("Name=\"u&lt;1&gt;\" NumberOfComponents=\"3\""));
        assert!(s.contains("0.5 0.5 0\n"));
        assert!(s.contains(">\n69\n</DataArray>"));
        // gmsh and VTK order the quadratic triangle alike.
        assert!(s.contains(">\n0\n1\n2\n3\n4\n5\n</DataArray>"));
    }

    #[test]
    fn appended_vtu_has_consistent_offsets() {
        let (coords, cells, multi) = quadratic_triangle();
        let view = CellMeshView { simplex: Simplex::Tri, order: 2, coords: &coords, cells: &cells, cell_multi: &multi };
        let mut buf = Vec::new();
        write_vtu_to(&mut buf, &view, &[], &[("q", &[f64::NAN])], VtuEncoding::AppendedRaw).unwrap();
        let start = buf.windows(2).position(|w| w == b"\n_").unwrap() + 2;
        let end = buf.len() - b"\n</AppendedData>\n</VTKFile>\n".len();
        // q (1 f64), points (18 f64), connectivity (6 i64), offsets (1 i64), types (1 u8).
        assert_eq!(end - start, 5 * 8 + 8 + 18 * 8 + 6 * 8 + 8 + 1);
        let head = String::from_utf8_lossy(&buf[..start]);
        assert!(head.contains("offset=\"16\"")); // after q: 8 + 8
        let mut ascii = Vec::new();
        let r = write_vtu_to(&mut ascii, &view, &[], &[("q", &[f64::NAN])], VtuEncoding::Ascii);
        assert!(matches!(r, Err(Error::InvalidInput(_))));
    }

    #[test]
    fn wrong_field_length_is_rejected() {
        let (coords, cells, multi) = quadratic_triangle();
        let view = CellMeshView { simplex: Simplex::Tri, order: 2, coords: &coords, cells: &cells, cell_multi: &multi };
        let r = write_vtu_to(Vec::new(), &view, &[("u", &[1.0; 7])], &[], VtuEncoding::Ascii);
        assert!(matches!(r, Err(Error::InvalidInput(_))));
    }
}
